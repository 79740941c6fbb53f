"""2D track layers: marker positions tracked in a video, in pixels.

Same layout as a capture layer (:mod:`usdface.usd.capture_layer`), so every capture reader
reads it, with what image tracks need on top::

    /Capture            Xform, default prim (identity transform)
    /Capture/Markers    Points + FaceMarkerSetAPI; points time-sampled (x, y, 0) in pixels (OpenCV
                        convention: integer = pixel centre, y down), never NaN (an invalid sample
                        holds the last valid value); primvars:usdface:valid time-sampled;
                        primvars:usdface:confidence (float[], vertex, time-sampled, 0 where invalid);
                        usdface:markerSet:dimensions = 2, usdface:markerSet:sourceUnits = "px";
                        usdface:track:imageSize (int2: width, height), usdface:track:sourceVideo

The capture writer cannot be used as is: it needs a metric unit for ``metersPerUnit`` and pixels
are not one, so this writer leaves ``metersPerUnit`` unauthored (image space has no metric scale)
and records the unit as ``sourceUnits = "px"``. The image size is also in the layer's
customLayerData (``usdface.imageSize``).
"""
from __future__ import annotations

import json
import os

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from ..model.capture import Capture
from ..errors import InputError, MarkerError
from .capture_layer import CAPTURE_PRIM, MARKER_SET_API, MARKERS_PRIM, hold_invalid, read_capture_layer
from .layers import output_layer, open_stage, set_provenance, set_stage_metadata
from .schemas import require_registered

__all__ = ["write_track_layer", "read_track_layer"]

CONFIDENCE_ATTR = "primvars:usdface:confidence"
IMAGE_SIZE_ATTR = "usdface:track:imageSize"
SOURCE_VIDEO_ATTR = "usdface:track:sourceVideo"


