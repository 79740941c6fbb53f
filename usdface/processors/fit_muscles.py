"""`usdface fit-muscles`: muscle contractions fitted to captured marker motion, simulated -> animation
layer (.usdc), with a shot stage (the face and the captured markers) beside it."""
from __future__ import annotations

import json
import logging
import math
import time
from pathlib import Path

import numpy as np

from ..errors import OptionError
from ..fileutil import refuse_overwriting_inputs
from ..options import FitMusclesOptions
from ..registry import Result
from ..usd.layers import check_output_path, describe, is_in_memory, provenance

log = logging.getLogger("usdface")

#: frames written between two saves of the animation layer
_CHUNK = 64


def fit_muscles(mesh_path, rig_path, capture_path, binding_path, *, options: FitMusclesOptions, output,
                report=None) -> Result:
    """Fit muscle contractions to a capture and write the simulated animation layer.

    Every ``options.step``-th capture frame of ``options.frames`` (indices [first, last), default
    all) is fitted (bounded least squares on the model's linearised response, then
    ``options.refine`` refinement passes by simulation; :func:`usdface.tissue.fit.fit_sequence`);
    the layer keeps the capture's time codes. ``report``: a JSON file with the fitted contractions
    per frame and the error statistics.
    """
    from ..progress import progress
    from ..tissue.animation import ControlSamples
    from ..tissue.fit import capture_displacements, fit_sequence, linear_response
    from ..tissue.simulation import build_simulator
    from ..usd.identity import capture_record, claims_of, identity, markers_record, verify
    from ..usd.muscle_layer import read_rig_layer, write_tissue_animation_layer, write_tissue_shot
    from ..usd.tissue_inputs import check_rig_mesh, load_tissue_mesh

    inputs = {"--mesh": mesh_path, "--rig": rig_path, "--capture": capture_path, "--binding": binding_path}
    out = check_output_path(output, suffixes=(".usdc", ".usd"), inputs=inputs)
    refuse_overwriting_inputs({"--report": report}, {k: v for k, v in inputs.items() if not is_in_memory(v)})
    _check_report_folder(report)
    t0 = time.perf_counter()
    mesh, regions = load_tissue_mesh(mesh_path)
    on_mesh = check_rig_mesh(rig_path, mesh_path, mesh)
    rig = read_rig_layer(rig_path, units=mesh.units)
    capture, binding = _read_capture_and_binding(capture_path, binding_path)
    verify(claims_of(binding_path, "binding"), mesh=(f"mesh {describe(mesh_path)}", on_mesh),
           remedy="bind the capture on this mesh (`usdface bind`)")
    # the take as its layer holds it; the markers as bound (a binding serves every take: no take)
    made_of = identity(mesh=on_mesh, markers=markers_record(binding), capture=capture_record(capture))
    disp, capture = capture_displacements(capture, binding, stabilize=options.stabilize)
    sel = _selected_frames(disp.shape[0], options)
    disp = disp[sel]
    sim = build_simulator(mesh, regions, rig)
    rate = capture.rate / options.step
    resp = linear_response(sim, binding.triangle_vertices, binding.barycentrics)
    bar = progress(total=(options.refine + 1) * len(sel), desc="fit-muscles", unit="frame")
    try:
        res = fit_sequence(sim, binding.triangle_vertices, binding.barycentrics, disp, rate=rate,
                           parameters=options.parameters(), marker_names=binding.names, response=resp, progress=bar)
    finally:
        bar.close()
    names = list(res.names)
    codes = capture.start_frame + sel.astype(np.float64)
    controls = ControlSamples(
        time_codes=codes, rate=capture.rate, muscle_names=rig.names,
        contractions=res.controls[:, [names.index(n) for n in rig.names]],
        jaw=res.controls[:, names.index("jawOpen")] if "jawOpen" in names else np.zeros(len(sel)))
    prov = provenance("fit-muscles", options={"step": options.step, "refine": options.refine,
                                              "regularization": options.regularization,
                                              "stabilize": options.stabilize, "integrator": sim.integrator,
                                              "frames": options.frames, "tissue": sim.model.options.to_dict()},
                      inputs={"mesh": mesh_path, "rig": rig_path, "capture": capture_path, "binding": binding_path},
                      identity=made_of)
    chunks = ((slice(s, min(s + _CHUNK, len(sel))), res.skin[s:s + _CHUNK]) for s in range(0, len(sel), _CHUNK))
    write_tissue_animation_layer(out, chunks, mesh_path=mesh_path, rig_path=rig_path, mesh=mesh, controls=controls,
                                 prov=prov)
    # the shot adds the binding layer: the captured markers beside the simulated face
    shot = write_tissue_shot(out, _shot_layers(out, binding_path, made_of["capture"], capture_path),
                             rate=capture.rate, start=float(codes[0]), end=float(codes[-1]), units=mesh.units,
                             stabilized_capture=capture.head_motion is not None, processor="fit-muscles")
    summary = {"output": str(out), "shot": shot, "frames": int(len(sel)), "rate": rate, "errors": res.errors,
               "perMarkerRms": res.per_marker, "meanContraction": dict(zip(names, res.controls.mean(axis=0).tolist())),
               "maxContraction": dict(zip(names, res.controls.max(axis=0).tolist())),
               "seconds": time.perf_counter() - t0, "capture": describe(capture_path)}
    files = {}
    if report is not None:
        files["report"] = _write_report(report, summary, names, codes, res.controls)
    text = _text(summary, res, options.refine, mesh.units)
    return Result(layers={"output": out}, files=files, summary=summary, text=text)


