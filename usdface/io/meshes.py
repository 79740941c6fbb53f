"""Read polygon meshes (OBJ, PLY, OFF, STL and other formats pymeshlab reads) into a FaceMesh.

What is kept
------------
- **Vertex order**: vertex ``i`` of the file is point ``i`` (data such as expression shapes or
  marker layouts index the file's vertices). Unreferenced vertices are kept.
- **Polygons**: quads stay quads, n-gons stay n-gons, each starting at the same vertex as in the
  file, so :meth:`FaceMesh.triangles` splits them along the file's own first diagonal.
- **UVs** when the file has them, face-varying (``uvs`` + ``uv_indices``).

How
---
- ``.obj`` and ASCII ``.off`` are parsed here. pymeshlab triangulates polygons on load;
  ``Mesh.polygonal_face_list()`` gives the polygons back, but for OBJ each polygon comes back
  rotated (starting at another vertex: 0 of the 1934 MakeHuman quads matched the file), OBJ
  face-varying UVs come back per triangle corner only, and for OFF pymeshlab re-triangulates quads
  along the shorter diagonal so even the first triangle does not tell the start vertex. Both
  formats are simple text formats, so reading them here is both exact and as fast.
- Every other suffix in :data:`MESH_SUFFIXES` goes through pymeshlab; each polygon of
  ``polygonal_face_list()`` is rotated to start at the first vertex of its first triangle, which
  reproduces the file's polygons exactly for PLY (verified on the MakeHuman quads). STL stores no
  shared vertices: pymeshlab merges coincident corners, so "vertex order" there means pymeshlab's.

Units
-----
Mesh files carry no units. ``units=`` wins; else a comment ``# Units: centimetres`` (OBJ/OFF)
or ``comment Units: cm`` (PLY header) is honoured; else the mesh is taken to be in centimetres
(``"cm"``), the unit of the sample meshes and of the AnimFace capture.
"""
from __future__ import annotations

import logging
import os
import re
from pathlib import Path

import numpy as np

from ..errors import FormatError, InputError, MeshError, OptionError
from ..inputfiles import FLOAT32_MAX, check_input_file, first_beyond_float32
from ..model.mesh import FaceMesh
from ..units import METERS_PER_UNIT

log = logging.getLogger("usdface")

__all__ = ["MESH_SUFFIXES", "DEFAULT_UNITS", "read_mesh"]

#: file suffixes :func:`read_mesh` accepts (lower case); all but .obj/.off are read by pymeshlab
MESH_SUFFIXES = (".obj", ".ply", ".off", ".stl", ".wrl", ".dae", ".x3d", ".3ds", ".ctm")

#: units assumed when neither ``units=`` nor a units comment in the file says otherwise
DEFAULT_UNITS = "cm"

_UNIT_WORDS = {
    "mm": "mm", "millimeter": "mm", "millimetre": "mm", "millimeters": "mm", "millimetres": "mm",
    "cm": "cm", "centimeter": "cm", "centimetre": "cm", "centimeters": "cm", "centimetres": "cm",
    "dm": "dm", "decimeter": "dm", "decimetre": "dm", "decimeters": "dm", "decimetres": "dm",
    "m": "m", "meter": "m", "metre": "m", "meters": "m", "metres": "m",
    "in": "in", "inch": "in", "inches": "in",
    "ft": "ft", "foot": "ft", "feet": "ft",
}
_UNITS_COMMENT = re.compile(r"^\s*(?:#|comment)\s*units?\s*[:=]\s*([A-Za-z]+)", re.IGNORECASE)


