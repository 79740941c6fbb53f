"""Size checks of mesh files against the counts their headers announce, before pymeshlab reads them.

pymeshlab (vcglib) trusts a file's header: a binary STL whose 80-byte header announces 1e6
triangles but holds 50 bytes is parsed as ASCII and spins for ever (SIGTERM cannot interrupt the
C++ call); a PLY announcing 1e9 vertices allocates them first. These checks read only the header
(and, for ASCII STL, count keywords) and refuse such a file with one line naming it, what the
header announces and what the file holds. A file whose counts are consistent with its size is
then checked against the memory its counts need (:func:`usdface.memory.check_memory`).
"""
from __future__ import annotations

import re
import struct
from pathlib import Path

from ..errors import FormatError

__all__ = ["check_mesh_file", "memory_estimate", "MESH_BYTES_PER_VERTEX", "MESH_BYTES_PER_FACE"]

#: memory pymeshlab and the reader hold per vertex and per face at their peak (vcglib's vertex and
#: face records, the polygon list and usdface's arrays; measured order of magnitude, rounded up)
MESH_BYTES_PER_VERTEX = 200
MESH_BYTES_PER_FACE = 200

_STL_HEADER = 84
_STL_TRIANGLE = 50
_PLY_TYPES = {"char": 1, "int8": 1, "uchar": 1, "uint8": 1, "short": 2, "int16": 2, "ushort": 2, "uint16": 2,
              "int": 4, "int32": 4, "uint": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}
_MAX_PLY_HEADER = 1 << 20
_MAX_COUNT = 2 ** 31 - 1  # vcglib counts are int


def check_mesh_file(path: Path, *, label: str) -> tuple[int, int] | None:
    """Check a mesh file that pymeshlab will read against its header's counts.

    Returns (vertices, faces) announced by the header (faces: triangles for STL), or None for a
    format whose header says nothing checkable. Raises FormatError naming the file, the counts
    and the size when they disagree.
    """
    suffix = path.suffix.lower()
    size = path.stat().st_size
    if size == 0:
        raise FormatError(f"{label}: the file is empty (0 bytes)")
    if suffix == ".stl":
        return _check_stl(path, size, label)
    if suffix == ".ply":
        return _check_ply(path, size, label)
    if suffix == ".off":
        return _check_binary_off(path, size, label)
    return None


def _check_stl(path: Path, size: int, label: str) -> tuple[int, int]:
    with open(path, "rb") as handle:
        head = handle.read(_STL_HEADER)
    announced = struct.unpack("<I", head[80:84])[0] if len(head) == _STL_HEADER else None
    if announced is not None and size == _STL_HEADER + _STL_TRIANGLE * announced:
        return 3 * announced, announced  # binary (pymeshlab merges the corners)
    binary = (f"the binary header announces {announced:,} triangles ({_STL_HEADER + _STL_TRIANGLE * announced:,} "
              f"bytes), but the file has {size:,} bytes" if announced is not None else
              f"a binary STL has at least {_STL_HEADER} bytes, the file {size:,}")
    if not head.lstrip().lower().startswith(b"solid"):
        raise FormatError(f"{label}: not a complete STL file: {binary}")
    problem, facets = _ascii_stl_problem(path)
    if problem:
        raise FormatError(f"{label}: not a complete STL file: as ASCII STL {problem}; as binary STL {binary}")
    return 3 * facets, facets


def _ascii_stl_problem(path: Path) -> tuple[str | None, int]:
    """(what is wrong with an ASCII STL, facet count): keywords must pair up and the file end
    with ``endsolid``; ASCII STL is 7-bit text."""
    data = path.read_bytes()
    if any(b > 127 for b in data[:4096]) or b"\0" in data:
        return "it holds binary bytes", 0
    text = data.lower()
    facets, ends = text.count(b"facet normal"), text.count(b"endfacet")
    vertices, loops = len(re.findall(rb"(?m)^\s*vertex\s", text)), text.count(b"endloop")
    if facets == 0:
        return "it has no 'facet normal'", 0
    if not (facets == ends == loops and vertices == 3 * facets):
        return (f"it has {facets:,} 'facet normal', {ends:,} 'endfacet', {loops:,} 'endloop' and {vertices:,} "
                f"'vertex' lines (3 per facet expected): truncated or malformed"), 0
    if b"endsolid" not in text[-256:]:
        return "it does not end with 'endsolid': truncated", 0
    return None, facets


