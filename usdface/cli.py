"""The ``usdface`` command: one entry point, one subcommand per processor.

Thin by design: parse options, call a processor, report. Every UsdFaceError becomes one line on
stderr and exit code 2; a failed `check` exits 1.
"""
from __future__ import annotations

import argparse
import json
import logging
import sys

from . import __version__
from .errors import UsdFaceError

log = logging.getLogger("usdface")


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print a machine-readable JSON summary on stdout")
    p.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    p.add_argument("-q", "--quiet", action="store_true", help="only errors")


def _capture_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("capture reading and conditioning")
    g.add_argument("--units", choices=["mm", "cm", "dm", "m", "in", "ft"],
                   help="units of the capture file when it does not declare them (CSV)")
    g.add_argument("--rate", type=float, metavar="HZ", help="capture rate when the file does not declare it")
    g.add_argument("--up-axis", choices=["Y", "Z"], help="the source's up axis (default: Z for C3D, Y otherwise)")
    g.add_argument("--stabilize", nargs="?", const="auto", metavar="auto|M1,M2,...",
                   help="remove rigid head motion: 'auto' picks the most rigid markers, or name them")
    g.add_argument("--fill-gaps", type=_positive_int, metavar="N", help="fill gaps of at most N frames")
    g.add_argument("--filter", choices=["butterworth", "savgol"], help="zero-phase noise filter")
    g.add_argument("--cutoff", type=_positive_float, default=8.0, metavar="HZ",
                   help="filter cutoff (default 8 Hz; below half the capture rate)")
    g.add_argument("--trim", nargs=2, type=int, metavar=("START", "END"),
                   help="keep frames START..END-1 (0-based frame indices of the file)")
    g.add_argument("--start-frame", type=int, metavar="F", help="time code of the first frame after trimming")
    g.add_argument("--resample", type=_positive_float, metavar="HZ", help="resample to this rate")
    g.add_argument("--neutral", default=None, metavar="FRAME|auto",
                   help="neutral frame (0-based index after trimming) or 'auto' (default: first frame)")
    _plausibility_options(p)


def _plausibility_options(p: argparse.ArgumentParser, *, capture: bool = True) -> None:
    """--allow CHECK... (every command that judges data); --keep-zeros, --drop-outliers (captures)."""
    from .capture.plausibility import CHECKS

    g = p.add_argument_group("plausibility checks (see the README's table)")
    g.add_argument("--allow", nargs="+", action="extend", type=_allow_arg, default=[], metavar="CHECK",
                   help="accept these findings: an error becomes a warning, a warning is silenced; "
                        f"checks: {', '.join(CHECKS)}")
    if capture:
        g.add_argument("--keep-zeros", action="store_true",
                       help="C3D: keep samples at exactly (0, 0, 0) as positions (default: they are gaps)")
        g.add_argument("--drop-outliers", action="store_true",
                       help="make outlier samples gaps instead of stopping (fill them with --fill-gaps N)")


def _distance_options(p: argparse.ArgumentParser, *, with_method: bool = True) -> None:
    g = p.add_argument_group("distances")
    if with_method:
        g.add_argument("--method", choices=["euclidean", "geodesic", "hybrid"], default="hybrid",
                       help="Euclidean (Eq. 6), geodesic (Eq. 7) or hybrid (Eq. 8); default hybrid")
    g.add_argument("--backend", choices=["graph", "heat", "exact"], default="graph",
                   help="geodesic back-end: shortest edge paths (the paper's), heat method, exact polyhedral")
    g.add_argument("--region-radius", type=float, default=1.0, metavar="CM",
                   help="hybrid: geodesic regions = vertices within this distance of the mouth/eye loops (cm)")
    g.add_argument("--sigma", type=float, default=2.0, metavar="CM", help="hybrid: weight width (cm)")
    g.add_argument("--threshold", type=float, default=0.6, help="hybrid: geodesic term skipped where w <= this")
    g.add_argument("--pin-border", choices=["upper", "all", "none"], default="upper",
                   help="outer border as zero-displacement centres: above the mouth corners (default; the "
                        "jaw's border moves with the jaw), all of it, or none")
    g.add_argument("--components", choices=["error", "euclidean"], default="error",
                   help="markers on different mesh components: error, or Euclidean distance across them")


