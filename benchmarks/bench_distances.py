"""Distance-matrix benchmark: 41 markers on a face refined to >= 300k vertices.

Run by hand (not in CI):

    python benchmarks/bench_distances.py [--n 13] [--markers 41] [--pairs 200] [--exact-300k 1]

What it does, all in one run so the ratios compare like with like:

- builds a large face: the MakeHuman face (2020 vertices, shared/data/meshes) refined 1-to-n^2
  (planar: the surface and its holes do not change; n = 13 gives 327,988 vertices);
- places 41 surface-point markers (farthest-point spread over the face, random barycentrics);
- times usdface: Euclidean (Eq. 6), graph geodesic (Eq. 7), heat geodesic, hybrid (Eq. 8, paper
  defaults: regions 1 cm around the mouth and eye loops, sigma 2 cm, threshold 0.6) with the
  bounded search, and the hybrid computed from the full geodesic matrix (the saving);
- baseline A, the paper's approach: one A* shortest-path search per vertex-marker pair, stopping
  at the target (numba-compiled, Euclidean heuristic), timed on a sample of pairs and
  extrapolated to N x 41 pairs;
- baseline B: scipy.sparse.csgraph.dijkstra multi-source and potpourri3d's heat solver (default
  t_coef) called directly;
- accuracy at 300k against exact geodesics: because the refinement is planar, exact (MMP)
  distances on the original 2020-vertex mesh are the exact distances on the refined surface at
  the original vertices, for every marker; plus pygeodesic run on the full 300k mesh for a few
  markers (``--exact-300k``; minutes each).
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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=13, help="refinement factor (13 -> 328k vertices)")
    ap.add_argument("--markers", type=int, default=41)
    ap.add_argument("--pairs", type=int, default=200, help="pairs sampled for baseline A")
    ap.add_argument("--exact-300k", type=int, default=0,
                    help="markers also checked with pygeodesic on the whole big mesh (~5 min each at 328k)")
    ap.add_argument("--skip-heat", action="store_true")
    args = ap.parse_args(argv)

    print(f"machine: {machine()}")
    print(f"load average at start: {os.getloadavg()[0]:.2f} (other processes share the CPUs: compare ratios)")
    P, T, coarse_mesh = load_face()
    t0 = time.perf_counter()
    p, t = G.refine_triangles(P, T, args.n)
    print(f"mesh: MakeHuman face {len(P)} v refined 1-to-{args.n ** 2}: {len(p)} vertices, {len(t)} triangles "
          f"({time.perf_counter() - t0:.1f} s to build)")
    from usdface.mesh.topology import find_hole_regions
    coarse_loops = [r.loop for r in find_hole_regions(coarse_mesh) if r.role in ("mouth", "eye")]
    fine_loops = [lp for lp in G.boundary_loops(t) if any(np.isin(c, lp).all() for c in coarse_loops)]
    assert len(fine_loops) == 3
    ctri, cbary = spread_markers(P, T, args.markers)
    q = np.einsum("sk,skd->sd", cbary, P[ctri])
    tri, bary = locate_in_refined(p, t, q)
    nearest = np.array([tri[i][np.argmax(bary[i])] for i in range(len(tri))])
    N, S = len(p), len(tri)
    print(f"markers: {S} surface points; regions: mouth + 2 eye loops ({sum(map(len, fine_loops))} loop vertices)")
    print(f"N x S float64 = {N * S * 8 / 1e6:.0f} MB\n")
    results = {}

    def timed(name, fn, repeat=1):
        best = np.inf
        out = None
        for _ in range(repeat):
            t0 = time.perf_counter()
            out = fn()
            best = min(best, time.perf_counter() - t0)
        results[name] = best
        print(f"  {name:<46s} {best:8.3f} s   (peak RSS so far {peak_mb():6.0f} MB)", flush=True)
        return out

    # warm the numba kernels on the small mesh (compile / cache load is not the benchmark)
    GeodesicSolver(P, T).distances(ctri[:2], cbary[:2])
    print("usdface:")
    euc = timed("euclidean (Eq. 6)", lambda: euclidean_distances(p, tri, bary), repeat=3)
    solver = timed("graph: set-up (edges, components, CSR graph)", lambda: GeodesicSolver(p, t))
    _ = timed("  (edge graph built on first use)", lambda: solver.graph)

    def fresh(fn):
        def run():
            solver._last = None          # no cached result: every repeat searches again
            return fn()
        return run
    graph = timed("graph geodesic (Eq. 7), N x S + S x S", fresh(lambda: solver.solve(tri, bary)), repeat=3)
    hyb = timed("hybrid (Eq. 8), paper defaults, bounded",
                fresh(lambda: hybrid_distances(solver, tri, bary, fine_loops, radius=1.0, sigma=2.0)), repeat=3)
    hyb_full = timed("hybrid from the full geodesic matrix",
                     fresh(lambda: hybrid_distances(solver, tri, bary, fine_loops, radius=1.0, sigma=2.0,
                                                    bounded=False)), repeat=3)
    assert np.array_equal(hyb.vertex, hyb_full.vertex)
    w, _ = hybrid_weights(p, fine_loops, radius=1.0, sigma=2.0)
    rep = hyb.geodesic
    print(f"    hybrid: {100 * (w > 0.6).mean():.1f} % of vertices have w > 0.6; bounded searches settled "
          f"{100 * rep.settled_fraction:.1f} % of N x S vertex visits; " +
          ", ".join(f"{k} {v:.2f} s" for k, v in hyb.seconds.items()))
    for sig in (1.0, 0.5):
        h = hybrid_distances(solver, tri, bary, fine_loops, radius=1.0, sigma=sig)
        hf = hybrid_distances(solver, tri, bary, fine_loops, radius=1.0, sigma=sig, bounded=False)
        print(f"    (narrower sigma = {sig} cm: {100 * h.geodesic_vertices.mean():.1f} % of vertices w > 0.6, "
              f"settled {100 * h.geodesic.settled_fraction:.1f} %, geodesic part {h.seconds['geodesic']:.2f} s "
              f"bounded vs {hf.seconds['geodesic']:.2f} s full)")
    if not args.skip_heat:
        heat = timed("heat geodesic (auto t_coef), incl. set-up", lambda: GeodesicSolver(p, t, backend="heat").solve(tri, bary))
        print(f"    heat t_coef used: {heat.report.t_coef}")

    print("baseline B (libraries called directly):")
    from scipy.sparse.csgraph import dijkstra
    g = solver.graph
    timed("scipy csgraph.dijkstra multi-source (nearest v)", lambda: dijkstra(g, directed=False, indices=nearest), repeat=2)
    aug = G.augmented_graph(g, p, tri, bary)
    timed("scipy csgraph.dijkstra on the augmented graph", lambda: dijkstra(aug, directed=True, indices=N + np.arange(S)), repeat=2)
    if not args.skip_heat:
        import potpourri3d as pp3d

        def pp3d_heat():
            s = pp3d.MeshHeatMethodDistanceSolver(p, t)
            return np.stack([s.compute_distance(int(v)) for v in nearest])
        pp = timed("potpourri3d heat, default t_coef (nearest v)", pp3d_heat)

    print("baseline A (the paper: one A* search per vertex-marker pair):")
    astar = astar_kernel()
    ip, ix, wt = g.indptr.astype(np.int64), g.indices.astype(np.int64), g.data
    astar(ip, ix, wt, p, int(nearest[0]), int(nearest[1]))
    rng = np.random.default_rng(1)
    pairs = [(int(nearest[rng.integers(S)]), int(rng.integers(N))) for _ in range(args.pairs)]
    t0 = time.perf_counter()
    settled = 0
    for s_, v_ in pairs:
        d_, k_ = astar(ip, ix, wt, p, s_, v_)
        settled += k_
    per_pair = (time.perf_counter() - t0) / len(pairs)
    total_a = per_pair * N * S
    results["baseline A"] = total_a
    print(f"  {len(pairs)} sampled pairs: {1e3 * per_pair:.2f} ms per pair, {settled / len(pairs) / N * 100:.1f} % "
          f"of the mesh settled per pair; extrapolated to {N} x {S} pairs: {total_a:.0f} s = {total_a / 3600:.1f} h")

    print("\nratios (same run):")
    gbest = min(results["scipy csgraph.dijkstra multi-source (nearest v)"],
                results["scipy csgraph.dijkstra on the augmented graph"])
    print(f"  baseline A / usdface graph            {total_a / results['graph geodesic (Eq. 7), N x S + S x S']:10.0f} x")
    print(f"  baseline A / usdface hybrid           {total_a / results['hybrid (Eq. 8), paper defaults, bounded']:10.0f} x")
    print(f"  usdface graph / best scipy dijkstra   {results['graph geodesic (Eq. 7), N x S + S x S'] / gbest:10.2f}")
    if not args.skip_heat:
        print(f"  usdface heat / potpourri3d direct     "
              f"{results['heat geodesic (auto t_coef), incl. set-up'] / results['potpourri3d heat, default t_coef (nearest v)']:10.2f}")
    print(f"  hybrid bounded / hybrid full          "
          f"{results['hybrid (Eq. 8), paper defaults, bounded'] / results['hybrid from the full geodesic matrix']:10.2f}")

    print("\naccuracy at this resolution against exact geodesics (at the original 2020 vertices, all markers):")
    exact = GeodesicSolver(P, T, backend="exact").solve(ctri, cbary)
    ref = exact.vertex
    print(f"  graph (edge paths)            {rel_stats(graph.vertex[:len(P)], ref)}")
    if not args.skip_heat:
        print(f"  heat, auto t_coef             {rel_stats(heat.vertex[:len(P)], ref)}")
        print(f"  potpourri3d heat, default t   {rel_stats(pp[:, :len(P)].T, ref)}  (sources at nearest vertices)")
    print(f"  euclidean                     {rel_stats(euc[:len(P)], ref)}")
    if args.exact_300k and not args.skip_heat:
        print(f"exact MMP on the full {N}-vertex mesh for {args.exact_300k} marker(s):")
        for k in range(args.exact_300k):
            t0 = time.perf_counter()
            ex = GeodesicSolver(p, t, backend="exact").solve(tri[k:k + 1], bary[k:k + 1])
            el = time.perf_counter() - t0
            print(f"  marker {k}: exact {el:.0f} s ({ex.report.exact_inf_entries} +inf entries filled); heat vs exact over "
                  f"all {N} vertices: {rel_stats(heat.vertex[:, k:k + 1], ex.vertex)}")
    print(f"\npeak RSS {peak_mb():.0f} MB; load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
