"""Exact closest points on a triangle mesh.

:class:`SurfaceLocator` builds k-d trees over triangle centroids once and answers many queries.
The candidate search is exact, not heuristic: every point of triangle ``t`` lies within ``r_t``
(its centroid-to-vertex radius) of its centroid ``c_t``, so ``dist(q, t) >= |q - c_t| - r_t``.
Given any upper bound ``d_best`` on the distance from ``q`` to the surface (from the triangles of
the k nearest centroids), the closest triangle therefore has ``|q - c_t| <= d_best + r_t``. The
triangles are grouped by radius (each class with its own tree and its own largest radius ``R_c``)
and every triangle with a centroid within ``d_best + R_c`` is examined exactly, so one large
triangle does not widen the search for all the others.
"""
from __future__ import annotations

from itertools import chain

import numpy as np
from scipy.spatial import cKDTree

from ..errors import MeshError, OptionError

__all__ = ["SurfaceLocator", "closest_points", "closest_point_on_triangles"]

#: largest coordinate a query may have (float32's range: USD stores points as float32)
_MAX_COORDINATE = float(np.finfo(np.float32).max)


def closest_point_on_triangles(q, a, b, c):
    """Exact closest point on triangles, element-wise.

    Parameters
    ----------
    q, a, b, c : ndarray, shape (K, 3), float64
        Query points and the vertices of the triangle each is tested against.

    Returns
    -------
    points : ndarray, shape (K, 3)
        Closest point of triangle ``(a, b, c)`` to ``q``.
    bary : ndarray, shape (K, 3)
        Its barycentric weights for ``(a, b, c)`` (non-negative, sum 1).
    dist : ndarray, shape (K,)
        ``|q - points|``.

    Notes
    -----
    The minimum over the interior projection (when it falls inside a non-degenerate triangle) and
    the closest points of the three edges: robust for degenerate (zero-area) triangles, which
    reduce to segments or points.
    """
    q, a, b, c = (np.asarray(x, dtype=np.float64) for x in (q, a, b, c))
    ab, ac, ap = b - a, c - a, q - a
    d00 = np.einsum("ij,ij->i", ab, ab)
    d01 = np.einsum("ij,ij->i", ab, ac)
    d11 = np.einsum("ij,ij->i", ac, ac)
    d20 = np.einsum("ij,ij->i", ap, ab)
    d21 = np.einsum("ij,ij->i", ap, ac)
    denom = d00 * d11 - d01 * d01
    ok = denom > 1e-14 * np.maximum(d00 * d11, np.finfo(float).tiny)
    safe = np.where(ok, denom, 1.0)
    v = (d11 * d20 - d01 * d21) / safe
    w = (d00 * d21 - d01 * d20) / safe
    u = 1.0 - v - w
    inside = ok & (u >= 0) & (v >= 0) & (w >= 0)
    best_bary = np.stack([u, v, w], axis=1)
    best_pt = a + v[:, None] * ab + w[:, None] * ac
    best_d2 = np.where(inside, np.einsum("ij,ij->i", q - best_pt, q - best_pt), np.inf)
    # edges ab, bc, ca: bary weights (i, j) of the segment ends
    for p0, p1, i, j in ((a, b, 0, 1), (b, c, 1, 2), (c, a, 2, 0)):
        e = p1 - p0
        ee = np.einsum("ij,ij->i", e, e)
        t = np.einsum("ij,ij->i", q - p0, e) / np.where(ee > 0, ee, 1.0)
        t = np.clip(np.where(ee > 0, t, 0.0), 0.0, 1.0)
        pt = p0 + t[:, None] * e
        d2 = np.einsum("ij,ij->i", q - pt, q - pt)
        better = d2 < best_d2
        if better.any():
            bb = np.zeros((better.sum(), 3))
            bb[:, i] = 1.0 - t[better]
            bb[:, j] = t[better]
            best_bary[better] = bb
            best_pt[better] = pt[better]
            best_d2[better] = d2[better]
    return best_pt, best_bary, np.sqrt(best_d2)


