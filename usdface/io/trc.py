"""OpenSim / Motion Analysis ``.trc`` marker files (reader and writer).

Layout (tab separated)::

    PathFileType  4  (X/Y/Z)  <file name>
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
    60        60          1590       41          cm     60            1                   1590
    Frame#  Time  ForeHead_M  <empty>  <empty>  ForeHead_L ...
    <empty> <empty> X1  Y1  Z1  X2  Y2  Z2 ...
    <blank line>
    1       0     14.12  84.15  3.48  ...

``Frame#`` is 1-based and ``Time`` in seconds. An empty cell (or NaN) in any coordinate makes the
sample invalid; frame numbers missing between the first and last row are invalid samples. Rows may
omit trailing empty cells. The reader checks ``NumFrames``/``NumMarkers`` against the data, so a
truncated file is an error rather than a short capture.

TRC files are Y-up by OpenSim convention; pass ``up_axis="Z"`` for Z-up data, which is rotated to
Y-up as (x, y, z) -> (x, z, -y). The writer writes Y-up data as it is. ``DataRate`` is the capture
rate; the capture's ``start_frame`` is ``round(Time * DataRate)`` of the first row.
"""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ..model.capture import Capture
from ..errors import FormatError, MarkerError
from ..errors import list_names
from ..findings import refuse
from ..io.limits import check_read_size, rate_finding
from .captures import (
    MAX_TIME_CODE, cells_to_float, check_float32_cells, check_up_axis, format_number, join_numbers, read_text,
    resolve_rate, resolve_units, unit_from_text, z_up_to_y_up,
)

__all__ = ["read_trc", "write_trc"]

_HEADER_KEYS = ("DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units", "OrigDataRate",
                "OrigDataStartFrame", "OrigNumFrames")


def read_trc(path, *, units: str | None = None, rate: float | None = None, up_axis: str | None = "Y",
             allow=frozenset()) -> Capture:
    """Read a ``.trc`` marker file.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.trc`` file.
    units : str, optional
        Needed only when the header has no ``Units``; must agree with it otherwise.
    rate : float, optional
        Needed only when the header has no ``DataRate``; must agree with it otherwise (Hz).
    up_axis : {"Y", "Z"}, optional
        Up axis of the file's data (default Y, the OpenSim convention).
    allow : set of str
        Plausibility codes accepted (``rate``, ``frame-count``: :mod:`usdface.io.limits`).

    Returns
    -------
    Capture
        positions (F, M, 3) float64 in the file's units, Y-up, NaN where invalid; history
        ({"step": "read", "format": "trc", "up_axis": ...},).

    Raises
    ------
    InputError, FormatError, MarkerError, OptionError
        See :func:`usdface.io.captures.read_capture`.
    """
    source = os.fspath(path)
    up = check_up_axis(up_axis) or "Y"
    text = read_text(path)
    lines = text.splitlines()
    if len(lines) < 5 or not lines[0].startswith("PathFileType"):
        raise FormatError(f"{source}, line 1: not a TRC file (expected a 'PathFileType' line followed by the "
                          f"DataRate/NumFrames/... header, the marker names and the X1/Y1/Z1 row)")
    keys = [c.strip() for c in lines[1].split("\t")]
    values = [c.strip() for c in lines[2].split("\t")]
    header = dict(zip(keys, values))
    missing = [k for k in ("NumFrames", "NumMarkers") if not header.get(k)]
    if missing:
        raise FormatError(f"{source}, line 2: header lacks {', '.join(missing)} (found: {', '.join(k for k in keys if k)})")
    n_frames_declared = _header_int(header, "NumFrames", source)
    n_markers_declared = _header_int(header, "NumMarkers", source)
    declared_rate = _header_float(header, "DataRate", source) if header.get("DataRate") else None
    declared_unit = None
    if header.get("Units"):
        declared_unit = unit_from_text(header["Units"])
        if declared_unit is None:
            raise FormatError(f"{source}, line 3: unknown Units {header['Units']!r}; expected mm, cm, m, in or ft")
    unit = resolve_units(declared_unit, units, source=source)
    capture_rate = resolve_rate(declared_rate, rate, source=source)
    refuse([rate_finding(capture_rate, what=source, origin="declared" if declared_rate else "given with --rate")],
           allow=allow)

    names = _marker_names(lines[3], source, n_markers_declared)

    width = 2 + 3 * len(names)
    rows, row_lines = [], []
    for number in range(5, len(lines)):
        line = lines[number]
        if not line.strip():
            continue
        cells = line.split("\t")
        if len(cells) > width:
            if any(c.strip() for c in cells[width:]):
                raise FormatError(f"{source}, line {number + 1}: {len(cells)} cells; {len(names)} markers need {width}")
            cells = cells[:width]
        elif len(cells) < width:
            cells = cells + [""] * (width - len(cells))
        rows.append(cells)
        row_lines.append(number + 1)
    if rows and not text.endswith(("\n", "\r")) and len(lines[row_lines[-1] - 1].split("\t")) < width:
        raise FormatError(f"{source}, line {row_lines[-1]}: the last row is incomplete: the file is truncated")
    if not rows:
        raise MarkerError(f"{source}: zero frames (no data rows after the header)")
    if len(rows) != n_frames_declared:
        raise FormatError(f"{source}: header says NumFrames {n_frames_declared} but the file has {len(rows)} "
                          f"data rows: the file is truncated or malformed")

    table = cells_to_float(rows, source=source, first_line=row_lines[0],
                           columns=["Frame#", "Time"] + [f"{n}.{a}" for n in names for a in "XYZ"])
    check_float32_cells(table[:, 2:], source=source, lines=row_lines, columns=[f"{n}.{a}" for n in names for a in "XYZ"])
    frame_numbers = table[:, 0]
    bad = np.flatnonzero(~np.isfinite(frame_numbers) | (frame_numbers != np.rint(frame_numbers)))
    if bad.size:
        raise FormatError(f"{source}, line {row_lines[bad[0]]}: Frame# {rows[bad[0]][0].strip()!r} is not an integer")
    bad = np.flatnonzero(np.abs(frame_numbers) > MAX_TIME_CODE)
    if bad.size:
        raise FormatError(f"{source}, line {row_lines[bad[0]]}: Frame# {rows[bad[0]][0].strip()} is beyond the time "
                          f"codes usdface stores (frames within +-{MAX_TIME_CODE:,})")
    frame_numbers = frame_numbers.astype(np.int64)
    first = int(frame_numbers.min())
    index = frame_numbers - first
    order = np.argsort(index, kind="stable")
    dup = np.flatnonzero(np.diff(index[order]) == 0)
    if dup.size:
        i = order[dup[0] + 1]
        raise FormatError(f"{source}, line {row_lines[i]}: Frame# {frame_numbers[i]} is listed twice")
    far = int(np.argmax(index))
    n_frames = check_read_size(what=source, frames=int(index.max()) + 1, markers=len(names), samples=len(rows),
                               detail=f" (line {row_lines[far]}: Frame# {frame_numbers[far]})", allow=allow)
    positions = np.full((n_frames, len(names), 3), np.nan)
    positions[index] = table[:, 2:].reshape(len(rows), len(names), 3)
    positions[~np.isfinite(positions).all(axis=2)] = np.nan
    if up == "Z":
        positions = z_up_to_y_up(positions)

    first_row = int(np.argmin(frame_numbers))
    first_time = table[first_row, 1]
    start_frame = int(round(first_time * capture_rate)) if math.isfinite(first_time) else first - 1
    capture = Capture(
        names=tuple(names), positions=positions, rate=capture_rate, units=unit, start_frame=start_frame,
        source=source, history=({"step": "read", "format": "trc", "up_axis": up},),
    )
    capture.check_not_all_invalid()
    return capture


