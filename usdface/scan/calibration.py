"""Stereo calibration files and rectification.

Calibration JSON, one of two forms:

Rectified pair (the images are already row-aligned, e.g. Middlebury, or rendered)::

    {"f": 994.978, "cx": 311.193, "cy": 254.877, "baseline": 193.001, "doffs": 31.086,
     "vertical": false, "units": "mm"}

- ``f``, ``cx``, ``cy``: focal length and principal point of the first (left or top) camera,
  pixels; ``doffs``: ``cx`` of the second camera minus ``cx`` of the first (Middlebury's
  "doffs"), pixels (default 0); ``baseline``: distance between the camera centres, in ``units``
  (default ``"mm"``); ``vertical``: true when the second camera sits *below* the first (the
  paper's arrangement, section 2.1): the first image is then the top one and disparities run
  along columns.
- Depth ``Z = f * baseline / (d + doffs)``; a pixel (x, y) is the point
  ``((x - cx) Z / f, (y - cy) Z / f, Z)`` of the first camera's frame (x right, y down, z forward).

Unrectified pair (calibrated, e.g. with cv2.stereoCalibrate)::

    {"K1": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], "D1": [k1, k2, p1, p2, k3],
     "K2": [[...]], "D2": [...], "R": [[...3x3...]], "T": [tx, ty, tz], "units": "mm"}

``R``, ``T`` take points from the first camera's frame to the second's (OpenCV's convention:
``X2 = R X1 + T``), so a second camera to the right of the first has ``tx < 0``. The pair is
rectified with cv2.stereoRectify (zero disparity at infinity, so ``doffs = 0``); whether it is
horizontal or vertical follows from ``T``.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import FormatError, OptionError, list_names
from ..inputfiles import read_json
from ..units import METERS_PER_UNIT

__all__ = ["StereoCalibration", "RectifiedPair", "read_calibration", "calibration_from_dict", "rectify_pair",
           "rectify_image_points", "scan_camera_dict"]

_RECTIFIED_KEYS = ("f", "cx", "cy", "baseline", "doffs", "vertical", "units")
_FULL_KEYS = ("K1", "D1", "K2", "D2", "R", "T", "units")


@dataclass(frozen=True, eq=False)
class StereoCalibration:
    """A stereo calibration, rectified (``f, cx, cy, baseline, doffs, vertical``) or full.

    Attributes
    ----------
    f, cx, cy : float
        Rectified intrinsics of the first camera (pixels); NaN for a full calibration until
        :func:`rectify_pair` computes them.
    baseline : float
        Camera distance in ``units``.
    doffs : float
        Principal point offset between the cameras along the baseline (pixels).
    vertical : bool
        Second camera below the first.
    units : str
        Unit of ``baseline`` (and of ``T``), and so of the scan.
    K1, D1, K2, D2, R, T : ndarray or None
        Full calibration (None for a rectified one).
    source : str
    """

    f: float = math.nan
    cx: float = math.nan
    cy: float = math.nan
    baseline: float = math.nan
    doffs: float = 0.0
    vertical: bool = False
    units: str = "mm"
    K1: np.ndarray | None = None
    D1: np.ndarray | None = None
    K2: np.ndarray | None = None
    D2: np.ndarray | None = None
    R: np.ndarray | None = None
    T: np.ndarray | None = None
    source: str = field(default="", compare=False)

    @property
    def rectified(self) -> bool:
        """True for a rectified calibration (no K1...T)."""
        return self.K1 is None

    def depth(self, disparity) -> np.ndarray:
        """Depth ``Z = f B / (d + doffs)`` (in ``units``) of a disparity map (pixels); NaN stays NaN,
        non-positive ``d + doffs`` gives NaN."""
        d = np.asarray(disparity, dtype=np.float64) + self.doffs
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(d > 0, self.f * self.baseline / d, np.nan)

    def disparity(self, depth) -> np.ndarray:
        """Inverse of :meth:`depth`: ``d = f B / Z - doffs`` (pixels)."""
        z = np.asarray(depth, dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.f * self.baseline / z - self.doffs

    def points(self, depth) -> np.ndarray:
        """(H, W, 3) first-camera coordinates (x right, y down, z forward) of a depth map."""
        z = np.asarray(depth, dtype=np.float64)
        h, w = z.shape
        xs, ys = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        return np.stack([(xs - self.cx) * z / self.f, (ys - self.cy) * z / self.f, z], axis=-1)

    def to_dict(self) -> dict:
        """The JSON form (rectified keys, or the full keys)."""
        if self.rectified:
            return {"f": self.f, "cx": self.cx, "cy": self.cy, "baseline": self.baseline, "doffs": self.doffs,
                    "vertical": self.vertical, "units": self.units}
        return {"K1": self.K1.tolist(), "D1": self.D1.ravel().tolist(), "K2": self.K2.tolist(),
                "D2": self.D2.ravel().tolist(), "R": self.R.tolist(), "T": self.T.ravel().tolist(), "units": self.units}


def _num(path, key, value, *, positive=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise FormatError(f"calibration {path}: {key!r} must be a finite number; got {json.dumps(value)}")
    if positive and value <= 0:
        raise FormatError(f"calibration {path}: {key!r} must be > 0; got {value}")
    return float(value)


def _mat(path, key, value, shape):
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise FormatError(f"calibration {path}: {key!r} must be numbers of shape {shape}") from None
    if shape == "dist":
        a = a.ravel()
        if a.size not in (0, 4, 5, 8, 12, 14):
            raise FormatError(f"calibration {path}: {key!r} must have 4, 5, 8, 12 or 14 distortion coefficients; "
                              f"got {a.size}")
    elif a.size != int(np.prod(shape)):
        raise FormatError(f"calibration {path}: {key!r} must have shape {shape}; got {a.shape}")
    else:
        a = a.reshape(shape)
    if not np.isfinite(a).all():
        raise FormatError(f"calibration {path}: {key!r} has non-finite values")
    return a


def calibration_from_dict(data: dict, *, source: str = "") -> StereoCalibration:
    """Validate and build a :class:`StereoCalibration` from the JSON object (see module docstring)."""
    path = source or "<dict>"
    if not isinstance(data, dict):
        raise FormatError(f"calibration {path}: expected a JSON object")
    units = data.get("units", "mm")
    if units not in METERS_PER_UNIT:
        raise FormatError(f"calibration {path}: unknown units {units!r}; expected one of {', '.join(METERS_PER_UNIT)}")
    if "K1" in data or "R" in data or "T" in data:
        unknown = [k for k in data if k not in _FULL_KEYS]
        missing = [k for k in ("K1", "D1", "K2", "D2", "R", "T") if k not in data]
        if unknown:
            raise FormatError(f"calibration {path}: unknown key(s) {list_names(unknown)} in a full calibration; "
                              f"expected {', '.join(_FULL_KEYS)}")
        if missing:
            raise FormatError(f"calibration {path}: full calibration lacks {list_names(missing)}")
        K1, K2 = _mat(path, "K1", data["K1"], (3, 3)), _mat(path, "K2", data["K2"], (3, 3))
        R = _mat(path, "R", data["R"], (3, 3))
        if abs(np.linalg.det(R) - 1) > 1e-3 or np.abs(R @ R.T - np.eye(3)).max() > 1e-3:
            raise FormatError(f"calibration {path}: 'R' is not a rotation matrix")
        T = _mat(path, "T", data["T"], (3,))
        if np.linalg.norm(T) <= 0:
            raise FormatError(f"calibration {path}: 'T' is zero (the cameras coincide)")
        return StereoCalibration(baseline=float(np.linalg.norm(T)), units=units, K1=K1,
                                 D1=_mat(path, "D1", data["D1"], "dist"), K2=K2,
                                 D2=_mat(path, "D2", data["D2"], "dist"), R=R, T=T, source=source)
    unknown = [k for k in data if k not in _RECTIFIED_KEYS]
    if unknown:
        raise FormatError(f"calibration {path}: unknown key(s) {list_names(unknown)}; expected "
                          f"{', '.join(_RECTIFIED_KEYS)} (rectified) or K1, D1, K2, D2, R, T (unrectified)")
    missing = [k for k in ("f", "cx", "cy", "baseline") if k not in data]
    if missing:
        raise FormatError(f"calibration {path}: missing {list_names(missing)} (a rectified calibration needs "
                          "f, cx, cy, baseline; doffs and vertical are optional)")
    vertical = data.get("vertical", False)
    if not isinstance(vertical, bool):
        raise FormatError(f"calibration {path}: 'vertical' must be true or false; got {json.dumps(vertical)}")
    return StereoCalibration(f=_num(path, "f", data["f"], positive=True), cx=_num(path, "cx", data["cx"]),
                             cy=_num(path, "cy", data["cy"]),
                             baseline=_num(path, "baseline", data["baseline"], positive=True),
                             doffs=_num(path, "doffs", data.get("doffs", 0.0)), vertical=vertical, units=units,
                             source=source)


def read_calibration(path) -> StereoCalibration:
    """Read a calibration JSON file (rectified or full; see the module docstring)."""
    p = Path(os.fspath(path))
    data = read_json(p, label=f"calibration {p}")
    if not isinstance(data, dict):
        raise FormatError(f"calibration {p}: expected a JSON object; got {type(data).__name__}")
    return calibration_from_dict(data, source=str(p))


@dataclass(frozen=True, eq=False)
class RectifiedPair:
    """A rectified image pair and its rectified calibration.

    Attributes
    ----------
    first, second : ndarray
        Rectified images (left/right, or top/bottom when ``calibration.vertical``).
    calibration : StereoCalibration
        Rectified calibration of the pair.
    R1 : ndarray, shape (3, 3) or None
        Rectifying rotation of the first camera (None when the input was already rectified).
    P1 : ndarray, shape (3, 4) or None
        Its new projection matrix.
    """

    first: np.ndarray
    second: np.ndarray
    calibration: StereoCalibration
    R1: np.ndarray | None = None
    P1: np.ndarray | None = None

    def rectify_points(self, points, original: StereoCalibration) -> np.ndarray:
        """Pixel positions (M, 2) in the original first image -> positions in the rectified one."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if self.R1 is None:
            return pts.copy()
        return rectify_image_points(pts, original.K1, original.D1, self.R1, self.P1)


