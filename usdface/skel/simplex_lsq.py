"""Many small least-squares problems on the probability simplex, solved together.

Skin weights of one vertex are non-negative and sum to one. Fitting them so that linear blend
skinning reproduces a target motion is, per vertex i, the quadratic program

    minimise   w^T G_S w - 2 h_{i,S}^T w      over w in R^S
    subject to w >= 0,  sum(w) = 1

on the vertex's candidate joints S (its support), with one Gram matrix G shared by every vertex
(G = A A^T, A the joints' motion) and a per-vertex linear term h_i = A b_i (b_i the target
motion of the vertex). This is non-negative least squares with one equality constraint; it is
solved here with the primal active-set method of Lawson & Hanson (1974, ch. 23), adapted to the
sum constraint (the equality enters every KKT solve) and batched over vertices: every iteration
solves one small KKT system per vertex with numpy's batched solver, so thousands of vertices cost
about as much as one. The method is exact (no step size), starts from the best single joint (a
feasible point) and never leaves the feasible set.
"""
from __future__ import annotations

import numpy as np

#: vertices per batch (memory: batch x S x S doubles)
CHUNK_VERTICES = 4096


def simplex_lsq(gram: np.ndarray, linear: np.ndarray, support: np.ndarray, *, allowed: np.ndarray | None = None,
                start: np.ndarray | None = None, max_iter: int | None = None,
                chunk: int = CHUNK_VERTICES) -> np.ndarray:
    """Solve ``min w^T G_S w - 2 h_S^T w, w >= 0, sum w = 1`` for every row (module docstring).

    Parameters
    ----------
    gram : ndarray, shape (J, J), float64
        Symmetric positive semi-definite Gram matrix over all J joints (a joint that never moves,
        such as a static root, has a zero row and column).
    linear : ndarray, shape (N, J), float64
        Linear term h_i per row (vertex).
    support : ndarray, shape (N, S), int
        Candidate joints of each row (distinct indices into J); the solution is zero elsewhere.
    allowed : ndarray, shape (N, S), bool, optional
        Candidates that may take weight (default all); every row needs at least one.
    start : ndarray, shape (N, S), optional
        A feasible starting point (a previous solution: warm start); rows that are not feasible
        (negative, not summing to one, weight on a candidate not allowed) start from their best
        single joint.
    max_iter : int, optional
        Active-set iterations (default ``4 S + 20``; the method needs about one per joint that
        enters or leaves the passive set).
    chunk : int
        Rows solved together.

    Returns
    -------
    ndarray, shape (N, S), float64
        Weights aligned with ``support``: non-negative, each row summing to one.
    """
    gram = np.asarray(gram, dtype=np.float64)
    linear = np.asarray(linear, dtype=np.float64)
    support = np.asarray(support, dtype=np.intp)
    n, s = support.shape
    out = np.empty((n, s))
    allowed = np.ones((n, s), dtype=bool) if allowed is None else np.asarray(allowed, dtype=bool)
    if allowed.shape != (n, s) or not allowed.any(axis=1).all():
        raise ValueError("simplex_lsq: every row needs at least one allowed candidate")
    iters = 4 * s + 20 if max_iter is None else int(max_iter)
    for a in range(0, n, chunk):
        sl = slice(a, min(n, a + chunk))
        sup = support[sl]
        g = gram[sup[:, :, None], sup[:, None, :]]
        h = np.take_along_axis(linear[sl], sup, axis=1)
        out[sl] = _active_set(g, h, allowed[sl], iters, None if start is None else start[sl])
    return out


def _kkt(g: np.ndarray, h: np.ndarray, passive: np.ndarray, ridge: np.ndarray) -> np.ndarray:
    """Minimiser of w^T G w - 2 h^T w on the passive set with sum(w) = 1 (zero off it)."""
    m, s = h.shape
    a = np.zeros((m, s + 1, s + 1))
    pp = passive[:, :, None] & passive[:, None, :]
    a[:, :s, :s] = np.where(pp, g, 0.0)
    diag = np.arange(s)
    # a tiny ridge keeps duplicate or static joints solvable; off the passive set, w = 0
    a[:, diag, diag] = np.where(passive, a[:, diag, diag] + ridge[:, None], 1.0)
    a[:, :s, s] = passive
    a[:, s, :s] = passive
    rhs = np.zeros((m, s + 1))
    rhs[:, :s] = np.where(passive, h, 0.0)
    rhs[:, s] = 1.0
    return np.linalg.solve(a, rhs[:, :, None])[:, :s, 0]


def _active_set(g: np.ndarray, h: np.ndarray, allowed: np.ndarray, max_iter: int,
                start: np.ndarray | None) -> np.ndarray:
    m, s = h.shape
    rows = np.arange(m)
    scale = np.maximum(np.abs(np.diagonal(g, axis1=1, axis2=2)).max(axis=1), np.abs(h).max(axis=1))
    scale = np.where(scale > 0, scale, 1.0)
    ridge = 1e-13 * scale
    tol = 1e-11 * scale
    # feasible start: all weight on the best single joint (cost G_jj - 2 h_j)
    j0 = np.argmin(np.where(allowed, np.diagonal(g, axis1=1, axis2=2) - 2.0 * h, np.inf), axis=1)
    w = np.zeros((m, s))
    w[rows, j0] = 1.0
    if start is not None:
        start = np.asarray(start, dtype=np.float64)
        good = ((start >= 0).all(axis=1) & (np.abs(start.sum(axis=1) - 1.0) < 1e-9)
                & ~((start > 0) & ~allowed).any(axis=1))
        w[good] = start[good]
    passive = w > 0
    todo = np.ones(m, dtype=bool)
    for _ in range(max_iter):
        idx = np.flatnonzero(todo)
        if idx.size == 0:
            break
        z = _kkt(g[idx], h[idx], passive[idx], ridge[idx])
        p = passive[idx]
        wi = w[idx]
        bad = p & (z <= 0.0)
        infeasible = bad.any(axis=1)
        # infeasible rows: move from w towards z until the first passive weight reaches zero
        if infeasible.any():
            r = np.flatnonzero(infeasible)
            den = wi[r] - z[r]
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(bad[r], np.where(den > 0, wi[r] / den, 0.0), np.inf)
            alpha = np.clip(ratio.min(axis=1), 0.0, 1.0)
            step = wi[r] + alpha[:, None] * (z[r] - wi[r])
            hit = bad[r] & (ratio <= alpha[:, None] * (1.0 + 1e-9))
            step[hit] = 0.0
            step = np.maximum(step, 0.0)
            step /= step.sum(axis=1, keepdims=True)
            w[idx[r]] = step
            passive[idx[r]] = p[r] & ~hit & (step > 0)
        # feasible rows: accept z, then free the zero weight whose gradient most wants to grow
        ok = np.flatnonzero(~infeasible)
        if ok.size:
            rows_ok = idx[ok]
            zk = z[ok]
            w[rows_ok] = zk
            grad = np.einsum("rij,rj->ri", g[rows_ok], zk) - h[rows_ok]
            pk = passive[rows_ok]
            # on the passive set the gradient equals the equality multiplier; its mean is robust
            mu = (np.where(pk, grad, 0.0).sum(axis=1) / pk.sum(axis=1))
            reduced = np.where(pk | ~allowed[rows_ok], np.inf, grad - mu[:, None])
            j = np.argmin(reduced, axis=1)
            enter = reduced[np.arange(ok.size), j] < -tol[rows_ok]
            passive[rows_ok[enter], j[enter]] = True
            todo[rows_ok[~enter]] = False
    return w
