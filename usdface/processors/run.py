"""`usdface run`: the main job, raw files (or USD) to a shot that plays in usdview.

import-mesh -> import-capture (stabilised) -> bind -> distances -> transfer -> shot.usda.
All files are written into a private folder inside OUTDIR and committed as a whole only when every
step has succeeded (usdface/shot_commit.py): a failed run leaves OUTDIR as it was, a crash at any
moment leaves the old shot or the new one (or an interrupted commit that the next run completes),
and OUTDIR is locked while a run writes it.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

from ..errors import EnvironmentFault, OptionError, ResourceError, UsdFaceError, WriteError
from ..options import CaptureOptions, RunOptions, SkelOptions, TransferOptions

def is_video(path) -> bool:
    """A movie file, an image-sequence pattern (name.####.png) or a folder of frames."""
    from ..io.video import MOVIE_SUFFIXES, is_sequence_pattern

    p = Path(path)
    return p.suffix.lower() in MOVIE_SUFFIXES or is_sequence_pattern(str(path)) or p.is_dir()


def output_files(output_kind=("points",), *, video: bool = False, livelink: bool = False) -> tuple:
    """The files a run writes into OUTDIR for the deliverables ``output_kind`` (RunOptions.output_kind)."""
    kinds = tuple(output_kind)
    files = ["mesh.usdc", "capture.usdc", "binding.usda", "analysis.usdc"]
    for kind in kinds:
        files.append(DELIVERABLE_LAYERS[kind])
    if "blendshapes" in kinds:
        files += ["curves.csv"] + (["curves_livelink.csv"] if livelink else [])
    if video:
        files.append("tracks.usdc")
    files += [shot for shot, _ in shot_stages(kinds)] + ["summary.json"]
    return tuple(files)


#: the layer each deliverable kind writes, and its shot stage when it is not the first kind
DELIVERABLE_LAYERS = {"points": "anim.usdc", "skel": "skel.usdc", "blendshapes": "blendshapes.usdc"}
DELIVERABLE_SHOTS = {"points": "shot.usda", "skel": "shot_skel.usda", "blendshapes": "shot_blendshapes.usda"}


def shot_stages(output_kind) -> list[tuple[str, str]]:
    """(shot stage, deliverable layer) pairs: the first deliverable's shot is shot.usda."""
    return [("shot.usda" if i == 0 else DELIVERABLE_SHOTS[kind], DELIVERABLE_LAYERS[kind])
            for i, kind in enumerate(output_kind)]


def _check_rig(mesh, o: RunOptions) -> None:
    """--output-kind blendshapes needs a rig: --shapes, or a USD mesh with UsdSkel blend shapes."""
    from .solve import load_rig

    try:
        load_rig(mesh, o.shapes, mesh_units=o.mesh_units)
    except UsdFaceError as exc:
        hint = "" if o.shapes else (" (--output-kind blendshapes and all solve weight curves on a blend-shape rig; "
                                    "without one, list the kinds you want, e.g. --output-kind points,skel)")
        raise type(exc)(f"{exc}{hint}") from None


def run(mesh, capture, out_dir, options: RunOptions | dict | None = None, *, cache=None) -> dict:
    """Run the whole pipeline; returns the summary (also written to OUTDIR/summary.json).

    Parameters
    ----------
    mesh, capture : path
        The face mesh (OBJ, PLY, ... or a USD mesh layer) and the capture (Maya ASCII, C3D, TRC,
        CSV, a capture layer, or a video of painted dots: movie, ``name.####.ext`` or a folder of
        frames).
    out_dir : path
        OUTDIR, created if missing; gets the files of :func:`output_files`.
    options : RunOptions or dict, optional
        Every option of `usdface run` (:class:`usdface.options.RunOptions`; a dict is turned into
        one). ``output_kind`` picks the deliverables: points (anim.usdc), skel (skel.usdc); the
        first one's shot stage is shot.usda, the others get shot_<kind>.usda.
    cache : usdface.batch.cache.ContentCache, optional
        Reuses imported captures and distance matrices computed before; the layers written are the
        same either way.

    The summary's ``provenance`` (:func:`run_provenance`) records the usdface version, the options
    and the input files' names and sha256, so a batch can tell whether OUTDIR is current. A video
    capture is tracked (``seeds`` or ``auto`` = N dots, ``radius`` in px) into OUTDIR/tracks.usdc
    and lifted onto the mesh through ``layout``.
    """
    from .bind import bind
    from .distances import distances
    from .import_capture import import_capture
    from .import_mesh import import_mesh
    from .transfer import transfer
    from ..usd.analysis_layer import write_shot_stage

    if options is None:
        options = RunOptions()
    elif not isinstance(options, RunOptions):
        options = RunOptions.from_mapping(options, what="run options")
    o = options
    kinds = o.output_kind
    video = is_video(capture)
    if video:
        if o.layout is None:
            raise OptionError(f"--capture {capture} is a video: give --layout LAYOUT.json (it names the markers and "
                              "places them on the mesh; 2D tracks cannot be bound automatically)")
        track_auto = o.auto if (o.auto is not True and o.auto) else None
        if (o.seeds is None) == (track_auto is None):
            raise OptionError(f"--capture {capture} is a video: give --seeds SEEDS.json or --auto N (the number of "
                              "dots to find on the first frame)")
    else:
        if o.auto not in (True, False):
            raise OptionError(f"--auto {o.auto}: a number of markers applies to video captures only")
        if (o.layout is None) == (not o.auto):
            raise OptionError("run: give exactly one of --layout LAYOUT.json or --auto")
    for label, path in (("--mesh", mesh), ("--capture", None if video else capture), ("--layout", o.layout),
                        ("--seeds", o.seeds)):
        if path is not None and not Path(path).is_file():
            raise OptionError(f"{label} {path}: no such file")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise OptionError(f"-o {out}: exists and is not a folder")
    from .transfer import parse_stiffness

    parse_stiffness(o.stiffness)  # a bad --stiffness fails now, not after the distances
    if "blendshapes" in kinds:
        _check_rig(mesh, o)  # before any work
    files = output_files(kinds, video=video, livelink=o.livelink)
    from ..shot_commit import ShotSession, check_run_paths, run_id

    stiffness_file = o.stiffness if isinstance(o.stiffness, str) and Path(o.stiffness).is_file() else None
    inputs = {"--mesh": mesh, "--capture": capture, "--layout": o.layout, "--seeds": o.seeds,
              "--stiffness": stiffness_file, "--shapes": o.shapes}
    check_run_paths(out, files, inputs)  # no output is an input, before any work
    prov = run_provenance(mesh, capture, o)
    created = [d for d in [out, *out.parents] if not d.exists()]
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        from ..fileutil import write_error

        raise write_error(out, exc) from None
    started = time.perf_counter()
    steps: dict = {}
    session = ShotSession(out, run_id(prov), inputs=inputs)
    try:
        work = session.open()  # locks OUTDIR, completes an interrupted commit, removes dead runs' temporaries
    except BaseException:
        _remove_created(created, out)
        raise
    capture_kw = o.group(CaptureOptions).to_dict()
    try:
        f = {name: work / name for name in files}
        steps["import-mesh"] = import_mesh(mesh, f["mesh.usdc"], units=o.mesh_units)
        if video:
            from .lift import lift
            from .track import track

            steps["track"] = track(capture, f["tracks.usdc"], seeds=o.seeds, auto=track_auto, layout=o.layout,
                                   mesh=mesh, radius=tuple(o.radius), rate=o.rate)
            lifted = work / "lifted.usdc"
            steps["lift"] = lift(f["tracks.usdc"], f["mesh.usdc"], lifted, layout=o.layout,
                                 neutral=None if o.neutral == "auto" else o.neutral, allow=o.allow)
            # the lifted capture still holds the head's motion in the image: condition it like any take
            # (its units, rate and neutral come from the tracks)
            for key in ("units", "rate", "up_axis", "neutral"):
                capture_kw.pop(key)
            steps["import-capture"] = import_capture(lifted, f["capture.usdc"], **capture_kw)
        else:
            steps["import-capture"] = import_capture(capture, f["capture.usdc"], cache=cache, **capture_kw)
        steps["bind"] = bind(f["mesh.usdc"], f["capture.usdc"], f["binding.usda"], layout=o.layout,
                             auto=bool(o.auto) and not video, retarget=o.retarget, allow=o.allow)
        steps["distances"] = distances(f["mesh.usdc"], f["binding.usda"], f["analysis.usdc"], method=o.method,
                                       backend=o.backend, region_radius_cm=o.region_radius, sigma_cm=o.sigma,
                                       threshold=o.threshold, pin_border=o.pin_border, components=o.components,
                                       cache=cache)
        transfer_options = dict(o.group(TransferOptions).to_dict(), method=o.method)
        if "anim.usdc" in f:
            steps["transfer"] = transfer(f["mesh.usdc"], f["capture.usdc"], f["binding.usda"],
                                         f["analysis.usdc"], f["anim.usdc"], head_motion=o.head_motion,
                                         **transfer_options)
        if "skel.usdc" in f:
            from .skel import skel

            steps["skel"] = skel(f["mesh.usdc"], f["capture.usdc"], f["binding.usda"], f["analysis.usdc"],
                                 f["skel.usdc"], head_motion=o.head_motion, **o.group(SkelOptions).to_dict(),
                                 **transfer_options)
        if "blendshapes.usdc" in f:
            from .solve import solve_shot

            # the rig: the imported mesh with --shapes (same points), else the input mesh's own blend shapes
            steps["blendshapes"] = solve_shot(f["mesh.usdc"] if o.shapes else mesh, f["capture.usdc"],
                                              f["binding.usda"], work, shapes=o.shapes, mesh_units=o.mesh_units,
                                              fps=o.fps, key_tolerance=o.key_tolerance, head_motion=o.head_motion,
                                              livelink=o.livelink, livelink_fill_zeros=o.livelink_fill_zeros,
                                              files=("blendshapes.usdc", None, "curves.csv"), **o.solver_kwargs())
        cap = steps["import-capture"]
        record = session.record(files)  # the shot stages list every file's sha256 and provenance id
        for shot_name, layer in shot_stages(kinds):
            if layer == "blendshapes.usdc":  # its own rate and range when the curves were resampled (--fps)
                st = steps["blendshapes"]["shotStage"]
                write_shot_stage(f[shot_name], layers=[f[layer], f["binding.usda"]], rate=st["rate"],
                                 start=st["start"], end=st["end"], units=steps["import-mesh"]["units"],
                                 stabilized_capture=st["stabilizedCapture"], record=record)
                continue
            write_shot_stage(f[shot_name], layers=[f[layer], f["analysis.usdc"], f["binding.usda"]],
                             rate=cap["rate"], start=cap["startTimeCode"],
                             end=cap["startTimeCode"] + cap["frames"] - 1, units=steps["import-mesh"]["units"],
                             # markers follow the face: head-stabilised unless the head motion is delivered
                             stabilized_capture=cap["stabilized"] and not o.head_motion, record=record)
        summary = {
            "outputDir": str(out), "shot": str(out / "shot.usda"), "mesh": str(mesh), "capture": str(capture),
            "method": o.method, "backend": o.backend if o.method != "euclidean" else None, "rbf": o.rbf,
            "kernel": o.kernel, "outputKind": list(kinds),
            "frames": cap["frames"], "rate": cap["rate"], "markers": cap["markers"],
            "vertices": steps["import-mesh"]["points"],
            "steps": {k: {kk: vv for kk, vv in v.items() if not kk.startswith("_")} for k, v in steps.items()},
            "seconds": round(time.perf_counter() - started, 3),
            "provenance": prov, "runId": session.run_id, "files": list(files),
        }
        # paths in the summary name the final files, not the private work folder
        text = json.dumps(summary, indent=2, default=str).replace(str(work), str(out))
        session.write_text("summary.json", text + "\n")
        session.commit(files)
    except UsdFaceError as exc:
        step = next(reversed(steps), None)
        failed = _next_step(step, video=video, output_kind=kinds)
        message = str(exc).replace(str(work) + os.sep, str(out) + os.sep).replace(str(work), str(out))
        raise type(exc)(f"{failed} step failed: {message}") from None
    except Exception as exc:  # noqa: BLE001 - file system, memory and USD errors become one line
        from ..fileutil import describe_exception

        if not isinstance(exc, (OSError, MemoryError)) and not type(exc).__module__.startswith("pxr"):
            raise
        step = _next_step(next(reversed(steps), None), video=video, output_kind=kinds)
        message = describe_exception(exc).replace(str(work) + os.sep, str(out) + os.sep).replace(str(work), str(out))
        kind = ResourceError if isinstance(exc, MemoryError) else WriteError if isinstance(exc, OSError) \
            else EnvironmentFault
        raise kind(f"{step} step failed: {message}") from None
    finally:
        session.close()
        _remove_created(created, out)
    summary = json.loads(text)
    b = summary["steps"]["bind"]
    tr = summary["steps"].get("transfer") or summary["steps"].get("skel")
    bs = summary["steps"].get("blendshapes")
    summary["_text"] = [
        f"shot: {out / 'shot.usda'}  ({summary['frames']} frames at {summary['rate']:g} Hz, "
        f"{summary['vertices']} vertices, {summary['markers']} markers)",
        f"  capture: {cap['markers']} markers, {cap['invalidSamples']} invalid samples, "
        f"stabilised: {'yes' if cap['stabilized'] else 'no'}",
        f"  binding: {b['method']}, {'fit ' if b['method'] == 'layout' else ''}residual median "
        f"{b['residualMedian']:.3f} max {b['residualMax']:.3f} {b['units']}",
        f"  distances: {o.method}{'/' + o.backend if o.method != 'euclidean' else ''} in "
        f"{summary['steps']['distances']['seconds']:.2f} s",
    ] + ([f"  transfer: {tr['mode']} {tr['kernel']}, {tr['seconds']:.2f} s"
          + (f", width {tr['widthMedian']:.3g} {tr['units']}" if "widthMedian" in tr else "")] if tr else []) \
      + ([f"  blend shapes: {bs['shapes']} shapes, marker residual mean {bs['residualMean'] or float('nan'):.3f} "
          f"(a still face: {bs['stillResidualMean'] or float('nan'):.3f}), curves at {bs['shotStage']['rate']:g} fps"]
         if bs else []) + ([f"  video: {summary['steps']['track']['frames']} frames tracked, "
          f"{100 * summary['steps']['track']['validFraction']:.1f}% of marker samples found, lifted with depth "
          f"{summary['steps']['lift']['depth']}"] if video else []) \
      + ([_skel_line(summary["steps"]["skel"])] if "skel" in summary["steps"] else []) \
      + [f"  total {summary['seconds']:.1f} s; files: {', '.join(files)}"]
    return summary


def _skel_line(sk: dict) -> str:
    err = sk.get("usdSkelPointCacheError")
    return (f"  skeleton: {sk['joints']} joints, {sk['maxInfluences']} influences per vertex ({sk['skinWeights']} "
            f"weights, {sk['correctiveShapes']} corrective shapes)"
            + (f"; UsdSkel vs the point cache: max {err:.3g} {sk['units']}" if err is not None else ""))


def _remove_created(created, out: Path) -> None:
    """Remove the folders a failed run made (leave the disk as it was)."""
    if (out / "summary.json").exists():
        return
    for d in created:
        try:
            d.rmdir()
        except OSError:
            break


def _next_step(done, *, video: bool, output_kind) -> str:
    """The step after ``done`` (the one that failed), for error messages."""
    order = ["import-mesh"] + (["track", "lift"] if video else []) + ["import-capture", "bind", "distances"]
    order += (["transfer"] if "points" in output_kind else []) + (["skel"] if "skel" in output_kind else []) \
        + (["blendshapes"] if "blendshapes" in output_kind else [])
    order.append("shot")
    return order[0] if done is None else order[min(order.index(done) + 1, len(order) - 1)]


def run_provenance(mesh, capture, options: RunOptions) -> dict:
    """What `run` was asked to do: usdface version, options (:meth:`RunOptions.record`), and the
    input files' names + sha256 (no paths, no timestamps), as in every layer's provenance; equal
    dicts mean the same job on the same bytes."""
    from ..usd.layers import provenance

    stiffness_file = options.stiffness if isinstance(options.stiffness, str) else None
    return provenance("run", options=options.record(),
                      inputs={"mesh": mesh, "capture": capture, "layout": options.layout, "stiffness": stiffness_file})
