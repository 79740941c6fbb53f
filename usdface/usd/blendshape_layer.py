"""Blend-shape rigs in USD (UsdSkel): reading a face mesh's shapes, writing weight-curve layers.

Reading (:func:`read_blendshape_rig`)
-------------------------------------
A rig is a Mesh with ``SkelBindingAPI`` ``skel:blendShapes`` (the names animations use) and
``skel:blendShapeTargets`` (one BlendShape prim per name), as Blender and Maya-USD export them.
Each BlendShape's ``offsets`` are dense (one per mesh point) or sparse with ``pointIndices``; both
become dense (K, N, 3) offsets. In-between shapes (``inbetweens:*``) are dropped and reported:
usdface solves and writes linear shapes (a weight moves every point along the full offset), so a
rig whose look depends on in-betweens is approximated by its full shapes (DCC importers handle
in-betweens badly too, DESIGN.md section 3). ``normalOffsets`` are ignored. Points are read in the
mesh prim's own space, as every usdface mesh input; a Z-up stage is turned Y-up like
``import-mesh --up-axis Z``. Several meshes with blend shapes are an error unless ``mesh_path``
names one.

Writing (:func:`write_curves_layer`)
------------------------------------
One self-contained layer (it sublayers nothing, so it imports alone)::

    /Face                 SkelRoot; time-sampled xformOp:transform = head motion (decision D1)
    /Face/Geom            Mesh (the neutral), SkelBindingAPI: skel:skeleton, skel:blendShapes,
                          skel:blendShapeTargets, rigid binding to the one joint
    /Face/Geom/<shape>    BlendShape: offsets (+ pointIndices when the shape moves few points)
    /Face/Skeleton        Skeleton: one joint "Face" at identity (no xformOp, decision D3),
                          skel:animationSource -> Anim
    /Face/Skeleton/Anim   SkelAnimation: blendShapes, time-sampled blendShapeWeights

Time code = frame index from 0 (decision D2); ``timeCodesPerSecond = framesPerSecond`` = the rate.
BlendShape prim names are the shape names made valid identifiers (the ``skel:blendShapes``
tokens keep the rig's names). :func:`evaluate_curves_layer` poses the mesh with UsdSkel's own
BlendShapeQuery, the reference the tests and the Blender check compare against.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

from ..errors import FormatError, InputError, MeshError, list_names
from ..model.mesh import FaceMesh
from .capture_layer import _matrix_from_usd
from .layers import open_stage, output_layer, set_provenance, set_stage_metadata, stage_units
from .motion import author_head_motion
from .mesh_layer import author_mesh, author_regions, mesh_from_prim, read_regions

__all__ = ["UsdRig", "CurveSamples", "read_blendshape_rig", "write_curves_layer", "evaluate_curves_layer",
           "read_curves_layer", "write_points_layer", "head_motion_of_layer", "SKELETON_NAME", "ANIM_NAME"]

SKELETON_NAME = "Skeleton"
ANIM_NAME = "Anim"
ROOT_JOINT = "Face"
#: a shape moving fewer than this fraction of the points is written sparse (pointIndices)
SPARSE_FRACTION = 0.5


@dataclass
class UsdRig:
    """What :func:`read_blendshape_rig` found."""

    mesh: FaceMesh
    regions: list
    names: list
    deltas: np.ndarray  # (K, N, 3)
    notes: list
    prim_path: str


def _identifier(name: str, taken: set) -> str:
    ident = re.sub(r"[^A-Za-z0-9_]", "_", name)
    if not ident or ident[0].isdigit():
        ident = "_" + ident
    base, i = ident, 1
    while ident in taken:
        i += 1
        ident = f"{base}_{i}"
    taken.add(ident)
    return ident


def _meshes_with_shapes(stage: Usd.Stage) -> list:
    out = []
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh) and prim.HasAPI(UsdSkel.BindingAPI):
            if UsdSkel.BindingAPI(prim).GetBlendShapesAttr().HasAuthoredValue():
                out.append(prim)
    return out


def read_blendshape_rig(path, *, mesh_path: str | None = None, units: str | None = None) -> UsdRig:
    """Read the blend shapes of a USD face mesh (see the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
    mesh_path : str, optional
        Prim path of the mesh when the file holds several meshes with blend shapes.
    units : str, optional
        Units when the stage has no ``metersPerUnit``.

    Raises
    ------
    InputError, FormatError, MeshError
        Naming the file, prim or shape at fault.
    """
    stage = open_stage(path, what="rig")
    if mesh_path is not None:
        prim = stage.GetPrimAtPath(mesh_path)
        if not prim or not prim.IsA(UsdGeom.Mesh):
            raise InputError(f"rig {path}: no Mesh prim at {mesh_path}")
    else:
        found = _meshes_with_shapes(stage)
        if not found:
            raise InputError(f"rig {path}: no Mesh with blend shapes (skel:blendShapes and skel:blendShapeTargets); "
                             "give a neutral mesh with --shapes DIR|NPZ instead")
        if len(found) > 1:
            raise InputError(f"rig {path}: {len(found)} meshes have blend shapes "
                             f"({list_names(str(p.GetPath()) for p in found)}); say which one")
        prim = found[0]
    binding = UsdSkel.BindingAPI(prim)
    names = list(binding.GetBlendShapesAttr().Get() or [])
    targets = list(binding.GetBlendShapeTargetsRel().GetTargets())
    where = f"rig {path}: {prim.GetPath()}"
    if not names:
        raise InputError(f"{where} has no skel:blendShapes")
    if len(targets) != len(names):
        raise FormatError(f"{where}: {len(names)} skel:blendShapes names but {len(targets)} skel:blendShapeTargets")
    dups = sorted({n for n in names if names.count(n) > 1})
    if dups:
        raise FormatError(f"{where}: duplicate shape names {list_names(dups)} in skel:blendShapes")
    unit = stage_units(stage) or units
    if unit is None:
        raise MeshError(f"rig {path}: the stage has no metersPerUnit; say its units with --mesh-units")
    mesh = mesh_from_prim(prim, units=unit, source=str(path))
    n_points = mesh.n_points
    deltas = np.zeros((len(names), n_points, 3))
    notes = []
    for k, (name, tpath) in enumerate(zip(names, targets)):
        tprim = stage.GetPrimAtPath(tpath)
        if not tprim or not tprim.IsA(UsdSkel.BlendShape):
            raise FormatError(f"{where}: target {tpath} of shape {name!r} is not a BlendShape prim")
        shape = UsdSkel.BlendShape(tprim)
        offsets = shape.GetOffsetsAttr().Get()
        if offsets is None:
            raise FormatError(f"{where}: shape {name!r} ({tpath}) has no offsets")
        off = np.asarray(offsets, dtype=np.float64)
        if not np.isfinite(off).all():
            raise FormatError(f"{where}: NaN or infinite offsets in shape {name!r} ({tpath})")
        idx_attr = shape.GetPointIndicesAttr()
        idx = idx_attr.Get() if idx_attr.HasAuthoredValue() else None
        if idx is not None:  # sparse (an empty list: a shape that moves nothing)
            ind = np.asarray(idx, dtype=np.int64)
            if ind.size != off.shape[0]:
                raise FormatError(f"{where}: shape {name!r} has {off.shape[0]} offsets for {ind.size} pointIndices")
            if ind.size and (ind.min() < 0 or ind.max() >= n_points):
                raise MeshError(f"{where}: shape {name!r} has another topology: pointIndices up to {int(ind.max())}, "
                                f"the mesh has {n_points} points")
            if np.unique(ind).size != ind.size:
                raise FormatError(f"{where}: shape {name!r} repeats points in its pointIndices")
            if ind.size:
                deltas[k, ind] = off
        else:
            if off.shape[0] != n_points:
                raise MeshError(f"{where}: shape {name!r} has another topology: {off.shape[0]} offsets, the mesh has "
                                f"{n_points} points")
            deltas[k] = off
        inb = shape.GetInbetweens()
        if inb:
            weights = sorted(float(i.GetWeight()) for i in inb)
            notes.append(f"in-between shapes of {name!r} at weights {', '.join(f'{w:g}' for w in weights)} dropped: "
                         "usdface uses the full shape linearly")
    if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z:  # (x, y, z) -> (x, z, -y), as import-mesh
        p = mesh.points
        mesh = mesh.with_points(np.stack([p[:, 0], p[:, 2], -p[:, 1]], axis=1))
        deltas = np.stack([deltas[..., 0], deltas[..., 2], -deltas[..., 1]], axis=-1)
        notes.append("Z-up stage turned Y-up")
    return UsdRig(mesh, read_regions(prim), names, deltas, notes, str(prim.GetPath()))


@dataclass(frozen=True)
class CurveSamples:
    """The animation of a curves layer (:func:`write_curves_layer`).

    Attributes
    ----------
    times : ndarray (T,)
        Time codes of the weight samples (frame indices).
    weights : ndarray (T, K)
        Weights at those times, in [0, 1].
    rate : float
        timeCodesPerSecond = framesPerSecond.
    start, end : float
        The layer's time range.
    head_motion : ndarray (H, 4, 4), optional
        Mesh-space head motion (column vectors) at ``head_times``; None: no op on /Face.
    head_times : ndarray (H,), optional
    """

    times: np.ndarray
    weights: np.ndarray
    rate: float
    start: float
    end: float
    head_motion: np.ndarray | None = None
    head_times: np.ndarray | None = None


def write_curves_layer(path, rig, regions, samples: CurveSamples | None = None, *, prov: dict,
                       report: dict | None = None) -> str:
    """Write a weight-curve layer (see the module docstring) atomically.

    Parameters
    ----------
    path : path, or (Python API) an Sdf.Layer / Usd.Stage to author into
    rig : usdface.blendshape.rig.BlendShapeRig (or any object with ``mesh``, ``names``, ``deltas``)
        The neutral (mesh units; its units are the layer's), the K shape names and their (K, N, 3)
        offsets.
    regions : list of Region
        Authored as FaceRegionAPI on the mesh (previews colour them).
    samples : CurveSamples, optional
        The weight curves and the head motion; None writes a rig (weights 0 as the attribute's
        default value, no time samples, no time range).
    prov, report : dict
        Provenance; a JSON-able report stored beside it.
    """
    mesh, names = rig.mesh, rig.names
    d = np.asarray(rig.deltas, dtype=np.float64)
    static = samples is None
    rate, start, end = (None, None, None) if static else (samples.rate, samples.start, samples.end)
    head_motion, head_times = (None, None) if static else (samples.head_motion, samples.head_times)
    w = np.zeros(len(names)) if static else np.asarray(samples.weights, dtype=np.float64)
    t = np.zeros(0) if static else np.asarray(samples.times, dtype=np.float64)
    if w.shape != ((len(names),) if static else (t.size, len(names))):
        raise InputError(f"weights must have shape {(len(names),) if static else (t.size, len(names))}; got {w.shape}")
    with output_layer(path) as stage:
        set_stage_metadata(stage, units=mesh.units, default_prim="Face", rate=rate, start=start, end=end)
        root = UsdSkel.Root.Define(stage, "/Face")
        if head_motion is not None:
            author_head_motion(stage, root.GetPath(), head_motion, times=head_times)
        geom = author_mesh(stage, mesh, "/Face/Geom")
        UsdGeom.Mesh(geom).CreateNormalsAttr().Block()  # shapes move the points: no stale normals
        author_regions(geom.GetPrim(), regions or [])
        binding = UsdSkel.BindingAPI.Apply(geom.GetPrim())
        taken: set = set()
        target_paths = []
        for k, name in enumerate(names):
            shape_path = geom.GetPath().AppendChild(_identifier(name, taken))
            shape = UsdSkel.BlendShape.Define(stage, shape_path)
            moved = np.flatnonzero(np.abs(d[k]).max(axis=1) > 0)
            if moved.size == 0:  # one zero offset: an empty shape is dropped by Blender's importer
                moved = np.zeros(1, dtype=np.int64)
            if moved.size < SPARSE_FRACTION * d.shape[1]:
                shape.CreateOffsetsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(d[k, moved], dtype=np.float32)))
                shape.CreatePointIndicesAttr(Vt.IntArray.FromNumpy(moved.astype(np.int32)))
            else:
                shape.CreateOffsetsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(d[k], dtype=np.float32)))
            target_paths.append(shape_path)
        binding.CreateBlendShapesAttr(Vt.TokenArray(list(names)))
        binding.CreateBlendShapeTargetsRel().SetTargets(target_paths)
        skel = UsdSkel.Skeleton.Define(stage, "/Face/" + SKELETON_NAME)
        skel.CreateJointsAttr(Vt.TokenArray([ROOT_JOINT]))
        skel.CreateBindTransformsAttr(Vt.Matrix4dArray([Gf.Matrix4d(1.0)]))
        skel.CreateRestTransformsAttr(Vt.Matrix4dArray([Gf.Matrix4d(1.0)]))
        anim = UsdSkel.Animation.Define(stage, skel.GetPath().AppendChild(ANIM_NAME))
        anim.CreateJointsAttr(Vt.TokenArray([ROOT_JOINT]))
        anim.CreateBlendShapesAttr(Vt.TokenArray(list(names)))
        attr = anim.CreateBlendShapeWeightsAttr()
        w32 = np.ascontiguousarray(w, dtype=np.float32)
        if static:
            attr.Set(Vt.FloatArray.FromNumpy(w32))
        with Sdf.ChangeBlock():
            for i, tc in enumerate(t):
                attr.Set(Vt.FloatArray.FromNumpy(w32[i]), Usd.TimeCode(float(tc)))
        UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
        binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
        # every point rigidly on the one joint: importers that skin see the rest pose
        binding.CreateJointIndicesPrimvar(True, 1).Set(Vt.IntArray([0]))
        binding.CreateJointWeightsPrimvar(True, 1).Set(Vt.FloatArray([1.0]))
        if report is not None:
            prov = dict(prov, blendshapes=json.dumps(report, sort_keys=True, default=float))
        set_provenance(stage, prov)
    return str(path)


def read_curves_layer(path) -> dict:
    """The weight curves of a layer written by :func:`write_curves_layer` (or any SkelAnimation with
    blend-shape weights): ``names``, ``times`` (T,), ``weights`` (T, K), ``rate``."""
    stage = open_stage(path, what="curves")
    anims = [p for p in stage.Traverse() if p.IsA(UsdSkel.Animation)]
    if len(anims) != 1:
        raise InputError(f"curves {path}: expected one SkelAnimation, found {len(anims)}")
    anim = UsdSkel.Animation(anims[0])
    names = list(anim.GetBlendShapesAttr().Get() or [])
    attr = anim.GetBlendShapeWeightsAttr()
    times = np.asarray(attr.GetTimeSamples(), dtype=np.float64)
    weights = np.stack([np.asarray(attr.Get(Usd.TimeCode(float(tc))), dtype=np.float64) for tc in times]) \
        if times.size else np.zeros((0, len(names)))
    return {"names": names, "times": times, "weights": weights, "rate": stage.GetTimeCodesPerSecond()}


def evaluate_curves_layer(path, *, times=None, world: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Pose the face mesh of a blend-shape layer with UsdSkel (AnimQuery + BlendShapeQuery).

    Parameters
    ----------
    path : path of a layer (or a shot composing one) with one SkelRoot
    times : sequence of time codes, optional (default: every weight sample)
    world : bool
        Apply the mesh's local-to-world transform (the head motion on /Face); False gives the
        points in the mesh's own (stabilised) space.

    Returns
    -------
    times : ndarray (F,)
    points : ndarray (F, N, 3) float64
    """
    stage = open_stage(path, what="curves")
    roots = [p for p in stage.Traverse() if p.IsA(UsdSkel.Root)]
    if len(roots) != 1:
        raise InputError(f"curves {path}: expected one SkelRoot, found {len(roots)}")
    cache = UsdSkel.Cache()
    root = UsdSkel.Root(roots[0])
    cache.Populate(root, Usd.TraverseInstanceProxies())
    bindings = cache.ComputeSkelBindings(root, Usd.TraverseInstanceProxies())
    if not bindings:
        raise InputError(f"curves {path}: no mesh bound to a skeleton under {roots[0].GetPath()}")
    skel_query = cache.GetSkelQuery(bindings[0].GetSkeleton())
    skin_query = bindings[0].GetSkinningTargets()[0]
    anim_query = skel_query.GetAnimQuery()
    if not anim_query:
        raise InputError(f"curves {path}: the skeleton has no animation source")
    mesh_prim = skin_query.GetPrim()
    blend_query = UsdSkel.BlendShapeQuery(UsdSkel.BindingAPI(mesh_prim))
    mapper = skin_query.GetBlendShapeMapper()
    point_indices = blend_query.ComputeBlendShapePointIndices()
    sub_offsets = blend_query.ComputeSubShapePointOffsets()
    rest = UsdGeom.Mesh(mesh_prim).GetPointsAttr().Get()
    if times is None:
        times = anim_query.GetBlendShapeWeightTimeSamples()
    times = [float(tc) for tc in times]
    out = np.empty((len(times), len(rest), 3))
    xf = UsdGeom.XformCache()
    for i, tc in enumerate(times):
        weights = anim_query.ComputeBlendShapeWeights(Usd.TimeCode(tc))
        if mapper is not None and not mapper.IsNull():
            weights = mapper.Remap(weights)
        sub_w, shape_idx, sub_idx = blend_query.ComputeSubShapeWeights(weights)
        pts = Vt.Vec3fArray(rest)
        if not blend_query.ComputeDeformedPoints(sub_w, shape_idx, sub_idx, point_indices, sub_offsets, pts):
            raise InputError(f"curves {path}: UsdSkel could not apply the blend shapes at time {tc}")
        p = np.asarray(pts, dtype=np.float64)
        if world:
            xf.SetTime(Usd.TimeCode(tc))
            m = np.array(xf.GetLocalToWorldTransform(mesh_prim), dtype=np.float64)
            p = p @ m[:3, :3] + m[3, :3]
        out[i] = p
    return np.asarray(times, dtype=np.float64), out


def head_motion_of_layer(path) -> tuple[np.ndarray, np.ndarray] | None:
    """(times, (T, 4, 4) column-vector matrices) of /Face's time-sampled transform, or None."""
    stage = open_stage(path, what="curves")
    prim = stage.GetDefaultPrim()
    attr = prim.GetAttribute("xformOp:transform") if prim else None
    if not attr or not attr.GetNumTimeSamples():
        return None
    times = np.asarray(attr.GetTimeSamples(), dtype=np.float64)
    return times, np.stack([_matrix_from_usd(attr.Get(Usd.TimeCode(float(t)))) for t in times])


def write_points_layer(path, *, mesh: FaceMesh, regions, points, rate: float, start: float, head_motion=None,
                       prov: dict) -> str:
    """A self-contained points shot: /Face (head motion op, D1) and /Face/Geom with time-sampled
    points (e.g. the rig's pose plus a corrective), time codes ``start + frame``."""
    pts = np.asarray(points, dtype=np.float32)
    n = pts.shape[0]
    with output_layer(path) as stage:
        set_stage_metadata(stage, units=mesh.units, default_prim="Face", rate=rate, start=start, end=start + n - 1)
        root = UsdGeom.Xform.Define(stage, "/Face")
        if head_motion is not None:
            author_head_motion(stage, root.GetPath(), head_motion, start=start)
        geom = author_mesh(stage, mesh, "/Face/Geom")
        geom.CreateNormalsAttr().Block()
        author_regions(geom.GetPrim(), regions or [])
        attr = geom.GetPointsAttr()
        ext = geom.GetExtentAttr()
        with Sdf.ChangeBlock():
            for f in range(n):
                tc = Usd.TimeCode(float(start + f))
                attr.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(pts[f])), tc)
                lo, hi = pts[f].min(axis=0), pts[f].max(axis=0)
                ext.Set(Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]), tc)
        set_provenance(stage, prov)
    return str(path)
