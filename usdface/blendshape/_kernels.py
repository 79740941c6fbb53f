"""numba kernels of the curve solver's inner loop (fused, float32 arrays, float64 sums).

Imported by :mod:`usdface.blendshape.solver`; when numba is missing the solver runs the same
arithmetic in numpy (slower).
"""
from __future__ import annotations

import numpy as np

from ..numba_cache import AVAILABLE, njit  # the solver keeps a numpy path without numba


@njit(cache=True)
def admm_box_update(w, z, u, r, b, hi, rho, relax):  # pragma: no cover - compiled
    """Over-relaxed box projection and dual update of scaled ADMM, and the next right-hand side.

    Per element (f, k): ``wh = relax w + (1 - relax) z``; ``z' = clip(wh + u, 0, hi_k)``;
    ``u' = u + wh - z'``; ``r = b + rho (z' - u')``. Arrays (F, K) float32 (``hi`` too: the upper
    bound of each entry), updated in place.

    Returns
    -------
    (sum (w - z')^2, sum (z' - z)^2) : float64
        For the primal and dual residuals.
    """
    f_n, k_n = w.shape
    primal = 0.0
    dual = 0.0
    for f in range(f_n):
        p_row = np.float32(0.0)
        d_row = np.float32(0.0)
        for k in range(k_n):
            wk = w[f, k]
            zk = z[f, k]
            wh = relax * wk + (np.float32(1.0) - relax) * zk
            uk = u[f, k]
            zn = min(max(wh + uk, np.float32(0.0)), hi[f, k])
            un = uk + wh - zn
            p_row += (wk - zn) * (wk - zn)
            d_row += (zn - zk) * (zn - zk)
            z[f, k] = zn
            u[f, k] = un
            r[f, k] = b[f, k] + rho * (zn - un)
        primal += p_row
        dual += d_row
    return primal, dual


@njit(cache=True)
def add_missing_term(r, w, frames, markers, basis):  # pragma: no cover - compiled
    """``r[f] += A_m^T A_m w[f]`` for every missing sample (f, m).

    r, w : (F, K) float32; frames, markers : (P,) int64; basis : (M, 3, K) float32 (A_m = basis[m]).
    """
    k_n = r.shape[1]
    for i in range(frames.size):
        f = frames[i]
        m = markers[i]
        y0 = np.float32(0.0)
        y1 = np.float32(0.0)
        y2 = np.float32(0.0)
        for k in range(k_n):
            wk = w[f, k]
            y0 += basis[m, 0, k] * wk
            y1 += basis[m, 1, k] * wk
            y2 += basis[m, 2, k] * wk
        for k in range(k_n):
            r[f, k] += basis[m, 0, k] * y0 + basis[m, 1, k] * y1 + basis[m, 2, k] * y2


def admm_box_update_numpy(w, z, u, r, b, hi, rho, relax):
    """numpy form of :func:`admm_box_update` (same results up to float32 rounding)."""
    wh = relax * w + (np.float32(1.0) - relax) * z
    zn = np.clip(wh + u, np.float32(0.0), hi)
    u += wh - zn
    primal = float(((w - zn).astype(np.float64) ** 2).sum())
    dual = float(((zn - z).astype(np.float64) ** 2).sum())
    z[...] = zn
    r[...] = b + rho * (zn - u)
    return primal, dual


def add_missing_term_numpy(r, w, frames, markers, basis):
    """numpy form of :func:`add_missing_term` (one pass per marker)."""
    for m in np.unique(markers):
        f = frames[markers == m]
        am = basis[m]  # (3, K)
        r[f] += (w[f] @ am.T) @ am
