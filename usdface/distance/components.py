"""Connected components of a triangle mesh straight from its triangles (no edge list).

:func:`usdface.distance.graph.connected_components` builds the unique edges first (a sort of 3T
keys: ~1 s at 560k vertices); the fast-marching back-end needs no edge list, so its solver labels
the components with a union-find over the triangles instead (tens of milliseconds). Both number
the components the same way.
"""
from __future__ import annotations

import numpy as np

from ..numba_cache import AVAILABLE, CACHE, njit

__all__ = ["triangle_components"]


def triangle_components(n_points: int, triangles) -> tuple[int, np.ndarray]:
    """Connected components of a mesh (vertices joined by triangle edges).

    Parameters
    ----------
    n_points : int
    triangles : array_like, shape (T, 3), int

    Returns
    -------
    n_components : int
    labels : ndarray, shape (N,), int64
        Component of each vertex, numbered by decreasing size (0 = largest), ties in the order of
        their lowest vertex; a vertex used by no triangle is a component of its own. The same
        labels as :func:`usdface.distance.graph.connected_components`.
    """
    t = np.ascontiguousarray(np.asarray(triangles, dtype=np.int64).reshape(-1, 3))
    if not AVAILABLE:  # pragma: no cover - numba is a dependency
        from .graph import connected_components
        return connected_components(n_points, t)
    first = _first_seen_labels(int(n_points), t)
    n = int(first.max()) + 1 if first.size else 0
    sizes = np.bincount(first, minlength=n)
    order = np.argsort(-sizes, kind="stable")
    rank = np.empty(n, dtype=np.int64)
    rank[order] = np.arange(n)
    return n, rank[first]


@njit(cache=CACHE, nogil=True)
def _root(parent, v):
    """Root of v's tree, halving the path on the way."""
    while parent[v] != v:
        parent[v] = parent[parent[v]]
        v = parent[v]
    return v


@njit(cache=CACHE, nogil=True)
def _first_seen_labels(n, t):
    """(N,) int64 component labels numbered in the order of each component's lowest vertex
    (union-find over the triangles' edges, union by index)."""
    parent = np.arange(n)
    for f in range(t.shape[0]):
        for c in range(2):
            a = _root(parent, t[f, c])
            b = _root(parent, t[f, c + 1])
            if a != b:
                if a < b:
                    parent[b] = a
                else:
                    parent[a] = b
    labels = np.empty(n, np.int64)
    count = 0
    for v in range(n):
        r = _root(parent, v)
        if r == v:              # the root is the component's lowest vertex (union by index)
            labels[v] = count
            count += 1
        else:
            labels[v] = labels[r]
    return labels
