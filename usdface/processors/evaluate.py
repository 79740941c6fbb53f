"""`usdface evaluate`: transfer quality against ground-truth expression shapes (a markdown table).

Reads a face mesh (OBJ/PLY/... or a USD mesh layer), a set of ground-truth shapes (an .npz with
``names`` (F,) and ``deltas`` (F, N, 3) in the mesh's units, optionally ``neutral`` (N, 3)) and a
marker layout (or a binding layer); for each shape, the shape's displacements at the bound marker
points are transferred back to every vertex with each distance method / RBF mode / pinned-border
variant, and the vertex errors are reported per face region (see
:mod:`usdface.evaluation.quality`). Writes nothing but the optional markdown report (``-o``).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError, OptionError

__all__ = ["load_shapes", "binding_from_layout", "evaluate_shapes", "register_cli"]


def load_shapes(path) -> tuple[list[str], np.ndarray | None, np.ndarray]:
    """Read ground-truth shapes from an .npz.

    Parameters
    ----------
    path : str or os.PathLike
        ``.npz`` with ``names`` (F,) str and ``deltas`` (F, N, 3) float (vertex displacements in
        the mesh's units); ``neutral`` (N, 3) optional.

    Returns
    -------
    names : list of str
    neutral : ndarray (N, 3) or None
    deltas : ndarray (F, N, 3) float64
    """
    from ..blendshape.rig import read_shapes_npz

    return read_shapes_npz(path)


def binding_from_layout(mesh, layout):
    """Bind a layout's markers to the mesh surface (projection; no capture needed).

    Returns
    -------
    Binding
        ``method="layout"``, identity capture transform (only the bound points matter here).
    """
    from ..mesh.binding import project_to_surface
    from ..model.mesh import Binding

    sp = project_to_surface(mesh, layout.positions(mesh))
    return Binding(names=layout.names, face_indices=sp.face_indices, triangle_vertices=sp.triangle_vertices,
                   barycentrics=sp.barycentrics, nearest_vertices=sp.nearest_vertices, residuals=sp.distances,
                   method="layout")


def _split(value) -> list[str] | None:
    if value is None:
        return None
    if isinstance(value, str):
        value = [value]
    out = []
    for v in value:
        out += [p.strip() for p in str(v).split(",") if p.strip()]
    return out or None


def evaluate_shapes(mesh_path, shapes_path, *, layout=None, binding=None, methods=None, modes=None, pins=None,
                    widths=None, backend="graph", heat=False, thin_plate=False, only=None, skip=None,
                    min_displacement_cm=0.1, region_radius_cm=1.5, hybrid_radius_cm=1.0, hybrid_sigma_cm=2.0,
                    threshold=0.6, units=None, output=None, per_shape=True) -> dict:
    """Run the quality evaluation; returns the summary (``_text`` = the markdown report).

    Parameters
    ----------
    mesh_path : path
        Mesh file (.obj, .ply, ...) or USD mesh layer; its hole regions are found if it has none.
    shapes_path : path
        Ground-truth shapes .npz (see :func:`load_shapes`), displacements in the mesh's units.
    layout, binding : path
        Exactly one: a marker layout JSON, or a binding layer (from ``usdface bind``).
    methods, modes, pins : list of str, optional
        Subsets of euclidean/geodesic/hybrid, paper/interpolate, border/none/upper (default all).
    widths : list of str, optional
        ``default`` (1.1 x the Euclidean median marker spacing: the pipeline's rule) and/or widths in cm (default: default and 2).
    backend : str
        Geodesic back-end for geodesic and hybrid.
    heat, thin_plate : bool
        Extra rows: geodesic/heat; thin-plate spline + polynomial.
    only, skip : list of str, optional
        Shape names or glob patterns to keep / drop.
    min_displacement_cm : float
        Skip shapes whose largest displacement is below this.
    region_radius_cm, hybrid_radius_cm, hybrid_sigma_cm, threshold : float
        Error-region radius; hybrid parameters.
    units : str, optional
        Units of a mesh file that has none (default cm).
    output : path, optional
        Write the markdown report here.
    per_shape : bool
        Add the per-shape table to the report.
    """
    from ..errors import MeshError
    from ..evaluation.quality import evaluate, format_report, parse_configs, select_shapes
    from ..mesh.layout import read_layout
    from ..mesh.topology import find_hole_regions
    from ..units import scale_between
    from .import_mesh import load_mesh

    if (layout is None) == (binding is None):
        raise OptionError("evaluate: give exactly one of --layout LAYOUT.json or --binding BINDING.usda")
    if not Path(mesh_path).is_file():
        raise OptionError(f"--mesh {mesh_path}: no such file")
    mesh, regions = load_mesh(mesh_path, units=units)
    if not regions:
        regions = find_hole_regions(mesh)
    if not any(r.role == "mouth" for r in regions) or not any(r.role == "eye" for r in regions):
        raise MeshError(f"mesh {mesh_path}: the evaluation needs a mouth and eye holes; regions found: "
                        f"{', '.join(r.name for r in regions) or 'none'}")
    names, neutral, deltas = load_shapes(shapes_path)
    if deltas.shape[1] != mesh.n_points:
        raise InputError(f"shapes {shapes_path} have {deltas.shape[1]} vertices, mesh {mesh_path} has {mesh.n_points}")
    if neutral is not None:
        if neutral.shape != mesh.points.shape:
            raise InputError(f"shapes {shapes_path}: neutral has shape {neutral.shape}, mesh has {mesh.points.shape}")
        size = float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
        off = float(np.abs(neutral - mesh.points).max())
        if off > 1e-3 * size:
            raise InputError(f"shapes {shapes_path}: neutral differs from mesh {mesh_path} by up to {off:.4g} "
                             f"{mesh.units or 'units'}: the shapes were made on another mesh (or other units)")
    if layout is not None:
        lay = read_layout(layout)
        bnd = binding_from_layout(mesh, lay)
    else:
        from ..usd.layers import open_stage
        from ..usd.mesh_layer import read_binding

        bnd = read_binding(open_stage(binding, what="binding"), source=str(binding))
        if bnd.triangle_vertices.max() >= mesh.n_points:
            raise OptionError(f"binding {binding} refers to vertex {int(bnd.triangle_vertices.max())} but mesh "
                              f"{mesh_path} has {mesh.n_points} points")
    cm = scale_between("cm", mesh.units or "cm")
    keep, d, skipped = select_shapes(names, deltas, min_displacement=min_displacement_cm * cm,
                                     only=_split(only), skip=_split(skip))
    if not keep:
        raise OptionError(f"no shapes left to evaluate (skipped: {', '.join(skipped) or 'none'})")
    configs = parse_configs(_split(methods), _split(modes), _split(pins), _split(widths) or ["default", "2"],
                            backend=backend, heat=heat, thin_plate=thin_plate)
    report = evaluate(mesh, regions, bnd, keep, d, configs=configs, region_radius_cm=region_radius_cm,
                      hybrid_radius_cm=hybrid_radius_cm, hybrid_sigma_cm=hybrid_sigma_cm,
                      hybrid_threshold=threshold, skipped=skipped)
    shape_cfgs = None
    if per_shape:
        # one column per method: the first interpolate row of each (else its first row)
        shape_cfgs = []
        for method in dict.fromkeys(c.method for c in configs):
            rows = [c for c in configs if c.method == method]
            shape_cfgs.append(next((c for c in rows if c.mode == "interpolate"), rows[0]))
    lines = format_report(report, shape_configs=shape_cfgs)
    summary = report.to_dict()
    summary.update({"mesh": str(mesh_path), "shapesFile": str(shapes_path),
                    "layout": None if layout is None else str(layout),
                    "binding": None if binding is None else str(binding)})
    if output is not None:
        out = _write_text(output, "\n".join(lines) + "\n")
        summary["output"] = str(out)
    summary["_text"] = lines + (["", f"wrote {summary['output']}"] if output is not None else [])
    return summary


def _write_text(path, text: str) -> Path:
    """Write ``text`` atomically (:func:`usdface.fileutil.write_text_atomic`)."""
    from ..fileutil import write_text_atomic

    path = Path(os.fspath(path))
    if not path.parent.is_dir():
        raise OptionError(f"-o {path}: folder {path.parent} does not exist")
    return write_text_atomic(path, text)


def _cmd_evaluate(args) -> dict:
    return evaluate_shapes(args.mesh, args.shapes, layout=args.layout, binding=args.binding, methods=args.methods,
                           modes=args.modes, pins=args.pins, widths=args.widths, backend=args.backend,
                           heat=args.heat, thin_plate=args.thin_plate, only=args.only, skip=args.skip,
                           min_displacement_cm=args.min_displacement, region_radius_cm=args.region_radius,
                           hybrid_radius_cm=args.hybrid_radius, hybrid_sigma_cm=args.sigma,
                           threshold=args.threshold, units=args.units, output=args.output,
                           per_shape=not args.no_per_shape)


def register_cli(subparsers) -> None:
    """Add ``usdface evaluate`` to the CLI's subparsers."""
    from ..cliargs import add_common_options

    p = subparsers.add_parser(
        "evaluate", help="transfer quality against ground-truth expression shapes (markdown table)",
        description="For each ground-truth shape, transfer its displacements at the bound marker points back to "
                    "the whole face with each distance method, RBF mode and pinned-border variant, and report the "
                    "mean/max vertex error over the face and per region (mouth, eyes, rest), in cm and as % of the "
                    "shape's mean displacement; plus the paper's claim (upper lip on jawOpen, lower lid on eyeBlink).")
    p.add_argument("--mesh", required=True, help="face mesh (.obj, .ply, ... or a USD mesh layer)")
    p.add_argument("--shapes", required=True,
                   help="ground-truth shapes .npz: names (F,), deltas (F, N, 3) in mesh units, optional neutral (N, 3)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--layout", help="marker layout JSON (usdface-layout/1)")
    src.add_argument("--binding", help="binding layer (from `usdface bind`)")
    p.add_argument("--units", choices=["mm", "cm", "dm", "m", "in", "ft"], help="units of a mesh file (default cm)")
    p.add_argument("--methods", nargs="+", metavar="M", help="euclidean geodesic hybrid (default: all)")
    p.add_argument("--modes", nargs="+", metavar="MODE", help="paper interpolate (default: both)")
    p.add_argument("--pins", nargs="+", metavar="PIN",
                   help="pinned border variants for interpolate mode: border (whole outer border, the pipeline "
                        "default), none, upper (border above the mouth corners); default: all three")
    p.add_argument("--widths", nargs="+", metavar="W",
                   help="kernel widths: 'default' (1.1 x the Euclidean median marker spacing, as `usdface run`) and/or cm values; default: default 2")
    p.add_argument("--backend", choices=["graph", "heat", "exact"], default="graph", help="geodesic back-end")
    p.add_argument("--heat", action="store_true", help="add a geodesic/heat interpolate row")
    p.add_argument("--thin-plate", action="store_true", help="add thin-plate spline + polynomial rows")
    p.add_argument("--only", nargs="+", metavar="NAME", help="evaluate only these shapes (names or glob patterns)")
    p.add_argument("--skip", nargs="+", metavar="NAME", help="skip these shapes (names or glob patterns)")
    p.add_argument("--min-displacement", type=float, default=0.1, metavar="CM",
                   help="skip shapes whose largest displacement is below this (default 0.1 cm)")
    p.add_argument("--region-radius", type=float, default=1.5, metavar="CM",
                   help="mouth / eye error regions: vertices within this of the hole loops (default 1.5 cm)")
    p.add_argument("--hybrid-radius", type=float, default=1.0, metavar="CM", help="hybrid region radius (cm)")
    p.add_argument("--sigma", type=float, default=2.0, metavar="CM", help="hybrid weight width (cm)")
    p.add_argument("--threshold", type=float, default=0.6, help="hybrid: geodesic term skipped where w <= this")
    p.add_argument("--no-per-shape", action="store_true", help="leave the per-shape table out")
    p.add_argument("-o", "--output", help="write the markdown report to this file")
    add_common_options(p)
    p.set_defaults(func=_cmd_evaluate)
