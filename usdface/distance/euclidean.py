"""Euclidean distance matrices (paper Eq. 6) and the helpers every distance method shares.

Sources are points on the mesh surface, given the way :class:`usdface.mesh.Binding` stores bound
markers: the vertices of the triangle holding each point, ``(S, 3)`` int, and the point's
barycentric weights in that triangle, ``(S, 3)`` float. A source sitting on vertex ``v`` is
``(v, v, v), (1, 0, 0)``.

All distances are in mesh units.
"""
from __future__ import annotations

import warnings

import numpy as np

from ..errors import InputError, OptionError, ResourceError
from ..fileutil import format_bytes
from ..memory import available_memory  # noqa: F401  (re-exported)

__all__ = [
    "DistanceWarning",
    "fmt_bytes",
    "available_memory",
    "check_matrix_memory",
    "euclidean_at_sources",
    "euclidean_distances",
    "pairwise_euclidean",
    "source_points",
    "validate_sources",
]


class DistanceWarning(UserWarning):
    """A distance matrix was computed but some entries needed a fallback (see the message)."""


def warn(message: str) -> None:
    """Issue a :class:`DistanceWarning` attributed to the caller of the public function."""
    warnings.warn(message, DistanceWarning, stacklevel=3)


# ----------------------------------------------------------------------------------------------
# memory
# ----------------------------------------------------------------------------------------------

def fmt_bytes(n: float) -> str:
    """Bytes as a short human-readable string (``"1.2 GB"``, decimal units)."""
    return _fmt_bytes(n)


def _fmt_bytes(n: float) -> str:
    return format_bytes(n).replace("kB", "KB")


def check_matrix_memory(n_rows: int, n_cols: int, dtype=np.float64, *, what: str = "distance matrix",
                        copies: float = 1.0, memory_limit: int | None = None, extra_bytes: int = 0,
                        detail: str = "") -> int:
    """Raise ResourceError when an ``n_rows x n_cols`` matrix would not fit in memory.

    Parameters
    ----------
    n_rows, n_cols : int
        Matrix shape (vertices x sources).
    dtype : numpy dtype
        Element type; ``N * S * itemsize`` bytes per copy.
    what : str
        What the matrix is, for the message.
    copies : float
        How many such matrices the computation holds at its peak.
    memory_limit : int, optional
        Bytes allowed; default: the memory available now (:func:`available_memory`). Pass a
        small value to test the error path.
    extra_bytes : int
        Memory the computation needs besides the matrices (search tables, scratch).
    detail : str
        What the estimate is made of, for the message (e.g. ``"matrix 1.2 GB + tables 0.3 GB"``).

    Returns
    -------
    int
        The estimate, in bytes.
    """
    itemsize = np.dtype(dtype).itemsize
    estimate = int(np.ceil(float(n_rows) * float(n_cols) * itemsize * copies)) + int(extra_bytes)
    limit = available_memory() if memory_limit is None else int(memory_limit)
    if limit is not None and estimate > limit:
        hints = ["fewer markers (sources)"]
        if itemsize > 4:
            hints.append("dtype=float32 (halves it)")
        hints.append("the euclidean method (no search scratch)")
        hints.append("a coarser mesh")
        raise ResourceError(
            f"{what} of {n_rows} vertices x {n_cols} sources ({np.dtype(dtype).name}) needs about "
            f"{_fmt_bytes(estimate)}{f' ({detail})' if detail else ''} but only {_fmt_bytes(limit)} "
            f"{'is available' if memory_limit is None else 'is allowed (memory_limit)'}; "
            f"use {', or '.join(hints)}"
        )
    return estimate


# ----------------------------------------------------------------------------------------------
# sources
# ----------------------------------------------------------------------------------------------

