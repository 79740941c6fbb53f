"""Capture layers: one Points prim of markers under an Xform carrying the head motion.

Layout (every processor agrees on it)::

    /Capture            Xform, default prim; xformOp:transform time-sampled = head motion removed
                        by stabilisation (identity when not stabilised)
    /Capture/Markers    Points + FaceMarkerSetAPI; points time-sampled, head-local, never NaN;
                        primvars:usdface:valid time-sampled per-marker validity

Time code = frame index at the capture rate; timeCodesPerSecond = framesPerSecond = rate;
metersPerUnit = the source units (no rescaling).
"""
from __future__ import annotations

import json
import os

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from ..model.capture import Capture, hold_invalid
from ..errors import InputError, MarkerError
from ..inputfiles import display_name, first_beyond_float32
from ..units import METERS_PER_UNIT
from .layers import describe, open_stage, output_layer, set_provenance, set_stage_metadata, stage_units
from .schemas import require_registered

CAPTURE_PRIM = "/Capture"
MARKERS_PRIM = "/Capture/Markers"
MARKER_SET_API = "FaceMarkerSetAPI"


def _matrix_to_usd(m: np.ndarray) -> Gf.Matrix4d:
    """Column-vector 4x4 (numpy) -> row-vector Gf.Matrix4d (USD)."""
    return Gf.Matrix4d(*np.asarray(m, dtype=np.float64).T.ravel().tolist())


def _matrix_from_usd(m: Gf.Matrix4d) -> np.ndarray:
    return np.array(m, dtype=np.float64).T


def write_capture_layer(path: str | os.PathLike, capture: Capture, *, prov: dict,
                        marker_width: float | None = None) -> str:
    """Write ``capture`` as a capture layer at ``path`` (atomically). Returns the path."""
    require_registered()
    if capture.units is None:
        raise MarkerError(f"capture {capture.source}: units unknown; pass --units")
    capture.check_not_all_invalid()
    valid = capture.valid
    beyond = first_beyond_float32(capture.positions)
    if beyond is not None:
        f, m, _ = beyond
        raise MarkerError(f"capture {capture.source}: marker {capture.names[m]!r} at frame {capture.start_frame + f} is "
                          f"{capture.positions[f, m].tolist()}, beyond the range of the float32 points USD stores")
    held = hold_invalid(capture.positions, valid).astype(np.float32)
    start = capture.start_frame
    with output_layer(path) as stage:
        set_stage_metadata(stage, units=capture.units, default_prim="Capture", rate=capture.rate,
                           start=start, end=start + capture.n_frames - 1)
        root = UsdGeom.Xform.Define(stage, CAPTURE_PRIM)
        points = UsdGeom.Points.Define(stage, MARKERS_PRIM)
        prim = points.GetPrim()
        prim.ApplyAPI(MARKER_SET_API)
        prim.GetAttribute("usdface:markerSet:names").Set(Vt.StringArray(list(capture.names)))
        prim.GetAttribute("usdface:markerSet:captureRate").Set(float(capture.rate))
        # only recorded, so a name that is not UTF-8 is kept with its odd bytes escaped (\xNN)
        prim.GetAttribute("usdface:markerSet:sourceFile").Set(display_name(os.path.basename(capture.source)))
        prim.GetAttribute("usdface:markerSet:sourceUnits").Set(capture.units)
        prim.GetAttribute("usdface:markerSet:neutralTime").Set(float(start + capture.neutral_frame))
        _write_rest_pose(prim, capture)
        dims = next((h.get("dims") for h in capture.history if "dims" in h), 3)
        prim.GetAttribute("usdface:markerSet:dimensions").Set(int(dims))
        valid_attr = prim.GetAttribute("primvars:usdface:valid")
        UsdGeom.Primvar(valid_attr).SetInterpolation(UsdGeom.Tokens.vertex)
        if marker_width is None:
            span = float(np.nanmax(np.ptp(held[capture.neutral_frame], axis=0)))
            marker_width = max(span / 60.0, 1e-6)
        points.CreateWidthsAttr(Vt.FloatArray([marker_width]))
        points.SetWidthsInterpolation(UsdGeom.Tokens.constant)
        points.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(Vt.Vec3fArray([Gf.Vec3f(1.0, 0.55, 0.1)]))
        points_attr = points.CreatePointsAttr()
        extent_attr = points.CreateExtentAttr()
        extents = np.stack([held.min(axis=1), held.max(axis=1)], axis=1)  # (F, 2, 3); M is small
        op = root.AddTransformOp()
        with Sdf.ChangeBlock():  # one change notification for all samples, not one per Set
            # bool arrays are held between samples: author validity only where it changes
            changes = np.flatnonzero(np.r_[True, (valid[1:] != valid[:-1]).any(axis=1)])
            for f in range(capture.n_frames):
                t = Usd.TimeCode(start + f)
                points_attr.Set(Vt.Vec3fArray.FromNumpy(held[f]), t)
                extent_attr.Set(Vt.Vec3fArray.FromNumpy(extents[f]), t)
            for f in changes:
                valid_attr.Set(Vt.BoolArray.FromNumpy(valid[f]), Usd.TimeCode(start + int(f)))
            if capture.head_motion is None:
                op.Set(Gf.Matrix4d(1.0))
            else:
                for f in range(capture.n_frames):
                    op.Set(_matrix_to_usd(capture.head_motion[f]), Usd.TimeCode(start + f))
        history = json.dumps(list(capture.history), sort_keys=True, default=str)
        set_provenance(stage, dict(prov, captureHistory=history))
    return str(path)