def _read_capture_and_binding(capture_path, binding_path):
    from ..usd.capture_layer import read_capture_layer
    from ..usd.layers import open_stage
    from ..usd.mesh_layer import read_binding

    capture = read_capture_layer(capture_path)
    binding = read_binding(open_stage(binding_path, what="binding"), source=describe(binding_path))
    return capture, binding


def _shot_layers(out, binding_path, take: dict, capture_path) -> list:
    """The layers of the shot beside ``out``: the animation and the binding (whose capture shows
    the markers), or the animation alone, with a warning, when the binding references another take
    than the one fitted (a binding serves every take; its markers would not be this take's)."""
    from ..model.identity import short
    from ..usd.identity import composed_take
    from ..usd.muscle_layer import shot_path_for

    shown = composed_take(binding_path)
    if is_in_memory(out) or shown is None or shown[1].get("sha256") == take.get("sha256"):
        return [out, binding_path]
    log.warning("%s", f"shot {shot_path_for(out)}: binding {describe(binding_path)} shows the markers of take "
                f"{short(shown[1].get('sha256'))} ({Path(shown[0]).name}), the fit is of take {short(take['sha256'])} "
                f"(capture {describe(capture_path)}): the shot holds the animation without markers; bind this take "
                "to see them")
    return [out]


def _selected_frames(n_frames: int, options: FitMusclesOptions) -> np.ndarray:
    """Indices of the capture frames to fit: ``options.frames`` [first, end), every ``step``-th."""
    sel = np.arange(n_frames)
    if options.frames is not None:
        a, b = options.frames
        if not 0 <= a < b <= n_frames:
            raise OptionError(f"--frames {a} {b}: outside the capture's 0..{n_frames}")
        sel = sel[a:b]
    return sel[::options.step]


def _check_report_folder(report) -> None:
    """Before any work: the report's folder exists (else the fit would run, write the layer and
    then fail)."""
    if report is None:
        return
    folder = Path(report).parent if str(Path(report).parent) else Path(".")
    if not folder.is_dir():
        raise OptionError(f"--report {report}: folder {folder} does not exist")


def _write_report(path, summary: dict, names: list, codes: np.ndarray, controls: np.ndarray) -> str:
    """The report JSON: the summary plus the fitted controls per frame (written atomically)."""
    from ..fileutil import write_text_atomic

    data = dict(summary)
    data["controls"] = {"names": names, "timeCodes": codes.tolist(), "values": np.round(controls, 5).tolist()}
    write_text_atomic(path, json.dumps(data, indent=1, default=float) + "\n")
    return str(path)


def _text(summary: dict, res, refine: int, units) -> list:
    u = units or "units"
    final = res.errors[f"pass{refine + 1}"]
    worst = sorted(res.per_marker.items(), key=lambda kv: -kv[1] if math.isfinite(kv[1]) else 0)[:4]
    return [
        f"wrote {summary['output']}: {summary['frames']} frames fitted ({len(res.names)} controls, {refine} "
        f"refinement pass(es), {summary['seconds']:.1f} s)"
        + (f"; shot stage {summary['shot']}" if summary["shot"] is not None else ""),
        f"  marker error RMS {final['rms']:.3f} {u} (median {final['median']:.3f}, p95 {final['p95']:.3f}); "
        f"a still face: RMS {res.errors['still']['rms']:.3f} {u}; linear fit: {res.errors['linear']['rms']:.3f} {u}",
        "  worst markers: " + ", ".join(f"{k} {v:.2f}" for k, v in worst),
    ]
