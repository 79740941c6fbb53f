"""Muscle rig layers (FaceMuscleAPI on BasisCurves) and simulated tissue animation layers.

Rig layer (``usdface muscles``, .usda)::

    /Face                      (the mesh layer is a sublayer, so the muscles' mesh relationships resolve)
      /Muscles       Scope     usdface:jaw:pivot, usdface:jaw:axis, usdface:jaw:maxAngle,
                               usdface:tissue:parameters (JSON), usdface:rig:placement,
                               usdface:rig:landmarks (JSON)
        /zygomaticMajor_L  BasisCurves + FaceMuscleAPI: a 2-point curve origin -> insertion
        /orbicularisOris   BasisCurves + FaceMuscleAPI: the ellipse (closed, 32 points) in its plane

Animation layer (``usdface simulate`` / ``fit-muscles``, .usdc): sublayers the rig and the mesh
layer (so it opens alone as the animated face), then ``over``s with time-sampled points and extent
on the mesh prim, ``usdface:muscle:contraction`` samples on each muscle prim and
``usdface:jaw:opening`` samples on /Face/Muscles, showing which muscles drive the face. Beside it,
``<stem>_shot.usda`` (:func:`write_tissue_shot`) is the shot stage to open.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from ..errors import InputError
from ..tissue.animation import ControlSamples
from ..tissue.muscles import Muscle
from ..tissue.rig import MuscleRig
from ..units import scale_between
from .layers import (USD_SUFFIXES, add_sublayer, checkpoint, is_in_memory, open_stage, output_layer, set_provenance,
                     set_stage_metadata, stage_units)
from .mesh_layer import GEOM_PRIM, find_mesh
from .schemas import require_registered

MUSCLE_API = "FaceMuscleAPI"
MUSCLES_SCOPE = "Muscles"
NS = "usdface:muscle"
_LINEAR_COLOR = (0.85, 0.2, 0.2)
_SPHINCTER_COLOR = (0.95, 0.55, 0.15)


def _is_usd(source) -> bool:
    """A USD layer (a file with a USD suffix, or in memory), not a mesh file."""
    return source is not None and (is_in_memory(source) or str(source).lower().endswith(USD_SUFFIXES))


def _vec3d(v):
    return Gf.Vec3d(*[float(c) for c in v])


def _ellipse_points(m: Muscle, n: int = 32) -> np.ndarray:
    """Points of a sphincter's ellipse in the plane of its two largest semi-axes."""
    order = np.argsort(m.semi_axes)[::-1]
    a, b = order[0], order[1]
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    pts = np.tile(m.centre, (n, 1))
    pts[:, a] += m.semi_axes[a] * np.cos(t)
    pts[:, b] += m.semi_axes[b] * np.sin(t)
    return pts


