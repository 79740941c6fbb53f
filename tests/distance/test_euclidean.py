"""Euclidean distance matrices (paper Eq. 6) and the shared input/memory checks."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.distance import (check_matrix_memory, euclidean_at_sources, euclidean_distances,
                              pairwise_euclidean, source_points)
from usdface.errors import InputError, OptionError, ResourceError


@pytest.fixture()
def cloud():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(50, 3)) + np.array([70.0, -30.0, 12.0])
    tri = rng.integers(0, 50, size=(7, 3))
    bary = rng.dirichlet([1, 1, 1], size=7)
    tri[0] = 4
    bary[0] = [1.0, 0.0, 0.0]
    return pts, tri, bary


def test_matches_brute_force(cloud):
    pts, tri, bary = cloud
    d = euclidean_distances(pts, tri, bary)
    q = (bary[:, :, None] * pts[tri]).sum(axis=1)
    ref = np.array([[np.sqrt(((p - s) ** 2).sum()) for s in q] for p in pts])
    assert d.shape == (50, 7) and d.dtype == np.float64
    np.testing.assert_allclose(d, ref, rtol=0, atol=1e-12)
    assert d[4, 0] == 0.0  # vertex source (v, v, v), (1, 0, 0)


def test_at_sources_symmetric(cloud):
    pts, tri, bary = cloud
    s = euclidean_at_sources(pts, tri, bary)
    assert s.shape == (7, 7)
    np.testing.assert_array_equal(s, s.T)
    np.testing.assert_array_equal(np.diag(s), 0.0)
    q = source_points(pts, tri, bary)
    np.testing.assert_allclose(s[1, 2], np.linalg.norm(q[1] - q[2]), rtol=1e-14)


def test_float32_and_precision_far_from_origin():
    a = np.array([[1e4, 1e4, 1e4]])
    b = np.array([[1e4 + 1e-6, 1e4, 1e4]])
    assert pairwise_euclidean(a, b)[0, 0] == pytest.approx(1e-6, rel=1e-6)  # no |a|^2+|b|^2-2ab loss
    d32 = pairwise_euclidean(a, b, dtype=np.float32)
    assert d32.dtype == np.float32


def test_bad_sources(cloud):
    pts, tri, bary = cloud
    with pytest.raises(InputError, match="outside"):
        euclidean_distances(pts, tri + 100, bary)
    with pytest.raises(InputError, match="sum to 1"):
        euclidean_distances(pts, tri, bary * 2)
    with pytest.raises(InputError, match="shape"):
        euclidean_distances(pts, tri[:, :2], bary)
    with pytest.raises(OptionError):
        euclidean_distances(pts, tri, bary, dtype=np.int32)


def test_memory_estimate_error(cloud):
    pts, tri, bary = cloud
    with pytest.raises(ResourceError) as exc:
        euclidean_distances(pts, tri, bary, memory_limit=1000)
    msg = str(exc.value)
    assert "50 vertices x 7 sources" in msg and "float32" in msg and "fewer markers" in msg
    # 300k x 41 float64 = 98 MB: an explicit estimate
    assert check_matrix_memory(300_000, 41, np.float64, memory_limit=10**9) == 300_000 * 41 * 8
    with pytest.raises(ResourceError, match="98.4 MB"):
        check_matrix_memory(300_000, 41, np.float64, memory_limit=50 * 10**6)
