"""DCC-safe skin fitting (usdface.skel.dcc, usdface.skel.simplex_lsq) against slow, obvious references."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.optimize import nnls

from usdface.errors import OptionError
from usdface.skel import (build_rig, fit_dcc_skin, full_weights, initial_weights, prune_weights, rom_covariance,
                          skinning_error, take_covariance)
from usdface.skel.dcc import MIN_WEIGHT, dcc_skinning_error, simplex_frame, solve_weights
from usdface.skel.simplex_lsq import simplex_lsq
from usdface.skel.weights import motion_gram


def _objective(g, h, w):
    return float(w @ g @ w - 2.0 * h @ w)


def _enumerate_simplex_qp(g, h):
    """Exact minimiser of w^T G w - 2 h^T w on the probability simplex by trying every active set."""
    s = len(h)
    best, best_w = np.inf, None
    for size in range(1, s + 1):
        for subset in itertools.combinations(range(s), size):
            idx = list(subset)
            a = np.zeros((size + 1, size + 1))
            a[:size, :size] = g[np.ix_(idx, idx)]
            a[:size, size] = a[size, :size] = 1.0
            try:
                sol = np.linalg.solve(a, np.concatenate([h[idx], [1.0]]))
            except np.linalg.LinAlgError:
                continue
            if (sol[:size] < -1e-12).any():
                continue
            w = np.zeros(s)
            w[idx] = np.maximum(sol[:size], 0.0)
            w /= w.sum()
            val = _objective(g, h, w)
            if val < best:
                best, best_w = val, w
    return best, best_w


@pytest.fixture(scope="module")
def qp():
    """Random per-vertex problems: 12 joints (joint 0 static, joints 3 and 4 nearly identical), 6 candidates."""
    rng = np.random.default_rng(11)
    j, n, s, f = 12, 80, 6, 40
    motion = rng.normal(size=(j, f))
    motion[0] = 0.0
    motion[4] = motion[3] * (1 + 1e-7)
    target = (rng.random((n, j)) @ motion) / 3.0 + 0.3 * rng.normal(size=(n, f))
    gram, linear = motion @ motion.T, target @ motion.T
    support = np.stack([np.concatenate([[0], rng.choice(np.arange(1, j), s - 1, replace=False)]) for _ in range(n)])
    support[0, 1:3] = [3, 4]
    return gram, linear, support, motion, target


def test_simplex_lsq_matches_exhaustive_active_sets(qp):
    gram, linear, support, _, _ = qp
    w = simplex_lsq(gram, linear, support)
    assert (w >= 0).all() and np.allclose(w.sum(axis=1), 1.0, atol=1e-12)
    for i in range(support.shape[0]):
        g = gram[np.ix_(support[i], support[i])]
        h = linear[i, support[i]]
        best, _ = _enumerate_simplex_qp(g, h)
        assert _objective(g, h, w[i]) <= best + 1e-9 * max(1.0, abs(best))


def test_simplex_lsq_matches_scipy_nnls(qp):
    """The same problems as least squares ||A^T w - b||^2 with scipy's NNLS (sum by a heavy row)."""
    gram, linear, support, motion, target = qp
    w = simplex_lsq(gram, linear, support)
    for i in range(support.shape[0]):
        a = motion[support[i]].T
        heavy = 1e5
        ref, _ = nnls(np.vstack([a, heavy * np.ones(a.shape[1])]), np.concatenate([target[i], [heavy]]), maxiter=5000)
        ours = np.sum((a @ w[i] - target[i]) ** 2)
        theirs = np.sum((a @ (ref / ref.sum()) - target[i]) ** 2)
        assert ours <= theirs * (1 + 1e-7) + 1e-9


def test_simplex_lsq_allowed_mask_and_warm_start(qp):
    gram, linear, support, _, _ = qp
    cold = simplex_lsq(gram, linear, support)
    warm = simplex_lsq(gram, linear, support, start=cold)
    assert np.allclose(warm, cold, atol=1e-10)
    allowed = np.ones(support.shape, dtype=bool)
    allowed[:, 1] = False
    masked = simplex_lsq(gram, linear, support, allowed=allowed, start=cold)  # infeasible starts restart
    assert (masked[:, 1] == 0).all() and np.allclose(masked.sum(axis=1), 1.0)
    for i in range(10):
        keep = np.flatnonzero(allowed[i])
        g = gram[np.ix_(support[i][keep], support[i][keep])]
        h = linear[i, support[i][keep]]
        best, _ = _enumerate_simplex_qp(g, h)
        assert _objective(g, h, masked[i, keep]) <= best + 1e-9 * max(1.0, abs(best))
    with pytest.raises(ValueError):
        simplex_lsq(gram, linear, support, allowed=np.zeros(support.shape, dtype=bool))


