"""Import a USD file into Blender (bpy) and write what Blender shows to an .npz.

Run as ``python blender_import.py INPUT.usd OUTPUT.npz --frames 0 12 ...`` with a Python that has
the ``bpy`` wheel. This runs in its own process: bpy carries its own USD, which must never meet
usd-core's ``pxr`` in one interpreter. It imports nothing from usdface.

The .npz holds, for every mesh object Blender made: its evaluated vertices in Blender's world space
(metres, Z up, as Blender shows them; the test undoes the conversion) at each frame, the same
with every armature in its rest position, and every attribute of the evaluated mesh (name,
domain, type, and the values of one-value-per-point float attributes); plus the scene's frame
rate and range after the import, and the objects made.
"""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np


def evaluated_points(obj, depsgraph) -> np.ndarray:
    """(N, 3) world-space vertex positions of ``obj`` after modifiers, as Blender shows them."""
    ev = obj.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    try:
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
        mesh.vertices.foreach_get("co", co)
        m = np.array(ev.matrix_world, dtype=np.float64)
    finally:
        ev.to_mesh_clear()
    co = co.reshape(-1, 3)
    return co @ m[:3, :3].T + m[:3, 3]


def attributes(obj, depsgraph) -> list[dict]:
    """Every attribute of the evaluated mesh; float values for one-float-per-point attributes."""
    ev = obj.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    out = []
    try:
        for a in mesh.attributes:
            item = {"name": a.name, "domain": a.domain, "data_type": a.data_type, "length": len(a.data)}
            if a.domain == "POINT" and a.data_type == "FLOAT":
                v = np.empty(len(a.data), dtype=np.float64)
                a.data.foreach_get("value", v)
                item["values"] = v.tolist()
            out.append(item)
    finally:
        ev.to_mesh_clear()
    return out


def _animated_paths(keys) -> int:
    """How many shape-key values have animation curves."""
    action = keys.animation_data.action if keys is not None and keys.animation_data else None
    if action is None:
        return 0
    if hasattr(action, "fcurves"):  # Blender 4.x
        curves = list(action.fcurves)
    else:  # Blender 5: layered actions, curves in the strips' channel bags
        curves = [fc for layer in action.layers for strip in layer.strips for bag in strip.channelbags
                  for fc in bag.fcurves]
    return len({fc.data_path for fc in curves if fc.data_path.startswith("key_blocks")})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("--frames", type=int, nargs="+", required=True)
    args = ap.parse_args(argv)

    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.wm.usd_import(filepath=args.input)
    scene = bpy.context.scene
    info = {"blender": bpy.app.version_string, "import_result": sorted(result),
            "fps": scene.render.fps, "fps_base": scene.render.fps_base,
            "frame_start": scene.frame_start, "frame_end": scene.frame_end,
            "unit_system": scene.unit_settings.system, "scale_length": scene.unit_settings.scale_length,
            "objects": [{"name": o.name, "type": o.type, "parent": o.parent.name if o.parent else None,
                         "modifiers": [m.type for m in o.modifiers] if o.type == "MESH" else []}
                        for o in scene.objects]}
    meshes = [o for o in scene.objects if o.type == "MESH"]
    arrays = {}
    for i, obj in enumerate(meshes):
        frames, key_values = [], []
        keys = obj.data.shape_keys
        for f in args.frames:
            scene.frame_set(f)
            frames.append(evaluated_points(obj, bpy.context.evaluated_depsgraph_get()))
            if keys is not None:
                key_values.append([k.value for k in keys.key_blocks])
        arrays[f"points_{i}"] = np.stack(frames) if frames else np.zeros((0, 0, 3))
        if keys is not None:  # shape keys (Basis first) and their values at each frame
            arrays[f"shape_keys_{i}"] = np.asarray(key_values, dtype=np.float64)
    # the rest pose: every armature in its rest position, at the first frame asked for
    armatures = [o for o in scene.objects if o.type == "ARMATURE"]
    for arm in armatures:
        arm.data.pose_position = "REST"
    scene.frame_set(args.frames[0])
    depsgraph = bpy.context.evaluated_depsgraph_get()
    for i, obj in enumerate(meshes):
        arrays[f"rest_{i}"] = evaluated_points(obj, depsgraph)
    info["meshes"] = [{"name": o.name, "vertices": len(o.data.vertices), "attributes": attributes(o, depsgraph),
                       "shapeKeys": [k.name for k in o.data.shape_keys.key_blocks] if o.data.shape_keys else [],
                       "animatedShapeKeys": _animated_paths(o.data.shape_keys)}
                      for o in meshes]
    info["frames"] = list(args.frames)
    np.savez_compressed(args.output, info=np.array(json.dumps(info)), **arrays)
    return 0


if __name__ == "__main__":
    sys.exit(main())
