"""The animated face mesh of any stage, evaluated at any time code, as USD composes it.

One evaluator for every deliverable: a point cache (time-sampled ``points``), a UsdSkel
skeleton (linear or dual-quaternion blend skinning), UsdSkel blend shapes (applied before
skinning, as UsdSkel specifies), and time-sampled transforms on the mesh's ancestors (the head
motion on ``/Face``). It works on a layer opened alone (``anim.usdc``, ``skel.usdc``, a
blend-shape or simulate output) and on a composed shot (``shot.usda``, ``shot_skel.usda``).

Build once, query many times (a playblast evaluates every frame)::

    ev = FaceEvaluator.open("shot_skel.usda")        # or FaceEvaluator(stage)
    ev.time_codes, ev.rate                           # every time code that moves the face
    p = ev.points(441)                               # (N, 3) float64, world space
    P = ev.points_range(ev.time_codes, space="mesh") # (F, N, 3)

Spaces (the stage's units):

- ``"world"``: what a viewer shows, every ancestor transform applied;
- ``"mesh"``: the mesh prim's own space, the space its ``points`` attribute is authored in
  (usdface's stabilised mesh space; the head motion on ``/Face`` is not in it). A skinned mesh is
  taken there from skeleton space the way ``UsdSkel.BakeSkinning`` bakes it:
  ``skinned * skelLocalToWorld * inverse(meshLocalToWorld)``.

The deformation follows UsdSkel exactly, through UsdSkel itself (``UsdSkel.Cache``,
``SkeletonQuery.ComputeSkinningTransforms``, ``BlendShapeQuery``, ``UsdSkel.SkinPoints``): a
mesh is skinned only under a ``SkelRoot`` with a bound Skeleton that has a bind pose, blend
shapes apply only when the Skeleton's animation has ``blendShapes`` weights, joint and blend-shape
orders are remapped from the animation to the mesh, rigid (constant-interpolation) influences move
the whole mesh (:mod:`usdface.usd.skel_deform`). Matrices returned here are numpy column-vector
4 x 4 (``M @ [x, y, z, 1]``), except :meth:`FaceEvaluator.head_motion` (row-vector, as the head
motion is authored).

It is also the one reader of what else a shot shows about the face: its triangles, regions,
hybrid weight, binding and bound points, the capture markers, the head motion on the face's root
prim and the transfer's settings. A playblast or report reads a shot through
:class:`usdface.usd.playback.ShotReader` and a preview a frame through
:func:`usdface.usd.scene.read_scene_frame`, both built on it.
"""
from __future__ import annotations

import json
import os
from functools import cached_property

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from ..errors import InputError, OptionError
from ..model.mesh import FaceMesh
from .capture_layer import find_marker_set
from .layers import open_stage, stage_units
from .mesh_layer import BINDING_API, find_mesh, read_binding, read_regions
from .skel_deform import SkelDeformation

__all__ = ["FaceEvaluator", "SPACES", "evaluate_points", "remove_head_motion"]

SPACES = ("world", "mesh")
_CHUNK_FRAMES = 64  # frames per chunk of iter_points (64 x 20k points x 3 doubles = 31 MB)
_IDENTITY = np.eye(4)


def _transform_into(p: np.ndarray, m: np.ndarray, out: np.ndarray) -> None:
    """out = p (N, 3) moved by the row-vector 4 x 4 ``m``, computed in float64."""
    if np.array_equal(m, _IDENTITY):
        out[...] = p
        return
    # a 2-D product: numpy's stacked matmul of (N, 3) x (3, 3) is much slower
    moved = np.dot(np.asarray(p, dtype=np.float64), np.ascontiguousarray(m[:3, :3]),
                   out=out if out.dtype == np.float64 and out.flags.c_contiguous else None)
    moved += m[3, :3]
    if moved is not out:
        out[...] = moved


def _check_space(space: str) -> str:
    if space not in SPACES:
        raise OptionError(f"space {space!r}: expected one of {', '.join(SPACES)}")
    return space


def _row(m) -> np.ndarray:
    """A Gf matrix (row-vector convention) as a float64 numpy array."""
    return np.array(m, dtype=np.float64)


