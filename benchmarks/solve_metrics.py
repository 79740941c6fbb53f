"""The blend-shape solve's figures, one definition for every benchmark (issue 19's wording).

- weight RMS: over all shapes and all frames;
- mesh error: over the frames where the true face moves (mean true vertex displacement above
  ``MOVING_CM`` = 0.5 mm), the sum of the frames' mean vertex errors over the sum of their mean
  true displacements;
- marker residual: the solver's per-frame RMS marker residual, averaged over frames (cm).
"""
from __future__ import annotations

import numpy as np

#: a frame moves when its mean true vertex displacement exceeds this (cm)
MOVING_CM = 0.05


def weight_rms(truth, estimate) -> float:
    return float(np.sqrt(((np.asarray(estimate) - np.asarray(truth)) ** 2).mean()))


def mesh_error(truth_deltas, truth_w, est_deltas, est_w, *, chunk: int = 256) -> float:
    """Issue 19's mesh error (see the module docstring); deltas (K, N, 3) cm, weights (F, K)."""
    err_sum = true_sum = 0.0
    for a in range(0, truth_w.shape[0], chunk):
        t = np.einsum("fk,knd->fnd", truth_w[a:a + chunk], truth_deltas)
        e = np.einsum("fk,knd->fnd", est_w[a:a + chunk], est_deltas)
        true_mean = np.linalg.norm(t, axis=2).mean(axis=1)
        moving = true_mean > MOVING_CM
        err_sum += float(np.linalg.norm(e - t, axis=2).mean(axis=1)[moving].sum())
        true_sum += float(true_mean[moving].sum())
    return err_sum / true_sum


def per_frame_bounded_lsq(basis, displacements, keep) -> np.ndarray:
    """The plain reference of issue 19: every frame alone, ``min |B w - d|^2, 0 <= w <= 1`` over
    the frame's valid markers and the shapes ``keep`` (others 0). basis (M, K, 3) cm."""
    from scipy.optimize import lsq_linear

    d = np.asarray(displacements, dtype=np.float64)
    f_n, m_n, _ = d.shape
    a = np.asarray(basis)[:, keep, :].transpose(0, 2, 1).reshape(3 * m_n, len(keep))
    out = np.zeros((f_n, basis.shape[1]))
    ok = np.isfinite(d).all(axis=2)
    for f in range(f_n):
        rows = np.repeat(ok[f], 3)
        if not rows.any():
            continue
        res = lsq_linear(a[rows], d[f].reshape(-1)[rows], bounds=(0.0, 1.0), method="bvls")
        out[f, keep] = res.x
    return out
