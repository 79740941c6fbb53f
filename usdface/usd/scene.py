"""Reading what a composed stage shows at a time, for previews and evaluation (the face mesh
through :mod:`usdface.usd.evaluate`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdGeom

from ..errors import InputError
from ..model.mesh import FaceMesh, Region
from .capture_layer import find_marker_set
from .evaluate import FaceEvaluator
from .layers import open_stage
from .mesh_layer import BINDING_API, mesh_from_prim, read_binding, read_regions


@dataclass
class SceneFrame:
    """What the stage shows at one time code (all in the stage's world space and units)."""

    mesh: FaceMesh                 # topology, points at the time
    rest_points: np.ndarray        # (N, 3) the undeformed (rest) points, placed as at the time
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


def read_scene_frame(path, *, time: float | None = None, stage: Usd.Stage | None = None,
                     evaluator: FaceEvaluator | None = None) -> SceneFrame:
    """The face mesh (points at ``time``, deformed as USD composes them: point cache, UsdSkel
    skinning and blend shapes, ancestor transforms), regions, binding and capture markers.

    ``evaluator``: a :class:`~usdface.usd.evaluate.FaceEvaluator` of the stage, to reuse for
    many frames (built from ``stage`` or ``path`` otherwise).
    """
    if evaluator is None:
        stage = stage or open_stage(path, what="file")
        evaluator = FaceEvaluator(stage, source=str(path))
    stage = evaluator.stage
    prim = evaluator.prim
    if not evaluator.has_topology:
        raise InputError(f"{path}: {prim.GetPath()} has no topology here (an over-only layer); "
                         "preview the shot.usda (or binding.usda) that composes it with the mesh")
    if time is None:
        time = evaluator.start
    tc = Usd.TimeCode(time)
    mesh = mesh_from_prim(prim, units=evaluator.units, source=str(path), time=tc)
    mesh = mesh.with_points(evaluator.points(time))
    # the undeformed mesh placed as at ``time``: displacement is the deformation alone, the
    # (rigid) head motion on the face's root moves both
    rest = evaluator.rest_points(space="world", time=time)
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
                      marker_names=names, hybrid_weight=weight, animated=evaluator.animated, time=float(time))

