"""`usdface run`: the main job, raw files (or USD) to a shot that plays in usdview.

import-mesh -> import-capture (stabilised) -> bind -> distances -> transfer -> shot.usda.
All files are written into a private folder inside OUTDIR and moved into place only when every
step has succeeded, so a failed run leaves OUTDIR as it was.
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from pathlib import Path

from ..errors import OptionError, UsdFaceError

OUTPUT_FILES = ("mesh.usdc", "capture.usdc", "binding.usda", "analysis.usdc", "anim.usdc", "shot.usda",
                "summary.json")
OUTPUTS = ("points", "skel", "both")


def is_video(path) -> bool:
    """A movie file, an image-sequence pattern (name.####.png) or a folder of frames."""
    from ..io.video import MOVIE_SUFFIXES, is_sequence_pattern

    p = Path(path)
    return p.suffix.lower() in MOVIE_SUFFIXES or is_sequence_pattern(str(path)) or p.is_dir()


def output_files(*, output: str = "points", video: bool = False) -> tuple:
    """The files a run writes into OUTDIR."""
    files = ["mesh.usdc", "capture.usdc", "binding.usda", "analysis.usdc"]
    if output in ("points", "both"):
        files.append("anim.usdc")
    if output in ("skel", "both"):
        files.append("skel.usdc")
    if video:
        files.append("tracks.usdc")
    files += ["shot.usda"] + (["shot_skel.usda"] if output == "both" else []) + ["summary.json"]
    return tuple(files)


def run(mesh, capture, out_dir, *, layout=None, auto=False, method="hybrid", backend="graph",
        rbf="interpolate", kernel="gaussian", stiffness=None, regularization="auto", polynomial=False,
        retarget="displacement", mesh_units=None, units=None, rate=None, up_axis=None, stabilize="auto",
        fill_gaps=None, filter=None, cutoff=8.0, trim=None, neutral=None, region_radius_cm=1.0,
        sigma_cm=2.0, threshold=0.6, pin_border="upper", components="error", cache=None,
        output="points", seeds=None, radius=(3.0, 10.0), max_influences=8, resample=None,
        start_frame=None, allow=(), keep_zeros=False, drop_outliers=False) -> dict:
    """Run the whole pipeline; returns the summary (also written to OUTDIR/summary.json).

    ``cache`` (a :class:`usdface.batch.cache.ContentCache`; default None, no cache) reuses imported
    captures and distance matrices computed before; the layers written are the same either way.
    The summary's ``provenance`` (see :func:`run_provenance`) records the usdface version, the
    options and the input files' names and sha256, so a batch can tell whether OUTDIR is current.

    ``output``: "points" (time-sampled mesh points, anim.usdc), "skel" (UsdSkel keyframes,
    skel.usdc) or "both" (shot.usda plays the points, shot_skel.usda the skeleton).
    A video ``capture`` (movie, ``name.####.ext`` or a folder of frames) is tracked
    (``seeds`` JSON or ``auto`` = N markers, ``radius`` in px) into OUTDIR/tracks.usdc and lifted
    onto the mesh through ``layout`` into capture.usdc; a video needs ``layout``.

    Plausibility (:mod:`usdface.capture.plausibility`): ``allow`` (check codes) accepts findings
    of import-capture, lift and bind that would stop the run; ``keep_zeros`` and ``drop_outliers``
    as in :func:`usdface.processors.import_capture.import_capture`.
    """
    from .bind import bind
    from .distances import distances
    from .import_capture import import_capture
    from .import_mesh import import_mesh
    from .transfer import transfer
    from ..usd.analysis_layer import write_shot_stage

    if output not in OUTPUTS:
        raise OptionError(f"--output {output}: expected one of {', '.join(OUTPUTS)}")
    video = is_video(capture)
    if video:
        if layout is None:
            raise OptionError(f"--capture {capture} is a video: give --layout LAYOUT.json (it names the markers and "
                              "places them on the mesh; 2D tracks cannot be bound automatically)")
        track_auto = auto if (auto is not True and auto) else None
        if (seeds is None) == (track_auto is None):
            raise OptionError(f"--capture {capture} is a video: give --seeds SEEDS.json or --auto N (the number of "
                              "dots to find on the first frame)")
    else:
        if auto not in (True, False, None):
            raise OptionError(f"--auto {auto}: a number of markers applies to video captures only")
        if (layout is None) == (not auto):
            raise OptionError("run: give exactly one of --layout LAYOUT.json or --auto")
    for label, path in (("--mesh", mesh), ("--capture", None if video else capture), ("--layout", layout),
                        ("--seeds", seeds)):
        if path is not None and not Path(path).is_file():
            raise OptionError(f"{label} {path}: no such file")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise OptionError(f"-o {out}: exists and is not a folder")
    if rbf == "paper" and (polynomial or regularization not in ("auto", 0, 0.0)):
        raise OptionError("--polynomial and --regularization apply to --rbf interpolate only (paper mode solves nothing)")
    from .transfer import parse_stiffness

    parse_stiffness(stiffness)  # a bad --stiffness fails now, not after the distances
    files = output_files(output=output, video=video)
    options = run_options(layout=layout, auto=auto, output=output, seeds=seeds, radius=radius,
                          max_influences=max_influences, method=method, backend=backend, rbf=rbf, kernel=kernel,
                          stiffness=stiffness, regularization=regularization, polynomial=polynomial,
                          retarget=retarget, mesh_units=mesh_units, units=units, rate=rate, up_axis=up_axis,
                          stabilize=stabilize, fill_gaps=fill_gaps, filter=filter, cutoff=cutoff, trim=trim,
                          neutral=neutral, region_radius_cm=region_radius_cm, sigma_cm=sigma_cm,
                          threshold=threshold, pin_border=pin_border, components=components,
                          allow=sorted(allow or ()), keep_zeros=keep_zeros, drop_outliers=drop_outliers)
    prov = run_provenance(mesh, capture, options, layout=layout, stiffness=stiffness)
    created = [d for d in [out, *out.parents] if not d.exists()]
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    steps: dict = {}
    work = Path(tempfile.mkdtemp(prefix=".usdface-run-", dir=out))
    try:
        f = {name: work / name for name in files}
        steps["import-mesh"] = import_mesh(mesh, f["mesh.usdc"], units=mesh_units)
        if video:
            from .lift import lift
            from .track import track

            steps["track"] = track(capture, f["tracks.usdc"], seeds=seeds, auto=track_auto, layout=layout,
                                   mesh=mesh, radius=tuple(radius), rate=rate)
            lifted = work / "lifted.usdc"
            steps["lift"] = lift(f["tracks.usdc"], f["mesh.usdc"], lifted, layout=layout, neutral=neutral,
                                 allow=allow)
            # the lifted capture still holds the head's motion in the image: condition it like any take
            steps["import-capture"] = import_capture(lifted, f["capture.usdc"], stabilize=stabilize,
                                                     fill_gaps=fill_gaps, filter=filter, cutoff=cutoff, trim=trim,
                                                     resample=resample, start_frame=start_frame, allow=allow,
                                                     drop_outliers=drop_outliers)
        else:
            steps["import-capture"] = import_capture(capture, f["capture.usdc"], units=units, rate=rate,
                                                     up_axis=up_axis, stabilize=stabilize, fill_gaps=fill_gaps,
                                                     filter=filter, cutoff=cutoff, trim=trim, neutral=neutral,
                                                     resample=resample, start_frame=start_frame, allow=allow,
                                                     keep_zeros=keep_zeros, drop_outliers=drop_outliers, cache=cache)
        steps["bind"] = bind(f["mesh.usdc"], f["capture.usdc"], f["binding.usda"], layout=layout,
                             auto=bool(auto) and not video, retarget=retarget, allow=allow)
        steps["distances"] = distances(f["mesh.usdc"], f["binding.usda"], f["analysis.usdc"], method=method,
                                       backend=backend, region_radius_cm=region_radius_cm, sigma_cm=sigma_cm,
                                       threshold=threshold, pin_border=pin_border, components=components,
                                       cache=cache)
        transfer_options = dict(rbf=rbf, kernel=kernel, stiffness=stiffness, regularization=regularization,
                                polynomial=polynomial, method=method)
        if "anim.usdc" in f:
            steps["transfer"] = transfer(f["mesh.usdc"], f["capture.usdc"], f["binding.usda"],
                                         f["analysis.usdc"], f["anim.usdc"], **transfer_options)
        if "skel.usdc" in f:
            from .skel import skel

            steps["skel"] = skel(f["mesh.usdc"], f["capture.usdc"], f["binding.usda"], f["analysis.usdc"],
                                 f["skel.usdc"], max_influences=max_influences, **transfer_options)
        cap = steps["import-capture"]
        shots = [("shot.usda", "anim.usdc" if "anim.usdc" in f else "skel.usdc")]
        if output == "both":
            shots.append(("shot_skel.usda", "skel.usdc"))
        for shot_name, motion in shots:
            write_shot_stage(f[shot_name], layers=[f[motion], f["analysis.usdc"], f["binding.usda"]],
                             rate=cap["rate"], start=cap["startTimeCode"],
                             end=cap["startTimeCode"] + cap["frames"] - 1, units=steps["import-mesh"]["units"],
                             stabilized_capture=cap["stabilized"])
        summary = {
            "outputDir": str(out), "shot": str(out / "shot.usda"), "mesh": str(mesh), "capture": str(capture),
            "method": method, "backend": backend if method != "euclidean" else None, "rbf": rbf, "kernel": kernel,
            "frames": cap["frames"], "rate": cap["rate"], "markers": cap["markers"],
            "vertices": steps["import-mesh"]["points"],
            "steps": {k: {kk: vv for kk, vv in v.items() if not kk.startswith("_")} for k, v in steps.items()},
            "seconds": round(time.perf_counter() - started, 3),
            "provenance": prov,
        }
        # paths in the summary name the final files, not the private work folder
        text = json.dumps(summary, indent=2, default=str).replace(str(work), str(out))
        f["summary.json"].write_text(text + "\n")
        for name in files:
            os.replace(work / name, out / name)
    except UsdFaceError as exc:
        step = next(reversed(steps), None)
        failed = _next_step(step, video=video, output=output)
        message = str(exc).replace(str(work) + os.sep, "").replace(str(work), str(out))
        raise type(exc)(f"{failed} step failed: {message}") from None
    finally:
        shutil.rmtree(work, ignore_errors=True)
        if not (out / "summary.json").exists():
            for d in created:  # the run made these folders: leave the disk as it was
                try:
                    d.rmdir()
                except OSError:
                    break
    summary = json.loads(text)
    b = summary["steps"]["bind"]
    tr = summary["steps"].get("transfer") or summary["steps"]["skel"]
    summary["_text"] = [
        f"shot: {out / 'shot.usda'}  ({summary['frames']} frames at {summary['rate']:g} Hz, "
        f"{summary['vertices']} vertices, {summary['markers']} markers)",
        f"  capture: {cap['markers']} markers, {cap['invalidSamples']} invalid samples, "
        f"stabilised: {'yes' if cap['stabilized'] else 'no'}",
        f"  binding: {b['method']}, {'fit ' if b['method'] == 'layout' else ''}residual median "
        f"{b['residualMedian']:.3f} max {b['residualMax']:.3f} {b['units']}",
        f"  distances: {method}{'/' + backend if method != 'euclidean' else ''} in "
        f"{summary['steps']['distances']['seconds']:.2f} s",
        f"  transfer: {tr['mode']} {tr['kernel']}, {tr['seconds']:.2f} s"
        + (f", width {tr['widthMedian']:.3g} {tr['units']}" if "widthMedian" in tr else ""),
    ] + ([f"  video: {summary['steps']['track']['frames']} frames tracked, "
          f"{100 * summary['steps']['track']['validFraction']:.1f}% of marker samples found, lifted with depth "
          f"{summary['steps']['lift']['depth']}"] if video else []) \
      + ([f"  skeleton: {summary['steps']['skel']['joints']} joints, "
          f"{summary['steps']['skel']['maxInfluences']} influences per vertex"] if "skel" in summary["steps"] else []) \
      + [f"  total {summary['seconds']:.1f} s; files: {', '.join(files)}"]
    return summary


def _next_step(done, *, video: bool, output: str) -> str:
    """The step after ``done`` (the one that failed), for error messages."""
    order = ["import-mesh"] + (["track", "lift"] if video else []) + ["import-capture", "bind", "distances"]
    order += (["transfer"] if output in ("points", "both") else []) + (["skel"] if output in ("skel", "both") else [])
    order.append("shot")
    return order[0] if done is None else order[min(order.index(done) + 1, len(order) - 1)]


def run_options(**options) -> dict:
    """The options of a run as recorded in its provenance (JSON types; paths by file name).

    Options not given take :func:`run`'s defaults, so callers that pass a subset (a batch
    manifest) and :func:`run` itself record the same dict for the same job.
    """
    import inspect

    defaults = {name: p.default for name, p in inspect.signature(run).parameters.items()
                if p.kind is p.KEYWORD_ONLY and name != "cache"}
    rec = {}
    for k, v in sorted({**defaults, **options}.items()):
        if k == "layout" and v is not None:
            v = Path(v).name
        elif k == "stiffness" and v is not None and not isinstance(v, (int, float, dict)) and Path(str(v)).is_file():
            v = Path(v).name
        elif isinstance(v, tuple):
            v = list(v)
        rec[k] = v
    return json.loads(json.dumps(rec, sort_keys=True, default=str))


def run_provenance(mesh, capture, options: dict, *, layout=None, stiffness=None) -> dict:
    """What `run` was asked to do: usdface version, options (:func:`run_options`), and the input
    files' names + sha256 (no paths, no timestamps), as in every layer's provenance; equal dicts
    mean the same job on the same bytes."""
    from ..usd.layers import provenance

    stiffness_file = None
    if stiffness is not None and not isinstance(stiffness, (int, float, dict)):
        try:
            float(stiffness)
        except ValueError:
            stiffness_file = stiffness if Path(stiffness).is_file() else None
    return provenance("run", options=options, inputs={"mesh": mesh, "capture": capture, "layout": layout,
                                                      "stiffness": stiffness_file})
