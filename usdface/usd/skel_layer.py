"""Skeleton layers (UsdSkel): the face mesh skinned to a head joint and one joint per marker.

Layout (the mesh layer is a sublayer, as in the binding layer; the default prim becomes the
character's one SkelRoot)::

    /Face                   SkelRoot (the mesh layer's root prim, retyped)
    /Face/Geom              the mesh: SkelBindingAPI, skel:skeleton -> /Face/Skeleton,
                            primvars:skel:jointIndices / jointWeights (vertex, elementSize K),
                            primvars:skel:geomBindTransform (translation by -origin: mesh space
                            to skeleton space)
    /Face/Skeleton          Skeleton, translated to the origin (the face's bounding-box centre): joints ["Head", "Head/<marker joint>", ...], bindTransforms,
                            restTransforms (skeleton space); SkelBindingAPI skel:animationSource -> Anim;
                            usdface:skel:markerNames (the marker of each joint, "" for the head)
    /Face/Skeleton/Anim     SkelAnimation: translations, rotations, scales time-sampled

Do not compose it with the animation layer (``anim.usdc``) of the same take: both move the mesh.
"""
from __future__ import annotations

import json
import os

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

from ..errors import InputError
from .layers import AtomicLayer, open_stage, relative_asset_path, set_provenance, set_stage_metadata
from .mesh_layer import find_mesh

SKELETON_NAME = "Skeleton"
ANIM_NAME = "Anim"
MARKER_NAMES_ATTR = "usdface:skel:markerNames"


def _matrices(ms: np.ndarray) -> Vt.Matrix4dArray:
    """(J, 4, 4) column-vector numpy -> row-vector Matrix4dArray."""
    return Vt.Matrix4dArray([Gf.Matrix4d(*np.asarray(m, dtype=np.float64).T.ravel().tolist()) for m in ms])


def float32_weights(weights: np.ndarray) -> np.ndarray:
    """Weights as float32 whose rows still sum to one as closely as float32 allows.

    Rounding each of K weights to float32 leaves the row sum off by up to K/2 ulp; any error in
    the sum moves the skinned vertex by (sum - 1) times its distance from the origin (80 cm on
    the sample faces), so the rounding error of the sum is put back on the strongest weight.
    """
    w = np.ascontiguousarray(weights, dtype=np.float32)
    for _ in range(2):
        r = 1.0 - w.astype(np.float64).sum(axis=1)
        w[:, 0] = (w[:, 0].astype(np.float64) + r).astype(np.float32)
    return w