@pytest.fixture(scope="module")
def small_face():
    """A small smooth 'face': a Gaussian interpolating transfer from 10 markers to 150 vertices on a
    curved patch, with marker motion from smooth random fields (the structure of the real one)."""
    rng = np.random.default_rng(5)
    uv = rng.uniform(-6, 6, size=(150, 2))
    pts = np.column_stack([uv, 0.05 * (uv ** 2).sum(axis=1)]) + [0.0, 70.0, 10.0]
    markers = rng.choice(150, 10, replace=False)
    d_vm = np.linalg.norm(pts[:, None] - pts[markers][None], axis=2)
    width = 3.0
    phi_vm = np.exp(-(d_vm / width) ** 2)
    b = phi_vm @ np.linalg.inv(phi_vm[markers])
    mp = pts[markers]
    cov = np.exp(-(np.linalg.norm(mp[:, None] - mp[None], axis=2) / 4.0) ** 2) + 1e-3 * np.eye(10)
    disp = np.einsum("mk,fkc->fmc", np.linalg.cholesky(cov), rng.normal(size=(60, 10, 3)))
    return {"points": pts, "markers": markers, "d_vm": d_vm, "width": width, "b": b, "disp": disp}


def test_dcc_fit_constraints_and_monotone_objective(small_face):
    sf = small_face
    w0 = initial_weights(sf["d_vm"], np.full(10, sf["width"]))
    assert (w0 >= 0).all() and np.allclose(w0.sum(axis=1), 1.0)
    cov = rom_covariance(np.linalg.norm(sf["points"][sf["markers"]][:, None] - sf["points"][sf["markers"]][None],
                                        axis=2))
    for k in (3, 5, None):
        fit = fit_dcc_skin(sf["b"], w0, k, cov, n_shapes=6, shape_offset=2.0)
        w = fit.weights.weights
        assert fit.weights.k == (11 if k is None else k)
        assert (w >= 0).all() and np.allclose(w.sum(axis=1), 1.0, atol=1e-12)
        assert ((w == 0) | (w >= MIN_WEIGHT)).all()
        for row in fit.weights.indices:
            assert len(set(row.tolist())) == row.size
        hist = np.asarray(fit.objective)
        scale = float(np.einsum("nm,mk,nk->", sf["b"], cov, sf["b"]))
        assert (np.diff(hist[:-1]) <= 1e-9 * hist[0] + 1e-14 * scale).all()  # alternations never increase it
        if k is None:  # every joint: the Gaussians span the interpolant exactly (no constraint centres here)
            assert hist[-2] < 1e-12 * scale and hist[-1] < 1e-8 * scale  # (then weights < 1e-5 are dropped)
        else:
            assert hist[-2] < 0.5 * hist[0]


def _slow_rig_displacements(fit, rest, marker_points, disp):
    """Independent reference: per frame, per vertex, blend shapes then LBS with 4x4 skinning matrices."""
    rig = build_rig([f"m{j}" for j in range(disp.shape[1])], marker_points, fit.joint_translations(disp))
    xforms = rig.skinning_transforms()  # (F, J, 4, 4)
    shape_w = fit.shape_weights(disp)
    out = np.zeros((disp.shape[0], rest.shape[0], 3))
    for f in range(disp.shape[0]):
        for i in range(rest.shape[0]):
            p = rest[i] + shape_w[f] @ fit.shapes[:, i, :]
            q = np.zeros(3)
            for j, wt in zip(fit.weights.indices[i], fit.weights.weights[i]):
                q += wt * (xforms[f, j] @ np.append(p, 1.0))[:3]
            out[f, i] = q - rest[i]
    return out


def test_rig_displacements_match_slow_lbs(small_face):
    sf = small_face
    w0 = initial_weights(sf["d_vm"], np.full(10, sf["width"]))
    fit = fit_dcc_skin(sf["b"], w0, 4, take_covariance(sf["disp"]), n_shapes=5, shape_offset=2.0)
    d = sf["disp"][:8]
    fast = fit.displacements(d)
    slow = _slow_rig_displacements(fit, sf["points"], sf["points"][sf["markers"]], d)
    assert np.abs(fast - slow).max() < 1e-9
    err = dcc_skinning_error(fit, sf["b"], d)
    ref = np.linalg.norm(slow - np.einsum("nm,fmc->fnc", sf["b"], d), axis=2)
    assert err["max"] == pytest.approx(ref.max(), rel=1e-9) and err["frames"] == 8


