"""Kernels: values, per-centre widths, purity, names."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.errors import OptionError
from usdface.rbf import kernels as K


def test_known_values():
    d = np.array([0.0, 1.0, 2.0])
    np.testing.assert_allclose(K.gaussian(d, 2.0), np.exp(-(d / 2) ** 2))
    np.testing.assert_allclose(K.gaussian([1.0], 1.0), [np.exp(-1.0)])  # paper Eq. 3, gamma = 2
    np.testing.assert_allclose(K.multiquadric(d, 2.0), np.sqrt(1 + (d / 2) ** 2))
    np.testing.assert_allclose(K.inverse_multiquadric(d, 2.0), 1 / np.sqrt(1 + (d / 2) ** 2))
    np.testing.assert_allclose(K.thin_plate_spline(d, 2.0), [0.0, 0.25 * np.log(0.5), 0.0])
    np.testing.assert_allclose(K.cubic(d, 2.0), (d / 2) ** 3)


def test_per_centre_width_broadcasts_along_columns():
    d = np.array([[1.0, 1.0, 1.0], [2.0, 0.0, 3.0]])
    s = np.array([1.0, 2.0, 4.0])
    for name, fn in K.KERNELS.items():
        out = fn(d, s)
        assert out.shape == (2, 3) and out.dtype == np.float64
        for i in range(2):
            for k in range(3):
                assert out[i, k] == pytest.approx(float(fn(np.array(d[i, k]), s[k])), rel=1e-14, abs=1e-300), name


def test_pure_and_infinite_distances():
    d = np.array([[0.5, np.inf]])
    keep = d.copy()
    for fn in K.KERNELS.values():
        fn(d, 1.0)
    np.testing.assert_array_equal(d, keep)
    assert K.gaussian(d, 1.0)[0, 1] == 0.0
    assert K.inverse_multiquadric(d, 1.0)[0, 1] == 0.0
    assert K.DECAYING_KERNELS == {"gaussian", "inverse_multiquadric"}


def test_names_and_aliases():
    assert K.get_kernel("tps") is K.thin_plate_spline
    assert K.get_kernel("Inverse-Multiquadric") is K.inverse_multiquadric
    with pytest.raises(OptionError, match="unknown kernel 'wendland'.*gaussian"):
        K.get_kernel("wendland")
