"""Distance-matrix benchmark: 41 markers on a real face refined to 0.3-2M vertices.

Run by hand (not in CI):

    python benchmarks/bench_distances.py [--n 17] [--markers 41] [--remesh 30000] [--skip-heat]

All in one process, so the ratios compare like with like on a shared machine:

- a large face: the MakeHuman face (2020 vertices, shared/data/meshes) refined 1-to-n^2 (planar:
  the surface and its holes do not change; n = 13: 327,988 vertices, 17: 560,420, 32: 1,983,230);
- 41 surface-point markers (farthest-point spread, random barycentrics);
- the baseline: scipy.sparse.csgraph.dijkstra multi-source computing the full, unbounded N x 41
  matrix (from the vertex nearest each marker), and the usdface back-ends: graph (Eq. 7, numba
  bucket queue), fmm (fast marching, the accurate one), fmm bounded at 3 kernel widths, hybrid (Eq. 8,
  paper defaults) on graph and on fmm, heat (potpourri3d, auto t_coef); wall time, CPU time (all
  threads) and peak memory of each (VmHWM reset before each, /proc/self/clear_refs);
- the paper's approach for scale: one A* search per vertex-marker pair, extrapolated;
- accuracy against exact geodesics over the pairs a kernel reaches (d above one mean edge length
  of the mesh and below 3 kernel widths, the default width 1.1 x the median marker spacing):
  the refinement is planar, so exact (MMP) distances on the original 2020-vertex mesh are the exact
  distances on the big mesh at the original vertices, for every marker;
- an irregular remesh (pymeshlab isotropic remeshing, ~30k vertices): every back-end against exact
  MMP computed on that mesh itself (``--remesh 0`` skips it; minutes).
"""
from __future__ import annotations

import argparse
import os
import platform
import resource
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from usdface.distance import (GeodesicSolver, euclidean_distances, hybrid_distances,  # noqa: E402
                              hybrid_weights)
from usdface.distance import graph as G  # noqa: E402

from procmem import reset_peak, status_mb  # noqa: E402  (benchmarks/procmem.py)

MESH = REPO.parent / "shared" / "data" / "meshes" / "makehuman_hm08_face_cm.obj"


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def machine() -> str:
    cpu = platform.processor() or "?"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = "?"
    try:
        for line in open("/proc/meminfo"):
            if line.startswith("MemTotal"):
                mem = f"{int(line.split()[1]) / 1024 ** 2:.1f} GB"
    except OSError:
        pass
    import numba
    import scipy
    import potpourri3d  # noqa: F401
    return (f"{cpu}, {os.cpu_count()} logical CPUs, {mem} RAM; Python {platform.python_version()}, "
            f"numpy {np.__version__}, scipy {scipy.__version__}, numba {numba.__version__} "
            f"({numba.get_num_threads()} threads)")


def load_face():
    try:
        from usdface.io.meshes import read_mesh
        m = read_mesh(MESH)
        return m.points, m.triangles(), m
    except ImportError:  # pragma: no cover
        raise SystemExit("usdface.io.meshes.read_mesh is needed")


def spread_markers(points, tris, k, seed=0):
    """k coarse triangles spread by farthest-point sampling, random barycentrics."""
    rng = np.random.default_rng(seed)
    cen = points[tris].mean(axis=1)
    chosen = [int(np.argmin(cen[:, 1]))]
    d = np.linalg.norm(cen - cen[chosen[0]], axis=1)
    for _ in range(k - 1):
        chosen.append(int(np.argmax(d)))
        d = np.minimum(d, np.linalg.norm(cen - cen[chosen[-1]], axis=1))
    return tris[chosen], rng.dirichlet([3.0, 3.0, 3.0], size=k)


def locate_in_refined(p_ref, t_ref, q):
    """(triangle vertices, barycentrics) of points q in the refined mesh."""
    from scipy.spatial import cKDTree
    tree = cKDTree(p_ref[t_ref].mean(axis=1))
    tri, bary = [], []
    for x in q:
        for c in tree.query(x, k=32)[1]:
            a = p_ref[t_ref[c]]
            m = np.stack([a[1] - a[0], a[2] - a[0]], axis=1)
            uv = np.linalg.lstsq(m, x - a[0], rcond=None)[0]
            b = np.array([1 - uv.sum(), uv[0], uv[1]])
            if b.min() > -1e-9 and np.linalg.norm(b @ a - x) < 1e-9:
                b = np.clip(b, 0, None)
                tri.append(t_ref[c])
                bary.append(b / b.sum())
                break
        else:
            raise RuntimeError("marker not located")
    return np.array(tri), np.array(bary)


