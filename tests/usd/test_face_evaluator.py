"""The face evaluator (usdface/usd/evaluate.py) against numpy references written by hand.

Small synthetic stages are authored here from numpy arrays (a point cache under animated
ancestors; a UsdSkel skeleton with a joint hierarchy, an animation that orders its joints
differently and leaves one joint to its rest transform, a mesh with its own joint order,
geomBindTransform and transform; blend shapes, dense and sparse, in another order than the
animation's). The references recompute linear blend skinning and blend shapes from those arrays
with numpy and scipy's quaternions, never reading the stage back through UsdSkel.
"""
from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt
from scipy.spatial.transform import Rotation

from usdface.errors import InputError, OptionError
from usdface.usd.face_evaluator import FaceEvaluator, evaluate_points

TOL = 5e-5  # UsdSkel skins in float32 (rigid skinning too): ~5e-7 of the stages' coordinates (< 100 units)

N_FRAMES = 6
N_POINTS = 40
JOINTS = ["Root", "Root/Jaw", "Root/Jaw/Lip", "Root/Brow"]
PARENTS = [-1, 0, 1, 0]
ANIM_JOINTS = ["Root/Brow", "Root", "Root/Jaw"]          # Lip is not animated: it keeps its rest transform
MESH_JOINTS = ["Root/Brow", "Root/Jaw/Lip", "Root", "Root/Jaw"]  # the mesh's own skel:joints order
MESH_SHAPES = ["smile", "jawOpen"]
ANIM_SHAPES = ["jawOpen", "unused", "smile"]


def _gf(m: np.ndarray) -> Gf.Matrix4d:
    """Column-vector numpy 4x4 -> Gf (row-vector)."""
    return Gf.Matrix4d(*np.asarray(m, dtype=np.float64).T.ravel().tolist())


def _trs(t, q_wxyz, s) -> np.ndarray:
    """Column-vector T R S (UsdSkel's joint transform from translation, rotation, scale)."""
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat(np.r_[q_wxyz[1:], q_wxyz[0]]).as_matrix() @ np.diag(s)
    m[:3, 3] = t
    return m


def _random_rigid(rng, angle=0.2, shift=3.0) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = Rotation.from_rotvec(rng.normal(scale=angle, size=3)).as_matrix()
    m[:3, 3] = rng.normal(scale=shift, size=3)
    return m


def _apply(m: np.ndarray, p: np.ndarray) -> np.ndarray:
    return p @ m[:3, :3].T + m[:3, 3]


