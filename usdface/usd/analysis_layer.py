"""Analysis layers (distance matrices) and animation layers (time-sampled points), and shot stages.

Both layers are ``over``s on the mesh prim; a shot stage composes them over the binding layer
(which itself sublayers the mesh and references the capture).
"""
from __future__ import annotations

import json

import numpy as np
from pxr import Sdf, Usd, UsdGeom, Vt

from ..distance.matrices import DistanceMatrix
from ..errors import InputError
from ..model.timing import FrameRange
from .layers import (add_sublayer, checkpoint, describe, open_stage, output_layer, relative_asset_path,
                     set_provenance, set_stage_metadata)
from .mesh_layer import find_mesh
from .schemas import require_registered

DISTANCE_API = "FaceDistanceMatrixAPI"
TRANSFER_API = "FaceTransferAPI"
HYBRID_WEIGHT_PRIMVAR = "usdface:hybridWeight"


def write_analysis_layer(path, matrices: list[DistanceMatrix], *, mesh_path, units, prov: dict) -> str:
    """Write distance matrices as FaceDistanceMatrixAPI instances in an over on the mesh prim."""
    require_registered()
    mesh_stage = open_stage(mesh_path, what="mesh")
    mesh_prim_path = find_mesh(mesh_stage).GetPath()
    with output_layer(path) as stage:
        set_stage_metadata(stage, units=units, default_prim=mesh_stage.GetDefaultPrim().GetName())
        prim = stage.OverridePrim(mesh_prim_path)
        for m in matrices:
            inst = m.method
            prim.ApplyAPI(DISTANCE_API, inst)
            ns = f"usdface:distanceMatrix:{inst}"
            prim.GetAttribute(f"{ns}:markerNames").Set(Vt.StringArray(list(m.marker_names)))
            prim.GetAttribute(f"{ns}:constraintVertices").Set(Vt.IntArray.FromNumpy(
                np.asarray(m.constraint_vertices, dtype=np.int32)))
            prim.GetAttribute(f"{ns}:method").Set(m.method)
            prim.GetAttribute(f"{ns}:backend").Set(m.backend)
            prim.GetAttribute(f"{ns}:centreDistances").Set(Vt.FloatArray.FromNumpy(
                np.ascontiguousarray(m.centre_to_centre, dtype=np.float32).ravel()))
            prim.GetAttribute(f"{ns}:parameters").Set(json.dumps(m.parameters, sort_keys=True, default=float))
            # a plain attribute, not a primvar: DCC importers turn vertex primvars into per-point
            # geometry attributes (an elementSize-C primvar became all-zero junk in Blender)
            prim.GetAttribute(f"{ns}:vertexDistances").Set(Vt.FloatArray.FromNumpy(
                np.ascontiguousarray(m.vertex_to_centre, dtype=np.float32).ravel()))
            if m.hybrid_weight is not None:
                w = UsdGeom.PrimvarsAPI(prim).CreatePrimvar(HYBRID_WEIGHT_PRIMVAR, Sdf.ValueTypeNames.FloatArray,
                                                            UsdGeom.Tokens.vertex)
                w.Set(Vt.FloatArray.FromNumpy(np.asarray(m.hybrid_weight, dtype=np.float32)))
        set_provenance(stage, prov)
    return str(path)


def read_distance_matrix(path, *, method: str | None = None, stage: Usd.Stage | None = None) -> DistanceMatrix:
    """Read one distance matrix (``method`` or the only/first one) from an analysis layer."""
    stage = stage or open_stage(path, what="analysis")
    prim = find_mesh(stage, what="analysis")
    instances = [s.split(":", 1)[1] for s in prim.GetAppliedSchemas() if s.startswith(DISTANCE_API + ":")]
    if not instances:
        raise InputError(f"analysis {path}: {prim.GetPath()} has no {DISTANCE_API} (write one with `usdface distances`)")
    inst = method or instances[0]
    if inst not in instances:
        raise InputError(f"analysis {path}: no {inst!r} distance matrix; it has {', '.join(instances)}")
    ns = f"usdface:distanceMatrix:{inst}"
    names = tuple(prim.GetAttribute(f"{ns}:markerNames").Get() or [])
    cons = np.asarray(prim.GetAttribute(f"{ns}:constraintVertices").Get() or [], dtype=np.int64)
    c = len(names) + cons.size
    vtc = vertex_distances(prim, inst)
    if vtc is None:
        raise InputError(f"analysis {path}: distance matrix {inst!r} on {prim.GetPath()} has no vertex distances")
    vtc = vtc.reshape(-1, c)
    ctc = np.asarray(prim.GetAttribute(f"{ns}:centreDistances").Get(), dtype=np.float64).reshape(c, c)
    w = UsdGeom.PrimvarsAPI(prim).GetPrimvar(HYBRID_WEIGHT_PRIMVAR)
    return DistanceMatrix(method=prim.GetAttribute(f"{ns}:method").Get(), backend=prim.GetAttribute(f"{ns}:backend").Get(),
                          marker_names=names, constraint_vertices=cons, vertex_to_centre=vtc, centre_to_centre=ctc,
                          parameters=json.loads(prim.GetAttribute(f"{ns}:parameters").Get() or "{}"),
                          hybrid_weight=np.asarray(w.Get(), dtype=np.float32) if w and w.HasValue() else None)