def write_rig_layer(path, rig: MuscleRig, *, mesh_path=None, mesh_prim_path: str = GEOM_PRIM, prov: dict,
                    default_prim: str = "Face") -> str:
    """Write a muscle rig layer atomically.

    Parameters
    ----------
    rig : MuscleRig
    mesh_path : path, optional
        The mesh layer (USD): sublayered, and its mesh prim is the muscles' ``mesh`` target. For a
        mesh that is not a USD layer, the target is ``mesh_prim_path`` (where `usdface import-mesh`
        puts it).
    """
    require_registered()
    target = Sdf.Path(mesh_prim_path)
    units = rig.units
    if _is_usd(mesh_path):
        mesh_stage = open_stage(mesh_path, what="mesh")
        target = find_mesh(mesh_stage).GetPath()
        dp = mesh_stage.GetDefaultPrim()
        default_prim = dp.GetName() if dp else default_prim
    else:
        mesh_path = None
    with output_layer(path) as stage:
        if mesh_path is not None:
            add_sublayer(stage, mesh_path, path)
        set_stage_metadata(stage, units=units, default_prim=default_prim)
        if not stage.GetPrimAtPath(f"/{default_prim}"):
            UsdGeom.Xform.Define(stage, f"/{default_prim}")
        scope = UsdGeom.Scope.Define(stage, f"/{default_prim}/{MUSCLES_SCOPE}").GetPrim()
        scope.CreateAttribute("usdface:jaw:pivot", Sdf.ValueTypeNames.Point3d, custom=True).Set(_vec3d(rig.jaw_pivot))
        scope.CreateAttribute("usdface:jaw:axis", Sdf.ValueTypeNames.Vector3d, custom=True).Set(_vec3d(rig.jaw_axis))
        scope.CreateAttribute("usdface:jaw:maxAngle", Sdf.ValueTypeNames.Double, custom=True).Set(float(rig.jaw_max_angle))
        scope.CreateAttribute("usdface:jaw:opening", Sdf.ValueTypeNames.Float, custom=True).Set(0.0)
        scope.CreateAttribute("usdface:tissue:parameters", Sdf.ValueTypeNames.String, custom=True).Set(
            json.dumps(rig.tissue, sort_keys=True))
        scope.CreateAttribute("usdface:rig:placement", Sdf.ValueTypeNames.Token, custom=True).Set(rig.placement)
        scope.CreateAttribute("usdface:rig:landmarks", Sdf.ValueTypeNames.String, custom=True).Set(
            json.dumps({k: [round(float(c), 6) for c in v] for k, v in rig.landmarks.items()}, sort_keys=True))
        for m in rig.muscles:
            curves = UsdGeom.BasisCurves.Define(stage, scope.GetPath().AppendChild(m.name))
            curves.CreateTypeAttr(UsdGeom.Tokens.linear)
            if m.type == "linear":
                pts = np.stack([m.origin, m.insertion])
                curves.CreateWrapAttr(UsdGeom.Tokens.nonperiodic)
                color = _LINEAR_COLOR
            else:
                pts = _ellipse_points(m)
                curves.CreateWrapAttr(UsdGeom.Tokens.periodic)
                color = _SPHINCTER_COLOR
            curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
            curves.CreateCurveVertexCountsAttr(Vt.IntArray([len(pts)]))
            width = 0.15 * (1.0 if units is None else scale_between("cm", units))
            curves.CreateWidthsAttr(Vt.FloatArray([width]))
            curves.SetWidthsInterpolation(UsdGeom.Tokens.constant)
            curves.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(Vt.Vec3fArray([Gf.Vec3f(*color)]))
            lo, hi = pts.min(axis=0) - width, pts.max(axis=0) + width
            curves.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*lo.tolist()), Gf.Vec3f(*hi.tolist())]))
            prim = curves.GetPrim()
            prim.ApplyAPI(MUSCLE_API)
            prim.GetAttribute(f"{NS}:type").Set(m.type)
            if m.type == "linear":
                prim.GetAttribute(f"{NS}:origin").Set(_vec3d(m.origin))
                prim.GetAttribute(f"{NS}:insertion").Set(_vec3d(m.insertion))
                prim.GetAttribute(f"{NS}:zoneAngle").Set(float(m.zone_angle))
            else:
                prim.GetAttribute(f"{NS}:centre").Set(_vec3d(m.centre))
                prim.GetAttribute(f"{NS}:semiAxes").Set(_vec3d(m.semi_axes))
            prim.GetAttribute(f"{NS}:innerRadius").Set(float(m.inner_radius))
            prim.GetAttribute(f"{NS}:outerRadius").Set(float(m.outer_radius))
            prim.GetAttribute(f"{NS}:maxForce").Set(float(m.max_force))
            prim.GetAttribute(f"{NS}:contraction").Set(0.0)
            prim.GetRelationship(f"{NS}:mesh").SetTargets([target])
        set_provenance(stage, prov)
    return str(path)


def _find_scope(stage: Usd.Stage, source) -> Usd.Prim:
    root = stage.GetDefaultPrim()
    if root:
        scope = root.GetChild(MUSCLES_SCOPE)
        if scope:
            return scope
    for prim in stage.Traverse():
        if prim.GetName() == MUSCLES_SCOPE and any(c.HasAPI(MUSCLE_API) for c in prim.GetChildren()):
            return prim
    raise InputError(f"rig {source}: no {MUSCLES_SCOPE} scope with {MUSCLE_API} curves (write one with "
                     "`usdface muscles`)")


