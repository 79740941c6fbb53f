"""`usdface run`: the main job, raw files (or USD) to a shot that plays in usdview.

import-mesh -> (track -> lift, for a video) -> import-capture (stabilised) -> bind -> distances ->
the deliverables' steps (:data:`usdface.options.DELIVERABLES`: transfer, skel, blendshapes) ->
shot stages. Every step is a registered processor called through :func:`usdface.registry.call`.
All files are written into a private folder inside OUTDIR and committed as a whole only when every
step has succeeded (:mod:`usdface.pipeline.shot_commit`): a failed run leaves OUTDIR as it was, a
crash at any moment leaves the old shot or the new one (or an interrupted commit that the next run
completes), and OUTDIR is locked while a run writes it.
"""
from __future__ import annotations

import json
import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from .. import registry
from ..errors import OptionError, UsdFaceError
from ..fileutil import environment_fault, is_environment_fault
from ..io.video import is_video
from ..options import (DELIVERABLES, BindOptions, BlendshapeOptions, CaptureOptions, ImportMeshOptions, LiftOptions,
                       RunOptions, TrackOptions, option_fields)
from ..registry import Result

log = logging.getLogger("usdface")

__all__ = ["run", "output_files", "shot_stages", "run_provenance", "step_order"]

#: the files every run writes before its deliverables
BASE_FILES = ("mesh.usdc", "capture.usdc", "binding.usda", "analysis.usdc")


def output_files(output_kind=("points",), *, video: bool = False, options: RunOptions | None = None) -> tuple:
    """The files a run writes into OUTDIR for the deliverables ``output_kind`` (RunOptions.output_kind)."""
    kinds = tuple(output_kind)
    files = list(BASE_FILES)
    for kind in kinds:
        files += DELIVERABLES[kind].all_files(options)
    if video:
        files.append("tracks.usdc")
    files += [shot for shot, _ in shot_stages(kinds)] + ["summary.json"]
    return tuple(files)


def shot_stages(output_kind) -> list[tuple[str, str]]:
    """(shot stage, deliverable layer) pairs: the first deliverable's shot is shot.usda."""
    return [("shot.usda" if i == 0 else DELIVERABLES[kind].shot, DELIVERABLES[kind].layer)
            for i, kind in enumerate(output_kind)]


def step_order(*, video: bool, output_kind) -> list[str]:
    """The steps of a run, in order (the last, ``shot``, writes the shot stages)."""
    order = ["import-mesh"] + (["track", "lift"] if video else []) + ["import-capture", "bind", "distances"]
    return order + [DELIVERABLES[k].step for k in output_kind] + ["shot"]


@dataclass
class _Job:
    """One run's inputs, checked, and what it writes."""

    mesh: str
    capture: str
    out: Path
    options: RunOptions
    video: bool
    track_auto: int | None
    files: tuple
    inputs: dict
    steps: dict = field(default_factory=dict)


def _check(mesh, capture, out_dir, o: RunOptions) -> _Job:
    """Every check that needs no work: the options that go together, the files that must exist."""
    video = is_video(capture)
    track_auto = None
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
    from ..inputfiles import check_utf8_path

    check_utf8_path(out_dir, label="-o")  # USD takes UTF-8 names only: refused before any work
    out = Path(out_dir)
    if out.is_symlink() and not out.exists():
        raise OptionError(f"-o {out}: a symbolic link that loops or points nowhere (to {os.readlink(out)}); "
                          "give a folder")
    if out.exists() and not out.is_dir():
        raise OptionError(f"-o {out}: exists and is not a folder")
    from ..rbf.stiffness import parse_stiffness

    parse_stiffness(o.stiffness)  # a bad --stiffness fails now, not after the distances
    if "blendshapes" in o.output_kind:
        _check_rig(mesh, o)  # before any work
    else:
        _warn_blendshape_options_unused(o)
    stiffness_file = o.stiffness if isinstance(o.stiffness, str) and Path(o.stiffness).is_file() else None
    inputs = {"--mesh": mesh, "--capture": capture, "--layout": o.layout, "--seeds": o.seeds,
              "--stiffness": stiffness_file, "--shapes": o.shapes}
    return _Job(mesh=mesh, capture=capture, out=out, options=o, video=video, track_auto=track_auto,
                files=output_files(o.output_kind, video=video, options=o), inputs=inputs)