def rectify_pair(first, second, calibration: StereoCalibration) -> RectifiedPair:
    """Rectify a calibrated pair (cv2.stereoRectify + remap); a rectified calibration passes through.

    Raises
    ------
    OptionError
        The second camera is left of (or above) the first: swap the images.
    """
    if calibration.rectified:
        return RectifiedPair(first, second, calibration)
    import cv2

    h, w = first.shape[:2]
    c = calibration
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(c.K1, c.D1, c.K2, c.D2, (w, h), c.R, c.T,
                                                flags=cv2.CALIB_ZERO_DISPARITY, alpha=0)
    vertical = abs(P2[1, 3]) > abs(P2[0, 3])
    shift = P2[1, 3] if vertical else P2[0, 3]
    if shift > 0:
        where = "above" if vertical else "left of"
        raise OptionError(f"calibration {c.source}: the second camera is {where} the first (T = {c.T.tolist()}); "
                          "give the left (or top) image first")
    f = float(P1[0, 0])
    baseline = float(-shift / f)
    m1 = cv2.initUndistortRectifyMap(c.K1, c.D1, R1, P1, (w, h), cv2.CV_32FC1)
    m2 = cv2.initUndistortRectifyMap(c.K2, c.D2, R2, P2, (w, h), cv2.CV_32FC1)
    a = cv2.remap(first, m1[0], m1[1], cv2.INTER_LINEAR)
    b = cv2.remap(second, m2[0], m2[1], cv2.INTER_LINEAR)
    doffs = float(P2[1, 2] - P1[1, 2]) if vertical else float(P2[0, 2] - P1[0, 2])
    rect = StereoCalibration(f=f, cx=float(P1[0, 2]), cy=float(P1[1, 2]), baseline=baseline, doffs=doffs,
                             vertical=bool(vertical), units=c.units, source=c.source)
    return RectifiedPair(a, b, rect, R1=R1, P1=P1)


