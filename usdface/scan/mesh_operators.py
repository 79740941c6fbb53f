"""Mesh operators of the registration (:mod:`usdface.scan.register`): boundaries, adjacency,
the uniform Laplacian, vertex normals, the hole vertices excluded from the data term, and
farthest-point sampling. Pure numpy/scipy on vertex and triangle arrays."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["boundary_vertex_mask", "boundary_edge_flags", "boundary_segments", "adjacency", "hole_vertices",
           "uniform_laplacian", "vertex_normals", "farthest_points"]


def _edges(triangles):
    """(3T, 2) directed edges of triangles (T, 3)."""
    t = np.asarray(triangles, dtype=np.int64)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    return e


def boundary_vertex_mask(n_points, triangles) -> np.ndarray:
    """(N,) True for vertices on a boundary edge (an edge used by one triangle)."""
    e = np.sort(_edges(triangles), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    mask = np.zeros(n_points, bool)
    mask[uniq[counts == 1].ravel()] = True
    return mask


def boundary_edge_flags(triangles) -> np.ndarray:
    """(T, 3) True where the triangle's edge opposite vertex k is a boundary edge."""
    t = np.asarray(triangles, dtype=np.int64)
    opp = np.concatenate([t[:, [1, 2]], t[:, [2, 0]], t[:, [0, 1]]])
    lo, hi = opp.min(axis=1), opp.max(axis=1)
    key = lo * (int(t.max()) + 1) + hi  # one int64 per undirected edge
    order = np.argsort(key, kind="stable")
    ks = key[order]
    start = np.r_[True, ks[1:] != ks[:-1]]
    run = np.cumsum(start) - 1
    counts = np.bincount(run)
    flags = np.empty(key.size, bool)
    flags[order] = counts[run] == 1
    return flags.reshape(3, -1).T


def boundary_segments(triangles, edge_flags) -> np.ndarray:
    """(E, 2) vertex pairs of the boundary edges (``edge_flags`` from :func:`boundary_edge_flags`)."""
    t = np.asarray(triangles, dtype=np.int64)
    opp = np.stack([t[:, [1, 2]], t[:, [2, 0]], t[:, [0, 1]]], axis=1)  # (T, 3, 2)
    return opp[edge_flags]


def adjacency(n, triangles) -> sp.csr_matrix:
    """(N, N) symmetric 0/1 vertex adjacency (float64 CSR) of triangles (T, 3) over ``n`` vertices."""
    e = _edges(triangles)
    A = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    A = ((A + A.T) > 0).astype(np.float64)
    return A.tocsr()


def hole_vertices(mesh, regions, *, roles=("eye", "mouth"), rings: int = 1) -> np.ndarray:
    """(N,) bool: vertices of the ``roles`` hole regions and ``rings`` rings of neighbours."""
    mask = np.zeros(mesh.n_points, bool)
    for r in regions:
        if r.role in roles:
            mask[r.indices] = True
    if rings > 0 and mask.any():
        A = adjacency(mesh.n_points, mesh.triangles())
        for _ in range(rings):
            mask = mask | (A @ mask.astype(np.float64) > 0)
    return mask


def uniform_laplacian(n, triangles) -> sp.csr_matrix:
    """(N, N) uniform Laplacian ``I - D^-1 A`` (CSR): a vertex minus the mean of its neighbours."""
    A = adjacency(n, triangles)
    deg = np.asarray(A.sum(axis=1)).ravel()
    return (sp.diags(np.ones(n)) - sp.diags(1.0 / np.maximum(deg, 1)) @ A).tocsr()


def vertex_normals(points, triangles) -> np.ndarray:
    """(N, 3) unit vertex normals: the sum of the area-weighted normals of the triangles around
    each vertex (zero for unused vertices)."""
    p = np.asarray(points)
    t = np.asarray(triangles)
    fn = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    flat = t.ravel()
    n = np.stack([np.bincount(flat, weights=np.repeat(fn[:, d], 3), minlength=len(p)) for d in range(3)], axis=1)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def farthest_points(P, m: int) -> np.ndarray:
    """Indices of ``m`` points of ``P`` spread out by farthest-point sampling (deterministic)."""
    m = min(m, len(P))
    idx = [int(np.argmin(P[:, 1]))]
    d = np.linalg.norm(P - P[idx[0]], axis=1)
    for _ in range(m - 1):
        i = int(d.argmax())
        idx.append(i)
        d = np.minimum(d, np.linalg.norm(P - P[i], axis=1))
    return np.array(idx)
