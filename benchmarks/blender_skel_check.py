"""Hand check: import a skeleton deliverable into Blender (bpy) and compare with the point cache.

Run (two interpreters: bpy 4.5 pins numpy < 2, usdface needs numpy >= 2, so Blender lives in its
own venv; this script drives it in a subprocess):

    python benchmarks/blender_skel_check.py OUTDIR --bpy-python /path/to/venv-with-bpy/bin/python \\
        [--file skel.usdc] [--frames 0 441]

OUTDIR is a `usdface run --output-kind both` folder (mesh.usdc, capture.usdc, binding.usda,
analysis.usdc, skel.usdc, shot_skel.usda, ...). The point cache is recomputed here with the
transfer (the same numbers anim.usdc holds) and moved by the head motion H_mesh(f) (decision D1).
Blender imports with ``bpy.ops.wm.usd_import`` (defaults), the mesh is evaluated (depsgraph,
``evaluated_get``, ``matrix_world``) at frame 0, the frame of largest Chin displacement and any
--frames given; Blender's 0.01 scale and Y-up -> Z-up are undone. Prints what Blender built
(objects, armature, shape keys and their slider ranges, animated objects) and the errors (cm).
Not run by the tests (the DCC tests in the suite are separate).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np


def blender_side(usd_file: str, frames: list[int], out_npz: str) -> None:
    """Runs inside the bpy interpreter: import, evaluate, save world-space vertices (metres, Z-up)."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=usd_file)
    scene = bpy.context.scene
    report = {"objects": [], "fps": scene.render.fps, "frame_range": [scene.frame_start, scene.frame_end]}
    for o in scene.objects:
        entry = {"name": o.name, "type": o.type, "parent": o.parent.name if o.parent else None,
                 "animated": bool(o.animation_data and o.animation_data.action),
                 "matrix_world_rest": str(np.round(np.array(o.matrix_world), 4).tolist())}
        if o.animation_data and o.animation_data.action:
            act = o.animation_data.action
            try:
                curves = act.fcurves
            except AttributeError:  # layered actions (Blender 4.4+)
                curves = [c for layer in act.layers for strip in layer.strips
                          for bag in strip.channelbags for c in bag.fcurves]
            paths = sorted({c.data_path for c in curves})
            entry["fcurves"] = len(paths)
            entry["fcurve_kinds"] = sorted({p.rsplit(".", 1)[-1] for p in paths})
        if o.type == "MESH":
            me = o.data
            entry["vertices"] = len(me.vertices)
            entry["vertex_groups"] = len(o.vertex_groups)
            entry["modifiers"] = [m.type for m in o.modifiers]
            if me.shape_keys:
                kb = me.shape_keys.key_blocks
                entry["shape_keys"] = len(kb)
                entry["slider_range"] = str(sorted({(round(k.slider_min, 3), round(k.slider_max, 3)) for k in kb}))
                sk_anim = me.shape_keys.animation_data
                entry["shape_keys_animated"] = bool(sk_anim and sk_anim.action)
            counts = [sum(1 for g in v.groups if g.weight > 0) for v in me.vertices]
            entry["max_groups_per_vertex"] = max(counts) if counts else 0
        if o.type == "ARMATURE":
            entry["bones"] = len(o.data.bones)
        report["objects"].append(entry)
    meshes = [o for o in scene.objects if o.type == "MESH"]
    pts = []
    for f in frames:
        scene.frame_set(f)
        dg = bpy.context.evaluated_depsgraph_get()
        eo = meshes[0].evaluated_get(dg)
        me = eo.to_mesh()
        co = np.empty(len(me.vertices) * 3)
        me.vertices.foreach_get("co", co)
        mw = np.array(eo.matrix_world)
        pts.append(co.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3])
        eo.to_mesh_clear()
    np.savez(out_npz, points=np.stack(pts), frames=np.asarray(frames), report=json.dumps(report))