def _warn_blendshape_options_unused(o: RunOptions) -> None:
    """One warning naming the blend-shape options given without the blendshapes deliverable, which
    alone reads them (usdface 0.2 accepted them, so they are not an error)."""
    only_blendshapes = {f.name for f in option_fields(BlendshapeOptions)} | {"livelink"}
    given = [f.metadata["flag"] for f in option_fields(RunOptions)
             if f.name in only_blendshapes and getattr(o, f.name) != f.default]
    if given:
        kinds = ",".join((*o.output_kind, "blendshapes"))
        log.warning("%s: only the blendshapes deliverable uses %s; ignored (add it: --output-kind %s)",
                    ", ".join(given), "it" if len(given) == 1 else "them", kinds)


def _check_rig(mesh, o: RunOptions) -> None:
    """--output-kind blendshapes needs a rig: --shapes, or a USD mesh with UsdSkel blend shapes."""
    from ..usd.rig_inputs import load_rig

    try:
        load_rig(mesh, o.shapes, mesh_units=o.mesh_units)
    except UsdFaceError as exc:
        hint = "" if o.shapes else (" (--output-kind blendshapes and all solve weight curves on a blend-shape rig; "
                                    "without one, list the kinds you want, e.g. --output-kind points,skel)")
        raise type(exc)(f"{exc}{hint}") from None


def run(mesh, capture, *, options: RunOptions, output, cache=None) -> Result:
    """Run the whole pipeline into the folder ``output``; returns its Result (the summary is also
    written to OUTDIR/summary.json).

    Parameters
    ----------
    mesh, capture : path
        The face mesh (OBJ, PLY, ... or a USD mesh layer) and the capture (Maya ASCII, C3D, TRC,
        CSV, a capture layer, or a video of painted dots: movie, ``name.####.ext`` or a folder of
        frames).
    options : RunOptions
        Every option of `usdface run`. ``output_kind`` picks the deliverables; the first one's
        shot stage is shot.usda, the others get shot_<kind>.usda.
    output : path
        OUTDIR, created if missing; gets the files of :func:`output_files`.
    cache : usdface.cache.ContentCache, optional
        Reuses imported captures and distance matrices computed before; the layers written are the
        same either way.

    The summary's ``provenance`` (:func:`run_provenance`) records the usdface version, the options
    and the input files' names and sha256, so a batch can tell whether OUTDIR is current. A video
    capture is tracked (``seeds`` or ``auto`` = N dots, ``radius`` in px) into OUTDIR/tracks.usdc
    and lifted onto the mesh through ``layout``.
    """
    from .shot_commit import ShotSession, check_run_paths, run_id

    job = _check(mesh, capture, output, options)
    out = job.out
    check_run_paths(out, job.files, job.inputs)  # no output is an input, before any work
    prov = run_provenance(mesh, capture, options)
    created = [d for d in [out, *out.parents] if not d.exists()]
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        from ..fileutil import write_error

        raise write_error(out, exc) from None
    started = time.perf_counter()
    session = ShotSession(out, run_id(prov), inputs=job.inputs)
    try:
        work = session.open()  # locks OUTDIR, completes an interrupted commit, removes dead runs' temporaries
    except BaseException:
        _remove_created(created, out)
        raise
    try:
        f = {name: work / name for name in job.files}
        _run_steps(job, f, work, cache)
        text = _commit(job, f, session, prov, started)
    except UsdFaceError as exc:
        failed = _failed_step(job)
        message = str(exc).replace(str(work) + os.sep, str(out) + os.sep).replace(str(work), str(out))
        raise type(exc)(f"{failed} step failed: {message}") from None
    except Exception as exc:  # noqa: BLE001 - file system, memory and USD errors become one line
        if not is_environment_fault(exc):
            raise
        fault = environment_fault(exc, f"{_failed_step(job)} step failed: ")
        raise type(fault)(str(fault).replace(str(work) + os.sep, str(out) + os.sep).replace(str(work), str(out))) \
            from None
    finally:
        session.close()
        _remove_created(created, out)
    summary = json.loads(text)
    files = {name: str(out / name) for name in job.files}
    return Result(layers={k: v for k, v in files.items() if k.endswith((".usdc", ".usda"))},
                  files={k: v for k, v in files.items() if not k.endswith((".usdc", ".usda"))},
                  summary=summary, text=_text(summary, job))


