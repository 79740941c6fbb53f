"""The fast-marching queue's bucket width: speed and distances against finer buckets and exact geodesics.

    python benchmarks/fmm_queue_sweep.py [--n 17] [--sources 6] [--widths 1,2,4,8,16,64]

For each value of ``usdface.distance.marching.BUCKETS_PER_EDGE`` (buckets per mean edge length;
finer buckets = closer to a strict distance order) it runs the fmm searches on one thread and
prints the CPU time per source, the largest and mean relative difference from the finest setting
(over vertices beyond one mean edge from the source), and the mean error against exact geodesics
(MMP on the original face: exact at its vertices on the planar refinement) over the pairs from
one mean edge to 3 kernel widths. Faces: the MakeHuman face refined 1-to-n^2 (where the constant
was chosen) and the MediaPipe face with holes refined 1-to-4 (held out).
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

MESHES = REPO / "sample_assets" / "meshes"


def sweep(name, path, n, k, widths, seed=3):
    import numba

    from usdface.distance import GeodesicSolver
    from usdface.distance import graph as G
    from usdface.distance import marching
    from usdface.io.meshes import read_mesh

    face = read_mesh(path)
    P, T = face.points, face.triangles()
    p, t = G.refine_triangles(P, T, n)
    rng = np.random.default_rng(seed)
    src = rng.choice(len(P), k, replace=False)                    # original vertices keep their index
    tri, bary = np.repeat(src[:, None], 3, axis=1), np.tile([1.0, 0.0, 0.0], (k, 1))
    e = G.mesh_edges(T)
    h = float(np.linalg.norm(P[e[:, 0]] - P[e[:, 1]], axis=1).mean())
    exact = GeodesicSolver(P, T, backend="exact").distances(tri, bary)
    width = 1.1 * 3.0                                             # ~ the default kernel width on these faces, cm
    window = (exact > h) & (exact < 3 * width)
    solver = GeodesicSolver(p, t, backend="fmm")
    numba.set_num_threads(1)
    rows, fields = [], {}
    default = marching.BUCKETS_PER_EDGE
    try:
        for w in sorted(widths, reverse=True):
            marching.BUCKETS_PER_EDGE = w
            solver._last = None
            solver.solve(tri[:1], bary[:1])                       # tables built, kernels loaded
            solver._last = None
            c0 = time.thread_time()
            d = np.asarray(solver.solve(tri, bary).vertex)
            rows.append((w, (time.thread_time() - c0) / k))
            fields[w] = d
    finally:
        marching.BUCKETS_PER_EDGE = default
    finest = fields[max(widths)]
    far = finest > solver.marching.mean_edge
    print(f"\n{name}: {len(p)} vertices (1-to-{n * n}), {k} vertex sources, one thread; load average {os.getloadavg()[0]:.2f}")
    print(f"  {'buckets/edge':>12s} {'CPU s/source':>13s} {'max rel diff':>13s} {'mean rel diff':>14s} {'error vs exact':>15s}")
    for w, cpu in rows:
        rel = np.abs(fields[w] - finest)[far] / finest[far]
        err = np.abs(fields[w][:len(P)] - exact)[window] / exact[window]
        print(f"  {w:12d} {cpu:13.3f} {rel.max():13.2e} {rel.mean():14.2e} {100 * err.mean():14.3f}%")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=17)
    ap.add_argument("--sources", type=int, default=6)
    ap.add_argument("--widths", default="1,2,4,8,16,64")
    args = ap.parse_args(argv)
    widths = [int(x) for x in args.widths.split(",")]
    sweep("MakeHuman face (tuned on)", MESHES / "makehuman_hm08_face_cm.obj", args.n, args.sources, widths)
    sweep("MediaPipe face with holes (held out)", MESHES / "mediapipe_canonical_face_model_holes.obj", 16,
          args.sources, widths)


if __name__ == "__main__":
    main()