def astar_kernel():
    import numba as nb

    @nb.njit(cache=True)
    def astar(indptr, indices, weights, pts, s, t):
        n = indptr.size - 1
        g = np.full(n, np.inf)
        done = np.zeros(n, np.bool_)
        hk = np.empty(1024, np.float64)
        hv = np.empty(1024, np.int64)
        size = 0
        g[s] = 0.0
        tx, ty, tz = pts[t, 0], pts[t, 1], pts[t, 2]
        hk[0] = np.sqrt((pts[s, 0] - tx) ** 2 + (pts[s, 1] - ty) ** 2 + (pts[s, 2] - tz) ** 2)
        hv[0] = s
        size = 1
        settled = 0
        while size > 0:
            v = hv[0]
            size -= 1
            lk, lv = hk[size], hv[size]
            i = 0
            while True:
                c = 2 * i + 1
                if c >= size:
                    break
                if c + 1 < size and hk[c + 1] < hk[c]:
                    c += 1
                if hk[c] >= lk:
                    break
                hk[i], hv[i] = hk[c], hv[c]
                i = c
            hk[i], hv[i] = lk, lv
            if done[v]:
                continue
            done[v] = True
            settled += 1
            if v == t:
                return g[t], settled
            for k in range(indptr[v], indptr[v + 1]):
                u = indices[k]
                nd = g[v] + weights[k]
                if nd < g[u]:
                    g[u] = nd
                    f = nd + np.sqrt((pts[u, 0] - tx) ** 2 + (pts[u, 1] - ty) ** 2 + (pts[u, 2] - tz) ** 2)
                    if size == hk.size:
                        hk = np.concatenate((hk, np.empty(hk.size)))
                        hv = np.concatenate((hv, np.empty(hv.size, np.int64)))
                    i = size
                    size += 1
                    while i > 0:
                        par = (i - 1) >> 1
                        if hk[par] <= f:
                            break
                        hk[i], hv[i] = hk[par], hv[par]
                        i = par
                    hk[i], hv[i] = f, u
        return np.inf, settled
    return astar


def rel_stats(a, ref):
    far = ref > 0.05 * ref.max()
    rel = np.abs(a - ref)[far] / ref[far]
    diam = ref.max()
    return (f"mean rel {100 * rel.mean():5.2f} %  max rel {100 * rel.max():6.1f} %  "
            f"max abs {np.abs(a - ref).max():6.3f} ({100 * np.abs(a - ref).max() / diam:4.1f} % of {diam:.1f})  "
            f"entries off by > 5 % of diameter: {100 * (np.abs(a - ref) > 0.05 * diam).mean():.2f} %")


def window_stats(a, ref, lo, hi):
    """Relative error over the pairs a kernel reaches: lo < exact distance < hi."""
    m = (ref > lo) & (ref < hi) & np.isfinite(ref)
    rel = np.abs(a - ref)[m] / ref[m]
    signed = (a - ref)[m] / ref[m]
    return (f"mean {100 * rel.mean():6.3f} %  (signed {100 * signed.mean():+6.3f} %)  p99 {100 * np.percentile(rel, 99):6.2f} %"
            f"  max {100 * rel.max():6.1f} %  over {m.sum()} pairs"), rel.mean()


