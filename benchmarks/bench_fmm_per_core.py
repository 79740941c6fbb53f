"""Fast marching against scipy's Dijkstra inside one process: time per source on one thread and on
numba's default threads, and the table build against scipy's edge graph.

Run by hand (not in CI):

    python benchmarks/bench_fmm_per_core.py [--n 17] [--sources 8] [--repeat 3]

The MakeHuman sample face refined 1-to-n^2 (n = 17: 560k vertices, the shared stand-in for a
592k-vertex scan). S vertex sources (seeded), full unbounded searches each: fmm
(:func:`usdface.distance.marching.march`) with ``numba.set_num_threads(1)`` and with numba's
default, scipy.sparse.csgraph.dijkstra (one core) on the edge graph. Repeats are interleaved,
medians printed with their ratio to Dijkstra. The set-up rows time a warm (numba cache loaded)
:class:`MarchingMesh` build, wall and CPU, against the edge graph scipy needs.

``benchmarks/bench_distances.py`` times the same work as whole command-line processes; this one
separates the kernels' cost per core from the share of the cores the machine gives a process,
which under load varies more than the kernels do. The load average is printed before and after.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

FACE = Path(__file__).resolve().parents[1] / "sample_assets" / "meshes" / "makehuman_hm08_face_cm.obj"


def timed(f, *args) -> tuple[float, float]:
    """(wall, CPU) seconds of one call."""
    w, c = time.perf_counter(), time.process_time()
    f(*args)
    return time.perf_counter() - w, time.process_time() - c


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=17, help="refinement of the face (17 -> 560k vertices)")
    ap.add_argument("--sources", type=int, default=8, help="vertex sources per timed call")
    ap.add_argument("--repeat", type=int, default=3, help="interleaved repeats (medians reported)")
    args = ap.parse_args(argv)

    import numba
    from scipy.sparse.csgraph import dijkstra

    from usdface.distance import graph as G
    from usdface.distance.marching import MarchingMesh, march
    from usdface.io.meshes import read_mesh

    face = read_mesh(FACE)
    p, t = G.refine_triangles(face.points, face.triangles(), args.n)
    src = np.random.default_rng(0).choice(len(p), args.sources, replace=False)
    tri, bary = np.repeat(src[:, None], 3, axis=1), np.tile([1.0, 0.0, 0.0], (src.size, 1))
    default_threads = numba.get_num_threads()
    print(f"{len(p)} vertices, {src.size} sources; {os.cpu_count()} CPUs, numba default {default_threads} threads; "
          f"load average {os.getloadavg()[0]:.2f}")
    mm = MarchingMesh(p, t)                    # loads the cached kernels: not timed
    march(mm, p, tri[:1], bary[:1])
    rows: dict = {k: [] for k in ("fmm 1 thread", f"fmm {default_threads} threads", "scipy dijkstra",
                                  "fmm tables", "scipy edge graph")}
    for _ in range(args.repeat):
        numba.set_num_threads(1)
        rows["fmm 1 thread"].append(timed(march, mm, p, tri, bary))
        numba.set_num_threads(default_threads)
        g = G.edge_graph(p, G.mesh_edges(t))
        # the edge graph is symmetric: directed=True searches the same graph without re-symmetrising
        # it on each call (a fixed cost the baseline script pays once for all its sources)
        rows["scipy dijkstra"].append(timed(lambda: dijkstra(g, directed=True, indices=src)))
        rows[f"fmm {default_threads} threads"].append(timed(march, mm, p, tri, bary))
        rows["fmm tables"].append(timed(MarchingMesh, p, t))
        rows["scipy edge graph"].append(timed(lambda: G.edge_graph(p, G.mesh_edges(t))))
    med = {k: np.median(np.asarray(v), axis=0) for k, v in rows.items()}
    base = med["scipy dijkstra"][0] / src.size
    print(f"{'':22s} {'wall s/src':>10s} {'cpu s/src':>10s} {'/dijkstra':>9s}")
    for k in ("scipy dijkstra", "fmm 1 thread", f"fmm {default_threads} threads"):
        w, c = med[k] / src.size
        print(f"{k:22s} {w:10.4f} {c:10.4f} {w / base:9.2f}")
    print(f"{'':22s} {'wall s':>10s} {'cpu s':>10s}")
    for k in ("fmm tables", "scipy edge graph"):
        print(f"{k:22s} {med[k][0]:10.3f} {med[k][1]:10.3f}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