def write_skel_layer(path, rig, weights, *, mesh_path, units, rate: float, start: float, prov: dict,
                     report: dict | None = None, progress=None, origin=None) -> str:
    """Write the skeleton layer (module docstring) atomically.

    Parameters
    ----------
    rig : usdface.skel.SkeletonRig
        Joints and their animation (mesh space, mesh units).
    weights : usdface.skel.SkinWeights
        K influences per vertex, joint indices in ``rig.joint_paths`` order.
    mesh_path : path
        The mesh layer (sublayered by relative path).
    report : dict, optional
        Skinning report stored as JSON in the layer's provenance (``skinning``).
    origin : array (3,), optional
        Where the skeleton's space is placed in the mesh's space (a translate op on the Skeleton;
        the geomBindTransform takes the mesh there). ``rig`` is then in skeleton space (mesh space
        minus ``origin``). Near the face's centre, the float32 skinning arithmetic works on
        coordinates of ~10 cm instead of ~80 cm: 8x less rounding error.
    """
    mesh_stage = open_stage(mesh_path, what="mesh")
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
    with AtomicLayer(path) as stage:
        stage.GetRootLayer().subLayerPaths.append(relative_asset_path(mesh_path, path))
        set_stage_metadata(stage, units=units, default_prim=root_path.name, rate=rate, start=start,
                           end=start + n_frames - 1)
        UsdSkel.Root.Define(stage, root_path)
        skel = UsdSkel.Skeleton.Define(stage, root_path.AppendChild(SKELETON_NAME))
        geom_bind = Gf.Matrix4d(1.0)
        if origin is not None:
            o = Gf.Vec3d(*[float(v) for v in origin])
            skel.AddTranslateOp().Set(o)
            geom_bind = Gf.Matrix4d(1.0).SetTranslate(-o)
        joints = Vt.TokenArray(list(rig.joint_paths))
        skel.CreateJointsAttr(joints)
        skel.CreateJointNamesAttr(Vt.TokenArray(["Head"] + list(rig.joint_names)))
        skel.CreateBindTransformsAttr(_matrices(rig.bind_transforms()))
        skel.CreateRestTransformsAttr(_matrices(rig.rest_transforms()))
        attr = skel.GetPrim().CreateAttribute(MARKER_NAMES_ATTR, Sdf.ValueTypeNames.StringArray, custom=True)
        attr.Set(Vt.StringArray([""] + list(rig.marker_names)))
        attr.SetDocumentation("The capture marker driving each joint ('' for the head joint); joint names are "
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
        binding.CreateGeomBindTransformAttr(geom_bind)

        trans, rot = rig.local_animation()
        t_attr = anim.CreateTranslationsAttr()
        r_attr = anim.CreateRotationsAttr()
        s_attr = anim.CreateScalesAttr()
        scales = Vt.Vec3hArray([Gf.Vec3h(1, 1, 1)] * rig.n_joints)
        trans32 = np.ascontiguousarray(trans, dtype=np.float32)
        rot_marker = Gf.Quatf(1.0)
        with Sdf.ChangeBlock():
            for f in range(n_frames):
                tc = Usd.TimeCode(start + f)
                t_attr.Set(Vt.Vec3fArray.FromNumpy(trans32[f]), tc)
                q = rot[f, 0]
                r_attr.Set(Vt.QuatfArray([Gf.Quatf(float(q[0]), float(q[1]), float(q[2]), float(q[3]))]
                                         + [rot_marker] * (rig.n_joints - 1)), tc)
                s_attr.Set(scales, tc)
                if progress is not None and (f + 1) % 256 == 0:
                    progress.update(256)
        if progress is not None:
            progress.update(n_frames % 256)
        if report is not None:
            prov = dict(prov, skinning=json.dumps(report, sort_keys=True, default=float))
        set_provenance(stage, prov)
    return str(path)


def skinned_points(path, *, times=None, stage: Usd.Stage | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Skin the face mesh of a skeleton layer with UsdSkel (:class:`usdface.usd.evaluate.FaceEvaluator`).

    Parameters
    ----------
    path : path of a skeleton layer (or any stage with a skinned face mesh)
    times : sequence of time codes, optional (default: every time code that moves the face)

    Returns
    -------
    times : ndarray (F,)
    points : ndarray (F, N, 3) float64 in the mesh's own space (where the point cache lives), as
        ``UsdSkel.BakeSkinning`` would bake them.
    """
    from .evaluate import FaceEvaluator

    ev = FaceEvaluator(stage, source=str(path)) if stage is not None else FaceEvaluator.open(path, what="skeleton")
    if not ev.skinned:
        raise InputError(f"skeleton {path}: the face mesh {ev.mesh_path} is not skinned (no SkelRoot ancestor, "
                         "no bound Skeleton with a bind pose, or no joint influences)")
    times = ev.resolve_times(times)
    return times, ev.points_range(times, space="mesh")


def read_skel_report(path) -> dict:
    """The skinning report stored in a skeleton layer's provenance."""
    layer = Sdf.Layer.FindOrOpen(os.fspath(path))
    if layer is None:
        raise InputError(f"skeleton {path}: cannot be read as USD")
    data = dict(layer.customLayerData.get("usdface", {}))
    return json.loads(data.get("skinning", "{}"))
