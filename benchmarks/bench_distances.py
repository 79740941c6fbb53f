"""Geodesic distances through the command line, against a plain scipy script, as a user runs them.

Run by hand (not in CI):

    python benchmarks/bench_distances.py [--n 17] [--middle 6] [--repeat 3] [--workdir DIR]

For each face -- the MakeHuman sample face (2020 vertices), refined 1-to-``middle``^2 and
1-to-``n``^2 (planar refinement: the surface and its holes do not change; n = 6: 71k vertices,
13: 328k, 17: 560k) -- it prepares the layers with the real command line, as the README's main job
does:

    usdface import-mesh face.obj -o mesh.usdc
    usdface import-capture sample_assets/capture/JawMoCap.ma -o capture.usdc      (once)
    usdface bind --mesh mesh.usdc --capture capture.usdc --layout <sample layout> -o binding.usda

then times, each as its own process, in interleaved repeats (medians reported):

(a) ``usdface distances --mesh mesh.usdc --binding binding.usda --method geodesic --backend fmm
    -o A.usdc --json -v``;
(b) the same with ``--backend graph``;
(c) ``python benchmarks/scipy_dijkstra_baseline.py mesh.usdc sources.npy D.npy``: imports pxr,
    numpy and scipy, reads the mesh layer's points and faces, builds the edge graph, runs
    scipy.sparse.csgraph.dijkstra with ``indices=`` the S source vertices (one full, unbounded
    search each, one core) and saves the (S, N) matrix with numpy.

The baseline computes the same entries as the CLI: S = the M bound markers + the P constraint
vertices of run (a)'s analysis layer. A marker is a surface point inside a triangle; the CLI
starts its search from the three vertices of that triangle at their straight distances, the
baseline starts from the marker's nearest vertex (``nearestVertices`` of the binding layer): one
search per source either way, over the whole mesh, nothing bounded. The constraint vertices are
vertices for both.

Printed per size: wall and CPU (user + system) time of each process, the searches' time per
source and the set-up time (from the ``usdface: INFO: geodesic ...`` line that ``-v`` prints; the
baseline prints its own phases), the ratios to the baseline of the same run, and fmm's error
against exact geodesics (MMP on the 2020-vertex face: exact at its vertices on the refined surface,
marker columns, pairs from one mean edge to 3 kernel widths). The load average is printed before
and after each size: other processes share the CPUs, so read the ratios; the CPU ratio does not
depend on the share of the cores a process is given.

``--usdface-root DIR`` times another checkout's `usdface distances` (e.g. an older commit
exported with ``git archive``) on the same layers; when its output has no timing line, the
set-up and search times come from a probe process that runs that checkout's GeodesicSolver on
the same sources (``--probe`` adds the probe for this checkout too).

Warm runs: the first `usdface distances` run of a checkout compiles the numba kernels and caches
them on disk (``first run`` below); every timed run loads them from that cache.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

SAMPLE = REPO / "sample_assets"
FACE = SAMPLE / "meshes" / "makehuman_hm08_face_cm.obj"
TAKE = SAMPLE / "capture" / "JawMoCap.ma"
LAYOUT = SAMPLE / "layouts" / "makehuman_hm08_face.layout.json"
BASELINE = Path(__file__).resolve().parent / "scipy_dijkstra_baseline.py"
INFO = re.compile(r"geodesic (\w+): (\d+) vertices x (\d+) sources in ([\d.]+) s: set-up ([\d.]+) s, "
                  r"searches ([\d.]+) s \(([\d.]+) s a source on (\d+) threads\)")


def usdface(*args) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r = subprocess.run([sys.executable, "-m", "usdface", *map(str, args)], capture_output=True, text=True, env=env,
                       cwd=tempfile.gettempdir())
    if r.returncode:
        raise SystemExit(f"usdface {' '.join(map(str, args))} failed ({r.returncode}):\n{r.stderr}")
    return r


def children_cpu() -> float:
    """User + system CPU seconds of the finished child processes so far."""
    u = resource.getrusage(resource.RUSAGE_CHILDREN)
    return u.ru_utime + u.ru_stime


def timed(cmd, env=None) -> tuple[float, subprocess.CompletedProcess]:
    """Wall time of one process, start to exit (its CPU time in ``timed.cpu``)."""
    t0, c0 = time.perf_counter(), children_cpu()
    # from a neutral folder: the current one would come first on sys.path (a checkout's usdface)
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tempfile.gettempdir())
    seconds = time.perf_counter() - t0
    timed.cpu = children_cpu() - c0
    if r.returncode:
        raise SystemExit(f"{' '.join(map(str, cmd))} failed ({r.returncode}):\n{r.stderr}")
    return seconds, r


def write_obj(path: Path, points, triangles) -> None:
    with open(path, "w") as f:
        np.savetxt(f, points, fmt="v %.9g %.9g %.9g")
        np.savetxt(f, np.asarray(triangles) + 1, fmt="f %d %d %d")


def prepare(work: Path, n: int, capture: Path) -> tuple[Path, Path, int]:
    """Refined face -> mesh layer -> binding layer, with the command line."""
    from usdface.distance.graph import refine_triangles
    from usdface.io.meshes import read_mesh

    face = read_mesh(FACE)
    p, t = refine_triangles(face.points, face.triangles(), n)
    obj = work / f"face_n{n}.obj"
    write_obj(obj, p, t)
    mesh, binding = work / f"mesh_n{n}.usdc", work / f"binding_n{n}.usda"
    usdface("import-mesh", obj, "-o", mesh, "-q")
    usdface("bind", "--mesh", mesh, "--capture", capture, "--layout", LAYOUT, "-o", binding, "-q")
    return mesh, binding, len(p)


def distances_cmd(mesh, binding, backend, out) -> list:
    return [sys.executable, "-m", "usdface", "distances", "--mesh", mesh, "--binding", binding, "--method", "geodesic",
            "--backend", backend, "-o", out, "--json", "-v"]


def run_cli(cmd, env) -> dict:
    seconds, r = timed(cmd, env)
    summary = json.loads(r.stdout)
    out = {"wall": seconds, "cpu": timed.cpu, "compute": summary["parameters"]["computeSeconds"],
           "sources": summary["markers"] + summary["constraintCentres"]}
    m = INFO.search(r.stderr)
    if m is not None:        # a checkout that logs its set-up and search times
        out.update(setup=float(m.group(5)), search=float(m.group(6)), threads=int(m.group(8)))
    return out


#: run with a checkout's PYTHONPATH: its fmm solver's set-up and search times on the CLI's sources
PROBE = """
import json, sys, time
import numpy as np
from usdface.usd.analysis_layer import read_distance_matrix
from usdface.usd.layers import open_stage
from usdface.usd.mesh_layer import read_binding, read_mesh_layer
mesh, _ = read_mesh_layer(sys.argv[1])
b = read_binding(open_stage(sys.argv[2], what="binding"))
cons = read_distance_matrix(sys.argv[3]).constraint_vertices
tri = np.concatenate([b.triangle_vertices, np.repeat(cons[:, None], 3, axis=1)])
bary = np.concatenate([b.barycentrics, np.tile([1.0, 0.0, 0.0], (cons.size, 1))])
from usdface.distance import GeodesicSolver
import numba
t0 = time.perf_counter()
solver = GeodesicSolver.from_mesh(mesh, backend="fmm")
solver.marching
t1 = time.perf_counter()
solver.solve(tri, bary)
t2 = time.perf_counter()
print(json.dumps({"setup": t1 - t0, "search": t2 - t1, "threads": min(numba.get_num_threads(), len(tri))}))
"""


def run_probe(mesh, binding, analysis, env) -> dict:
    _, r = timed([sys.executable, "-c", PROBE, mesh, binding, analysis], env)
    return json.loads(r.stdout.strip().splitlines()[-1])


def source_vertices(binding: Path, analysis: Path) -> np.ndarray:
    """The baseline's sources (each marker's nearest vertex, then the analysis layer's constraint
    vertices: the CLI's centres, in its order) and the number of markers."""
    from usdface.usd.analysis_layer import read_distance_matrix
    from usdface.usd.layers import open_stage
    from usdface.usd.mesh_layer import read_binding

    b = read_binding(open_stage(binding, what="binding"))
    m = read_distance_matrix(analysis)
    assert list(m.marker_names) == list(b.names)
    return np.concatenate([b.nearest_vertices, m.constraint_vertices]).astype(np.int64), len(b.names)