def find_marker_set(stage: Usd.Stage, *, what: str = "capture") -> Usd.Prim:
    """The Points prim with FaceMarkerSetAPI (default prim's first, else the stage's first)."""
    root = stage.GetDefaultPrim()
    candidates = [root] if root else []
    candidates.append(stage.GetPseudoRoot())
    for top in candidates:
        for prim in Usd.PrimRange(top):
            if prim.HasAPI(MARKER_SET_API):
                return prim
    raise InputError(
        f"{what} {stage.GetRootLayer().identifier}: no Points prim with {MARKER_SET_API} "
        f"(expected {MARKERS_PRIM}, written by `usdface import-capture`)"
    )


def read_capture_layer(path: str | os.PathLike, *, stage: Usd.Stage | None = None) -> Capture:
    """Read a capture layer back into a Capture (invalid samples become NaN)."""
    stage = stage or open_stage(path, what="capture")
    prim = find_marker_set(stage)
    names = list(prim.GetAttribute("usdface:markerSet:names").Get() or [])
    points_attr = UsdGeom.Points(prim).GetPointsAttr()
    times = points_attr.GetTimeSamples()
    if not times:
        value = points_attr.Get()
        if value is None:
            raise InputError(f"capture {describe(path)}: {prim.GetPath()} has no points")
        times = [Usd.TimeCode.Default()]
    valid_attr = prim.GetAttribute("primvars:usdface:valid")
    # the head motion is the capture's own xformOp:transform on /Capture, not the composed
    # transform: a binding or shot stage adds a captureToMesh placement in front of it
    head_op = _head_op(prim)
    pos, valid, head = [], [], []
    has_motion = head_op is not None and head_op.GetNumTimeSamples() > 0
    where = f"capture {describe(path)}: {prim.GetPath()}"
    for t in times:
        tc = Usd.TimeCode(t) if not isinstance(t, Usd.TimeCode) else t
        when = "" if tc.IsDefault() else f" at time {tc.GetValue():g}"
        p = np.asarray(points_attr.Get(tc), dtype=np.float64)
        if p.shape != (len(names), 3):
            raise InputError(f"{where} has {len(p)} points{when} for its {len(names)} marker names: every time "
                             f"sample holds one point per marker")
        pos.append(p)
        v = valid_attr.Get(tc) if valid_attr and valid_attr.HasValue() else None
        v = np.ones(len(names), bool) if v is None else np.asarray(v, dtype=bool)
        if v.shape != (len(names),):
            raise InputError(f"{where}: primvars:usdface:valid has {v.size} values{when} for its {len(names)} markers")
        valid.append(v)
        if has_motion:
            head.append(_matrix_from_usd(head_op.Get(tc)))
    positions = np.stack(pos)
    if not np.isfinite(positions).all():
        t, m = np.argwhere(~np.isfinite(positions).all(axis=2))[0]
        when = "" if isinstance(times[t], Usd.TimeCode) else f" at time {times[t]:g}"
        raise InputError(f"{where}: marker {names[m]!r} is NaN or infinite{when}; a capture layer holds finite points "
                         f"and marks gaps in primvars:usdface:valid")
    valid = np.stack(valid)
    positions[~valid] = np.nan
    head_motion = np.stack(head) if head else None
    rate = prim.GetAttribute("usdface:markerSet:captureRate").Get() or stage.GetTimeCodesPerSecond()
    start = int(round(times[0])) if not isinstance(times[0], Usd.TimeCode) else 0
    neutral_value = prim.GetAttribute("usdface:markerSet:neutralTime").Get()
    neutral_time = start if neutral_value is None else neutral_value
    neutral_frame = int(round(neutral_time)) - start
    window = _read_neutral_window(prim, start, neutral_frame, positions.shape[0], path)
    history = json.loads(stage.GetRootLayer().customLayerData.get("usdface", {}).get("captureHistory", "[]"))
    # units as the capture recorded them (a composing stage may have other metersPerUnit)
    source_units = prim.GetAttribute("usdface:markerSet:sourceUnits").Get()
    units = source_units if source_units in METERS_PER_UNIT else stage_units(stage)
    return Capture(names=names, positions=positions, rate=float(rate), units=units, start_frame=start,
                   neutral_frame=neutral_frame, source=describe(path),
                   head_motion=head_motion, history=tuple(history), neutral_window=window)