class Scene:
    """Numpy data of a synthetic face and the stage authored from it."""

    def __init__(self, seed=3, *, joints=True, shapes=False, rigid=False, method=None, mesh_xform=True,
                 geom_bind=True):
        rng = np.random.default_rng(seed)
        self.rest = rng.normal(scale=4.0, size=(N_POINTS, 3)) + [0.0, 60.0, 5.0]
        self.world = _random_rigid(rng, 0.1, 20.0)                                    # /World, static
        self.head = np.stack([_random_rigid(rng, 0.05, 1.0) for _ in range(N_FRAMES)])  # /World/Face, animated
        self.skel_xf = _random_rigid(rng, 0.1, 2.0)                                   # the Skeleton prim
        self.mesh_xf = _random_rigid(rng, 0.1, 2.0) if mesh_xform else np.eye(4)      # the Mesh prim
        self.geom_bind = _random_rigid(rng, 0.1, 2.0) if geom_bind else np.eye(4)
        self.author_geom_bind = geom_bind
        # skeleton: skeleton-space bind transforms of a small hierarchy, rest = bind (local)
        self.bind = np.stack([_random_rigid(rng, 0.3, 4.0) for _ in JOINTS])
        self.rest_local = np.stack([self.bind[j] if p < 0 else np.linalg.inv(self.bind[p]) @ self.bind[j]
                                    for j, p in enumerate(PARENTS)])
        # animation (for ANIM_JOINTS, in that order): translation, rotation (w, x, y, z), scale
        self.anim_t = rng.normal(scale=2.0, size=(N_FRAMES, len(ANIM_JOINTS), 3))
        q = rng.normal(size=(N_FRAMES, len(ANIM_JOINTS), 4)) * [1, 0.2, 0.2, 0.2]
        q[..., 0] = 1.0
        self.anim_r = q / np.linalg.norm(q, axis=-1, keepdims=True)
        self.anim_s = 1.0 + rng.normal(scale=0.05, size=(N_FRAMES, len(ANIM_JOINTS), 3))
        self.anim_s = self.anim_s.astype(np.float16).astype(np.float64)  # scales are half3 in USD
        self.anim_t = self.anim_t.astype(np.float32).astype(np.float64)
        self.anim_r = self.anim_r.astype(np.float32).astype(np.float64)
        # influences, indices into MESH_JOINTS
        k = 1 if rigid else 3
        self.k = k
        if rigid:
            self.idx = np.array([[1, 3]])
            self.w = np.array([[0.3, 0.7]], dtype=np.float32)
        else:
            self.idx = np.stack([rng.choice(len(MESH_JOINTS), k, replace=False) for _ in range(N_POINTS)])
            w = rng.random((N_POINTS, k)) + 0.1
            self.w = (w / w.sum(axis=1, keepdims=True)).astype(np.float32)
        self.rigid = rigid
        # blend shapes: smile moves every point, jawOpen only the points in jaw_indices
        self.smile = rng.normal(scale=0.5, size=(N_POINTS, 3)).astype(np.float32)
        self.jaw_indices = np.array([3, 7, 8, 20, 31, 39])
        self.jaw = rng.normal(scale=1.0, size=(len(self.jaw_indices), 3)).astype(np.float32)
        self.anim_bs = rng.uniform(-0.2, 1.2, size=(N_FRAMES, len(ANIM_SHAPES))).astype(np.float32)
        self.joints, self.shapes, self.method = joints, shapes, method
        self.stage = self._author()

    # -- authoring -------------------------------------------------------------------------------

    def _author(self) -> Usd.Stage:
        stage = Usd.Stage.CreateInMemory()
        stage.SetStartTimeCode(0)
        stage.SetEndTimeCode(N_FRAMES - 1)
        world = UsdGeom.Xform.Define(stage, "/World")
        world.AddTransformOp().Set(_gf(self.world))
        stage.SetDefaultPrim(world.GetPrim())
        face = UsdSkel.Root.Define(stage, "/World/Face")
        op = face.AddTransformOp()
        for f in range(N_FRAMES):
            op.Set(_gf(self.head[f]), f)
        mesh = UsdGeom.Mesh.Define(stage, "/World/Face/Geom")
        mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(self.rest.astype(np.float32)))
        mesh.CreateFaceVertexCountsAttr([3] * (N_POINTS - 2))
        mesh.CreateFaceVertexIndicesAttr([int(i) for f in range(N_POINTS - 2) for i in (0, f + 1, f + 2)])
        mesh.AddTransformOp().Set(_gf(self.mesh_xf))
        skel = UsdSkel.Skeleton.Define(stage, "/World/Face/Skeleton")
        skel.AddTransformOp().Set(_gf(self.skel_xf))
        skel.CreateJointsAttr(JOINTS)
        skel.CreateBindTransformsAttr(Vt.Matrix4dArray([_gf(m) for m in self.bind]))
        skel.CreateRestTransformsAttr(Vt.Matrix4dArray([_gf(m) for m in self.rest_local]))
        anim = UsdSkel.Animation.Define(stage, "/World/Face/Skeleton/Anim")
        anim.CreateJointsAttr(ANIM_JOINTS)
        UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
        for f in range(N_FRAMES):
            anim.CreateTranslationsAttr().Set(Vt.Vec3fArray.FromNumpy(self.anim_t[f].astype(np.float32)), f)
            anim.CreateRotationsAttr().Set(Vt.QuatfArray([Gf.Quatf(*map(float, q)) for q in self.anim_r[f]]), f)
            anim.CreateScalesAttr().Set(Vt.Vec3hArray([Gf.Vec3h(*map(float, s)) for s in self.anim_s[f]]), f)
        binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
        binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
        if self.joints:
            binding.CreateJointsAttr(MESH_JOINTS)
            constant = self.rigid
            idx = binding.CreateJointIndicesPrimvar(constant, self.idx.shape[1])
            idx.Set(Vt.IntArray([int(i) for i in self.idx.ravel()]))
            binding.CreateJointWeightsPrimvar(constant, self.idx.shape[1]).Set(
                Vt.FloatArray([float(w) for w in self.w.ravel()]))
            if self.author_geom_bind:
                binding.CreateGeomBindTransformAttr(_gf(self.geom_bind))
            if self.method:
                binding.CreateSkinningMethodAttr(self.method)
        if self.shapes:
            smile = UsdSkel.BlendShape.Define(stage, "/World/Face/Geom/Smile")
            smile.CreateOffsetsAttr(Vt.Vec3fArray.FromNumpy(self.smile))
            jaw = UsdSkel.BlendShape.Define(stage, "/World/Face/Geom/Jaw")
            jaw.CreateOffsetsAttr(Vt.Vec3fArray.FromNumpy(self.jaw))
            jaw.CreatePointIndicesAttr(Vt.IntArray([int(i) for i in self.jaw_indices]))
            binding.CreateBlendShapesAttr(MESH_SHAPES)
            binding.CreateBlendShapeTargetsRel().SetTargets([smile.GetPath(), jaw.GetPath()])
            anim.CreateBlendShapesAttr(ANIM_SHAPES)
            for f in range(N_FRAMES):
                anim.CreateBlendShapeWeightsAttr().Set(Vt.FloatArray([float(w) for w in self.anim_bs[f]]), f)
        return stage

    # -- references (numpy only) ----------------------------------------------------------------

    def skel_space_joints(self, f: int) -> np.ndarray:
        """(J, 4, 4) skeleton-space joint transforms: animated joints from TRS, the rest from
        restTransforms, concatenated down the hierarchy."""
        local = self.rest_local.copy()
        for a, name in enumerate(ANIM_JOINTS):
            local[JOINTS.index(name)] = _trs(self.anim_t[f, a], self.anim_r[f, a], self.anim_s[f, a])
        out = np.empty_like(local)
        for j, p in enumerate(PARENTS):
            out[j] = local[j] if p < 0 else out[p] @ local[j]
        return out

    def skinning(self, f: int) -> np.ndarray:
        """(J, 4, 4) skinning transforms in the MESH's joint order: joint(skel) @ inverse(bind)."""
        sk = self.skel_space_joints(f)
        per_skel = np.stack([sk[j] @ np.linalg.inv(self.bind[j]) for j in range(len(JOINTS))])
        return per_skel[[JOINTS.index(n) for n in MESH_JOINTS]]

    def shape_weights(self, f: int) -> np.ndarray:
        return np.array([self.anim_bs[f, ANIM_SHAPES.index(n)] for n in MESH_SHAPES], dtype=np.float64)

    def blended(self, f: int) -> np.ndarray:
        """Rest points plus the weighted blend-shape offsets (before skinning)."""
        p = self.rest.astype(np.float32).astype(np.float64)
        if not self.shapes:
            return p
        w = self.shape_weights(f)
        p = p + w[0] * self.smile
        p[self.jaw_indices] += w[1] * self.jaw
        return p

    def ancestors(self, f: int) -> np.ndarray:
        return self.world @ self.head[f]

    def world_points(self, f: int) -> np.ndarray:
        p = self.blended(f)
        if not self.joints:  # blend shapes only: the mesh's own space, then its transforms
            return _apply(self.ancestors(f) @ self.mesh_xf, p)
        x = self.skinning(f)
        q = _apply(self.geom_bind, p)
        if self.rigid:
            m = sum(float(w) * x[j] for j, w in zip(self.idx[0], self.w[0]))
            skinned = _apply(m, q)
        else:
            skinned = np.zeros_like(q)
            for k in range(self.idx.shape[1]):
                skinned += self.w[:, k, None].astype(np.float64) * np.einsum("nij,nj->ni", x[self.idx[:, k]],
                                                                              np.c_[q, np.ones(len(q))])[:, :3]
        return _apply(self.ancestors(f) @ self.skel_xf, skinned)

    def mesh_points(self, f: int) -> np.ndarray:
        return _apply(np.linalg.inv(self.ancestors(f) @ self.mesh_xf), self.world_points(f))