def add_transfer_options(p: argparse.ArgumentParser) -> None:
    """--rbf, --kernel, --stiffness, --regularization, --polynomial (transfer, run, skel)."""
    _transfer_options(p)


def _transfer_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("transfer")
    g.add_argument("--rbf", choices=["paper", "interpolate"], default="interpolate",
                   help="paper: Eqs. 1-5 as published; interpolate: exact RBF solve (default)")
    g.add_argument("--kernel", default="gaussian",
                   choices=["gaussian", "multiquadric", "inverse_multiquadric", "thin_plate_spline", "cubic"])
    g.add_argument("--stiffness", metavar="WIDTH|JSON",
                   help="kernel width in mesh units for every marker, or a JSON file {marker: width} "
                        "(default: 1.1 x the median nearest-marker distance, about 2 cm on a face)")
    g.add_argument("--regularization", type=_regularization_arg, default="auto", metavar="LAMBDA|auto",
                   help="ridge term added to the kernel matrix (interpolate mode). auto (default): exact "
                        "interpolation unless it amplifies marker motion more than 25x (geodesic kernels can), "
                        "then the lambda with the least amplification")
    g.add_argument("--polynomial", action="store_true", help="add a linear polynomial term (interpolate mode)")


def _add_subcommands(sub) -> None:
    p = sub.add_parser("import-capture", help="import marker capture (Maya ASCII, C3D, TRC, CSV) into a capture layer",
                       description="Import marker capture (.ma, .c3d, .trc, .csv) into a .usdc capture layer "
                                   "(/Capture/Markers), optionally stabilised, gap-filled, filtered, trimmed, resampled.")
    p.add_argument("input", help="capture file")
    p.add_argument("-o", "--output", required=True, help="capture layer to write (.usdc)")
    _capture_options(p)
    _add_common(p)
    p.set_defaults(func=_cmd_import_capture)

    p = sub.add_parser("import-mesh", help="import a face mesh (OBJ, PLY, STL, OFF, USD) into a mesh layer",
                       description="Import a face mesh into a mesh layer (/Face/Geom), keeping polygons and UVs, "
                                   "with boundary loops found and holes stored as face regions.")
    p.add_argument("input", help="mesh file")
    p.add_argument("-o", "--output", required=True, help="mesh layer to write (.usdc or .usda)")
    p.add_argument("--units", choices=["mm", "cm", "dm", "m", "in", "ft"],
                   help="units of the mesh file (OBJ has none: default cm)")
    p.add_argument("--up-axis", choices=["Y", "Z"], default="Y", help="the source's up axis (Z is rotated to Y)")
    _add_common(p)
    p.set_defaults(func=_cmd_import_mesh)

    p = sub.add_parser("bind", help="bind capture markers to points on the mesh surface",
                       description="Bind each capture marker to a point on the mesh surface, from a layout file "
                                   "or by automatic alignment of the neutral marker cloud.")
    p.add_argument("--mesh", required=True, help="mesh layer (from import-mesh)")
    p.add_argument("--capture", required=True, help="capture layer (from import-capture)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--layout", help="marker layout JSON (usdface-layout/1)")
    src.add_argument("--auto", action="store_true", help="align the neutral marker cloud to the surface")
    p.add_argument("--retarget", choices=["displacement", "similarity"], default="displacement",
                   help="displacement: capture motion rotated, not scaled (the paper); similarity: also scaled")
    _plausibility_options(p, capture=False)
    p.add_argument("-o", "--output", required=True, help="binding layer to write (.usda)")
    _add_common(p)
    p.set_defaults(func=_cmd_bind)

    p = sub.add_parser("distances", help="vertex-to-marker distance matrices (euclidean, geodesic, hybrid)",
                       description="Compute the N x M vertex-to-marker and M x M marker-to-marker distance matrices "
                                   "(plus pinned constraint vertices) and store them on the mesh in an analysis layer.")
    p.add_argument("--mesh", required=True, help="mesh layer")
    p.add_argument("--binding", required=True, help="binding layer")
    _distance_options(p)
    p.add_argument("-o", "--output", required=True, help="analysis layer to write (.usdc)")
    _add_common(p)
    p.set_defaults(func=_cmd_distances)

    p = sub.add_parser("transfer", help="RBF transfer of the capture onto the face -> animated points",
                       description="Transfer the capture's marker displacements to every vertex with radial basis "
                                   "functions over a precomputed distance matrix; write time-sampled points.")
    p.add_argument("--mesh", required=True, help="mesh layer")
    p.add_argument("--capture", required=True, help="capture layer")
    p.add_argument("--binding", required=True, help="binding layer")
    p.add_argument("--analysis", required=True, help="analysis layer (from `usdface distances`)")
    p.add_argument("--method", choices=["euclidean", "geodesic", "hybrid"],
                   help="which distance matrix of the analysis layer (default: its only one)")
    _transfer_options(p)
    p.add_argument("-o", "--output", required=True, help="animation layer to write (.usdc)")
    _add_common(p)
    p.set_defaults(func=_cmd_transfer)

    p = sub.add_parser("run", help="the main job: mesh + capture -> OUTDIR/shot.usda",
                       description="Import the mesh and the capture (stabilised), bind the markers, compute the "
                                   "distances and transfer the motion; OUTDIR gets mesh.usdc capture.usdc "
                                   "binding.usda analysis.usdc anim.usdc shot.usda summary.json.")
    p.add_argument("--mesh", required=True, help="face mesh (OBJ, PLY, ... or USD)")
    p.add_argument("--capture", required=True,
                   help="capture (Maya ASCII, C3D, TRC, CSV, a capture layer, or a video of painted dots)")
    p.add_argument("--layout", help="marker layout JSON (required for a video capture)")
    p.add_argument("--auto", nargs="?", const=True, type=int, metavar="N",
                   help="bind automatically; for a video capture, --auto N finds N dots on the first frame")
    p.add_argument("--output-kind", dest="output_kind", choices=["points", "skel", "both"],
                   default="points", help="time-sampled points (anim.usdc), UsdSkel keyframes (skel.usdc), or both")
    p.add_argument("--max-influences", type=int, default=8, metavar="K", help="skel: joints per vertex (default 8)")
    g = p.add_argument_group("video capture")
    g.add_argument("--seeds", help="JSON {marker: [x, y]} of every dot on the first frame (pixels)")
    g.add_argument("--radius", type=float, nargs=2, default=(3.0, 10.0), metavar=("R1", "R2"),
                   help="dot radius range in pixels (default 3 10)")
    p.add_argument("--retarget", choices=["displacement", "similarity"], default="displacement")
    p.add_argument("--mesh-units", choices=["mm", "cm", "dm", "m", "in", "ft"], help="units of the mesh file")
    p.add_argument("--method", choices=["euclidean", "geodesic", "hybrid"], default="hybrid",
                   help="distance method (default hybrid)")
    _distance_options(p, with_method=False)
    _transfer_options(p)
    _capture_options(p)
    p.set_defaults(stabilize="auto")
    p.add_argument("--no-stabilize", dest="stabilize", action="store_const", const=None,
                   help="keep the head motion in the marker displacements")
    p.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder (created if missing)")
    _add_common(p)
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("info", help="what a layer holds: prims, markers, frames, rate, units, schemas",
                       description="Summarise a USD layer written by usdface (or any USD file).")
    p.add_argument("file")
    _add_common(p)
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser("check", help="validate a layer (USD's validators + usdface's rules); exit 1 on errors",
                       description="Run UsdValidation's validators and usdface's own schema rules on a file.")
    p.add_argument("file")
    _add_common(p)
    p.set_defaults(func=_cmd_check)

    p = sub.add_parser("preview", help="software-rendered PNG of a mesh/binding/animation layer (no GPU)",
                       description="Render a picture of the face with regions coloured and markers drawn.")
    p.add_argument("file", help="a mesh, binding, analysis, animation or shot layer")
    p.add_argument("-o", "--output", required=True, help="PNG to write")
    p.add_argument("--frame", type=float, help="time code to show (default: the layer's start)")
    p.add_argument("--frames", type=float, nargs="+", metavar="F", help="several time codes: a contact sheet")
    p.add_argument("--view", choices=["front", "left", "right", "side"], default="front")
    p.add_argument("--size", type=int, default=768, help="image size in pixels (square)")
    p.add_argument("--color", choices=["regions", "displacement", "error", "hybrid-weight", "none"], default="regions",
                   help="colour the surface by region, by displacement from the rest pose, by error against "
                        "--reference, or by the hybrid weight")
    p.add_argument("--reference", help="a layer with reference points (for --color error)")
    p.add_argument("--labels", action="store_true", help="write marker names")
    _add_common(p)
    p.set_defaults(func=_cmd_preview)

    p = sub.add_parser("plugin-path", help="print the folder to put on PXR_PLUGINPATH_NAME (for DCCs)",
                       description="Print the folder holding usdface's plugInfo.json. DCCs import their own pxr "
                                   "before any plug-in: set PXR_PLUGINPATH_NAME to this folder before starting them.")
    _add_common(p)
    p.set_defaults(func=_cmd_plugin_path)