def _xform_samples(prim: Usd.Prim) -> set[float]:
    """Time samples of the transforms of ``prim`` and every ancestor."""
    times: set[float] = set()
    while prim and not prim.IsPseudoRoot():
        if prim.IsA(UsdGeom.Xformable):
            times.update(UsdGeom.Xformable(prim).GetTimeSamples())
        prim = prim.GetParent()
    return times


def _find_face_prim(stage: Usd.Stage, source: str) -> Usd.Prim:
    """The face mesh (:func:`find_mesh`), or in an over-only layer opened alone (a point cache
    without usdface schemas) the first prim, default prim's subtree first, with authored points."""
    try:
        return find_mesh(stage, what="file")
    except InputError:
        pass
    root = stage.GetDefaultPrim()
    ranges = ([Usd.PrimRange(root, Usd.PrimAllPrimsPredicate)] if root else []) + [
        Usd.PrimRange.Stage(stage, Usd.PrimAllPrimsPredicate)]
    for prims in ranges:
        for prim in prims:
            attr = prim.GetAttribute(UsdGeom.Tokens.points)
            if attr and attr.HasAuthoredValue():
                return prim
    raise InputError(f"{source}: no face mesh (no Mesh prim, and no prim with points)")


class FaceEvaluator:
    """The face mesh of a stage, deformed and placed as USD composes it at any time code.

    Parameters
    ----------
    stage : Usd.Stage
        An open stage (a shot, or any deliverable layer opened alone).
    mesh : str or Sdf.Path, optional
        The mesh prim; by default the face mesh (:func:`usdface.usd.mesh_layer.find_mesh`: the
        prim with usdface schemas, else the default prim's first Mesh; in an over-only layer
        without schemas, the first prim with authored points).
    source : str, optional
        Name used in error messages (default: the root layer's identifier).

    Attributes
    ----------
    stage, prim : the stage and the mesh prim
    mesh_path : str, the mesh prim's path
    n_points : int
    face_vertex_counts, face_vertex_indices : ndarray (int64) or None (an over-only layer
        carries no topology)
    units : str or None, the stage's linear unit (``"cm"``...)
    rate : float, ``timeCodesPerSecond``; fps : float, ``framesPerSecond``
    time_codes : ndarray (T,) float64, sorted: every authored time code that can change the
        result (points, joint animation, blend-shape weights, influences, the mesh's and the
        skeleton's ancestors' transforms); empty for a still mesh
    frame_range : (start, end) or None, the stage's authored range, else the first and last
        of ``time_codes``
    deformation : tuple of str, what moves the points, in order of application: ``"points"``
        (time-sampled points), ``"blendShapes"``, ``"skinning"`` (per-point linear or
        dual-quaternion blend skinning) or ``"rigidSkinning"``; ``()`` for a still mesh
    skinning_method : str or None (``"classicLinear"``, ``"dualQuaternion"``)
    joints : list of str, the skeleton's joint order ([] without skinning)
    blend_shapes : list of str, the mesh's ``skel:blendShapes`` order ([] without blend shapes)
    animated : bool, whether more than one time code moves the face (in world space)
    triangles : ndarray (T, 3) int64, the polygons' fan triangulation (read on first use, as
        the following)
    regions : list of Region; hybrid_weight : ndarray (N,) or None
    binding : Binding or None, the markers bound to the surface (:meth:`bound_points`)
    marker_names : list of str, the capture's markers (:meth:`markers`; [] without a capture)
    """

    def __init__(self, stage: Usd.Stage, *, mesh: str | Sdf.Path | None = None, source: str | None = None):
        self.stage = stage
        self.source = source or stage.GetRootLayer().identifier
        if mesh is None:
            prim = _find_face_prim(stage, self.source)
        else:
            prim = stage.GetPrimAtPath(Sdf.Path(str(mesh)))
            if not prim:
                raise InputError(f"{self.source}: no prim at {mesh}")
        self.prim = prim
        self.mesh_path = str(prim.GetPath())
        self.geom = UsdGeom.Mesh(prim)
        self._points_query = Usd.AttributeQuery(self.geom.GetPointsAttr())
        rest = self.geom.GetPointsAttr().Get(Usd.TimeCode.Default())
        samples = self._points_query.GetTimeSamples()
        if rest is None and not samples:
            raise InputError(f"{self.source}: the mesh {self.mesh_path} has no points")
        self._rest_vt = Vt.Vec3fArray(rest) if rest is not None else None
        first = rest if rest is not None else self.geom.GetPointsAttr().Get(samples[0])
        self.n_points = len(first)
        counts = self.geom.GetFaceVertexCountsAttr().Get()
        indices = self.geom.GetFaceVertexIndicesAttr().Get()
        self.face_vertex_counts = np.asarray(counts, dtype=np.int64) if counts else None
        self.face_vertex_indices = np.asarray(indices, dtype=np.int64) if counts and indices else None
        self.units = stage_units(stage)
        self.rate = float(stage.GetTimeCodesPerSecond())
        self.fps = float(stage.GetFramesPerSecond())
        self._points_vary = len(samples) > 0
        self._xf_cache = UsdGeom.XformCache()
        self._skel = SkelDeformation(prim, n_points=self.n_points, source=self.source)
        self.skinning_method = self._skel.skinning_method
        self.joints = self._skel.joints
        self.blend_shapes = self._skel.blend_shapes
        self._setup_times(samples)

    # -- set-up ----------------------------------------------------------------------------------

    @classmethod
    def open(cls, path: str | os.PathLike, *, mesh: str | None = None, what: str = "file") -> "FaceEvaluator":
        """Open ``path`` (any USD file) and build its evaluator."""
        return cls(open_stage(path, what=what), mesh=mesh, source=str(path))

    def _setup_times(self, point_samples) -> None:
        times = set(point_samples)
        times |= _xform_samples(self.prim)
        if self._skel.skinned:
            times |= _xform_samples(self._skel.skel_prim)
        times |= self._skel.time_samples()
        self.time_codes = np.array(sorted(times), dtype=np.float64)
        if self.stage.HasAuthoredTimeCodeRange():
            self.frame_range = (float(self.stage.GetStartTimeCode()), float(self.stage.GetEndTimeCode()))
        elif self.time_codes.size:
            self.frame_range = (float(self.time_codes[0]), float(self.time_codes[-1]))
        else:
            self.frame_range = None
        self.deformation = (("points",) if self._points_vary else ()) + self._skel.steps
        self.animated = self.time_codes.size > 1

    @property
    def has_topology(self) -> bool:
        return self.face_vertex_counts is not None and self.face_vertex_indices is not None

    @property
    def skinned(self) -> bool:
        return self._skel.skinned

    @property
    def start(self) -> float:
        """The time code a query without a time uses: the first of ``frame_range`` (0 for a
        still stage without one)."""
        return self.frame_range[0] if self.frame_range else 0.0

    def default_times(self) -> np.ndarray:
        """(F,) float64: ``time_codes``, or ``[start]`` for a still mesh."""
        return self.time_codes.copy() if self.time_codes.size else np.array([self.start])

    def _timecode(self, time) -> Usd.TimeCode:
        if isinstance(time, Usd.TimeCode):
            return time
        return Usd.TimeCode(self.start if time is None else float(time))

    # -- transforms ------------------------------------------------------------------------------

    def _world_gf(self, prim: Usd.Prim, tc: Usd.TimeCode) -> Gf.Matrix4d:
        self._xf_cache.SetTime(tc)
        return self._xf_cache.GetLocalToWorldTransform(prim)

    def local_to_world(self, time=None) -> np.ndarray:
        """(4, 4) column-vector transform of the mesh prim's space to world space at ``time``."""
        return _row(self._world_gf(self.prim, self._timecode(time))).T

    def _to_space(self, tc: Usd.TimeCode, space: str, rigid: Gf.Matrix4d | None = None,
                  undeformed: bool = False) -> np.ndarray:
        """Row-vector (4, 4) taking deformed points (skeleton space when skinned, else mesh
        space) to ``space``; Gf does the 4 x 4 algebra (numpy's LAPACK inverse of one 4 x 4
        costs a millisecond on a busy machine)."""
        if self.skinned:
            m = self._world_gf(self._skel.skel_prim, tc)
            if rigid is not None:
                m = rigid * m
            if undeformed:
                m = self._skel.geom_bind_transform(tc) * m
        elif space == "mesh":
            return _IDENTITY  # points are authored in mesh space: exactly, not W * W^-1
        else:
            m = self._world_gf(self.prim, tc)
        if space == "mesh":
            m = m * self._world_gf(self.prim, tc).GetInverse()
        return _row(m)

    # -- deformation -----------------------------------------------------------------------------

    def _base_points(self, tc: Usd.TimeCode) -> Vt.Vec3fArray:
        if self._points_vary or self._rest_vt is None:
            pts = self._points_query.Get(tc)
            if pts is None:
                raise InputError(f"{self.source}: {self.mesh_path} has no points at time {tc.GetValue():g}")
            return Vt.Vec3fArray(pts)
        return Vt.Vec3fArray(self._rest_vt)  # a copy: UsdSkel deforms in place

    def blend_shape_weights(self, time=None) -> np.ndarray:
        """(B,) float32 blend-shape weights at ``time`` in the mesh's ``blend_shapes`` order."""
        return self._skel.blend_shape_weights(self._timecode(time))

    def skinning_transforms(self, time=None) -> np.ndarray:
        """(J, 4, 4) column-vector skinning transforms (inverse bind times joint, skeleton space)
        in the mesh's joint order at ``time``."""
        if not self.skinned:
            return np.zeros((0, 4, 4))
        xforms = self._skel.skinning_transforms(self._timecode(time))
        return np.transpose(np.asarray(xforms, dtype=np.float64), (0, 2, 1))

    def _deformed(self, tc: Usd.TimeCode) -> tuple[Vt.Vec3fArray, Gf.Matrix4d | None]:
        """Deformed points (skeleton space when skinned, else mesh space) and, for rigid
        skinning, the row-vector transform UsdSkel gives the whole mesh."""
        pts = self._base_points(tc)
        return pts, self._skel.deform(pts, tc)

    # -- queries ---------------------------------------------------------------------------------

    def points(self, time=None, *, space: str = "world") -> np.ndarray:
        """(N, 3) float64 points at ``time`` (a time code; default :attr:`start`) in ``space``
        ("world" or "mesh")."""
        out = np.empty((1, self.n_points, 3), dtype=np.float64)
        self._fill([time], _check_space(space), out)
        return out[0]

    def points_range(self, times=None, *, space: str = "world", out: np.ndarray | None = None,
                     progress=None) -> np.ndarray:
        """(F, N, 3) points at each of ``times`` (default: :meth:`default_times`) in ``space``.

        ``out``: an (F, N, 3) float64 or float32 array to fill (default: a new float64 array).
        Touching fresh memory is a large part of the cost on some machines (1590 frames of 20k
        points are 763 MB); a playblast should prefer :meth:`iter_points`. ``progress``: an
        object with ``update(n)`` (a usdface progress bar).
        """
        _check_space(space)
        times = self.resolve_times(times)
        if out is None:
            out = np.empty((len(times), self.n_points, 3), dtype=np.float64)
        elif out.shape != (len(times), self.n_points, 3):
            raise OptionError(f"out: expected shape {(len(times), self.n_points, 3)}, got {out.shape}")
        for a in range(0, len(times), _CHUNK_FRAMES):
            chunk = times[a:a + _CHUNK_FRAMES]
            self._fill(chunk, space, out[a:a + len(chunk)])
            if progress is not None:
                progress.update(len(chunk))
        return out

    def iter_points(self, times=None, *, space: str = "world", chunk: int = _CHUNK_FRAMES,
                    dtype=np.float64):
        """Yield ``(times, points)`` for consecutive chunks of ``times``: ``times`` (f,) float64,
        ``points`` (f, N, 3) in one buffer reused from chunk to chunk (copy what you keep). The
        way to walk a whole take without holding it in memory (a playblast)."""
        _check_space(space)
        if chunk < 1:
            raise OptionError(f"chunk {chunk}: expected at least 1 frame")
        times = self.resolve_times(times)
        buf = np.empty((min(chunk, max(len(times), 1)), self.n_points, 3), dtype=dtype)
        for a in range(0, len(times), chunk):
            part = times[a:a + chunk]
            view = buf[:len(part)]
            self._fill(part, space, view)
            yield part.copy(), view

    def resolve_times(self, times=None) -> np.ndarray:
        """(F,) float64 time codes: ``times`` as an array, or :meth:`default_times` for None."""
        if times is None:
            return self.default_times()
        times = np.atleast_1d(np.asarray(times, dtype=np.float64))
        if times.ndim != 1:
            raise OptionError(f"times: expected a sequence of time codes, got an array of shape {times.shape}")
        return times

    def _fill(self, times, space: str, out: np.ndarray) -> None:
        """Evaluate ``times`` (at most a chunk) into ``out`` (len(times), N, 3)."""
        for i, t in enumerate(times):
            tc = self._timecode(t)
            pts, rigid = self._deformed(tc)
            p = np.asarray(pts)
            if len(p) != self.n_points:
                raise InputError(f"{self.source}: {self.mesh_path} has {len(p)} points at time {tc.GetValue():g}, "
                                 f"{self.n_points} elsewhere")
            _transform_into(p, self._to_space(tc, space, rigid), out[i])

    def rest_points(self, *, space: str = "mesh", time=None) -> np.ndarray:
        """(N, 3) float64 undeformed points: the authored ``points`` default value (a skinned
        mesh's bind pose, a blend-shape mesh's neutral), placed as UsdSkel places an undeformed
        mesh (through ``geomBindTransform`` and the skeleton when skinned). ``space="world"``
        uses the transforms at ``time`` (default: :attr:`start`)."""
        _check_space(space)
        if self._rest_vt is None:
            raise InputError(f"{self.source}: {self.mesh_path} has no rest points (no default value of points; "
                             "open the shot or the layer that holds the mesh)")
        m = self._to_space(self._timecode(time), space, undeformed=True)
        return np.asarray(self._rest_vt, dtype=np.float64) @ m[:3, :3] + m[3, :3]

    # -- what else the stage shows about the face ------------------------------------------------

    @cached_property
    def triangles(self) -> np.ndarray:
        """(T, 3) int64 fan triangulation of the mesh's polygons (:meth:`FaceMesh.triangles`)."""
        if not self.has_topology:
            raise InputError(f"{self.source}: {self.mesh_path} has no topology here (an over-only layer)")
        return FaceMesh(points=np.zeros((self.n_points, 3)), face_vertex_counts=self.face_vertex_counts,
                        face_vertex_indices=self.face_vertex_indices).triangles()

    @cached_property
    def regions(self) -> list:
        """Every FaceRegionAPI instance on the mesh (list of :class:`usdface.mesh.Region`)."""
        return read_regions(self.prim)

    @cached_property
    def hybrid_weight(self) -> np.ndarray | None:
        """(N,) float64 ``primvars:usdface:hybridWeight`` (the hybrid distance's weight), or None."""
        w = UsdGeom.PrimvarsAPI(self.prim).GetPrimvar("usdface:hybridWeight")
        return np.asarray(w.Get(), dtype=np.float64) if w and w.HasValue() else None

    @cached_property
    def binding(self):
        """The markers' binding to the surface (:class:`usdface.mesh.Binding`), or None."""
        return read_binding(self.stage, source=self.source) if self.prim.HasAPI(BINDING_API) else None

    def bound_points(self, points: np.ndarray) -> np.ndarray | None:
        """(..., M, 3) bound surface points of the binding on face points (..., N, 3), in their
        space (None without a binding)."""
        b = self.binding
        if b is None:
            return None
        tv, bc = np.asarray(b.triangle_vertices), np.asarray(b.barycentrics)
        return np.einsum("...mkd,mk->...md", np.asarray(points)[..., tv, :], bc)

    @cached_property
    def _marker_prim(self) -> Usd.Prim | None:
        try:
            return find_marker_set(self.stage)
        except InputError:
            return None

    @cached_property
    def marker_names(self) -> list:
        """Names of the capture markers the stage holds ([] without a capture)."""
        prim = self._marker_prim
        return [] if prim is None else list(prim.GetAttribute("usdface:markerSet:names").Get() or [])

    def markers(self, times, *, stabilized: bool = False) -> np.ndarray | None:
        """(F, M, 3) world positions of the capture markers at ``times``, NaN where invalid (None
        without a capture); ``stabilized``: without the head motion (:meth:`head_motion`)."""
        prim = self._marker_prim
        if prim is None:
            return None
        if stabilized:
            return remove_head_motion(self.markers(times), self.head_motion(times))
        attr = UsdGeom.Points(prim).GetPointsAttr()
        valid = prim.GetAttribute("primvars:usdface:valid")
        cache = UsdGeom.XformCache()
        out = np.empty((len(times), len(self.marker_names), 3))
        for i, t in enumerate(times):
            tc = Usd.TimeCode(float(t))
            cache.SetTime(tc)
            m = _row(cache.GetLocalToWorldTransform(prim))
            p = np.asarray(attr.Get(tc), dtype=np.float64)
            p = p @ m[:3, :3] + m[3, :3]
            if valid and valid.HasValue():
                p[~np.asarray(valid.Get(tc), dtype=bool)] = np.nan
            out[i] = p
        return out

    def head_motion(self, times) -> np.ndarray:
        """(F, 4, 4) row-vector transforms of the face's root prim (the default prim above the
        mesh: its time-sampled ``xformOp:transform`` is the head motion, identity at the neutral
        frame), identity when it has none. World = stabilised @ H(t)."""
        out = np.repeat(np.eye(4)[None], len(times), axis=0)
        root = self.stage.GetDefaultPrim()
        if not root or not self.prim.GetPath().HasPrefix(root.GetPath()) or not root.IsA(UsdGeom.Xformable):
            return out
        xf = UsdGeom.Xformable(root)
        if not xf.TransformMightBeTimeVarying():
            m = np.asarray(xf.GetLocalTransformation(Usd.TimeCode.Default()), dtype=np.float64)
            return np.repeat(m[None], len(times), axis=0)
        for i, t in enumerate(times):
            out[i] = np.asarray(xf.GetLocalTransformation(Usd.TimeCode(float(t))), dtype=np.float64)
        return out

    def transfer_settings(self) -> dict:
        """Every ``usdface:transfer:*`` value on the face mesh (FaceTransferAPI), JSON strings decoded."""
        out = {}
        for attr in self.prim.GetAttributes():
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
        data = dict(self.stage.GetRootLayer().customLayerData.get("usdface", {}))
        out = {}
        for k, v in data.items():
            try:
                out[k] = json.loads(v) if isinstance(v, str) and v[:1] in "[{" else v
            except ValueError:
                out[k] = v
        return out

    def describe(self) -> dict:
        """A JSON-ready summary (for reports and error messages)."""
        return {"mesh": self.mesh_path, "points": self.n_points, "deformation": list(self.deformation),
                "skinningMethod": self.skinning_method, "joints": len(self.joints),
                "blendShapes": len(self.blend_shapes), "timeCodes": int(self.time_codes.size),
                "frameRange": list(self.frame_range) if self.frame_range else None, "rate": self.rate,
                "fps": self.fps, "units": self.units, "animated": self.animated}


def evaluate_points(path_or_stage, times=None, *, space: str = "world", mesh: str | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """One call: ``(times, points)`` of the face mesh of a file or stage.

    Returns
    -------
    times : ndarray (F,) float64, the time codes evaluated (default:
        :meth:`FaceEvaluator.default_times`, every time code that moves the face)
    points : ndarray (F, N, 3) float64 in ``space``
    """
    if isinstance(path_or_stage, Usd.Stage):
        ev = FaceEvaluator(path_or_stage, mesh=mesh)
    else:
        ev = FaceEvaluator.open(path_or_stage, mesh=mesh)
    times = ev.resolve_times(times)
    return times, ev.points_range(times, space=space)


def remove_head_motion(points: np.ndarray, head: np.ndarray) -> np.ndarray:
    """points (F, K, 3) @ inverse(head (F, 4, 4)), row-vector convention: world points taken back
    into the stabilised space (:meth:`FaceEvaluator.head_motion`)."""
    inv = np.linalg.inv(head)
    return np.einsum("fkj,fjl->fkl", points, inv[:, :3, :3]) + inv[:, None, 3, :3]