def read_rig_layer(path, *, stage: Usd.Stage | None = None, units: str | None = None) -> MuscleRig:
    """Read a muscle rig layer.

    Parameters
    ----------
    units : str, optional
        Convert the rig's lengths to these units (the mesh's) when the layer's differ.

    Raises
    ------
    InputError
        No muscles, or a muscle with missing or malformed values (named).
    """
    stage = stage or open_stage(path, what="rig")
    scope = _find_scope(stage, path)
    rig_units = stage_units(stage)
    factor = 1.0
    if units is not None and rig_units is not None and units != rig_units:
        factor = scale_between(rig_units, units)
    muscles = []
    for prim in scope.GetChildren():
        if not prim.HasAPI(MUSCLE_API):
            continue
        get = lambda n: prim.GetAttribute(f"{NS}:{n}").Get()  # noqa: E731
        kind = get("type") or "linear"
        vec = lambda n: None if get(n) is None else np.asarray(get(n), dtype=np.float64)  # noqa: E731
        try:
            m = Muscle(name=prim.GetName(), type=str(kind), origin=vec("origin"), insertion=vec("insertion"),
                       centre=vec("centre"), semi_axes=vec("semiAxes"),
                       zone_angle=float(get("zoneAngle") if get("zoneAngle") is not None else 40.0),
                       inner_radius=get("innerRadius"), outer_radius=get("outerRadius"),
                       max_force=float(get("maxForce") if get("maxForce") is not None else 1.0))
        except InputError as e:
            raise InputError(f"rig {path}: {prim.GetPath()}: {e}") from None
        muscles.append(m.scaled(factor) if factor != 1.0 else m)
    if not muscles:
        raise InputError(f"rig {path}: {scope.GetPath()} holds no {MUSCLE_API} curves")
    attr = lambda n: scope.GetAttribute(n).Get() if scope.HasAttribute(n) else None  # noqa: E731
    pivot = attr("usdface:jaw:pivot")
    axis = attr("usdface:jaw:axis")
    if pivot is None or axis is None:
        raise InputError(f"rig {path}: {scope.GetPath()} has no usdface:jaw:pivot / usdface:jaw:axis")
    tissue = json.loads(attr("usdface:tissue:parameters") or "{}")
    landmarks = {k: np.asarray(v, dtype=np.float64) * factor
                 for k, v in json.loads(attr("usdface:rig:landmarks") or "{}").items()}
    return MuscleRig(muscles=tuple(muscles), jaw_pivot=np.asarray(pivot, dtype=np.float64) * factor,
                     jaw_axis=np.asarray(axis, dtype=np.float64),
                     jaw_max_angle=float(attr("usdface:jaw:maxAngle") or 25.0), tissue=tissue, landmarks=landmarks,
                     placement=str(attr("usdface:rig:placement") or "mesh"),
                     units=units if factor != 1.0 else (rig_units or units))


def rig_prim_paths(path, *, stage: Usd.Stage | None = None) -> tuple[str, dict]:
    """(scope path, {muscle name: prim path}) of a rig layer, for writing overs."""
    stage = stage or open_stage(path, what="rig")
    scope = _find_scope(stage, path)
    return str(scope.GetPath()), {p.GetName(): str(p.GetPath()) for p in scope.GetChildren() if p.HasAPI(MUSCLE_API)}


def write_tissue_animation_layer(path, chunks, *, mesh_path, rig_path, mesh, controls: ControlSamples, prov: dict,
                                 progress=None) -> str:
    """Stream a simulated animation into a .usdc layer (saved after every chunk).

    The layer stands alone: it sublayers the rig layer (muscles) and the mesh layer it animates
    (or, for a mesh that is not a USD layer, defines the mesh from ``mesh``), then holds the
    time-sampled points and contractions as overs.

    Parameters
    ----------
    path : path, Sdf.Layer or Usd.Stage
        The layer to write (in memory: authored there, all or nothing).
    chunks : iterable of (slice, ndarray (f, N, 3))
        Skin points (absolute, mesh units) for frames ``slice`` (0-based).
    mesh_path, rig_path : path, Sdf.Layer or Usd.Stage
        The mesh (layer or mesh file) and the rig layer the animation is made of.
    mesh : FaceMesh
        The face (its units are the layer's; its points count is checked against the mesh layer).
    controls : ControlSamples
        Time code of each frame, the layer's rate (timeCodesPerSecond), and per frame the
        contraction of each muscle and the jaw opening, written as time samples.
    prov : dict
        Provenance (:func:`usdface.usd.layers.provenance`).
    progress : object with ``update(n)``, optional

    The chunks are consumed inside the atomic write: if computing them raises (e.g. a diverging
    simulation), nothing is left at ``path``.
    """
    require_registered()
    mesh_stage = open_stage(mesh_path, what="mesh") if _is_usd(mesh_path) else None
    mesh_prim_path = find_mesh(mesh_stage).GetPath() if mesh_stage is not None else Sdf.Path(GEOM_PRIM)
    default_prim = (mesh_stage.GetDefaultPrim().GetName() if mesh_stage is not None and mesh_stage.GetDefaultPrim()
                    else "Face")
    scope_path, muscle_paths = rig_prim_paths(rig_path)
    n_points = mesh.n_points
    if mesh_stage is not None:
        pts = UsdGeom.Mesh(mesh_stage.GetPrimAtPath(mesh_prim_path)).GetPointsAttr().Get()
        if pts is not None and len(pts) != n_points:
            raise InputError(f"animation {path}: {n_points} simulated points but mesh {mesh_path} has {len(pts)}")
    codes = np.asarray(controls.time_codes, dtype=np.float64)
    n_frames = codes.size
    contractions, jaw = controls.contractions, controls.jaw
    if len(contractions) != n_frames or len(jaw) != n_frames:
        raise InputError(f"animation {path}: {n_frames} time codes for {len(contractions)} frames of contractions "
                         f"and {len(jaw)} of jaw opening")
    with output_layer(path) as stage:
        add_sublayer(stage, rig_path, path)
        if mesh_stage is not None:
            add_sublayer(stage, mesh_path, path)
        else:
            from .mesh_layer import author_mesh

            author_mesh(stage, mesh, str(mesh_prim_path))
        set_stage_metadata(stage, units=mesh.units, default_prim=default_prim, rate=controls.rate,
                           start=float(codes[0]), end=float(codes[-1]))
        geom = UsdGeom.Mesh(stage.OverridePrim(mesh_prim_path))
        geom.CreateNormalsAttr().Block()  # normals would go stale under animated points
        points_attr = geom.CreatePointsAttr()
        extent_attr = geom.CreateExtentAttr()
        scope = stage.OverridePrim(scope_path)
        jaw_attr = scope.CreateAttribute("usdface:jaw:opening", Sdf.ValueTypeNames.Float, custom=True)
        c_attrs = []
        for name in controls.muscle_names:
            if name not in muscle_paths:
                raise InputError(f"rig {rig_path}: no muscle prim {name!r}")
            p = stage.OverridePrim(muscle_paths[name])
            c_attrs.append(p.CreateAttribute(f"{NS}:contraction", Sdf.ValueTypeNames.Float))
        written = 0
        for frames, pts in chunks:
            pts = np.asarray(pts, dtype=np.float32)
            lo, hi = pts.min(axis=1), pts.max(axis=1)
            for k, f in enumerate(range(frames.start, frames.stop)):
                t = Usd.TimeCode(float(codes[f]))
                points_attr.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(pts[k])), t)
                extent_attr.Set(Vt.Vec3fArray([Gf.Vec3f(*lo[k].tolist()), Gf.Vec3f(*hi[k].tolist())]), t)
                for a, attr in zip(contractions[f], c_attrs):
                    attr.Set(float(a), t)
                jaw_attr.Set(float(jaw[f]), t)
            written += frames.stop - frames.start
            checkpoint(stage)
            if progress is not None:
                progress.update(frames.stop - frames.start)
        if written != n_frames:
            raise InputError(f"animation {path}: {written} frames computed, expected {n_frames}")
        set_provenance(stage, prov)
    return str(path)