# -- command implementations (parse -> processor -> report) ----------------------------------------

def _positive_int(value):
    try:
        n = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number > 0; got {value!r}") from None
    if n <= 0:
        raise argparse.ArgumentTypeError(f"expected a whole number > 0; got {value!r}")
    return n


def _positive_float(value):
    try:
        x = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number > 0; got {value!r}") from None
    if not x > 0:
        raise argparse.ArgumentTypeError(f"expected a number > 0; got {value!r}")
    return x


def _regularization_arg(value):
    if value == "auto":
        return value
    try:
        lam = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number >= 0 or 'auto'; got {value!r}") from None
    if not lam >= 0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0 or 'auto'; got {value!r}")
    return lam


def _allow_arg(value):
    from .capture.plausibility import parse_allow
    from .errors import OptionError

    try:
        parse_allow(value)
    except OptionError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return value


def _stabilize_arg(value):
    if value is None or value == "auto":
        return value
    return [v.strip() for v in value.split(",") if v.strip()]


def _neutral_arg(value):
    if value is None or value == "auto":
        return value
    try:
        return int(value)
    except ValueError:
        raise UsdFaceError(f"--neutral: expected a frame index or 'auto'; got {value!r}") from None


def _cmd_import_capture(args) -> dict:
    from .processors.import_capture import import_capture

    return import_capture(args.input, args.output, units=args.units, rate=args.rate, up_axis=args.up_axis,
                          stabilize=_stabilize_arg(args.stabilize), fill_gaps=args.fill_gaps, filter=args.filter,
                          cutoff=args.cutoff, trim=args.trim, start_frame=args.start_frame,
                          resample=args.resample, neutral=_neutral_arg(args.neutral), allow=args.allow,
                          keep_zeros=args.keep_zeros, drop_outliers=args.drop_outliers)


