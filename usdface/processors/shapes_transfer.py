"""`usdface shapes transfer`: a generic blend-shape rig carried onto a face that has none.

The generic face is registered onto the target with ``usdface register``'s algorithm
(:class:`usdface.scan.register.GenericRegistration`: similarity, thin-plate warp, closest-point
projection; the target's topology is never used), then every shape is transferred
(:mod:`usdface.blendshape.rig_transfer`). The output is a rig layer (mesh, BlendShape prims, a
skeleton binding, no animation) that ``usdface solve --mesh RIG.usdc`` takes as it is.

The default generic is the MakeHuman rig shipped in ``usdface/resources/generic`` (the face mesh, its
52 ARKit shapes and its 20 landmarks: :func:`usdface.usd.rig_inputs.default_generic`), so it works
from an installed package.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..errors import InputError, OptionError
from ..options import ShapesTransferOptions
from ..registry import Result

__all__ = ["shapes_transfer"]

#: landmarks the registration needs at least (20 recommended)
MIN_LANDMARKS = 4


def shapes_transfer(target, landmarks, *, options: ShapesTransferOptions, output) -> Result:
    """Register the generic onto ``target`` and transfer its shapes; write the rig layer.

    Parameters
    ----------
    target : path (or Sdf.Layer / Usd.Stage)
        The face without a rig (mesh file or USD mesh layer).
    landmarks : path
        The target's landmarks: a marker layout on it, or a landmarks JSON with scan points.
    options : ShapesTransferOptions
        ``generic`` / ``generic_shapes`` (as ``solve --mesh/--shapes``; default the MakeHuman rig),
        ``generic_landmarks`` (a marker layout; default: beside the generic, or MakeHuman's),
        ``method`` (how each shape moves onto the registered generic), ``border``, ``field`` and
        ``iterations`` (``usdface register``'s; the defaults ``--border --field 8`` suit target meshes
        cropped like the generic), ``mesh_units``.
    output : path (or layer)
        The rig layer (.usdc/.usda).
    """
    from ..blendshape.rig_transfer import transfer_rig
    from ..mesh.layout import read_layout
    from ..mesh.topology import find_hole_regions
    from ..scan.landmarks import FACE_LANDMARKS
    from ..scan.register import GenericRegistration
    from ..usd.blendshape_layer import write_curves_layer
    from ..usd.identity import identity, mesh_record
    from ..usd.inputs import load_mesh
    from ..usd.layers import check_output_path, describe, is_in_memory, provenance
    from ..usd.outputs import check_outputs
    from ..usd.rig_inputs import load_rig

    t0 = time.perf_counter()
    o = options
    out = check_output_path(output)
    if landmarks is None:
        raise OptionError("shapes transfer: give the target's landmarks with --landmarks (a marker layout on the "
                          "target, or {\"name\": {\"scan\": [x, y, z]}}); registration starts from them")
    generic, generic_shapes, generic_landmarks = _generic(o)
    check_outputs({"--target": target, "--generic": generic, "--generic-shapes": generic_shapes},
                  {"-o": (output, "usd")})
    rig, g_regions = load_rig(generic, generic_shapes, mesh_units=o.mesh_units)
    tmesh, t_regions = load_mesh(target, units=o.mesh_units)
    tmesh.check_degenerate()
    if not t_regions:
        t_regions = find_hole_regions(tmesh)
    if rig.units and tmesh.units and rig.units != tmesh.units:
        raise InputError(f"generic rig in {rig.units}, target {describe(target)} in {tmesh.units}: import one in the "
                         "other's units (--mesh-units)")
    glay = read_layout(generic_landmarks)
    names = [n for n in glay.names if n in FACE_LANDMARKS] or list(glay.names)
    have, tl = _target_landmarks(landmarks, names, tmesh)
    if len(have) < MIN_LANDMARKS:
        raise InputError(f"shapes transfer: only {len(have)} landmark(s) shared by {landmarks} and "
                         f"{generic_landmarks}; "
                         f"at least {MIN_LANDMARKS} are needed (20 recommended)")
    reg = GenericRegistration(rig.mesh, g_regions, glay.positions(rig.mesh, have)).register(
        tmesh.points, tmesh.triangles(), tl, o.registration())
    moved = transfer_rig(rig, g_regions, reg.points, tmesh, t_regions, method=o.method)
    prov = provenance("shapes transfer", options={"method": o.method, "border": o.border, "field": o.field,
                                                  "iterations": o.iterations, "landmarks": have},
                      inputs={"generic": generic, "genericShapes": generic_shapes if generic_shapes and
                              Path(generic_shapes).is_file() else None, "target": target, "landmarks": landmarks,
                              "genericLandmarks": generic_landmarks},
                      identity=identity(mesh=mesh_record(moved.rig.mesh)))  # the target, as the layer holds it
    write_curves_layer(out, moved.rig, t_regions, prov=prov, report={"transfer": moved.info})
    seconds = time.perf_counter() - t0
    u = tmesh.units or "units"
    summary = {"output": describe(out) if is_in_memory(out) else str(out), "shapes": rig.n_shapes,
               "points": tmesh.n_points, "method": o.method, "landmarks": have,
               "registration": {"scale": float(reg.similarity[0]),
                                "landmarkResidualMean": float(reg.landmark_residuals.mean())},
               "correspondence": moved.info, "seconds": round(seconds, 3),
               "maxDisplacement": {n: round(float(v), 4) for n, v in zip(rig.names, moved.rig.max_displacement())}}
    text = [
        f"wrote {summary['output']}: {rig.n_shapes} shapes of {rig.source} on {tmesh.n_points} points of "
        f"{describe(target)} ({o.method} transfer through registration on {len(have)} landmarks) in {seconds:.1f} s",
        f"  target vertices to the registered generic: median {moved.info['distanceMedian']:.3g} {u}, max "
        f"{moved.info['distanceMax']:.3g} {u}; similarity scale {moved.info['similarityScale']:.3f}",
    ]
    return Result(layers={"output": out}, summary=summary, text=text)


def _generic(o: ShapesTransferOptions) -> tuple:
    """(generic, its shapes, its landmarks): the options', or the MakeHuman rig shipped with usdface;
    a generic's landmarks default to ``STEM.landmarks.layout.json`` beside it."""
    from ..usd.rig_inputs import default_generic

    generic, generic_shapes, generic_landmarks = o.generic, o.generic_shapes, o.generic_landmarks
    if generic is None:
        d = default_generic()
        generic, generic_shapes = d["mesh"], d["shapes"]
        generic_landmarks = generic_landmarks or d["landmarks"]
    if generic_landmarks is None:
        cand = Path(generic).with_name(Path(generic).name.split(".")[0] + ".landmarks.layout.json")
        if not cand.is_file():
            raise OptionError(f"shapes transfer: give the generic's landmarks with --generic-landmarks (no {cand.name} "
                              f"beside {generic})")
        generic_landmarks = cand
    return generic, generic_shapes, generic_landmarks


def _target_landmarks(path, names, mesh):
    """Landmark positions on the target: a marker layout on it, or a landmarks JSON of scan points."""
    from ..inputfiles import read_json
    from ..mesh.layout import read_layout
    from ..scan.landmarks import read_landmarks

    p = Path(path)
    data = read_json(p, label=f"--landmarks {p}")  # a regular file, bounded size and nesting, UTF-8
    fmt = data.get("format", "") if isinstance(data, dict) else ""
    if str(fmt).startswith("usdface-layout/"):
        lay = read_layout(p)
        have = [n for n in names if n in lay.names]
        return have, lay.positions(mesh, have)
    lm = read_landmarks(p)
    have = [n for n in names if n in lm.scan]
    return have, np.array([lm.scan[n] for n in have], dtype=np.float64)