class SurfaceLocator:
    """Closest points on a triangle surface (build once, query many times).

    Parameters
    ----------
    points : ndarray, shape (N, 3), float
        Vertex positions.
    triangles : ndarray, shape (T, 3), int
        Triangle vertex indices (e.g. :meth:`FaceMesh.triangles`).
    k : int
        Number of nearest centroids examined first to get the upper bound ``d_best`` (default 8).

    Examples
    --------
    >>> loc = SurfaceLocator(mesh.points, mesh.triangles())        # doctest: +SKIP
    >>> tri, bary, pts, dist = loc.closest(queries)                 # doctest: +SKIP
    """

    def __init__(self, points, triangles, *, k: int = 8) -> None:
        pts = np.asarray(points, dtype=np.float64)
        tris = np.asarray(triangles, dtype=np.int64)
        if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] == 0:
            raise MeshError(f"SurfaceLocator: points must have shape (N>0, 3); got {pts.shape}")
        if tris.ndim != 2 or tris.shape[1] != 3 or tris.shape[0] == 0:
            raise MeshError(f"SurfaceLocator: triangles must have shape (T>0, 3); got {tris.shape}")
        if tris.min() < 0 or tris.max() >= pts.shape[0]:
            raise MeshError(f"SurfaceLocator: triangle indices outside 0..{pts.shape[0] - 1}")
        self.points = pts
        self.triangles = tris
        self._a, self._b, self._c = pts[tris[:, 0]], pts[tris[:, 1]], pts[tris[:, 2]]
        cen = (self._a + self._b + self._c) / 3.0
        rad = np.sqrt(np.max(np.stack([np.sum((v - cen) ** 2, axis=1) for v in (self._a, self._b, self._c)]), axis=0))
        self._cen, self._rad = cen, rad
        self._k = max(1, min(int(k), tris.shape[0]))
        self._all_tree = cKDTree(cen)
        # radius classes: factor-2 bins above the median radius (few classes on real meshes)
        med = float(np.median(rad)) or float(rad.max()) or 1.0
        cls = np.clip(np.ceil(np.log2(np.maximum(rad / med, 1.0))).astype(int), 0, 30)
        self._classes = []
        for c in np.unique(cls):
            members = np.flatnonzero(cls == c)
            self._classes.append((members, cKDTree(cen[members]), float(rad[members].max())))

    @property
    def n_triangles(self) -> int:
        return self.triangles.shape[0]

    def closest(self, queries, *, chunk: int = 4096):
        """Closest surface point to each query point.

        Parameters
        ----------
        queries : ndarray, shape (Q, 3), float
            Query points, same space and units as the mesh.
        chunk : int
            Queries processed together (bounds the candidate arrays' memory).

        Returns
        -------
        tri_index : ndarray, shape (Q,), int64
            Triangle holding the closest point (the lowest index among exact ties).
        barycentrics : ndarray, shape (Q, 3), float64
            Barycentric weights of the closest point for that triangle's 3 vertices.
        closest_points : ndarray, shape (Q, 3), float64
        distances : ndarray, shape (Q,), float64
            Euclidean distance from each query to its closest point (mesh units).
        """
        q = np.asarray(queries, dtype=np.float64)
        if q.ndim != 2 or q.shape[1] != 3:
            raise OptionError(f"closest(): queries must have shape (Q, 3); got {q.shape}")
        if not np.isfinite(q).all():
            raise OptionError("closest(): queries contain NaN or infinite coordinates")
        if q.size and np.abs(q).max() > _MAX_COORDINATE:
            # squared distances of such points overflow float64 and the search goes wrong
            raise OptionError(f"closest(): a query coordinate ({np.abs(q).max():.3g}) is beyond float32's range")
        n = q.shape[0]
        tri = np.empty(n, dtype=np.int64)
        bary = np.empty((n, 3))
        cp = np.empty((n, 3))
        dist = np.empty(n)
        for s in range(0, n, max(1, int(chunk))):
            sl = slice(s, min(n, s + chunk))
            tri[sl], bary[sl], cp[sl], dist[sl] = self._closest_chunk(q[sl])
        return tri, bary, cp, dist

    def _closest_chunk(self, q):
        nq = q.shape[0]
        # 1. upper bound from the k nearest centroids
        _, cand = self._all_tree.query(q, k=self._k)
        cand = cand.reshape(nq, -1)
        qi = np.repeat(np.arange(nq), cand.shape[1])
        _, _, d = closest_point_on_triangles(q[qi], self._a[cand.ravel()], self._b[cand.ravel()], self._c[cand.ravel()])
        d_best = d.reshape(nq, -1).min(axis=1)
        # 2. every triangle that could beat d_best, per radius class
        q_list, t_list = [], []
        for members, tree, rmax in self._classes:
            hits = tree.query_ball_point(q, d_best + rmax * (1 + 1e-9) + 1e-12, return_sorted=False)
            lens = np.fromiter((len(h) for h in hits), dtype=np.int64, count=nq)
            if lens.sum() == 0:
                continue
            q_list.append(np.repeat(np.arange(nq), lens))
            t_list.append(members[np.fromiter(chain.from_iterable(hits), dtype=np.int64, count=int(lens.sum()))])
        qi = np.concatenate(q_list)
        ti = np.concatenate(t_list)
        # per-triangle lower bound |q - c_t| - r_t: drop candidates that cannot beat d_best
        diff = q[qi] - self._cen[ti]
        keep = np.sqrt(np.einsum("ij,ij->i", diff, diff)) - self._rad[ti] <= d_best[qi] * (1 + 1e-12) + 1e-12
        qi, ti = qi[keep], ti[keep]
        pt, bc, d = closest_point_on_triangles(q[qi], self._a[ti], self._b[ti], self._c[ti])
        # 3. per query: smallest distance, ties -> lowest triangle index
        order = np.lexsort((ti, d, qi))
        first = np.ones(order.size, dtype=bool)
        first[1:] = qi[order][1:] != qi[order][:-1]
        pick = order[first]
        return ti[pick], bc[pick], pt[pick], d[pick]


def closest_points(points, triangles, queries):
    """One-call form of :meth:`SurfaceLocator.closest` (builds the locator each call)."""
    return SurfaceLocator(points, triangles).closest(queries)
