"""The face evaluator on real outputs of `usdface run` (Jaw take on the MakeHuman face, 300 frames).

The skinned shot is checked against blend shapes and linear blend skinning written here with numpy
from the layer's raw attributes (blend-shape offsets and weights, joints, bind/rest transforms, joint
animation, influences): no UsdSkel query is involved in the reference.
"""
from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdSkel
from scipy.spatial.transform import Rotation

from usdface.cli import main
from usdface.usd.face_evaluator import FaceEvaluator

SKIN_TOL = 1e-4  # cm: float32 skinning of a face ~80 cm from the origin


@pytest.fixture(scope="module")
def shot(tmp_path_factory, sample_assets):
    out = tmp_path_factory.mktemp("evaluate_shot")
    code = main(["run", "--mesh", str(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj"),
                 "--capture", str(sample_assets / "capture" / "JawMoCap.ma"),
                 "--layout", str(sample_assets / "layouts" / "makehuman_hm08_face.layout.json"),
                 "--output-kind", "both", "--trim", "0", "300", "-o", str(out), "-q"])
    assert code == 0
    return out


def _col(m) -> np.ndarray:
    return np.array(m, dtype=np.float64).T


def lbs_by_hand(path, times) -> np.ndarray:
    """World-space blend shapes + linear blend skinning of the face mesh of ``path`` from its raw attributes."""
    stage = Usd.Stage.Open(str(path))
    geom = next(p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh))
    skel_prim = stage.GetPrimAtPath(geom.GetRelationship("skel:skeleton").GetTargets()[0])
    joints = list(skel_prim.GetAttribute("joints").Get())
    parents = [joints.index(j.rsplit("/", 1)[0]) if "/" in j else -1 for j in joints]
    bind = np.stack([_col(m) for m in skel_prim.GetAttribute("bindTransforms").Get()])
    rest = np.stack([_col(m) for m in skel_prim.GetAttribute("restTransforms").Get()])
    anim = stage.GetPrimAtPath(skel_prim.GetRelationship("skel:animationSource").GetTargets()[0])
    anim_joints = list(anim.GetAttribute("joints").Get())
    idx_attr = geom.GetAttribute("primvars:skel:jointIndices")
    k = int(idx_attr.GetMetadata("elementSize") or 1)
    idx = np.asarray(idx_attr.Get(), dtype=np.int64).reshape(-1, k)
    w = np.asarray(geom.GetAttribute("primvars:skel:jointWeights").Get(), dtype=np.float64).reshape(-1, k)
    gbind_attr = geom.GetAttribute("primvars:skel:geomBindTransform")
    gbind = _col(gbind_attr.Get()) if gbind_attr and gbind_attr.HasValue() else np.eye(4)
    rest_pts = np.asarray(geom.GetAttribute("points").Get(), dtype=np.float64)
    shape_names = list(geom.GetAttribute("skel:blendShapes").Get() or [])
    targets = geom.GetRelationship("skel:blendShapeTargets").GetTargets() if shape_names else []
    offsets = {n: np.asarray(stage.GetPrimAtPath(t).GetAttribute("offsets").Get(), dtype=np.float64)
               for n, t in zip(shape_names, targets)}  # dense offsets (usdface writes no pointIndices)
    anim_shapes = list(anim.GetAttribute("blendShapes").Get() or []) if shape_names else []
    out = []
    for t in times:
        base = rest_pts.copy()
        if anim_shapes:
            for name, wt in zip(anim_shapes, anim.GetAttribute("blendShapeWeights").Get(t)):
                base += float(wt) * offsets[name]
        q = np.c_[base, np.ones(len(base))] @ gbind.T
        local = rest.copy()
        tr = np.asarray(anim.GetAttribute("translations").Get(t), dtype=np.float64)
        rot = np.asarray(anim.GetAttribute("rotations").Get(t), dtype=np.float64)  # (J, 4): i, j, k, real
        sc = np.asarray(anim.GetAttribute("scales").Get(t), dtype=np.float64)
        for a, name in enumerate(anim_joints):
            m = np.eye(4)
            m[:3, :3] = Rotation.from_quat(rot[a]).as_matrix() @ np.diag(sc[a])
            m[:3, 3] = tr[a]
            local[joints.index(name)] = m
        skel_space = np.empty_like(local)
        for j, p in enumerate(parents):
            skel_space[j] = local[j] if p < 0 else skel_space[p] @ local[j]
        xf = skel_space @ np.linalg.inv(bind)  # (J, 4, 4) skinning transforms
        skinned = np.zeros((len(q), 3))
        for kk in range(k):
            skinned += w[:, kk, None] * np.einsum("nij,nj->ni", xf[idx[:, kk]], q)[:, :3]
        to_world = _col(UsdGeom.Xformable(skel_prim).ComputeLocalToWorldTransform(Usd.TimeCode(t)))
        out.append(skinned @ to_world[:3, :3].T + to_world[:3, 3])
    return np.stack(out)