def _check(scene: Scene, ev: FaceEvaluator):
    frames = list(range(N_FRAMES))
    world = ev.points_range(frames)
    mesh = ev.points_range(frames, space="mesh")
    for f in frames:
        ref_w, ref_m = scene.world_points(f), scene.mesh_points(f)
        assert np.abs(world[f] - ref_w).max() < TOL, f"frame {f}: world {np.abs(world[f] - ref_w).max():.3g}"
        assert np.abs(mesh[f] - ref_m).max() < TOL, f"frame {f}: mesh {np.abs(mesh[f] - ref_m).max():.3g}"
    # the motion is large against the tolerance: the test would see a wrong order or space
    assert np.abs(world - world[:1]).max() > 0.5


def test_linear_blend_skinning_matches_numpy_by_hand():
    scene = Scene(joints=True)
    ev = FaceEvaluator(scene.stage)
    assert ev.deformation == ("skinning",) and ev.skinning_method == "classicLinear"
    assert ev.joints == JOINTS and ev.mesh_path == "/World/Face/Geom"
    assert list(ev.time_codes) == list(range(N_FRAMES)) and ev.frame_range == (0, N_FRAMES - 1)
    _check(scene, ev)
    # skinning transforms come out in the mesh's joint order, column-vector
    assert np.allclose(ev.skinning_transforms(2), scene.skinning(2), atol=1e-5)


