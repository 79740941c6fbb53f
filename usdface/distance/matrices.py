"""Distance matrices between mesh vertices and surface-point sources (bound markers and constraint
vertices): Euclidean, geodesic or hybrid (paper Eqs. 6-8), as the transfer uses them."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import MeshError
from ..units import scale_between
from .methods import DEFAULT_BACKEND, GEODESIC_ROLES

__all__ = ["DistanceMatrix", "DistanceParameters", "compute_distance_matrix"]


@dataclass(frozen=True)
class DistanceMatrix:
    """A distance matrix as stored on the mesh.

    Attributes
    ----------
    method : str  ("euclidean", "geodesic", "hybrid")
    backend : str ("none", "graph", "heat", "exact")
    marker_names : tuple of str, length M
    constraint_vertices : ndarray (P,) int64
    vertex_to_centre : ndarray (N, C) float32, C = M + P, mesh units
    centre_to_centre : ndarray (C, C) float64 (row j uses centre j's hybrid weight)
    parameters : dict
    hybrid_weight : ndarray (N,) float32 or None
    """

    method: str
    backend: str
    marker_names: tuple
    constraint_vertices: np.ndarray
    vertex_to_centre: np.ndarray
    centre_to_centre: np.ndarray
    parameters: dict
    hybrid_weight: np.ndarray | None = None


@dataclass(frozen=True)
class DistanceParameters:
    """How the matrices are computed (the options of `usdface distances` build it:
    :meth:`usdface.options.DistanceOptions.parameters`).

    ``method``: euclidean, geodesic or hybrid; ``backend``: the geodesic back-end; ``components``:
    "error" or "euclidean" across mesh components; ``t_coef``: the heat method's time step ("auto");
    ``pin_border``: upper, all or none (constraint centres on the outer border);
    ``region_radius_cm``, ``sigma_cm``, ``threshold``: the hybrid's regions and weight (Eq. 8).
    """

    method: str = "hybrid"
    backend: str = DEFAULT_BACKEND
    components: str = "error"
    t_coef: object = "auto"
    pin_border: str = "upper"
    region_radius_cm: float = 1.0
    sigma_cm: float = 2.0
    threshold: float = 0.6

    def record(self) -> dict:
        """As recorded in provenance and the cache key (usdface 0.2's names)."""
        return {"method": self.method, "backend": self.backend, "region_radius_cm": self.region_radius_cm,
                "sigma_cm": self.sigma_cm, "threshold": self.threshold, "pin_border": self.pin_border,
                "components": self.components, "t_coef": self.t_coef}


def compute_distance_matrix(mesh, regions, binding, params: DistanceParameters, *, mesh_name: str = "mesh"):
    """The N x C and C x C distance matrices of ``mesh`` to the binding's bound points and the
    constraint vertices (paper Eqs. 6-8), and their parameters.

    Parameters
    ----------
    mesh : FaceMesh
    regions : list of Region
        The mesh's regions (the hybrid's geodesic regions and the pinned border come from them).
    binding : Binding
        Markers bound to the surface (names, triangle vertices, barycentrics).
    params : DistanceParameters
    mesh_name : str
        How error messages name the mesh.

    Returns
    -------
    matrix : DistanceMatrix
        ``vertex_to_centre`` (N, C) float32 and ``centre_to_centre`` (C, C) float64, mesh units.
    timing : dict
        Wall times (seconds), kept out of the layer so that it is reproducible.
    """
    from ..mesh.regions import constraint_vertices
    from ..rbf.stiffness import median_marker_spacing_from_points
    from .euclidean import euclidean_at_sources, euclidean_distances
    from .geodesic import GeodesicSolver
    from .hybrid import hybrid_distances

    method, backend, components, t_coef = params.method, params.backend, params.components, params.t_coef
    pin_border, threshold = params.pin_border, params.threshold
    cm = scale_between("cm", mesh.units)
    region_radius_cm, sigma_cm = params.region_radius_cm, params.sigma_cm
    mesh_path = mesh_name
    started = time.perf_counter()
    timing = {}

    marker_points = binding.surface_points(mesh.points)
    spacing = median_marker_spacing_from_points(marker_points)
    cons, cons_counts = constraint_vertices(mesh.points, regions, spacing=spacing, pin_border=pin_border,
                                            exclude_near=marker_points, clearance=0.5 * spacing)
    src_tri = np.concatenate([binding.triangle_vertices, np.repeat(cons[:, None], 3, axis=1)])
    src_bary = np.concatenate([binding.barycentrics, np.tile([1.0, 0.0, 0.0], (cons.size, 1))])
    names = list(binding.names) + [f"constraint vertex {v}" for v in cons]
    params = {"constraintSpacing": spacing, "constraintRegions": cons_counts, "pinBorder": pin_border}
    weight = None
    report = None
    if method == "euclidean":
        backend = "none"
        vertex = euclidean_distances(mesh.points, src_tri, src_bary)
        centres = euclidean_at_sources(mesh.points, src_tri, src_bary)
    else:
        solver = GeodesicSolver.from_mesh(mesh, backend=backend, components=components, t_coef=t_coef)
        if method == "geodesic":
            result = solver.solve(src_tri, src_bary, names=names)
            vertex, centres, report = result.vertex, result.sources, result.report
        else:
            seeds = [r.loop if r.loop is not None else r.indices for r in regions if r.role in GEODESIC_ROLES]
            if not seeds:
                raise MeshError(f"{mesh_path}: no mouth, eye or geodesic region for the hybrid method "
                                f"(regions: {', '.join(r.name for r in regions) or 'none'}); use --method geodesic, "
                                "or add a FaceRegionAPI instance with role 'geodesic'")
            hyb = hybrid_distances(solver, src_tri, src_bary, seeds, radius=region_radius_cm * cm,
                                   sigma=sigma_cm * cm, threshold=threshold, names=names)
            vertex, centres, weight, report = hyb.vertex, hyb.sources, hyb.weights, hyb.geodesic
            params.update(regionRadius=region_radius_cm * cm, sigma=sigma_cm * cm, threshold=threshold,
                          regionSeeds=[r.name for r in regions if r.role in GEODESIC_ROLES],
                          geodesicVertices=int(hyb.geodesic_vertices.sum()),
                          geodesicFraction=float(hyb.geodesic_vertices.mean()))
            timing["hybridSeconds"] = {k: round(v, 4) for k, v in hyb.seconds.items()}
        if report is not None:
            params.update(components=report.n_components, unreachablePairs=report.unreachable_pairs,
                          euclideanFallbackPairs=report.euclidean_fallback_pairs,
                          exactInfEntries=report.exact_inf_entries, notes=list(report.notes))
            if report.t_coef:
                params["tCoef"] = {str(k): v for k, v in report.t_coef.items()}
    timing["computeSeconds"] = round(time.perf_counter() - started, 4)
    if not np.isfinite(vertex).all():
        bad = int((~np.isfinite(vertex)).sum())
        raise MeshError(f"{method} distances: {bad} entries are infinite (vertices unreachable from some markers); "
                        "use --components euclidean to fall back to Euclidean distances across components")
    matrix = DistanceMatrix(method=method, backend=backend, marker_names=tuple(binding.names),
                            constraint_vertices=cons, vertex_to_centre=np.asarray(vertex, dtype=np.float32),
                            centre_to_centre=np.asarray(centres, dtype=np.float64), parameters=params,
                            hybrid_weight=weight)
    return matrix, timing
