"""What `lift` reads: 2D marker tracks from a track layer, a capture layer holding 2D data, or a
usdface 2D CSV (pixels)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.capture import Capture
from ..errors import InputError, OptionError
from .layers import USD_SUFFIXES, describe, is_in_memory

__all__ = ["read_tracks"]


def read_tracks(source, *, rate: float | None = None) -> Capture:
    """2D tracks (a Capture in pixels, z = 0) from a track layer (.usd*, or in memory an
    ``Sdf.Layer`` / ``Usd.Stage``), a capture layer of 2D data, or a 2D capture CSV (``rate``:
    the CSV's rate when it does not declare one).

    Raises
    ------
    InputError
        No such file, an unknown kind of file, or 3D data.
    """
    if is_in_memory(source):
        capture = _read_layer(source)
        name = describe(source)
    else:
        p = Path(source)
        name = p
        if not p.is_file():
            raise InputError(f"tracks {p}: no such file")
        suffix = p.suffix.lower()
        if suffix in USD_SUFFIXES:
            capture = _read_layer(p)
        elif suffix == ".csv":
            capture = _read_csv(p, rate)
        else:
            raise InputError(f"tracks {p}: expected a track layer ({', '.join(USD_SUFFIXES)}) or a 2D CSV")
    dims = next((int(h["dims"]) for h in capture.history if "dims" in h), None)
    z = capture.positions[..., 2]
    if dims == 3 or (dims is None and np.nanmax(np.abs(z)) > 0):
        raise InputError(f"tracks {name}: the tracks are 3D; `usdface lift` takes 2D image tracks "
                         "(import 3D capture with `usdface import-capture`)")
    return capture


def _read_layer(source) -> Capture:
    from .capture_layer import read_capture_layer
    from .track_layer import read_track_layer

    try:
        capture, _ = read_track_layer(source)
    except InputError:
        capture = read_capture_layer(source)  # a capture layer of 2D data also holds tracks
    return capture


def _read_csv(path: Path, rate) -> Capture:
    from ..io.csv_format import read_csv

    try:
        return read_csv(path, rate=rate)
    except OptionError as exc:
        if "units" not in str(exc):
            raise
        return read_csv(path, units="cm", rate=rate)  # pixel tracks declare no length unit