def _ply_header(path: Path, label: str) -> tuple[str, list, int]:
    """(format, elements [(name, count, properties)], header bytes) of a PLY file."""
    with open(path, "rb") as handle:
        head = handle.read(_MAX_PLY_HEADER)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise FormatError(f"{label}: not a PLY file (no 'ply' ... 'end_header' header in its first "
                          f"{_MAX_PLY_HEADER // 1024} KB)")
    stop = head.find(b"\n", end)
    header_bytes = len(head) if stop < 0 else stop + 1
    fmt, elements = None, []
    for number, raw in enumerate(head[:end].decode("ascii", "replace").splitlines(), 1):
        words = raw.split()
        if not words or words[0] in ("comment", "obj_info", "ply"):
            continue
        try:
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element":
                count = int(words[2])
                if not 0 <= count <= _MAX_COUNT:
                    raise ValueError
                elements.append((words[1], count, []))
            elif words[0] == "property":
                if words[1] == "list":
                    elements[-1][2].append(("list", _PLY_TYPES[words[2]], _PLY_TYPES[words[3]]))
                else:
                    elements[-1][2].append(("scalar", _PLY_TYPES[words[1]], 0))
        except (IndexError, ValueError, KeyError):
            raise FormatError(f"{label}: PLY header line {number} {raw.strip()[:60]!r} is malformed "
                              f"(counts are whole numbers 0..{_MAX_COUNT:,}; types: {', '.join(_PLY_TYPES)})") from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise FormatError(f"{label}: PLY format {fmt!r} is not ascii, binary_little_endian or binary_big_endian")
    return fmt, elements, header_bytes


def _check_ply(path: Path, size: int, label: str) -> tuple[int, int]:
    fmt, elements, header_bytes = _ply_header(path, label)
    counts = {name: count for name, count, _ in elements}
    announced = ", ".join(f"'element {name} {count}'" for name, count, _ in elements)
    if fmt == "ascii":
        lines = 0
        with open(path, "rb") as handle:
            handle.seek(header_bytes)
            for block in iter(lambda: handle.read(1 << 20), b""):
                lines += block.count(b"\n")
        needed = sum(count for _, count, _ in elements)
        if lines + 1 < needed:  # one entry per line (the last may lack its newline)
            raise FormatError(f"{label}: the PLY header announces {announced} ({needed:,} lines) but the file has "
                              f"{lines + 1:,} lines after its header: truncated or not what it claims")
    else:
        # a scalar needs its size, a list at least its count (an empty list)
        needed = header_bytes + sum(count * sum(nbytes for _, nbytes, _ in props) for _, count, props in elements)
        if size < needed:
            raise FormatError(f"{label}: the PLY header announces {announced} (at least {needed:,} bytes) but the "
                              f"file has {size:,} bytes: truncated or not what it claims")
    return counts.get("vertex", 0), counts.get("face", 0)


def _check_binary_off(path: Path, size: int, label: str) -> tuple[int, int] | None:
    """Binary OFF (``OFF BINARY``, then big-endian int32 counts); ASCII OFF is read by usdface itself."""
    with open(path, "rb") as handle:
        head = handle.read(256)
    first = head.split(b"\n", 1)[0]
    if b"BINARY" not in first.upper():
        return None
    counts = head[len(first) + 1:len(first) + 13]
    if len(counts) < 12:
        raise FormatError(f"{label}: binary OFF header is cut short (no vertex/face/edge counts)")
    nv, nf, _ = struct.unpack(">iii", counts)
    if nv < 0 or nf < 0:
        raise FormatError(f"{label}: binary OFF header announces {nv} vertices and {nf} faces; counts are >= 0")
    needed = len(first) + 13 + 12 * nv + 20 * nf  # xyz float32; a triangle: count, 3 indices, colour count
    if size < needed:
        raise FormatError(f"{label}: the binary OFF header announces {nv:,} vertices and {nf:,} faces (at least "
                          f"{needed:,} bytes) but the file has {size:,} bytes: truncated or not what it claims")
    return nv, nf


def memory_estimate(counts: tuple[int, int] | None) -> int:
    """Bytes reading a mesh of (vertices, faces) holds at its peak (an estimate)."""
    if not counts:
        return 0
    vertices, faces = counts
    return vertices * MESH_BYTES_PER_VERTEX + faces * MESH_BYTES_PER_FACE
