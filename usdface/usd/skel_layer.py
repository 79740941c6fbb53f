"""Skeleton layers (UsdSkel): the face mesh skinned to a static root and one joint per marker.

Layout (the mesh layer is a sublayer, as in the binding layer; the default prim becomes the
character's one SkelRoot)::

    /Face                   SkelRoot (the mesh layer's root prim, retyped); the head motion as a
                            time-sampled xformOp:transform (mesh space, identity at the neutral
                            frame; no op without head motion)
    /Face/Geom              the mesh: SkelBindingAPI, skel:skeleton -> /Face/Skeleton,
                            primvars:skel:jointIndices / jointWeights (vertex, elementSize K),
                            primvars:skel:geomBindTransform = identity; with corrective shapes,
                            skel:blendShapes and skel:blendShapeTargets
    /Face/Geom/<shape>      BlendShape: offsets (one per point), time-invariant
    /Face/Skeleton          Skeleton without any transform: joints ["Head", "Head/<marker joint>", ...],
                            bindTransforms and restTransforms at mesh-space positions;
                            SkelBindingAPI skel:animationSource -> Anim; usdface:skel:markerNames
    /Face/Skeleton/Anim     SkelAnimation: translations time-sampled (rotations and scales
                            constant), blendShapes and time-sampled blendShapeWeights

No compensating transform pair: importers that read geomBindTransform as the mesh's own transform
(Blender) or ignore a transform on the Skeleton prim see the same thing UsdSkel does. Far from the
origin UsdSkel's float32 skinning stays accurate: the same face skins within 8.5e-5 cm at
y = 170 cm and 3.8e-4 cm at y = 10 m of the face at the origin (benchmarks/skin_weights.py,
tests/skel/test_placement.py); that is float32 arithmetic on 10 m coordinates, and the weight
rows summing to one in float32 (:func:`float32_weights`) keeps the skinned point from being
scaled about the origin on top of it.

Do not compose it with the animation layer (``anim.usdc``) of the same take: both move the mesh.
"""
from __future__ import annotations

import json

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

from ..errors import InputError
from .layers import (add_sublayer, open_layer, open_stage, output_layer, set_provenance, set_stage_metadata,
                     stage_units)
from .motion import author_head_motion
from .mesh_layer import find_mesh

SKELETON_NAME = "Skeleton"
ANIM_NAME = "Anim"
MARKER_NAMES_ATTR = "usdface:skel:markerNames"
SHAPE_PREFIX = "Corrective_"


def _matrix(m: np.ndarray) -> Gf.Matrix4d:
    """Column-vector numpy 4x4 -> row-vector Gf.Matrix4d."""
    return Gf.Matrix4d(*np.asarray(m, dtype=np.float64).T.ravel().tolist())


def _matrices(ms: np.ndarray) -> Vt.Matrix4dArray:
    """(J, 4, 4) column-vector numpy -> row-vector Matrix4dArray."""
    return Vt.Matrix4dArray([_matrix(m) for m in ms])


def float32_weights(weights: np.ndarray) -> np.ndarray:
    """Weights as float32 whose rows still sum to one as closely as float32 allows.

    Rounding each of K weights to float32 leaves the row sum off by up to K/2 ulp; any error in
    the sum scales the skinned vertex about the origin by (sum - 1) (80 cm away on the sample
    faces, 10 m in a set), so the rounding error of the sum is put back on the strongest weight.
    Zero weights stay zero.
    """
    w = np.ascontiguousarray(weights, dtype=np.float32)
    for _ in range(2):
        r = 1.0 - w.astype(np.float64).sum(axis=1)
        w[:, 0] = (w[:, 0].astype(np.float64) + r).astype(np.float32)
    return w


def shape_names(n: int) -> list[str]:
    """Names of the corrective blend shapes: Corrective_00, Corrective_01, ..."""
    return [f"{SHAPE_PREFIX}{s:02d}" for s in range(n)]