def _cmd_import_mesh(args) -> dict:
    from .processors.import_mesh import import_mesh

    return import_mesh(args.input, args.output, units=args.units, up_axis=args.up_axis)


def _cmd_bind(args) -> dict:
    from .processors.bind import bind

    return bind(args.mesh, args.capture, args.output, layout=args.layout, auto=args.auto, retarget=args.retarget,
                allow=args.allow)


def _cmd_distances(args) -> dict:
    from .processors.distances import distances

    return distances(args.mesh, args.binding, args.output, method=args.method, backend=args.backend,
                     region_radius_cm=args.region_radius, sigma_cm=args.sigma, threshold=args.threshold,
                     pin_border=args.pin_border, components=args.components)


def _cmd_transfer(args) -> dict:
    from .processors.transfer import transfer

    return transfer(args.mesh, args.capture, args.binding, args.analysis, args.output, rbf=args.rbf,
                    kernel=args.kernel, stiffness=args.stiffness, regularization=args.regularization,
                    polynomial=args.polynomial, method=args.method)


def _cmd_run(args) -> dict:
    from .processors.run import run

    return run(args.mesh, args.capture, args.output, layout=args.layout, auto=args.auto, method=args.method,
               backend=args.backend, rbf=args.rbf, kernel=args.kernel, stiffness=args.stiffness,
               regularization=args.regularization, polynomial=args.polynomial, retarget=args.retarget,
               mesh_units=args.mesh_units, units=args.units, rate=args.rate, up_axis=args.up_axis,
               stabilize=_stabilize_arg(args.stabilize), fill_gaps=args.fill_gaps, filter=args.filter,
               cutoff=args.cutoff, trim=args.trim, neutral=_neutral_arg(args.neutral),
               region_radius_cm=args.region_radius, sigma_cm=args.sigma, threshold=args.threshold,
               pin_border=args.pin_border, components=args.components, output=args.output_kind,
               seeds=args.seeds, radius=tuple(args.radius), max_influences=args.max_influences,
               resample=args.resample, start_frame=args.start_frame, allow=args.allow, keep_zeros=args.keep_zeros,
               drop_outliers=args.drop_outliers)


