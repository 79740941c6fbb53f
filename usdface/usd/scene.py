"""Reading what a composed stage shows at a time, for previews and evaluation."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdGeom

from ..errors import InputError
from ..mesh.model import FaceMesh, Region
from .capture_layer import find_marker_set
from .layers import open_stage, stage_units
from .mesh_layer import BINDING_API, find_mesh, mesh_from_prim, read_binding, read_regions


@dataclass
class SceneFrame:
    """What the stage shows at one time code (all in the stage's world space and units)."""

    mesh: FaceMesh                 # topology, points at the time
    rest_points: np.ndarray        # (N, 3) the mesh's default (rest) points
    regions: list[Region]
    bound_points: np.ndarray | None  # (M, 3) bound surface points at the time
    markers: np.ndarray | None       # (M', 3) capture markers, world space, NaN where invalid
    marker_names: list[str]
    hybrid_weight: np.ndarray | None
    animated: bool
    time: float


def _world(prim: Usd.Prim, points: np.ndarray, time) -> np.ndarray:
    m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(time))
    return points @ m[:3, :3] + m[3, :3]


def time_range(stage: Usd.Stage) -> tuple[float, float] | None:
    if stage.HasAuthoredTimeCodeRange():
        return stage.GetStartTimeCode(), stage.GetEndTimeCode()
    return None


def read_scene_frame(path, *, time: float | None = None, stage: Usd.Stage | None = None) -> SceneFrame:
    """The face mesh (points at ``time``), regions, binding and capture markers of a stage."""
    stage = stage or open_stage(path, what="file")
    prim = find_mesh(stage, what="file")
    geom = UsdGeom.Mesh(prim)
    if not geom.GetFaceVertexCountsAttr().HasValue():
        raise InputError(f"{path}: {prim.GetPath()} has no topology here (an over-only layer); "
                         "preview the shot.usda (or binding.usda) that composes it with the mesh")
    animated = geom.GetPointsAttr().GetNumTimeSamples() > 0
    if time is None:
        rng = time_range(stage)
        time = rng[0] if rng else 0.0
    tc = Usd.TimeCode(time)
    units = stage_units(stage)
    mesh = mesh_from_prim(prim, units=units, source=str(path), time=tc)
    mesh = mesh.with_points(_world(prim, mesh.points, tc))
    rest = np.asarray(geom.GetPointsAttr().Get(Usd.TimeCode.Default()), dtype=np.float64)
    rest = _world(prim, rest, Usd.TimeCode.Default())
    bound = None
    if prim.HasAPI(BINDING_API):
        bound = read_binding(stage, source=str(path)).surface_points(mesh.points)
    markers, names = None, []
    try:
        mprim = find_marker_set(stage)
    except InputError:
        mprim = None
    if mprim is not None:
        pts = np.asarray(UsdGeom.Points(mprim).GetPointsAttr().Get(tc), dtype=np.float64)
        markers = _world(mprim, pts, tc)
        valid = mprim.GetAttribute("primvars:usdface:valid")
        if valid and valid.HasValue():
            markers[~np.asarray(valid.Get(tc), dtype=bool)] = np.nan
        names = list(mprim.GetAttribute("usdface:markerSet:names").Get() or [])
    w = UsdGeom.PrimvarsAPI(prim).GetPrimvar("usdface:hybridWeight")
    weight = np.asarray(w.Get(), dtype=np.float64) if w and w.HasValue() else None
    return SceneFrame(mesh=mesh, rest_points=rest, regions=read_regions(prim), bound_points=bound, markers=markers,
                      marker_names=names, hybrid_weight=weight, animated=animated, time=float(time))


def read_points_at(path, time: float) -> np.ndarray:
    """World-space points of the face mesh of ``path`` at ``time`` (for error previews)."""
    stage = open_stage(path, what="reference")
    prim = find_mesh(stage, what="reference")
    pts = np.asarray(UsdGeom.Mesh(prim).GetPointsAttr().Get(Usd.TimeCode(time)), dtype=np.float64)
    return _world(prim, pts, Usd.TimeCode(time))
