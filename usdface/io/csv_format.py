"""Marker tracks as CSV: one specification for the reader and the writer, 2D or 3D.

Specification (usdface capture CSV)
-----------------------------------
A text file (UTF-8) of comma-separated values, with ``"`` quoting as in RFC 4180.

1. **Declaration line (optional).** If the first line starts with ``#`` it declares properties as
   ``key=value`` pairs separated by spaces: ``# units=cm rate=60``. Keys: ``units`` (one of ``mm``,
   ``cm``, ``dm``, ``m``, ``in``, ``ft``) and ``rate`` (capture rate in Hz, a positive number);
   either may be left out. Any other key is an error.
2. **Header row**, then one data row per line. Blank lines are ignored. Names in the header are
   case-insensitive (``frame``, ``Frame``, ``_X``...). Two forms:

   - *wide*: ``frame`` (or ``time``), then per marker ``<Marker>_x,<Marker>_y`` and, for 3D data,
     ``<Marker>_z``, in that order and next to each other. The marker name is the text before the
     last ``_``; it may contain ``_`` itself. Every marker has the same number of coordinates (2 or 3).
     One row per sample time.
   - *long*: exactly ``frame,marker,x,y`` or ``frame,marker,x,y,z`` (or ``time`` for ``frame``).
     One row per marker and sample time; markers are ordered by first appearance.

3. **Time column.** ``frame``: integer time codes at the capture rate, 0-based (frame ``n`` is at
   ``n / rate`` seconds); the capture starts at the smallest frame. ``time``: seconds; the frame is
   ``round(time * rate)`` and ``time * rate`` must be within 0.05 of that integer.
   Rows need not be sorted. Frames missing between the first and the last are invalid samples;
   a frame (wide) or a frame/marker pair (long) listed twice is an error.
4. **Invalid samples.** An empty cell or ``NaN`` (any case) in any coordinate makes the whole
   sample invalid (NaN).
5. **Units and rate.** Taken from the declaration line; a file without one needs ``--units`` /
   ``--rate`` (``units=``, ``rate=``), and an option that contradicts the declaration is an error.
   Positions are never rescaled.
6. **2D data** (e.g. tracked image points) reads as z = 0 with ``"dims": 2`` in the history step.
7. Every row has exactly as many cells as the header (a short last row means a truncated file).

The writer emits the declaration line (units when the capture has them, and rate), the wide form
by default, a ``frame`` column with the capture's time codes, the shortest decimal text that reads
back to the same float, and empty cells for invalid samples. Example::

    # units=cm rate=60
    frame,ForeHead_M_x,ForeHead_M_y,ForeHead_M_z,Chin_x,Chin_y,Chin_z
    0,14.12384,84.155664,3.480625,9.93,60.1,7.2
    1,14.13,84.16,3.49,,,
"""
from __future__ import annotations

import csv
import io
import math
import os
import re

import numpy as np

from ..model.capture import Capture
from ..errors import FormatError, MarkerError, OptionError
from ..errors import list_names
from ..units import METERS_PER_UNIT
from ..findings import refuse
from ..io.limits import check_read_size, rate_finding
from .captures import (
    MAX_TIME_CODE, cells_to_float, check_float32_cells, check_up_axis, format_number, join_numbers, read_text,
    resolve_rate, resolve_units, unit_from_text, z_up_to_y_up,
)

__all__ = ["read_csv", "write_csv", "CSV_TIME_TOLERANCE"]

#: how far ``time * rate`` may be from an integer frame (in frames)
CSV_TIME_TOLERANCE = 0.05

_DECLARATION_KEYS = ("units", "rate")
_COORD = re.compile(r"^(.+)_([xyzXYZ])$")


