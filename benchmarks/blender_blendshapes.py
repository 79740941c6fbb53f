"""Import a blend-shape curves layer into Blender and compare the evaluated mesh with usdface's own.

Blender's wheel (``bpy``) pins numpy 1.26, which usdface's other dependencies (opencv, OpenImageIO,
pygeodesic: numpy >= 2) cannot share, so Blender runs in its own interpreter::

    python3.11 -m venv /path/bpy-venv && /path/bpy-venv/bin/pip install "bpy==4.5.*"
    python benchmarks/blender_blendshapes.py CURVES.usdc --blender-python /path/bpy-venv/bin/python \
        --frames 0 370 900

The same file is the script Blender's interpreter runs (``--inside-blender``): it imports the layer
alone with Blender's default USD import options, checks that the mesh has one shape key per
BlendShape and that their values are animated, and writes the world-space evaluated vertices at the
frames asked for. The usdface side (:func:`compare`) undoes Blender's unit scale and Z-up turn
(``metersPerUnit`` 0.01 -> 0.01 scale; Y-up -> Z-up = +90 degrees about X) and compares with
UsdSkel's evaluation of the layer (:func:`usdface.usd.blendshape_layer.evaluate_curves_layer`,
head motion on /Face included) and with usdface's own numpy reconstruction (neutral + weights x
offsets read back from the layer, then the head motion). Reusable: :func:`blender_evaluate` and :func:`compare`.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile


def _inside_blender(layer: str, frames: list[int], out: str) -> None:  # runs under bpy's python
    import bpy
    import numpy as np

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=layer)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    report = {"objects": [[o.name, o.type] for o in bpy.context.scene.objects], "meshes": [o.name for o in meshes]}
    target = next((o for o in meshes if o.data.shape_keys is not None), None)
    if target is None:
        report["error"] = "no mesh with shape keys"
        json.dump(report, open(out + ".json", "w"))
        return
    keys = target.data.shape_keys
    report["shapeKeys"] = [k.name for k in keys.key_blocks]
    action = keys.animation_data.action if keys.animation_data else None
    animated = {}
    if action is not None:
        for fc in action.fcurves:
            animated[fc.data_path] = len(fc.keyframe_points)
    report["animatedPaths"] = animated
    report["scene"] = {"fps": bpy.context.scene.render.fps, "frame_start": bpy.context.scene.frame_start,
                       "frame_end": bpy.context.scene.frame_end}
    points = []
    values = []
    for f in frames:
        bpy.context.scene.frame_set(int(f))
        dg = bpy.context.evaluated_depsgraph_get()
        ev = target.evaluated_get(dg)
        me = ev.to_mesh()
        co = np.empty(len(me.vertices) * 3)
        me.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3)
        m = np.array(ev.matrix_world)
        points.append(co @ m[:3, :3].T + m[:3, 3])
        ev.to_mesh_clear()
        values.append([k.value for k in keys.key_blocks])
    np.savez(out, points=np.array(points), frames=np.array(frames), values=np.array(values))
    json.dump(report, open(out + ".json", "w"))


def blender_evaluate(layer, frames, *, blender_python: str) -> tuple[dict, dict]:
    """Run Blender's interpreter on ``layer``; returns (report, arrays) with ``points`` (F, N, 3) in
    Blender's world space (metres, Z up) and the shape-key ``values`` (F, K+1, Basis first)."""
    import numpy as np

    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "blender")
        cmd = [blender_python, os.path.abspath(__file__), "--inside-blender", os.path.abspath(str(layer)),
               "--out", out, "--frames", *[str(int(f)) for f in frames]]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        if proc.returncode != 0 or not os.path.exists(out + ".json"):
            raise RuntimeError(f"Blender failed ({proc.returncode}): {proc.stderr[-2000:]}")
        report = json.load(open(out + ".json"))
        arrays = dict(np.load(out + ".npz")) if os.path.exists(out + ".npz") else {}
    return report, arrays