def rectify_image_points(points, K1, D1, R1, P1) -> np.ndarray:
    """Pixel positions (M, 2) in an original first image -> the rectified image (undistorted,
    rotated by ``R1``, projected by ``P1``), e.g. landmarks clicked on the camera's own picture."""
    import cv2

    pts = np.asarray(points, dtype=np.float64).reshape(-1, 1, 2)
    out = cv2.undistortPoints(pts, np.asarray(K1, np.float64), np.asarray(D1, np.float64),
                              R=np.asarray(R1, np.float64), P=np.asarray(P1, np.float64))
    return out.reshape(-1, 2)


def scan_camera_dict(rcal: StereoCalibration, size, *, rect: RectifiedPair | None = None,
                     original: StereoCalibration | None = None) -> dict:
    """The camera a stereo scan records (``scanCamera`` in its provenance), so image landmarks can
    later be lifted onto the scan (:func:`usdface.scan.image_landmarks.lift_image_landmarks`): the
    first rectified camera (``rcal``, images of ``size`` = (width, height) pixels) and, when the
    pair was rectified here (``rect`` from the ``original`` calibration), the first camera's
    rectification K1, D1, R1, P1."""
    cam = {"f": rcal.f, "cx": rcal.cx, "cy": rcal.cy, "width": int(size[0]), "height": int(size[1]),
           "baseline": rcal.baseline, "doffs": rcal.doffs, "vertical": bool(rcal.vertical), "units": rcal.units,
           "frame": "scan = (x, -y, -z) of the first rectified camera (x right, y down, z forward)"}
    if rect is not None and rect.R1 is not None:
        cam["rectification"] = {"K1": original.K1.tolist(), "D1": original.D1.ravel().tolist(),
                                "R1": rect.R1.tolist(), "P1": rect.P1.tolist()}
    return cam
