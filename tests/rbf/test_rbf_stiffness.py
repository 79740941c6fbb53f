"""Kernel widths: the default rule and per-marker overrides."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.errors import ComputeError, OptionError
from usdface.rbf import stiffness as S


def _line(spacings):
    x = np.concatenate([[0.0], np.cumsum(spacings)])
    return np.abs(x[:, None] - x[None, :]), x


def test_median_spacing_and_default_rule():
    D, x = _line([1.0, 2.0, 4.0, 8.0])  # nearest distances 1, 1, 2, 4, 8 -> median 2
    assert S.median_marker_spacing(D) == 2.0
    pts = np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1)
    assert S.median_marker_spacing_from_points(pts) == pytest.approx(2.0)
    assert S.DEFAULT_WIDTH_FACTOR == 1.1
    assert S.default_width(D, 5) == pytest.approx(2.2)
    # only the marker block counts: a constraint centre very close to marker 0 changes nothing
    Dc = np.zeros((6, 6))
    Dc[:5, :5] = D
    Dc[5, :5] = Dc[:5, 5] = D[0] + 0.01
    assert S.default_width(Dc, 5) == pytest.approx(2.2)


def test_spacing_uses_row_minimum_for_asymmetric_distances():
    D = np.array([[0.0, 1.0, 5.0], [3.0, 0.0, 2.0], [5.0, 2.5, 0.0]])
    assert S.median_marker_spacing(D) == 2.0  # row minima 1, 2, 2.5


def test_resolve_widths_forms():
    D, _ = _line([1.0, 2.0, 4.0, 8.0])
    C, M = 5, 4  # last centre is a constraint centre
    names = ["a", "b", "c", "d"]
    np.testing.assert_allclose(S.resolve_widths(None, D, M), 1.1 * np.median([1, 1, 2, 4]))
    np.testing.assert_allclose(S.resolve_widths(2.0, D, M), np.full(C, 2.0))
    w = S.resolve_widths([1, 2, 3, 4], D, M)
    np.testing.assert_allclose(w[:4], [1, 2, 3, 4])
    assert w[4] == pytest.approx(S.default_width(D, M))
    np.testing.assert_allclose(S.resolve_widths([1, 2, 3, 4, 5], D, M), [1, 2, 3, 4, 5])
    w = S.resolve_widths({"b": 7.0}, D, M, marker_names=names)
    default = S.default_width(D, M)
    np.testing.assert_allclose(w, [default, 7.0, default, default, default])


def test_resolve_widths_errors():
    D, _ = _line([1.0, 2.0, 4.0])
    names = ["Chin", "Nose", "Brow", "Lip"]
    with pytest.raises(OptionError, match=r"unknown marker\(s\) Chinn; the 4 markers are: Chin, Nose, Brow, Lip"):
        S.resolve_widths({"Chinn": 1.0}, D, 4, marker_names=names)
    with pytest.raises(OptionError, match="needs marker_names"):
        S.resolve_widths({"Chin": 1.0}, D, 4)
    with pytest.raises(OptionError, match="Nose=nan"):
        S.resolve_widths([1.0, np.nan, 1.0, 1.0], D, 4, marker_names=names)
    with pytest.raises(OptionError, match="positive"):
        S.resolve_widths(-1.0, D, 4)
    with pytest.raises(OptionError, match="positive"):
        S.resolve_widths({"Lip": 0.0}, D, 4, marker_names=names)
    with pytest.raises(OptionError, match="4 \\(markers\\) or 4"):
        S.resolve_widths([1.0, 2.0], D, 4)
    with pytest.raises(OptionError, match="expected a number"):
        S.resolve_widths("wide", D, 4)
    with pytest.raises(ComputeError, match="coincide"):
        S.median_marker_spacing(np.zeros((3, 3)))