def vertex_distances(prim: Usd.Prim, instance: str) -> np.ndarray | None:
    """The flat N x C vertex-to-centre distances of one FaceDistanceMatrixAPI instance (float32),
    from ``vertexDistances`` or, in layers of usdface 0.1, the vertex primvar
    ``primvars:usdface:distance:<instance>``; None when neither holds a value."""
    attr = prim.GetAttribute(f"usdface:distanceMatrix:{instance}:vertexDistances")
    if attr and attr.HasAuthoredValue():
        return np.asarray(attr.Get(), dtype=np.float32)
    legacy = UsdGeom.PrimvarsAPI(prim).GetPrimvar(f"usdface:distance:{instance}")
    if legacy and legacy.HasValue():
        return np.asarray(legacy.Get(), dtype=np.float32)
    return None


def prefetch(iterable):
    """Iterate ``iterable`` one item ahead in a worker thread.

    The transfer's chunks are numpy matrix products (which release the GIL): computing the next
    chunk while USD writes the current one overlaps the two instead of adding them. An item must
    stay valid while the next one is computed: fresh arrays, or a ring of at least 3 buffers
    (RBFTransfer.iter_chunks ``buffers=3``; not ``reuse_buffer=True``). An exception in the
    producer is raised here, in the consumer.
    """
    from concurrent.futures import ThreadPoolExecutor

    it = iter(iterable)
    done = object()
    with ThreadPoolExecutor(max_workers=1) as pool:
        pending = pool.submit(next, it, done)
        while True:
            item = pending.result()
            if item is done:
                return
            pending = pool.submit(next, it, done)
            yield item


def frame_extents(points: np.ndarray) -> np.ndarray:
    """(F, 2, 3) per-frame bounding boxes of (F, N, 3) points.

    Reduces over a contiguous last axis: numpy's min over the middle axis of (F, N, 3) runs ~7x
    slower (an inner loop of length 3), which made the extent cost more than the .usdc write.
    """
    xyz = np.ascontiguousarray(points.transpose(0, 2, 1))  # (F, 3, N)
    return np.stack([xyz.min(axis=2), xyz.max(axis=2)], axis=1)