def _cmd_info(args) -> dict:
    from .processors.info import info

    return info(args.file)


def _cmd_check(args) -> dict:
    from .usd.validation import check_layer

    findings = check_layer(args.file)
    errors = [f for f in findings if f.severity == "error"]
    return {"file": args.file, "ok": not errors, "errors": len(errors),
            "findings": [f.__dict__ for f in findings], "_text": [str(f) for f in findings] or ["no problems found"],
            "_exit": 1 if errors else 0}


def _cmd_preview(args) -> dict:
    from .processors.preview import preview

    return preview(args.file, args.output, frame=args.frame, frames=args.frames, view=args.view,
                   size=args.size, color=args.color, reference=args.reference, labels=args.labels)


def _cmd_plugin_path(args) -> dict:
    from .usd.schemas import plugin_path

    return {"_text": [str(plugin_path())], "path": str(plugin_path())}


#: processor modules that add their own subcommands with ``register_cli(subparsers)``; each
#: subcommand's ``func(args) -> dict`` returns the summary (``_text`` lines, ``_exit`` code)
PLUGIN_COMMANDS = (
    "usdface.processors.evaluate",
    "usdface.processors.batch",
    "usdface.processors.track",
    "usdface.processors.lift",
    "usdface.processors.skel",
    "usdface.processors.acquisition",
    "usdface.processors.tissue",
)


def add_common_options(p: argparse.ArgumentParser) -> None:
    """--json, -v, -q: every subcommand has them."""
    _add_common(p)


def add_plausibility_options(p: argparse.ArgumentParser, *, capture: bool = True) -> None:
    """--allow CHECK... (and, for captures, --keep-zeros, --drop-outliers)."""
    _plausibility_options(p, capture=capture)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="usdface",
        description="Facial-animation stage processors for OpenUSD: import capture and meshes, bind markers, "
                    "compute distance matrices, transfer marker motion to the face, preview and check layers.")
    parser.add_argument("--version", action="version", version=f"usdface {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    _add_subcommands(sub)
    import importlib

    for module in PLUGIN_COMMANDS:
        importlib.import_module(module).register_cli(sub)
    return parser


def _print_summary(summary: dict, as_json: bool, quiet: bool) -> None:
    if as_json:
        print(json.dumps({k: v for k, v in summary.items() if not k.startswith("_")}, indent=2, default=str))
        return
    if quiet:
        return
    for line in summary.get("_text", []):
        print(line)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.ERROR if args.quiet else (logging.WARNING, logging.INFO, logging.DEBUG)[min(args.verbose, 2)]
    logging.basicConfig(level=level, format="usdface: %(levelname)s: %(message)s", stream=sys.stderr)
    try:
        summary = args.func(args)
    except UsdFaceError as exc:
        print(f"usdface {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"usdface {args.command}: interrupted", file=sys.stderr)
        return 130
    _print_summary(summary, args.json, args.quiet)
    return int(summary.get("_exit", 0))


if __name__ == "__main__":
    raise SystemExit(main())
