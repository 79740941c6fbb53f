"""Capture file formats behind one interface, chosen by suffix.

``read_capture(path) -> Capture`` and ``write_capture(path, capture)`` dispatch on the file suffix
(case-insensitive) to one reader/writer module per format:

========  ===================================  =========  ======================================
suffix    module                               writable   source up axis (default)
========  ===================================  =========  ======================================
``.ma``   :mod:`usdface.io.maya_ascii`         no         Y
``.c3d``  :mod:`usdface.io.c3d`                yes        Z (rotated to Y-up on import)
``.trc``  :mod:`usdface.io.trc`                yes        Y
``.csv``  :mod:`usdface.io.csv_format`         yes        Y
========  ===================================  =========  ======================================

Every reader returns a Y-up :class:`~usdface.capture.Capture` with positions in the file's own
linear unit (never rescaled), NaN for invalid samples, ``source`` set to the path as given and one
history step ``{"step": "read", "format": ..., ...}``.

Format modules are imported on first use, so a missing optional dependency (ezc3d for C3D) fails
only when that format is used. The helpers at the bottom (file checks, unit names, option
resolution) are shared by the format modules so that every reader words its errors the same way.
"""
from __future__ import annotations

import importlib
import math
import os
from pathlib import Path

import numpy as np

from ..model.capture import Capture
from ..errors import FormatError, InputError, OptionError
from ..inputfiles import FLOAT32_MAX, check_input_file as _check_input_file, first_beyond_float32
from ..units import METERS_PER_UNIT

#: suffix -> (module, reader function, writer function or None, default source up axis)
_FORMATS = {
    ".ma": ("usdface.io.maya_ascii", "read_maya_ascii", None, "Y"),
    ".c3d": ("usdface.io.c3d", "read_c3d", "write_c3d", "Z"),
    ".trc": ("usdface.io.trc", "read_trc", "write_trc", "Y"),
    ".csv": ("usdface.io.csv_format", "read_csv", "write_csv", "Y"),
}

#: suffixes :func:`read_capture` understands (lower case, with the dot)
CAPTURE_SUFFIXES: tuple[str, ...] = tuple(_FORMATS)

#: suffixes :func:`write_capture` can write
WRITABLE_CAPTURE_SUFFIXES: tuple[str, ...] = tuple(s for s, f in _FORMATS.items() if f[2])


def _format_for(path, suffixes) -> tuple:
    suffix = Path(os.fspath(path)).suffix.lower()
    if suffix not in suffixes:
        shown = suffix or "no suffix"
        raise InputError(
            f"{os.fspath(path)}: unknown capture file type ({shown}); known suffixes: {', '.join(suffixes)}"
        )
    return _FORMATS[suffix]


def read_capture(path, *, units: str | None = None, rate: float | None = None,
                 up_axis: str | None = None, keep_zeros: bool = False, allow=frozenset()) -> Capture:
    """Read a marker capture file, choosing the reader by suffix.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.ma``, ``.c3d``, ``.trc`` or ``.csv`` file (suffix case-insensitive).
    units : str, optional
        Linear unit of the file's positions (``"mm"``, ``"cm"``, ``"m"``, ``"in"``, ``"ft"``...).
        Required when the file does not declare one (CSV without a ``# units=`` line); an error
        when it contradicts the file's declaration. Positions are never rescaled.
    rate : float, optional
        Capture rate in Hz. Required when the file does not declare one; an error when it
        contradicts the file's declaration. For Maya ASCII it chooses the sampling grid
        (default: the key spacing).
    up_axis : {"Y", "Z"}, optional
        Up axis of the SOURCE data; None takes the format's convention (Z for C3D, Y for the
        others). Z-up data is rotated to Y-up: (x, y, z) -> (x, z, -y).
    keep_zeros : bool
        C3D only: keep samples at exactly (0, 0, 0) as positions (default: they are gaps, the
        usual C3D gap code; see :mod:`usdface.io.c3d`).
    allow : set of str
        Plausibility codes the reader accepts (``rate``, ``frame-count``; see
        :mod:`usdface.io.limits`): the readers judge a capture's rate and frame numbers
        before they allocate anything.

    Returns
    -------
    Capture
        Y-up, positions (F, M, 3) float64 in ``units``, NaN where invalid.

    Raises
    ------
    InputError
        Missing or unreadable file, unknown suffix.
    FormatError
        Truncated or malformed content (the message names the file and, where known, the line).
    MarkerError
        Zero markers or frames, duplicate marker names, a marker without any valid sample.
    OptionError
        A missing or conflicting ``units``/``rate``, a bad ``up_axis``.
    PlausibilityError
        An implausible rate or frame count not accepted by ``allow``.
    ResourceError
        The capture's frames would not fit in memory.
    """
    module_name, reader_name, _, default_up = _format_for(path, CAPTURE_SUFFIXES)
    up = check_up_axis(up_axis)
    reader = getattr(importlib.import_module(module_name), reader_name)
    if module_name.endswith(".maya_ascii"):
        # Maya scenes carry their own up axis convention (Y); an explicit Z override still applies.
        capture = reader(path, units=units, rate=rate, allow=allow)
        if up == "Z":
            capture = capture.replace(positions=z_up_to_y_up(capture.positions))
    elif module_name.endswith(".c3d"):
        capture = reader(path, units=units, rate=rate, up_axis=up or default_up, keep_zeros=keep_zeros, allow=allow)
    else:
        capture = reader(path, units=units, rate=rate, up_axis=up or default_up, allow=allow)
    return capture