def shot_path_for(output) -> Path:
    """The shot stage written beside a simulate / fit-muscles layer: ``<stem>_shot.usda``."""
    out = Path(output)
    return out.with_name(f"{out.stem}_shot.usda")


def write_tissue_shot(output, layers, *, rate, start, end, units, stabilized_capture=False,
                      processor: str | None = None) -> str | None:
    """Write the shot stage beside the animation layer ``output``: a .usda composing ``layers``
    (strongest first; layers held in memory are left out: they have no file to point to), whose
    provenance names ``processor`` and the identity its layers agree on.
    Returns its path, or None when ``output`` is in memory (no folder to write beside)."""
    from .analysis_layer import write_shot_stage

    if is_in_memory(output):
        return None
    shot = shot_path_for(output)
    write_shot_stage(shot, layers=[layer for layer in layers if not is_in_memory(layer)], rate=rate, start=start,
                     end=end, units=units, stabilized_capture=stabilized_capture, processor=processor)
    return str(shot)


def read_animation_points(path, *, stage: Usd.Stage | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(time codes (F,), points (F, N, 3)) of the mesh prim's time-sampled points in a layer."""
    stage = stage or open_stage(path, what="animation")
    prim = find_mesh(stage, what="animation") if any(p.IsA(UsdGeom.Mesh) for p in stage.Traverse()) else None
    if prim is None:  # an over-only layer: the mesh prim has no type here (TraverseAll sees overs)
        prim = next((p for p in stage.TraverseAll() if p.HasAttribute("points")
                     and p.GetAttribute("points").GetNumTimeSamples()), None)
    if prim is None:
        raise InputError(f"animation {path}: no prim with points")
    attr = prim.GetAttribute("points")
    times = np.asarray(attr.GetTimeSamples(), dtype=np.float64)
    pts = np.stack([np.asarray(attr.Get(Usd.TimeCode(t)), dtype=np.float64) for t in times]) if times.size else \
        np.zeros((0, 0, 3))
    return times, pts


def read_contractions(path, *, stage: Usd.Stage | None = None) -> tuple[np.ndarray, dict]:
    """(time codes, {muscle name: (F,) contraction}) from an animation layer's muscle overs."""
    stage = stage or open_stage(path, what="animation")
    out, times = {}, None
    for prim in stage.TraverseAll():
        attr = prim.GetAttribute(f"{NS}:contraction")
        if attr and attr.GetNumTimeSamples():
            t = np.asarray(attr.GetTimeSamples(), dtype=np.float64)
            times = t if times is None else times
            out[prim.GetName()] = np.asarray([attr.Get(Usd.TimeCode(v)) for v in t], dtype=np.float64)
    return (times if times is not None else np.zeros(0)), out

