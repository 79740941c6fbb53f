"""`usdface solve`: marker capture -> weight curves on a blend-shape rig (CURVES.usdc, CSVs).

A pipeline: the capture is read and conditioned as `import-capture` does, bound as `bind` does
(judged alike) and solved on the rig in memory (:mod:`usdface.blendshape`), without the layers of
those steps. ``usdface solve --apply CURVES.csv --mesh OTHER_RIG -o OUT.usdc`` plays the curves of
one character on another whose shapes share the names.

Every output of one call is written to a temporary name and renamed into place only when all of
them are complete (:class:`usdface.fileutil.StagedOutputs`): a failure leaves nothing new.
"""
from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from ..errors import InputError, OptionError, list_names
from ..options import SolveOptions
from ..registry import Result

log = logging.getLogger("usdface")

__all__ = ["solve"]


def solve(mesh, capture=None, apply=None, *, options: SolveOptions, output, csv=None, livelink=None,
          corrective=None) -> Result:
    """Solve ``capture`` on the rig ``mesh`` (+ ``options.shapes``), or play the curves ``apply`` on it.

    Parameters
    ----------
    mesh : path (or Sdf.Layer / Usd.Stage)
        A USD mesh with UsdSkel blend shapes, or a neutral mesh with ``options.shapes`` (an ``.npz``,
        a folder of ``<shape>.obj`` or a USD rig).
    capture : path (or layer)
        Raw capture (.ma .c3d .trc .csv) or a capture layer; conditioned like `run`'s (``stabilize``
        "auto" by default; None keeps the head motion in the markers) and bound with
        ``options.layout`` or ``options.auto`` (exactly one).
    apply : path, optional
        Instead of solving: curves (a curves CSV or a CURVES.usdc) played on the rig, shapes matched
        by name (``capture``, ``layout``, ``auto`` and ``corrective`` do not apply).
    options : SolveOptions
    output : path (or layer)
        The curves layer: the mesh, its BlendShape prims and a UsdSkel animation (imports alone).
    csv, livelink : paths, optional
        The curves CSV (``frame,time,<names>``) and the Live Link Face CSV.
    corrective : path or True, optional
        A points shot: the rig's pose plus the RBF transfer of the residual (markers hit exactly);
        True names it ``<output>_corrective.usdc``. Its own shot, never layered over the curves.
    """
    from ..usd.curves_files import CurveFiles

    files = CurveFiles(output, csv, livelink)
    if apply is not None:
        given = (("--capture", capture), ("--layout", options.layout), ("--auto", options.auto),
                 ("--corrective", corrective))
        extra = [flag for flag, value in given if value]
        if extra:
            raise OptionError(f"--apply plays existing curves: {', '.join(extra)} do not apply")
        return _apply(apply, mesh, options, files)
    if capture is None:
        raise OptionError("solve: give --capture CAPTURE (or --apply CURVES to play curves on a rig)")
    return _solve(mesh, capture, options, files, corrective)


def _solve(mesh, capture, options: SolveOptions, files, corrective) -> Result:
    """Read, condition and bind the capture, solve it on the rig, write the deliverable's files."""
    from ..blendshape.report import layer_report, take_summary, take_text
    from ..blendshape.take import deliverable_curves, solve_take
    from ..capture.conditioning import condition_capture
    from ..fileutil import StagedOutputs
    from ..mesh.judged_binding import bind_and_judge
    from ..usd.curves_files import write_curve_files
    from ..usd.identity import capture_record, identity, markers_record, mesh_record
    from ..usd.inputs import load_capture
    from ..usd.layers import describe, provenance

    t0 = time.perf_counter()
    o, params, delivery = options, options.take_parameters(), options.delivery()
    if (o.layout is None) == (not o.auto):
        raise OptionError("solve: give exactly one of --layout LAYOUT.json or --auto")
    outs = _check_outputs(mesh, capture, o, files, corrective)
    rig, regions = _rig(mesh, o, livelink=files.livelink is not None)
    cap = load_capture(capture, units=o.units, rate=o.rate, up_axis=o.up_axis, keep_zeros=o.keep_zeros, allow=o.allow)
    cap, reports = condition_capture(cap, o.conditioning())
    # judged as `bind` judges a binding (face size, layout distance, fit residual, unit scale)
    binding, _, _ = bind_and_judge(rig.mesh, cap, layout=o.layout, retarget=o.retarget, allow=o.allow,
                                   mesh_name=f"mesh {describe(mesh)}", capture_name=f"capture {describe(capture)}")
    take = solve_take(rig, cap, binding, params)
    curves = deliverable_curves(rig.names, take.weights, rate=take.rate, fps=delivery.fps,
                                key_tolerance=delivery.key_tolerance, head_motion=take.head_motion)
    # D2: time code = frame index from 0 (a trimmed take too) unless --start-frame says otherwise
    start_out = 0 if o.start_frame is None else int(round(o.start_frame * curves.rate / take.rate))
    # the take conditioned, identified as the capture layer `import-capture` would write from it
    prov = provenance("solve", options=_recorded(o, params, take),
                      inputs={"mesh": mesh, "shapes": _shapes_file(o.shapes), "capture": capture, "layout": o.layout},
                      identity=identity(mesh=mesh_record(rig.mesh), markers=markers_record(binding),
                                        capture=capture_record(cap)))
    summary = take_summary(take, curves, rig, binding, output=_named(outs["-o"]), conditioning=reports)
    corrected = None
    if "--corrective" in outs:
        corrected, cinfo = _corrective(take, rig, regions, binding, fps=delivery.fps)
        summary["corrective"] = {"output": _named(outs["--corrective"]), "amplification": cinfo["amplification"],
                                 "markerResidual": "0 at the bound points (the transfer interpolates them)"}
    with StagedOutputs() as staged:
        written = write_curve_files(curves, rig, regions, _files_of(outs), staged=staged, prov=prov,
                                    report=layer_report(summary), start_frame=start_out,
                                    fill_zeros=delivery.livelink_fill_zeros)
        if corrected is not None:
            _write_corrective(outs["--corrective"], staged, rig, regions, corrected, curves=curves, start=start_out,
                              prov=dict(prov, processor="solve --corrective"))
        staged.commit()
    summary.update(written)
    summary["seconds"] = round(time.perf_counter() - t0, 3)
    summary["_text"] = take_text(summary)
    layers = {"output": outs["-o"], **({"corrective": outs["--corrective"]} if "--corrective" in outs else {})}
    return Result.from_summary(summary, layers=layers, files=_file_outputs(outs))