def _write_rest_pose(prim: Usd.Prim, capture: Capture) -> None:
    """The neutral stretch (time codes, inclusive), the rest pose and the motion over the stretch."""
    from ..capture.neutral import neutral_motion

    a, b = capture.neutral_frames
    start = capture.start_frame
    prim.GetAttribute("usdface:markerSet:neutralStartTime").Set(float(start + a))
    prim.GetAttribute("usdface:markerSet:neutralEndTime").Set(float(start + b - 1))
    rest = np.asarray(capture.neutral, dtype=np.float64)
    held = np.where(np.isfinite(rest), rest, 0.0)  # a marker without a rest position: 0, as the data says
    prim.GetAttribute("usdface:markerSet:restPoints").Set(Vt.Vec3fArray.FromNumpy(held.astype(np.float32)))
    rms, top = neutral_motion(capture)
    prim.GetAttribute("usdface:markerSet:neutralMotionRms").Set(float(rms))
    prim.GetAttribute("usdface:markerSet:neutralMotionMax").Set(float(top))


def _read_neutral_window(prim: Usd.Prim, start: int, neutral_frame: int, n_frames: int, path):
    """``(start, end)`` frame indices of the recorded neutral stretch, or None (usdface 0.2 layers
    record none: the neutral frame alone)."""
    first = prim.GetAttribute("usdface:markerSet:neutralStartTime")
    last = prim.GetAttribute("usdface:markerSet:neutralEndTime")
    if not (first and first.HasAuthoredValue() and last and last.HasAuthoredValue()):
        return None
    a, b = int(round(first.Get())) - start, int(round(last.Get())) - start + 1
    if not 0 <= a <= neutral_frame < b <= n_frames:
        raise InputError(f"capture {describe(path)}: neutral stretch {first.Get():g}-{last.Get():g} must hold the "
                         f"neutral time {start + neutral_frame} and lie within the layer's time codes "
                         f"{start}-{start + n_frames - 1}")
    return None if b - a == 1 else (a, b)


def _head_op(prim: Usd.Prim):
    """The capture's head-motion op: xformOp:transform on the marker set's Xform parent."""
    parent = prim.GetParent()
    if not parent or not parent.IsA(UsdGeom.Xformable):
        return None
    for op in UsdGeom.Xformable(parent).GetOrderedXformOps():
        if op.GetOpName() == "xformOp:transform":
            return op
    return None
