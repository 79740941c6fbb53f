"""Weight curves as CSV: usdface's own table and the layout Unreal's Live Link Face app records.

usdface curves CSV
------------------
Header ``frame,time,<shape names as in the rig>``; one row per frame: the frame index (time code,
0-based unless a start frame says otherwise), the time in seconds (``frame / rate``) and each
shape's weight in [0, 1]. :func:`read_curves_csv` reads it back (``usdface solve --apply``); the
rate is recovered from the frame and time columns.

Live Link Face CSV
------------------
The layout the Live Link Face iOS app records, which Unreal's LiveLinkFace importer and many DCC
scripts read: header ``Timecode,BlendShapeCount,`` then the 52 ARKit shapes in the app's order
(:data:`LIVE_LINK_FACE_SHAPES`: PascalCase, ``JawRight`` before ``JawLeft`` and ``MouthRight``
before ``MouthLeft`` as the app writes them), then ``HeadYaw,HeadPitch,HeadRoll,LeftEyeYaw,
LeftEyePitch,LeftEyeRoll,RightEyeYaw,RightEyePitch,RightEyeRoll``. ``BlendShapeCount`` is 61 (the
52 shapes and 9 rotations). ``Timecode`` is ``HH:MM:SS:FF.mmm``: FF the frame within the second at
the file's rate, mmm the milliseconds past that frame (000 here: rows are whole frames).

What usdface writes in the rotation columns: the head rotation removed by stabilisation, in mesh
space relative to the neutral frame (decision D1's ``H_mesh``), as radians of the intrinsic
decomposition ``R = R_y(yaw) R_x(pitch) R_z(roll)`` about the mesh's axes (+Y up, +X the
performer's left, +Z forward; right-handed, so positive yaw turns the face toward the performer's
left, positive pitch tips it down, positive roll tilts it toward the performer's right shoulder);
zeros without head motion. The eye columns are zeros: skin markers do not measure gaze. Rig names
are matched to ARKit names ignoring the case of the first letter (``jawOpen`` = ``JawOpen``); a
rig lacking ARKit shapes is an error unless ``fill_missing`` writes zeros for them.
"""
from __future__ import annotations

import csv
import io
import math
import os
from pathlib import Path

import numpy as np

from ..errors import FormatError, InputError, list_names

__all__ = ["LIVE_LINK_FACE_SHAPES", "LIVE_LINK_FACE_ROTATIONS", "write_curves_csv", "read_curves_csv",
           "curves_csv_text", "live_link_face_text", "live_link_timecode", "head_angles", "check_arkit_names",
           "missing_arkit_shapes"]

#: the 52 ARKit shapes in the order the Live Link Face app writes its CSV columns
LIVE_LINK_FACE_SHAPES = (
    "EyeBlinkLeft", "EyeLookDownLeft", "EyeLookInLeft", "EyeLookOutLeft", "EyeLookUpLeft", "EyeSquintLeft",
    "EyeWideLeft", "EyeBlinkRight", "EyeLookDownRight", "EyeLookInRight", "EyeLookOutRight", "EyeLookUpRight",
    "EyeSquintRight", "EyeWideRight", "JawForward", "JawRight", "JawLeft", "JawOpen", "MouthClose", "MouthFunnel",
    "MouthPucker", "MouthRight", "MouthLeft", "MouthSmileLeft", "MouthSmileRight", "MouthFrownLeft",
    "MouthFrownRight", "MouthDimpleLeft", "MouthDimpleRight", "MouthStretchLeft", "MouthStretchRight",
    "MouthRollLower", "MouthRollUpper", "MouthShrugLower", "MouthShrugUpper", "MouthPressLeft", "MouthPressRight",
    "MouthLowerDownLeft", "MouthLowerDownRight", "MouthUpperUpLeft", "MouthUpperUpRight", "BrowDownLeft",
    "BrowDownRight", "BrowInnerUp", "BrowOuterUpLeft", "BrowOuterUpRight", "CheekPuff", "CheekSquintLeft",
    "CheekSquintRight", "NoseSneerLeft", "NoseSneerRight", "TongueOut",
)
#: the rotation columns after the shapes
LIVE_LINK_FACE_ROTATIONS = ("HeadYaw", "HeadPitch", "HeadRoll", "LeftEyeYaw", "LeftEyePitch", "LeftEyeRoll",
                            "RightEyeYaw", "RightEyePitch", "RightEyeRoll")


