"""Hostile mesh files: counts that lie, negative or huge dimensions, coordinates beyond float32,
non-regular files. Each is refused with one line naming the file, before pymeshlab sees it."""
from __future__ import annotations

import os
import struct

import numpy as np
import pytest

from usdface.errors import FormatError, InputError, MeshError
from usdface.io.meshes import read_mesh

from ..hostile import assert_one_line, digest, run_in_process, run_subprocess


def _binary_stl(triangles, *, count=None, extra=b"", header=b"\0" * 80) -> bytes:
    rec = np.zeros(len(triangles), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = triangles
    return header + struct.pack("<I", len(triangles) if count is None else count) + rec.tobytes() + extra


TRIANGLES = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0], [0, 1, 0]]], np.float32)


def test_lying_binary_stl_is_refused_before_pymeshlab(tmp_path):
    # issue 20 (7): 80 zero bytes, a count of 1e6, 50 bytes of data: pymeshlab spun for > 16 min
    stl = tmp_path / "lie.stl"
    stl.write_bytes(b"\0" * 80 + struct.pack("<I", 1_000_000) + b"\1" * 50)
    before = digest(stl)
    rc, lines = run_subprocess("import-mesh", stl, "-o", tmp_path / "m.usdc", timeout=60)
    assert_one_line(rc, lines, code=2, command="import-mesh",
                    contains=(str(stl), "announces 1,000,000 triangles (50,000,084 bytes)", "has 134 bytes"))
    assert digest(stl) == before and sorted(p.name for p in tmp_path.iterdir()) == ["lie.stl"]


def test_binary_stl_with_trailing_bytes_and_truncated_ascii_stl(tmp_path):
    trail = tmp_path / "trail.stl"
    trail.write_bytes(_binary_stl(TRIANGLES, extra=b"\0" * 10))
    with pytest.raises(FormatError, match=r"trail\.stl: not a complete STL file: the binary header announces 2 "
                                          r"triangles \(184 bytes\), but the file has 194 bytes"):
        read_mesh(trail)
    cut = tmp_path / "cut.stl"
    cut.write_text("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n")
    with pytest.raises(FormatError, match=r"cut\.stl: .*as ASCII STL it has 1 'facet normal', 0 'endfacet', "
                                          r"0 'endloop' and 2 'vertex' lines"):
        read_mesh(cut)


def test_well_formed_stl_still_reads(tmp_path):
    good = tmp_path / "good.stl"
    good.write_bytes(_binary_stl(TRIANGLES))
    assert (read_mesh(good).n_points, read_mesh(good).n_faces) == (4, 2)
    # a binary STL whose 80-byte header starts with "solid" (many exporters) is still binary
    solid = tmp_path / "solid.stl"
    solid.write_bytes(_binary_stl(TRIANGLES, header=b"solid exported".ljust(80)))
    assert read_mesh(solid).n_faces == 2
    text = tmp_path / "text.stl"
    text.write_text("solid x\nfacet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 1 0\n"
                    " endloop\nendfacet\nendsolid x\n")
    assert read_mesh(text).n_faces == 1


PLY_HEAD = ("ply\nformat {fmt} 1.0\nelement vertex 1000000000\nproperty float x\nproperty float y\n"
            "property float z\nelement face 1000000000\nproperty list uchar int vertex_indices\nend_header\n")


@pytest.mark.parametrize("fmt, body, match", [
    ("ascii", b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", r"announces 'element vertex 1000000000', 'element face 1000000000' "
                                                 r"\(2,000,000,000 lines\) but the file has 5 lines"),
    ("binary_little_endian", b"\1" * 50, r"announces 'element vertex 1000000000', 'element face 1000000000' "
                                         r"\(at least 13,000,000,18\d bytes\) but the file has \d+ bytes"),
])
def test_lying_ply_counts_are_refused_before_allocation(tmp_path, fmt, body, match):
    ply = tmp_path / "lie.ply"
    ply.write_bytes(PLY_HEAD.format(fmt=fmt).encode() + body)
    with pytest.raises(FormatError, match=r"lie\.ply: the PLY header " + match):
        read_mesh(ply)


def test_negative_and_lying_off_counts(tmp_path, capsys):
    # issue 20 (5): an OFF header "-3 -1 0" was a traceback (negative dimensions)
    off = tmp_path / "neg.off"
    off.write_text("OFF\n-3 -1 0\n")
    rc, lines = run_in_process(capsys, "import-mesh", off, "-o", tmp_path / "m.usdc")
    assert_one_line(rc, lines, code=2, command="import-mesh",
                    contains=(str(off), "bad counts line '-3 -1 0'", "whole numbers >= 0"))
    binary = tmp_path / "lie.off"
    binary.write_bytes(b"OFF BINARY\n" + struct.pack(">iii", 10**9, 10**9, 0) + b"\1" * 50)
    with pytest.raises(FormatError, match=r"lie\.off: the binary OFF header announces 1,000,000,000 vertices and "
                                          r"1,000,000,000 faces"):
        read_mesh(binary)
    binary.write_bytes(b"OFF BINARY\n" + struct.pack(">iii", -3, -1, 0))
    with pytest.raises(FormatError, match=r"lie\.off: binary OFF header announces -3 vertices and -1 faces"):
        read_mesh(binary)


