"""`usdface skel`: skeletal keyframes (UsdSkel) from a capture, skinned so they reproduce the transfer.

One static root joint plus one translation-only joint per marker (children of the root, at the
markers' bound surface points) and skin weights, in one of two modes (:mod:`usdface.skel.fitting`):

- ``skin_weights="dcc"`` (default): weights Blender, Maya and game engines take as they are
  (non-negative, summing to one, at most K per vertex, none below 1e-5), fitted to the transfer
  over a range of motion (:mod:`usdface.skel.dcc`); the joints' translations are fitted blends of
  the marker displacements, and up to 16 time-invariant corrective blend shapes with per-frame
  weights take what skinning misses. Fitted on the synthetic range of motion (default), the
  weights, joint mapping and shapes depend on the character (mesh, binding, transfer) only: every
  take of one character gets the same ones.
- ``skin_weights="exact"``: the transfer matrix itself (signed; the root takes the remainder),
  joints translated by the marker displacements: with every weight kept, UsdSkel reproduces
  `usdface transfer`'s point cache (:mod:`usdface.skel.weights`); pruned to K and refitted on the
  take. Negative weights are dropped by DCC importers: this mode is for UsdSkel consumers.

Frames with missing markers: their joints follow the surface the valid markers re-solve
(:func:`usdface.skel.fitting.effective_displacements`).

Head motion (decision D1): when the capture was stabilised, the SkelRoot /Face carries the head
motion removed by stabilisation as a time-sampled ``xformOp:transform``, mapped into mesh space by
the binding's capture-to-mesh similarity and taken relative to the neutral frame:
``H_mesh(f) = C H(n)^-1 H(f) C^-1`` (identity on the neutral frame). The skinned mesh stays in
stabilised mesh space, so the face in world space is the stabilised point cache moved by
H_mesh(f); ``head_motion=False`` (``--no-head-motion``) writes no op on /Face.
"""
from __future__ import annotations

import logging
import time

import numpy as np

from ..options import SkelLayerOptions
from ..progress import progress
from ..registry import Result
from ..usd.layers import check_output_path, describe, is_in_memory, provenance

log = logging.getLogger("usdface")

__all__ = ["skel"]

#: frames deformed by UsdSkel at once when verifying the written layer
VERIFY_CHUNK = 128


def skel(mesh, capture, binding, analysis, *, options: SkelLayerOptions, output) -> Result:
    """Write the skeleton layer (:mod:`usdface.usd.skel_layer`).

    The transfer is `usdface transfer`'s (``options``' transfer fields, same defaults, same
    handling; ``options.method`` picks the analysis layer's matrix). The skinning
    (``options.skin_parameters()``): ``skin_weights`` "dcc" or "exact", ``max_influences`` K (or
    "all"), ``skin_fit`` "rom" or "take" (dcc), ``corrective_shapes`` 0 or 2..16 (dcc),
    ``weight_fit`` (exact); ``head_motion`` authors the head motion on /Face (when the capture has
    one). ``verify``: deform the written layer with UsdSkel (blend shapes and skinning) and report
    its world-space error against the point cache moved by the head motion; an in-memory output
    (the Python API's) is not verified (the check needs the mesh composed with it).
    """
    from ..skel import build_rig, fit_skin, skel_inputs
    from ..usd.identity import capture_record, identity, markers_record, mesh_record
    from ..usd.inputs import load_transfer_inputs
    from ..usd.skel_layer import write_skel_layer

    out = check_output_path(output, inputs={"--mesh": mesh, "--capture": capture, "--binding": binding,
                                            "--analysis": analysis})
    params, skin = options.parameters(), options.skin_parameters()
    t0 = time.perf_counter()
    loaded = load_transfer_inputs(mesh, capture, binding, analysis, method=options.method)
    made_of = identity(mesh=mesh_record(loaded[0]), markers=markers_record(loaded[2]),
                       capture=capture_record(loaded[1]))  # the take as its layer holds it
    inputs = skel_inputs(*loaded, params)
    hm = inputs.head_motion if options.head_motion else None
    fitted = fit_skin(inputs, skin)
    rig = build_rig(inputs.binding.names, inputs.bound_points, fitted.translations)
    chosen = fitted.weights
    report = {"skinWeights": skin.mode, "maxInfluences": chosen.k, "weightFit": chosen.fit,
              "skinFit": skin.skin_fit if skin.mode == "dcc" else "take", "correctiveShapes": skin.corrective_shapes,
              "pointCacheError": fitted.errors, "gapFrameError": fitted.gap_errors,
              "gapFrames": int(inputs.gap_frames.size), "weights": _weight_stats(chosen),
              "headMotion": hm is not None, "framesResolved": inputs.effective_info["framesResolved"],
              "jointNameMapping": rig.name_mapping}
    recorded = {"rbf": params.rbf, "kernel": params.kernel, "stiffness": params.stiffness,
                "regularization": inputs.info["regularization"], "polynomial": inputs.info["polynomial"],
                "method": inputs.dm.method, "all_invalid": params.all_invalid, "skin_weights": skin.mode,
                "max_influences": chosen.k, "skin_fit": options.skin_fit, "corrective_shapes": skin.corrective_shapes,
                "weight_fit": options.weight_fit, "head_motion": hm is not None}
    prov = provenance("skel", options=recorded, inputs={"mesh": mesh, "capture": capture, "binding": binding,
                                                        "analysis": analysis}, identity=made_of)
    capture_data = inputs.capture
    bar = progress(total=capture_data.n_frames, desc="skel", unit="frame")
    try:
        write_skel_layer(out, rig, fitted, mesh_path=mesh, rate=capture_data.rate, start=capture_data.start_frame,
                         prov=prov, report=report, progress=bar, head_motion=hm)
    finally:
        bar.close()
    verified = _verify(out, inputs, world=hm is not None) if options.verify and not is_in_memory(out) else None
    seconds = time.perf_counter() - t0
    summary = _summary(out, inputs, rig, report, verified, rbf=params.rbf, seconds=seconds)
    return Result(layers={"output": out}, summary=summary, text=_text(summary, skin, seconds=seconds))


