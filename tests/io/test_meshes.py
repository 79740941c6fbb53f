"""usdface.io.meshes: polygons, vertex order, UVs and units kept; bad files named in errors."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.errors import FormatError, InputError, MeshError, OptionError, UsdFaceError
from usdface.io.meshes import DEFAULT_UNITS, MESH_SUFFIXES, read_mesh

HM08 = "makehuman_hm08_face_cm.obj"
HM08_STYLIZED = "makehuman_hm08_face_stylized_cm.obj"
MP = "mediapipe_canonical_face_model.obj"
MP_HOLES = "mediapipe_canonical_face_model_holes.obj"


def plain_obj(path):
    """The obvious OBJ parse: v rows, vt rows, and per face the (v, vt) 0-based index lists."""
    v, vt, faces, face_vt = [], [], [], []
    for line in open(path):
        t = line.split()
        if not t:
            continue
        if t[0] == "v":
            v.append([float(x) for x in t[1:4]])
        elif t[0] == "vt":
            vt.append([float(x) for x in t[1:3]])
        elif t[0] == "f":
            faces.append([int(c.split("/")[0]) - 1 for c in t[1:]])
            face_vt.append([int(c.split("/")[1]) - 1 for c in t[1:]] if "/" in t[1] else None)
    return np.array(v), np.array(vt), faces, face_vt


@pytest.fixture(scope="module")
def meshes_dir(shared_data):
    return shared_data / "meshes"


@pytest.mark.parametrize(
    "name, n_points, n_faces, sides",
    [(HM08, 2020, 1934, 4), (HM08_STYLIZED, 2020, 1934, 4), (MP, 468, 898, 3), (MP_HOLES, 468, 852, 3)],
)
def test_real_meshes_counts_units_uvs(meshes_dir, name, n_points, n_faces, sides):
    m = read_mesh(meshes_dir / name)
    assert (m.n_points, m.n_faces) == (n_points, n_faces)
    assert (m.face_vertex_counts == sides).all()
    assert m.units == "cm"
    assert m.source == str(meshes_dir / name)
    assert m.name == name[:-4]
    assert m.uvs is not None and m.uvs.shape == (n_points, 2)  # every sample OBJ has one vt per v
    assert m.uv_indices.shape == m.face_vertex_indices.shape


@pytest.mark.parametrize("name", [HM08, HM08_STYLIZED, MP_HOLES])
def test_obj_vertex_order_faces_and_uvs_are_the_files(meshes_dir, name):
    v, vt, faces, face_vt = plain_obj(meshes_dir / name)
    m = read_mesh(meshes_dir / name)
    np.testing.assert_array_equal(m.points, v)  # vertex i of the OBJ is point i, exactly
    np.testing.assert_array_equal(m.face_vertex_counts, [len(f) for f in faces])
    # same polygons, same first vertex (so the same fan diagonal as the file)
    np.testing.assert_array_equal(m.face_vertex_indices, np.concatenate(faces))
    np.testing.assert_array_equal(m.uvs, vt)
    np.testing.assert_array_equal(m.uv_indices, np.concatenate(face_vt))


def test_hm08_vertex_order_matches_ground_truth_shapes(meshes_dir):
    # the expression deltas index the OBJ's vertices; their neutral must be the OBJ's points
    gt = np.load(meshes_dir / "makehuman_hm08_face_units_cm.npz")
    m = read_mesh(meshes_dir / HM08)
    np.testing.assert_allclose(m.points, gt["neutral"], atol=1e-5)


def test_quads_triangulate_along_the_files_first_diagonal(meshes_dir):
    m = read_mesh(meshes_dir / HM08)
    _, _, faces, _ = plain_obj(meshes_dir / HM08)
    tris = m.triangles()
    assert tris.shape == (2 * 1934, 3)
    a, b, c, d = faces[0]
    np.testing.assert_array_equal(tris[:2], [[a, b, c], [a, c, d]])


def write_ply(path, points, faces, *, st=None, comment=None):
    with open(path, "w") as f:
        f.write("ply\nformat ascii 1.0\n")
        if comment:
            f.write(f"comment {comment}\n")
        f.write(f"element vertex {len(points)}\nproperty double x\nproperty double y\nproperty double z\n")
        if st is not None:
            f.write("property float s\nproperty float t\n")
        f.write(f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
        for i, p in enumerate(points):
            uv = "" if st is None else " %r %r" % tuple(st[i].tolist())
            f.write(" ".join(repr(float(x)) for x in p) + uv + "\n")
        for fc in faces:
            f.write(f"{len(fc)} " + " ".join(map(str, fc)) + "\n")


def test_ply_keeps_quads_vertex_order_and_uvs(meshes_dir, tmp_path):
    ref = read_mesh(meshes_dir / HM08)
    faces = ref.face_vertex_indices.reshape(-1, 4)
    st = np.zeros((ref.n_points, 2))
    st[ref.face_vertex_indices] = ref.uvs[ref.uv_indices]
    write_ply(tmp_path / "face.ply", ref.points, faces, st=st, comment="Units: mm")
    m = read_mesh(tmp_path / "face.ply")
    np.testing.assert_array_equal(m.face_vertex_counts, ref.face_vertex_counts)
    np.testing.assert_array_equal(m.face_vertex_indices, ref.face_vertex_indices)  # rotation restored
    np.testing.assert_allclose(m.points, ref.points, atol=1e-5)  # pymeshlab stores float32
    assert m.units == "mm"  # from the PLY header comment
    np.testing.assert_allclose(m.uvs[m.uv_indices], st[m.face_vertex_indices], atol=1e-6)
    assert read_mesh(tmp_path / "face.ply", units="cm").units == "cm"


def test_off_keeps_quads_exactly(meshes_dir, tmp_path):
    ref = read_mesh(meshes_dir / HM08)
    with open(tmp_path / "face.off", "w") as f:
        f.write(f"OFF\n# Units: centimetres\n{ref.n_points} {ref.n_faces} 0\n")
        for p in ref.points:
            f.write("%r %r %r\n" % tuple(p.tolist()))
        for fc in ref.face_vertex_indices.reshape(-1, 4):
            f.write("4 " + " ".join(map(str, fc)) + "\n")
    m = read_mesh(tmp_path / "face.off")
    np.testing.assert_array_equal(m.points, ref.points)
    np.testing.assert_array_equal(m.face_vertex_indices, ref.face_vertex_indices)
    assert m.units == "cm"


def test_stl_reads_triangles(tmp_path):
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    tris = [(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)]
    with open(tmp_path / "tet.stl", "w") as f:
        f.write("solid tet\n")
        for t in tris:
            f.write(" facet normal 0 0 0\n  outer loop\n")
            for i in t:
                f.write("   vertex %g %g %g\n" % tuple(tet[i]))
            f.write("  endloop\n endfacet\n")
        f.write("endsolid tet\n")
    m = read_mesh(tmp_path / "tet.stl")
    assert m.n_faces == 4 and (m.face_vertex_counts == 3).all()
    assert m.n_points == 4  # coincident STL corners merged
    assert m.units == DEFAULT_UNITS == "cm"


def test_obj_token_forms_negative_indices_and_units(tmp_path):
    (tmp_path / "a.obj").write_text(
        "# Units: millimetres\n"
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
        "f 1/1/1 2/2/1 3/3/1 4/4/1\n"
        "f -4/-4 -2/-2 -1/-1\n"
    )
    m = read_mesh(tmp_path / "a.obj")
    np.testing.assert_array_equal(m.face_vertex_counts, [4, 3])
    np.testing.assert_array_equal(m.face_vertex_indices, [0, 1, 2, 3, 0, 2, 3])
    np.testing.assert_array_equal(m.uv_indices, [0, 1, 2, 3, 0, 2, 3])
    assert m.units == "mm"
    assert read_mesh(tmp_path / "a.obj", units="m").units == "m"
    (tmp_path / "b.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\n")
    b = read_mesh(tmp_path / "b.obj")
    assert b.uvs is None and b.units == "cm"


def test_obj_with_uvs_on_some_faces_only_drops_them_with_a_warning(tmp_path, caplog):
    (tmp_path / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 2 4 3\n")
    with caplog.at_level("WARNING", logger="usdface"):
        m = read_mesh(tmp_path / "a.obj")
    assert m.uvs is None
    assert [r.getMessage() for r in caplog.records] == [
        f"mesh file {tmp_path / 'a.obj'}: only some face corners have texture coordinates; UVs not read"]


def test_suffixes_listed():
    assert {".obj", ".ply", ".stl", ".off"} <= set(MESH_SUFFIXES)


# -- errors --------------------------------------------------------------------------------------
def test_missing_file(tmp_path):
    with pytest.raises(InputError, match=r"mesh file .*nope\.obj: no such file"):
        read_mesh(tmp_path / "nope.obj")


def test_unknown_suffix(tmp_path):
    p = tmp_path / "face.xyz"
    p.write_text("0 0 0\n")
    with pytest.raises(InputError, match=r"face\.xyz: unknown suffix '\.xyz'; expected one of \.obj"):
        read_mesh(p)


def test_unknown_units_option(meshes_dir):
    with pytest.raises(OptionError, match="unknown unit 'furlong'"):
        read_mesh(meshes_dir / MP, units="furlong")


def test_no_faces(tmp_path):
    p = tmp_path / "points.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(MeshError, match=r"points\.obj has no faces \(3 vertices\)"):
        read_mesh(p)


def test_degenerate_faces(tmp_path):
    p = tmp_path / "flat.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n")
    with pytest.raises(MeshError, match=r"flat\.obj: 1 degenerate \(zero-area\) face\(s\), e\.g\. faces \[1\]"):
        read_mesh(p)
    assert read_mesh(p, check_degenerate=False).n_faces == 2


@pytest.mark.parametrize(
    "text, match",
    [
        ("v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n", r"bad\.obj, line 2: bad vertex 'v 1 zero 0'"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", r"bad\.obj, line 4: bad face 'f 1 2 x'"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", r"bad\.obj, line 4: face with 2 vertices"),
        ("vt 0\nvt a b\n", r"bad\.obj, line 2: bad texture coordinate"),
    ],
)
def test_malformed_obj(tmp_path, text, match):
    p = tmp_path / "bad.obj"
    p.write_text(text)
    with pytest.raises(FormatError, match=match):
        read_mesh(p)


def test_obj_index_out_of_range(tmp_path):
    p = tmp_path / "bad.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")
    with pytest.raises(MeshError, match=r"bad\.obj, line 4: vertex index 7 outside 1\.\.3"):
        read_mesh(p)


def test_malformed_ply_and_off(tmp_path):
    p = tmp_path / "bad.ply"
    p.write_text("this is not a ply file\n")
    with pytest.raises(FormatError, match=r"mesh file .*bad\.ply: not a PLY file"):
        read_mesh(p)
    o = tmp_path / "bad.off"
    o.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n")
    with pytest.raises(FormatError, match=r"bad\.off, line 6: bad face '3 0 1'"):
        read_mesh(o)
    o.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")
    with pytest.raises(FormatError, match=r"bad\.off: header announces 3 vertices and 1 faces"):
        read_mesh(o)


def test_directory_is_not_a_mesh(tmp_path):
    d = tmp_path / "dir.obj"
    d.mkdir()
    with pytest.raises(InputError, match=r"dir\.obj: is a folder, not a file"):
        read_mesh(d)


def test_errors_are_usdface_errors():
    assert issubclass(FormatError, UsdFaceError) and issubclass(MeshError, UsdFaceError)


def test_crlf_leading_spaces_and_vertex_colours(tmp_path):
    body = "# Units: m\n v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 1 1 0 0 0 1\n\tv 0 1 0 1 1 1\nf 1 2 3 4\n"
    (tmp_path / "lf.obj").write_text(body)
    (tmp_path / "crlf.obj").write_bytes(body.replace("\n", "\r\n").encode())
    a, b = read_mesh(tmp_path / "lf.obj"), read_mesh(tmp_path / "crlf.obj")
    np.testing.assert_array_equal(a.points, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(b.face_vertex_indices, [0, 1, 2, 3])
    assert a.units == b.units == "m"


@pytest.mark.parametrize("name", [HM08, MP_HOLES])
def test_vectorised_and_line_by_line_obj_parsers_agree(meshes_dir, name):
    from usdface.io.meshes import _parse_obj_fast, _parse_obj_slow

    path = meshes_dir / name
    text = path.read_text()
    fast, slow = _parse_obj_fast(text, path), _parse_obj_slow(text, path)
    assert fast is not None
    for x, y in zip(fast, slow):
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y)
        else:
            assert x == y