def _jaw_open_frame(ev: FaceEvaluator) -> int:
    p = ev.points_range(space="mesh")
    return int(np.linalg.norm(p - ev.rest_points()[None], axis=2).max(axis=1).argmax())


def test_skeleton_shot_matches_skinning_by_hand(shot):
    ev = FaceEvaluator.open(shot / "shot_skel.usda")
    assert ev.deformation == ("blendShapes", "skinning") and ev.n_points == 2020 and ev.rate == 60
    assert ev.time_codes[0] == 0 and ev.time_codes.size == 300
    times = [0, 37, 150, 299, _jaw_open_frame(ev)]
    ref = lbs_by_hand(shot / "shot_skel.usda", times)
    got = ev.points_range(times)
    err = np.linalg.norm(got - ref, axis=2).max()
    print(f"evaluator vs LBS by hand on shot_skel.usda: max {err:.3g} cm")
    assert err < SKIN_TOL
    # the skinned face moves (the jaw opens) far beyond the tolerance
    assert np.linalg.norm(got[-1] - ev.rest_points(space="world", time=times[-1]), axis=1).max() > 0.5


def test_skeleton_layer_alone_equals_the_shot(shot):
    alone = FaceEvaluator.open(shot / "skel.usdc")
    composed = FaceEvaluator.open(shot / "shot_skel.usda")
    assert alone.deformation == ("blendShapes", "skinning")
    assert np.array_equal(alone.points_range(), composed.points_range())


def test_point_cache_shot_and_its_layer_alone(shot):
    ev = FaceEvaluator.open(shot / "shot.usda")
    assert ev.deformation == ("points",) and ev.time_codes.size == 300
    stage = Usd.Stage.Open(str(shot / "anim.usdc"))
    geom = next(p for p in Usd.PrimRange.Stage(stage, Usd.PrimAllPrimsPredicate) if p.HasAttribute("points"))
    composed = Usd.Stage.Open(str(shot / "shot.usda"))
    xformable = UsdGeom.Xformable(composed.GetPrimAtPath(geom.GetPath()))
    for t in (0, 120, 299):
        raw = np.asarray(geom.GetAttribute("points").Get(t), dtype=np.float64)
        m = _col(xformable.ComputeLocalToWorldTransform(Usd.TimeCode(t)))
        assert np.array_equal(ev.points(t, space="mesh"), raw)
        assert np.abs(ev.points(t) - (raw @ m[:3, :3].T + m[:3, 3])).max() < 1e-9
    alone = FaceEvaluator.open(shot / "anim.usdc")
    assert np.array_equal(alone.points_range(space="mesh"), ev.points_range(space="mesh"))


def test_skinning_queries_agree_with_usdskel_cache(shot):
    """The evaluator's skinning transforms are UsdSkel's SkeletonQuery's, in the mesh's order."""
    stage = Usd.Stage.Open(str(shot / "shot_skel.usda"))
    cache = UsdSkel.Cache()
    root = next(UsdSkel.Root(p) for p in stage.Traverse() if p.IsA(UsdSkel.Root))
    cache.Populate(root, Usd.TraverseInstanceProxies())
    binding = cache.ComputeSkelBindings(root, Usd.TraverseInstanceProxies())[0]
    query = cache.GetSkelQuery(binding.GetSkeleton())
    ev = FaceEvaluator(stage)
    ref = np.transpose(np.asarray(query.ComputeSkinningTransforms(Usd.TimeCode(42))), (0, 2, 1))
    assert np.array_equal(ev.skinning_transforms(42), ref)


def test_preview_of_the_skeleton_shot_shows_the_skinned_face(shot, tmp_path):
    """`usdface preview shot_skel.usda --color displacement` renders the skinned mesh: the jaw-open
    frame's picture differs from the rest frame's, and the scene it draws is the evaluator's."""
    import cv2

    from usdface.usd.scene import read_scene_frame

    ev = FaceEvaluator.open(shot / "shot_skel.usda")
    frame = _jaw_open_frame(ev)
    scene = read_scene_frame(shot / "shot_skel.usda", time=frame)
    assert np.array_equal(scene.mesh.points, ev.points(frame))
    disp = np.linalg.norm(scene.mesh.points - scene.rest_points, axis=1)
    print(f"shot_skel.usda frame {frame}: displacement up to {disp.max():.2f} cm")
    assert disp.max() > 0.5
    images = {}
    for t in (0, frame):
        out = tmp_path / f"skel_{t}.png"
        assert main(["preview", str(shot / "shot_skel.usda"), "--frame", str(t), "--color", "displacement",
                     "-o", str(out), "-q"]) == 0
        images[t] = cv2.imread(str(out)).astype(np.int32)
    changed = np.abs(images[frame] - images[0]).sum(axis=2) > 30
    assert changed.mean() > 0.02  # the open jaw changes a visible part of the picture