def test_w_step_is_per_vertex_nnls_with_the_sum_constraint(small_face):
    """The weights for a joint motion = scipy NNLS per vertex on its support (sum one by a heavy row)."""
    sf = small_face
    w0 = initial_weights(sf["d_vm"], np.full(10, sf["width"]))
    cov = take_covariance(sf["disp"])
    fit = fit_dcc_skin(sf["b"], w0, 4, cov, n_shapes=0)
    support = np.sort(fit.weights.indices, axis=1)
    w = solve_weights(sf["b"], fit.joint_map, cov, support)
    half = np.linalg.cholesky(cov)
    a_full = np.vstack([np.zeros((1, 10)), fit.joint_map]) @ half  # joint motion over the range (root still)
    for i in range(sf["b"].shape[0]):
        a = a_full[support[i]].T
        target = sf["b"][i] @ half
        heavy = 1e5
        ref, _ = nnls(np.vstack([a, heavy * np.ones(a.shape[1])]), np.concatenate([target, [heavy]]), maxiter=5000)
        ours = np.sum((a @ w[i, support[i]] - target) ** 2)
        theirs = np.sum((a @ (ref / ref.sum()) - target) ** 2)
        assert ours <= theirs * (1 + 1e-7) + 1e-12
        assert np.abs(w[i, support[i]] - ref / ref.sum()).max() < 1e-4


def test_corrective_shapes_are_the_least_squares_correction(small_face):
    sf = small_face
    w0 = initial_weights(sf["d_vm"], np.full(10, sf["width"]))
    cov = take_covariance(sf["disp"])
    base = fit_dcc_skin(sf["b"], w0, 3, cov, n_shapes=0)
    assert base.shape_weights(sf["disp"]).shape == (60, 0) and base.shapes.shape == (0, 150, 3)
    fit = fit_dcc_skin(sf["b"], w0, 3, cov, n_shapes=7, shape_offset=50.0)  # large offset: no clipping
    assert np.abs(fit.shapes.sum(axis=0)).max() < 1e-12  # the simplex: shapes sum to zero
    d = sf["disp"]
    sw = fit.shape_weights(d)
    assert sw.min() >= 0 and sw.max() < 1 and (sw.min(axis=1) == 0).all()  # zero at rest, in [0, 1)
    residual = (np.einsum("nm,fmc->fnc", sf["b"], d) - base.displacements(d)).reshape(len(d), -1)
    basis = fit.shapes.reshape(7, -1).T
    projected = basis @ np.linalg.lstsq(basis, residual.T, rcond=None)[0]
    correction = (sw @ fit.shapes.reshape(7, -1)).T
    assert np.abs(correction - projected).max() < 1e-9
    assert dcc_skinning_error(fit, sf["b"], d)["rms"] < dcc_skinning_error(base, sf["b"], d)["rms"]


def test_simplex_frame():
    for c in (1, 2, 5, 15):
        v = simplex_frame(c)
        assert v.shape == (c, c + 1)
        assert np.allclose(v @ v.T, np.eye(c)) and np.allclose(v.sum(axis=1), 0.0)


def test_rom_covariance():
    rng = np.random.default_rng(2)
    pts = rng.uniform(0, 10, size=(20, 3))
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    cov = rom_covariance(d, width=2.0, jitter=0.1)
    assert np.allclose(cov, cov.T) and np.linalg.eigvalsh(cov).min() > 0.09
    assert cov[0, 1] == pytest.approx(np.exp(-(d[0, 1] / 2.0) ** 2), abs=1e-8)
    asym = d + rng.uniform(0, 0.5, size=d.shape)  # hybrid distances need not be symmetric nor Euclidean
    assert np.linalg.eigvalsh(rom_covariance(asym)).min() > 0


def test_fit_options_are_checked(small_face):
    sf = small_face
    w0 = initial_weights(sf["d_vm"], np.full(10, sf["width"]))
    cov = np.eye(10)
    for k in (0, -2, True):
        with pytest.raises(OptionError, match="--max-influences"):
            fit_dcc_skin(sf["b"], w0, k, cov)
    for s in (1, 17, -1):
        with pytest.raises(OptionError, match="--corrective-shapes"):
            fit_dcc_skin(sf["b"], w0, 4, cov, n_shapes=s)


def test_exact_weights_algebra_on_random_transfer():
    rng = np.random.default_rng(7)
    n, m, f = 300, 12, 80
    b = rng.normal(scale=0.3, size=(n, m))
    d = rng.normal(size=(f, m, 3))
    rest = rng.normal(scale=50, size=(n, 3))
    full = full_weights(b)
    assert np.allclose(full.sum(axis=1), 1.0)
    exact = prune_weights(full, None)
    assert skinning_error(exact, b, d, rest)["max"] < 1e-10
    gram = motion_gram(d)
    lsq = prune_weights(full, 4, gram=gram)
    ren = prune_weights(full, 4, fit="renormalize")
    assert np.allclose(lsq.weights.sum(axis=1), 1.0) and np.allclose(ren.weights.sum(axis=1), 1.0)
    assert skinning_error(lsq, b, d, rest)["rms"] < skinning_error(ren, b, d, rest)["rms"]
    dense = lsq.dense(m + 1)
    skinned = rest[None] + np.einsum("nj,fjc->fnc", dense[:, 1:], d)
    cache = rest[None] + np.einsum("nm,fmc->fnc", b, d)
    assert abs(np.linalg.norm(skinned - cache, axis=2).max() - skinning_error(lsq, b, d, rest)["max"]) < 1e-9
