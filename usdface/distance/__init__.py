"""Distance matrices between mesh vertices and surface-point sources (bound markers).

Paper (seed 000) Sec. 4.2 and 5: Euclidean (Eq. 6), geodesic mesh-based (Eq. 7) and hybrid
(Eq. 8) distances, precomputed as N x S (vertices x markers) and S x S (markers x markers)
matrices for the RBF transfer. All lengths are in mesh units.

- :func:`euclidean_distances`, :func:`euclidean_at_sources` (Eq. 6)
- :class:`GeodesicSolver` with back-ends ``"graph"`` (shortest edge paths, Eq. 7; the paper's),
  ``"fmm"`` (fast marching with exact point-source updates: 0.03-0.34 % from exact; the default),
  ``"heat"`` (potpourri3d heat method) and ``"exact"`` (pygeodesic MMP); one-call
  :func:`geodesic_distances`
- :func:`hybrid_distances`, :func:`hybrid_weights` (Eq. 8), geodesics only where ``w > 0.6``
- :mod:`usdface.distance.graph`: edge graphs, components, the multi-source search kernel
- :mod:`usdface.distance.marching`: the fast-marching kernel and its update tables
- :mod:`usdface.distance.refinement`: mesh refinement and surface-point insertion
"""
from ..lazy import lazy_exports

#: public name -> submodule, loaded on first use
_EXPORTS = {
    "DistanceWarning": "euclidean", "available_memory": "euclidean", "check_matrix_memory": "euclidean",
    "euclidean_at_sources": "euclidean", "euclidean_distances": "euclidean", "pairwise_euclidean": "euclidean",
    "source_points": "euclidean", "BACKENDS": "methods", "DEFAULT_BACKEND": "methods", "PAPER_BACKEND": "methods",
    "default_backend": "methods", "GEODESIC_ROLES": "methods", "METHODS": "methods",
    "DistanceReport": "geodesic", "GeodesicResult": "geodesic", "GeodesicSolver": "geodesic",
    "auto_t_coef": "geodesic", "geodesic_distances": "geodesic", "HybridResult": "hybrid",
    "hybrid_distances": "hybrid", "hybrid_weights": "hybrid", "region_mask": "hybrid",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())

__all__ = [
    "BACKENDS",
    "DEFAULT_BACKEND",
    "PAPER_BACKEND",
    "default_backend",
    "GEODESIC_ROLES",
    "METHODS",
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