def write_skel_layer(path, rig, skin, *, mesh_path, rate: float, start: float, prov: dict, report: dict | None = None,
                     progress=None, head_motion=None) -> str:
    """Write the skeleton layer (module docstring) atomically.

    Parameters
    ----------
    path : path, or (Python API) an Sdf.Layer / Usd.Stage to author into
    rig : usdface.skel.SkeletonRig
        Joints and their animation (mesh space, mesh units).
    skin : usdface.skel.SkinFit (or any object with ``weights``, ``shapes``, ``shape_weights``)
        ``weights`` (:class:`usdface.skel.SkinWeights`): K influences per vertex, joint indices in
        ``rig.joint_paths`` order; ``shapes`` (S, N, 3) or None: corrective blend-shape offsets
        (mesh units), applied before skinning; ``shape_weights`` (F, S): their weight at every frame.
    mesh_path : path (or layer)
        The mesh layer (sublayered by relative path); the layer takes its units.
    rate, start : float
        timeCodesPerSecond = framesPerSecond, and the first frame's time code.
    report : dict, optional
        Skinning report stored as JSON in the layer's provenance (``skinning``).
    head_motion : ndarray (F, 4, 4), optional
        The head motion in mesh space (column vectors), authored on /Face as a time-sampled
        ``xformOp:transform``; None: /Face gets no transform op.
    """
    weights, shapes, shape_weights = skin.weights, skin.shapes, skin.shape_weights
    mesh_stage = open_stage(mesh_path, what="mesh")
    units = stage_units(mesh_stage)
    mesh_prim = find_mesh(mesh_stage)
    mesh_path_in_stage = mesh_prim.GetPath()
    root_path = Sdf.Path(mesh_path_in_stage.GetPrefixes()[0])
    if root_path == mesh_path_in_stage:
        raise InputError(f"mesh {mesh_path}: the mesh {mesh_path_in_stage} is a root prim; a SkelRoot must be its "
                         "ancestor (put the mesh under a root Xform, as `usdface import-mesh` does)")
    n_points = len(UsdGeom.Mesh(mesh_prim).GetPointsAttr().Get() or [])
    if weights.indices.shape[0] != n_points:
        raise InputError(f"skin weights for {weights.indices.shape[0]} vertices, mesh {mesh_path} has {n_points}")
    n_frames = rig.n_frames
    n_shapes = 0 if shapes is None else int(shapes.shape[0])
    if n_shapes and (shapes.shape != (n_shapes, n_points, 3) or shape_weights is None
                     or np.shape(shape_weights) != (n_frames, n_shapes)):
        raise InputError(f"corrective shapes {np.shape(shapes)} / weights {np.shape(shape_weights)} do not match "
                         f"{n_points} points and {n_frames} frames")
    if head_motion is not None and np.shape(head_motion) != (n_frames, 4, 4):
        raise InputError(f"head motion {np.shape(head_motion)} for {n_frames} frames")
    with output_layer(path) as stage:
        add_sublayer(stage, mesh_path, path)
        set_stage_metadata(stage, units=units, default_prim=root_path.name, rate=rate, start=start,
                           end=start + n_frames - 1)
        UsdSkel.Root.Define(stage, root_path)
        if head_motion is not None:
            author_head_motion(stage, root_path, head_motion, start=start)
        skel = UsdSkel.Skeleton.Define(stage, root_path.AppendChild(SKELETON_NAME))
        joints = Vt.TokenArray(list(rig.joint_paths))
        skel.CreateJointsAttr(joints)
        skel.CreateJointNamesAttr(Vt.TokenArray(["Head"] + list(rig.joint_names)))
        skel.CreateBindTransformsAttr(_matrices(rig.bind_transforms()))
        skel.CreateRestTransformsAttr(_matrices(rig.rest_transforms()))
        attr = skel.GetPrim().CreateAttribute(MARKER_NAMES_ATTR, Sdf.ValueTypeNames.StringArray, custom=True)
        attr.Set(Vt.StringArray([""] + list(rig.marker_names)))
        attr.SetDocumentation("The capture marker of each joint ('' for the static root); joint names are "
                              "the marker names made valid USD identifiers")
        anim = UsdSkel.Animation.Define(stage, skel.GetPath().AppendChild(ANIM_NAME))
        anim.CreateJointsAttr(joints)
        UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])

        over = stage.OverridePrim(mesh_path_in_stage)
        binding = UsdSkel.BindingAPI.Apply(over)
        binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
        k = weights.k
        binding.CreateJointIndicesPrimvar(False, k).Set(Vt.IntArray.FromNumpy(
            np.ascontiguousarray(weights.indices, dtype=np.int32).ravel()))
        binding.CreateJointWeightsPrimvar(False, k).Set(Vt.FloatArray.FromNumpy(float32_weights(weights.weights).ravel()))
        binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))

        names = shape_names(n_shapes)
        if n_shapes:
            targets = []
            for s, name in enumerate(names):
                bs = UsdSkel.BlendShape.Define(stage, mesh_path_in_stage.AppendChild(name))
                bs.CreateOffsetsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(shapes[s], dtype=np.float32)))
                targets.append(bs.GetPath())
            binding.CreateBlendShapesAttr(Vt.TokenArray(names))
            binding.CreateBlendShapeTargetsRel().SetTargets(targets)
            anim.CreateBlendShapesAttr(Vt.TokenArray(names))

        trans32 = np.ascontiguousarray(rig.local_animation(), dtype=np.float32)
        t_attr = anim.CreateTranslationsAttr()
        anim.CreateRotationsAttr(Vt.QuatfArray([Gf.Quatf(1.0)] * rig.n_joints))
        anim.CreateScalesAttr(Vt.Vec3hArray([Gf.Vec3h(1, 1, 1)] * rig.n_joints))
        w_attr = anim.CreateBlendShapeWeightsAttr() if n_shapes else None
        sw32 = np.ascontiguousarray(shape_weights, dtype=np.float32) if n_shapes else None
        with Sdf.ChangeBlock():
            for f in range(n_frames):
                tc = Usd.TimeCode(start + f)
                t_attr.Set(Vt.Vec3fArray.FromNumpy(trans32[f]), tc)
                if w_attr is not None:
                    w_attr.Set(Vt.FloatArray.FromNumpy(sw32[f]), tc)
                if progress is not None and (f + 1) % 256 == 0:
                    progress.update(256)
        if progress is not None:
            progress.update(n_frames % 256)
        if report is not None:
            prov = dict(prov, skinning=json.dumps(report, sort_keys=True, default=float))
        set_provenance(stage, prov)
    return str(path)