def read_csv(path, *, units: str | None = None, rate: float | None = None,
             up_axis: str | None = "Y", allow=frozenset()) -> Capture:
    """Read a usdface capture CSV (module docstring: the specification).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.csv`` file.
    units : str, optional
        Linear unit when the file does not declare one (``--units``); must agree when it does.
    rate : float, optional
        Capture rate in Hz when the file does not declare one (``--rate``); must agree when it does.
    up_axis : {"Y", "Z"}, optional
        Up axis of the data in the file; Z-up is rotated to Y-up, (x, y, z) -> (x, z, -y).
    allow : set of str
        Plausibility codes accepted (``rate``, ``frame-count``: :mod:`usdface.io.limits`).

    Returns
    -------
    Capture
        positions (F, M, 3) float64 in the declared unit, NaN where invalid, z = 0 for 2D data;
        history ({"step": "read", "format": "csv", "dims": 2 or 3, "form": "wide" or "long"},).

    Raises
    ------
    InputError, FormatError, MarkerError, OptionError
        See :func:`usdface.io.captures.read_capture`.
    """
    source = os.fspath(path)
    up = check_up_axis(up_axis) or "Y"
    text = read_text(path)
    lines = text.splitlines()
    declared, first = _read_declaration(lines, source)
    unit = resolve_units(declared.get("units"), units, source=source)
    capture_rate = resolve_rate(declared.get("rate"), rate, source=source)
    # the rate turns a time column into frame numbers: judge it before they are computed
    rate_origin = "declared" if "rate" in declared else "given with --rate"
    refuse([rate_finding(capture_rate, what=source, origin=rate_origin)], allow=allow)

    rows, line_numbers = [], []
    reader = csv.reader(io.StringIO("\n".join(lines[first:])))
    for row in reader:
        if not row or all(not c.strip() for c in row):
            continue
        rows.append(row)
        line_numbers.append(first + reader.line_num)
    if not rows:
        raise FormatError(f"{source}: no header row (expected 'frame,<Marker>_x,<Marker>_y[,<Marker>_z],...' "
                          f"or 'frame,marker,x,y[,z]')")
    header, header_line = [c.strip() for c in rows[0]], line_numbers[0]
    body, body_lines = rows[1:], line_numbers[1:]
    if not body:
        raise MarkerError(f"{source}: the file has a header but zero frames (no data rows)")
    for row, line in zip(body, body_lines):
        if len(row) != len(header):
            raise FormatError(f"{source}, line {line}: {len(row)} cells where the header (line {header_line}) "
                              f"has {len(header)}: the file is truncated or malformed")

    time_kind = header[0].lower()
    if time_kind not in ("frame", "time"):
        raise FormatError(f"{source}, line {header_line}: the first column must be 'frame' or 'time'; got {header[0]!r}")
    lowered = [h.lower() for h in header]
    if len(header) >= 2 and lowered[1] == "marker":
        if lowered[2:] not in (["x", "y"], ["x", "y", "z"]):
            raise FormatError(f"{source}, line {header_line}: long form header must be "
                              f"'{header[0]},marker,x,y' or '{header[0]},marker,x,y,z'; got {','.join(header)!r}")
        names, frames, coords, dims = _long_form(body, body_lines, header, source, capture_rate, time_kind)
        form = "long"
    else:
        names, dims = _wide_header(header, header_line, source)
        table = cells_to_float([r[1:] for r in body], source=source, first_line=body_lines[0], columns=header[1:])
        check_float32_cells(table, source=source, lines=body_lines, columns=header[1:])
        times = [r[0] for r in body]
        frames = _frames(times, body_lines, source, capture_rate, time_kind)
        coords = table.reshape(len(body), len(names), dims)
        form = "wide"
        order = np.argsort(frames, kind="stable")
        dup = np.flatnonzero(np.diff(frames[order]) == 0)
        if dup.size:
            i = order[dup[0] + 1]
            raise FormatError(f"{source}, line {body_lines[i]}: frame {frames[i]} is listed twice")

    start = int(frames.min())
    far = int(np.argmax(np.abs(frames - np.median(frames))))
    n_frames = check_read_size(what=source, frames=int(frames.max()) - start + 1, markers=len(names),
                               samples=int(np.unique(frames).size), detail=f" (line {body_lines[far]}: frame "
                               f"{frames[far]})", allow=allow)
    positions = np.full((n_frames, len(names), 3), np.nan)
    if form == "wide":
        positions[frames - start, :, :dims] = coords
    else:
        marker_index, values = coords
        positions[frames - start, marker_index, :dims] = values
    if dims == 2:
        positions[..., 2] = 0.0
    positions[~np.isfinite(positions).all(axis=2)] = np.nan
    if up == "Z":
        positions = z_up_to_y_up(positions)
    capture = Capture(
        names=tuple(names), positions=positions, rate=capture_rate, units=unit, start_frame=start,
        source=source, history=({"step": "read", "format": "csv", "dims": dims, "form": form},),
    )
    capture.check_not_all_invalid()
    return capture


