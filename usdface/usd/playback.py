"""Reading a shot frame by frame for playblasts and reports: the face's world points, the capture
markers and the bound points at any list of time codes.

:func:`face_points_at` is the one place that turns a stage and time codes into the face's world
points, through the shared evaluator of animated faces (``usdface.usd.evaluate``: time-sampled
points, UsdSkel skinning and blend shapes, ancestor transforms such as the head motion on /Face);
nothing here evaluates animation itself.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pxr import Usd, UsdGeom, UsdSkel

from ..errors import InputError
from ..model.mesh import Region
from .capture_layer import find_marker_set
from .layers import open_stage, stage_units
from .mesh_layer import BINDING_API, find_mesh, read_binding, read_regions

__all__ = ["ShotReader", "face_points_at", "remove_head_motion"]


def _world_matrices(prim: Usd.Prim, times) -> np.ndarray:
    """(F, 4, 4) local-to-world matrices of ``prim`` (row-vector convention) at ``times``."""
    cache = UsdGeom.XformCache()
    out = np.empty((len(times), 4, 4))
    for i, t in enumerate(times):
        cache.SetTime(Usd.TimeCode(float(t)))
        out[i] = np.asarray(cache.GetLocalToWorldTransform(prim), dtype=np.float64)
    return out


def _skinned(prim: Usd.Prim) -> bool:
    return prim.HasAPI(UsdSkel.BindingAPI) and bool(UsdSkel.BindingAPI(prim).GetSkeletonRel().GetTargets())


def face_points_at(stage: Usd.Stage, prim: Usd.Prim, times) -> np.ndarray:
    """World-space points of the face mesh ``prim`` at each time code of ``times``: the shared
    evaluator (:class:`usdface.usd.evaluate.FaceEvaluator`: point caches, UsdSkel skinning and
    blend shapes, ancestor transforms such as the head motion on /Face).

    Returns
    -------
    ndarray, shape (F, N, 3), float64, the stage's world space and units.
    """
    from .evaluate import FaceEvaluator

    return FaceEvaluator(stage, mesh=prim.GetPath()).points_range([float(t) for t in times])


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
        World-space default (rest) points.
    regions : list of Region
    hybrid_weight : ndarray (N,) or None
    marker_names : list of str
        Markers of the capture in the shot (empty if none).
    has_binding : bool
    animated : bool
        The face moves (time-sampled points or skinning).
    transfer : dict
        FaceTransferAPI settings (mode, kernel, distanceMethod) when present.
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
    _stage: Usd.Stage | None = field(default=None, repr=False)
    _prim: Usd.Prim | None = field(default=None, repr=False)
    _markers_prim: Usd.Prim | None = field(default=None, repr=False)
    _binding: object = field(default=None, repr=False)
    _evaluator: object = field(default=None, repr=False)

    # --------------------------------------------------------------------------------------------
    @classmethod
    def open(cls, path) -> "ShotReader":
        """Open ``path``; an error names the file when it holds no face mesh with topology."""
        from ..model.mesh import FaceMesh

        path = Path(path)
        stage = open_stage(path, what="shot")
        prim = _find_face_mesh(stage)
        if prim is None:
            raise InputError(f"shot {path}: no Mesh prim (expected a face mesh such as /Face/Geom; "
                             "play a shot.usda, binding.usda or mesh layer)")
        geom = UsdGeom.Mesh(prim)
        counts, indices = geom.GetFaceVertexCountsAttr().Get(), geom.GetFaceVertexIndicesAttr().Get()
        if not counts or indices is None:
            raise InputError(f"shot {path}: {prim.GetPath()} has no topology here (an over-only layer); play the "
                             "shot.usda that composes it with the mesh")
        counts, indices = np.asarray(counts), np.asarray(indices)
        rest_local = geom.GetPointsAttr().Get(Usd.TimeCode.Default())
        if rest_local is None:
            raise InputError(f"shot {path}: {prim.GetPath()} has no points")
        tris = FaceMesh(points=np.zeros((len(rest_local), 3)), face_vertex_counts=counts,
                        face_vertex_indices=indices).triangles()
        m = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default()))
        rest = np.asarray(rest_local, dtype=np.float64) @ m[:3, :3] + m[3, :3]
        if stage.HasAuthoredTimeCodeRange():
            start, end = int(round(stage.GetStartTimeCode())), int(round(stage.GetEndTimeCode()))
        else:
            samples = geom.GetPointsAttr().GetTimeSamples()
            start, end = (int(round(samples[0])), int(round(samples[-1]))) if samples else (0, 0)
        try:
            mprim = find_marker_set(stage)
            names = list(mprim.GetAttribute("usdface:markerSet:names").Get() or [])
        except InputError:
            mprim, names = None, []
        w = UsdGeom.PrimvarsAPI(prim).GetPrimvar("usdface:hybridWeight")
        weight = np.asarray(w.Get(), dtype=np.float64) if w and w.HasValue() else None
        binding = read_binding(stage, source=str(path)) if prim.HasAPI(BINDING_API) else None
        transfer = {}
        for key in ("mode", "kernel", "distanceMethod"):
            a = prim.GetAttribute(f"usdface:transfer:{key}")
            if a and a.HasAuthoredValue():
                transfer[key] = a.Get()
        animated = geom.GetPointsAttr().GetNumTimeSamples() > 1 or _skinned(prim)
        return cls(path=path, name=shot_name(path), rate=float(stage.GetTimeCodesPerSecond()), start=start, end=end,
                   units=stage_units(stage), triangles=tris, face_vertex_counts=counts, face_vertex_indices=indices,
                   rest_points=rest, regions=read_regions(prim), hybrid_weight=weight, marker_names=names,
                   has_binding=binding is not None, animated=animated, transfer=transfer, _stage=stage, _prim=prim,
                   _markers_prim=mprim, _binding=binding)

    # --------------------------------------------------------------------------------------------
    @property
    def evaluator(self):
        """The shared evaluator of this shot's face (built once)."""
        if self._evaluator is None:
            from .evaluate import FaceEvaluator

            self._evaluator = FaceEvaluator(self._stage, mesh=self._prim.GetPath(), source=str(self.path))
        return self._evaluator

    @property
    def n_frames(self) -> int:
        return self.end - self.start + 1

    @property
    def method(self) -> str:
        """``hybrid interpolate`` style label of the transfer (distance method, RBF mode), or ''."""
        t = self.transfer
        return " ".join(v for v in (t.get("distanceMethod"), t.get("mode")) if v)

    def face_points(self, times, *, stabilized: bool = False) -> np.ndarray:
        """(F, N, 3) world points of the face at ``times`` (see :func:`face_points_at`); with
        ``stabilized`` the head motion on the face's root prim (D1) is taken out, leaving what the
        transfer did (the displacement the colours and the report measure)."""
        pts = self.evaluator.points_range([float(t) for t in times])
        return remove_head_motion(pts, self.head_motion(times)) if stabilized else pts

    def head_motion(self, times) -> np.ndarray:
        """(F, 4, 4) row-vector transforms of the face's root prim (the default prim above the
        mesh: its time-sampled ``xformOp:transform`` is the head motion, identity at the neutral
        frame), identity when it has none. World = stabilised @ H(t)."""
        out = np.repeat(np.eye(4)[None], len(times), axis=0)
        root = self._stage.GetDefaultPrim()
        if not root or not self._prim.GetPath().HasPrefix(root.GetPath()) or not root.IsA(UsdGeom.Xformable):
            return out
        xf = UsdGeom.Xformable(root)
        if not xf.TransformMightBeTimeVarying():
            m = np.asarray(xf.GetLocalTransformation(Usd.TimeCode.Default()), dtype=np.float64)
            return np.repeat(m[None], len(times), axis=0)
        for i, t in enumerate(times):
            out[i] = np.asarray(xf.GetLocalTransformation(Usd.TimeCode(float(t))), dtype=np.float64)
        return out

    def markers(self, times, *, stabilized: bool = False) -> np.ndarray | None:
        """(F, M, 3) world positions of the capture markers, NaN where invalid (None: no capture);
        ``stabilized``: without the head motion, like :meth:`face_points`."""
        if self._markers_prim is None:
            return None
        if stabilized:
            return remove_head_motion(self.markers(times), self.head_motion(times))
        prim = self._markers_prim
        attr = UsdGeom.Points(prim).GetPointsAttr()
        valid = prim.GetAttribute("primvars:usdface:valid")
        mats = _world_matrices(prim, times)
        out = np.empty((len(times), len(self.marker_names), 3))
        for i, t in enumerate(times):
            tc = Usd.TimeCode(float(t))
            p = np.asarray(attr.Get(tc), dtype=np.float64)
            p = p @ mats[i, :3, :3] + mats[i, 3, :3]
            if valid and valid.HasValue():
                p[~np.asarray(valid.Get(tc), dtype=bool)] = np.nan
            out[i] = p
        return out

    def bound_points(self, face_points: np.ndarray) -> np.ndarray | None:
        """(F, M, 3) bound surface points of the binding on the given face points (None: no binding)."""
        if self._binding is None:
            return None
        b = self._binding
        tv, bc = np.asarray(b.triangle_vertices), np.asarray(b.barycentrics)
        return np.einsum("fmkd,mk->fmd", face_points[:, tv], bc)

    def transfer_settings(self) -> dict:
        """Every ``usdface:transfer:*`` value on the face mesh (FaceTransferAPI), JSON strings decoded."""
        out = {}
        for attr in self._prim.GetAttributes():
            name = attr.GetName()
            if name.startswith("usdface:transfer:") and attr.HasAuthoredValue():
                v = attr.Get()
                if isinstance(v, str) and v[:1] in "[{":
                    try:
                        v = json.loads(v)
                    except ValueError:
                        pass
                elif hasattr(v, "__len__") and not isinstance(v, str):
                    v = list(v)
                out[name.split(":", 2)[2]] = v
        return out

    def layer_data(self) -> dict:
        """The root layer's usdface provenance (customLayerData), decoded."""
        data = dict(self._stage.GetRootLayer().customLayerData.get("usdface", {}))
        out = {}
        for k, v in data.items():
            try:
                out[k] = json.loads(v) if isinstance(v, str) and v[:1] in "[{" else v
            except ValueError:
                out[k] = v
        return out


def remove_head_motion(points: np.ndarray, head: np.ndarray) -> np.ndarray:
    """points (F, K, 3) @ inverse(head (F, 4, 4)), row-vector convention."""
    inv = np.linalg.inv(head)
    return np.einsum("fkj,fjl->fkl", points, inv[:, :3, :3]) + inv[:, None, 3, :3]


def _find_face_mesh(stage: Usd.Stage) -> Usd.Prim | None:
    """The face mesh (:func:`usdface.usd.mesh_layer.find_mesh`), or None when the stage has none."""
    try:
        return find_mesh(stage, what="shot")
    except InputError:
        return None


def shot_name(path) -> str:
    """``take`` for ``.../take/shot.usda`` (the run's folder names the shot), else the file's stem."""
    p = Path(path)
    if p.stem.startswith("shot") and p.parent.name:
        return p.parent.name + ("" if p.stem == "shot" else p.stem[4:])
    return p.stem