def _fmt(v: float) -> str:
    return f"{v:.6f}"


def curves_csv_text(names, values, *, rate: float, start_frame: int = 0) -> str:
    """The usdface curves CSV for ``values`` (F, K) at ``rate`` (frames per second)."""
    v = np.asarray(values, dtype=np.float64)
    buf = io.StringIO()
    buf.write(",".join(["frame", "time", *names]) + "\n")
    for i, row in enumerate(v):
        f = start_frame + i
        buf.write(f"{f},{f / rate:.6f}," + ",".join(_fmt(x) for x in row) + "\n")
    return buf.getvalue()


def write_curves_csv(path, names, values, *, rate: float, start_frame: int = 0) -> Path:
    """Write :func:`curves_csv_text` atomically."""
    from ..fileutil import write_text_atomic

    return write_text_atomic(path, curves_csv_text(names, values, rate=rate, start_frame=start_frame))


def read_curves_csv(path) -> tuple[list[str], np.ndarray, np.ndarray, float]:
    """Read a usdface curves CSV.

    Returns
    -------
    names : list of str
    frames : ndarray (F,) int64
    values : ndarray (F, K) float64
    rate : float
        From the frame and time columns (``(f_last - f_first) / (t_last - t_first)``).
    """
    p = Path(os.fspath(path))
    if not p.is_file():
        raise InputError(f"--apply {p}: no such file")
    with open(p, newline="") as fh:
        rows = list(csv.reader(fh))
    if not rows or [c.strip() for c in rows[0][:2]] != ["frame", "time"]:
        raise FormatError(f"curves CSV {p}: the header must start with 'frame,time,' followed by shape names")
    names = [c.strip() for c in rows[0][2:]]
    if not names:
        raise FormatError(f"curves CSV {p}: no shape columns after 'frame,time'")
    dups = sorted({n for n in names if names.count(n) > 1})
    if dups:
        raise FormatError(f"curves CSV {p}: duplicate shape columns {list_names(dups)}")
    body = [r for r in rows[1:] if any(c.strip() for c in r)]
    if not body:
        raise FormatError(f"curves CSV {p}: no rows")
    frames, times, values = [], [], []
    for line, r in enumerate(body, start=2):
        if len(r) != len(names) + 2:
            raise FormatError(f"curves CSV {p} line {line}: {len(r)} columns, the header has {len(names) + 2}")
        try:
            frames.append(int(r[0]))
            times.append(float(r[1]))
            values.append([float(x) for x in r[2:]])
        except ValueError as exc:
            raise FormatError(f"curves CSV {p} line {line}: {exc}") from None
    w = np.asarray(values, dtype=np.float64)
    if not np.isfinite(w).all():
        raise FormatError(f"curves CSV {p}: NaN or infinite weights")
    fr = np.asarray(frames, dtype=np.int64)
    if fr.size > 1 and (np.diff(fr) != 1).any():
        raise FormatError(f"curves CSV {p}: frames must be consecutive (one row per frame)")
    if fr.size > 1:
        span = times[-1] - times[0]
        if span <= 0:
            raise FormatError(f"curves CSV {p}: times do not increase")
        rate = (fr[-1] - fr[0]) / span
    else:
        rate = fr[0] / times[0] if times[0] > 0 else math.nan
    if not (np.isfinite(rate) and rate > 0):
        raise FormatError(f"curves CSV {p}: cannot tell the frame rate from the frame and time columns")
    return names, fr, w, float(rate)


def live_link_timecode(frame: int, rate: float) -> str:
    """``HH:MM:SS:FF.mmm`` of frame ``frame`` (from 0) at ``rate``."""
    t = frame / rate
    whole = int(math.floor(t + 1e-9))
    h, rem = divmod(whole, 3600)
    m, s = divmod(rem, 60)
    sub = (t - whole) * rate
    ff = int(math.floor(sub + 1e-6))
    ms = int(round((sub - ff) / rate * 1000.0))
    return f"{h:02d}:{m:02d}:{s:02d}:{ff:02d}.{ms:03d}"


