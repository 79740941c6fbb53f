"""The ``usdface`` command: one entry point, one subcommand per processor.

Thin by design: parse options, call a processor, report. Every error reaches the user as one line
on stderr (no traceback) and an exit code: 2 bad input or usage (a UsdFaceError; also argparse's
own usage errors), 1 a failure while working (environment faults included: disk full, read-only
folder, permission, out of memory, a USD error, an output folder locked by another run; a failed
`check`; a batch with a failed shot), 130 interrupted by Ctrl-C (SIGINT), 143 stopped by SIGTERM
(how farm schedulers stop jobs), both after removing the partial work.
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import signal
import sys
import threading

from . import __version__
from .cliargs import add_common_options, add_options, options_from_args
from .errors import Interrupted, UsdFaceError
from .options import COLORS, VIEWS, BindOptions, CaptureOptions, DistanceOptions, RunOptions, TransferOptions

log = logging.getLogger("usdface")


def _add_subcommands(sub) -> None:
    p = sub.add_parser("import-capture", help="import marker capture (Maya ASCII, C3D, TRC, CSV) into a capture layer",
                       description="Import marker capture (.ma, .c3d, .trc, .csv) into a .usdc capture layer "
                                   "(/Capture/Markers), optionally stabilised, gap-filled, filtered, trimmed, resampled.")
    p.add_argument("input", help="capture file")
    p.add_argument("-o", "--output", required=True, help="capture layer to write (.usdc)")
    add_options(p, CaptureOptions)
    add_common_options(p)
    p.set_defaults(func=_cmd_import_capture)

    p = sub.add_parser("import-mesh", help="import a face mesh (OBJ, PLY, STL, OFF, USD) into a mesh layer",
                       description="Import a face mesh into a mesh layer (/Face/Geom), keeping polygons and UVs, "
                                   "with boundary loops found and holes stored as face regions.")
    p.add_argument("input", help="mesh file")
    p.add_argument("-o", "--output", required=True, help="mesh layer to write (.usdc or .usda)")
    p.add_argument("--units", choices=["mm", "cm", "dm", "m", "in", "ft"],
                   help="units of the mesh file (OBJ has none: default cm)")
    p.add_argument("--up-axis", choices=["Y", "Z"], default="Y", help="the source's up axis (Z is rotated to Y)")
    add_common_options(p)
    p.set_defaults(func=_cmd_import_mesh)

    p = sub.add_parser("bind", help="bind capture markers to points on the mesh surface",
                       description="Bind each capture marker to a point on the mesh surface, from a layout file "
                                   "or by automatic alignment of the neutral marker cloud.")
    p.add_argument("--mesh", required=True, help="mesh layer (from import-mesh)")
    p.add_argument("--capture", required=True, help="capture layer (from import-capture)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--layout", help="marker layout JSON (usdface-layout/1)")
    src.add_argument("--auto", action="store_true", help="align the neutral marker cloud to the surface")
    add_options(p, BindOptions)
    p.add_argument("-o", "--output", required=True, help="binding layer to write (.usda)")
    add_common_options(p)
    p.set_defaults(func=_cmd_bind)

    p = sub.add_parser("distances", help="vertex-to-marker distance matrices (euclidean, geodesic, hybrid)",
                       description="Compute the N x M vertex-to-marker and M x M marker-to-marker distance matrices "
                                   "(plus pinned constraint vertices) and store them on the mesh in an analysis layer.")
    p.add_argument("--mesh", required=True, help="mesh layer")
    p.add_argument("--binding", required=True, help="binding layer")
    add_options(p, DistanceOptions)
    p.add_argument("-o", "--output", required=True, help="analysis layer to write (.usdc)")
    add_common_options(p)
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
    add_options(p, TransferOptions)
    add_options(p, RunOptions, only={"head_motion"})
    p.add_argument("-o", "--output", required=True, help="animation layer to write (.usdc)")
    add_common_options(p)
    p.set_defaults(func=_cmd_transfer)

    p = sub.add_parser("run", help="the main job: mesh + capture -> OUTDIR/shot.usda",
                       description="Import the mesh and the capture (stabilised), bind the markers, compute the "
                                   "distances and transfer the motion; OUTDIR gets mesh.usdc capture.usdc "
                                   "binding.usda analysis.usdc anim.usdc shot.usda summary.json.")
    p.add_argument("--mesh", required=True, help="face mesh (OBJ, PLY, ... or USD)")
    p.add_argument("--capture", required=True,
                   help="capture (Maya ASCII, C3D, TRC, CSV, a capture layer, or a video of painted dots)")
    add_options(p, RunOptions)
    p.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder (created if missing)")
    add_common_options(p)
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("info", help="what a layer holds: prims, markers, frames, rate, units, schemas",
                       description="Summarise a USD layer written by usdface (or any USD file).")
    p.add_argument("file")
    add_common_options(p)
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser("check", help="validate a layer (USD's validators + usdface's rules); exit 1 on errors",
                       description="Run UsdValidation's validators and usdface's own schema rules on a file.")
    p.add_argument("file")
    add_common_options(p)
    p.set_defaults(func=_cmd_check)

    p = sub.add_parser("preview", help="software-rendered PNG of a mesh/binding/animation layer (no GPU)",
                       description="Render a picture of the face with regions coloured and markers drawn.")
    p.add_argument("file", help="a mesh, binding, analysis, animation or shot layer")
    p.add_argument("-o", "--output", required=True, help="PNG to write")
    p.add_argument("--frame", type=float, help="time code to show (default: the layer's start)")
    p.add_argument("--frames", type=float, nargs="+", metavar="F", help="several time codes: a contact sheet")
    p.add_argument("--view", choices=VIEWS, default="front",
                   help="camera (the list playblast shares; turntable turns only in a playblast: a still is the front)")
    p.add_argument("--size", type=int, default=768, help="image size in pixels (square)")
    p.add_argument("--color", choices=COLORS, default="regions",
                   help="colour the surface by region, by displacement from the rest pose, by error against "
                        "--reference, or by the hybrid weight")
    p.add_argument("--reference", help="a layer with reference points (for --color error)")
    p.add_argument("--labels", action="store_true", help="write marker names")
    add_common_options(p)
    p.set_defaults(func=_cmd_preview)

    p = sub.add_parser("plugin-path", help="print the folder to put on PXR_PLUGINPATH_NAME (for DCCs)",
                       description="Print the folder holding usdface's plugInfo.json. DCCs import their own pxr "
                                   "before any plug-in: set PXR_PLUGINPATH_NAME to this folder before starting them.")
    add_common_options(p)
    p.set_defaults(func=_cmd_plugin_path)


# -- command implementations (parse -> processor -> report) ----------------------------------------

def _cmd_import_capture(args) -> dict:
    from .processors.import_capture import import_capture

    return import_capture(args.input, args.output, **options_from_args(CaptureOptions, args).to_dict())


def _cmd_import_mesh(args) -> dict:
    from .processors.import_mesh import import_mesh

    return import_mesh(args.input, args.output, units=args.units, up_axis=args.up_axis)


def _cmd_bind(args) -> dict:
    from .processors.bind import bind

    return bind(args.mesh, args.capture, args.output, layout=args.layout, auto=args.auto,
                **options_from_args(BindOptions, args).to_dict())


def _cmd_distances(args) -> dict:
    from .processors.distances import distances

    o = options_from_args(DistanceOptions, args)
    return distances(args.mesh, args.binding, args.output, method=o.method, backend=o.backend,
                     region_radius_cm=o.region_radius, sigma_cm=o.sigma, threshold=o.threshold,
                     pin_border=o.pin_border, components=o.components)


def _cmd_transfer(args) -> dict:
    from .processors.transfer import transfer

    return transfer(args.mesh, args.capture, args.binding, args.analysis, args.output, method=args.method,
                    head_motion=getattr(args, "head_motion", True),
                    **options_from_args(TransferOptions, args).to_dict())


def _cmd_run(args) -> dict:
    from .processors.run import run

    return run(args.mesh, args.capture, args.output, options_from_args(RunOptions, args))


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
    "usdface.processors.playblast",
    "usdface.processors.report",
    "usdface.processors.solve",
    "usdface.processors.shapes",
)


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


#: argparse destinations naming files a command writes; every other argument naming an existing
#: file is an input, and no output may be an input (usdface.fileutil.same_file_problems)
OUTPUT_DESTS = ("output", "csv", "preview", "disparity", "report", "layout_output", "summary")


def _option_labels(parser: argparse.ArgumentParser) -> dict:
    """{dest: how the user wrote it ("-o", "--mesh", "input")} for the chosen subcommand."""
    labels = {}
    todo = [parser]
    while todo:
        p = todo.pop()
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                todo.extend(action.choices.values())
            elif action.dest not in labels:
                labels[action.dest] = action.option_strings[0] if action.option_strings else action.dest
    return labels


def refuse_outputs_over_inputs(args, parser: argparse.ArgumentParser | None = None) -> None:
    """Every command: refuse (exit 2) when a file it would write is one of the files it reads."""
    from .fileutil import refuse_overwriting_inputs

    labels = _option_labels(parser) if parser is not None else {}
    outputs, inputs = {}, {}
    for dest, value in vars(args).items():
        if dest in ("func", "command"):
            continue
        label = labels.get(dest, dest)
        for v in (value if isinstance(value, list) else [value]):
            if not isinstance(v, (str, os.PathLike)) or not str(v):
                continue
            if dest in OUTPUT_DESTS:
                outputs[label] = v
            elif os.path.exists(v):
                inputs.setdefault(label, []).append(os.fspath(v))
    if outputs and inputs:
        from .usd.layers import composed_files

        for label, paths in list(inputs.items()):
            for p in paths:
                deps = composed_files(p)
                if deps:
                    inputs[f"composed by {label} {p}"] = deps
        refuse_overwriting_inputs(outputs, inputs)


class _terminate_as_interrupt:
    """SIGTERM raises :class:`~usdface.errors.Interrupted` (like Ctrl-C), so partial work is removed."""

    def __enter__(self):
        self.previous = None
        if threading.current_thread() is threading.main_thread() and hasattr(signal, "SIGTERM"):
            self.previous = signal.signal(signal.SIGTERM, self._raise)
        return self

    @staticmethod
    def _raise(signum, frame):
        raise Interrupted(signum)

    def __exit__(self, *exc):
        if self.previous is not None:
            signal.signal(signal.SIGTERM, self.previous)
        return False


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.ERROR if args.quiet else (logging.WARNING, logging.INFO, logging.DEBUG)[min(args.verbose, 2)]
    logging.basicConfig(level=level, format="usdface: %(levelname)s: %(message)s", stream=sys.stderr)
    name = f"usdface {args.command}"
    try:
        with _terminate_as_interrupt():
            refuse_outputs_over_inputs(args, parser)
            summary = args.func(args)
    except UsdFaceError as exc:
        print(f"{name}: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except Interrupted as exc:
        print(f"{name}: stopped by {exc}; partial work removed", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print(f"{name}: interrupted; partial work removed", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001 - file system, memory and USD errors: one line, exit 1
        if not isinstance(exc, (OSError, MemoryError)) and not type(exc).__module__.startswith("pxr"):
            raise  # a bug: the traceback is what a report needs
        from .fileutil import describe_exception

        print(f"{name}: error: {describe_exception(exc)}", file=sys.stderr)
        return 1
    _print_summary(summary, args.json, args.quiet)
    return int(summary.get("_exit", 0))


if __name__ == "__main__":
    raise SystemExit(main())