def compare(layer, frames, *, blender_python: str) -> dict:
    """Blender's evaluated mesh vs usdface/UsdSkel's, in the layer's units (max and RMS per frame)."""
    import numpy as np
    from pxr import Usd, UsdGeom

    from usdface.usd.blendshape_layer import evaluate_curves_layer

    report, arrays = blender_evaluate(layer, frames, blender_python=blender_python)
    if "points" not in arrays:
        return {"report": report, "ok": False}
    stage = Usd.Stage.Open(str(layer))
    mpu = UsdGeom.GetStageMetersPerUnit(stage)
    zup = UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    b = arrays["points"] / mpu  # Blender works in metres
    if not zup:  # Blender turned Y-up into Z-up: (x, y, z) -> (x, -z, y); undo it
        b = np.stack([b[..., 0], b[..., 2], -b[..., 1]], axis=-1)
    _, ours = evaluate_curves_layer(layer, times=frames)
    err = np.linalg.norm(b - ours, axis=2)
    # usdface's own reconstruction, without UsdSkel: neutral + weights x offsets, then the head motion
    from usdface.blendshape.curves import interpolate_rigid
    from usdface.usd.blendshape_layer import head_motion_of_layer, read_blendshape_rig, read_curves_layer

    rig = read_blendshape_rig(layer)
    curves = read_curves_layer(layer)
    w = np.stack([np.interp(frames, curves["times"], curves["weights"][:, k]) for k in range(len(curves["names"]))],
                 axis=1)
    order = [curves["names"].index(n) for n in rig.names]
    posed = rig.mesh.points[None] + np.einsum("fk,knd->fnd", w[:, order], rig.deltas)
    head = head_motion_of_layer(layer)
    if head is not None:
        hm = interpolate_rigid(head[0], head[1], frames)
        posed = np.einsum("fij,fnj->fni", hm[:, :3, :3], posed) + hm[:, None, :3, 3]
    err_numpy = np.linalg.norm(b - posed, axis=2)
    motion = np.linalg.norm(ours - ours[:1], axis=2).max(axis=1)
    return {"report": report, "ok": True, "frames": list(map(int, frames)),
            "maxError": [float(e.max()) for e in err], "rmsError": [float(np.sqrt((e ** 2).mean())) for e in err],
            "maxErrorNumpy": [float(e.max()) for e in err_numpy],
            "motionFromFirstFrame": [float(m) for m in motion], "units": "layer units"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("layer")
    ap.add_argument("--frames", type=int, nargs="+", default=[0])
    ap.add_argument("--blender-python", default=os.environ.get("USDFACE_BLENDER_PYTHON"))
    ap.add_argument("--inside-blender", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.inside_blender:
        _inside_blender(args.layer, args.frames, args.out)
        return 0
    if not args.blender_python:
        ap.error("give --blender-python (an interpreter with bpy) or set USDFACE_BLENDER_PYTHON")
    res = compare(args.layer, args.frames, blender_python=args.blender_python)
    rep = res["report"]
    print(f"Blender objects: {rep.get('objects')}")
    print(f"shape keys: {len(rep.get('shapeKeys', []))} (Basis + {len(rep.get('shapeKeys', [])) - 1}); animated "
          f"paths: {len(rep.get('animatedPaths', {}))}; keys per path (first 3): "
          f"{list(rep.get('animatedPaths', {}).items())[:3]}")
    if res["ok"]:
        for f, mx, rms, mn, mo in zip(res["frames"], res["maxError"], res["rmsError"], res["maxErrorNumpy"],
                                      res["motionFromFirstFrame"]):
            print(f"frame {f}: Blender vs UsdSkel max {mx:.2e} rms {rms:.2e}; vs usdface's numpy reconstruction max "
                  f"{mn:.2e} (the mesh moves up to {mo:.3f} from frame {res['frames'][0]})")
    return 0 if res["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
