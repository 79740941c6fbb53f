"""`usdface shapes transfer`: a generic blend-shape rig carried onto a face that has none.

The generic face is registered onto the target with ``usdface register``'s algorithm
(:class:`usdface.scan.register.GenericRegistration`: similarity, thin-plate warp, closest-point
projection; the target's topology is never used), then every shape is transferred
(:mod:`usdface.blendshape.transfer`). The output is a rig layer (mesh, BlendShape prims, a
skeleton binding, no animation) that ``usdface solve --mesh RIG.usdc`` takes as it is.

The default generic is the MakeHuman rig shipped in ``usdface/resources/generic`` (the face mesh, its
52 ARKit shapes and its 20 landmarks), so it works from an installed package.
"""
from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from ..errors import InputError, OptionError, list_names

log = logging.getLogger("usdface")

__all__ = ["transfer_shapes", "default_generic", "register_cli"]


def default_generic() -> dict:
    """Paths of the default generic rig (MakeHuman, CC0), shipped with the package
    (``usdface/resources/generic``)."""
    root = Path(__file__).resolve().parents[1] / "resources" / "generic"
    paths = {"mesh": root / "makehuman_hm08_face_cm.usdc",
             "shapes": root / "makehuman_hm08_face_units_cm.npz",
             "landmarks": root / "makehuman_hm08_face.landmarks.layout.json"}
    missing = [str(p) for p in paths.values() if not p.is_file()]
    if missing:
        raise InputError(f"the default generic rig is missing from this installation ({list_names(missing)}); "
                         "reinstall usdface, or give --generic RIG (and --generic-landmarks)")
    return paths


def _target_landmarks(path, names, mesh):
    """Landmark positions on the target: a marker layout on it, or a landmarks JSON of scan points."""
    import json

    from ..mesh.layout import read_layout
    from ..scan.landmarks import read_landmarks

    p = Path(path)
    try:
        fmt = json.loads(p.read_text()).get("format", "")
    except (OSError, ValueError, AttributeError):
        fmt = ""
    if str(fmt).startswith("usdface-layout/"):
        lay = read_layout(p)
        have = [n for n in names if n in lay.names]
        return have, lay.positions(mesh, have)
    lm = read_landmarks(p)
    have = [n for n in names if n in lm.scan]
    return have, np.array([lm.scan[n] for n in have], dtype=np.float64)


def transfer_shapes(target, output, *, generic=None, generic_shapes=None, generic_landmarks=None, landmarks=None,
                    method="displacement", border=True, field=8, iterations=20, mesh_units=None) -> dict:
    """Register the generic onto ``target`` and transfer its shapes; write the rig layer.

    Parameters
    ----------
    target : path
        The face without a rig (mesh file or USD mesh layer).
    output : path
        Rig layer (.usdc/.usda).
    generic, generic_shapes : paths, optional
        The generic rig (as ``solve --mesh/--shapes``); default the MakeHuman rig.
    generic_landmarks : path, optional
        The generic's landmarks as a marker layout (default: beside the generic, or MakeHuman's).
    landmarks : path
        The target's landmarks: a marker layout on it, or a landmarks JSON with scan points.
    method : {"displacement", "deformation"}
        How each shape moves onto the registered generic (:mod:`usdface.blendshape.transfer`).
    border, field, iterations
        ``usdface register``'s options (the defaults here: ``--border --field 8``, the setting
        for target meshes cropped like the generic).
    """
    from ..blendshape.transfer import TRANSFER_METHODS, transfer_rig
    from ..mesh.layout import read_layout
    from ..mesh.topology import find_hole_regions
    from ..scan.landmarks import FACE_LANDMARKS
    from ..scan.register import GenericRegistration, RegistrationParameters
    from ..usd.blendshape_layer import write_curves_layer
    from ..usd.layers import check_output_path, provenance
    from .import_mesh import load_mesh
    from .solve import _check_outputs, load_rig

    t0 = time.perf_counter()
    if method not in TRANSFER_METHODS:
        raise OptionError(f"--method {method}: expected one of {', '.join(TRANSFER_METHODS)}")
    out = check_output_path(output)
    if generic is None:
        d = default_generic()
        generic, generic_shapes = d["mesh"], d["shapes"]
        generic_landmarks = generic_landmarks or d["landmarks"]
    if landmarks is None:
        raise OptionError("shapes transfer: give the target's landmarks with --landmarks (a marker layout on the "
                          "target, or {\"name\": {\"scan\": [x, y, z]}}); registration starts from them")
    if generic_landmarks is None:
        cand = Path(generic).with_name(Path(generic).name.split(".")[0] + ".landmarks.layout.json")
        if not cand.is_file():
            raise OptionError(f"shapes transfer: give the generic's landmarks with --generic-landmarks (no {cand.name} "
                              f"beside {generic})")
        generic_landmarks = cand
    _check_outputs({"--target": target, "--generic": generic, "--generic-shapes": generic_shapes},
                   {"-o": (output, "usd")})
    rig, g_regions = load_rig(generic, generic_shapes, mesh_units=mesh_units)
    tmesh, t_regions = load_mesh(target, units=mesh_units)
    tmesh.check_degenerate()
    if not t_regions:
        t_regions = find_hole_regions(tmesh)
    if rig.units and tmesh.units and rig.units != tmesh.units:
        raise InputError(f"generic rig in {rig.units}, target {target} in {tmesh.units}: import one in the other's "
                         "units (--mesh-units)")
    glay = read_layout(generic_landmarks)
    names = [n for n in glay.names if n in FACE_LANDMARKS] or list(glay.names)
    have, tl = _target_landmarks(landmarks, names, tmesh)
    if len(have) < 4:
        raise InputError(f"shapes transfer: only {len(have)} landmark(s) shared by {landmarks} and {generic_landmarks}; "
                         "at least 4 are needed (20 recommended)")
    gl = glay.positions(rig.mesh, have)
    reg = GenericRegistration(rig.mesh, g_regions, gl).register(
        tmesh.points, tmesh.triangles(), tl, RegistrationParameters(iterations=iterations,
                                                                    border_weight=1.0 if border else 0.0,
                                                                    field_iterations=field))
    moved = transfer_rig(rig, g_regions, reg.points, tmesh, t_regions, method=method)
    prov = provenance("shapes transfer", options={"method": method, "border": border, "field": field,
                                                  "iterations": iterations, "landmarks": have},
                      inputs={"generic": generic, "genericShapes": generic_shapes if generic_shapes and
                              Path(generic_shapes).is_file() else None, "target": target, "landmarks": landmarks,
                              "genericLandmarks": generic_landmarks})
    write_curves_layer(out, mesh=tmesh, regions=t_regions, names=rig.names, deltas=moved.rig.deltas, times=None,
                       weights=np.zeros(rig.n_shapes), rate=None, start=None, end=None, prov=prov,
                       report={"transfer": moved.info})
    seconds = time.perf_counter() - t0
    u = tmesh.units or "units"
    summary = {"output": str(out), "shapes": rig.n_shapes, "points": tmesh.n_points, "method": method,
               "landmarks": have, "registration": {"scale": float(reg.similarity[0]),
                                                   "landmarkResidualMean": float(reg.landmark_residuals.mean())},
               "correspondence": moved.info, "seconds": round(seconds, 3),
               "maxDisplacement": {n: round(float(v), 4) for n, v in zip(rig.names, moved.rig.max_displacement())}}
    summary["_text"] = [
        f"wrote {out}: {rig.n_shapes} shapes of {rig.source} on {tmesh.n_points} points of {target} ({method} transfer "
        f"through registration on {len(have)} landmarks) in {seconds:.1f} s",
        f"  target vertices to the registered generic: median {moved.info['distanceMedian']:.3g} {u}, max "
        f"{moved.info['distanceMax']:.3g} {u}; similarity scale {moved.info['similarityScale']:.3f}",
    ]
    return summary