def test_unauthored_geom_bind_transform_is_identity():
    scene = Scene(joints=True, geom_bind=False)
    ev = FaceEvaluator(scene.stage)
    _check(scene, ev)


def test_blend_shapes_alone_deform_in_mesh_space():
    scene = Scene(joints=False, shapes=True)
    ev = FaceEvaluator(scene.stage)
    assert ev.deformation == ("blendShapes",) and not ev.skinned
    assert ev.blend_shapes == MESH_SHAPES
    assert np.allclose(ev.blend_shape_weights(4), scene.shape_weights(4))
    _check(scene, ev)


def test_blend_shapes_apply_before_skinning():
    scene = Scene(joints=True, shapes=True)
    ev = FaceEvaluator(scene.stage)
    assert ev.deformation == ("blendShapes", "skinning")
    _check(scene, ev)
    # the offsets added after skinning instead (not turned by the joints) give another answer
    no_shapes = Scene(joints=True, shapes=False)  # same seed: same skeleton, weights and shapes
    offsets = scene.blended(3) - no_shapes.blended(3)
    to_world = scene.ancestors(3) @ scene.skel_xf @ scene.geom_bind
    after = no_shapes.world_points(3) + offsets @ to_world[:3, :3].T
    assert np.abs(ev.points(3) - after).max() > 0.05


def test_rigid_influences_move_the_whole_mesh():
    scene = Scene(joints=True, rigid=True)
    ev = FaceEvaluator(scene.stage)
    assert ev.deformation == ("rigidSkinning",)
    _check(scene, ev)