def _check_outputs(mesh, capture, o: SolveOptions, files, corrective) -> dict:
    """Every output checked before any work (``--corrective`` alone names the points shot after
    ``-o``), and the capture and layout files found."""
    from ..usd.layers import is_in_memory
    from ..usd.outputs import check_outputs

    if corrective is True:
        if is_in_memory(files.output):
            raise OptionError("--corrective: name the points shot to write (the curves layer is in memory)")
        corrective = Path(files.output).with_name(Path(files.output).stem + "_corrective.usdc")
    outs = check_outputs({"--mesh": mesh, "--shapes": o.shapes, "--capture": capture, "--layout": o.layout},
                         {"-o": (files.output, "usd"), "--csv": (files.csv, "csv"),
                          "--livelink": (files.livelink, "csv"), "--corrective": (corrective, "usd")})
    for label, path in (("--capture", capture), ("--layout", o.layout)):
        if path is not None and not is_in_memory(path) and not Path(path).is_file():
            raise InputError(f"{label} {path}: no such file")
    return outs


def _rig(mesh, o: SolveOptions, *, livelink: bool):
    """The rig and its regions; with a Live Link CSV to write, a rig lacking ARKit names fails
    before the work, not after it."""
    from ..usd.rig_inputs import load_rig

    rig, regions = load_rig(mesh, o.shapes, mesh_units=o.mesh_units)
    if livelink:
        from ..blendshape.csvio import check_arkit_names

        check_arkit_names(rig.names, fill_missing=o.livelink_fill_zeros, source=f"the rig {rig.source}")
    return rig, regions


def _recorded(o: SolveOptions, params, take) -> dict:
    """The solve's options as its provenance records them (usdface 0.2's keys and values)."""
    return {**params.record(), "fps": o.fps, "key_tolerance": o.key_tolerance,
            "head_motion": take.head_motion is not None, "retarget": o.retarget, "stabilize": o.stabilize,
            "trim": o.trim, "fill_gaps": o.fill_gaps, "filter": o.filter, "resample": o.resample,
            "neutral": o.neutral, "start_frame": o.start_frame, "layout": Path(o.layout).name if o.layout else None,
            "auto": bool(o.auto)}


def _corrective(take, rig, regions, binding, *, fps):
    """The corrective points (at the curves' rate) and the transfer's info."""
    from ..blendshape.corrective import corrective_points

    corrected, info = corrective_points(take, rig, regions, binding)
    if fps is not None:  # the points shot plays at the curves' rate
        from ..blendshape.curves import resample_curves

        n = corrected.shape[1]
        corrected = resample_curves(corrected.reshape(corrected.shape[0], -1), take.rate, fps).reshape(-1, n, 3)
    return corrected, info


def _write_corrective(target, staged, rig, regions, points, *, curves, start, prov) -> None:
    from ..usd.blendshape_layer import write_points_layer
    from ..usd.layers import is_in_memory

    write_points_layer(target if is_in_memory(target) else staged.path(target), mesh=rig.mesh, regions=regions,
                       points=points, rate=curves.rate, start=start, head_motion=curves.head_motion, prov=prov)