def read_mesh(path, *, units: str | None = None, check_degenerate: bool = True,
              other_suffixes: tuple = ()) -> FaceMesh:
    """Read a polygon mesh file, keeping vertex order, polygons and UVs.

    Parameters
    ----------
    path : str or os.PathLike
        Mesh file; its suffix (case-insensitive) picks the reader, see :data:`MESH_SUFFIXES`.
    units : str, optional
        Linear unit of the file's coordinates (``"mm"``, ``"cm"``, ``"m"``...). Default: a
        ``Units:`` comment in the file if there is one, else :data:`DEFAULT_UNITS` (``"cm"``).
    check_degenerate : bool
        Raise on polygons of zero area (default True).
    other_suffixes : tuple of str
        Suffixes the caller reads itself (USD layers: :func:`usdface.usd.inputs.load_mesh`), listed
        after :data:`MESH_SUFFIXES` in the unknown-suffix message.

    Returns
    -------
    FaceMesh
        ``points`` (N, 3) float64 in ``units``; ``face_vertex_counts`` (P,) and
        ``face_vertex_indices`` as in the file; ``uvs`` (K, 2) and ``uv_indices`` when the file has
        texture coordinates on every polygon corner; ``name`` = file stem; ``source`` = path.

    Raises
    ------
    InputError
        The file does not exist or is not a file; the suffix is not a mesh format.
    OptionError
        ``units`` is not a known unit name.
    FormatError
        The file is malformed or unreadable (the message names the file and, for OBJ/OFF, the line).
    MeshError
        The file has no faces, indices out of range, or degenerate (zero-area) faces.
    """
    path = Path(os.fspath(path))
    if units is not None and units not in METERS_PER_UNIT:
        raise OptionError(f"units: unknown unit {units!r} for {path}; expected one of {', '.join(METERS_PER_UNIT)}")
    label = f"mesh file {path}"
    check_input_file(path, label=label)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        known = ", ".join(MESH_SUFFIXES + tuple(other_suffixes))
        raise InputError(f"mesh file {path}: unknown suffix {path.suffix or '(none)'!r}; expected one of {known}")
    if suffix == ".obj":
        data = _read_obj(path, units_given=units is not None)
    elif suffix == ".off" and _is_ascii_off(path):
        data = _read_off(path, units_given=units is not None)
    else:
        data = _read_pymeshlab(path, label, units is not None)
    points, counts, indices, uvs, uv_indices, file_units = data
    if counts.size == 0:
        raise MeshError(f"mesh file {path} has no faces ({points.shape[0]} vertices)")
    if points.shape[0] == 0:
        raise MeshError(f"mesh file {path} has no vertices")
    _check_coordinates(points, path, suffix)
    mesh = FaceMesh(
        points=points,
        face_vertex_counts=counts,
        face_vertex_indices=indices,
        units=units or file_units or DEFAULT_UNITS,
        uvs=uvs,
        uv_indices=uv_indices,
        name=_prim_name(path.stem),
        source=str(path),
    )
    if check_degenerate:
        mesh.check_degenerate()
    return mesh


# -- helpers -------------------------------------------------------------------------------------
def _prim_name(stem: str) -> str:
    """File stem as a valid identifier (letters, digits, underscores; not starting with a digit)."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", stem) or "Face"
    return "_" + name if name[0].isdigit() else name


def _check_coordinates(points: np.ndarray, path: Path, suffix: str) -> None:
    """FormatError naming the first vertex beyond float32's range (USD stores points as float32:
    such a vertex would become inf, and every face's area test would go wrong)."""
    at = first_beyond_float32(points)
    if at is None:
        return
    i, axis = at
    line = _obj_vertex_line(path, i) if suffix == ".obj" else None
    where = f", line {line}" if line else ""
    n_bad = int((np.abs(points) > FLOAT32_MAX).any(axis=1).sum())
    more = f" ({n_bad} vertices in all)" if n_bad > 1 else ""
    raise FormatError(f"mesh file {path}{where}: vertex {i} has {'xyz'[axis]} = {points[i, axis]:.6g}, beyond the "
                      f"range of the float32 coordinates USD stores (|x| <= {FLOAT32_MAX:.4g}){more}: a corrupt "
                      f"coordinate")


def _obj_vertex_line(path: Path, index: int) -> int | None:
    """File line of the ``index``-th ``v`` statement of an OBJ file (for messages)."""
    text = _read_text(path)
    for k, m in enumerate(_OBJ_V.finditer(text)):
        if k == index:
            return text.count("\n", 0, m.start()) + 1
    return None


def _units_from_comment(line: str, path: Path, *, units_given: bool = False) -> str | None:
    m = _UNITS_COMMENT.match(line)
    if not m:
        return None
    unit = _UNIT_WORDS.get(m.group(1).lower())
    if unit is None and not units_given:  # the comment matters only when no units were given
        log.warning("mesh file %s: units comment %r not understood (known: %s); the mesh is taken to be in %s",
                    path, line.strip(), ", ".join(sorted(set(_UNIT_WORDS.values()))), DEFAULT_UNITS)
    return unit


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise InputError(f"mesh file {path} cannot be read: {e.strerror or e}") from None


def _resolve(idx: np.ndarray, n: int) -> np.ndarray:
    """OBJ indices (1-based, or negative = relative to the end) -> 0-based."""
    return np.where(idx < 0, idx + n, idx - 1)


