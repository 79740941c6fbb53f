"""Border and hole detection on real face meshes made hostile: a non-manifold fin on the border,
duplicate faces, bow-tie vertices. The border is never mislabelled and the run goes on with the
problem named."""
from __future__ import annotations

import json

import numpy as np
import pytest

from usdface.io.meshes import read_mesh
from usdface.model.mesh import FaceMesh
from usdface.mesh.topology import border_surface, boundary_loops, find_hole_regions

HM08 = "makehuman_hm08_face_cm.obj"


@pytest.fixture(scope="module")
def face(sample_assets):
    return read_mesh(sample_assets / "meshes" / HM08)


@pytest.fixture(scope="module")
def clean(face):
    return {r.name: r for r in find_hole_regions(face)}


def _faces(mesh):
    return [list(mesh.face_vertex_indices[s:s + c]) for s, c in zip(mesh.face_starts, mesh.face_vertex_counts)]


def _mesh(points, faces):
    return FaceMesh(np.asarray(points, float), [len(f) for f in faces], np.concatenate(faces))


def _write_obj(path, mesh):
    with open(path, "w") as fh:
        fh.writelines(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in mesh.points)
        fh.writelines("f " + " ".join(str(i + 1) for i in f) + "\n" for f in _faces(mesh))


def with_fin(face, clean):
    """Two faces glued on one border edge (three faces on it): a quad flap 40 cm long and a
    triangle reaching 42 cm away, larger than the whole face."""
    border = clean["outerBorder"].loop
    a, b = int(border[10]), int(border[11])
    p = face.points
    pts = np.vstack([p, p[a] + [0, 0, -40], p[b] + [0, 0, -40], p[a] + [0, 30, -30]])
    n = len(p)
    return _mesh(pts, _faces(face) + [[b, a, n, n + 1], [b, a, n + 2]]), (min(a, b), max(a, b))


def assert_same_regions(mesh, clean):
    regions = {r.name: r for r in find_hole_regions(mesh)}
    assert list(regions) == ["outerBorder", "mouth", "leftEye", "rightEye"]
    for name, r in clean.items():
        np.testing.assert_array_equal(regions[name].indices, r.indices)
        assert regions[name].role == r.role


def test_fin_on_the_border_is_left_out(face, clean):
    mesh, edge = with_fin(face, clean)
    assert_same_regions(mesh, clean)
    s = border_surface(mesh)
    np.testing.assert_array_equal(s.non_manifold_edges, [edge])
    np.testing.assert_array_equal(s.fin_faces, [face.n_faces, face.n_faces + 1])
    assert not s.faces[face.n_faces:].any() and s.faces[:face.n_faces].all()
    assert f"{edge[0]}-{edge[1]}" in s.message("x.obj")


def test_duplicate_faces_on_the_border_are_ignored(face, clean):
    border = set(clean["outerBorder"].loop.tolist())
    faces = _faces(face)
    touching = [f for f in faces if border & set(f)][:10]
    mesh = _mesh(face.points, faces + [f[::-1] for f in touching[:5]] + [f[1:] + f[:1] for f in touching[5:]])
    assert_same_regions(mesh, clean)
    s = border_surface(mesh)
    np.testing.assert_array_equal(s.duplicate_faces, np.arange(face.n_faces, face.n_faces + 10))
    assert s.fin_faces.size == 0


def test_eye_touching_the_border_at_a_bowtie_vertex(face, clean):
    eye, border = clean["leftEye"].loop, clean["outerBorder"].loop
    d = np.linalg.norm(face.points[eye][:, None] - face.points[border][None], axis=2)
    i, j = np.unravel_index(d.argmin(), d.shape)
    gone, kept = int(eye[i]), int(border[j])
    # merge the eye vertex into the border vertex and drop it (indices above it shift down)
    remap = np.arange(face.n_points)
    remap[gone] = kept
    remap = remap - (remap > gone)
    pts = np.delete(face.points, gone, axis=0)
    mesh = _mesh(pts, [[int(remap[v]) for v in f] for f in _faces(face)])
    regions = {r.name: r for r in find_hole_regions(mesh)}
    assert list(regions) == ["outerBorder", "mouth", "leftEye", "rightEye"]
    np.testing.assert_array_equal(regions["outerBorder"].indices, np.unique(remap[clean["outerBorder"].indices]))
    np.testing.assert_array_equal(regions["leftEye"].indices, np.unique(remap[eye]))
    assert int(remap[kept]) in regions["leftEye"].indices  # the shared vertex is in both loops
    np.testing.assert_array_equal(border_surface(mesh).non_manifold_vertices, [remap[kept]])


def test_triangle_hanging_from_a_border_vertex(face, clean):
    a = int(clean["outerBorder"].loop[20])
    n = face.n_points
    mesh = _mesh(np.vstack([face.points, face.points[a] + [0, 0, -3], face.points[a] + [0, 3, -3]]),
                 _faces(face) + [[a, n, n + 1]])
    assert_same_regions(mesh, clean)
    s = border_surface(mesh)
    np.testing.assert_array_equal(s.non_manifold_vertices, [a])
    np.testing.assert_array_equal(s.fin_faces, [face.n_faces])


def test_loops_meeting_at_a_vertex_are_cut_apart():
    # a square with two square holes sharing a corner vertex (a bow-tie between the holes)
    pts = [[x, y, 0.0] for y in range(4) for x in range(4)]
    faces = [[y * 4 + x, y * 4 + x + 1, (y + 1) * 4 + x + 1, (y + 1) * 4 + x] for y in range(3) for x in range(3)]
    faces = [f for k, f in enumerate(faces) if k not in (0, 4)]  # cells (0,0) and (1,1) removed: touch at 5
    mesh = _mesh(pts, faces)
    loops = [lp.tolist() for lp in boundary_loops(mesh)]
    # the corner cell opens onto the border, which then touches the centre hole at vertex 5
    assert loops == [[1, 2, 3, 7, 11, 15, 14, 13, 12, 8, 4, 5], [6, 5, 9, 10]]
    # the same walked from another start passes vertex 5 twice: it is cut into the same two loops
    from usdface.mesh.topology import _simple_cycles

    walk = [5, 6, 10, 9, 5, 1, 2, 3, 7, 11, 15, 14, 13, 12, 8, 4]
    assert sorted(map(len, _simple_cycles(walk))) == [4, 12]


def test_import_and_run_go_on_with_the_fin_reported(face, clean, tmp_path, sample_assets, caplog):
    """Before: the fin's loops were labelled as an eye and the real eye hole1, silently."""
    import logging

    from usdface.cli import main

    mesh, edge = with_fin(face, clean)
    obj = tmp_path / "face_fin.obj"
    _write_obj(obj, mesh)
    caplog.set_level(logging.WARNING, logger="usdface")
    out = tmp_path / "run"
    assert main([str(a) for a in ("run", "--mesh", obj, "--capture", sample_assets / "capture" / "JawMoCap.ma",
                                  "--layout", sample_assets / "layouts" / "makehuman_hm08_face.layout.json",
                                  "--trim", "0", "300", "-o", out, "-q")]) == 0
    (warning,) = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert "face_fin.obj" in warning and f"vertex pairs {edge[0]}-{edge[1]}" in warning
    assert "2 face(s) of fins" in warning and "1934, 1935" in warning
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"]["import-mesh"]["regions"] == {
        "outerBorder": {"role": "outerBorder", "vertices": 82}, "mouth": {"role": "mouth", "vertices": 38},
        "leftEye": {"role": "eye", "vertices": 28}, "rightEye": {"role": "eye", "vertices": 28}}