def test_preview_reference_with_another_mesh_is_refused(shot, tmp_path, sample_assets, capsys):
    out = tmp_path / "never.png"
    code = main(["preview", str(shot / "shot_skel.usda"), "--frame", "10", "--color", "error", "--reference",
                 str(sample_assets / "meshes" / "mediapipe_canonical_face_model_holes.usdc"), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "--reference" in err and "2020" in err, err
    assert not out.exists()


def test_one_reader_of_the_shot_checked_against_its_raw_attributes(shot):
    """The evaluator also reads what else the shot shows (issue 18: one stage reader): markers,
    head motion, binding and bound points, regions, hybrid weight, triangles; each checked here
    against the shot's raw attributes read with pxr alone."""
    path = shot / "shot.usda"
    ev = FaceEvaluator.open(path)
    stage = Usd.Stage.Open(str(path))
    times = [0, 120, 299]
    marker_prim = next(p for p in stage.Traverse() if p.IsA(UsdGeom.Points))
    assert ev.marker_names == list(marker_prim.GetAttribute("usdface:markerSet:names").Get())
    markers = ev.markers(times)
    head = ev.head_motion(times)
    face = stage.GetDefaultPrim()
    for i, t in enumerate(times):
        raw = np.asarray(marker_prim.GetAttribute("points").Get(t), dtype=np.float64)
        m = _col(UsdGeom.Xformable(marker_prim).ComputeLocalToWorldTransform(Usd.TimeCode(t)))
        want = raw @ m[:3, :3].T + m[:3, 3]
        want[~np.asarray(marker_prim.GetAttribute("primvars:usdface:valid").Get(t), dtype=bool)] = np.nan
        np.testing.assert_allclose(markers[i], want, atol=1e-9)
        # the head motion is /Face's own transform (row vectors, as authored); world = stabilised @ H
        np.testing.assert_array_equal(head[i], np.asarray(UsdGeom.Xformable(face).GetLocalTransformation(t)))
        stable = ev.markers([t], stabilized=True)[0]
        np.testing.assert_allclose(stable @ head[i][:3, :3] + head[i][3, :3], want, atol=1e-6)
    assert np.abs(head[-1][3, :3]).max() > 0.05  # the head moves in this take
    # bound points: barycentric combinations of the bound triangles' vertices, on any pose
    geom = stage.GetPrimAtPath(ev.mesh_path)
    tv = np.asarray(geom.GetAttribute("usdface:binding:triangleVertexIndices").Get())
    bc = np.asarray(geom.GetAttribute("usdface:binding:barycentrics").Get(), dtype=np.float64)
    pts = ev.points_range(times)
    np.testing.assert_allclose(ev.bound_points(pts), (pts[:, tv] * bc[None, :, :, None]).sum(axis=2), atol=1e-9)
    np.testing.assert_allclose(ev.bound_points(pts[1]), (pts[1][tv] * bc[:, :, None]).sum(axis=1), atol=1e-9)
    # regions, hybrid weight, triangles
    schemas = [s.split(":", 1)[1] for s in geom.GetAppliedSchemas() if s.startswith("FaceRegionAPI:")]
    assert [r.name for r in ev.regions] == schemas and schemas
    np.testing.assert_array_equal(ev.hybrid_weight, np.asarray(geom.GetAttribute(
        "primvars:usdface:hybridWeight").Get(), dtype=np.float64))
    counts = np.asarray(geom.GetAttribute("faceVertexCounts").Get())
    assert ev.triangles.shape == (int((counts - 2).sum()), 3)


def test_playback_and_preview_readers_are_views_of_the_one_reader(shot):
    """ShotReader (playblast, report) and read_scene_frame (preview) give the evaluator's data."""
    from usdface.usd.playback import ShotReader
    from usdface.usd.scene import read_scene_frame

    reader = ShotReader.open(shot / "shot.usda")
    ev = reader.evaluator
    scene = read_scene_frame(shot / "shot.usda", time=120, evaluator=ev)
    np.testing.assert_array_equal(scene.mesh.points, reader.face_points([120])[0])
    np.testing.assert_array_equal(scene.markers, reader.markers([120])[0])
    np.testing.assert_array_equal(scene.bound_points, reader.bound_points(reader.face_points([120]))[0])
    assert scene.regions is reader.regions is ev.regions and scene.marker_names == reader.marker_names
    np.testing.assert_array_equal(reader.triangles, scene.mesh.triangles())
