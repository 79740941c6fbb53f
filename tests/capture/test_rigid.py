"""Rigid / similarity fitting kernels, checked against scipy and a per-frame loop."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from usdface.capture.rigid import (
    apply_rigid,
    fit_rigid,
    fit_rigid_batch,
    from_matrix,
    invert_matrix,
    rotation_angle,
    to_matrix,
)
from usdface.errors import ComputeError, OptionError


def _random_case(rng, k=12, scale=1.0):
    src = rng.normal(size=(k, 3)) * 5.0
    rot = Rotation.random(random_state=rng).as_matrix()
    t = rng.normal(size=3) * 10.0
    return src, rot, t, scale * src @ rot.T + t


def test_fit_rigid_recovers_exact_transform():
    rng = np.random.default_rng(1)
    src, rot, t, dst = _random_case(rng)
    src0 = src.copy()
    R, s, tt = fit_rigid(src, dst)
    np.testing.assert_allclose(R, rot, atol=1e-12)
    np.testing.assert_allclose(tt, t, atol=1e-10)
    assert s == 1.0
    np.testing.assert_array_equal(src, src0)  # inputs not modified


def test_fit_similarity_recovers_scale():
    rng = np.random.default_rng(2)
    src, rot, t, dst = _random_case(rng, scale=2.5)
    R, s, tt = fit_rigid(src, dst, scale=True)
    assert s == pytest.approx(2.5, rel=1e-12)
    np.testing.assert_allclose(R, rot, atol=1e-12)
    np.testing.assert_allclose(apply_rigid(src, R, s, tt), dst, atol=1e-10)


def test_weighted_fit_matches_scipy_align_vectors():
    rng = np.random.default_rng(3)
    src, rot, t, dst = _random_case(rng, k=20)
    dst = dst + rng.normal(scale=0.3, size=dst.shape)
    w = rng.uniform(0.1, 3.0, size=20)
    R, _, tt = fit_rigid(src, dst, weights=w)
    # the slow obvious reference: weighted centroids, then scipy's weighted Wahba solution
    cs = (w[:, None] * src).sum(0) / w.sum()
    cd = (w[:, None] * dst).sum(0) / w.sum()
    ref, _ = Rotation.align_vectors(dst - cd, src - cs, weights=w)
    np.testing.assert_allclose(R, ref.as_matrix(), atol=1e-9)
    np.testing.assert_allclose(tt, cd - R @ cs, atol=1e-9)


def test_nan_points_are_ignored_and_zero_weight_equals_dropping():
    rng = np.random.default_rng(4)
    src, rot, t, dst = _random_case(rng, k=10)
    dst = dst + rng.normal(scale=0.2, size=dst.shape)
    dst_nan = dst.copy()
    dst_nan[3] = np.nan
    w = np.ones(10)
    w[3] = 0
    a = fit_rigid(src, dst_nan)
    b = fit_rigid(np.delete(src, 3, 0), np.delete(dst, 3, 0))
    c = fit_rigid(src, dst, weights=w)
    for x, y, z in zip(a, b, c):
        np.testing.assert_allclose(x, y, atol=1e-12)
        np.testing.assert_allclose(x, z, atol=1e-12)


def test_planar_mirrored_points_give_a_proper_rotation():
    # a planar point set and its mirror image: the best orthogonal map is a reflection; the fit
    # must still return det(R) = +1
    rng = np.random.default_rng(5)
    src = np.c_[rng.normal(size=(8, 2)), np.zeros(8)]
    dst = src * np.array([-1.0, 1.0, 1.0])
    R, _, _ = fit_rigid(src, dst)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)


def test_batch_matches_per_frame_loop_and_flags_underdetermined_frames():
    rng = np.random.default_rng(6)
    n_frames, k = 50, 7
    src = rng.normal(size=(k, 3))
    rots = Rotation.random(n_frames, random_state=rng).as_matrix()
    dst = np.einsum("fij,kj->fki", rots, src) + rng.normal(size=(n_frames, 1, 3))
    dst = dst + rng.normal(scale=0.05, size=dst.shape)
    dst[10, 2:] = np.nan  # only 2 valid points
    weights = rng.uniform(0.5, 2.0, size=(n_frames, k))
    R, s, t = fit_rigid_batch(src, dst, weights=weights)
    assert R.shape == (n_frames, 3, 3) and s.shape == (n_frames,) and t.shape == (n_frames, 3)
    assert np.isnan(R[10]).all() and np.isnan(t[10]).all() and np.isnan(s[10])
    for f in [0, 5, 11, 49]:
        Rf, sf, tf = fit_rigid(src, dst[f], weights=weights[f])
        np.testing.assert_allclose(R[f], Rf, atol=1e-12)
        np.testing.assert_allclose(t[f], tf, atol=1e-12)
    with pytest.raises(ComputeError, match="at least 3 points"):
        fit_rigid(src, dst[10])


def test_bad_shapes_and_weights_raise_option_error():
    with pytest.raises(OptionError):
        fit_rigid(np.zeros((4, 2)), np.zeros((4, 2)))
    with pytest.raises(OptionError):
        fit_rigid(np.zeros((4, 3)), np.zeros((5, 3)))
    with pytest.raises(OptionError):
        fit_rigid(np.eye(3), np.eye(3), weights=[1, -1, 1])


def test_matrix_helpers_roundtrip_and_rotation_angle():
    rng = np.random.default_rng(7)
    rots = Rotation.random(5, random_state=rng)
    R = rots.as_matrix()
    s = rng.uniform(0.5, 2, 5)
    t = rng.normal(size=(5, 3))
    m = to_matrix(R, s, t)
    R2, s2, t2 = from_matrix(m)
    np.testing.assert_allclose(R2, R, atol=1e-12)
    np.testing.assert_allclose(s2, s)
    np.testing.assert_allclose(np.matmul(m, invert_matrix(m)), np.broadcast_to(np.eye(4), (5, 4, 4)), atol=1e-12)
    np.testing.assert_allclose(rotation_angle(R), np.degrees(rots.magnitude()), atol=1e-9)
    tiny = Rotation.from_rotvec([1e-9, 0, 0]).as_matrix()
    assert rotation_angle(tiny) == pytest.approx(np.degrees(1e-9), rel=1e-6)