def write_capture(path, capture: Capture) -> Path:
    """Write ``capture`` to a ``.csv``, ``.trc`` or ``.c3d`` file chosen by suffix.

    Positions are written as they are (Y-up; C3D files get the Z-up convention of the format by
    the inverse of the import rotation, so a read gives back the same capture). Returns the path.
    """
    module_name, _, writer_name, _ = _format_for(path, WRITABLE_CAPTURE_SUFFIXES)
    writer = getattr(importlib.import_module(module_name), writer_name)
    writer(path, capture)
    return Path(os.fspath(path))


# -- shared helpers for the format modules ------------------------------------------------------

#: frame numbers (time codes) a capture may have: USD stores time codes as doubles, usdface's
#: frame arithmetic as int64; a frame number beyond this is a corrupt value, not a take
MAX_TIME_CODE = 2**31 - 1


def check_input_file(path) -> Path:
    """Return ``path`` as a Path if it is a readable regular file, else raise InputError
    (named pipes, devices, sockets and folders named as such: :func:`usdface.inputfiles.check_input_file`)."""
    return _check_input_file(path)


def check_float32_cells(table: np.ndarray, *, source, lines: list[int], columns: list[str]) -> None:
    """FormatError naming the line and column of the first value of ``table`` (rows x columns)
    beyond float32's finite range (inf included; NaN is an invalid sample)."""
    at = first_beyond_float32(table)
    if at is None:
        return
    row, col = at
    name = f"column {columns[col]!r}" if col < len(columns) else f"column {col + 1}"
    raise FormatError(f"{os.fspath(source)}, line {lines[row]}: {name}: {table[row, col]:g} is beyond the range of the "
                      f"float32 positions USD stores (|x| <= {FLOAT32_MAX:.4g}); an invalid sample is an empty "
                      f"cell or NaN")