def fmm_error(analysis: Path, coarse_binding: Path, coarse_edge: float, width: float) -> str:
    """fmm's error against exact geodesics at the 2020 original vertices, marker columns."""
    from usdface.distance import GeodesicSolver
    from usdface.io.meshes import read_mesh
    from usdface.usd.analysis_layer import read_distance_matrix
    from usdface.usd.layers import open_stage
    from usdface.usd.mesh_layer import read_binding

    face = read_mesh(FACE)
    b = read_binding(open_stage(coarse_binding, what="binding"))
    exact = GeodesicSolver(face.points, face.triangles(), backend="exact").distances(b.triangle_vertices,
                                                                                       b.barycentrics)
    got = read_distance_matrix(analysis).vertex_to_centre[:len(face.points), :b.n_markers].astype(np.float64)
    far = (exact > coarse_edge) & (exact < 3 * width)
    rel = np.abs(got - exact)[far] / exact[far]
    return f"mean {100 * rel.mean():.3f} %, p99 {100 * np.percentile(rel, 99):.2f} % over {far.sum()} pairs"


def median(rows, key) -> float:
    return float(np.median([r[key] for r in rows]))


def bench_size(work, n, capture, repeat, env, coarse, probe) -> dict:
    t0 = time.perf_counter()
    mesh, binding, nv = prepare(work, n, capture)
    print(f"\n== n = {n}: {nv} vertices (layers prepared with the CLI in {time.perf_counter() - t0:.1f} s); "
          f"load average {os.getloadavg()[0]:.2f}", flush=True)
    out = {b: work / f"A_n{n}_{b}.usdc" for b in ("fmm", "graph")}
    first = {b: run_cli(distances_cmd(mesh, binding, b, out[b]), env) for b in ("fmm", "graph")}
    sources = work / f"sources_n{n}.npy"
    src, markers = source_vertices(binding, out["fmm"])
    np.save(sources, src)
    s = int(src.size)
    assert first["fmm"]["sources"] == s == first["graph"]["sources"], (first, s)
    base_cmd = [sys.executable, str(BASELINE), mesh, sources, work / f"D_n{n}.npy"]
    rows = {"fmm": [], "graph": [], "scipy": []}
    probe = probe or "setup" not in first["fmm"]
    for _ in range(repeat):
        rows["fmm"].append(run_cli(distances_cmd(mesh, binding, "fmm", out["fmm"]), env))
        if probe:           # set-up and search times from a probe process instead of the log line
            rows["fmm"][-1].update(run_probe(mesh, binding, out["fmm"], env))
        rows["graph"].append(run_cli(distances_cmd(mesh, binding, "graph", out["graph"]), env))
        rows["graph"][-1].setdefault("setup", float("nan"))
        rows["graph"][-1].setdefault("search", float("nan"))
        rows["graph"][-1].setdefault("threads", 0)
        seconds, r = timed(base_cmd, env)
        rows["scipy"].append({"wall": seconds, "cpu": timed.cpu, **json.loads(r.stdout)})
    d = np.load(work / f"D_n{n}.npy", mmap_mode="r")
    assert d.shape == (s, nv) and np.isfinite(d).all()
    sc = median(rows["scipy"], "wall")
    sc_src = median(rows["scipy"], "dijkstra") / s
    sc_cpu = median(rows["scipy"], "cpu")
    res = {"n": n, "vertices": nv, "sources": s, "scipy": sc, "scipy_src": sc_src, "scipy_cpu": sc_cpu,
           "scipy_setup": median(rows["scipy"], "graph")}
    print(f"   {s} sources ({markers} markers + {s - markers} constraint vertices); "
          f"first runs (numba cache cold or warm as found): fmm {first['fmm']['wall']:.2f} s, "
          f"graph {first['graph']['wall']:.2f} s")
    print(f"   {'process':28s} {'wall s':>8s} {'/scipy':>7s} {'set-up s':>9s} {'search s':>9s} {'s/source':>9s} "
          f"threads {'cpu s':>7s} {'/scipy':>7s}")
    print(f"   {'scipy script (baseline)':28s} {sc:8.2f} {1.0:7.2f} {res['scipy_setup']:9.2f} "
          f"{median(rows['scipy'], 'dijkstra'):9.2f} {sc_src:9.4f}       1 {sc_cpu:7.2f} {1.0:7.2f}")
    for b in ("fmm", "graph"):
        w, su, se = median(rows[b], "wall"), median(rows[b], "setup"), median(rows[b], "search")
        cpu = median(rows[b], "cpu")
        res.update({b: w, b + "_setup": su, b + "_src": se / s, b + "_cpu": cpu})
        print(f"   {'usdface distances --backend ' + b:28s} {w:8.2f} {w / sc:7.2f} {su:9.2f} {se:9.2f} "
              f"{se / s:9.4f} {rows[b][0]['threads']:7d} {cpu:7.2f} {cpu / sc_cpu:7.2f}"
              + ("  (set-up, search: probe)" if b == "fmm" and probe else ""))
    print(f"   per source, fmm / scipy: {res['fmm_src'] / sc_src:.2f}; fmm set-up {res['fmm_setup']:.2f} s "
          f"(scipy's edge graph {res['scipy_setup']:.2f} s)")
    print("   baseline phases (median s): " + ", ".join(
        f"{k} {median(rows['scipy'], k):.2f}" for k in ("imports", "read", "graph", "dijkstra", "save")))
    if coarse is not None:
        print(f"   fmm against exact geodesics (the 2020 original vertices, marker columns): "
              f"{fmm_error(out['fmm'], coarse[0], coarse[1], coarse[2])}")
    print(f"   load average after: {os.getloadavg()[0]:.2f}", flush=True)
    return res, binding


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=17, help="refinement of the large face (17 -> 560k vertices)")
    ap.add_argument("--middle", type=int, default=6, help="refinement of the middle face (6 -> 71k vertices)")
    ap.add_argument("--repeat", type=int, default=3, help="interleaved timed repeats (medians reported)")
    ap.add_argument("--workdir", type=Path, default=None, help="keep the layers here (default: a temporary folder)")
    ap.add_argument("--usdface-root", type=Path, default=REPO,
                    help="the checkout whose `usdface distances` is timed (default: this one)")
    ap.add_argument("--probe", action="store_true", help="set-up and search times from a probe process")
    args = ap.parse_args(argv)

    import numba
    import scipy
    print(f"{os.cpu_count()} CPUs; Python {sys.version.split()[0]}, numpy {np.__version__}, scipy {scipy.__version__}, "
          f"numba {numba.__version__} ({numba.config.NUMBA_NUM_THREADS} threads); load average {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        root = args.usdface_root.resolve()
        env = dict(os.environ, PYTHONPATH=str(root) + os.pathsep + os.environ.get("PYTHONPATH", ""))
        print(f"timing the usdface of {root}")
        capture = work / "capture.usdc"
        usdface("import-capture", TAKE, "-o", capture, "-q")
        from usdface.distance import graph as G
        from usdface.io.meshes import read_mesh
        from usdface.rbf.stiffness import DEFAULT_WIDTH_FACTOR, median_marker_spacing_from_points
        face = read_mesh(FACE)
        e = G.mesh_edges(face.triangles())
        coarse_edge = float(np.linalg.norm(face.points[e[:, 0]] - face.points[e[:, 1]], axis=1).mean())
        results, coarse = [], None
        for n in dict.fromkeys([1, args.middle, args.n]):
            res, binding = bench_size(work, n, capture, args.repeat, env, coarse, args.probe)
            results.append(res)
            if n == 1:
                from usdface.usd.layers import open_stage
                from usdface.usd.mesh_layer import read_binding
                b = read_binding(open_stage(binding, what="binding"))
                width = DEFAULT_WIDTH_FACTOR * median_marker_spacing_from_points(b.surface_points(face.points))
                coarse = (binding, coarse_edge, width)
        print("\nsummary (medians; ratios to the scipy script of the same size and run):")
        print(f"{'vertices':>9s} {'S':>4s} | {'fmm s/src':>9s} {'scipy s/src':>11s} {'ratio':>6s} | "
              f"{'fmm set-up':>10s} | {'fmm proc':>8s} {'graph proc':>10s} {'scipy proc':>10s} | {'fmm/sc':>6s} {'graph/sc':>8s} "
              f"| {'fmm cpu/sc':>10s}")
        for r in results:
            print(f"{r['vertices']:9d} {r['sources']:4d} | {r['fmm_src']:9.4f} {r['scipy_src']:11.4f} "
                  f"{r['fmm_src'] / r['scipy_src']:6.2f} | {r['fmm_setup']:10.2f} | {r['fmm']:8.2f} {r['graph']:10.2f} "
                  f"{r['scipy']:10.2f} | {r['fmm'] / r['scipy']:6.2f} {r['graph'] / r['scipy']:8.2f} "
                  f"| {r['fmm_cpu'] / r['scipy_cpu']:10.2f}")
        print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
