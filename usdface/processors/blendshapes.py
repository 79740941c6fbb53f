"""`run --output-kind blendshapes`'s step: the blend-shape weight curves of a take, solved on the rig
from the layers `run` wrote (the capture conditioned, the binding made on the rig's mesh), written
as the curves layer and the curves CSVs. `run` writes the shot stage that composes them."""
from __future__ import annotations

import time
from pathlib import Path

from ..errors import InputError
from ..options import SolveOptions
from ..registry import Result

__all__ = ["blendshapes"]


def blendshapes(mesh, capture, binding, *, options: SolveOptions, output, csv, livelink=None) -> Result:
    """Solve the take of ``capture`` on the rig ``mesh`` (+ ``options.shapes``) through ``binding``.

    Parameters
    ----------
    mesh : path (or Sdf.Layer / Usd.Stage)
        The rig: the mesh layer `run` imported, with ``options.shapes`` (``.npz``, folder of OBJs,
        or a USD rig matching it); or a USD mesh with UsdSkel blend shapes.
    capture, binding : paths (or layers)
        The capture layer (conditioned) and the binding layer `run` wrote.
    options : SolveOptions
        The solve's settings (``smoothing``, ``sparsity``, ...), the delivery (``fps``,
        ``key_tolerance``, ``livelink_fill_zeros``), ``head_motion``, ``mesh_units``; the capture
        and binding options are not used (the layers come conditioned and bound).
    output : path (or layer)
        The curves layer; ``csv`` the curves CSV; ``livelink`` the Live Link Face CSV (None: not
        written).

    Time codes start at the capture layer's start frame (`run` writes it from 0, or from its
    ``--start-frame``: decision D2). The summary's ``shotStage`` gives the rate, range and units of
    the shot stage `run` writes for the curves.
    """
    from ..blendshape.report import layer_report, take_summary, take_text
    from ..blendshape.take import deliverable_curves, solve_take
    from ..fileutil import StagedOutputs
    from ..usd.capture_layer import read_capture_layer
    from ..usd.curves_files import CurveFiles, write_curve_files
    from ..usd.identity import capture_record, claims_of, identity, markers_record, mesh_record, verify
    from ..usd.layers import describe, is_in_memory, open_stage, provenance
    from ..usd.mesh_layer import read_binding
    from ..usd.outputs import check_outputs
    from ..usd.rig_inputs import load_rig

    t0 = time.perf_counter()
    params, delivery, shapes = options.take_parameters(), options.delivery(), options.shapes
    outs = check_outputs({"--mesh": mesh, "--shapes": shapes, "--capture": capture, "--binding": binding},
                         {"-o": (output, "usd"), "--csv": (csv, "csv"), "--livelink": (livelink, "csv")})
    rig, regions = load_rig(mesh, shapes, mesh_units=options.mesh_units)
    cap = read_capture_layer(capture)
    bound = read_binding(open_stage(binding, what="binding"), source=describe(binding))
    rig_mesh = mesh_record(rig.mesh)
    verify(claims_of(binding, "binding"), mesh=(f"the rig's mesh {describe(mesh)}", rig_mesh),
           remedy="bind the capture on the rig's mesh (`usdface bind`)")
    if bound.triangle_vertices.max() >= rig.n_points:  # a binding of usdface 0.2, unverified
        raise InputError(f"binding {describe(binding)} refers to vertex {int(bound.triangle_vertices.max())}, the rig "
                         f"{rig.source} has {rig.n_points} points")
    take = solve_take(rig, cap, bound, params)
    curves = deliverable_curves(rig.names, take.weights, rate=take.rate, fps=delivery.fps,
                                key_tolerance=delivery.key_tolerance, head_motion=take.head_motion)
    start_out = int(round(take.start_frame * curves.rate / take.rate))
    prov = provenance("solve", options={**params.record(), "fps": delivery.fps, "key_tolerance": delivery.key_tolerance,
                                        "head_motion": params.head_motion},
                      inputs={"mesh": mesh, "capture": capture, "binding": binding,
                              "shapes": shapes if shapes and Path(shapes).is_file() else None},
                      identity=identity(mesh=rig_mesh, markers=markers_record(bound), capture=capture_record(cap)))
    out = outs["-o"]
    summary = take_summary(take, curves, rig, bound, output=describe(out) if is_in_memory(out) else str(out),
                           conditioning={})
    n = curves.values.shape[0]
    with StagedOutputs() as staged:
        written = write_curve_files(curves, rig, regions, CurveFiles(out, outs.get("--csv"), outs.get("--livelink")),
                                    staged=staged, prov=prov, report=layer_report(summary), start_frame=start_out,
                                    fill_zeros=delivery.livelink_fill_zeros)
        staged.commit()
    summary["shotStage"] = {"rate": curves.rate, "start": start_out, "end": start_out + n - 1, "units": rig.units,
                            "stabilizedCapture": cap.head_motion is not None and take.head_motion is None}
    summary.update(written)
    summary["seconds"] = round(time.perf_counter() - t0, 3)
    summary["_text"] = take_text(summary)
    files = {name: outs[flag] for name, flag in (("csv", "--csv"), ("livelink", "--livelink")) if flag in outs}
    return Result.from_summary(summary, layers={"output": out}, files=files)
