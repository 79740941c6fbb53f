"""C3D marker files (reader and writer), through ezc3d.

What is read: the 3D points (``POINT`` group), named by ``POINT:LABELS`` (and ``LABELS2``... for
more than 255 points), at ``POINT:RATE`` Hz, in ``POINT:UNITS`` (``mm`` usually). A sample whose
residual is negative (the C3D "invalid" flag) or whose coordinates are NaN is invalid (NaN). So is
a sample at exactly (0, 0, 0), the way many exporters write a gap without setting the residual
(``keep_zeros=True`` keeps such samples as positions); the read step of the history counts them
(``zero_samples``, ``zero_markers``) so the import reports them.
Analog channels, force plates and events are ignored. The capture's ``start_frame`` is the
header's first frame, 0-based (C3D frame 1 is time code 0).

Axes: C3D data is Z-up by convention, so the reader rotates it to usdface's Y-up as
(x, y, z) -> (x, z, -y) unless ``up_axis="Y"`` says the file is already Y-up. The writer applies
the inverse rotation (x, y, z) -> (x, -z, y), so writing then reading gives the same capture.

Precision: C3D stores floating-point coordinates as float32, so a round trip keeps about 7
significant digits (1e-5 cm on face-sized coordinates).

The reader also checks that the file holds all the frames its header announces (ezc3d reads a
truncated data section without complaint).
"""
from __future__ import annotations

import math
import os
import struct
from pathlib import Path

import numpy as np

from ..findings import refuse
from ..io.limits import check_read_size, rate_finding
from ..model.capture import Capture
from ..errors import FormatError, MarkerError
from ..inputfiles import FLOAT32_MAX, first_beyond_float32
from .c3d_header import read_layout
from .captures import (
    check_input_file, check_up_axis, resolve_rate, resolve_units, unit_from_text, y_up_to_z_up, z_up_to_y_up,
)

__all__ = ["read_c3d", "write_c3d"]


def _ezc3d():
    try:
        import ezc3d
    except ImportError:  # pragma: no cover - ezc3d is a declared dependency
        raise ImportError("reading or writing C3D files needs ezc3d: pip install ezc3d") from None
    return ezc3d