def skinned_points(path, *, times=None, stage: Usd.Stage | None = None,
                   space: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """Deform the face mesh of a skeleton layer with UsdSkel: blend shapes, then skinning
    (:class:`usdface.usd.face_evaluator.FaceEvaluator`: ``UsdSkel.BlendShapeQuery`` with the
    SkelAnimation's weights, then ``UsdSkel.SkinningQuery.ComputeSkinnedPoints``).

    Parameters
    ----------
    path : path of a skeleton layer (or any stage with a skinned face mesh)
    times : sequence of time codes, optional (default: every time code that moves the face)
    space : {"mesh", "world"}
        "mesh": the mesh's own space, where the stabilised point cache lives (as
        ``UsdSkel.BakeSkinning`` would bake the points); "world": where a DCC shows the face (the
        head motion on /Face applied).

    Returns
    -------
    times : ndarray (F,)
    points : ndarray (F, N, 3) float64
    """
    from .face_evaluator import FaceEvaluator

    ev = FaceEvaluator(stage, source=str(path)) if stage is not None else FaceEvaluator.open(path, what="skeleton")
    if not ev.skinned:
        raise InputError(f"skeleton {path}: the face mesh {ev.mesh_path} is not skinned (no SkelRoot ancestor, "
                         "no bound Skeleton with a bind pose, or no joint influences)")
    times = ev.resolve_times(times)
    return times, ev.points_range(times, space=space)


def read_skel_report(path) -> dict:
    """The skinning report stored in a skeleton layer's provenance."""
    layer = open_layer(path, what="skeleton")
    data = dict(layer.customLayerData.get("usdface", {}))
    return json.loads(data.get("skinning", "{}"))