def _apply(curves_path, mesh, options: SolveOptions, files) -> Result:
    """Play solved curves (a curves CSV or a CURVES.usdc) on another rig whose shapes share names.

    Shapes of the curves the rig lacks are dropped (reported); rig shapes without a curve stay at
    0; no shared name is an error. A CURVES.usdc also brings its head motion along.
    """
    from ..blendshape.take import deliverable_curves
    from ..fileutil import StagedOutputs
    from ..usd.curves_files import read_curve_file, write_curve_files
    from ..usd.layers import provenance
    from ..usd.outputs import check_outputs

    t0 = time.perf_counter()
    o, delivery = options, options.delivery()
    outs = check_outputs({"--apply": curves_path, "--mesh": mesh, "--shapes": o.shapes},
                         {"-o": (files.output, "usd"), "--csv": (files.csv, "csv"),
                          "--livelink": (files.livelink, "csv")})
    cp = Path(curves_path)
    read = read_curve_file(cp)
    rig, regions = _rig(mesh, o, livelink=files.livelink is not None)
    w, shared, dropped = _on_rig(read, rig, cp)
    delivered = deliverable_curves(rig.names, w, rate=read.rate, fps=delivery.fps, key_tolerance=delivery.key_tolerance,
                                   head_motion=read.head_motion)
    prov = provenance("solve --apply", options={"fps": delivery.fps, "key_tolerance": delivery.key_tolerance},
                      inputs={"curves": curves_path, "mesh": mesh, "shapes": _shapes_file(o.shapes)},
                      identity=_applied_identity(cp, rig))
    start_out = int(round(read.start * delivered.rate / read.rate))
    with StagedOutputs() as staged:
        written = write_curve_files(delivered, rig, regions, _files_of(outs), staged=staged, prov=prov,
                                    report={"appliedFrom": cp.name, "dropped": dropped}, start_frame=start_out,
                                    fill_zeros=delivery.livelink_fill_zeros)
        staged.commit()
    seconds = time.perf_counter() - t0
    summary = {"output": _named(outs["-o"]), "frames": int(delivered.values.shape[0]), "rate": delivered.rate,
               "shared": shared, "dropped": dropped, "unanimated": [n for n in rig.names if n not in read.names],
               "headMotion": read.head_motion is not None, "seconds": round(seconds, 3), **written}
    summary["_text"] = [f"wrote {summary['output']}: {len(shared)} of {len(read.names)} curves applied to {rig.source} "
                        f"({rig.n_shapes} shapes), {summary['frames']} frames at {delivered.rate:g} fps"] + \
        ([f"  dropped (no such shape): {', '.join(dropped)}"] if dropped else [])
    return Result.from_summary(summary, layers={"output": outs["-o"]}, files=_file_outputs(outs))


def _applied_identity(curves_path: Path, rig) -> dict:
    """The identity of curves played on ``rig``: its mesh, and the take the curves were solved from
    when a curves layer records it (the markers were bound to another mesh: not carried)."""
    from ..usd.identity import claims_of, identity, mesh_record
    from ..usd.layers import USD_SUFFIXES

    take = claims_of(curves_path, "curves").get("capture") if curves_path.suffix.lower() in USD_SUFFIXES else None
    return identity(mesh=mesh_record(rig.mesh), capture=take)


def _on_rig(read, rig, path) -> tuple[np.ndarray, list, list]:
    """(F, K) weights of the rig's shapes from the curves read, the shared and the dropped names."""
    names, values = read.names, read.values
    shared = [n for n in names if n in rig.names]
    if not shared:
        raise InputError(f"--apply {path}: none of its {len(names)} curves ({list_names(names)}) names a shape of the "
                         f"rig {rig.source} ({list_names(rig.names)})")
    dropped = [n for n in names if n not in rig.names]
    if dropped:
        log.warning("curves for %s have no shape in %s: dropped", list_names(dropped), rig.source)
    w = np.zeros((values.shape[0], rig.n_shapes))
    for n in shared:
        w[:, rig.index(n)] = values[:, names.index(n)]
    if (w < -1e-6).any() or (w > 1 + 1e-6).any():
        log.warning("some weights of %s are outside [0, 1]; applied as they are", path)
    return w, shared, dropped


def _files_of(outs: dict):
    """The checked outputs as :class:`usdface.usd.curves_files.CurveFiles`."""
    from ..usd.curves_files import CurveFiles

    return CurveFiles(outs["-o"], outs.get("--csv"), outs.get("--livelink"))


def _file_outputs(outs: dict) -> dict:
    return {name: outs[flag] for name, flag in (("csv", "--csv"), ("livelink", "--livelink")) if flag in outs}


def _shapes_file(shapes):
    """``--shapes`` as provenance records it: a file (hashed); a folder of OBJs is not recorded."""
    return shapes if shapes and Path(shapes).is_file() else None


def _named(target) -> str:
    """An output as the summary names it: its path, or an in-memory layer's name."""
    from ..usd.layers import describe

    return describe(target)