def read_c3d(path, *, units: str | None = None, rate: float | None = None, up_axis: str | None = "Z",
             keep_zeros: bool = False, allow=frozenset()) -> Capture:
    """Read the 3D marker points of a ``.c3d`` file.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.c3d`` file.
    units : str, optional
        Needed only when ``POINT:UNITS`` is missing or empty; must agree with it otherwise.
    rate : float, optional
        Needed only when ``POINT:RATE`` is missing; must agree with it otherwise (Hz).
    up_axis : {"Z", "Y"}, optional
        Up axis of the file's data; default Z (the C3D convention), rotated to Y-up.
    keep_zeros : bool
        Keep samples at exactly (0, 0, 0) as positions (default False: they are gaps).
    allow : set of str
        Plausibility codes accepted (``rate``, ``frame-count``: :mod:`usdface.io.limits`).

    Returns
    -------
    Capture
        positions (F, M, 3) float64 in the file's units, Y-up, NaN where the residual is negative
        or (unless ``keep_zeros``) the sample is exactly (0, 0, 0); history ({"step": "read",
        "format": "c3d", "up_axis": ...},), plus ``"zero_samples": n, "zero_markers": {name: n}``
        when zeros were read as gaps.

    Raises
    ------
    InputError, FormatError, MarkerError, OptionError
        See :func:`usdface.io.captures.read_capture`.
    """
    source = os.fspath(path)
    up = check_up_axis(up_axis) or "Z"
    file = check_input_file(path)
    _check_announced(file, source, allow)
    ezc3d = _ezc3d()
    try:
        c3d = ezc3d.c3d(str(file))
    except Exception as exc:  # ezc3d raises OSError/RuntimeError with its own wording
        raise FormatError(f"{source}: not a readable C3D file ({exc})") from None

    parameters = c3d["parameters"]
    point = parameters.get("POINT", {}) if hasattr(parameters, "get") else parameters["POINT"]
    points = np.asarray(c3d["data"]["points"], dtype=np.float64)  # (4, M, F)
    if points.ndim != 3 or points.shape[1] == 0:
        raise MarkerError(f"{source}: the file has zero 3D points (markers)")
    n_markers, n_frames = points.shape[1], points.shape[2]
    if n_frames == 0:
        raise MarkerError(f"{source}: the file has zero frames")
    _check_complete(c3d, file, source, n_markers, n_frames)

    labels = _labels(point)
    if len(labels) < n_markers:
        raise FormatError(f"{source}: POINT:LABELS names {len(labels)} points but the data has {n_markers}")
    labels = labels[:n_markers]
    if any(not name for name in labels):
        raise FormatError(f"{source}: POINT:LABELS has an empty label (point {labels.index('') + 1})")

    declared_rate = None
    if "RATE" in point and len(point["RATE"]["value"]) and float(point["RATE"]["value"][0]) > 0:
        declared_rate = float(point["RATE"]["value"][0])
    elif c3d["header"]["points"]["frame_rate"] > 0:
        declared_rate = float(c3d["header"]["points"]["frame_rate"])
    declared_unit = None
    if "UNITS" in point and len(point["UNITS"]["value"]) and str(point["UNITS"]["value"][0]).strip():
        text = str(point["UNITS"]["value"][0]).strip()
        declared_unit = unit_from_text(text)
        if declared_unit is None:
            raise FormatError(f"{source}: POINT:UNITS {text!r} is not a unit usdface knows (mm, cm, m, in, ft)")
    unit = resolve_units(declared_unit, units, source=source)
    capture_rate = resolve_rate(declared_rate, rate, source=source)

    at = first_beyond_float32(points[:3])
    if at is not None:
        axis, marker, frame = at
        raise FormatError(f"{source}: point {labels[marker]!r} at frame {frame} has {'xyz'[axis]} = "
                          f"{points[axis, marker, frame]:g}, beyond the range of the float32 positions USD stores "
                          f"(|x| <= {FLOAT32_MAX:.4g}): the file is corrupt")
    positions = points[:3].transpose(2, 1, 0).copy()  # (F, M, 3)
    residuals = np.asarray(c3d["data"]["meta_points"]["residuals"])
    invalid = ~np.isfinite(positions).all(axis=2)
    if residuals.shape == (1, n_markers, n_frames):
        invalid |= residuals[0].T < 0
    zeros = ~invalid & (positions == 0.0).all(axis=2)
    if not keep_zeros:
        invalid |= zeros
    positions[invalid] = np.nan
    if up == "Z":
        positions = z_up_to_y_up(positions)
    step = {"step": "read", "format": "c3d", "up_axis": up}
    if zeros.any() and not keep_zeros:
        step["zero_samples"] = int(zeros.sum())
        step["zero_markers"] = {labels[m]: int(n) for m, n in enumerate(zeros.sum(axis=0)) if n}
    capture = Capture(
        names=tuple(labels), positions=positions, rate=capture_rate, units=unit,
        start_frame=int(c3d["header"]["points"]["first_frame"]), source=source,
        history=(step,),
    )
    capture.check_not_all_invalid()
    return capture


#: bytes ezc3d holds per point value and per analog sample while reading (doubles, nested vectors)
_EZC3D_BYTES_PER_POINT_FRAME = 4 * 8 * 3
_EZC3D_BYTES_PER_ANALOG_SAMPLE = 200


def _check_announced(file: Path, source: str, allow) -> None:
    """Before ezc3d reads the file: its header's counts against its size, the frame count and
    rate against :mod:`usdface.io.limits`, and what ezc3d will allocate against memory."""
    from ..memory import check_memory

    layout = read_layout(file, source)
    size = file.stat().st_size
    if layout.data_bytes > size:
        raise FormatError(f"{source}: the header announces {layout.frames:,} frames of {layout.points:,} points"
                          + (f" and {layout.analog_channels} analog channels" if layout.analog_channels else "")
                          + f" ({layout.data_bytes:,} bytes) but the file has {size:,} bytes: it is truncated")
    if layout.point_rate:
        refuse([rate_finding(layout.point_rate, what=source, origin="POINT:RATE")], allow=allow)
    check_read_size(what=source, frames=layout.frames, markers=max(layout.points, 1), allow=allow)
    analog = layout.frames * math.ceil(layout.analog_ratio) * (8 * layout.analog_channels + _EZC3D_BYTES_PER_ANALOG_SAMPLE)
    check_memory(layout.frames * layout.points * _EZC3D_BYTES_PER_POINT_FRAME + analog,
                 what=f"{source}: reading {layout.frames:,} frames of {layout.points:,} points and "
                      f"{layout.analog_channels} analog channels", hint="read a smaller file")