def _read_obj(path: Path, *, units_given: bool = False):
    text = _read_text(path)
    if "\\\n" in text:  # line continuations
        text = text.replace("\\\n", " ")
    fast = _parse_obj_fast(text, path, units_given)
    # the line-by-line parser handles irregular files and names the offending line in errors
    return fast if fast is not None else _parse_obj_slow(text, path, units_given)


_OBJ_V = re.compile(r"^[ \t]*v[ \t](.*)", re.MULTILINE)
_OBJ_VT = re.compile(r"^[ \t]*vt[ \t](.*)", re.MULTILINE)
_OBJ_F = re.compile(r"^[ \t]*f[ \t](.*)", re.MULTILINE)
_OBJ_UNITS = re.compile(r"^[ \t]*#[ \t]*units?[ \t]*[:=].*$", re.MULTILINE | re.IGNORECASE)


def _token_layout(rows: list[str]):
    """Tokens per row, and per token the number of '/' and of '//' (numpy on the bytes)."""
    block = "\n".join(rows)
    b = np.frombuffer(block.encode("latin-1", errors="replace"), dtype=np.uint8)
    if b.size == 0:
        return block, np.zeros(len(rows), np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
    sep = b <= 32  # space, tab, CR, LF (and other control characters)
    starts = np.flatnonzero(~sep & np.concatenate([[True], sep[:-1]]))
    newlines = np.flatnonzero(b == 10)
    counts = np.bincount(np.searchsorted(newlines, starts), minlength=len(rows)).astype(np.int64)
    slashes = np.flatnonzero(b == 47)
    if slashes.size == 0:
        zero = np.zeros(starts.size, np.int64)
        return block, counts, zero, zero
    tok_of_slash = np.searchsorted(starts, slashes, side="right") - 1
    per_slash = np.bincount(tok_of_slash, minlength=starts.size)
    dbl = np.flatnonzero(np.diff(slashes) == 1)
    per_dbl = np.bincount(tok_of_slash[dbl], minlength=starts.size)
    return block, counts, per_slash, per_dbl


def _numbers(block: str, dtype, expected: int):
    """Whitespace-separated numbers of ``block``; None unless exactly ``expected`` parse."""
    import warnings as _w

    with _w.catch_warnings():
        _w.simplefilter("ignore")
        try:
            arr = np.fromstring(block, dtype=dtype, sep=" ")
        except ValueError:
            return None
    return arr if arr.size == expected else None


def _parse_obj_fast(text: str, path: Path, units_given: bool = False):
    """Vectorised OBJ parse for regular files (same token count on every v/vt row, same face-token
    form); None when the file needs the line-by-line parser."""
    v_rows, vt_rows, f_rows = _OBJ_V.findall(text), _OBJ_VT.findall(text), _OBJ_F.findall(text)
    if not v_rows or not f_rows:
        return None
    block, counts, _, _ = _token_layout(v_rows)
    k = int(counts[0])
    if k < 3 or (counts != k).any():
        return None
    arr = _numbers(block, np.float64, k * len(v_rows))
    if arr is None:
        return None
    points = arr.reshape(-1, k)[:, :3].copy()
    uv_all = np.zeros((0, 2))
    if vt_rows:
        block, counts, _, _ = _token_layout(vt_rows)
        k = int(counts[0])
        if k < 2 or (counts != k).any():
            return None
        arr = _numbers(block, np.float64, k * len(vt_rows))
        if arr is None:
            return None
        uv_all = arr.reshape(-1, k)[:, :2].copy()
    block, counts, per_slash, per_dbl = _token_layout(f_rows)
    if (counts < 3).any() or per_slash.size == 0:
        return None
    n_slash, n_dbl = int(per_slash[0]), int(per_dbl[0])
    if (per_slash != n_slash).any() or (per_dbl != n_dbl).any() or n_slash > 2:
        return None
    n_corner = int(counts.sum())
    if n_dbl:  # v//vn
        arr = _numbers(block.replace("//", " "), np.int64, 2 * n_corner)
        vi, ti = (None, None) if arr is None else (arr[0::2], None)
    elif n_slash == 0:
        arr = _numbers(block, np.int64, n_corner)
        vi, ti = arr, None
    else:  # v/vt or v/vt/vn
        arr = _numbers(block.replace("/", " "), np.int64, (n_slash + 1) * n_corner)
        vi, ti = (None, None) if arr is None else (arr[0:: n_slash + 1], arr[1:: n_slash + 1])
    if arr is None or vi is None:
        return None
    n, m = points.shape[0], uv_all.shape[0]
    if (vi == 0).any() or (vi > n).any() or (vi < -n).any():
        return None
    uvs = uv_indices = None
    if ti is not None:
        if m == 0 or (ti == 0).any() or (ti > m).any() or (ti < -m).any():
            return None
        uvs, uv_indices = uv_all, _resolve(ti, m)
    file_units = None
    for line in _OBJ_UNITS.findall(text)[:1]:
        file_units = _units_from_comment(line, path, units_given=units_given)
    return points, counts, _resolve(vi, n), uvs, uv_indices, file_units


def _parse_obj_slow(text: str, path: Path, units_given: bool = False):
    v_rows, vt_rows, f_lines = [], [], []
    v_lines_no, f_lines_no = [], []
    file_units = None
    for lineno, line in enumerate(text.splitlines(), 1):
        s = line.lstrip()
        if not s:
            continue
        c0 = s[0]
        if c0 == "v":
            if s.startswith("v ") or s.startswith("v\t"):
                v_rows.append(s[2:])
                v_lines_no.append(lineno)
            elif s.startswith("vt ") or s.startswith("vt\t"):
                vt_rows.append((lineno, s[3:]))
        elif c0 == "f" and (s.startswith("f ") or s.startswith("f\t")):
            f_lines.append(s[2:])
            f_lines_no.append(lineno)
        elif c0 == "#" and file_units is None:
            file_units = _units_from_comment(s, path, units_given=units_given)
    # vertices: x y z [w] [r g b]; only xyz are used
    xyz = []
    for i, row in enumerate(v_rows):
        parts = row.split()
        try:
            if len(parts) < 3:
                raise ValueError
            xyz.append((float(parts[0]), float(parts[1]), float(parts[2])))
        except ValueError:
            raise FormatError(f"mesh file {path}, line {v_lines_no[i]}: bad vertex 'v {row.strip()}'") from None
    points = np.array(xyz, dtype=np.float64).reshape(-1, 3)
    uv_list = []
    for lineno, row in vt_rows:
        parts = row.split()
        try:
            uv_list.append((float(parts[0]), float(parts[1]) if len(parts) > 1 else 0.0))
        except (ValueError, IndexError):
            raise FormatError(f"mesh file {path}, line {lineno}: bad texture coordinate 'vt {row.strip()}'") from None
    uv_all = np.array(uv_list, dtype=np.float64).reshape(-1, 2)
    # faces: tokens v, v/vt, v//vn, v/vt/vn
    counts = np.empty(len(f_lines), dtype=np.int64)
    tokens: list[str] = []
    for i, row in enumerate(f_lines):
        parts = row.split()
        counts[i] = len(parts)
        tokens.extend(parts)
    n_corner = len(tokens)
    try:
        vl, tl = [], []  # tl: 0 = no vt
        for t in tokens:
            a, _, rest = t.partition("/")
            vl.append(int(a))
            b = rest.partition("/")[0]
            tl.append(int(b) if b else 0)
        vi = np.array(vl, dtype=np.int64)
        ti = np.array(tl, dtype=np.int64)
    except ValueError:
        bad = _first_bad_face(f_lines)
        raise FormatError(f"mesh file {path}, line {f_lines_no[bad]}: bad face 'f {f_lines[bad].strip()}'") from None
    if (counts < 3).any():
        bad = int(np.flatnonzero(counts < 3)[0])
        raise FormatError(
            f"mesh file {path}, line {f_lines_no[bad]}: face with {counts[bad]} vertices (at least 3 needed)"
        )
    n = points.shape[0]
    if (vi == 0).any() or (vi > n).any() or (vi < -n).any():
        k = int(np.flatnonzero((vi == 0) | (vi > n) | (vi < -n))[0])
        face = int(np.searchsorted(np.cumsum(counts), k, side="right"))
        raise MeshError(
            f"mesh file {path}, line {f_lines_no[face]}: vertex index {vi[k]} outside 1..{n} (or -{n}..-1)"
        )
    vi = _resolve(vi, n)
    uvs = uv_indices = None
    if n_corner and uv_all.shape[0] and (ti != 0).all():
        m = uv_all.shape[0]
        if ((ti > m) | (ti < -m)).any():
            k = int(np.flatnonzero((ti > m) | (ti < -m))[0])
            face = int(np.searchsorted(np.cumsum(counts), k, side="right"))
            raise MeshError(f"mesh file {path}, line {f_lines_no[face]}: texture index {ti[k]} outside 1..{m}")
        uvs, uv_indices = uv_all, _resolve(ti, m)
    elif (ti != 0).any():
        log.warning("mesh file %s: only some face corners have texture coordinates; UVs not read", path)
    return points, counts, vi, uvs, uv_indices, file_units


def _first_bad_face(f_lines: list[str]) -> int:
    for i, row in enumerate(f_lines):
        try:
            for t in row.split():
                a, _, rest = t.partition("/")
                int(a)
                b = rest.partition("/")[0]
                if b:
                    int(b)
        except ValueError:
            return i
    return 0


_OFF_HEADER = re.compile(r"^(ST)?(C)?(N)?OFF$")


def _is_ascii_off(path: Path) -> bool:
    """True for ASCII OFF/COFF/NOFF/STOFF (3-D, not binary); others go to pymeshlab."""
    try:
        with open(path, "rb") as f:
            head = f.read(256)
    except OSError as e:
        raise InputError(f"mesh file {path} cannot be read: {e.strerror or e}") from None
    first = head.split(b"\n", 1)[0].decode("ascii", errors="replace").split()
    return bool(first) and bool(_OFF_HEADER.match(first[0])) and "BINARY" not in (w.upper() for w in first[1:])


def _read_off(path: Path, *, units_given: bool = False):
    text = _read_text(path)
    file_units = None
    rows = []  # (lineno, tokens) of non-empty, comment-stripped lines
    for lineno, line in enumerate(text.splitlines(), 1):
        body, hash_, comment = line.partition("#")
        if hash_ and file_units is None:
            file_units = _units_from_comment("#" + comment, path, units_given=units_given)
        toks = body.split()
        if toks:
            rows.append((lineno, toks))
    header = _OFF_HEADER.match(rows[0][1][0]) if rows else None
    if header is None:
        raise FormatError(f"mesh file {path}: not an OFF file (first line must be OFF, COFF, NOFF or STOFF)")
    has_st = header.group(1) is not None
    first = rows[0][1][1:]
    r = 1
    if not first:
        if len(rows) < 2:
            raise FormatError(f"mesh file {path}: missing vertex/face counts after the OFF header")
        first = rows[1][1]
        r = 2
    try:
        nv, nf = int(first[0]), int(first[1])
        if nv < 0 or nf < 0:
            raise ValueError
    except (ValueError, IndexError):
        raise FormatError(f"mesh file {path}: bad counts line {' '.join(first)!r} (expected 'vertices faces edges', "
                          f"whole numbers >= 0)") from None
    if len(rows) < r + nv + nf:
        raise FormatError(f"mesh file {path}: header announces {nv} vertices and {nf} faces but the file ends early")
    points = np.empty((nv, 3))
    st = np.empty((nv, 2)) if has_st else None
    for i in range(nv):
        lineno, toks = rows[r + i]
        try:
            points[i] = (float(toks[0]), float(toks[1]), float(toks[2]))
            if has_st:
                st[i] = (float(toks[-2]), float(toks[-1]))
        except (ValueError, IndexError):
            raise FormatError(f"mesh file {path}, line {lineno}: bad vertex {' '.join(toks)!r}") from None
    counts = np.empty(nf, dtype=np.int64)
    idx: list[int] = []
    for j in range(nf):
        lineno, toks = rows[r + nv + j]
        try:
            k = int(toks[0])
            if k < 3 or len(toks) < k + 1:
                raise ValueError
            idx.extend(int(t) for t in toks[1 : k + 1])
        except ValueError:
            raise FormatError(f"mesh file {path}, line {lineno}: bad face {' '.join(toks)!r}") from None
        counts[j] = k
    indices = np.asarray(idx, dtype=np.int64)
    if indices.size and (indices.min() < 0 or indices.max() >= nv):
        raise MeshError(f"mesh file {path}: face vertex index outside 0..{nv - 1}")
    uvs = uv_indices = None
    if has_st:
        uvs, uv_indices = st, indices.copy()
    return points, counts, indices, uvs, uv_indices, file_units


def _ply_units(path: Path, units_given: bool = False) -> str | None:
    try:
        with open(path, "rb") as f:
            head = f.read(65536)
    except OSError:
        return None
    if not head.startswith(b"ply"):
        return None
    for raw in head.split(b"end_header", 1)[0].splitlines():
        unit = _units_from_comment(raw.decode("ascii", errors="replace"), path, units_given=units_given)
        if unit:
            return unit
    return None


def _read_pymeshlab(path: Path, label: str, units_given: bool = False):
    from ..memory import check_memory
    from .mesh_headers import check_mesh_file, memory_estimate

    # pymeshlab trusts the header's counts (a lying STL spins for ever in C++): check them first
    counts = check_mesh_file(path, label=label)
    check_memory(memory_estimate(counts), what=f"{label}: {counts[0]:,} vertices and {counts[1]:,} faces"
                 if counts else label, hint="read a smaller mesh")
    try:
        import pymeshlab
    except ImportError as e:  # pragma: no cover - pymeshlab is a dependency
        raise InputError(f"reading {path} needs pymeshlab (pip install pymeshlab): {e}") from None
    ms = pymeshlab.MeshSet()
    try:
        ms.load_new_mesh(str(path))
    except Exception as e:  # pymeshlab raises PyMeshLabException for everything
        msg = " ".join(str(e).split())
        raise FormatError(f"mesh file {path} could not be read: {msg}") from None
    m = ms.current_mesh()
    points = np.asarray(m.vertex_matrix(), dtype=np.float64)
    if m.face_number() == 0:
        return points, np.zeros(0, np.int64), np.zeros(0, np.int64), None, None, None
    tri = np.asarray(m.face_matrix(), dtype=np.int64)
    polys = m.polygonal_face_list()
    counts = np.fromiter((len(p) for p in polys), dtype=np.int64, count=len(polys))
    indices = np.concatenate(polys).astype(np.int64) if polys else np.zeros(0, np.int64)
    if (counts - 2).sum() == tri.shape[0]:
        # rotate each polygon to start at the first vertex of its first triangle (the file's start)
        first_tri = np.concatenate([[0], np.cumsum(counts - 2)[:-1]])
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        lead = tri[first_tri, 0]
        face_of = np.repeat(np.arange(counts.size), counts)
        local = np.arange(indices.size) - starts[face_of]
        hit = (indices == lead[face_of])
        shift = np.zeros(counts.size, dtype=np.int64)
        shift[face_of[hit][::-1]] = local[hit][::-1]  # first hit per face
        src = starts[face_of] + (local + shift[face_of]) % counts[face_of]
        indices = indices[src]
    else:  # polygon list and triangles disagree: keep the triangles
        counts = np.full(tri.shape[0], 3, dtype=np.int64)
        indices = tri.ravel()
    uvs = uv_indices = None
    if m.has_wedge_tex_coord():
        wedge = np.asarray(m.wedge_tex_coord_matrix(), dtype=np.float64).reshape(-1, 3, 2)
        if wedge.shape[0] == tri.shape[0] and np.ptp(wedge, axis=(0, 1)).max() > 0:
            uvs, uv_indices = _wedge_to_face_varying(tri, wedge, counts, indices)
    if uvs is None and m.has_vertex_tex_coord():
        vt = np.asarray(m.vertex_tex_coord_matrix(), dtype=np.float64)
        if vt.shape[0] == points.shape[0] and np.ptp(vt, axis=0).max() > 0:
            uvs, uv_indices = vt, indices.copy()
    units = _ply_units(path, units_given) if path.suffix.lower() == ".ply" else None
    return points, counts, indices, uvs, uv_indices, units


def _wedge_to_face_varying(tri, wedge, counts, indices):
    """Per-triangle-corner UVs -> polygon face-varying UVs (shared values deduplicated)."""
    n_tri_per = counts - 2
    if n_tri_per.sum() != tri.shape[0]:
        return None, None
    face_of_tri = np.repeat(np.arange(counts.size), n_tri_per)
    # (face, vertex) -> uv from any triangle corner of that face at that vertex
    key_tri = face_of_tri[:, None] * (indices.max() + 1) + tri
    key_poly = np.repeat(np.arange(counts.size), counts) * (indices.max() + 1) + indices
    order = np.argsort(key_tri.ravel(), kind="stable")
    sorted_keys = key_tri.ravel()[order]
    pos = np.searchsorted(sorted_keys, key_poly)
    pos = np.minimum(pos, sorted_keys.size - 1)
    if not np.array_equal(sorted_keys[pos], key_poly):
        return None, None
    fv_uv = wedge.reshape(-1, 2)[order[pos]]
    uvs, uv_indices = np.unique(fv_uv, axis=0, return_inverse=True)
    return uvs, uv_indices.ravel().astype(np.int64)
