"""What a composed stage shows at one time code, for previews: one frame of the one reader of a
composed shot (:class:`usdface.usd.face_evaluator.FaceEvaluator`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd

from ..errors import InputError
from ..model.mesh import FaceMesh, Region
from .face_evaluator import FaceEvaluator
from .layers import open_stage
from .mesh_layer import mesh_from_prim

__all__ = ["SceneFrame", "read_scene_frame"]


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


def read_scene_frame(path, *, time: float | None = None, stage: Usd.Stage | None = None,
                     evaluator: FaceEvaluator | None = None) -> SceneFrame:
    """The face mesh (points at ``time``, deformed as USD composes them: point cache, UsdSkel
    skinning and blend shapes, ancestor transforms), regions, binding and capture markers.

    ``evaluator``: a :class:`~usdface.usd.face_evaluator.FaceEvaluator` of the stage, to reuse for
    many frames (built from ``stage`` or ``path`` otherwise).
    """
    if evaluator is None:
        stage = stage or open_stage(path, what="file")
        evaluator = FaceEvaluator(stage, source=str(path))
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
    markers = evaluator.markers([time])
    return SceneFrame(mesh=mesh, rest_points=rest, regions=evaluator.regions,
                      bound_points=evaluator.bound_points(mesh.points), markers=None if markers is None else markers[0],
                      marker_names=evaluator.marker_names, hybrid_weight=evaluator.hybrid_weight,
                      animated=evaluator.animated, time=float(time))