def validate_sources(n_points: int, source_tri_vertices, source_barycentrics, *,
                     names=None) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Check and normalise surface-point sources.

    Parameters
    ----------
    n_points : int
        Number of mesh vertices N.
    source_tri_vertices : array_like, shape (S, 3), int
        Vertices of the triangle holding each source point.
    source_barycentrics : array_like, shape (S, 3), float
        Barycentric weights of each point in its triangle; non-negative, summing to 1 (checked
        to 1e-6, then renormalised).
    names : sequence of str, optional
        Source (marker) names for messages; default ``"source 0"``, ``"source 1"``...

    Returns
    -------
    tri : ndarray, shape (S, 3), int64
    bary : ndarray, shape (S, 3), float64
    names : list of str
    """
    tri = np.asarray(source_tri_vertices)
    bary = np.asarray(source_barycentrics, dtype=np.float64)
    if tri.ndim == 1 and tri.size == 3:
        tri, bary = tri.reshape(1, 3), bary.reshape(1, 3)
    if tri.ndim != 2 or tri.shape[1] != 3 or bary.shape != tri.shape:
        raise InputError(f"sources: triangle vertices {tri.shape} and barycentrics {bary.shape} must both have shape (S, 3)")
    if tri.shape[0] == 0:
        raise InputError("sources: no source points given (S = 0)")
    if not np.issubdtype(tri.dtype, np.integer):
        if not np.all(np.equal(np.mod(tri, 1), 0)):
            raise InputError("sources: triangle vertices must be integers")
    tri = tri.astype(np.int64)
    s = tri.shape[0]
    if names is None:
        names = [f"source {i}" for i in range(s)]
    else:
        names = [str(n) for n in names]
        if len(names) != s:
            raise InputError(f"sources: {len(names)} names for {s} sources")
    bad = np.flatnonzero((tri < 0).any(axis=1) | (tri >= n_points).any(axis=1))
    if bad.size:
        raise InputError(f"sources {[names[i] for i in bad[:10]]}: triangle vertex indices outside 0..{n_points - 1}")
    bad = np.flatnonzero(~np.isfinite(bary).all(axis=1) | (bary < -1e-9).any(axis=1)
                         | (np.abs(bary.sum(axis=1) - 1.0) > 1e-6))
    if bad.size:
        raise InputError(f"sources {[names[i] for i in bad[:10]]}: barycentrics must be >= 0 and sum to 1; "
                         f"got e.g. {bary[bad[0]].tolist()}")
    bary = np.clip(bary, 0.0, None)
    bary = bary / bary.sum(axis=1, keepdims=True)
    return tri, bary, names


def source_points(points, source_tri_vertices, source_barycentrics) -> np.ndarray:
    """Positions of surface-point sources.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Mesh vertex positions.
    source_tri_vertices : array_like, shape (S, 3), int
    source_barycentrics : array_like, shape (S, 3), float

    Returns
    -------
    ndarray, shape (S, 3), float64
        ``sum_k b_k * points[tri_k]``.
    """
    pts = np.asarray(points, dtype=np.float64)
    tri = np.asarray(source_tri_vertices, dtype=np.int64).reshape(-1, 3)
    bary = np.asarray(source_barycentrics, dtype=np.float64).reshape(-1, 3)
    return np.einsum("sk,skd->sd", bary, pts[tri])


# ----------------------------------------------------------------------------------------------
# Eq. 6
# ----------------------------------------------------------------------------------------------

def pairwise_euclidean(a, b, *, dtype=np.float64, out: np.ndarray | None = None) -> np.ndarray:
    """Euclidean distances between two point sets (paper Eq. 6).

    ``||p - q|| = sqrt((p_x - q_x)^2 + (p_y - q_y)^2 + (p_z - q_z)^2)``, computed coordinate by
    coordinate from differences (no ``|p|^2 + |q|^2 - 2 p.q`` cancellation: exact to rounding even
    for points far from the origin), with two ``(N, S)`` temporaries at most.

    Parameters
    ----------
    a : array_like, shape (N, 3)
    b : array_like, shape (S, 3)
    dtype : {numpy.float64, numpy.float32}
        Output type; the arithmetic is float64 either way.
    out : ndarray, shape (N, S), optional
        Where to write the result.

    Returns
    -------
    ndarray, shape (N, S)
    """
    a = np.asarray(a, dtype=np.float64).reshape(-1, 3)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 3)
    acc = np.subtract.outer(a[:, 0], b[:, 0])
    np.square(acc, out=acc)
    tmp = np.empty_like(acc)
    for k in (1, 2):
        np.subtract.outer(a[:, k], b[:, k], out=tmp)
        np.square(tmp, out=tmp)
        acc += tmp
    del tmp
    np.sqrt(acc, out=acc)
    if out is not None:
        out[...] = acc
        return out
    return acc if np.dtype(dtype) == np.float64 else acc.astype(dtype)


def euclidean_distances(points, source_tri_vertices, source_barycentrics, *, dtype=np.float64,
                        memory_limit: int | None = None) -> np.ndarray:
    """Vertex-to-source Euclidean distance matrix (paper Eq. 6).

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Mesh vertex positions, mesh units.
    source_tri_vertices : array_like, shape (S, 3), int
        Triangle vertices of each source point (a vertex source is ``(v, v, v)``).
    source_barycentrics : array_like, shape (S, 3), float
        Barycentric weights of each source point (a vertex source is ``(1, 0, 0)``).
    dtype : {numpy.float64, numpy.float32}
        Output type.
    memory_limit : int, optional
        Bytes allowed for the result (default: memory available now); ResourceError past it.

    Returns
    -------
    ndarray, shape (N, S)
        ``D[i, j] = || points[i] - source_j ||``, mesh units.
    """
    dtype = _check_dtype(dtype)
    pts = np.asarray(points, dtype=np.float64)
    tri, bary, _ = validate_sources(pts.shape[0], source_tri_vertices, source_barycentrics)
    check_matrix_memory(pts.shape[0], tri.shape[0], np.float64, what="Euclidean distance matrix",
                        copies=2.0 if np.dtype(dtype) == np.float64 else 2.5, memory_limit=memory_limit)
    return pairwise_euclidean(pts, source_points(pts, tri, bary), dtype=dtype)


def euclidean_at_sources(points, source_tri_vertices, source_barycentrics, *, dtype=np.float64) -> np.ndarray:
    """Source-to-source Euclidean distance matrix (paper Eq. 6).

    Parameters
    ----------
    points : array_like, shape (N, 3)
    source_tri_vertices, source_barycentrics : array_like, shape (S, 3)
        As in :func:`euclidean_distances`.
    dtype : {numpy.float64, numpy.float32}

    Returns
    -------
    ndarray, shape (S, S)
        Symmetric, zero diagonal, mesh units.
    """
    pts = np.asarray(points, dtype=np.float64)
    tri, bary, _ = validate_sources(pts.shape[0], source_tri_vertices, source_barycentrics)
    q = source_points(pts, tri, bary)
    return pairwise_euclidean(q, q, dtype=dtype)


def _check_dtype(dtype) -> np.dtype:
    dt = np.dtype(dtype)
    if dt not in (np.dtype(np.float64), np.dtype(np.float32)):
        raise OptionError(f"dtype must be float64 or float32; got {dt}")
    return dt