def remesh_face(P, T, target_vertices, seed=0):
    import pymeshlab
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(P, T))
    area = 0.5 * np.linalg.norm(np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]), axis=1).sum()
    edge = float(np.sqrt(4 * area / (np.sqrt(3) * 2 * target_vertices)))
    ms.meshing_isotropic_explicit_remeshing(targetlen=pymeshlab.PureValue(edge), iterations=6)
    m = ms.current_mesh()
    return np.asarray(m.vertex_matrix(), dtype=np.float64), np.asarray(m.face_matrix(), dtype=np.int64)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=17, help="refinement factor (17 -> 560k vertices, 32 -> 2M)")
    ap.add_argument("--markers", type=int, default=41)
    ap.add_argument("--pairs", type=int, default=200, help="pairs sampled for the A* baseline")
    ap.add_argument("--repeat", type=int, default=2, help="timed repeats (best kept) of the fast methods")
    ap.add_argument("--remesh", type=int, default=30000, help="vertices of the irregular remesh (0: skip)")
    ap.add_argument("--remesh-markers", type=int, default=41)
    ap.add_argument("--skip-heat", action="store_true")
    args = ap.parse_args(argv)

    print(f"machine: {machine()}")
    print(f"load average at start: {os.getloadavg()[0]:.2f} (other processes share the CPUs: compare ratios)")
    from usdface.rbf.stiffness import DEFAULT_WIDTH_FACTOR, median_marker_spacing_from_points
    P, T, coarse_mesh = load_face()
    t0 = time.perf_counter()
    p, t = G.refine_triangles(P, T, args.n)
    e = G.mesh_edges(t)
    h = float(np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1).mean())
    del e
    print(f"mesh: MakeHuman face {len(P)} v refined 1-to-{args.n ** 2}: {len(p)} vertices, {len(t)} triangles, "
          f"mean edge {h:.4f} cm ({time.perf_counter() - t0:.1f} s to build)")
    from usdface.mesh.topology import find_hole_regions
    coarse_loops = [r.loop for r in find_hole_regions(coarse_mesh) if r.role in ("mouth", "eye")]
    fine_loops = [lp for lp in G.boundary_loops(t) if any(np.isin(c, lp).all() for c in coarse_loops)]
    assert len(fine_loops) == 3
    ctri, cbary = spread_markers(P, T, args.markers)
    q = np.einsum("sk,skd->sd", cbary, P[ctri])
    tri, bary = locate_in_refined(p, t, q)
    nearest = np.array([tri[i][np.argmax(bary[i])] for i in range(len(tri))])
    N, S = len(p), len(tri)
    width = DEFAULT_WIDTH_FACTOR * median_marker_spacing_from_points(q)
    print(f"markers: {S} surface points, default kernel width {width:.2f} cm; regions: mouth + 2 eye loops")
    print(f"N x S float64 = {N * S * 8 / 1e6:.0f} MB\n")
    results = {}

    def timed(name, fn, repeat=1):
        best, best_cpu, out = np.inf, np.inf, None
        base = reset_peak()
        for _ in range(repeat):
            out = None
            t0, c0 = time.perf_counter(), time.process_time()
            out = fn()
            best = min(best, time.perf_counter() - t0)
            best_cpu = min(best_cpu, time.process_time() - c0)
        results[name] = best
        results[name + " cpu"] = best_cpu
        print(f"  {name:44s} {best:8.2f} s wall {best_cpu:8.2f} s CPU   peak +{status_mb('VmHWM') - base:6.0f} MB "
              f"(RSS high-water {status_mb('VmHWM'):6.0f} MB)", flush=True)
        return out

    # warm the numba kernels on the small mesh (compile / cache load is not the benchmark)
    for b in ("graph", "fmm"):
        GeodesicSolver(P, T, backend=b).distances(ctri[:2], cbary[:2])

    def fresh(solver, fn):
        def run():
            solver._last = None          # no cached result: every repeat searches again
            return fn()
        return run

    print(f"baseline (numba threads: {numba_threads()}; scipy is single-threaded):")
    from scipy.sparse.csgraph import dijkstra
    gsolver = GeodesicSolver(p, t, backend="graph")
    g = gsolver.graph
    timed("scipy csgraph.dijkstra multi-source, N x 41", lambda: dijkstra(g, directed=False, indices=nearest),
          repeat=args.repeat)
    print("usdface:")
    euc = timed("euclidean (Eq. 6)", lambda: euclidean_distances(p, tri, bary))
    graph = timed("graph geodesic (Eq. 7), N x S + S x S", fresh(gsolver, lambda: gsolver.solve(tri, bary)),
                  repeat=args.repeat)
    fsolver = GeodesicSolver(p, t, backend="fmm")
    timed("fmm: tables (once per mesh)", lambda: fsolver.marching)
    fmm = timed("fmm geodesic, N x S + S x S", fresh(fsolver, lambda: fsolver.solve(tri, bary)),
                repeat=args.repeat)
    bound = 3.0 * width
    fmm_b = timed(f"fmm bounded at 3 widths ({bound:.1f} cm)",
                  fresh(fsolver, lambda: fsolver.solve(tri, bary, max_distance=bound)), repeat=args.repeat)
    print(f"    bounded fmm settled {100 * fmm_b.report.settled_fraction:.1f} % of the N x S vertex visits")
    hyb_g = timed("hybrid (Eq. 8) on graph, paper defaults", fresh(gsolver, lambda: hybrid_distances(
        gsolver, tri, bary, fine_loops, radius=1.0, sigma=2.0)), repeat=args.repeat)
    hyb_f = timed("hybrid (Eq. 8) on fmm, paper defaults", fresh(fsolver, lambda: hybrid_distances(
        fsolver, tri, bary, fine_loops, radius=1.0, sigma=2.0)), repeat=args.repeat)
    print(f"    hybrid: {100 * hyb_f.geodesic_vertices.mean():.1f} % of vertices have w > 0.6; bounded searches "
          f"settled {100 * hyb_f.geodesic.settled_fraction:.1f} % (fmm), {100 * hyb_g.geodesic.settled_fraction:.1f} % (graph)")
    heat = None
    if not args.skip_heat:
        heat = timed("heat geodesic (potpourri3d, auto t_coef), incl. set-up",
                     lambda: GeodesicSolver(p, t, backend="heat").solve(tri, bary))
        print(f"    heat t_coef used: {heat.report.t_coef}")

    print("the paper's approach (one A* search per vertex-marker pair):")
    astar = astar_kernel()
    ip, ix, wt = g.indptr.astype(np.int64), g.indices.astype(np.int64), g.data
    astar(ip, ix, wt, p, int(nearest[0]), int(nearest[1]))
    rng = np.random.default_rng(1)
    pairs = [(int(nearest[rng.integers(S)]), int(rng.integers(N))) for _ in range(args.pairs)]
    t0 = time.perf_counter()
    for s_, v_ in pairs:
        astar(ip, ix, wt, p, s_, v_)
    per_pair = (time.perf_counter() - t0) / len(pairs)
    total_a = per_pair * N * S
    print(f"  {len(pairs)} sampled pairs: {1e3 * per_pair:.2f} ms per pair; extrapolated to {N} x {S} pairs: "
          f"{total_a:.0f} s = {total_a / 3600:.1f} h")

    sc = results["scipy csgraph.dijkstra multi-source, N x 41"]
    scc = results["scipy csgraph.dijkstra multi-source, N x 41 cpu"]
    print("\nratios to scipy's multi-source Dijkstra (same run; goal: fmm <= 1.5, graph <= 1.0):")
    for name in ("graph geodesic (Eq. 7), N x S + S x S", "fmm geodesic, N x S + S x S",
                 f"fmm bounded at 3 widths ({bound:.1f} cm)", "hybrid (Eq. 8) on fmm, paper defaults") + \
            (() if heat is None else ("heat geodesic (potpourri3d, auto t_coef), incl. set-up",)):
        print(f"  {name:44s} wall {results[name] / sc:6.2f}   CPU {results[name + ' cpu'] / scc:6.2f}")
    print(f"  A* per pair / usdface fmm                   {total_a / results['fmm geodesic, N x S + S x S']:8.0f} x")

    print(f"\naccuracy against exact geodesics (MMP on the 2020-vertex original = exact at its vertices on the "
          f"refined surface), pairs with {h:.3f} < d < {3 * width:.2f} cm (one mean edge .. 3 kernel widths):")
    exact = GeodesicSolver(P, T, backend="exact").solve(ctri, cbary)
    ref = exact.vertex
    rows = [("fmm", fmm.vertex[:len(P)], 3 * width), ("graph (edge paths)", graph.vertex[:len(P)], 3 * width)]
    if heat is not None:
        rows.append(("heat, auto t_coef", heat.vertex[:len(P)], 3 * width))
    rows.append(("euclidean", euc[:len(P)], 3 * width))
    # the bounded search leaves +inf past its bound: pairs exactly at the bound can fall either side
    rows.append(("fmm bounded (d < 0.99 bound)", fmm_b.vertex[:len(P)], 0.99 * bound))
    for name, a, hi in rows:
        print(f"  {name:28s} {window_stats(np.asarray(a, dtype=np.float64), ref, h, hi)[0]}")
    print(f"  (all pairs beyond one edge: fmm {window_stats(fmm.vertex[:len(P)], ref, h, np.inf)[0]})")
    print(f"  sources S x S: fmm {window_stats(fmm.sources, exact.sources, h, 3 * width)[0]}")

    if args.remesh:
        print(f"\nirregular remesh (pymeshlab isotropic remeshing of the original face, target {args.remesh} vertices):")
        pr, tr = remesh_face(P, T, args.remesh)
        er = G.mesh_edges(tr)
        hr = float(np.linalg.norm(pr[er[:, 0]] - pr[er[:, 1]], axis=1).mean())
        k = args.remesh_markers
        rtri, rbary = locate_nearest(pr, tr, q[:k])
        print(f"  {len(pr)} vertices, {len(tr)} triangles, mean edge {hr:.3f} cm; {k} markers (closest surface points)")
        t0 = time.perf_counter()
        ex = GeodesicSolver(pr, tr, backend="exact").solve(rtri, rbary)
        print(f"  exact MMP: {time.perf_counter() - t0:.0f} s ({ex.report.exact_inf_entries} +inf entries filled)")
        for b in ("fmm", "graph") + (() if args.skip_heat else ("heat",)):
            t0 = time.perf_counter()
            r = GeodesicSolver(pr, tr, backend=b).solve(rtri, rbary)
            el = time.perf_counter() - t0
            print(f"  {b:6s} {el:6.2f} s  {window_stats(r.vertex, ex.vertex, hr, 3 * width)[0]}")
    print(f"\npeak RSS {status_mb('VmHWM'):.0f} MB (since the last reset); load average at end: {os.getloadavg()[0]:.2f}")


def numba_threads() -> int:
    import numba
    return numba.get_num_threads()


def locate_nearest(p, t, x):
    """(triangle vertices, barycentrics) of the closest surface points of a mesh to points x."""
    from usdface.mesh.closest import closest_points
    fi, b = closest_points(p, t, x)[:2]
    return t[fi], b


if __name__ == "__main__":
    main()