def write_trc(path, capture: Capture) -> None:
    """Write ``capture`` as a tab-separated ``.trc`` file (Y-up, positions in ``capture.units``).

    ``Frame#`` = start_frame + f + 1, ``Time`` = (start_frame + f) / rate; invalid samples are
    empty cells; numbers use the shortest text that reads back to the same float.
    """
    if capture.units is None:
        raise FormatError(f"cannot write {os.fspath(path)}: the capture has no units and TRC files must declare them")
    rate = format_number(capture.rate)
    n_frames, n_markers = capture.n_frames, capture.n_markers
    out = [
        f"PathFileType\t4\t(X/Y/Z)\t{Path(os.fspath(path)).name}",
        "\t".join(_HEADER_KEYS),
        "\t".join([rate, rate, str(n_frames), str(n_markers), capture.units, rate,
                   str(capture.start_frame + 1), str(n_frames)]),
        "\t".join(["Frame#", "Time"] + [f"{n}\t\t" for n in capture.names]).rstrip("\t"),
        "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, n_markers + 1)),
        "",
    ]
    values = capture.positions.reshape(n_frames, -1).tolist()
    for f, row in enumerate(values):
        code = capture.start_frame + f
        out.append(f"{code + 1}\t{format_number(code / capture.rate)}\t" + join_numbers(row, "\t"))
    from ..fileutil import atomic_path

    with atomic_path(path) as tmp, open(tmp, "w", newline="\n", encoding="utf-8") as handle:
        handle.write("\n".join(out) + "\n")


def _marker_names(line: str, source: str, declared: int) -> list[str]:
    """Marker names of line 4 (``Frame#<tab>Time<tab>Name<tab><tab>Name...``), checked."""
    name_cells = line.rstrip("\r\n").split("\t")
    if len(name_cells) < 2 or name_cells[0].strip() != "Frame#":
        raise FormatError(f"{source}, line 4: expected 'Frame#<tab>Time<tab><marker names>'")
    names = [c.strip() for c in name_cells[2::3]]
    while names and not names[-1]:
        names.pop()  # trailing tabs
    if any(not n for n in names):
        raise FormatError(f"{source}, line 4: empty marker name in column {3 + 3 * names.index('')}")
    stray = [c.strip() for i, c in enumerate(name_cells[2:]) if i % 3 and c.strip()]
    if stray:
        raise FormatError(f"{source}, line 4: marker names must be 3 columns apart; unexpected {stray[0]!r}")
    if not names:
        raise MarkerError(f"{source}, line 4: zero markers")
    if len(names) != declared:
        raise FormatError(f"{source}: header says NumMarkers {declared} but line 4 names "
                          f"{len(names)} markers: {list_names(names)}")
    seen, dups = set(), set()
    for name in names:
        (dups if name in seen else seen).add(name)
    if dups:
        raise MarkerError(f"{source}, line 4: duplicate marker names: {list_names(sorted(dups))}")
    return names


def _header_int(header: dict, key: str, source: str) -> int:
    try:
        value = float(header[key])
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and value == int(value) and value >= 0):
        raise FormatError(f"{source}, line 3: {key} must be a whole number; got {header[key]!r}")
    return int(value)


def _header_float(header: dict, key: str, source: str) -> float:
    try:
        value = float(header[key])
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and value > 0):
        raise FormatError(f"{source}, line 3: {key} must be a positive number; got {header[key]!r}")
    return value