def write_track_layer(path: str | os.PathLike, capture: Capture, *, confidence: np.ndarray | None = None,
                      image_size: tuple[int, int], prov: dict, source_video: str = "") -> str:
    """Write 2D marker tracks as a track layer (atomically). Returns the path.

    Parameters
    ----------
    path : str or os.PathLike
        Output ``.usdc`` / ``.usda``.
    capture : Capture
        Positions (F, M, 3) in pixels with z = 0, NaN where invalid.
    confidence : ndarray, shape (F, M), optional
        Per-sample confidence in [0, 1] (0 where invalid); default 1 where valid.
    image_size : (width, height)
        Video frame size in pixels.
    prov : dict
        Provenance (:func:`usdface.usd.layers.provenance`).
    source_video : str
        The video's file name (a record).
    """
    require_registered()
    capture.check_not_all_invalid()
    valid = capture.valid
    f_count, m = valid.shape
    if confidence is None:
        confidence = valid.astype(np.float32)
    conf = np.where(valid, np.nan_to_num(np.asarray(confidence, dtype=np.float32)), 0.0).astype(np.float32)
    if conf.shape != (f_count, m):
        raise MarkerError(f"track layer: confidence must have shape ({f_count}, {m}); got {conf.shape}")
    held = hold_invalid(capture.positions, valid).astype(np.float32)
    held[..., 2] = 0.0
    w, h = (int(v) for v in image_size)
    start = capture.start_frame
    with output_layer(path) as stage:
        set_stage_metadata(stage, units=None, default_prim="Capture", rate=capture.rate, start=start,
                           end=start + f_count - 1)
        root = UsdGeom.Xform.Define(stage, CAPTURE_PRIM)
        root.AddTransformOp().Set(Gf.Matrix4d(1.0))
        points = UsdGeom.Points.Define(stage, MARKERS_PRIM)
        prim = points.GetPrim()
        prim.ApplyAPI(MARKER_SET_API)
        prim.GetAttribute("usdface:markerSet:names").Set(Vt.StringArray(list(capture.names)))
        prim.GetAttribute("usdface:markerSet:captureRate").Set(float(capture.rate))
        prim.GetAttribute("usdface:markerSet:sourceFile").Set(os.path.basename(source_video or capture.source))
        prim.GetAttribute("usdface:markerSet:sourceUnits").Set("px")
        prim.GetAttribute("usdface:markerSet:neutralTime").Set(float(start + capture.neutral_frame))
        prim.GetAttribute("usdface:markerSet:dimensions").Set(2)
        prim.CreateAttribute(IMAGE_SIZE_ATTR, Sdf.ValueTypeNames.Int2, custom=True).Set(Gf.Vec2i(w, h))
        prim.CreateAttribute(SOURCE_VIDEO_ATTR, Sdf.ValueTypeNames.String, custom=True).Set(
            os.path.basename(source_video or capture.source))
        valid_attr = prim.GetAttribute("primvars:usdface:valid")
        UsdGeom.Primvar(valid_attr).SetInterpolation(UsdGeom.Tokens.vertex)
        conf_pv = UsdGeom.PrimvarsAPI(prim).CreatePrimvar("usdface:confidence", Sdf.ValueTypeNames.FloatArray,
                                                          UsdGeom.Tokens.vertex)
        conf_attr = conf_pv.GetAttr()
        points.CreateWidthsAttr(Vt.FloatArray([float(max(2.0, min(w, h) / 100.0))]))
        points.SetWidthsInterpolation(UsdGeom.Tokens.constant)
        points.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(Vt.Vec3fArray([Gf.Vec3f(0.1, 0.4, 1.0)]))
        points_attr = points.CreatePointsAttr()
        extent_attr = points.CreateExtentAttr()
        extents = np.stack([held.min(axis=1), held.max(axis=1)], axis=1)
        with Sdf.ChangeBlock():
            changes = np.flatnonzero(np.r_[True, (valid[1:] != valid[:-1]).any(axis=1)])
            for f in range(f_count):
                t = Usd.TimeCode(start + f)
                points_attr.Set(Vt.Vec3fArray.FromNumpy(held[f]), t)
                extent_attr.Set(Vt.Vec3fArray.FromNumpy(extents[f]), t)
                conf_attr.Set(Vt.FloatArray.FromNumpy(conf[f]), t)
            for f in changes:
                valid_attr.Set(Vt.BoolArray.FromNumpy(valid[f]), Usd.TimeCode(start + int(f)))
        history = json.dumps(list(capture.history), sort_keys=True, default=str)
        set_provenance(stage, dict(prov, captureHistory=history, imageSize=Vt.IntArray([w, h]), units="px"))
    return str(path)


def read_track_layer(path: str | os.PathLike):
    """Read a track layer.

    Returns
    -------
    capture : Capture
        Positions (F, M, 3) in pixels, z = 0, NaN where invalid; ``units = "px"``.
    info : dict
        ``image_size`` (width, height), ``confidence`` (F, M) float64, ``source_video`` (str),
        ``dimensions`` (2).

    Raises
    ------
    InputError
        Not a track layer (no image size or not 2D).
    """
    stage = open_stage(path, what="track layer")
    capture = read_capture_layer(path, stage=stage)
    from .capture_layer import find_marker_set

    prim = find_marker_set(stage, what="track layer")
    dims = prim.GetAttribute("usdface:markerSet:dimensions").Get()
    size_attr = prim.GetAttribute(IMAGE_SIZE_ATTR)
    if dims != 2 or not size_attr or not size_attr.HasValue():
        raise InputError(f"track layer {path}: not a 2D track layer (dimensions = {dims}, "
                         f"{'no' if not size_attr else 'an'} {IMAGE_SIZE_ATTR}); written by `usdface track`?")
    size = tuple(int(v) for v in size_attr.Get())
    conf_attr = prim.GetAttribute(CONFIDENCE_ATTR)
    times = capture.times
    if conf_attr and conf_attr.HasValue():
        conf = np.stack([np.asarray(conf_attr.Get(Usd.TimeCode(float(t))), dtype=np.float64) for t in times])
    else:
        conf = capture.valid.astype(np.float64)
    capture = capture.replace(units="px")
    info = {"image_size": size, "confidence": conf,
            "source_video": prim.GetAttribute(SOURCE_VIDEO_ATTR).Get() or "", "dimensions": 2}
    return capture, info
