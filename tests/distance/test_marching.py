"""Fast-marching back-end ("fmm"): exact where the surface develops into a plane, close to exact
(MMP) geodesics on real faces, and the numba kernel equal to a slow pure-Python reference."""
from __future__ import annotations

import heapq
import math
import warnings
from collections import deque

import numpy as np
import pytest
from scipy.spatial import Delaunay

from usdface.distance import DistanceWarning, GeodesicSolver, geodesic_distances
from usdface.distance import graph as G
from usdface.distance.marching import MarchingMesh, march, queue_buckets


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
    np.testing.assert_array_equal(mm.points, pts[mm.order])
    pts = mm.points                                 # the tables number the vertices in their order
    b = np.repeat(np.arange(len(pts)), np.diff(mm.sptr))
    u, w = mm.split_vertices[:, 0].astype(int), mm.split_vertices[:, 1].astype(int)
    luw, lwb, bx, by = mm.split_geom.astype(np.float64).T
    for stored, x, y in ((luw, u, w), (lwb, w, b), (np.hypot(bx, by), u, b)):
        np.testing.assert_allclose(stored, np.linalg.norm(pts[x] - pts[y], axis=1), rtol=1e-6)
    # b in the frame u = origin, w on +x: (u->b . u->w / |uw|, -|cross| / |uw|)
    ub, uw = pts[b] - pts[u], pts[w] - pts[u]
    np.testing.assert_allclose(bx, np.einsum("ij,ij->i", ub, uw) / luw, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(by, -np.abs(np.cross(uw, ub)[:, 2]) / luw, rtol=1e-5, atol=1e-6)
    # each split corner: b's two virtual triangles share w; (b, u) and (b, w) within 90 degrees
    assert (np.einsum("ij,ij->i", pts[u] - pts[b], pts[w] - pts[b]) >= -1e-9).all()


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


class StrictQueue:
    """Strict distance order (heapq)."""

    def __init__(self):
        self.heap = []

    def push(self, d, v):
        heapq.heappush(self.heap, (d, v))

    def pop(self):
        return heapq.heappop(self.heap)[1] if self.heap else None


class BucketQueue:
    """The kernel's untidy queue: buckets ``width`` wide, first in first out within one, starting
    at the bucket of distance ``first``; a distance below the current bucket joins the current
    bucket."""

    def __init__(self, width, first):
        self.inv, self.buckets, self.size = 1.0 / width, {}, 0
        self.cur = int(first * self.inv)

    def push(self, d, v):
        self.buckets.setdefault(max(int(d * self.inv), self.cur), deque()).append(v)
        self.size += 1

    def pop(self):
        if not self.size:
            return None
        while not self.buckets.get(self.cur):
            self.cur += 1
        self.size -= 1
        return self.buckets[self.cur].popleft()


def reference_march(p, tris, splits, starts, queue):
    """Each vertex leaving ``queue`` (StrictQueue: Dijkstra order; BucketQueue) updates the other
    two corners of its triangles (edge and triangle candidates), reopening a settled vertex a later
    update shortens; obtuse corners read their virtual triangles (from ``splits``, laid flat here
    from their lengths) when they leave the queue. ``starts``: (vertex, distance)."""
    corners: dict = {}
    for t in tris:
        for k in range(3):
            corners.setdefault(int(t[k]), []).append((int(t[(k + 1) % 3]), int(t[(k + 2) % 3])))
    n = len(p)
    dist, done = [math.inf] * n, [False] * n
    for v, d in starts:
        dist[v] = d
        queue.push(d, v)
    while (v := queue.pop()) is not None:
        if done[v]:
            continue
        d = best = dist[v]
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
            queue.push(best, v)
            continue
        done[v] = True
        for a, b in corners.get(v, []):
            for tgt, other in ((b, a), (a, b)):
                if done[tgt] and done[other]:
                    c = _through_edge(d, dist[other], *_frame(p, v, other, tgt))
                    if c < dist[tgt] * (1 - 1e-6):
                        done[tgt], dist[tgt] = False, c
                        queue.push(c, tgt)
                elif not done[tgt]:
                    c = d + float(np.linalg.norm(p[tgt] - p[v]))
                    if done[other]:
                        c = min(c, _through_edge(d, dist[other], *_frame(p, v, other, tgt)))
                    if c < dist[tgt]:
                        dist[tgt] = c
                        queue.push(c, tgt)
    return np.array([dist[i] if done[i] else math.inf for i in range(n)])


def split_rows(mm):
    """{b: [(u, w, |uw|, |ub|, |wb|)]} of a MarchingMesh, in the mesh's vertex numbering."""
    splits: dict = {}
    for b in range(mm.n_points):
        for k in range(mm.sptr[b], mm.sptr[b + 1]):
            (u, w), (lo, lw, bx, by) = mm.order[mm.split_vertices[k]], mm.split_geom[k]
            splits.setdefault(int(mm.order[b]), []).append((int(u), int(w), float(lo), float(np.hypot(bx, by)),
                                                            float(lw)))
    return splits


def test_kernel_equals_slow_reference(shared_data):
    from usdface.io.meshes import read_mesh
    m = read_mesh(shared_data / "meshes" / "mediapipe_canonical_face_model_holes.obj")
    pts, tris = m.points, m.triangles()
    mm = MarchingMesh(pts, tris)
    splits = split_rows(mm)
    tri, bary = sources_in(tris, 4, seed=5)
    vertex, _, settled = march(mm, pts, tri, bary)
    assert (settled == len(pts)).all()
    width = queue_buckets(mm)[0]
    for s in range(4):
        q = bary[s] @ pts[tri[s]]
        starts = [(v, float(np.linalg.norm(pts[v] - q))) for v in dict.fromkeys(tri[s].tolist())]
        ref = reference_march(pts, tris, splits, starts, BucketQueue(width, min(d for _, d in starts)))
        np.testing.assert_allclose(vertex[:, s], ref, rtol=2e-6, atol=1e-7)
        # the untidy order moves distances by much less than the method's error (0.3-1 % here)
        strict = reference_march(pts, tris, splits, starts, StrictQueue())
        np.testing.assert_allclose(vertex[:, s], strict, rtol=3e-5, atol=1e-7)


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


# ------------------------------------------------------------------------------------------------
# the pieces: the triangle update with its bound, the tables, the report


def test_through_edge_with_bound_equals_reference():
    """The kernel's update returns the reference distance when it is below the bound, +inf when
    it is not (a late-update check must never lengthen a settled distance)."""
    from usdface.distance.marching import _through_edge as kernel
    rng = np.random.default_rng(0)
    checked = below = 0
    for i in range(4000):
        L = rng.uniform(0.2, 2.0)
        px, py = rng.uniform(-1.0, 3.0), -rng.uniform(0.0, 2.0)
        if i % 2:       # distances of a true source above the edge: the update usually applies
            sx, sy = rng.uniform(-2.0, 4.0), rng.uniform(0.05, 5.0)
            du, da = np.hypot(sx, sy), np.hypot(sx - L, sy)
        else:           # any distances: circles that may not meet
            du, da = rng.uniform(0.5, 6.0, 2)
        ref = _through_edge(du, da, L, px, py)
        bound = rng.choice([np.inf, ref * rng.uniform(0.9, 1.1) if np.isfinite(ref) else rng.uniform(1, 8)])
        got = kernel(du, da, L, px, py, bound)
        if ref < bound:
            assert got == pytest.approx(ref, rel=1e-12), (du, da, L, px, py, bound)
            below += 1
        else:
            assert got == np.inf, (du, da, L, px, py, bound, ref, got)
        checked += np.isfinite(ref)
    assert checked > 800 and below > 400


def test_wedge_tables_equal_triangle_geometry(shared_data):
    """Each vertex's wedges are its triangles' corners in triangle order, laid flat: lengths and
    the far vertex's position in the frame (v at 0, the other on +x) from the points."""
    from usdface.io.meshes import read_mesh
    m = read_mesh(shared_data / "meshes" / "mediapipe_canonical_face_model_holes.obj")
    p, t = m.points.astype(np.float64), m.triangles()
    mm = MarchingMesh(p, t)
    rows = {v: [] for v in range(len(p))}
    for f in t:
        for k in range(3):
            rows[int(f[k])].append((int(f[(k + 1) % 3]), int(f[(k + 2) % 3])))
    assert mm.ptr[-1] == 3 * len(t)
    np.testing.assert_array_equal(np.sort(mm.order), np.arange(len(p)))
    np.testing.assert_array_equal(mm.rank[mm.order], np.arange(len(p)))
    for v in range(0, len(p), 7):
        r = mm.rank[v]                                   # v's place in the tables' order
        got = mm.order[mm.wedge_vertices[mm.ptr[r]:mm.ptr[r + 1]]].tolist()
        assert [tuple(x) for x in got] == rows[v]
        for (a, b), g in zip(rows[v], mm.wedge_geom[mm.ptr[r]:mm.ptr[r + 1]].astype(np.float64)):
            la, bx, by = _frame(p, v, a, b)
            lb, ax, ay = _frame(p, v, b, a)
            np.testing.assert_allclose(g, [la, lb, bx, by], rtol=2e-6, atol=1e-6)
            np.testing.assert_allclose(g[2:] * la / lb, [ax, ay], rtol=2e-6, atol=1e-6)   # a's frame


def test_kernel_equals_slow_reference_on_the_makehuman_face(shared_data):
    """Half of this face's triangles are obtuse: many splits, requeues and late updates."""
    from usdface.io.meshes import read_mesh
    m = read_mesh(shared_data / "meshes" / "makehuman_hm08_face_cm.obj")
    pts, tris = m.points, m.triangles()
    mm = MarchingMesh(pts, tris)
    splits = split_rows(mm)
    rng = np.random.default_rng(7)
    tri = tris[rng.choice(len(tris), 2, replace=False)]
    bary = rng.dirichlet([2.0, 2.0, 2.0], size=2)
    vertex, _, settled = march(mm, pts, tri, bary)
    assert (settled == len(pts)).all()
    width = queue_buckets(mm)[0]
    for s in range(2):
        q = bary[s] @ pts[tri[s]]
        starts = [(v, float(np.linalg.norm(pts[v] - q))) for v in dict.fromkeys(tri[s].tolist())]
        ref = reference_march(pts, tris, splits, starts, BucketQueue(width, min(d for _, d in starts)))
        np.testing.assert_allclose(vertex[:, s], ref, rtol=2e-6, atol=1e-7)
        strict = reference_march(pts, tris, splits, starts, StrictQueue())
        np.testing.assert_allclose(vertex[:, s], strict, rtol=3e-5, atol=1e-7)


def test_report_times_set_up_and_searches(caplog):
    """The solver reports its set-up (first solve only) and its searches, and logs them on one
    INFO line (benchmarks/bench_distances.py reads it from `usdface distances -v`)."""
    import logging
    import re
    pts, tris = planar_mesh(200, seed=9)
    solver = GeodesicSolver(pts, tris, backend="fmm")
    tri, bary = sources_in(tris, 3, seed=3)
    with caplog.at_level(logging.INFO, logger="usdface"):
        first = solver.solve(tri, bary).report
        second = solver.solve(tri[:2], bary[:2]).report
    assert first.setup_seconds > 0 and first.search_seconds > 0 and first.threads >= 1
    assert second.setup_seconds == 0.0 and second.search_seconds > 0     # tables reused
    assert first.search_seconds <= first.seconds          # (the set-up includes the constructor's part)
    line = re.compile(r"geodesic fmm: (\d+) vertices x (\d+) sources in [\d.]+ s: set-up ([\d.]+) s, "
                      r"searches ([\d.]+) s \(([\d.]+) s a source on (\d+) threads\)")
    found = [line.search(r.getMessage()) for r in caplog.records]
    found = [m for m in found if m]
    assert [(int(m.group(1)), int(m.group(2))) for m in found] == [(len(pts), 3), (len(pts), 2)]


def test_vertex_order_of_the_mesh_does_not_matter(shared_data):
    """The tables renumber the vertices along a space-filling curve: a shuffled copy of the mesh
    gives the same distances, entry for entry."""
    from usdface.io.meshes import read_mesh
    m = read_mesh(shared_data / "meshes" / "makehuman_hm08_face_cm.obj")
    pts, tris = m.points, m.triangles()
    tri, bary = sources_in(tris, 5, seed=6)
    perm = np.random.default_rng(1).permutation(len(pts))        # new vertex i is old vertex perm[i]
    inv = np.empty_like(perm)
    inv[perm] = np.arange(len(perm))
    a = GeodesicSolver(pts, tris, backend="fmm").solve(tri, bary)
    b = GeodesicSolver(pts[perm], inv[tris], backend="fmm").solve(inv[tri], bary)
    np.testing.assert_array_equal(b.vertex[inv], a.vertex)
    np.testing.assert_array_equal(b.sources, a.sources)


def test_vertex_major_matrix_in_the_asked_type():
    """The (N, S) matrix comes vertex-major (C-contiguous, as the analysis layer stores it) in the
    asked type: float32 is the float64 result rounded."""
    pts, tris = planar_mesh(150, seed=10)
    tri, bary = sources_in(tris, 4, seed=11)
    d64 = GeodesicSolver(pts, tris, backend="fmm").distances(tri, bary)
    d32 = GeodesicSolver(pts, tris, backend="fmm", dtype=np.float32).distances(tri, bary)
    assert d64.flags.c_contiguous and d32.flags.c_contiguous and d32.dtype == np.float32
    np.testing.assert_array_equal(d32, d64.astype(np.float32))


def test_morton_order_equals_a_slow_reference():
    """The tables' vertex order: points sorted (stably) by their interleaved 10-bit grid
    coordinates, which keeps neighbours in space close in the order."""
    from usdface.distance.marching_tables import morton_order
    rng = np.random.default_rng(12)
    pts = np.concatenate([rng.uniform(-3, 7, (2000, 3)), np.zeros((3, 3))])     # ties keep their order
    lo, span = pts.min(axis=0), np.ptp(pts, axis=0).max()
    grid = ((pts - lo) * (1023.0 / span)).astype(np.int64)

    def code(g):
        return sum(((int(g[k]) >> b) & 1) << (3 * b + k) for b in range(10) for k in range(3))

    want = np.argsort([code(g) for g in grid], kind="stable")
    got = morton_order(pts)
    np.testing.assert_array_equal(got, want)
    step = np.linalg.norm(np.diff(pts[got], axis=0), axis=1).mean()
    assert step < 0.25 * np.linalg.norm(np.diff(pts, axis=0), axis=1).mean()
