"""The baseline of benchmarks/bench_distances.py: what a TD would write with scipy alone.

    python benchmarks/scipy_dijkstra_baseline.py MESH.usdc SOURCES.npy OUT.npy

Reads the mesh layer's points and faces with pxr, builds the undirected edge graph of the
polygons' fan triangulation (edge weight = Euclidean length; the same edges usdface's ``graph``
back-end searches), runs scipy.sparse.csgraph.dijkstra once with ``indices=`` all the source
vertices (one full, unbounded search per source: scipy's multi-source call; single-threaded), and
saves the (S, N) float64 matrix with numpy. SOURCES.npy holds the source vertex indices (int64):
bench_distances.py writes there the vertex nearest each bound marker point followed by the
constraint vertices the `usdface distances` run under test put in its analysis layer, so both
compute S full fields over the same mesh. It uses nothing from usdface. It prints the seconds of
its phases (imports, read, graph, dijkstra, save) as one JSON line.
"""
import time

STARTED = time.perf_counter()

import json  # noqa: E402
import sys  # noqa: E402

import numpy as np  # noqa: E402
from pxr import Usd, UsdGeom  # noqa: E402
from scipy.sparse import coo_matrix  # noqa: E402
from scipy.sparse.csgraph import dijkstra  # noqa: E402


def main(mesh_path, sources_path, out_path):
    phases = {"imports": time.perf_counter() - STARTED}
    t0 = time.perf_counter()
    stage = Usd.Stage.Open(mesh_path)
    mesh = next(UsdGeom.Mesh(p) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh))
    points = np.asarray(mesh.GetPointsAttr().Get(), dtype=np.float64)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(), dtype=np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), dtype=np.int64)
    t1 = time.perf_counter()
    # fan triangulation: polygon (v0, v1, ..., vk) -> edges v0-vi and vi-v(i+1)
    start = np.repeat(np.cumsum(counts) - counts, counts)
    pos = np.arange(indices.size) - start
    nxt = np.where(pos + 1 < np.repeat(counts, counts), np.arange(indices.size) + 1, start)
    a = np.concatenate([indices, indices[start][pos >= 2]])
    b = np.concatenate([indices[nxt], indices[pos >= 2]])
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = np.unique(lo * points.shape[0] + hi)
    lo, hi = key // points.shape[0], key % points.shape[0]
    w = np.linalg.norm(points[lo] - points[hi], axis=1)
    n = points.shape[0]
    graph = coo_matrix((w, (lo, hi)), shape=(n, n)).tocsr()
    sources = np.load(sources_path)
    t2 = time.perf_counter()
    dist = dijkstra(graph, directed=False, indices=sources)
    t3 = time.perf_counter()
    np.save(out_path, dist)
    phases.update(read=t1 - t0, graph=t2 - t1, dijkstra=t3 - t2, save=time.perf_counter() - t3)
    print(json.dumps(phases))


if __name__ == "__main__":
    main(*sys.argv[1:4])
