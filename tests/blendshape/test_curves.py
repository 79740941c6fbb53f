"""Resampling to film rates and key reduction within a tolerance."""
import numpy as np
import pytest

from usdface.blendshape.curves import interpolate_rigid, reduce_curve, reduce_keys, resample_curves, resample_times


@pytest.mark.parametrize("fps", [24.0, 25.0, 30.0])
def test_resampling_keeps_times_and_bounds(fps):
    f = np.arange(601)
    line = np.stack([f / 600.0, 1 - f / 600.0], axis=1)  # linear curves at 60 Hz over 10 s
    out = resample_curves(line, 60.0, fps)
    assert out.shape[0] == int(10 * fps) + 1
    t = np.arange(out.shape[0]) / fps
    assert np.allclose(out[:, 0], t / 10.0) and np.allclose(out[:, 1], 1 - t / 10.0)
    rng = np.random.default_rng(0)
    noisy = rng.random((601, 5))
    r = resample_curves(noisy, 60.0, fps)
    assert r.min() >= 0.0 and r.max() <= 1.0
    assert np.allclose(resample_times(601, 60.0, fps)[:3], np.arange(3) * 60.0 / fps)


def test_key_reduction_stays_within_tolerance():
    rng = np.random.default_rng(1)
    t = np.arange(2000)
    curves = np.stack([np.clip(np.sin(t / 37.0) * 0.6 + 0.4 + 0.01 * rng.normal(size=t.size), 0, 1),
                       np.clip(np.cumsum(rng.normal(size=t.size)) * 0.01 + 0.5, 0, 1),
                       np.zeros(t.size)], axis=1)
    for tol in (0.001, 0.01, 0.05):
        keyed = reduce_keys(curves, ["a", "b", "c"], tol)
        assert np.abs(keyed.sample() - curves).max() <= tol + 1e-9
        assert keyed.keys[2].tolist() == [0, t.size - 1]  # a flat curve needs its two ends
        assert all(k[0] == 0 and k[-1] == t.size - 1 for k in keyed.keys)
        # USD samples at the union of the keys reproduce every reduced curve exactly
        u = keyed.union_keys()
        at_union = keyed.sample(u)
        again = np.stack([np.interp(t, u, at_union[:, j]) for j in range(3)], axis=1)
        assert np.allclose(again, keyed.sample(), atol=1e-12)
    fewer = [reduce_keys(curves, ["a", "b", "c"], tol).key_counts()["a"] for tol in (0.001, 0.01, 0.05)]
    assert fewer[0] > fewer[1] > fewer[2]


def test_reduce_curve_is_exact_on_piecewise_linear_curves():
    y = np.interp(np.arange(100), [0, 20, 50, 99], [0.0, 1.0, 0.25, 0.25])
    assert reduce_curve(y, 0.0).tolist() == [0, 20, 50, 99]


def test_rigid_interpolation_slerps():
    def rot_y(a):
        m = np.eye(4)
        m[0, 0] = m[2, 2] = np.cos(a)
        m[0, 2], m[2, 0] = np.sin(a), -np.sin(a)
        return m

    a, b = rot_y(0.0), rot_y(0.4)
    b[:3, 3] = [2.0, 0.0, 0.0]
    mid = interpolate_rigid([0.0, 1.0], np.stack([a, b]), [0.5])[0]
    want = rot_y(0.2)
    assert np.allclose(mid[:3, :3], want[:3, :3], atol=1e-12) and np.allclose(mid[:3, 3], [1.0, 0, 0])