def test_dual_quaternion_skinning_is_usdskels():
    scene = Scene(joints=True, method="dualQuaternion")
    ev = FaceEvaluator(scene.stage)
    assert ev.skinning_method == "dualQuaternion"
    # UsdSkel's other entry point (SkinningQuery.ComputeSkinnedPoints) as the reference
    cache = UsdSkel.Cache()
    root = UsdSkel.Root(scene.stage.GetPrimAtPath("/World/Face"))
    cache.Populate(root, Usd.TraverseInstanceProxies())
    query = cache.GetSkinningQuery(scene.stage.GetPrimAtPath("/World/Face/Geom"))
    skel = cache.GetSkelQuery(UsdSkel.Skeleton(scene.stage.GetPrimAtPath("/World/Face/Skeleton")))
    tc = Usd.TimeCode(4)
    xf = skel.ComputeSkinningTransforms(tc)  # the query remaps them to the mesh's joint order
    pts = Vt.Vec3fArray.FromNumpy(scene.rest.astype(np.float32))
    assert query.ComputeSkinnedPoints(xf, pts, tc)
    ref = _apply(scene.ancestors(4) @ scene.skel_xf, np.asarray(pts, dtype=np.float64))
    assert np.abs(ev.points(4) - ref).max() < TOL
    assert np.abs(ev.points(4) - scene.world_points(4)).max() > 1e-3  # not linear blend skinning


def test_point_cache_under_animated_ancestors(tmp_path):
    rng = np.random.default_rng(5)
    scene = Scene(joints=False, shapes=False)
    cache = scene.rest[None] + rng.normal(scale=0.7, size=(N_FRAMES, N_POINTS, 3))
    geom = UsdGeom.Mesh(scene.stage.GetPrimAtPath("/World/Face/Geom"))
    for f in range(N_FRAMES):
        geom.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(cache[f].astype(np.float32)), f)
    ev = FaceEvaluator(scene.stage)
    assert ev.deformation == ("points",) and ev.animated
    world = ev.points_range()
    for f in range(N_FRAMES):
        p = cache[f].astype(np.float32).astype(np.float64)
        assert np.abs(world[f] - _apply(scene.ancestors(f) @ scene.mesh_xf, p)).max() < TOL
        assert np.abs(ev.points(f, space="mesh") - p).max() < TOL
    assert np.abs(ev.rest_points() - scene.rest).max() < TOL
    rest_w = ev.rest_points(space="world", time=2)
    assert np.abs(rest_w - _apply(scene.ancestors(2) @ scene.mesh_xf, scene.rest)).max() < TOL
    assert np.allclose(ev.local_to_world(2), scene.ancestors(2) @ scene.mesh_xf, atol=1e-9)


def test_iteration_buffers_and_one_call_agree():
    scene = Scene(joints=True, shapes=True)
    ev = FaceEvaluator(scene.stage)
    full = ev.points_range()
    seen = []
    for times, pts in ev.iter_points(chunk=4):
        assert pts.shape == (len(times), N_POINTS, 3)
        seen.append((times.copy(), pts.copy()))
    assert [len(t) for t, _ in seen] == [4, 2]
    assert np.array_equal(np.concatenate([p for _, p in seen]), full)
    out = np.empty((N_FRAMES, N_POINTS, 3), dtype=np.float32)
    assert ev.points_range(out=out) is out and np.abs(out - full).max() < 1e-4
    times, pts = evaluate_points(scene.stage, [1, 5], space="mesh")
    assert list(times) == [1, 5] and np.array_equal(pts, ev.points_range([1, 5], space="mesh"))


