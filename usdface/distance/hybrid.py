"""Hybrid Euclidean/geodesic distance (paper Eq. 8), computing geodesics only where needed.

``||p - q||_Hyb = w ||p - q||_Geo + (1 - w) ||p - q||_Euc`` with a per-vertex weight
``w = exp(-g^2 / sigma^2)``, g the Euclidean distance from the vertex to the nearest vertex of the
geodesic regions (w = 1 inside them). Where ``w <= threshold`` (0.6 in the paper) the geodesic
term is skipped and the distance is the Euclidean one.

Regions are the vertices within ``radius`` (Euclidean) of given seed vertex sets: the caller
passes the mouth and eye hole loops (or user regions). ``radius`` and ``sigma`` are in mesh units:
the paper's 1 cm / 2 cm become 1 / 2 for a mesh in cm, 0.01 / 0.02 in m (the caller converts).

Saving. Geodesic values are needed only at vertices with ``w > threshold`` (and, for the S x S
matrix, at sources with ``w > threshold``). With the ``"graph"`` back-end each source's search
stops as soon as every needed vertex is settled; with ``"exact"`` the MMP propagation stops at
them; the ``"heat"`` method solves over the whole mesh whatever is needed (no saving). With one
search per source (not per pair) the saving is the fraction of the mesh each search no longer
visits: a search must still reach the *farthest* needed vertex, so sources far from the mouth and
eyes still cover most of the face. :attr:`HybridResult.report` gives the fraction settled; the
benchmark measures the time against the full geodesic matrix.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError, OptionError
from .euclidean import check_matrix_memory, pairwise_euclidean, source_points, validate_sources
from .geodesic import DistanceReport, GeodesicSolver

if TYPE_CHECKING:  # annotations only: imported where used
    import scipy.spatial

__all__ = ["HybridResult", "hybrid_distances", "hybrid_weights", "region_mask"]

PAPER_THRESHOLD = 0.6


def _tree(points) -> scipy.spatial.cKDTree:
    from scipy.spatial import cKDTree  # here, not at import: only the hybrid method needs it

    # sliding-midpoint tree: median splits degrade badly on the lattice-like vertex sets of
    # refined meshes (measured 2.9 s vs 0.5 s for 185k queries at 328k vertices)
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


def _seed_indices(region_vertices, n_points: int) -> np.ndarray:
    if region_vertices is None:
        raise InputError("hybrid distance: no region vertices given (mouth/eye loops or user regions)")
    if isinstance(region_vertices, np.ndarray) and region_vertices.dtype != object:
        parts = [region_vertices.ravel()]
    else:
        parts = [np.asarray(r).ravel() for r in region_vertices]
    idx = np.unique(np.concatenate(parts).astype(np.int64)) if parts else np.zeros(0, np.int64)
    if idx.size == 0:
        raise InputError("hybrid distance: the region vertex sets are empty")
    if idx.min() < 0 or idx.max() >= n_points:
        raise InputError(f"hybrid distance: region vertex indices outside 0..{n_points - 1}")
    return idx


def region_mask(points, region_vertices, *, radius: float) -> np.ndarray:
    """Vertices within ``radius`` (Euclidean, mesh units) of the region seed vertices.

    Parameters
    ----------
    points : array_like, shape (N, 3)
    region_vertices : array_like of int, or sequence of them
        Seed vertex sets (e.g. the mouth and eye hole loops).
    radius : float
        Mesh units (paper: 1 cm).

    Returns
    -------
    ndarray, shape (N,), bool
    """
    pts = np.asarray(points, dtype=np.float64)
    seeds = _seed_indices(region_vertices, pts.shape[0])
    if not radius >= 0:
        raise OptionError(f"hybrid radius must be >= 0 (mesh units); got {radius!r}")
    d, _ = _tree(pts[seeds]).query(pts, k=1, distance_upper_bound=max(radius * (1 + 1e-9), 1e-150),
                                     workers=-1)
    return d <= radius


def hybrid_weights(points, region_vertices, *, radius: float, sigma: float,
                   query_points=None) -> tuple[np.ndarray, np.ndarray]:
    """Per-vertex hybrid weight ``w = exp(-g^2 / sigma^2)`` (paper Sec. 5.3).

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Mesh vertices, mesh units.
    region_vertices : array_like of int, or sequence of them
        Seed vertex sets; the region is every vertex within ``radius`` of them.
    radius : float
        Region radius, mesh units (paper: 1 cm).
    sigma : float
        Gaussian width, mesh units (paper code: 2 cm).
    query_points : array_like, shape (Q, 3), optional
        Weigh these points (e.g. the source points) instead of the vertices; a point within
        ``radius`` of a seed has w = 1, else g is its distance to the nearest region vertex.

    Returns
    -------
    w : ndarray, shape (N,) (or (Q,) for ``query_points``), float64
        1 inside the region, decaying with the Euclidean distance g to the nearest region vertex;
        0 where g > 8 sigma (w would be below 1.6e-28).
    inside : ndarray of bool, same shape
        Inside the region.
    """
    w, inside, wq, inside_q = _weights(points, region_vertices, radius, sigma, query_points)
    return (w, inside) if query_points is None else (wq, inside_q)


def _weights(points, region_vertices, radius, sigma, query_points=None):
    pts = np.asarray(points, dtype=np.float64)
    if not sigma > 0:
        raise OptionError(f"hybrid sigma must be > 0 (mesh units); got {sigma!r}")
    seeds = _seed_indices(region_vertices, pts.shape[0])
    inside_v = region_mask(pts, seeds, radius=radius)
    tree = _tree(pts[inside_v])
    g = np.zeros(pts.shape[0])
    # beyond 8 sigma w < exp(-64) ~ 1.6e-28: the search stops there and w is 0
    g[~inside_v] = tree.query(pts[~inside_v], k=1, distance_upper_bound=8.0 * sigma, workers=-1)[0]
    w = np.exp(-(g * g) / (sigma * sigma))
    wq = inside_q = None
    if query_points is not None:
        q = np.asarray(query_points, dtype=np.float64).reshape(-1, 3)
        ds, _ = _tree(pts[seeds]).query(q, k=1)
        inside_q = ds <= radius
        gq, _ = tree.query(q, k=1)
        gq[inside_q] = 0.0
        wq = np.exp(-(gq * gq) / (sigma * sigma))
    return w, inside_v, wq, inside_q


@dataclass
class HybridResult:
    """Hybrid distance matrices (Eq. 8) and what it took.

    Attributes
    ----------
    vertex : ndarray, shape (N, S)
        ``w_i geo_ij + (1 - w_i) euc_ij`` where ``w_i > threshold``, else ``euc_ij``; mesh units.
    sources : ndarray, shape (S, S), float64
        The same with the *row* source's weight: ``sources[i, j]`` uses ``w`` of source i, so the
        matrix is not symmetric where the two weights differ.
    weights : ndarray, shape (N,)
        w per vertex.
    source_weights : ndarray, shape (S,)
        w per source point.
    geodesic_vertices : ndarray, shape (N,), bool
        Vertices that use the geodesic term (``w > threshold``).
    geodesic : DistanceReport or None
        Report of the geodesic computation (None when no geodesic was needed).
    seconds : dict
        ``weights``, ``euclidean``, ``geodesic``, ``blend``, ``total``.
    """

    vertex: np.ndarray
    sources: np.ndarray
    weights: np.ndarray
    source_weights: np.ndarray
    geodesic_vertices: np.ndarray
    geodesic: DistanceReport | None
    seconds: dict = field(default_factory=dict)


def _blend(vertex, g, geo_v, wcol) -> None:
    """``vertex = e + wcol (g - e)`` where ``geo_v``, else ``e`` (the Euclidean ``vertex``), in place,
    in the geodesic matrix's memory order: column by column for a source-major one (graph), by
    blocks of rows for a vertex-major one (fmm). Element for element the same arithmetic either way."""
    if g.flags.c_contiguous and not g.flags.f_contiguous:
        block = 8192
        for i0 in range(0, vertex.shape[0], block):
            rows = slice(i0, i0 + block)
            e = vertex[rows]
            gj = np.where(geo_v[rows, None], g[rows], e)
            vertex[rows] = e + wcol[rows, None] * (gj - e)
        return
    for j in range(vertex.shape[1]):
        e = vertex[:, j]
        gj = np.where(geo_v, g[:, j], e)
        vertex[:, j] = e + wcol * (gj - e)


def hybrid_distances(solver: GeodesicSolver, source_tri_vertices, source_barycentrics, region_vertices, *,
                     radius: float, sigma: float, threshold: float = PAPER_THRESHOLD,
                     bounded: bool = True, names=None) -> HybridResult:
    """Hybrid distance matrices (paper Eq. 8), with geodesics only where ``w > threshold``.

    Parameters
    ----------
    solver : GeodesicSolver
        Gives the geodesic term (any back-end; ``"graph"`` is the paper's).
    source_tri_vertices, source_barycentrics : array_like, shape (S, 3)
        Surface-point sources (bound markers).
    region_vertices : array_like of int, or sequence of them
        Seed vertex sets of the geodesic regions (mouth and eye hole loops, user regions).
    radius : float
        Region radius in mesh units (paper: 1 cm).
    sigma : float
        Weight width in mesh units (paper code: 2 cm).
    threshold : float
        Geodesic term used only where ``w > threshold`` (paper: 0.6).
    bounded : bool
        Stop the geodesic searches once the needed vertices are settled (default). False computes
        the full geodesic matrix first (same result, for comparison).
    names : sequence of str, optional
        Marker names for messages.

    Returns
    -------
    HybridResult
    """
    t0 = time.perf_counter()
    pts = solver.points
    tri, bary, names = validate_sources(pts.shape[0], source_tri_vertices, source_barycentrics, names=names)
    if not 0.0 <= threshold < 1.0:
        raise OptionError(f"hybrid threshold must be in [0, 1); got {threshold!r}")
    # before any work: the geodesic computation's estimate plus the Euclidean matrix blended into
    need, detail = solver.memory_estimate(tri.shape[0])
    check_matrix_memory(pts.shape[0], tri.shape[0], solver.dtype, what=f"hybrid ({solver.backend}) distances",
                        copies=1.0, extra_bytes=need, detail=f"Euclidean matrix + {detail}",
                        memory_limit=solver.memory_limit)
    q = source_points(pts, tri, bary)
    w, _, ws, _ = _weights(pts, region_vertices, radius, sigma, q)
    geo_v = w > threshold
    geo_s = ws > threshold
    t1 = time.perf_counter()
    vertex = pairwise_euclidean(q, pts, dtype=solver.dtype).T   # (N, S), column-major like the geodesic one
    sources = pairwise_euclidean(q, q)
    t2 = time.perf_counter()
    report = None
    if geo_v.any() or geo_s.any():
        needed = geo_v.copy()
        needed[tri[geo_s].ravel()] = True   # the sink of a needed source is exact once its vertices are
        res = solver.solve(tri, bary, names=names, needed=needed if bounded else None)
        report = res.report
        t3 = time.perf_counter()
        # blend in place; rows with w <= threshold keep the Euclidean value (their geodesic entries
        # may be +inf: not searched)
        _blend(vertex, res.vertex, geo_v, np.where(geo_v, w, 0.0).astype(vertex.dtype))
        srows = np.flatnonzero(geo_s)
        wsr = ws[srows, None]
        sources[srows] = wsr * res.sources[srows] + (1.0 - wsr) * sources[srows]
    else:
        t3 = time.perf_counter()
    t4 = time.perf_counter()
    seconds = {"weights": t1 - t0, "euclidean": t2 - t1, "geodesic": t3 - t2, "blend": t4 - t3,
               "total": t4 - t0}
    return HybridResult(vertex, sources, w, ws, geo_v, report, seconds)
