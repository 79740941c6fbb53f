"""Graph back-end (paper Eq. 7): shortest edge paths from surface points, multi-source."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra, shortest_path

from usdface.distance import DistanceWarning, GeodesicSolver, geodesic_distances
from usdface.distance import graph as G
from usdface.errors import ComputeError, InputError, OptionError, ResourceError


def load_face(shared_data, name="makehuman_hm08_face_cm.obj"):
    from usdface.io.meshes import read_mesh
    m = read_mesh(shared_data / "meshes" / name)
    return m.points, m.triangles()


def grid(nx=9, ny=7, *, z=None):
    x, y = np.meshgrid(np.linspace(0, 4, nx), np.linspace(0, 3, ny))
    pts = np.stack([x.ravel(), y.ravel(), np.zeros(x.size) if z is None else z(x, y).ravel()], axis=1)
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return pts, tris


def random_sources(tris, s, seed=0):
    rng = np.random.default_rng(seed)
    tri = tris[rng.choice(len(tris), s, replace=False)].copy()
    bary = rng.dirichlet([1.0, 1.0, 1.0], size=s)
    tri[0] = tri[0, 0]            # a vertex source
    bary[0] = [1.0, 0.0, 0.0]
    tri[2] = tri[1]               # two sources in one triangle
    bary[2] = [0.2, 0.3, 0.5]
    bary[3] = [0.5, 0.5, 0.0]     # a point on an edge
    return tri, bary


def reference_min_formula(points, tris, tri, bary):
    """Independent reference: d(p, x) = min_k |p - v_k| + D(v_k, x) on the plain edge graph."""
    e = G.mesh_edges(tris)
    w = np.linalg.norm(points[e[:, 0]] - points[e[:, 1]], axis=1)
    g = sp.coo_matrix((w, (e[:, 0], e[:, 1])), shape=(len(points),) * 2).tocsr()
    D = shortest_path(g, method="D", directed=False, indices=np.unique(tri))
    row = {v: i for i, v in enumerate(np.unique(tri))}
    q = np.einsum("sk,skd->sd", bary, points[tri])
    out = np.full((len(points), len(tri)), np.inf)
    for s in range(len(tri)):
        for v in tri[s]:
            out[:, s] = np.minimum(out[:, s], np.linalg.norm(q[s] - points[v]) + D[row[v]])
    # sources: p_i -> vertex of j's triangle -> p_j, or straight when they share a triangle
    ss = np.array([[min(out[v, i] + np.linalg.norm(points[v] - q[j]) for v in tri[j]) for j in range(len(tri))]
                   for i in range(len(tri))])
    key = np.sort(tri, axis=1)
    for i in range(len(tri)):
        for j in range(len(tri)):
            if (key[i] == key[j]).all():
                ss[i, j] = min(ss[i, j], np.linalg.norm(q[i] - q[j]))
    np.fill_diagonal(ss, 0.0)
    return out, ss


@pytest.mark.parametrize("engine", ["numba", "scipy"])
def test_graph_equals_scipy_shortest_paths(shared_data, engine):
    if engine == "numba" and not G.HAVE_NUMBA:
        pytest.skip("numba not installed")
    pts, tris = load_face(shared_data)
    tri, bary = random_sources(tris, 41, seed=3)
    solver = GeodesicSolver(pts, tris, backend="graph", engine=engine)
    r = solver.solve(tri, bary)
    assert r.vertex.shape == (len(pts), 41) and r.sources.shape == (41, 41)
    # 1. scipy.sparse.csgraph on the same (augmented) edge graph
    aug = G.augmented_graph(solver.graph, pts, tri, bary)
    ref = dijkstra(aug, directed=True, indices=len(pts) + np.arange(41))
    np.testing.assert_allclose(r.vertex, ref[:, :len(pts)].T, rtol=0, atol=1e-12)
    ref_s = ref[:, len(pts) + 41:].T
    np.fill_diagonal(ref_s, 0.0)
    np.testing.assert_allclose(r.sources, ref_s, rtol=0, atol=1e-12)
    # 2. independent: plain edge graph + start offsets, scipy shortest_path
    ref2, ref2_s = reference_min_formula(pts, tris, tri, bary)
    np.testing.assert_allclose(r.vertex, ref2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.sources, ref2_s, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.sources, r.sources.T, rtol=0, atol=1e-12)
    assert r.vertex[tri[0, 0], 0] == 0.0
    # distances() and at_sources() reuse the same search
    assert solver.distances(tri, bary) is r.vertex
    assert solver.at_sources(tri, bary) is r.sources


def test_heap_fallback_equals_scipy():
    # one very short edge makes the bucket queue impractical: the heap path runs
    pts, tris = grid(12, 10)
    pts[5, 0] = pts[4, 0] + 1e-7
    g = G.edge_graph(pts, G.mesh_edges(tris))
    assert G._bucket_width(g)[0] == 0.0
    tri, bary = random_sources(tris, 6, seed=1)
    v, s, _ = G.multi_source_shortest_paths(g, pts, tri, bary)
    v2, s2, _ = G.multi_source_shortest_paths(g, pts, tri, bary, engine="scipy")
    np.testing.assert_allclose(v, v2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(s, s2, rtol=0, atol=1e-12)


def test_bounded_search_exact_where_needed(shared_data):
    pts, tris = load_face(shared_data)
    tri, bary = random_sources(tris, 12, seed=5)
    g = G.edge_graph(pts, G.mesh_edges(tris))
    full, full_s, settled_full = G.multi_source_shortest_paths(g, pts, tri, bary)
    needed = pts[:, 1] < np.percentile(pts[:, 1], 30)
    part, _, settled = G.multi_source_shortest_paths(g, pts, tri, bary, needed=needed)
    np.testing.assert_array_equal(part[needed], full[needed])
    assert settled.sum() < settled_full.sum()
    assert np.all(settled_full == len(pts))
    lim, _, _ = G.multi_source_shortest_paths(g, pts, tri, bary, limit=3.0)
    ref = np.where(full <= 3.0, full, np.inf)
    np.testing.assert_array_equal(lim, ref)


def test_polygon_edges_option(shared_data):
    from usdface.io.meshes import read_mesh
    m = read_mesh(shared_data / "meshes" / "makehuman_hm08_face_cm.obj")
    e = G.polygon_edges(m.face_vertex_counts, m.face_vertex_indices)
    assert len(e) < len(G.mesh_edges(m.triangles()))           # no quad diagonals
    quads = GeodesicSolver(m.points, m.triangles(), edges=e, backend="graph")
    with pytest.raises(OptionError, match="graph"):
        GeodesicSolver(m.points, m.triangles(), edges=e, backend="fmm")
    tris = GeodesicSolver(m.points, m.triangles(), backend="graph")
    src = (np.array([[100, 100, 100]]), np.array([[1.0, 0.0, 0.0]]))
    dq, dt = quads.distances(*src), tris.distances(*src)
    assert np.all(dq >= dt - 1e-12) and (dq > dt + 1e-9).any()


def two_islands():
    p1, t1 = grid(6, 5)
    p2, t2 = grid(4, 4)
    p2 = p2 + np.array([10.0, 0.0, 0.0])
    pts = np.concatenate([p1, p2])
    tris = np.concatenate([t1, t2 + len(p1)])
    return pts, tris, len(p1)


@pytest.mark.parametrize("backend", ["graph", "fmm"])
def test_components_error_names_markers(backend):
    pts, tris, n1 = two_islands()
    solver = GeodesicSolver(pts, tris, backend=backend)
    assert solver.n_components == 2
    tri = np.array([[0, 0, 0], [7, 7, 7], [n1 + 1, n1 + 1, n1 + 1]])
    bary = np.tile([1.0, 0.0, 0.0], (3, 1))
    np.testing.assert_array_equal(solver.source_components(tri), [0, 0, 1])
    with pytest.raises(ComputeError) as exc:
        solver.distances(tri, bary, names=["Chin", "Mouth_Up", "LeftEar"])
    msg = str(exc.value)
    assert "component 1 (16 vertices): LeftEar" in msg and "Chin, Mouth_Up" in msg and "euclidean" in msg


@pytest.mark.parametrize("backend", ["graph", "fmm"])
def test_components_euclidean_and_inf(backend):
    pts, tris, n1 = two_islands()
    tri = np.array([[0, 0, 0], [n1 + 1, n1 + 1, n1 + 1]])
    bary = np.tile([1.0, 0.0, 0.0], (2, 1))
    raw = GeodesicSolver(pts, tris, components="inf", backend=backend)
    with pytest.warns(DistanceWarning):
        r = raw.solve(tri, bary)
    assert np.isinf(r.vertex[n1:, 0]).all() and np.isinf(r.vertex[:n1, 1]).all()
    assert np.isinf(r.sources[0, 1]) and r.report.unreachable_pairs == len(pts)
    fb = GeodesicSolver(pts, tris, components="euclidean", backend=backend)
    with pytest.warns(DistanceWarning, match="Euclidean"):
        r2 = fb.solve(tri, bary)
    assert np.isfinite(r2.vertex).all()
    np.testing.assert_allclose(r2.vertex[n1:, 0], np.linalg.norm(pts[n1:] - pts[0], axis=1))
    np.testing.assert_allclose(r2.sources[0, 1], np.linalg.norm(pts[n1 + 1] - pts[0]))
    np.testing.assert_array_equal(r2.vertex[:n1, 0], r.vertex[:n1, 0])  # same-component values untouched
    assert r2.report.euclidean_fallback_pairs == len(pts) + 2


@pytest.mark.parametrize("backend", ["graph", "fmm"])
def test_vertices_on_marker_free_component_are_reported(backend):
    pts, tris, n1 = two_islands()
    tri, bary = np.array([[0, 0, 0]]), np.array([[1.0, 0.0, 0.0]])
    with pytest.warns(DistanceWarning, match="16 vertices"):
        r = GeodesicSolver(pts, tris, backend=backend).solve(tri, bary)
    assert r.report.unreachable_vertices == 16 and np.isinf(r.vertex[n1:]).all()


@pytest.mark.parametrize("backend", ["graph", "fmm"])
def test_memory_limit_raises(backend):
    pts, tris = grid()
    tri, bary = random_sources(tris, 5)
    solver = GeodesicSolver(pts, tris, memory_limit=100, backend=backend)
    need, detail = solver.memory_estimate(5)
    assert need > 63 * 5 * 8 and "matrix 2.5 KB" in detail
    with pytest.raises(ResourceError, match=r"63 vertices x 5 sources .* needs about .*matrix 2.5 KB.* but only "
                                            r"100 B is allowed"):
        solver.distances(tri, bary)


@pytest.mark.parametrize("backend", ["graph", "fmm"])
def test_float32_output(shared_data, backend):
    pts, tris = load_face(shared_data)
    tri, bary = random_sources(tris, 4)
    d64 = GeodesicSolver(pts, tris, backend=backend).distances(tri, bary)
    d32 = GeodesicSolver(pts, tris, dtype=np.float32, backend=backend).distances(tri, bary)
    assert d32.dtype == np.float32
    np.testing.assert_allclose(d32, d64, rtol=1e-6)


def test_bad_sources_are_named():
    pts, tris = grid()
    with pytest.raises(InputError, match="Chin"):
        geodesic_distances(pts, tris, np.array([[0, 1, 999]]), np.array([[0.2, 0.3, 0.5]]), names=["Chin"])


def test_refine_and_loops(shared_data):
    pts, tris = load_face(shared_data)
    p4, t4 = G.refine_triangles(pts, tris, 3)
    np.testing.assert_array_equal(p4[:len(pts)], pts)
    assert len(t4) == 9 * len(tris)
    area = lambda p, t: np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1).sum()
    normal = lambda p, t: np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]).sum(axis=0)
    assert area(p4, t4) == pytest.approx(area(pts, tris), rel=1e-12)
    np.testing.assert_allclose(normal(p4, t4), normal(pts, tris), rtol=1e-9, atol=1e-9)  # same orientation
    assert G.connected_components(len(p4), t4)[0] == 1
    loops, loops4 = G.boundary_loops(tris), G.boundary_loops(t4)
    assert [len(l) for l in loops] == [82, 38, 28, 28]
    assert [len(l) for l in loops4] == [3 * 82, 3 * 38, 3 * 28, 3 * 28]


def test_insert_surface_points_keeps_surface():
    pts, tris = grid(5, 4)
    tri = np.array([tris[3], tris[3], tris[3], tris[7], [2, 2, 2]])
    bary = np.array([[0.2, 0.3, 0.5], [0.6, 0.2, 0.2], [0.2, 0.3, 0.5], [0.5, 0.5, 0.0], [1.0, 0.0, 0.0]])
    p2, t2, sv, moved = G.insert_surface_points(pts, tris, tri, bary)
    assert len(p2) == len(pts) + 3 and len(t2) == len(tris) + 6
    assert sv[0] == sv[2] and sv[4] == 2                       # coincident points share a vertex
    q = np.einsum("sk,skd->sd", bary, pts[tri])
    np.testing.assert_allclose(p2[sv[:3]], q[:3], atol=1e-15)
    assert moved[3] > 0 and moved[3] < 1e-3                   # on-edge point nudged inside
    area = lambda p, t: 0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1)
    assert area(p2, t2).sum() == pytest.approx(area(pts, tris).sum(), rel=1e-12)
    assert area(p2, t2).min() > 0
    n = lambda p, t: np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])[:, 2]
    assert (np.sign(n(p2, t2)) == np.sign(n(pts, tris)[0])).all()
    with pytest.raises(InputError, match="not a triangle"):
        G.insert_surface_points(pts, tris, np.array([[0, 1, 19]]), np.array([[0.3, 0.3, 0.4]]))