def head_angles(head_motion) -> np.ndarray:
    """(F, 3) (yaw, pitch, roll) radians of rigid motions (F, 4, 4): ``R = R_y(yaw) R_x(pitch) R_z(roll)``."""
    r = np.asarray(head_motion, dtype=np.float64)[:, :3, :3]
    # R = Ry Rx Rz: R[1, 2] = -sin(pitch); R[0, 2] = cos(pitch) sin(yaw); R[2, 2] = cos(pitch) cos(yaw);
    # R[1, 0] = cos(pitch) sin(roll); R[1, 1] = cos(pitch) cos(roll)
    pitch = np.arcsin(np.clip(-r[:, 1, 2], -1.0, 1.0))
    yaw = np.arctan2(r[:, 0, 2], r[:, 2, 2])
    roll = np.arctan2(r[:, 1, 0], r[:, 1, 1])
    return np.stack([yaw, pitch, roll], axis=1)


def _arkit_lookup(rig_names) -> dict:
    by_key = {}
    for i, n in enumerate(rig_names):
        by_key.setdefault(n[:1].lower() + n[1:], i)
    return by_key


def missing_arkit_shapes(names) -> list[str]:
    """ARKit shapes (camelCase) of the Live Link Face CSV that ``names`` lacks."""
    lookup = _arkit_lookup(names)
    return [a[:1].lower() + a[1:] for a in LIVE_LINK_FACE_SHAPES if a[:1].lower() + a[1:] not in lookup]


def check_arkit_names(names, *, fill_missing: bool = False, source: str = "the rig") -> list[str]:
    """Raise InputError (unless ``fill_missing``) when ``names`` lacks ARKit shapes; returns them."""
    missing = missing_arkit_shapes(names)
    if missing and not fill_missing:
        raise InputError(f"--livelink: {source} lacks {len(missing)} of the 52 ARKit shapes the Live Link Face CSV "
                         f"needs: {list_names(missing)}; rename its shapes to ARKit names, or pass "
                         "--livelink-fill-zeros to write zeros for them")
    return missing


def live_link_face_text(names, values, *, rate: float, head_motion=None, fill_missing: bool = False,
                        source: str = "the rig") -> tuple[str, dict]:
    """The Live Link Face CSV of curves ``values`` (F, K) over the rig's shape ``names``.

    Parameters
    ----------
    head_motion : ndarray (F, 4, 4), optional
        Mesh-space head motion relative to the neutral frame; its angles fill the head columns.
    fill_missing : bool
        Write zeros for ARKit shapes the rig lacks instead of raising.

    Returns
    -------
    text : str
    report : dict
        ``missing`` (ARKit shapes written as zeros) and ``unused`` (rig shapes with no ARKit column).
    """
    v = np.asarray(values, dtype=np.float64)
    missing = check_arkit_names(names, fill_missing=fill_missing, source=source)
    lookup = _arkit_lookup(names)
    cols = [lookup.get(a[:1].lower() + a[1:], -1) for a in LIVE_LINK_FACE_SHAPES]
    used = {c for c in cols if c >= 0}
    unused = [n for i, n in enumerate(names) if i not in used]
    angles = head_angles(head_motion) if head_motion is not None else np.zeros((v.shape[0], 3))
    if angles.shape[0] != v.shape[0]:
        raise InputError(f"head motion has {angles.shape[0]} frames, the curves {v.shape[0]}")
    buf = io.StringIO()
    buf.write(",".join(["Timecode", "BlendShapeCount", *LIVE_LINK_FACE_SHAPES, *LIVE_LINK_FACE_ROTATIONS]) + "\n")
    count = len(LIVE_LINK_FACE_SHAPES) + len(LIVE_LINK_FACE_ROTATIONS)
    zero_eyes = ",".join(["0.000000"] * 6)
    for f in range(v.shape[0]):
        shapes = ",".join(_fmt(v[f, c]) if c >= 0 else "0.000000" for c in cols)
        head = ",".join(_fmt(a) for a in angles[f])
        buf.write(f"{live_link_timecode(f, rate)},{count},{shapes},{head},{zero_eyes}\n")
    return buf.getvalue(), {"missing": missing, "unused": unused}
