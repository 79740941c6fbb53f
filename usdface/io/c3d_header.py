"""What a C3D file announces (header and parameter section), read before ezc3d reads the data.

ezc3d trusts the counts: an ``ANALOG:RATE`` of 1e9 Hz in a 15 kB file made it allocate 12 GB and
run for over a minute. This module reads the 512-byte header and the ``POINT`` and ``ANALOG``
parameters with :mod:`struct` (no ezc3d), so :func:`usdface.io.c3d.read_c3d` can compare what
the file announces with its size, and the memory it needs with what the machine has, first.

Layout (C3D format): byte 0 is the first parameter block (1-based, 512-byte blocks), byte 1 is
0x50; 16-bit words: 2 the number of 3D points, 3 the analog values per frame, 4-5 the first and
last frame (1-based), 7-8 the scale factor (float; negative: float32 data), 9 the first data
block, 11-12 the frame rate (float). The parameter section starts with 4 bytes (the fourth the
processor: 84 Intel, 85 DEC, 86 MIPS big-endian), then groups and parameters: name length (int8,
negative when locked), id (int8; negative for a group), name, offset to the next entry (int16),
then for a parameter its type (-1 char, 1 byte, 2 int16, 4 float), dimensions and data.
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from pathlib import Path

from ..errors import FormatError

__all__ = ["C3DLayout", "read_layout"]

#: analog samples per point frame beyond this are not a C3D file's (force plates: 10-20 x the rate)
MAX_ANALOG_RATIO = 1000.0


@dataclass(frozen=True)
class C3DLayout:
    """What a C3D file announces: counts and where its data lie."""

    points: int
    frames: int
    analog_channels: int
    analog_ratio: float          # analog samples per point frame
    data_start: int              # first data block, 1-based
    word: int                    # bytes per value: 4 (float) or 2 (int16)
    point_rate: float | None

    @property
    def data_bytes(self) -> int:
        """Bytes the data section needs (points: x, y, z, residual; then the analog values)."""
        per_frame = self.word * (4 * self.points + math.ceil(self.analog_ratio * self.analog_channels))
        return (self.data_start - 1) * 512 + self.frames * per_frame


def _vax_float(raw: bytes) -> float:
    """A DEC (VAX F) float as stored in a C3D file of processor type 85: its 16-bit halves
    swapped give an IEEE float four times too large."""
    return struct.unpack("<f", raw[2:4] + raw[0:2])[0] / 4.0


def _parameters(data: bytes, source: str) -> tuple[dict, str, int]:
    """``{(GROUP, NAME): (type, dims, offset)}`` of a parameter section (``data`` starts at its
    first byte), the byte order and the processor type. Parsing stops at the first entry that
    does not fit; what was read until then is kept."""
    if len(data) < 4:
        raise FormatError(f"{source}: the header points to a parameter section beyond the end of the file")
    processor = data[3]
    order = ">" if processor == 86 else "<"
    end = len(data)
    groups, params, pos = {}, {}, 4
    while pos + 4 <= end:
        nchar, gid = struct.unpack_from("bb", data, pos)
        if nchar == 0:
            break
        name_end = pos + 2 + abs(nchar)
        if name_end + 2 > end:
            break
        name = data[pos + 2:name_end].decode("ascii", "replace").upper()
        step = struct.unpack_from(order + "h", data, name_end)[0]
        body = name_end + 2
        if gid < 0:
            groups[-gid] = name
        elif body + 2 <= end:
            kind, ndim = struct.unpack_from("bB", data, body)
            dims = tuple(data[body + 2:body + 2 + ndim])
            params[(gid, name)] = (kind, dims, body + 2 + ndim)
        if step <= 0:
            break
        pos = name_end + step
    named = {(groups.get(g, str(g)), n): v for (g, n), v in params.items()}
    return named, order, processor


def _number(data: bytes, params: dict, key: tuple, order: str, processor: int) -> float | None:
    """The first value of a numeric parameter, or None when absent or unreadable."""
    if key not in params:
        return None
    kind, _, offset = params[key]
    size = {1: 1, 2: 2, 4: 4}.get(abs(kind))
    if size is None or kind < 0 or offset + size > len(data):
        return None
    raw = data[offset:offset + size]
    if kind == 1:
        return float(raw[0])
    if kind == 2:
        return float(struct.unpack(order + "H", raw)[0])  # counts above 32767 are written unsigned
    return _vax_float(raw) if processor == 85 else struct.unpack(order + "f", raw)[0]


def read_layout(path: Path, source: str) -> C3DLayout:
    """Read what a C3D file announces; FormatError when it is not a C3D file or its counts are
    impossible (an analog rate a million times the point rate)."""
    with open(path, "rb") as handle:
        head = handle.read(512)
        if len(head) < 512 or head[1] != 0x50 or head[0] == 0:
            raise FormatError(f"{source}: not a C3D file (no C3D header: byte 2 must be 0x50)")
        base = (head[0] - 1) * 512
        handle.seek(base)
        block = handle.read(4)
        blocks = block[2] if len(block) == 4 else 1
        handle.seek(base)
        section = handle.read(512 * max(blocks, 1))
    params, order, processor = _parameters(section, source)
    words = struct.unpack(order + "10H", head[2:22])
    scale = _vax_float(head[12:16]) if processor == 85 else struct.unpack(order + "f", head[12:16])[0]
    get = lambda group, name: _number(section, params, (group, name), order, processor)  # noqa: E731
    points = int(get("POINT", "USED") if get("POINT", "USED") is not None else words[0])
    first, last = words[2], words[3]
    frames = last - first + 1 if last >= first else 0
    declared = get("POINT", "FRAMES")
    if declared is not None and math.isfinite(declared):
        frames = max(frames, int(declared))
    data_start = int(get("POINT", "DATA_START") or words[7] or 1)
    point_scale = get("POINT", "SCALE")
    word = 4 if (point_scale if point_scale is not None else scale) < 0 else 2
    point_rate = get("POINT", "RATE")
    channels = int(get("ANALOG", "USED") or 0)
    analog_rate = get("ANALOG", "RATE")
    ratio = 0.0
    if analog_rate is not None and point_rate:
        ratio = analog_rate / point_rate
        if not (math.isfinite(ratio) and 0 <= ratio <= MAX_ANALOG_RATIO):
            raise FormatError(f"{source}: ANALOG:RATE {analog_rate:g} Hz is {ratio:.3g} times POINT:RATE "
                              f"{point_rate:g} Hz; analog channels run at a small multiple of the point rate (at "
                              f"most {MAX_ANALOG_RATIO:g}x): the file is corrupt")
    elif words[1]:  # no ANALOG:RATE: the header's analog values per frame
        ratio, channels = words[1] / max(channels, 1), max(channels, 1)
    return C3DLayout(points=points, frames=frames, analog_channels=channels, analog_ratio=ratio,
                     data_start=data_start, word=word, point_rate=point_rate)