def point_cache(outdir: Path):
    """Mesh rest points, the point cache in world space (head motion applied) and stabilised (F, N, 3),
    the frame of largest Chin displacement and the capture's first time code."""
    from usdface.capture.retarget import marker_displacements
    from usdface.processors.skel import apply_matrix, effective_displacements
    from usdface.processors.transfer import build_transfer_solver, load_transfer_inputs
    from usdface.skel import head_motion_in_mesh_space

    mesh, cap, binding, dm = load_transfer_inputs(outdir / "mesh.usdc", outdir / "capture.usdc",
                                                  outdir / "binding.usda", outdir / "analysis.usdc")
    disp = marker_displacements(cap, binding.names, binding.displacement_transform())
    solver, _ = build_transfer_solver(mesh, binding, dm)
    d_eff, _ = effective_displacements(solver, disp)
    cache = stabilised = mesh.points[None] + apply_matrix(solver.transfer_matrix, d_eff)
    if cap.head_motion is not None:
        rel = np.einsum("ij,fjk->fik", np.linalg.inv(cap.head_motion[cap.neutral_frame]), cap.head_motion)
        hm = head_motion_in_mesh_space(rel, binding.capture_to_mesh)
        cache = np.einsum("fij,fnj->fni", hm[:, :3, :3], cache) + hm[:, None, :3, 3]
    chin = list(binding.names).index("Chin") if "Chin" in binding.names else 0
    chin_frame = int(np.nanargmax(np.linalg.norm(d_eff[:, chin], axis=1)))
    return mesh.points, cache, stabilised, chin_frame, cap.start_frame


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("outdir", type=Path)
    ap.add_argument("--bpy-python", required=True, help="a Python interpreter that can import bpy")
    ap.add_argument("--file", default="skel.usdc", help="the file to import, in OUTDIR (default skel.usdc)")
    ap.add_argument("--frames", type=int, nargs="*", default=[])
    ap.add_argument("--worst", type=int, default=5, help="also the N frames of largest UsdSkel error (default 5)")
    ap.add_argument("--blender-side", nargs=3, metavar=("USD", "FRAMES", "NPZ"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.blender_side:
        usd, frames, npz = args.blender_side
        blender_side(usd, [int(f) for f in frames.split(",")], npz)
        return 0
    from usdface.usd.skel_layer import skinned_points

    rest, cache, stabilised, chin_frame, start = point_cache(args.outdir)
    _, usdskel = skinned_points(args.outdir / args.file, space="world")
    usdskel_err = np.linalg.norm(usdskel - cache, axis=2).max(axis=1)
    worst = [int(f) for f in np.argsort(-usdskel_err)[:args.worst]]
    frames = sorted({0, chin_frame, *worst, *args.frames})
    with tempfile.TemporaryDirectory() as tmp:
        npz = str(Path(tmp) / "blender.npz")
        subprocess.run([args.bpy_python, __file__, str(args.outdir), "--bpy-python", args.bpy_python,
                        "--blender-side", str(args.outdir / args.file), ",".join(str(start + f) for f in frames), npz],
                       check=True)
        data = np.load(npz)
        report = json.loads(str(data["report"]))
        got = data["points"]
    # Blender: metres, Z-up (x, -z, y) of the USD Y-up layer; back to cm, Y-up
    got_usd = np.stack([got[..., 0], got[..., 2], -got[..., 1]], axis=-1) / 0.01
    print(json.dumps(report, indent=1, default=str))
    print(f"{args.file}: Blender {bpy_version(args.bpy_python)} vs point cache (cm)")
    for i, f in enumerate(frames):
        err = np.linalg.norm(got_usd[i] - cache[f], axis=1)
        still = np.linalg.norm(got_usd[i] - stabilised[f], axis=1).max()
        rest_err = np.linalg.norm(got_usd[i] - rest, axis=1).max()
        label = ("frame 0" if f == 0 else "largest Chin displacement" if f == chin_frame
                 else "large UsdSkel error" if f in worst else "")
        vs_usdskel = np.linalg.norm(got_usd[i] - usdskel[f], axis=1).max()
        print(f"  frame {f:5d} {label:27s} max {err.max():.4f}  rms {np.sqrt((err ** 2).mean()):.4f}  "
              f"UsdSkel max {usdskel_err[f]:.4f}  Blender vs UsdSkel {vs_usdskel:.4f}  "
              f"(max distance from the stabilised point cache {still:.4f}, from the mesh at rest {rest_err:.4f}; "
              f"head motion moves the face up to {np.linalg.norm(cache[f] - stabilised[f], axis=1).max():.4f})")
    return 0


def bpy_version(python: str) -> str:
    out = subprocess.run([python, "-c", "import bpy; print(bpy.app.version_string)"], capture_output=True, text=True)
    return out.stdout.strip().splitlines()[-1] if out.stdout.strip() else "?"


if __name__ == "__main__":
    sys.exit(main())