def test_a_layer_alone_and_the_shot_that_composes_it(tmp_path):
    """An over-only animation layer opened alone gives its points (no topology, no rest); the
    shot that sublayers it over the mesh gives the same points with topology."""
    rng = np.random.default_rng(9)
    rest = rng.normal(size=(N_POINTS, 3)).astype(np.float32)
    mesh_layer = tmp_path / "mesh.usda"
    stage = Usd.Stage.CreateNew(str(mesh_layer))
    UsdGeom.Xform.Define(stage, "/Face")
    geom = UsdGeom.Mesh.Define(stage, "/Face/Geom")
    geom.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(rest))
    geom.CreateFaceVertexCountsAttr([3])
    geom.CreateFaceVertexIndicesAttr([0, 1, 2])
    stage.SetDefaultPrim(stage.GetPrimAtPath("/Face"))
    stage.Save()
    anim_layer = tmp_path / "anim.usda"
    stage = Usd.Stage.CreateNew(str(anim_layer))
    over = stage.OverridePrim("/Face/Geom")
    attr = over.CreateAttribute("points", Sdf.ValueTypeNames.Point3fArray)
    moved = rest[None] + rng.normal(size=(3, N_POINTS, 3)).astype(np.float32)
    for f in range(3):
        attr.Set(Vt.Vec3fArray.FromNumpy(moved[f]), f)
    stage.Save()
    shot = tmp_path / "shot.usda"
    stage = Usd.Stage.CreateNew(str(shot))
    stage.GetRootLayer().subLayerPaths = ["./anim.usda", "./mesh.usda"]
    stage.Save()

    alone = FaceEvaluator.open(anim_layer)
    assert not alone.has_topology and alone.deformation == ("points",)
    assert np.array_equal(alone.points_range(), moved.astype(np.float64))
    with pytest.raises(InputError, match="no rest points"):
        alone.rest_points()
    composed = FaceEvaluator.open(shot)
    assert composed.has_topology and list(composed.face_vertex_indices) == [0, 1, 2]
    assert np.array_equal(composed.points_range(), moved.astype(np.float64))
    assert np.array_equal(composed.rest_points(), rest.astype(np.float64))


def test_bad_input_names_the_file_prim_or_option(tmp_path):
    empty = tmp_path / "empty.usda"
    stage = Usd.Stage.CreateNew(str(empty))
    UsdGeom.Xform.Define(stage, "/Face")
    stage.Save()
    with pytest.raises(InputError, match="empty.usda: no face mesh"):
        FaceEvaluator.open(empty)
    with pytest.raises(InputError, match="no such file"):
        FaceEvaluator.open(tmp_path / "missing.usda")
    scene = Scene()
    with pytest.raises(InputError, match="/World/Nope"):
        FaceEvaluator(scene.stage, mesh="/World/Nope")
    ev = FaceEvaluator(scene.stage)
    with pytest.raises(OptionError, match="space 'skel'"):
        ev.points(0, space="skel")
    with pytest.raises(OptionError, match="chunk 0"):
        next(ev.iter_points(chunk=0))
    with pytest.raises(OptionError, match="out: expected shape"):
        ev.points_range([0, 1], out=np.empty((3, N_POINTS, 3)))
    # joint indices past the mesh's joints: UsdSkel refuses, the error names the prim
    binding = UsdSkel.BindingAPI(scene.stage.GetPrimAtPath("/World/Face/Geom"))
    binding.GetJointIndicesPrimvar().Set(Vt.IntArray([9] * (N_POINTS * 3)))
    with pytest.raises(InputError, match="/World/Face/Geom"):
        FaceEvaluator(scene.stage).points(0)


def test_weights_without_a_skel_root_are_not_applied(caplog):
    """UsdSkel deforms only under a SkelRoot: the evaluator says so and keeps the authored points."""
    scene = Scene(joints=True)
    scene.stage.GetPrimAtPath("/World/Face").SetTypeName("Xform")
    with caplog.at_level("WARNING", logger="usdface"):
        ev = FaceEvaluator(scene.stage)
    assert ev.deformation == () and "no SkelRoot" in caplog.text
    assert np.abs(ev.points(0, space="mesh") - scene.rest).max() < TOL
