"""A shot as playblasts and reports play it: frame by frame over its whole-frame range, with a name
for burn-ins, built on the one reader of a composed shot (:class:`usdface.usd.face_evaluator.FaceEvaluator`:
time-sampled points, UsdSkel skinning and blend shapes, ancestor transforms such as the head motion
on /Face, the capture markers, the binding). Nothing here evaluates animation itself.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from pxr import Usd, UsdGeom, UsdSkel

from ..errors import InputError
from ..model.mesh import Region
from .face_evaluator import FaceEvaluator, remove_head_motion
from .layers import open_stage
from .mesh_layer import find_mesh

if TYPE_CHECKING:
    from ..playblast.plan import PlayblastParameters, PlayblastShots

__all__ = ["ShotReader", "open_playblast_shots", "remove_head_motion", "shot_name"]


def _skinned(prim: Usd.Prim) -> bool:
    return prim.HasAPI(UsdSkel.BindingAPI) and bool(UsdSkel.BindingAPI(prim).GetSkeletonRel().GetTargets())


@dataclass
class ShotReader:
    """A shot (or any layer with a face mesh) opened for frame-by-frame reading.

    Attributes
    ----------
    path : Path
    name : str
        A label for burn-ins: the shot's folder name for ``OUTDIR/shot.usda``, else the file name.
    rate : float
        Time codes per second.
    start, end : int
        First and last time code.
    units : str or None
    triangles : ndarray (T, 3) int64
    face_vertex_counts, face_vertex_indices : ndarray
        The polygons (for wireframes).
    rest_points : ndarray (N, 3)
        World-space default (rest) points: the authored points placed by the transforms at the
        default time (the stabilised space the displacement is measured in).
    regions : list of Region
    hybrid_weight : ndarray (N,) or None
    marker_names : list of str
        Markers of the capture in the shot (empty if none).
    has_binding : bool
    animated : bool
        The face moves (time-sampled points or skinning).
    transfer : dict
        FaceTransferAPI settings (mode, kernel, distanceMethod) when present.
    evaluator : FaceEvaluator
        The reader everything comes from.
    """

    path: Path
    name: str
    rate: float
    start: int
    end: int
    units: str | None
    triangles: np.ndarray
    face_vertex_counts: np.ndarray
    face_vertex_indices: np.ndarray
    rest_points: np.ndarray
    regions: list[Region]
    hybrid_weight: np.ndarray | None
    marker_names: list[str]
    has_binding: bool
    animated: bool
    transfer: dict = field(default_factory=dict)
    evaluator: FaceEvaluator | None = field(default=None, repr=False)

    # --------------------------------------------------------------------------------------------
    @classmethod
    def open(cls, path) -> "ShotReader":
        """Open ``path``; an error names the file when it holds no face mesh with topology."""
        path = Path(path)
        stage = open_stage(path, what="shot")
        try:
            prim = find_mesh(stage, what="shot")
        except InputError:
            raise InputError(f"shot {path}: no Mesh prim (expected a face mesh such as /Face/Geom; "
                             "play a shot.usda, binding.usda or mesh layer)") from None
        geom = UsdGeom.Mesh(prim)
        counts, indices = geom.GetFaceVertexCountsAttr().Get(), geom.GetFaceVertexIndicesAttr().Get()
        if not counts or indices is None:
            raise InputError(f"shot {path}: {prim.GetPath()} has no topology here (an over-only layer); play the "
                             "shot.usda that composes it with the mesh")
        if geom.GetPointsAttr().Get(Usd.TimeCode.Default()) is None:
            raise InputError(f"shot {path}: {prim.GetPath()} has no points")
        ev = FaceEvaluator(stage, mesh=prim.GetPath(), source=str(path))
        if stage.HasAuthoredTimeCodeRange():
            start, end = int(round(stage.GetStartTimeCode())), int(round(stage.GetEndTimeCode()))
        else:
            samples = geom.GetPointsAttr().GetTimeSamples()
            start, end = (int(round(samples[0])), int(round(samples[-1]))) if samples else (0, 0)
        transfer = {}
        for key in ("mode", "kernel", "distanceMethod"):
            a = prim.GetAttribute(f"usdface:transfer:{key}")
            if a and a.HasAuthoredValue():
                transfer[key] = a.Get()
        animated = geom.GetPointsAttr().GetNumTimeSamples() > 1 or _skinned(prim)
        return cls(path=path, name=shot_name(path), rate=ev.rate, start=start, end=end, units=ev.units,
                   triangles=ev.triangles, face_vertex_counts=ev.face_vertex_counts,
                   face_vertex_indices=ev.face_vertex_indices, rest_points=cls._rest(prim),
                   regions=ev.regions, hybrid_weight=ev.hybrid_weight, marker_names=ev.marker_names,
                   has_binding=ev.binding is not None, animated=animated, transfer=transfer, evaluator=ev)

    @staticmethod
    def _rest(prim: Usd.Prim) -> np.ndarray:
        # the authored points placed by the mesh's transforms at the default time (skinned or
        # not): the stabilised space, where the head motion on /Face (time samples only) is absent
        rest_local = UsdGeom.Mesh(prim).GetPointsAttr().Get(Usd.TimeCode.Default())
        m = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default()))
        return np.asarray(rest_local, dtype=np.float64) @ m[:3, :3] + m[3, :3]

    # --------------------------------------------------------------------------------------------
    @property
    def n_frames(self) -> int:
        return self.end - self.start + 1

    @property
    def method(self) -> str:
        """``hybrid interpolate`` style label of the transfer (distance method, RBF mode), or ''."""
        t = self.transfer
        return " ".join(v for v in (t.get("distanceMethod"), t.get("mode")) if v)

    def face_points(self, times, *, stabilized: bool = False) -> np.ndarray:
        """(F, N, 3) world points of the face at ``times`` (the evaluator's); with ``stabilized``
        the head motion on the face's root prim (D1) is taken out, leaving what the transfer did
        (the displacement the colours and the report measure)."""
        pts = self.evaluator.points_range([float(t) for t in times])
        return remove_head_motion(pts, self.head_motion(times)) if stabilized else pts

    def stabilize(self, points: np.ndarray, times) -> np.ndarray | None:
        """``points`` (F, K, 3) at ``times`` without the head motion, or None where the head does
        not move at those times (the points are already stabilised)."""
        head = self.head_motion(times)
        if np.allclose(head, np.eye(4)[None]):
            return None
        return remove_head_motion(points, head)

    def head_motion(self, times) -> np.ndarray:
        """(F, 4, 4) row-vector head motion (:meth:`FaceEvaluator.head_motion`)."""
        return self.evaluator.head_motion(times)

    def markers(self, times, *, stabilized: bool = False) -> np.ndarray | None:
        """(F, M, 3) world positions of the capture markers, NaN where invalid (None: no capture)."""
        return self.evaluator.markers(times, stabilized=stabilized)

    def bound_points(self, face_points: np.ndarray) -> np.ndarray | None:
        """(F, M, 3) bound surface points of the binding on the given face points (None: no binding)."""
        return self.evaluator.bound_points(face_points)

    def transfer_settings(self) -> dict:
        """Every ``usdface:transfer:*`` value on the face mesh (FaceTransferAPI), JSON strings decoded."""
        return self.evaluator.transfer_settings()

    def layer_data(self) -> dict:
        """The root layer's usdface provenance (customLayerData), decoded."""
        return self.evaluator.layer_data()


def shot_name(path) -> str:
    """``take`` for ``.../take/shot.usda`` (the run's folder names the shot), else the file's stem."""
    p = Path(path)
    if p.stem.startswith("shot") and p.parent.name:
        return p.parent.name + ("" if p.stem == "shot" else p.stem[4:])
    return p.stem


def open_playblast_shots(shot, params: PlayblastParameters) -> PlayblastShots:
    """Open a playblast's shots and check them, in this order: the shot (a face mesh that moves)
    and the time codes it plays (``params.frame_range``), the reference (as many points, covering
    those time codes), the second shot (it moves). Errors name the file and the flag."""
    from ..playblast.plan import PlayblastShots  # (the renderer is loaded only for a playblast)
    from ..playblast.timing import shot_times

    reader = ShotReader.open(shot)
    if not reader.animated:
        raise InputError(f"shot {shot}: the face has no animation (no time-sampled points, no skinning); "
                         "use `usdface preview` for a still")
    times = shot_times(reader.start, reader.end, params.frame_range, what=f"shot {shot}")
    reference = other = None
    if params.reference is not None:
        reference = ShotReader.open(params.reference)
        if reference.rest_points.shape != reader.rest_points.shape:
            raise InputError(f"--reference {params.reference}: {reference.rest_points.shape[0]} points; the shot has "
                             f"{reader.rest_points.shape[0]}")
        shot_times(reference.start, reference.end, (times[0], times[-1]), what=f"reference {params.reference}")
    if params.compare is not None:
        other = ShotReader.open(params.compare)
        if not other.animated:
            raise InputError(f"--compare {params.compare}: the face has no animation")
    return PlayblastShots(shot=reader, times=times, reference=reference, compare=other)
