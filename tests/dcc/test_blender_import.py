"""Blender imports usdface's deliverables alone and plays what USD composes (issue 10, item 8).

Each file is imported by itself into an empty Blender scene (``bpy.ops.wm.usd_import`` with its
defaults, as a user would) and Blender's evaluated mesh (modifiers, armature, mesh sequence cache
applied) is compared, in USD world space, with the point cache as usdface's evaluator composes
``shot.usda``. Blender's conversion (metres: scale metersPerUnit; Z up: +90 degrees about X) is
undone from the layer's own metadata. Frames: 0, the frame of largest Chin displacement, and the
5 frames where UsdSkel's skinning of ``shot_skel.usda`` is furthest from the point cache.
"""
from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd, UsdGeom

from usdface.usd.capture_layer import read_capture_layer
from usdface.usd.face_evaluator import FaceEvaluator

POINTS_TOL = 0.01   # cm: a point cache must play exactly (float32 in metres)
REST_TOL = 0.01     # cm: the skeleton shot's rest pose is the mesh
SKIN_TOL = 0.25     # cm: DCC-safe weights at K = 8 through Blender's armature


def to_usd_world(points_b: np.ndarray, layer) -> np.ndarray:
    """Blender world space (metres, Z up) -> the layer's world space (its units, its up axis)."""
    stage = Usd.Stage.Open(str(layer))
    scale = UsdGeom.GetStageMetersPerUnit(stage)
    p = np.asarray(points_b, dtype=np.float64) / scale
    if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y:  # Blender turned +Y up into +Z up
        p = np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)
    return p


@pytest.fixture(scope="module")
def reference(jaw_outputs):
    """The point cache in world space at the frames to test, and the skeleton shot's rest pose."""
    points = FaceEvaluator.open(jaw_outputs / "shot.usda")
    skel = FaceEvaluator.open(jaw_outputs / "shot_skel.usda")
    cache = points.points_range()
    skinned = skel.points_range()
    usdskel_error = np.linalg.norm(skinned - cache, axis=2).max(axis=1)
    capture = read_capture_layer(jaw_outputs / "capture.usdc")
    chin = capture.positions[:, capture.index("Chin")]
    chin_frame = int(np.nanargmax(np.linalg.norm(chin - chin[capture.neutral_frame], axis=1)))
    worst = [int(f) for f in np.argsort(usdskel_error)[::-1][:5]]
    frames = sorted({0, chin_frame, *worst})
    times = points.default_times()
    idx = [int(np.flatnonzero(times == f)[0]) for f in frames]
    print(f"frames: 0, Chin {chin_frame}, worst UsdSkel {worst} "
          f"(UsdSkel vs point cache there: {np.round(usdskel_error[worst], 4).tolist()} cm)")
    return {"frames": frames, "cache": cache[idx], "n_points": points.n_points,
            "skel_rest": skel.rest_points(space="world", time=frames[0]), "usdskel_error": usdskel_error[idx]}


def _imported_mesh(result, n_points, name):
    i = result.mesh_with(n_points)
    assert i is not None, f"Blender imported no mesh with {n_points} vertices from {name}: {result.describe()}"
    return i


def _errors(result, i, reference, layer) -> np.ndarray:
    got = to_usd_world(result.points[i], layer)
    return np.linalg.norm(got - reference["cache"], axis=2).max(axis=1)


def test_points_shot_plays_the_point_cache(blender, jaw_outputs, reference, tmp_path):
    layer = jaw_outputs / "shot.usda"
    result = blender(layer, reference["frames"], workdir=tmp_path)
    i = _imported_mesh(result, reference["n_points"], layer.name)
    err = _errors(result, i, reference, layer)
    print(f"Blender {result.info['blender']} shot.usda vs point cache (cm) at {reference['frames']}: "
          f"{np.round(err, 5).tolist()}; scene fps after import {result.info['fps']}, "
          f"frames {result.info['frame_start']}..{result.info['frame_end']}")
    assert err.max() <= POINTS_TOL


def test_skeleton_shot_rests_on_the_mesh_and_follows_the_point_cache(blender, jaw_outputs, reference, tmp_path):
    layer = jaw_outputs / "shot_skel.usda"
    result = blender(layer, reference["frames"], workdir=tmp_path)
    i = _imported_mesh(result, reference["n_points"], layer.name)
    rest = to_usd_world(result.rest[i], layer)
    rest_err = np.linalg.norm(rest - reference["skel_rest"], axis=1).max()
    err = _errors(result, i, reference, layer)
    print(f"Blender shot_skel.usda: rest pose vs mesh {rest_err:.4g} cm; vs point cache (cm) at "
          f"{reference['frames']}: {np.round(err, 4).tolist()} (UsdSkel: "
          f"{np.round(reference['usdskel_error'], 4).tolist()})")
    assert rest_err <= REST_TOL
    assert err.max() <= SKIN_TOL


