"""usdface.mesh.topology: edges, boundary loops, components, non-manifold elements, hole regions."""
from __future__ import annotations

import time

import numpy as np
import pytest

from usdface.io.meshes import read_mesh
from usdface.model.mesh import FaceMesh
from usdface.mesh.topology import (
    boundary_edges,
    boundary_loops,
    connected_components,
    edge_topology,
    find_hole_regions,
    mesh_topology,
    non_manifold_edges,
    non_manifold_vertices,
)

HM08 = "makehuman_hm08_face_cm.obj"
HM08_STYLIZED = "makehuman_hm08_face_stylized_cm.obj"
MP = "mediapipe_canonical_face_model.obj"
MP_HOLES = "mediapipe_canonical_face_model_holes.obj"


@pytest.fixture(scope="module")
def meshes(shared_data):
    return {n: read_mesh(shared_data / "meshes" / n) for n in (HM08, HM08_STYLIZED, MP, MP_HOLES)}


def grid(n, holes=()):
    """n x n vertex quad grid in the z = 0 plane, optionally with square holes (cx, cy, half-size)."""
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    pts = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
    v0 = (j * n + i).ravel()
    quads = np.stack([v0, v0 + 1, v0 + n + 1, v0 + n], axis=1)
    keep = np.ones(len(quads), bool)
    for cx, cy, h in holes:
        keep &= ~((np.abs(i.ravel() + 0.5 - cx) < h) & (np.abs(j.ravel() + 0.5 - cy) < h))
    quads = quads[keep]
    return FaceMesh(pts, np.full(len(quads), 4), quads.ravel())


def check_loops(mesh, loops):
    """Every loop is a closed chain of boundary sides (face orientation); every boundary edge used once."""
    t = edge_topology(mesh)
    be = boundary_edges(t)
    directed = set(map(tuple, be.tolist()))
    seen = []
    for lp in loops:
        for a, b in zip(lp, np.roll(lp, -1)):
            assert (int(a), int(b)) in directed
            seen.append((int(a), int(b)))
    assert len(seen) == len(set(seen)) == be.shape[0]


@pytest.mark.parametrize(
    "name, n_edges, loop_sizes, euler",
    [(HM08, 3956, [82, 38, 28, 28], -2), (HM08_STYLIZED, 3956, [82, 38, 28, 28], -2),
     (MP_HOLES, 1322, [36, 20, 16, 16], -2), (MP, 1365, [36], 1)],
)
def test_real_mesh_topology(meshes, name, n_edges, loop_sizes, euler):
    m = meshes[name]
    t = edge_topology(m)
    assert t.n_edges == n_edges
    assert (t.edges[:, 0] < t.edges[:, 1]).all()
    loops = boundary_loops(m)
    assert [len(lp) for lp in loops] == loop_sizes
    check_loops(m, loops)
    assert connected_components(m)[0] == 1
    assert non_manifold_edges(m).shape == (0, 2)
    assert non_manifold_vertices(m).size == 0
    summary = mesh_topology(m)
    assert summary["euler_characteristic"] == euler == 2 - len(loop_sizes)  # discs with holes, genus 0
    assert summary["boundary_loops"] == len(loop_sizes) and summary["components"] == 1


def test_edge_incidence_of_a_quad_mesh(meshes):
    m = meshes[HM08]
    t = edge_topology(m)
    # every polygon side maps to the undirected edge of its two vertices
    np.testing.assert_array_equal(np.sort(np.stack([t.side_from, t.side_to], 1), axis=1), t.edges[t.side_edges])
    inc = t.edge_faces
    assert inc.shape == (t.n_edges, m.n_faces)
    np.testing.assert_array_equal(np.asarray(inc.sum(axis=1)).ravel(), t.edge_face_counts)
    assert set(np.unique(t.edge_face_counts)) == {1, 2}
    assert (t.edge_face_counts == 1).sum() == 82 + 38 + 28 + 28
    # the quad diagonal of the fan triangulation is not an edge
    a, _, c, _ = m.face_vertex_indices[:4]
    key = np.minimum(a, c) * m.n_points + np.maximum(a, c)
    assert key not in set((t.edges[:, 0] * m.n_points + t.edges[:, 1]).tolist())


@pytest.mark.parametrize("name", [HM08, HM08_STYLIZED, MP_HOLES])
def test_hole_regions_mouth_and_eyes(meshes, name):
    m = meshes[name]
    regions = find_hole_regions(m)
    assert [r.name for r in regions] == ["outerBorder", "mouth", "leftEye", "rightEye"]
    assert [r.role for r in regions] == ["outerBorder", "mouth", "eye", "eye"]
    by = {r.name: r for r in regions}
    p = m.points
    for r in regions:
        np.testing.assert_array_equal(r.indices, np.unique(r.loop))
    mouth, left, right = (p[by[k].loop] for k in ("mouth", "leftEye", "rightEye"))
    # the mouth is the low slit across the midline, wide and flat
    assert mouth[:, 0].min() < 0 < mouth[:, 0].max()
    assert mouth[:, 1].mean() < min(left[:, 1].mean(), right[:, 1].mean()) - 4.0
    assert np.ptp(mouth[:, 0]) > 4.0 and np.ptp(mouth[:, 1]) < 0.6
    # performer's left = +X
    assert left[:, 0].min() > 1.5 and right[:, 0].max() < -1.5
    np.testing.assert_allclose(left[:, 0].mean(), -right[:, 0].mean(), atol=1e-3)