def _face_obj_with(sample_assets, tmp_path, value: str) -> tuple:
    lines = (sample_assets / "meshes" / "makehuman_hm08_face_cm.obj").read_text().splitlines()
    k = [i for i, line in enumerate(lines) if line.startswith("v ")][17]
    lines[k] = f"v {value} 70 10"
    out = tmp_path / "face.obj"
    out.write_text("\n".join(lines) + "\n")
    return out, k + 1


def test_vertex_beyond_float32_is_named_with_its_line(sample_assets, tmp_path, capsys):
    # issue 20 (15): a vertex at 1e39 reported "1934 degenerate (zero-area) faces"
    obj, line = _face_obj_with(sample_assets, tmp_path, "1e39")
    rc, lines = run_in_process(capsys, "import-mesh", obj, "-o", tmp_path / "m.usdc")
    assert_one_line(rc, lines, code=2, command="import-mesh",
                    contains=(f"mesh file {obj}, line {line}: vertex 17 has x = 1e+39, beyond the range of the "
                              "float32 coordinates USD stores",))


def test_wild_vertex_within_float32_is_named_instead_of_degenerate_faces(sample_assets, tmp_path):
    obj, _ = _face_obj_with(sample_assets, tmp_path, "1e30")
    with pytest.raises(MeshError, match=r"vertex 17 at \(1e\+30, 70, 10\) is 2\.\d+e\+29 times farther from the "
                                        r"mesh's centre than its median vertex \(1 such vertices\): a corrupt "
                                        r"coordinate, which makes 1934 faces look degenerate"):
        read_mesh(obj)


def test_fifo_folder_and_empty_files_are_refused(tmp_path):
    fifo = tmp_path / "pipe.obj"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match=r"pipe\.obj: is a named pipe \(FIFO\), not a regular file"):
        read_mesh(fifo)
    (tmp_path / "dir.stl").mkdir()
    with pytest.raises(InputError, match=r"dir\.stl: is a folder, not a file"):
        read_mesh(tmp_path / "dir.stl")
    empty = tmp_path / "empty.ply"
    empty.write_bytes(b"")
    with pytest.raises(FormatError, match=r"empty\.ply: the file is empty \(0 bytes\)"):
        read_mesh(empty)


def test_a_units_comment_matters_only_without_units(tmp_path, caplog):
    # issue 20 (13): shapes read with the neutral's units printed a raw UserWarning per OBJ
    obj = tmp_path / "s.obj"
    obj.write_text("# Units: furlongs\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with caplog.at_level("WARNING", logger="usdface"):
        read_mesh(obj, units="cm")
    assert caplog.records == []
    with caplog.at_level("WARNING", logger="usdface"):
        assert read_mesh(obj).units == "cm"
    assert [r.getMessage() for r in caplog.records] == [
        f"mesh file {obj}: units comment '# Units: furlongs' not understood (known: cm, dm, ft, in, m, mm); "
        "the mesh is taken to be in cm"]


def test_shapes_folder_warns_through_usdface_not_python(sample_assets, tmp_path):
    """`solve --shapes DIR` with OBJ shapes: no raw UserWarning line (its units come from the mesh)."""
    shapes = tmp_path / "shapes"
    shapes.mkdir()
    text = (sample_assets / "meshes" / "makehuman_hm08_face_cm.obj").read_text()
    for k in range(2):
        moved = [f"v {float(t[1]) + 0.1 * (k + 1)} {t[2]} {t[3]}" if t and t[0] == "v" else line
                 for line, t in ((line, line.split()) for line in text.splitlines())]
        (shapes / f"s{k}.obj").write_text("# units: furlongs\n" + "\n".join(moved) + "\n")
    rc, lines = run_subprocess("solve", "--mesh", sample_assets / "meshes" / "makehuman_hm08_face_cm.obj",
                               "--shapes", shapes, "--capture", sample_assets / "capture" / "JawMoCap.usdc",
                               "--layout", sample_assets / "layouts" / "makehuman_hm08_face.layout.json",
                               "--trim", 0, 20, "-o", tmp_path / "solve.usdc", "-q", timeout=600)
    assert rc == 0 and lines == [], lines