def _weight_stats(chosen) -> dict:
    w = chosen.weights
    return {"min": float(w.min()), "negative": int((w < 0).sum()), "minNonZero": float(np.abs(w[w != 0]).min()),
            "maxRowSumError": float(np.abs(w.sum(axis=1) - 1.0).max())}


def _verify(out, inputs, *, world: bool) -> tuple[float, float | None]:
    """(largest error over every frame, over the frames with missing markers) of the written layer
    deformed by UsdSkel against the point cache (world space when the head motion is authored)."""
    from ..usd.layers import open_stage
    from ..usd.skel_layer import skinned_points

    capture, gaps = inputs.capture, inputs.gap_frames
    stage = open_stage(out, what="skeleton")
    err = np.empty(capture.n_frames)
    for a in range(0, capture.n_frames, VERIFY_CHUNK):  # memory: a chunk of frames at a time
        frames = np.arange(a, min(capture.n_frames, a + VERIFY_CHUNK))
        _, pts = skinned_points(out, times=(capture.start_frame + frames).tolist(), stage=stage, space="world")
        expected = inputs.point_cache(frames, world=world)
        err[frames] = np.sqrt(((pts - expected) ** 2).sum(axis=2)).max(axis=1)
    return float(err.max()), (float(err[gaps].max()) if gaps.size else None)


def _summary(out, inputs, rig, report, verified, *, rbf: str, seconds: float) -> dict:
    """What ``usdface skel --json`` prints."""
    mesh, capture, binding, info = inputs.mesh, inputs.capture, inputs.binding, inputs.info
    usdskel_error, usdskel_gap_error = verified if verified is not None else (None, None)
    return {
        "output": describe(out) if is_in_memory(out) else str(out), "frames": capture.n_frames,
        "vertices": mesh.n_points, "markers": binding.n_markers, "joints": rig.n_joints,
        "skinWeights": report["skinWeights"], "maxInfluences": report["maxInfluences"], "skinFit": report["skinFit"],
        "correctiveShapes": report["correctiveShapes"], "weightFit": report["weightFit"],
        "headMotion": report["headMotion"], "units": mesh.units, "pointCacheError": report["pointCacheError"],
        "gapFrameError": report["gapFrameError"], "gapFrames": report["gapFrames"],
        "usdSkelPointCacheError": usdskel_error, "usdSkelGapFrameError": usdskel_gap_error,
        "weights": report["weights"], "framesResolved": report["framesResolved"],
        "jointNameMapping": rig.name_mapping, "mode": rbf,
        "kernel": inputs.solver.kernel, "distanceMethod": inputs.dm.method, "regularization": info["regularization"],
        "amplification": info["amplification"], "seconds": round(seconds, 3),
    }


def _text(summary: dict, skin, *, seconds: float) -> list[str]:
    """The lines ``usdface skel`` prints."""
    units, gaps = summary["units"], summary["gapFrames"]
    errs = ", ".join(f"K={name}: max {v['max']:.3g} rms {v['rms']:.3g}"
                     for name, v in summary["pointCacheError"].items())
    gap_text = ", ".join(f"K={name}: max {v['max']:.3g}" for name, v in summary["gapFrameError"].items())
    how = (f"DCC-safe weights fitted on the {'synthetic range of motion' if skin.skin_fit == 'rom' else 'take'}, "
           f"{skin.corrective_shapes} corrective shapes" if skin.mode == "dcc"
           else f"exact signed weights ({summary['weightFit']})")
    err = summary["usdSkelPointCacheError"]
    mapping = summary["jointNameMapping"]
    return [
        f"wrote {summary['output']}: {summary['joints']} joints (root + {summary['markers']} markers), "
        f"{summary['frames']} frames, {summary['maxInfluences']} influences per vertex, {how}, "
        f"head motion {'on /Face' if summary['headMotion'] else 'none'}, in {seconds:.2f} s",
        f"  skinning error against the point cache ({units}): {errs}",
    ] + ([f"  UsdSkel deformation of the written layer vs the point cache (world space): max {err:.3g} {units}"]
         if err is not None else []) \
      + ([f"  {gaps} frames with missing markers (their joints follow the re-solved surface): {gap_text}"]
         if gaps else []) \
      + ([f"  joints renamed from markers: {mapping}"] if mapping else [])