def read_text(path) -> str:
    """Read a text file (UTF-8, falling back to Latin-1 for older Windows code pages)."""
    p = check_input_file(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise InputError(f"{os.fspath(path)}: cannot read file: {exc.strerror or exc}") from None
    try:
        return data.decode("utf-8-sig")  # a BOM (Excel CSV) is not part of the text
    except UnicodeDecodeError:
        return data.decode("latin-1")


_UNIT_ALIASES = {
    "mm": "mm", "millimeter": "mm", "millimeters": "mm", "millimetre": "mm", "millimetres": "mm",
    "cm": "cm", "centimeter": "cm", "centimeters": "cm", "centimetre": "cm", "centimetres": "cm",
    "dm": "dm", "decimeter": "dm", "decimeters": "dm", "decimetre": "dm", "decimetres": "dm",
    "m": "m", "meter": "m", "meters": "m", "metre": "m", "metres": "m",
    "in": "in", "inch": "in", "inches": "in",
    "ft": "ft", "foot": "ft", "feet": "ft",
}


def unit_from_text(text: str) -> str | None:
    """Map a unit name as files write it (``"mm"``, ``"Millimeters"``, ``"centimeter"``) to
    usdface's unit name, or None if it is not one usdface knows."""
    return _UNIT_ALIASES.get(text.strip().lower())


def check_units_option(units: str | None) -> str | None:
    """Validate a ``units=`` option (usdface unit names, or their long spellings)."""
    if units is None:
        return None
    name = unit_from_text(str(units))
    if name is None:
        raise OptionError(f"--units: unknown unit {units!r}; expected one of {', '.join(METERS_PER_UNIT)}")
    return name


def check_rate_option(rate) -> float | None:
    """Validate a ``rate=`` option: a positive finite number of Hz."""
    if rate is None:
        return None
    try:
        value = float(rate)
    except (TypeError, ValueError):
        raise OptionError(f"--rate: expected a positive number of Hz; got {rate!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise OptionError(f"--rate: expected a positive number of Hz; got {rate!r}")
    return value


def check_up_axis(up_axis: str | None) -> str | None:
    """Validate an ``up_axis=`` option: ``"Y"``, ``"Z"`` (either case) or None."""
    if up_axis is None:
        return None
    value = str(up_axis).upper()
    if value not in ("Y", "Z"):
        raise OptionError(f"--up-axis: expected 'Y' or 'Z'; got {up_axis!r}")
    return value


def resolve_units(declared: str | None, option: str | None, *, source) -> str:
    """Pick the capture's unit from the file's declaration and the ``units=`` option.

    The option supplies what the file lacks; it must agree with a declaration when both exist.
    """
    option = check_units_option(option)
    if declared is not None and option is not None and declared != option:
        raise OptionError(
            f"{os.fspath(source)}: the file declares units {declared!r} but --units {option!r} was given; "
            f"positions are not rescaled on import: drop the option or fix the file"
        )
    unit = declared if declared is not None else option
    if unit is None:
        raise OptionError(f"{os.fspath(source)}: the file does not declare its linear units; pass --units "
                          f"(units=...), one of {', '.join(METERS_PER_UNIT)}")
    return unit


def resolve_rate(declared: float | None, option, *, source, rel_tol: float = 1e-6) -> float:
    """Pick the capture rate from the file's declaration and the ``rate=`` option (Hz)."""
    option = check_rate_option(option)
    if declared is not None and option is not None and not math.isclose(declared, option, rel_tol=rel_tol):
        raise OptionError(
            f"{os.fspath(source)}: the file declares a rate of {declared:g} Hz but --rate {option:g} was given; "
            f"drop the option or fix the file"
        )
    rate = declared if declared is not None else option
    if rate is None:
        raise OptionError(f"{os.fspath(source)}: the file does not declare its capture rate; pass --rate (rate=..., Hz)")
    return float(rate)


def z_up_to_y_up(positions: np.ndarray) -> np.ndarray:
    """Rotate Z-up points to Y-up: (x, y, z) -> (x, z, -y), shape (..., 3)."""
    p = np.asarray(positions, dtype=np.float64)
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)


def y_up_to_z_up(positions: np.ndarray) -> np.ndarray:
    """Inverse of :func:`z_up_to_y_up`: (x, y, z) -> (x, -z, y), shape (..., 3)."""
    p = np.asarray(positions, dtype=np.float64)
    return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)


def format_number(value: float) -> str:
    """Shortest text that reads back as the same float (``60.0`` -> ``"60"``); NaN -> ``""``."""
    if value != value:
        return ""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def join_numbers(values: list[float], separator: str) -> str:
    """Shortest round-trip decimal text of floats joined by ``separator``; NaN -> empty cell.

    (The repr of a list formats its floats in C, several times faster than one by one.)
    """
    return repr(values)[1:-1].replace(" ", "").replace("nan", "").replace(",", separator)


def cells_to_float(rows: list[list[str]], *, source, first_line: int, columns: list[str] | None = None) -> np.ndarray:
    """Convert a rectangular table of text cells to float64; empty cells and NaN -> NaN.

    ``first_line`` is the file line number of ``rows[0]``; a bad cell raises FormatError naming its
    line and column (by header name when ``columns`` is given).
    """
    if not rows:
        return np.empty((0, 0))
    width = len(rows[0])
    nan = math.nan
    try:
        # fast path: cells are numbers, "nan" or exactly empty
        values = [float(c) if c else nan for row in rows for c in row]
    except ValueError:
        values = []
        for i, row in enumerate(rows):
            for j, cell in enumerate(row):
                text = cell.strip()
                try:
                    values.append(float(text) if text else nan)
                except ValueError:
                    col = f"column {columns[j]!r}" if columns and j < len(columns) else f"column {j + 1}"
                    raise FormatError(
                        f"{os.fspath(source)}, line {first_line + i}: {col}: {cell!r} is not a number"
                    ) from None
    return np.array(values, dtype=np.float64).reshape(len(rows), width)
