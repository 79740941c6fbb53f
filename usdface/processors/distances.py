"""`usdface distances`: vertex-to-marker distance matrices -> analysis layer (.usdc).

Centres are the bound marker points followed by constraint vertices (pinned/rigid regions, the
outer border by default) thinned to the marker spacing; the transfer keeps those at zero.
"""
from __future__ import annotations

import time

import numpy as np

from ..errors import MeshError, OptionError
from ..usd.layers import check_output_path, open_stage, provenance

METHODS = ("euclidean", "geodesic", "hybrid")
#: roles whose vertices seed the hybrid's geodesic regions (paper Fig. 5: mouth and eyes)
GEODESIC_ROLES = ("mouth", "eye", "geodesic")


def distances(mesh_path, binding_path, output, *, method="hybrid", backend="graph", region_radius_cm=1.0,
              sigma_cm=2.0, threshold=0.6, pin_border="upper", components="error", t_coef="auto") -> dict:
    """Compute the N x C and C x C distance matrices with ``method``; write the analysis layer."""
    from ..distance import (GeodesicSolver, euclidean_at_sources, euclidean_distances, hybrid_distances)
    from ..mesh.regions import constraint_vertices
    from ..rbf.stiffness import median_marker_spacing_from_points
    from ..units import scale_between
    from ..usd.analysis_layer import DistanceMatrix, write_analysis_layer
    from ..usd.mesh_layer import read_binding, read_mesh_layer

    if method not in METHODS:
        raise OptionError(f"--method {method}: expected one of {', '.join(METHODS)}")
    out = check_output_path(output)
    mesh, regions = read_mesh_layer(mesh_path)
    binding = read_binding(open_stage(binding_path, what="binding"), source=str(binding_path))
    if binding.triangle_vertices.max() >= mesh.n_points:
        raise OptionError(f"binding {binding_path} refers to vertex {int(binding.triangle_vertices.max())} but mesh "
                          f"{mesh_path} has {mesh.n_points} points: they belong to different meshes")
    if mesh.units is None:
        raise MeshError(f"mesh {mesh_path}: units unknown (no metersPerUnit); re-import it with --units")
    cm = scale_between("cm", mesh.units)
    started = time.perf_counter()

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
                raise MeshError(f"mesh {mesh_path}: no mouth, eye or geodesic region for the hybrid method "
                                f"(regions: {', '.join(r.name for r in regions) or 'none'}); use --method geodesic, "
                                "or add a FaceRegionAPI instance with role 'geodesic'")
            hyb = hybrid_distances(solver, src_tri, src_bary, seeds, radius=region_radius_cm * cm,
                                   sigma=sigma_cm * cm, threshold=threshold, names=names)
            vertex, centres, weight, report = hyb.vertex, hyb.sources, hyb.weights, hyb.geodesic
            params.update(regionRadius=region_radius_cm * cm, sigma=sigma_cm * cm, threshold=threshold,
                          regionSeeds=[r.name for r in regions if r.role in GEODESIC_ROLES],
                          geodesicVertices=int(hyb.geodesic_vertices.sum()),
                          geodesicFraction=float(hyb.geodesic_vertices.mean()),
                          hybridSeconds={k: round(v, 4) for k, v in hyb.seconds.items()})
        if report is not None:
            params.update(components=report.n_components, unreachablePairs=report.unreachable_pairs,
                          euclideanFallbackPairs=report.euclidean_fallback_pairs,
                          exactInfEntries=report.exact_inf_entries, notes=list(report.notes))
            if report.t_coef:
                params["tCoef"] = {str(k): v for k, v in report.t_coef.items()}
    seconds = time.perf_counter() - started
    params["seconds"] = round(seconds, 4)
    if not np.isfinite(vertex).all():
        bad = int((~np.isfinite(vertex)).sum())
        raise MeshError(f"{method} distances: {bad} entries are infinite (vertices unreachable from some markers); "
                        "use --components euclidean to fall back to Euclidean distances across components")
    matrix = DistanceMatrix(method=method, backend=backend, marker_names=tuple(binding.names),
                            constraint_vertices=cons, vertex_to_centre=np.asarray(vertex, dtype=np.float32),
                            centre_to_centre=np.asarray(centres, dtype=np.float64), parameters=params,
                            hybrid_weight=weight)
    options = {"method": method, "backend": backend, "region_radius_cm": region_radius_cm, "sigma_cm": sigma_cm,
               "threshold": threshold, "pin_border": pin_border, "components": components, "t_coef": t_coef}
    prov = provenance("distances", options=options, inputs={"mesh": mesh_path, "binding": binding_path})
    write_analysis_layer(out, [matrix], mesh_path=mesh_path, units=mesh.units, prov=prov)
    summary = {"output": str(out), "method": method, "backend": backend, "vertices": mesh.n_points,
               "markers": binding.n_markers, "constraintCentres": int(cons.size), "seconds": round(seconds, 4),
               "parameters": params}
    extra = ""
    if method == "hybrid":
        extra = (f"; geodesic term on {params['geodesicVertices']} of {mesh.n_points} vertices "
                 f"({100 * params['geodesicFraction']:.1f}%)")
    summary["_text"] = [f"wrote {out}: {method}{'/' + backend if backend != 'none' else ''} distances, "
                        f"{mesh.n_points} vertices x ({binding.n_markers} markers + {cons.size} constraint vertices) "
                        f"in {seconds:.2f} s{extra}"]
    return summary
