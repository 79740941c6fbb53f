"""`usdface distances`: vertex-to-marker distance matrices -> analysis layer (.usdc).

Centres are the bound marker points followed by constraint vertices (pinned/rigid regions, the
outer border by default) thinned to the marker spacing; the transfer keeps those at zero.
"""
from __future__ import annotations

import json
import time

import numpy as np

from ..distance.matrices import DistanceMatrix, compute_distance_matrix
from ..errors import MeshError, OptionError
from ..options import DistanceOptions
from ..registry import Result
from ..usd.layers import check_output_path, describe, open_stage, provenance


def distances(mesh_path, binding_path, *, options: DistanceOptions, output, cache=None) -> Result:
    """Compute the N x C and C x C distance matrices (``options.method``); write the analysis layer.

    ``cache`` (a :class:`usdface.cache.ContentCache`, default None: no cache) reuses matrices
    computed before for the same mesh points, topology and regions, bound points, method and
    options (one character, many takes); the analysis layer written is the same either way. Run
    times are reported in the summary only, never in the layer, so the layer is reproducible.
    """
    from ..usd.analysis_layer import write_analysis_layer
    from ..usd.identity import claims_of, identity, markers_record, mesh_record, verify
    from ..usd.mesh_layer import read_binding, read_mesh_layer

    params = options.parameters()
    method = params.method
    out = check_output_path(output, inputs={"--mesh": mesh_path, "--binding": binding_path})
    mesh, regions = read_mesh_layer(mesh_path)
    binding = read_binding(open_stage(binding_path, what="binding"), source=str(binding_path))
    mesh_rec = mesh_record(mesh)
    verify(claims_of(binding_path, "binding"), mesh=(f"mesh {describe(mesh_path)}", mesh_rec),
           remedy="bind the capture on this mesh (`usdface bind`)")
    if binding.triangle_vertices.max() >= mesh.n_points:  # a binding of usdface 0.2, unverified
        raise OptionError(f"binding {binding_path} refers to vertex {int(binding.triangle_vertices.max())} but mesh "
                          f"{mesh_path} has {mesh.n_points} points: they belong to different meshes")
    if mesh.units is None:
        raise MeshError(f"mesh {mesh_path}: units unknown (no metersPerUnit); re-import it with --units")
    options = params.record()
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
                matrix, timing = compute_distance_matrix(mesh, regions, binding, params, mesh_name=f"mesh {mesh_path}")
                _store(cache, cache_key, matrix)
                cache_status = "miss"
    else:
        matrix, timing = compute_distance_matrix(mesh, regions, binding, params, mesh_name=f"mesh {mesh_path}")
    seconds = time.perf_counter() - started
    backend = matrix.backend
    params = matrix.parameters
    cons = matrix.constraint_vertices
    # no take: the analysis (and the cache) serve every take of the character
    prov = provenance("distances", options=options, inputs={"mesh": mesh_path, "binding": binding_path},
                      identity=identity(mesh=mesh_rec, markers=markers_record(binding)))
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
    text = [f"wrote {out}: {method}{'/' + backend if backend != 'none' else ''} distances, "
                        f"{mesh.n_points} vertices x ({binding.n_markers} markers + {cons.size} constraint vertices) "
                        f"in {seconds:.2f} s{extra}"]
    return Result(layers={"output": out}, summary=summary, text=text)


def _cache_key(mesh, regions, binding, options) -> str:
    """Everything the matrices depend on: mesh points, topology, units and regions; the bound
    surface points (names, triangles, barycentrics); method and options."""
    from ..cache import content_key

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
    a = entry.arrays()
    m = entry.meta
    return DistanceMatrix(method=m["method"], backend=m["backend"], marker_names=tuple(m["markerNames"]),
                          constraint_vertices=a["constraint_vertices"], vertex_to_centre=a["vertex_to_centre"],
                          centre_to_centre=a["centre_to_centre"], parameters=json.loads(m["parameters"]),
                          hybrid_weight=a.get("hybrid_weight"))
