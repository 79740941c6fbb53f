"""`usdface distances`: vertex-to-marker distance matrices -> analysis layer (.usdc).

Centres are the bound marker points followed by constraint vertices (pinned/rigid regions, the
outer border by default) thinned to the marker spacing; the transfer keeps those at zero.
"""
from __future__ import annotations

import json
import time

import numpy as np

from ..errors import MeshError, OptionError
from ..usd.layers import check_output_path, open_stage, provenance

METHODS = ("euclidean", "geodesic", "hybrid")
#: roles whose vertices seed the hybrid's geodesic regions (paper Fig. 5: mouth and eyes)
GEODESIC_ROLES = ("mouth", "eye", "geodesic")


def distances(mesh_path, binding_path, output, *, method="hybrid", backend="graph", region_radius_cm=1.0,
              sigma_cm=2.0, threshold=0.6, pin_border="upper", components="error", t_coef="auto",
              cache=None) -> dict:
    """Compute the N x C and C x C distance matrices with ``method``; write the analysis layer.

    ``cache`` (a :class:`usdface.batch.cache.ContentCache`, default None: no cache) reuses matrices
    computed before for the same mesh points, topology and regions, bound points, method and
    options (one character, many takes); the analysis layer written is the same either way. Run
    times are reported in the summary only, never in the layer, so the layer is reproducible.
    """
    from ..units import scale_between
    from ..usd.analysis_layer import write_analysis_layer
    from ..usd.mesh_layer import read_binding, read_mesh_layer

    if method not in METHODS:
        raise OptionError(f"--method {method}: expected one of {', '.join(METHODS)}")
    out = check_output_path(output, inputs={"--mesh": mesh_path, "--binding": binding_path})
    mesh, regions = read_mesh_layer(mesh_path)
    binding = read_binding(open_stage(binding_path, what="binding"), source=str(binding_path))
    if binding.triangle_vertices.max() >= mesh.n_points:
        raise OptionError(f"binding {binding_path} refers to vertex {int(binding.triangle_vertices.max())} but mesh "
                          f"{mesh_path} has {mesh.n_points} points: they belong to different meshes")
    if mesh.units is None:
        raise MeshError(f"mesh {mesh_path}: units unknown (no metersPerUnit); re-import it with --units")
    cm = scale_between("cm", mesh.units)
    options = {"method": method, "backend": backend, "region_radius_cm": region_radius_cm, "sigma_cm": sigma_cm,
               "threshold": threshold, "pin_border": pin_border, "components": components, "t_coef": t_coef}
    started = time.perf_counter()
    cache_key = cache_status = None
    if cache is not None:
        cache_key = _cache_key(mesh, regions, binding, options)
        with cache.lock("distances", cache_key):
            entry = cache.get("distances", cache_key)
            if entry is not None:
                matrix, timing = _matrix_from_entry(entry), {}
                cache_status = "hit"
            else:
                matrix, timing = _compute(mesh, regions, binding, mesh_path, method, backend, components, t_coef,
                                          pin_border, region_radius_cm, sigma_cm, threshold, cm)
                _store(cache, cache_key, matrix)
                cache_status = "miss"
    else:
        matrix, timing = _compute(mesh, regions, binding, mesh_path, method, backend, components, t_coef,
                                  pin_border, region_radius_cm, sigma_cm, threshold, cm)
    seconds = time.perf_counter() - started
    backend = matrix.backend
    params = matrix.parameters
    cons = matrix.constraint_vertices
    prov = provenance("distances", options=options, inputs={"mesh": mesh_path, "binding": binding_path})
    write_analysis_layer(out, [matrix], mesh_path=mesh_path, units=mesh.units, prov=prov)
    summary = {"output": str(out), "method": method, "backend": backend, "vertices": mesh.n_points,
               "markers": binding.n_markers, "constraintCentres": int(cons.size), "seconds": round(seconds, 4),
               "parameters": {**params, **timing, "seconds": round(seconds, 4)}}
    if cache is not None:
        summary["cache"] = {"status": cache_status, "key": cache_key}
    extra = ""
    if method == "hybrid":
        extra = (f"; geodesic term on {params['geodesicVertices']} of {mesh.n_points} vertices "
                 f"({100 * params['geodesicFraction']:.1f}%)")
    if cache_status == "hit":
        extra += " (from the cache)"
    summary["_text"] = [f"wrote {out}: {method}{'/' + backend if backend != 'none' else ''} distances, "
                        f"{mesh.n_points} vertices x ({binding.n_markers} markers + {cons.size} constraint vertices) "
                        f"in {seconds:.2f} s{extra}"]
    return summary


def _compute(mesh, regions, binding, mesh_path, method, backend, components, t_coef, pin_border,
             region_radius_cm, sigma_cm, threshold, cm):
    """The matrices and their parameters; returns (DistanceMatrix, timings kept out of the layer)."""
    from ..distance import (GeodesicSolver, euclidean_at_sources, euclidean_distances, hybrid_distances)
    from ..mesh.regions import constraint_vertices
    from ..rbf.stiffness import median_marker_spacing_from_points
    from ..usd.analysis_layer import DistanceMatrix

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
                raise MeshError(f"mesh {mesh_path}: no mouth, eye or geodesic region for the hybrid method "
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


def _cache_key(mesh, regions, binding, options) -> str:
    """Everything the matrices depend on: mesh points, topology, units and regions; the bound
    surface points (names, triangles, barycentrics); method and options."""
    from ..batch.cache import content_key

    region_parts = []
    for r in sorted(regions, key=lambda r: r.name):
        region_parts += [r.name, r.role, np.asarray(r.indices, dtype=np.int64),
                         np.asarray(r.loop if r.loop is not None else [], dtype=np.int64)]
    return content_key("distances", np.asarray(mesh.points, dtype=np.float64),
                       np.asarray(mesh.face_vertex_counts, dtype=np.int64),
                       np.asarray(mesh.face_vertex_indices, dtype=np.int64), mesh.units, region_parts,
                       list(binding.names), np.asarray(binding.triangle_vertices, dtype=np.int64),
                       np.asarray(binding.barycentrics, dtype=np.float64), options)


def _store(cache, key, matrix) -> None:
    arrays = {"vertex_to_centre": matrix.vertex_to_centre, "centre_to_centre": matrix.centre_to_centre,
              "constraint_vertices": np.asarray(matrix.constraint_vertices, dtype=np.int64)}
    if matrix.hybrid_weight is not None:
        arrays["hybrid_weight"] = np.asarray(matrix.hybrid_weight)
    cache.put("distances", key, arrays=arrays,
              meta={"method": matrix.method, "backend": matrix.backend, "markerNames": list(matrix.marker_names),
                    "parameters": json.dumps(matrix.parameters, sort_keys=True, default=float)})


def _matrix_from_entry(entry):
    from ..usd.analysis_layer import DistanceMatrix

    a = entry.arrays()
    m = entry.meta
    return DistanceMatrix(method=m["method"], backend=m["backend"], marker_names=tuple(m["markerNames"]),
                          constraint_vertices=a["constraint_vertices"], vertex_to_centre=a["vertex_to_centre"],
                          centre_to_centre=a["centre_to_centre"], parameters=json.loads(m["parameters"]),
                          hybrid_weight=a.get("hybrid_weight"))