def register_cli(sub) -> None:
    """Add `usdface shapes transfer` to the CLI (`rig` already names the muscle rig)."""
    from ..cliargs import add_common_options

    p = sub.add_parser("shapes", help="blend-shape rigs: transfer a generic rig onto a face without one",
                       description="Blend-shape rig tools.")
    shapes_sub = p.add_subparsers(dest="shapes_command", metavar="ACTION", required=True)
    t = shapes_sub.add_parser("transfer", help="register a generic rig onto a face and transfer its shapes",
                              description="Register the generic face onto TARGET (similarity, thin-plate warp, "
                                          "closest-point projection, as `usdface register`; the target's topology is "
                                          "not used) and carry every blend shape over; writes a rig layer for "
                                          "`usdface solve --mesh RIG.usdc`.")
    t.add_argument("--target", required=True, help="the face without a rig (OBJ, PLY, ... or a USD mesh layer)")
    t.add_argument("--landmarks", required=True,
                   help="the target's landmarks: a marker layout on it, or {\"name\": {\"scan\": [x, y, z]}}")
    t.add_argument("--generic", help="generic rig: a USD mesh with blend shapes, or a neutral mesh with "
                                     "--generic-shapes (default: the MakeHuman rig of sample_assets)")
    t.add_argument("--generic-shapes", metavar="DIR|NPZ|RIG.usd", help="the generic neutral's shapes")
    t.add_argument("--generic-landmarks", help="the generic's landmarks (marker layout)")
    t.add_argument("--method", choices=["displacement", "deformation"], default="displacement",
                   help="offsets rotated and scaled with the face (default), or deformation transfer "
                        "(Sumner & Popovic 2004) following the target's local shape")
    t.add_argument("--no-border", dest="border", action="store_false",
                   help="do not match the outer borders (for targets not cropped like the generic)")
    t.add_argument("--field", type=int, default=8, metavar="N", help="registration smooth-field iterations (default 8)")
    t.add_argument("--iterations", type=int, default=20, help="registration closest-point iterations (default 20)")
    t.add_argument("--mesh-units", choices=["mm", "cm", "dm", "m", "in", "ft"], help="units of mesh files")
    t.add_argument("-o", "--output", required=True, help="rig layer to write (.usdc)")
    add_common_options(t)
    t.set_defaults(func=_cmd_transfer)


def _cmd_transfer(args) -> dict:
    return transfer_shapes(args.target, args.output, generic=args.generic, generic_shapes=args.generic_shapes,
                           generic_landmarks=args.generic_landmarks, landmarks=args.landmarks, method=args.method,
                           border=args.border, field=args.field, iterations=args.iterations,
                           mesh_units=args.mesh_units)
