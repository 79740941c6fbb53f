"""Closest points on a scan for the registration (:mod:`usdface.scan.register`): a fast
approximate search on dense scans, and the closest point on a set of boundary segments."""
from __future__ import annotations

import numpy as np

__all__ = ["NearSurface", "closest_on_segments"]


def closest_on_segments(q, a, b, k: int = 8):
    """Closest point of each query on a set of segments (exact among the k nearest midpoints)."""
    from scipy.spatial import cKDTree

    mid = 0.5 * (a + b)
    kk = min(k, len(mid))
    _, idx = cKDTree(mid).query(q, k=kk)
    idx = idx.reshape(len(q), -1)
    A, B = a[idx], b[idx]
    e = B - A
    ee = np.maximum(np.einsum("qkd,qkd->qk", e, e), 1e-300)
    tt = np.clip(np.einsum("qkd,qkd->qk", q[:, None, :] - A, e) / ee, 0.0, 1.0)
    P = A + tt[..., None] * e
    d = np.linalg.norm(P - q[:, None, :], axis=2)
    j = d.argmin(axis=1)
    r = np.arange(len(q))
    return P[r, j], d[r, j]


class NearSurface:
    """Closest points on a dense scan mesh for the projection iterations: the exact closest point
    among the triangles around the ``k`` nearest scan vertices of each query (one k-d tree query,
    fixed-size candidate sets). On a scan whose triangles are small compared with the distances
    involved it almost always finds the exact closest point (:class:`usdface.mesh.closest.SurfaceLocator`
    gives the final distances); it is several times faster than the exact search when many queries
    hang off the scan's border."""

    def __init__(self, points, triangles, tree, *, k: int = 2, max_per_vertex: int = 8):
        self.P = np.asarray(points, dtype=np.float64)
        self.F = np.asarray(triangles, dtype=np.int64)
        self.tree = tree
        self.k = k
        nv = self.P.shape[0]
        v = self.F.ravel()
        t = np.repeat(np.arange(len(self.F)), 3)
        order = np.argsort(v, kind="stable")
        v, t = v[order], t[order]
        starts = np.searchsorted(v, np.arange(nv))
        rank = np.arange(v.size) - starts[v]
        keep = rank < max_per_vertex
        self.vt = np.full((nv, max_per_vertex), -1, dtype=np.int64)
        self.vt[v[keep], rank[keep]] = t[keep]

    def closest(self, q):
        from ..mesh.closest import closest_point_on_triangles

        q = np.asarray(q, dtype=np.float64)
        _, nv = self.tree.query(q, k=self.k)
        cand = self.vt[nv.reshape(len(q), -1)].reshape(len(q), -1)  # (Q, k * max_per_vertex)
        valid = cand >= 0
        cand = np.where(valid, cand, self.vt[nv.reshape(len(q), -1)[:, :1], 0])  # pad with a real triangle
        qi = np.repeat(np.arange(len(q)), cand.shape[1])
        tri = cand.ravel()
        f = self.F[tri]
        pt, bc, d = closest_point_on_triangles(q[qi], self.P[f[:, 0]], self.P[f[:, 1]], self.P[f[:, 2]])
        d = d.reshape(len(q), -1)
        j = d.argmin(axis=1)
        r = np.arange(len(q))
        sel = r * cand.shape[1] + j
        return tri[sel], bc[sel], pt[sel], d[r, j]