def write_csv(path, capture: Capture, *, dims: int | None = None, form: str = "wide") -> None:
    """Write ``capture`` as a usdface capture CSV (module docstring: the specification).

    Parameters
    ----------
    path : str or os.PathLike
        Output file (replaced atomically: :func:`usdface.fileutil.atomic_path`).
    capture : Capture
        Positions (F, M, 3); invalid samples are written as empty cells.
    dims : {2, 3}, optional
        Coordinates per marker. Default: 2 if the capture was read from 2D data (a history step
        with ``"dims": 2``), else 3. With 2, z is dropped.
    form : {"wide", "long"}
        Table layout.
    """
    if dims is None:
        dims = next((int(s["dims"]) for s in reversed(capture.history) if "dims" in s), 3)
    if dims not in (2, 3):
        raise OptionError(f"--dims: expected 2 or 3; got {dims!r}")
    if form not in ("wide", "long"):
        raise OptionError(f"--form: expected 'wide' or 'long'; got {form!r}")
    declaration = []
    if capture.units is not None:
        declaration.append(f"units={capture.units}")
    declaration.append(f"rate={format_number(capture.rate)}")
    axes = "xyz"[:dims]
    frames = [str(capture.start_frame + f) for f in range(capture.n_frames)]
    positions = capture.positions[:, :, :dims]
    from ..fileutil import atomic_path

    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as out:
        out.write("# " + " ".join(declaration) + "\n")
        writer = csv.writer(out, lineterminator="\n")
        if form == "wide":
            writer.writerow(["frame"] + [f"{name}_{a}" for name in capture.names for a in axes])
            for frame, row in zip(frames, positions.reshape(capture.n_frames, -1).tolist()):
                out.write(frame + "," + join_numbers(row, ",") + "\n")
        else:
            writer.writerow(["frame", "marker"] + list(axes))
            quoted_names = [_quote(n) for n in capture.names]
            for frame, per_marker in zip(frames, positions.tolist()):
                for name, xyz in zip(quoted_names, per_marker):
                    out.write(frame + "," + name + "," + join_numbers(xyz, ",") + "\n")


# -- helpers ------------------------------------------------------------------------------------

def _quote(name: str) -> str:
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="").writerow([name])
    return buffer.getvalue()


def _read_declaration(lines: list[str], source: str) -> tuple[dict, int]:
    """Parse the optional ``# units=.. rate=..`` first line; return (values, index of next line)."""
    if not lines or not lines[0].lstrip().startswith("#"):
        return {}, 0
    declared = {}
    for item in lines[0].lstrip()[1:].split():
        key, sep, value = item.partition("=")
        key = key.strip().lower()
        if not sep or key not in _DECLARATION_KEYS:
            raise FormatError(f"{source}, line 1: cannot read {item!r} in the declaration line; "
                              f"expected '# units=<unit> rate=<Hz>' (keys: {', '.join(_DECLARATION_KEYS)})")
        if key == "units":
            unit = unit_from_text(value)
            if unit is None:
                raise FormatError(f"{source}, line 1: unknown unit {value!r}; expected one of {', '.join(METERS_PER_UNIT)}")
            declared["units"] = unit
        else:
            try:
                hz = float(value)
            except ValueError:
                hz = float("nan")
            if not (math.isfinite(hz) and hz > 0):
                raise FormatError(f"{source}, line 1: rate must be a positive number of Hz; got {value!r}")
            declared["rate"] = hz
    return declared, 1