def _run_steps(job: _Job, f: dict, work: Path, cache) -> None:
    """Every step before the shot stages, through the registry; their summaries in ``job.steps``."""
    o, steps = job.options, job.steps
    steps["import-mesh"] = registry.call("import-mesh", job.mesh, options=ImportMeshOptions(units=o.mesh_units),
                                         output=f["mesh.usdc"]).summary
    capture_options = CaptureOptions.from_other(o)
    if job.video:
        steps["track"] = registry.call(
            "track", job.capture, options=TrackOptions(seeds=o.seeds, auto=job.track_auto, layout=o.layout,
                                                       mesh=job.mesh, radius=tuple(o.radius), rate=o.rate),
            output=f["tracks.usdc"]).summary
        lifted = work / "lifted.usdc"
        steps["lift"] = registry.call(
            "lift", f["tracks.usdc"], f["mesh.usdc"],
            options=LiftOptions(layout=o.layout, neutral=None if o.neutral == "auto" else o.neutral, allow=o.allow),
            output=lifted).summary
        # the lifted capture still holds the head's motion in the image: condition it like any take
        # (its units, rate and neutral come from the tracks)
        capture_options = capture_options.replace(units=None, rate=None, up_axis=None, neutral=None)
        steps["import-capture"] = registry.call("import-capture", lifted, options=capture_options,
                                                output=f["capture.usdc"]).summary
    else:
        steps["import-capture"] = registry.call("import-capture", job.capture, options=capture_options,
                                                output=f["capture.usdc"], cache=cache).summary
    steps["bind"] = registry.call(
        "bind", f["mesh.usdc"], f["capture.usdc"],
        options=BindOptions(layout=o.layout, auto=bool(o.auto) and not job.video, retarget=o.retarget,
                            allow=o.allow), output=f["binding.usda"]).summary
    steps["distances"] = registry.call("distances", f["mesh.usdc"], f["binding.usda"], options=o,
                                       output=f["analysis.usdc"], cache=cache).summary
    available = {"mesh": f["mesh.usdc"], "capture": f["capture.usdc"], "binding": f["binding.usda"],
                 "analysis": f["analysis.usdc"], "rig": f["mesh.usdc"] if o.shapes else job.mesh}
    # a video run's --auto N counted dots: the deliverables' steps never bind
    step_options = o.replace(auto=False) if job.video else o
    for kind in o.output_kind:
        d = DELIVERABLES[kind]
        step = registry.find(d.step)
        outputs = {"output": f[d.layer], **{name: f[file] for name, file in d.files.items()}}
        outputs.update({name: f[file] for name, (flag, file) in d.optional_files.items() if getattr(o, flag, False)})
        inputs = [available[i.name] for i in step.inputs]
        # the step's options are run's of the same names; a studio step's own take their defaults
        options = step.options.from_other(step_options, strict=False)
        steps[d.step] = registry.call(d.step, *inputs, options=options, **outputs).summary


def _commit(job: _Job, f: dict, session, prov: dict, started: float) -> str:
    """Write the shot stages and summary.json, and commit the run folder; returns the summary text."""
    from ..usd.analysis_layer import write_shot_stage

    o, steps, out = job.options, job.steps, job.out
    cap, units = steps["import-capture"], steps["import-mesh"]["units"]
    record = session.record(job.files)  # the shot stages list every file's sha256 and provenance id
    for shot_name, layer in shot_stages(o.output_kind):
        step = next(d.step for d in DELIVERABLES.values() if d.layer == layer)
        st = steps[step].get("shotStage")
        if st is not None:  # the step's own rate and range (curves resampled with --fps)
            write_shot_stage(f[shot_name], layers=[f[layer], f["binding.usda"]], rate=st["rate"], start=st["start"],
                             end=st["end"], units=units, stabilized_capture=st["stabilizedCapture"], record=record)
            continue
        write_shot_stage(f[shot_name], layers=[f[layer], f["analysis.usdc"], f["binding.usda"]],
                         rate=cap["rate"], start=cap["startTimeCode"], end=cap["startTimeCode"] + cap["frames"] - 1,
                         units=units,
                         # markers follow the face: head-stabilised unless the head motion is delivered
                         stabilized_capture=cap["stabilized"] and not o.head_motion, record=record)
    summary = {
        "outputDir": str(out), "shot": str(out / "shot.usda"), "mesh": str(job.mesh), "capture": str(job.capture),
        "method": o.method, "backend": o.backend if o.method != "euclidean" else None, "rbf": o.rbf,
        "kernel": o.kernel, "outputKind": list(o.output_kind),
        "frames": cap["frames"], "rate": cap["rate"], "markers": cap["markers"],
        "vertices": steps["import-mesh"]["points"], "steps": steps,
        "seconds": round(time.perf_counter() - started, 3),
        "provenance": prov, "runId": session.run_id, "files": list(job.files),
    }
    # paths in the summary name the final files, not the private work folder
    text = json.dumps(summary, indent=2, default=str).replace(str(session.work), str(out))
    session.write_text("summary.json", text + "\n")
    session.commit(job.files)
    return text


