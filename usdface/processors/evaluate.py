"""`usdface evaluate`: transfer quality against ground-truth expression shapes (a markdown table).

Reads a face mesh (OBJ/PLY/... or a USD mesh layer), a set of ground-truth shapes (an .npz with
``names`` (F,) and ``deltas`` (F, N, 3) in the mesh's units, optionally ``neutral`` (N, 3)) and a
marker layout (or a binding layer); for each shape, the shape's displacements at the bound marker
points are transferred back to every vertex with each distance method / RBF mode / pinned-border
variant, and the vertex errors are reported per face region (see
:mod:`usdface.evaluation.quality`). Writes nothing but the optional markdown report (``output``).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError, MeshError, OptionError
from ..options import EvaluateOptions
from ..registry import Result
from ..usd.layers import describe, is_in_memory


def evaluate(mesh_path, shapes_path, *, options: EvaluateOptions, output=None) -> Result:
    """Run the quality evaluation; the Result's text is the markdown report (also written to
    ``output`` when given).

    ``mesh_path``: a mesh file (.obj, .ply, ...) or a USD mesh layer (a path, or in memory a stage or
    layer), its hole regions found if it has none; ``shapes_path``: the ground-truth shapes .npz
    (:func:`usdface.blendshape.rig.read_shapes_npz`), displacements in the mesh's units. Exactly one
    of ``options.layout`` (a marker layout JSON) and ``options.binding`` (a binding layer) places
    the markers.
    """
    from ..evaluation.quality import (TransferSetup, evaluate as evaluate_quality, format_report, report_summary,
                                      select_shapes)
    from ..units import scale_between

    if (options.layout is None) == (options.binding is None):
        raise OptionError("evaluate: give exactly one of --layout LAYOUT.json or --binding BINDING.usda")
    if not is_in_memory(mesh_path) and not Path(mesh_path).is_file():
        raise OptionError(f"--mesh {mesh_path}: no such file")
    mesh, regions = _read_mesh(mesh_path, options.units)
    names, deltas = _read_shapes(shapes_path, mesh, mesh_path)
    binding = _binding(mesh, mesh_path, options)
    cm = scale_between("cm", mesh.units or "cm")
    keep, d, skipped = select_shapes(names, deltas, min_displacement=options.min_displacement * cm,
                                     only=options.only, skip=options.skip)
    if not keep:
        raise OptionError(f"no shapes left to evaluate (skipped: {', '.join(skipped) or 'none'})")
    configs = _configs(options)
    setup = TransferSetup(mesh, regions, binding, region_radius_cm=options.region_radius,
                          hybrid_radius_cm=options.hybrid_radius, hybrid_sigma_cm=options.sigma,
                          hybrid_threshold=options.threshold)
    report = evaluate_quality(mesh, regions, binding, keep, d, configs=configs, skipped=skipped, setup=setup)
    lines = format_report(report, shape_configs=None if options.no_per_shape else _per_shape_configs(configs))
    summary = report_summary(report)
    summary.update({"mesh": describe(mesh_path), "shapesFile": str(shapes_path),
                    "layout": None if options.layout is None else str(options.layout),
                    "binding": None if options.binding is None else str(options.binding)})
    files = {}
    if output is not None:
        out = _write_text(output, "\n".join(lines) + "\n")
        summary["output"] = files["output"] = str(out)
        lines = lines + ["", f"wrote {summary['output']}"]
    return Result(files=files, summary=summary, text=lines)


def _read_mesh(mesh_path, units):
    """(mesh, regions) with the mouth and eye holes the evaluation's regions are made from."""
    from ..mesh.topology import find_hole_regions
    from ..usd.inputs import load_mesh

    mesh, regions = load_mesh(mesh_path, units=units)
    if not regions:
        regions = find_hole_regions(mesh)
    if not any(r.role == "mouth" for r in regions) or not any(r.role == "eye" for r in regions):
        raise MeshError(f"mesh {describe(mesh_path)}: the evaluation needs a mouth and eye holes; regions found: "
                        f"{', '.join(r.name for r in regions) or 'none'}")
    return mesh, regions


def _read_shapes(shapes_path, mesh, mesh_path):
    """The shapes' names and deltas (F, N, 3), checked against the mesh (vertex count, neutral)."""
    from ..blendshape.rig import read_shapes_npz

    names, neutral, deltas = read_shapes_npz(shapes_path)
    where = describe(mesh_path)
    if deltas.shape[1] != mesh.n_points:
        raise InputError(f"shapes {shapes_path} have {deltas.shape[1]} vertices, mesh {where} has {mesh.n_points}")
    if neutral is not None:
        if neutral.shape != mesh.points.shape:
            raise InputError(f"shapes {shapes_path}: neutral has shape {neutral.shape}, mesh has {mesh.points.shape}")
        size = float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
        off = float(np.abs(neutral - mesh.points).max())
        if off > 1e-3 * size:
            raise InputError(f"shapes {shapes_path}: neutral differs from mesh {where} by up to {off:.4g} "
                             f"{mesh.units or 'units'}: the shapes were made on another mesh (or other units)")
    return names, deltas


def _binding(mesh, mesh_path, options: EvaluateOptions):
    """The markers on the mesh: the layout's projected onto the surface, or the binding layer's."""
    if options.layout is not None:
        from ..mesh.layout import read_layout
        from ..mesh.layout_binding import binding_from_layout

        return binding_from_layout(mesh, read_layout(options.layout))
    from ..usd.identity import claims_of, mesh_record, verify
    from ..usd.layers import open_stage
    from ..usd.mesh_layer import read_binding

    binding = read_binding(open_stage(options.binding, what="binding"), source=str(options.binding))
    verify(claims_of(options.binding, "binding"), mesh=(f"mesh {describe(mesh_path)}", mesh_record(mesh)),
           remedy="bind on this mesh (`usdface bind`), or place the markers with --layout")
    if binding.triangle_vertices.max() >= mesh.n_points:  # a binding of usdface 0.2, unverified
        raise OptionError(f"binding {options.binding} refers to vertex {int(binding.triangle_vertices.max())} but "
                          f"mesh {describe(mesh_path)} has {mesh.n_points} points")
    return binding


def _configs(options: EvaluateOptions) -> list:
    """The transfer configurations to measure (every method x mode x pin x width asked for)."""
    from ..evaluation.quality import parse_configs

    return parse_configs(options.methods, options.modes, options.pins, options.widths or ["default", "2"],
                         backend=options.backend, heat=options.heat, thin_plate=options.thin_plate)


def _per_shape_configs(configs) -> list:
    """One column per method in the per-shape table: the first interpolate row of each (else its
    first row)."""
    out = []
    for method in dict.fromkeys(c.method for c in configs):
        rows = [c for c in configs if c.method == method]
        out.append(next((c for c in rows if c.mode == "interpolate"), rows[0]))
    return out


def _write_text(path, text: str) -> Path:
    """Write ``text`` atomically (:func:`usdface.fileutil.write_text_atomic`)."""
    from ..fileutil import write_text_atomic

    path = Path(os.fspath(path))
    if not path.parent.is_dir():
        raise OptionError(f"-o {path}: folder {path.parent} does not exist")
    return write_text_atomic(path, text)