def _wide_header(header: list[str], line: int, source: str) -> tuple[list[str], int]:
    names, axes = [], []
    for column in header[1:]:
        m = _COORD.match(column)
        if not m:
            raise FormatError(f"{source}, line {line}: column {column!r} is not '<Marker>_x', '<Marker>_y' or "
                              f"'<Marker>_z' (or use the long form 'frame,marker,x,y[,z]')")
        names.append(m.group(1))
        axes.append(m.group(2).lower())
    if not names:
        raise MarkerError(f"{source}, line {line}: the header names zero markers")
    dims = 3 if "z" in axes else 2
    expected = list("xyz"[:dims])
    if len(axes) % dims:
        raise FormatError(f"{source}, line {line}: {len(axes)} coordinate columns is not a whole number of "
                          f"{dims}D markers")
    marker_names = []
    for i in range(0, len(axes), dims):
        group_names, group_axes = names[i:i + dims], axes[i:i + dims]
        if group_axes != expected or len(set(group_names)) != 1:
            columns = ",".join(header[1 + i:1 + i + dims])
            raise FormatError(f"{source}, line {line}: columns {columns!r} should be "
                              f"{','.join(group_names[0] + '_' + a for a in expected)!r}: every marker needs "
                              f"{'/'.join(expected)} columns in that order")
        marker_names.append(group_names[0])
    seen, dups = set(), []
    for n in marker_names:
        if n in seen:
            dups.append(n)
        seen.add(n)
    if dups:
        raise MarkerError(f"{source}, line {line}: duplicate marker names: {list_names(sorted(set(dups)))}")
    return marker_names, dims


def _frames(cells: list[str], lines: list[int], source: str, rate: float, kind: str) -> np.ndarray:
    """Integer time codes from the frame or time column."""
    try:
        values = np.array([c.strip() for c in cells], dtype=np.float64)
    except ValueError:
        values = None
    if values is None or not np.isfinite(values).all():
        for c, line in zip(cells, lines):
            try:
                ok = math.isfinite(float(c))
            except ValueError:
                ok = False
            if not ok:
                raise FormatError(f"{source}, line {line}: {kind} {c.strip()!r} is not a number")
    far = np.flatnonzero(np.abs(values * (rate if kind == "time" else 1.0)) > MAX_TIME_CODE)
    if far.size:
        i = int(far[0])
        raise FormatError(f"{source}, line {lines[i]}: {kind} {cells[i].strip()} is beyond the time codes usdface "
                          f"stores (frames within +-{MAX_TIME_CODE:,})")
    if kind == "frame":
        frames = np.rint(values)
        bad = np.flatnonzero(frames != values)
        if bad.size:
            raise FormatError(f"{source}, line {lines[bad[0]]}: frame {cells[bad[0]].strip()!r} is not an integer")
    else:
        exact = values * rate
        frames = np.rint(exact)
        bad = np.flatnonzero(np.abs(exact - frames) > CSV_TIME_TOLERANCE)
        if bad.size:
            i = bad[0]
            raise FormatError(f"{source}, line {lines[i]}: time {cells[i].strip()} s is {exact[i]:.3f} frames at "
                              f"{rate:g} Hz, not a whole frame (tolerance {CSV_TIME_TOLERANCE} frame): wrong rate?")
    return frames.astype(np.int64)


def _long_form(body, lines, header, source, rate, kind):
    dims = len(header) - 2
    frames = _frames([r[0] for r in body], lines, source, rate, kind)
    marker_column = np.array([r[1].strip() for r in body])
    empty = np.flatnonzero(marker_column == "")
    if empty.size:
        raise FormatError(f"{source}, line {lines[empty[0]]}: empty marker name")
    unique, first_row, inverse = np.unique(marker_column, return_index=True, return_inverse=True)
    appearance = np.argsort(first_row, kind="stable")      # unique index -> rank by first appearance
    rank = np.empty_like(appearance)
    rank[appearance] = np.arange(appearance.size)
    marker_index = rank[inverse]
    names = [str(n) for n in unique[appearance]]
    values = cells_to_float([r[2:] for r in body], source=source, first_line=lines[0], columns=header[2:])
    check_float32_cells(values, source=source, lines=lines, columns=header[2:])
    key = (frames - frames.min()) * len(names) + marker_index
    order = np.argsort(key, kind="stable")
    dup = np.flatnonzero(np.diff(key[order]) == 0)
    if dup.size:
        i = order[dup[0] + 1]
        raise FormatError(f"{source}, line {lines[i]}: marker {names[marker_index[i]]!r} at frame {frames[i]} "
                          f"is listed twice")
    return names, frames, (marker_index, values), dims