def test_animation_layer_alone_imports_the_animated_mesh(blender, jaw_outputs, reference, tmp_path):
    layer = jaw_outputs / "anim.usdc"
    result = blender(layer, reference["frames"], workdir=tmp_path)
    i = _imported_mesh(result, reference["n_points"], layer.name)
    err = _errors(result, i, reference, layer)
    print(f"Blender anim.usdc alone vs point cache (cm): {np.round(err, 5).tolist()}")
    assert err.max() <= POINTS_TOL


def test_skeleton_layer_alone_imports_the_animated_mesh(blender, jaw_outputs, reference, tmp_path):
    layer = jaw_outputs / "skel.usdc"
    result = blender(layer, reference["frames"], workdir=tmp_path)
    i = _imported_mesh(result, reference["n_points"], layer.name)
    err = _errors(result, i, reference, layer)
    print(f"Blender skel.usdc alone vs point cache (cm): {np.round(err, 4).tolist()}")
    assert err.max() <= SKIN_TOL
    moved = np.linalg.norm(result.points[i] - result.points[i][:1], axis=2).max() / 0.01
    assert moved > 0.5  # cm: the mesh is animated, not a still rest pose


def test_blend_shape_layer_alone_imports_as_animated_shape_keys(blender, jaw_outputs, reference, tmp_path):
    """blendshapes.usdc alone: the mesh with its 52 shapes as shape keys whose values are animated,
    and Blender's evaluated mesh equal to usdface's own reconstruction (the shared evaluator:
    UsdSkel blend shapes and the head motion on /Face) within 0.01 cm (issue 11)."""
    layer = jaw_outputs / "blendshapes.usdc"
    ours = FaceEvaluator.open(layer)
    frames = reference["frames"]
    expected = ours.points_range([float(f) for f in frames])
    result = blender(layer, frames, workdir=tmp_path)
    i = _imported_mesh(result, reference["n_points"], layer.name)
    mesh = result.info["meshes"][i]
    assert len(mesh["shapeKeys"]) == 53 and mesh["shapeKeys"][0] == "Basis"  # Basis + the rig's 52 shapes
    assert mesh["animatedShapeKeys"] >= 40  # every solved shape has a curve (eyeLook*, tongueOut held at 0)
    values = result.shape_keys[i]
    assert values is not None and np.ptp(values[:, 1:], axis=0).max() > 0.2  # the first jaw drop moves a key
    err = np.linalg.norm(to_usd_world(result.points[i], layer) - expected, axis=2).max(axis=1)
    print(f"Blender blendshapes.usdc alone vs usdface's evaluation (cm) at {frames}: {np.round(err, 6).tolist()}")
    assert err.max() <= POINTS_TOL


@pytest.mark.parametrize("name", ["shot.usda", "shot_skel.usda", "shot_blendshapes.usda"])
def test_usdface_attributes_carry_one_value_per_point(blender, jaw_outputs, reference, tmp_path, name):
    """No usdface primvar reaches Blender as a junk per-point attribute: every imported usdface
    attribute comes from a primvar with one value per point and holds that primvar's values."""
    layer = jaw_outputs / name
    result = blender(layer, reference["frames"], workdir=tmp_path)
    i = _imported_mesh(result, reference["n_points"], name)
    attrs = [a for a in result.info["meshes"][i]["attributes"] if a["name"].lower().startswith("usdface")]
    evaluator = FaceEvaluator.open(layer)  # keeps the stage open
    primvars = {p.GetPrimvarName(): p for p in UsdGeom.PrimvarsAPI(evaluator.prim).GetPrimvars()}
    primvars |= {name.replace(":", "_"): p for name, p in primvars.items()}  # Blender may rename ':' to '_'
    bad = []
    for a in attrs:
        primvar = primvars.get(a["name"])
        assert primvar, f"{name}: Blender attribute {a['name']} matches no primvar of {evaluator.mesh_path}"
        values = np.asarray(primvar.Get(), dtype=np.float64)
        if primvar.GetElementSize() != 1 or values.size != a["length"]:
            bad.append(f"{a['name']} (primvar elementSize {primvar.GetElementSize()}, {values.size} values "
                       f"for {a['length']} points)")
        elif "values" in a and np.abs(np.asarray(a["values"]) - values).max() > 1e-6 * max(1, np.abs(values).max()):
            bad.append(f"{a['name']} (values differ from the primvar's)")
    print(f"{name}: usdface attributes in Blender: {[a['name'] for a in attrs]}")
    assert not bad, f"{name}: usdface attributes with more than one value per point in Blender: {bad}"