def test_mediapipe_without_holes_has_only_its_outer_border(meshes):
    regions = find_hole_regions(meshes[MP])
    assert [(r.name, r.role, len(r.loop)) for r in regions] == [("outerBorder", "outerBorder", 36)]


def test_extra_holes_are_other_and_off_centre_holes_are_not_the_mouth():
    # a 41 x 41 grid: mouth-like slit across the midline low, two "eyes", plus a small extra hole
    m = grid(41, holes=[(20, 8, 3), (10, 28, 2), (30, 28, 2), (30, 10, 1)])
    regions = find_hole_regions(m)
    names = [r.name for r in regions]
    assert names == ["outerBorder", "mouth", "leftEye", "rightEye", "hole1"]
    by = {r.name: r for r in regions}
    assert m.points[by["leftEye"].loop, 0].mean() > 20 > m.points[by["rightEye"].loop, 0].mean()
    assert by["hole1"].role == "other"
    assert m.points[by["mouth"].loop, 1].mean() == pytest.approx(8.0)


def test_closed_mesh_has_no_regions():
    tet = FaceMesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]), [3] * 4,
                   [0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2])
    assert boundary_loops(tet) == []
    assert find_hole_regions(tet) == []
    assert mesh_topology(tet)["euler_characteristic"] == 2


def test_components_and_unreferenced_vertices():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 0, 0], [6, 0, 0], [5, 1, 0], [9, 9, 9.0]])
    m = FaceMesh(pts, [3, 3], [0, 1, 2, 3, 4, 5])
    n, labels = connected_components(m)
    assert n == 3  # two triangles and the lone vertex
    assert labels[0] == labels[1] == labels[2] != labels[3] == labels[4] == labels[5] != labels[6]
    s = mesh_topology(m)
    assert s["components"] == 2 and s["unreferenced_points"] == 1


def test_non_manifold_edge_and_vertices():
    # three triangles on the edge (0, 1)
    pts = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1.0]])
    m = FaceMesh(pts, [3, 3, 3], [0, 1, 2, 1, 0, 3, 0, 1, 4])
    np.testing.assert_array_equal(non_manifold_edges(m), [[0, 1]])
    assert {0, 1} <= set(non_manifold_vertices(m).tolist())
    assert mesh_topology(m)["non_manifold_edges"] == 1


def test_bowtie_vertex_is_non_manifold():
    # two triangles sharing only vertex 0
    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [-1, 0, 0], [-1, -1, 0.0]])
    m = FaceMesh(pts, [3, 3], [0, 1, 2, 0, 3, 4])
    assert non_manifold_edges(m).shape == (0, 2)
    np.testing.assert_array_equal(non_manifold_vertices(m), [0])
    loops = boundary_loops(m)
    assert sum(len(lp) for lp in loops) == 6  # all boundary edges walked
    check_loops(m, loops)


def test_fan_vertices_are_manifold():
    # a closed fan around vertex 0 (interior) and an open fan (boundary vertex): both manifold
    ang = np.linspace(0, 2 * np.pi, 7)[:-1]
    pts = np.vstack([[0, 0, 0], np.stack([np.cos(ang), np.sin(ang), np.zeros(6)], 1)])
    closed = FaceMesh(pts, [3] * 6, np.concatenate([[0, 1 + k, 1 + (k + 1) % 6] for k in range(6)]))
    opened = FaceMesh(pts, [3] * 5, np.concatenate([[0, 1 + k, 2 + k] for k in range(5)]))
    assert non_manifold_vertices(closed).size == 0
    assert non_manifold_vertices(opened).size == 0
    assert [len(lp) for lp in boundary_loops(opened)] == [7]


def test_inconsistent_orientation_still_gives_closed_loops():
    # two quads sharing an edge, the second wound the other way
    pts = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0.0]])
    m = FaceMesh(pts, [4, 4], [0, 1, 4, 3, 1, 4, 5, 2])
    loops = boundary_loops(m)
    assert len(loops) == 1 and sorted(loops[0].tolist()) == [0, 1, 2, 3, 4, 5]


def test_fast_on_a_300k_vertex_mesh():
    m = grid(550, holes=[(275, 150, 40), (150, 380, 25), (400, 380, 25)])  # 302,500 vertices
    t0 = time.perf_counter()
    t = edge_topology(m)
    loops = boundary_loops(t)
    n_cc, _ = connected_components(t)
    nmv = non_manifold_vertices(t)
    regions = find_hole_regions(m, loops=loops)
    elapsed = time.perf_counter() - t0
    assert [r.name for r in regions] == ["outerBorder", "mouth", "leftEye", "rightEye"]
    assert nmv.size == 0
    assert elapsed < 10.0, f"topology of a 300k-vertex mesh took {elapsed:.1f} s"