def _text(summary: dict, job: _Job) -> list[str]:
    """The lines `usdface run` prints."""
    o, out, steps = job.options, job.out, summary["steps"]
    units = steps["import-mesh"]["units"] or "mesh units"
    cap, b = steps["import-capture"], steps["bind"]
    tr = steps.get("transfer") or steps.get("skel")
    bs = steps.get("blendshapes")
    lines = [
        f"shot: {out / 'shot.usda'}  ({summary['frames']} frames at {summary['rate']:g} Hz, "
        f"{summary['vertices']} vertices, {summary['markers']} markers)",
        f"  capture: {cap['markers']} markers, {cap['invalidSamples']} invalid samples, "
        f"stabilised: {'yes' if cap['stabilized'] else 'no'}",
        f"  {cap['reports']['restPose']['text']}",
        f"  binding: {b['method']}, {'fit ' if b['method'] == 'layout' else ''}residual median "
        f"{b['residualMedian']:.3f} max {b['residualMax']:.3f} {b['units']}",
        f"  distances: {o.method}{'/' + o.backend if o.method != 'euclidean' else ''} in "
        f"{steps['distances']['seconds']:.2f} s",
    ]
    if tr:
        from ..rbf.stiffness import width_source

        lines.append(f"  transfer: {tr['mode']} {tr['kernel']}, {tr['seconds']:.2f} s"
                     + (f", width {tr['widthMedian']:.3g} {tr['units']} ({width_source(o.stiffness, tr['widthRule'])})"
                        if "widthMedian" in tr else ""))
    if bs:
        lines.append(f"  blend shapes: {bs['shapes']} shapes, marker residual mean {_cm(bs['residualMean'], units)} "
                     f"(a still face: {_cm(bs['stillResidualMean'], units)}), curves at {bs['shotStage']['rate']:g} fps")
    if job.video:
        lines.append(f"  video: {steps['track']['frames']} frames tracked, "
                     f"{100 * steps['track']['validFraction']:.1f}% of marker samples found, lifted with depth "
                     f"{steps['lift']['depth']}")
    if "skel" in steps:
        lines.append(_skel_line(steps["skel"]))
    lines.append(f"  total {summary['seconds']:.1f} s; files: {', '.join(job.files)}")
    return lines


def _cm(value, units: str) -> str:
    """A residual for the terminal: ``0.165 cm``, or ``n/a`` where there is none (a one-frame take)."""
    return "n/a" if value is None or value != value else f"{value:.3f} {units}"


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


def _failed_step(job: _Job) -> str:
    """The step after the last one done (the one that failed), for error messages."""
    order = step_order(video=job.video, output_kind=job.options.output_kind)
    done = next(reversed(job.steps), None)
    return order[0] if done is None else order[min(order.index(done) + 1, len(order) - 1)]


def run_provenance(mesh, capture, options: RunOptions) -> dict:
    """What `run` was asked to do: usdface version, options (:meth:`RunOptions.record`), and the
    input files' names + sha256 (no paths, no timestamps), as in every layer's provenance; equal
    dicts mean the same job on the same bytes."""
    from ..usd.layers import provenance

    stiffness_file = options.stiffness if isinstance(options.stiffness, str) else None
    return provenance("run", options=options.record(),
                      inputs={"mesh": mesh, "capture": capture, "layout": options.layout, "stiffness": stiffness_file})
