"""Fast-marching back-end ("fmm"): exact where the surface develops into a plane, close to exact
(MMP) geodesics on real faces, and the numba kernel equal to a slow pure-Python reference."""
from __future__ import annotations

import heapq
import math
import warnings

import numpy as np
import pytest
from scipy.spatial import Delaunay

from usdface.distance import DistanceWarning, GeodesicSolver, geodesic_distances
from usdface.distance import graph as G
from usdface.distance.marching import MarchingMesh, march, triangle_neighbours


def planar_mesh(n=600, seed=0):
    """Random points in a 10 x 10 square (its border included) triangulated by Delaunay: convex, so
    geodesics are straight segments; plenty of obtuse triangles."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 10, 16)
    xy = np.concatenate([rng.uniform(0, 10, (n, 2)), np.stack([t, 0 * t], 1), np.stack([t, 0 * t + 10], 1),
                         np.stack([0 * t, t], 1), np.stack([0 * t + 10, t], 1)])
    xy = np.unique(xy, axis=0)
    return np.c_[xy, np.zeros(len(xy))], Delaunay(xy).simplices.astype(np.int64)


def folded_strips(seed=0):
    """A developable surface: points on 12 vertical columns of the plane, each strip between two
    columns triangulated on its own (irregular triangles), then the columns wrapped onto a polygonal
    cylinder with chords equal to the column spacing. Every triangle keeps its shape, so the surface
    is isometric to the flat rectangle: geodesics = straight-line distances in the plane."""
    rng = np.random.default_rng(seed)
    cols, spacing, height = 12, 0.8, 6.0
    ys = [np.sort(np.concatenate([[0.0, height], rng.uniform(0, height, 14)])) for _ in range(cols)]
    flat, ids = [], []
    for i, y in enumerate(ys):
        ids.append(np.arange(len(flat), len(flat) + len(y)))
        flat += [(i * spacing, v) for v in y]
    flat = np.array(flat)
    tris = []
    for i in range(cols - 1):
        idx = np.concatenate([ids[i], ids[i + 1]])
        for s in Delaunay(flat[idx]).simplices:
            tri = idx[s]
            if len({int(flat[v, 0] / spacing + 0.5) for v in tri}) == 2:   # spans the strip
                tris.append(tri)
    step = 2 * np.arcsin(spacing / (2 * 4.0))                           # chord = spacing on R = 4
    theta = np.round(flat[:, 0] / spacing) * step
    pts = np.stack([4.0 * np.cos(theta), flat[:, 1], 4.0 * np.sin(theta)], axis=1)
    return pts, np.array(tris, dtype=np.int64), flat


def sources_in(tris, k, seed):
    rng = np.random.default_rng(seed)
    tri = tris[rng.choice(len(tris), k, replace=False)].copy()
    bary = rng.dirichlet([2.0, 2.0, 2.0], size=k)
    tri[0] = tri[0, 0]
    bary[0] = [1.0, 0.0, 0.0]            # a vertex source
    bary[1] = [0.5, 0.5, 0.0]            # a point on an edge
    return tri, bary


def test_exact_on_a_plane():
    pts, tris = planar_mesh()
    mm = MarchingMesh(pts, tris)
    assert mm.n_obtuse > 300 and mm.n_split > 0.9 * mm.n_obtuse
    tri, bary = sources_in(tris, 8, seed=1)
    r = GeodesicSolver(pts, tris, backend="fmm").solve(tri, bary)
    q = np.einsum("sk,skd->sd", bary, pts[tri])
    ref = np.linalg.norm(pts[:, None] - q[None], axis=2)
    np.testing.assert_allclose(r.vertex, ref, rtol=0, atol=2e-5)
    np.testing.assert_allclose(r.sources, np.linalg.norm(q[:, None] - q[None], axis=2), rtol=0, atol=2e-5)
    # the edge graph on the same mesh is far off (zig-zag paths)
    g = GeodesicSolver(pts, tris, backend="graph").distances(tri, bary)
    assert np.mean(np.abs(g - ref)[ref > 1] / ref[ref > 1]) > 0.02


def test_exact_on_a_developable_surface():
    pts, tris, flat = folded_strips()
    edges = G.mesh_edges(tris)
    np.testing.assert_allclose(np.linalg.norm(pts[edges[:, 0]] - pts[edges[:, 1]], axis=1),
                               np.linalg.norm(flat[edges[:, 0]] - flat[edges[:, 1]], axis=1), rtol=1e-12)
    tri, bary = sources_in(tris, 6, seed=2)
    d = geodesic_distances(pts, tris, tri, bary, backend="fmm")[0]
    q = np.einsum("sk,skd->sd", bary, flat[tri])
    ref = np.linalg.norm(flat[:, None] - q[None], axis=2)
    np.testing.assert_allclose(d, ref, rtol=0, atol=2e-5)
    # the 3D chord is shorter than the surface distance across the folds
    e = np.linalg.norm(pts[:, None] - np.einsum("sk,skd->sd", bary, pts[tri])[None], axis=2)
    assert (e < ref - 0.05).any()


def test_split_tables_are_true_unfoldings():
    """On a plane the unfolded vertex w is where it is: the stored lengths are true distances, and w
    lies within 90 degrees of both edges of the obtuse corner b (its acute section)."""
    pts, tris = planar_mesh(300, seed=3)
    mm = MarchingMesh(pts, tris)
    b = np.repeat(np.arange(len(pts)), np.diff(mm.sptr))
    u, w = mm.su.astype(int), mm.sw.astype(int)
    for stored, x, y in ((mm.slo, u, w), (mm.slu, u, b), (mm.slw, w, b)):
        np.testing.assert_allclose(stored, np.linalg.norm(pts[x] - pts[y], axis=1), rtol=1e-6)
    # each split corner: b's two virtual triangles share w; (b, u) and (b, w) within 90 degrees
    assert (np.einsum("ij,ij->i", pts[u] - pts[b], pts[w] - pts[b]) >= -1e-9).all()
    nb = triangle_neighbours(tris)
    assert (nb >= -1).all() and (nb < len(tris)).all()


def test_against_exact_geodesics_on_sample_faces(shared_data):
    from usdface.io.meshes import read_mesh
    for name, limit in (("makehuman_hm08_face_cm.obj", 0.005), ("mediapipe_canonical_face_model_holes.obj", 0.010)):
        m = read_mesh(shared_data / "meshes" / name)
        pts, tris = m.points, m.triangles()
        rng = np.random.default_rng(7)
        tri = tris[rng.choice(len(tris), 12, replace=False)]
        bary = rng.dirichlet([2.0, 2.0, 2.0], size=12)
        exact = GeodesicSolver(pts, tris, backend="exact").solve(tri, bary)
        fmm = GeodesicSolver(pts, tris, backend="fmm").solve(tri, bary)
        graph = GeodesicSolver(pts, tris, backend="graph").solve(tri, bary)
        e = G.mesh_edges(tris)
        h = np.linalg.norm(pts[e[:, 0]] - pts[e[:, 1]], axis=1).mean()
        far = exact.vertex > h                      # the pairs a kernel reaches: beyond one edge
        rel = lambda a: np.abs(a - exact.vertex)[far] / exact.vertex[far]
        assert rel(fmm.vertex).mean() < limit, (name, rel(fmm.vertex).mean())
        assert rel(graph.vertex).mean() > 0.05
        fs = exact.sources > h
        assert (np.abs(fmm.sources - exact.sources)[fs] / exact.sources[fs]).mean() < limit
        # edge paths are all too long; the marching bias is a small fraction of theirs
        bias = lambda a: np.mean((a - exact.vertex)[far] / exact.vertex[far])
        assert abs(bias(fmm.vertex)) < 0.1 * bias(graph.vertex)


@pytest.mark.slow
def test_converges_on_a_refined_face(shared_data):
    """The MakeHuman face refined 1-to-16 (31k vertices, the same surface): exact MMP distances on
    the original 2020 vertices are the exact distances there."""
    from usdface.io.meshes import read_mesh
    m = read_mesh(shared_data / "meshes" / "makehuman_hm08_face_cm.obj")
    pts, tris = m.points, m.triangles()
    p4, t4 = G.refine_triangles(pts, tris, 4)
    src = np.array([534, 1200, 77, 1500, 300])     # vertex sources keep their index when refined
    tri, bary = np.repeat(src[:, None], 3, axis=1), np.tile([1.0, 0.0, 0.0], (5, 1))
    exact = GeodesicSolver(pts, tris, backend="exact").distances(tri, bary)
    fine = GeodesicSolver(p4, t4, backend="fmm").distances(tri, bary)[:len(pts)]
    coarse = GeodesicSolver(pts, tris, backend="fmm").distances(tri, bary)
    far = exact > 0.46
    rel_fine = (np.abs(fine - exact)[far] / exact[far]).mean()
    rel_coarse = (np.abs(coarse - exact)[far] / exact[far]).mean()
    assert rel_fine < 0.0025 and rel_fine < 0.7 * rel_coarse, (rel_fine, rel_coarse)


# ------------------------------------------------------------------------------------------------
# the kernel against a slow, obvious reference


def _through_edge(du, da, L, px, py):
    """The point source at distance du from (0, 0) and da from (L, 0), y > 0; its distance at
    (px, py) if the ray to it crosses [0, L] x {0}."""
    sx = (du * du - da * da + L * L) / (2 * L)
    sy2 = du * du - sx * sx
    if sy2 < -1e-6 * du * du:           # circles that do not meet (a little slack for rounding)
        return math.inf
    sy = math.sqrt(max(sy2, 0.0))
    if sy - py <= 0:
        return math.inf
    x0 = sx + (px - sx) * sy / (sy - py)
    return math.hypot(px - sx, py - sy) if 0 <= x0 <= L else math.inf


def _frame(p, u, a, b):
    """Triangle (u, a, b) laid flat: u at 0, a on +x; returns |ua| and b below the x axis."""
    ea, eb = p[a] - p[u], p[b] - p[u]
    L = float(np.linalg.norm(ea))
    bx = float(eb @ ea) / L
    return L, bx, -math.sqrt(max(0.0, float(eb @ eb) - bx * bx))


def reference_march(p, tris, splits, starts):
    """Dijkstra order with heapq; each settled vertex updates the other two corners of its triangles
    (edge and triangle candidates), reopening a settled vertex a later update shortens; obtuse
    corners read their virtual triangles (from ``splits``, laid flat here from their lengths) when
    they leave the queue."""
    corners: dict = {}
    for t in tris:
        for k in range(3):
            corners.setdefault(int(t[k]), []).append((int(t[(k + 1) % 3]), int(t[(k + 2) % 3])))
    n = len(p)
    dist, done, heap = [math.inf] * n, [False] * n, []
    for v, d in starts:
        dist[v] = min(dist[v], d)
    for v, _ in starts:
        heapq.heappush(heap, (dist[v], v))
    while heap:
        d, v = heapq.heappop(heap)
        if done[v] or d > dist[v]:
            continue
        best = d
        for u, w, lo, lu, lw in splits.get(v, []):
            if done[w]:
                c = dist[w] + lw
                if done[u]:
                    cos_u = (lo * lo + lu * lu - lw * lw) / (2 * lo * lu)
                    sin_u = math.sqrt(max(0.0, 1 - cos_u * cos_u))
                    c = min(c, _through_edge(dist[u], dist[w], lo, lu * cos_u, -lu * sin_u))
                best = min(best, c)
        if best < d:
            dist[v] = best
            heapq.heappush(heap, (best, v))
            continue
        done[v] = True
        for a, b in corners.get(v, []):
            for tgt, other in ((b, a), (a, b)):
                if done[tgt] and done[other]:
                    c = _through_edge(d, dist[other], *_frame(p, v, other, tgt))
                    if c < dist[tgt] * (1 - 1e-6):
                        done[tgt], dist[tgt] = False, c
                        heapq.heappush(heap, (c, tgt))
                elif not done[tgt]:
                    c = d + float(np.linalg.norm(p[tgt] - p[v]))
                    if done[other]:
                        c = min(c, _through_edge(d, dist[other], *_frame(p, v, other, tgt)))
                    if c < dist[tgt]:
                        dist[tgt] = c
                        heapq.heappush(heap, (c, tgt))
    return np.array([dist[i] if done[i] else math.inf for i in range(n)])


def test_kernel_equals_slow_reference(shared_data):
    from usdface.io.meshes import read_mesh
    m = read_mesh(shared_data / "meshes" / "mediapipe_canonical_face_model_holes.obj")
    pts, tris = m.points, m.triangles()
    mm = MarchingMesh(pts, tris)
    splits: dict = {}
    for b in range(len(pts)):
        for k in range(mm.sptr[b], mm.sptr[b + 1]):
            splits.setdefault(b, []).append((int(mm.su[k]), int(mm.sw[k]), float(mm.slo[k]), float(mm.slu[k]),
                                             float(mm.slw[k])))
    tri, bary = sources_in(tris, 4, seed=5)
    vertex, _, settled = march(mm, pts, tri, bary)
    assert (settled == len(pts)).all()
    for s in range(4):
        q = bary[s] @ pts[tri[s]]
        starts = [(int(v), float(np.linalg.norm(pts[v] - q))) for v in set(tri[s].tolist())]
        ref = reference_march(pts, tris, splits, starts)
        np.testing.assert_allclose(vertex[:, s], ref, rtol=2e-6, atol=1e-7)


# ------------------------------------------------------------------------------------------------
# bounded searches, degenerate input


def test_bounded_searches(shared_data):
    from usdface.io.meshes import read_mesh
    m = read_mesh(shared_data / "meshes" / "makehuman_hm08_face_cm.obj")
    pts, tris = m.points, m.triangles()
    tri, bary = sources_in(tris, 6, seed=4)
    solver = GeodesicSolver(pts, tris, backend="fmm")
    full = solver.solve(tri, bary)
    assert full.report.settled_fraction == 1.0 and full.report.max_distance is None
    near = solver.solve(tri, bary, max_distance=4.0)          # cm: a few kernel widths
    assert near.report.max_distance == 4.0 and near.report.settled_fraction < 0.5
    inside = full.vertex <= 4.0 * (1 - 1e-6)
    np.testing.assert_allclose(near.vertex[inside], full.vertex[inside], rtol=1e-6)
    assert np.isinf(near.vertex[full.vertex > 4.0 * (1 + 1e-6)]).all()
    needed = pts[:, 1] < np.percentile(pts[:, 1], 25)
    part = solver.solve(tri, bary, needed=needed)
    np.testing.assert_allclose(part.vertex[needed], full.vertex[needed], rtol=1e-6)
    assert part.report.settled_fraction < 1.0
    # a bound beyond the mesh's size covers everything: unbounded, and said so
    with pytest.warns(DistanceWarning, match="ran unbounded"):
        wide = solver.solve(tri, bary, max_distance=1e4)
    assert wide.report.max_distance is None and "bounding-box diagonal" in wide.report.notes[0]
    np.testing.assert_array_equal(wide.vertex, full.vertex)


def test_degenerate_triangles_and_isolated_vertices():
    pts, tris = planar_mesh(80, seed=6)
    # a duplicated vertex glued by a zero-area triangle, and one vertex used by no triangle
    dup = len(pts)
    pts = np.concatenate([pts, pts[tris[0, :1]], [[50.0, 50.0, 0.0]]])
    tris = np.concatenate([tris, [[tris[0, 0], tris[0, 1], dup]]])
    tri, bary = np.array([[5, 5, 5]]), np.array([[1.0, 0.0, 0.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DistanceWarning)
        r = GeodesicSolver(pts, tris, backend="fmm", components="inf").solve(tri, bary)
    assert np.isfinite(r.vertex[:-1]).all() and np.isinf(r.vertex[-1]).all()
    assert r.vertex[dup, 0] == pytest.approx(r.vertex[tris[0, 0], 0], abs=1e-6)