def write_animation_layer(path, chunks, *, mesh_path, frames: FrameRange, units, transfer: dict, prov: dict,
                          rest_points: np.ndarray | None = None, progress=None,
                          head_motion: np.ndarray | None = None) -> str:
    """Stream time-sampled points into an animation layer (.usdc), saving after every chunk.

    The layer sublayers the mesh layer it animates (relative path), so it imports alone as the
    animated face; a shot stage that also sublayers the mesh composes it once more, harmlessly.

    Parameters
    ----------
    frames : FrameRange
        The layer's time codes (start, rate, number of frames).
    chunks : iterable of (slice, ndarray (f, N, 3) float32) or (slice, points, extents (f, 2, 3))
        Frames ``slice`` (0-based) and their vertex displacements from ``rest_points``, or, when
        ``rest_points`` is None, their vertex positions (mesh units). A third item gives each
        frame's bounding box (computed here otherwise).
    rest_points : ndarray (N, 3), optional
        The mesh's rest positions; authored points = rest + displacement. None: the chunks hold
        the positions (:meth:`usdface.rbf.RBFTransfer.iter_chunks` with ``offset`` adds the rest
        inside its matrix product, and gives the extents too: the writer then only writes).
    transfer : dict
        FaceTransferAPI values: mode, kernel, distanceMethod, markerNames, widths, regularization,
        polynomial, conditionNumber, parameters (dict).
    head_motion : ndarray (F, 4, 4), optional
        Head motion for the face's root prim (:mod:`usdface.usd.motion`); the points stay
        head-stabilised.
    """
    require_registered()
    start, rate, n_frames = frames.start, frames.rate, frames.frames
    mesh_stage = open_stage(mesh_path, what="mesh")
    mesh_prim_path = find_mesh(mesh_stage).GetPath()
    rest = None if rest_points is None else np.asarray(rest_points, dtype=np.float32)
    root_name = mesh_stage.GetDefaultPrim().GetName()
    with output_layer(path) as stage:
        add_sublayer(stage, mesh_path, path)
        set_stage_metadata(stage, units=units, default_prim=root_name, rate=rate, start=start,
                           end=start + n_frames - 1)
        if head_motion is not None:
            from .motion import author_head_motion

            if len(head_motion) != n_frames:
                raise InputError(f"animation {path}: head motion has {len(head_motion)} frames, expected {n_frames}")
            author_head_motion(stage, Sdf.Path("/" + root_name), head_motion, start=start)
        prim = stage.OverridePrim(mesh_prim_path)
        mesh = UsdGeom.Mesh(prim)
        prim.ApplyAPI(TRANSFER_API)
        ns = "usdface:transfer"
        for key in ("mode", "kernel", "distanceMethod"):
            prim.GetAttribute(f"{ns}:{key}").Set(transfer[key])
        prim.GetAttribute(f"{ns}:markerNames").Set(Vt.StringArray(list(transfer["markerNames"])))
        prim.GetAttribute(f"{ns}:widths").Set(Vt.DoubleArray.FromNumpy(np.asarray(transfer["widths"], dtype=np.float64)))
        prim.GetAttribute(f"{ns}:regularization").Set(float(transfer.get("regularization", 0.0)))
        prim.GetAttribute(f"{ns}:polynomial").Set(bool(transfer.get("polynomial", False)))
        cond = transfer.get("conditionNumber")
        if cond is not None and np.isfinite(cond):
            prim.GetAttribute(f"{ns}:conditionNumber").Set(float(cond))
        prim.GetAttribute(f"{ns}:parameters").Set(json.dumps(transfer.get("parameters", {}), sort_keys=True, default=str))
        # normals would go stale under animated points: block them (renderers recompute)
        mesh.GetNormalsAttr().Block() if prim.HasAttribute("normals") else mesh.CreateNormalsAttr().Block()
        points_attr = mesh.CreatePointsAttr()
        extent_attr = mesh.CreateExtentAttr()
        written = 0
        for item in prefetch(chunks):
            frames, pts = item[0], item[1]
            if rest is not None:
                pts = pts + rest[None]
            extents = item[2] if len(item) > 2 and item[2] is not None else frame_extents(pts)
            # (no Sdf.ChangeBlock here: with large arrays it made the sets ~2x slower)
            for k, f in enumerate(range(frames.start, frames.stop)):
                t = Usd.TimeCode(start + f)
                points_attr.Set(Vt.Vec3fArray.FromNumpy(pts[k]), t)
                extent_attr.Set(Vt.Vec3fArray.FromNumpy(extents[k]), t)
            written += frames.stop - frames.start
            checkpoint(stage)  # appends in place: memory stays flat on long takes
            if progress is not None:
                progress.update(frames.stop - frames.start)
        if written != n_frames:
            raise InputError(f"animation {path}: {written} frames computed, expected {n_frames}")
        set_provenance(stage, prov)
    return str(path)


def write_shot_stage(path, *, layers: list, rate: float, start: float, end: float, units,
                     default_prim: str = "Face", stabilized_capture: bool = False, record: dict | None = None,
                     processor: str | None = None) -> str:
    """A small .usda composing the given layers (strongest first) with relative asset paths.

    With ``stabilized_capture`` the markers are shown head-stabilised (the capture's head-motion op
    is dropped from /Capture's op order), so they stay on the stabilised face animation.
    ``record`` (usdface.shot_commit.shot_record: the run id, every file's sha256 and provenance id)
    goes into ``customLayerData["usdface"]["shot"]`` as JSON, for ``usdface check``, beside the
    identity the layers agree on (:func:`usdface.usd.identity.agreeing_identity`: the layers given
    and the files they compose). Without a record, ``processor`` (the command writing the stage
    beside its layer: simulate, fit-muscles) records the version, itself and that identity; with
    neither, the stage carries no provenance.

    Raises MixedLayersError, before writing, when the layers were made for different meshes, bound
    points or takes.
    """
    from .identity import agreeing_identity

    agreed = agreeing_identity(layers, what=f"shot {describe(path)}")
    with output_layer(path) as stage:
        root = stage.GetRootLayer()
        if record is not None or processor is not None:
            from .. import __version__

            prov = {"usdfaceVersion": __version__, "processor": "run" if record is not None else processor,
                    "identity": agreed}
            if record is not None:
                prov["shot"] = json.dumps(record, sort_keys=True)
            set_provenance(stage, prov)
        for layer in layers:
            root.subLayerPaths.append(relative_asset_path(layer, path))
        set_stage_metadata(stage, units=units, default_prim=default_prim, rate=rate, start=start, end=end)
        if stabilized_capture:
            cap = stage.GetPrimAtPath("/Capture")
            if cap:
                order = [op for op in UsdGeom.Xformable(cap).GetOrderedXformOps()
                         if op.GetOpName() != "xformOp:transform"]
                over = stage.OverridePrim("/Capture")
                UsdGeom.Xformable(over).SetXformOpOrder(order)
    return str(path)
