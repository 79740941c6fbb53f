"""Distance matrices between mesh vertices and surface-point sources (bound markers).

Paper (seed 000) Sec. 4.2 and 5: Euclidean (Eq. 6), geodesic mesh-based (Eq. 7) and hybrid
(Eq. 8) distances, precomputed as N x S (vertices x markers) and S x S (markers x markers)
matrices for the RBF transfer. All lengths are in mesh units.

- :func:`euclidean_distances`, :func:`euclidean_at_sources` (Eq. 6)
- :class:`GeodesicSolver` with back-ends ``"graph"`` (shortest edge paths, Eq. 7; the paper's,
  the default), ``"fmm"`` (fast marching with exact point-source updates: 0.03-0.34 % from exact),
  ``"heat"`` (potpourri3d heat method) and ``"exact"`` (pygeodesic MMP); one-call
  :func:`geodesic_distances`
- :func:`hybrid_distances`, :func:`hybrid_weights` (Eq. 8), geodesics only where ``w > 0.6``
- :mod:`usdface.distance.graph`: edge graphs, components, the multi-source search kernel
- :mod:`usdface.distance.marching`: the fast-marching kernel and its update tables
"""
from .euclidean import (DistanceWarning, available_memory, check_matrix_memory, euclidean_at_sources,
                        euclidean_distances, pairwise_euclidean, source_points)
from .geodesic import (BACKENDS, DEFAULT_BACKEND, DistanceReport, GeodesicResult, GeodesicSolver, auto_t_coef,
                       geodesic_distances)
from .hybrid import HybridResult, hybrid_distances, hybrid_weights, region_mask

__all__ = [
    "BACKENDS",
    "DEFAULT_BACKEND",
    "DistanceReport",
    "DistanceWarning",
    "GeodesicResult",
    "GeodesicSolver",
    "HybridResult",
    "auto_t_coef",
    "available_memory",
    "check_matrix_memory",
    "euclidean_at_sources",
    "euclidean_distances",
    "geodesic_distances",
    "hybrid_distances",
    "hybrid_weights",
    "pairwise_euclidean",
    "region_mask",
    "source_points",
]
