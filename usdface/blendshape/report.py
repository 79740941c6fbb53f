"""What a solved take reports: the JSON summary (``usdface solve --json``, and `run`'s blend-shape
step in summary.json) and the lines the command prints. Residuals are in cm (the mesh's units
converted)."""
from __future__ import annotations

import numpy as np

__all__ = ["take_summary", "layer_report", "take_text"]


def take_summary(take, curves, rig, binding, *, output: str, conditioning: dict) -> dict:
    """The summary of a solved take.

    Parameters
    ----------
    take : usdface.blendshape.take.TakeSolution
    curves : usdface.blendshape.take.DeliverableCurves
    rig : usdface.blendshape.rig.BlendShapeRig
    binding : usdface.model.mesh.Binding
    output : str
        The curves layer, as the summary names it.
    conditioning : dict
        The capture conditioning's reports ({} when the capture came conditioned).
    """
    from ..units import scale_between

    sol = take.solution
    to_cm = scale_between(rig.units, "cm") if rig.units else 1.0
    residual, still, per_marker = sol.residual * to_cm, sol.still_residual * to_cm, sol.marker_rms * to_cm
    fin = np.isfinite(residual)
    units = "cm" if rig.units else "units"
    return {
        "output": output, "frames": int(sol.n_frames), "rate": take.rate, "deliveredFrames":
            int(curves.values.shape[0]), "deliveredRate": curves.rate, "shapes": rig.n_shapes,
        "markers": binding.n_markers, "units": units,  # of the residuals below
        "meshUnits": rig.units,
        "residual": [None if not np.isfinite(r) else round(float(r), 5) for r in residual],
        "residualMean": float(np.mean(residual[fin])) if fin.any() else None,
        "residualMax": float(np.max(residual[fin])) if fin.any() else None,
        "stillResidualMean": float(np.mean(still[fin])) if fin.any() else None,
        "markerResidual": {n: (None if not np.isfinite(v) else round(float(v), 5))
                           for n, v in zip(binding.names, per_marker)},
        "weightMax": {n: round(float(v), 4) for n, v in zip(rig.names, sol.weights.max(axis=0))},
        "iterations": int(sol.iterations), "converged": bool(sol.converged),
        "solveSeconds": round(float(sol.seconds), 4), "solver": sol.summary(),
        "mirror": take.mirror, "excludedShapes": sol.info.get("excludedShapes", []),
        "headMotion": take.head_motion is not None, "keys": curves.key_counts,
        "keyTolerance": curves.tolerance, "timeSamples": int(curves.sample_frames.size),
        "warnings": list(take.warnings), "rigNotes": list(rig.notes), "conditioning": conditioning,
        "poseRefit": take.pose_refit,
    }


def layer_report(summary: dict) -> dict:
    """What the curves layer stores beside its provenance (a subset of the summary)."""
    return {k: summary[k] for k in ("residualMean", "stillResidualMean", "iterations", "mirror", "excludedShapes",
                                    "poseRefit")}


def take_text(summary: dict) -> list[str]:
    """The lines ``usdface solve`` prints for :func:`take_summary`'s summary (with ``seconds``,
    ``files`` and, for a corrective shot, ``corrective`` added)."""
    u = summary["units"]

    def cm(key):  # a residual, or n/a where there is none (a take without any valid frame)
        v = summary.get(key)
        return "n/a" if v is None or v != v else f"{v:.3f} {u}"

    lines = [f"wrote {summary['output']}: {summary['shapes']} shapes x {summary['deliveredFrames']} frames at "
             f"{summary['deliveredRate']:g} fps ({summary['timeSamples']} time samples), head motion "
             f"{'on /Face' if summary['headMotion'] else 'none'}, in {summary['seconds']:.2f} s",
             f"  solve: {summary['frames']} frames at {summary['rate']:g} Hz in {summary['solveSeconds']:.3f} s "
             f"({summary['iterations']} iterations); marker residual mean {cm('residualMean')} "
             f"(still face {cm('stillResidualMean')}), max {cm('residualMax')}"]
    rest = summary.get("conditioning", {}).get("restPose")
    if rest is not None:
        lines.append(f"  {rest['text']}")
    refit = summary.get("poseRefit")
    if refit is not None and refit["rounds"]:
        frames = refit["restFrames"]
        lines.append(f"  pose refit: {refit['rounds']} round(s); rest pose corrected by {refit['restOffsetRmsCm']:.3f} cm RMS"
                     + (f" over the quiet frames {frames[0]}-{frames[-1]}" if frames else " (no quiet neutral frames)")
                     + (f"; head turned {refit['headAngleDegMedian']:.2f} deg more (median, {refit['headAngleDegMax']:.2f} "
                        "max) than the stabilisation said" if "headAngleDegMedian" in refit else ""))
    top = sorted(summary["weightMax"].items(), key=lambda kv: -kv[1])[:6]
    lines.append("  largest weights: " + ", ".join(f"{n} {v:.2f}" for n, v in top))
    pairs = summary["mirror"].get("prior", [])
    lines.append(f"  left/right prior on {len(pairs)} mirror pair(s); excluded: "
                 f"{', '.join(summary['excludedShapes']) or 'none'}")
    for key in ("csv", "livelink"):
        if key in summary.get("files", {}):
            lines.append(f"  {key}: {summary['files'][key]}")
    if "corrective" in summary:
        lines.append(f"  corrective points shot: {summary['corrective']['output']}")
    lines += [f"  warning: {w}" for w in summary["warnings"]]
    return lines