def write_c3d(path, capture: Capture) -> None:
    """Write ``capture`` as a ``.c3d`` file (float32 points, Z-up by the C3D convention).

    Invalid samples get residual -1; valid ones residual 0. ``POINT:UNITS`` is the capture's
    unit (empty when unknown); the header's first frame is ``capture.start_frame`` (0-based).
    The file is written to a temporary name in the same folder and renamed into place.
    """
    ezc3d = _ezc3d()
    if not 0 <= capture.start_frame < 65535:
        raise FormatError(f"cannot write {os.fspath(path)}: C3D cannot store start frame {capture.start_frame}")
    c3d = ezc3d.c3d()
    point = c3d["parameters"]["POINT"]
    point["RATE"]["value"] = [float(capture.rate)]
    point["LABELS"]["value"] = list(capture.names)
    point["UNITS"]["value"] = [capture.units or ""]
    data = np.ones((4, capture.n_markers, capture.n_frames))
    valid = capture.valid
    z_up = np.where(valid[..., None], y_up_to_z_up(capture.positions), 0.0)
    data[:3] = z_up.transpose(2, 1, 0)
    c3d["data"]["points"] = data
    c3d["data"]["meta_points"]["residuals"] = np.where(valid.T, 0.0, -1.0)[None]
    c3d["header"]["points"]["first_frame"] = int(capture.start_frame)

    target = Path(os.fspath(path))
    # ezc3d appends ".c3d" unless the name ends with it (case-sensitively): write a temporary name
    # it accepts (the one scheme of usdface.fileutil), renamed over the target when complete
    from ..fileutil import atomic_path

    with atomic_path(target, suffix=".c3d") as temp:
        c3d.write(str(temp))


def _labels(point) -> list[str]:
    labels = [str(s).strip() for s in point["LABELS"]["value"]] if "LABELS" in point else []
    i = 2
    while f"LABELS{i}" in point:
        labels += [str(s).strip() for s in point[f"LABELS{i}"]["value"]]
        i += 1
    return labels


def _header_frame_count(file: Path) -> int | None:
    """Number of frames the file's 512-byte header announces, or None if it cannot tell.

    ezc3d shortens ``last_frame`` to the frames actually present, so a truncated file is only
    visible in the raw header: words 4-5 hold the first and last frame (1-based, 16-bit), in the
    byte order given by the processor type (byte 4 of the parameter section: 84 Intel, 85 DEC,
    86 MIPS big-endian).
    """
    try:
        with open(file, "rb") as handle:
            header = handle.read(512)
            parameter_block = header[0]
            handle.seek(max(parameter_block - 1, 0) * 512)
            parameter_head = handle.read(4)
    except OSError:
        return None
    if len(header) < 512 or len(parameter_head) < 4 or header[1] != 0x50:
        return None
    byte_order = ">" if parameter_head[3] == 86 else "<"
    first, last = struct.unpack(byte_order + "HH", header[6:10])
    if last == 65535 or last < first:  # long trials keep the real count elsewhere (TRIAL group)
        return None
    return last - first + 1


def _check_complete(c3d, file: Path, source: str, n_markers: int, n_frames: int) -> None:
    """FormatError if the file holds fewer frames than its header announces."""
    announced = _header_frame_count(file)
    if announced is not None and announced > n_frames:
        raise FormatError(f"{source}: the header announces {announced} frames but the file holds only "
                          f"{n_frames}: it is truncated")
    point = c3d["parameters"]["POINT"]
    try:
        data_start = int(point["DATA_START"]["value"][0])
        scale = float(point["SCALE"]["value"][0])
    except (KeyError, IndexError, TypeError, ValueError):
        return
    analogs = np.asarray(c3d["data"]["analogs"])
    analog_values_per_frame = analogs.size // n_frames if analogs.size else 0
    word = 4 if scale < 0 else 2
    frames = max(n_frames, announced or 0)
    needed = (data_start - 1) * 512 + frames * word * (4 * n_markers + analog_values_per_frame)
    size = file.stat().st_size
    if size < needed:
        raise FormatError(f"{source}: the header announces {frames} frames of {n_markers} points "
                          f"({needed} bytes) but the file has {size} bytes: it is truncated")
