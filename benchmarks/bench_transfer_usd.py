"""End-to-end transfer: 1000 frames onto a ~100k-vertex face, streamed into an animation .usdc.

Run by hand:  python benchmarks/bench_transfer_usd.py [--n 7] [--frames 1000] [--repeat 3]

Process level (the issue's measure, every row a fresh process, wall time and its own peak RSS):
  (P1) `usdface transfer` with default options on a real face (the MakeHuman face refined 1-to-n^2,
       n = 7: 95,380 vertices) and the real Jaw take trimmed to 1000 frames (inputs made once by
       `usdface run`), 41 markers + constraint centres;
  (P0) the baseline: a process writing the same points (precomputed, memory-mapped .npy) and
       extents with the same USD writer loop: 64 frames per chunk, one Set per frame, a Save per
       chunk, then fsync and rename (usdface.usd.layers.AtomicLayer).
  Ratio P1 / P0 (goal <= 1.1) and P1's peak RSS (goal <= 1 GB). The processes alternate
  (P0 P1 P0 P1 ...) and the median of --repeat runs is reported: the machine is shared.

In process (where the time goes, synthetic 317 x 317 grid, 100,489 vertices):
  (a) write_animation_layer fed by RBFTransfer.iter_chunks (fit + float32 evaluation + write);
  (b) write_animation_layer fed precomputed zero displacements (the writer alone);
  (c) the RBF evaluation alone (no write).

The script runs whatever usdface its folder belongs to (PYTHONPATH is set for the children), so the
same command on a checkout of an older commit gives the "before" numbers.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
SHARED = REPO.parent / "shared" / "data"

from procmem import status_mb  # noqa: E402  (benchmarks/procmem.py)
SAMPLES = REPO / "sample_assets"
CHUNK = 64


def child_env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


def timed_process(cmd: list[str]) -> dict:
    """Run ``cmd``: wall seconds, the child's own CPU seconds (user + system, all its threads) and its
    peak RSS (printed by the child: VmHWM)."""
    import threading

    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=child_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out: list = []
    readers = [threading.Thread(target=lambda s=s: out.append(s.read())) for s in (proc.stdout, proc.stderr)]
    for r in readers:
        r.start()
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - t0
    for r in readers:
        r.join()
    proc.returncode = os.waitstatus_to_exitcode(status)
    text = "".join(out)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{text[-3000:]}")
    peak = None
    for line in text.splitlines():
        if line.startswith("PEAK_RSS_MB "):
            peak = float(line.split()[1])
    return {"seconds": seconds, "cpu": usage.ru_utime + usage.ru_stime, "maxrss_mb": peak}


# ------------------------------------------------------------------------------------------------
# process-level measurement


def make_inputs(work: Path, n: int, frames: int) -> Path:
    """The refined face and `usdface run` on it (once): mesh, capture, binding and analysis layers."""
    from usdface.distance.graph import refine_triangles
    from usdface.io.meshes import read_mesh

    setup = work / f"setup_n{n}_f{frames}"
    if (setup / "analysis.usdc").is_file():
        return setup
    m = read_mesh(SAMPLES / "meshes" / "makehuman_hm08_face_cm.obj")
    p, t = refine_triangles(m.points, m.triangles(), n)
    obj = work / f"face_n{n}.obj"
    with open(obj, "w") as fh:
        fh.write("".join(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in p))
        fh.write("".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in t))
    capture = SHARED / "animface" / "JawMoCap.ma"
    if not capture.is_file():
        capture = SAMPLES / "capture" / "JawMoCap.ma"
    cmd = [sys.executable, "-m", "usdface", "run", "--mesh", str(obj), "--capture", str(capture), "--layout",
           str(SAMPLES / "layouts" / "makehuman_hm08_face.layout.json"), "--trim", "0", str(frames),
           "-o", str(setup)]
    subprocess.run(cmd, env=child_env(), check=True, capture_output=True, text=True)
    return setup


def mesh_prim_path(mesh_layer: Path):
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(mesh_layer))
    return next(p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)).GetPath()


def export_points(anim: Path, mesh_layer: Path, out: Path) -> None:
    """The time-sampled points and extents of an animation layer as .npy files (the baseline's input)."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(anim))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(mesh_prim_path(mesh_layer)))
    times = mesh.GetPointsAttr().GetTimeSamples()
    first = np.asarray(mesh.GetPointsAttr().Get(times[0]), dtype=np.float32)
    pts = np.lib.format.open_memmap(out / "points.npy", mode="w+", dtype=np.float32,
                                    shape=(len(times), first.shape[0], 3))
    ext = np.empty((len(times), 2, 3), dtype=np.float32)
    for i, t in enumerate(times):
        pts[i] = np.asarray(mesh.GetPointsAttr().Get(t), dtype=np.float32)
        ext[i] = np.asarray(mesh.GetExtentAttr().Get(t), dtype=np.float32)
    pts.flush()
    del pts
    np.save(out / "extents.npy", ext)
    (out / "times.json").write_text(json.dumps([float(t) for t in times]))


def baseline_writer(data: Path, output: Path, mesh_layer: Path) -> None:
    """P0: write precomputed points and extents with the same chunking, fsync and rename."""
    from pxr import Usd, UsdGeom, Vt

    from usdface.usd.layers import AtomicLayer

    pts = np.load(data / "points.npy", mmap_mode="r")
    ext = np.load(data / "extents.npy")
    times = json.loads((data / "times.json").read_text())
    mesh_path = mesh_prim_path(mesh_layer)
    with AtomicLayer(output) as stage:
        stage.SetStartTimeCode(times[0])
        stage.SetEndTimeCode(times[-1])
        mesh = UsdGeom.Mesh(stage.OverridePrim(mesh_path))
        points_attr = mesh.CreatePointsAttr()
        extent_attr = mesh.CreateExtentAttr()
        layer = stage.GetRootLayer()
        for a in range(0, len(times), CHUNK):
            for f in range(a, min(a + CHUNK, len(times))):
                points_attr.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(pts[f])), Usd.TimeCode(times[f]))
                extent_attr.Set(Vt.Vec3fArray.FromNumpy(ext[f]), Usd.TimeCode(times[f]))
            layer.Save()


def peak_line() -> str:
    """This process's peak RSS: VmHWM (ru_maxrss would include the parent's peak before exec)."""
    return f"PEAK_RSS_MB {status_mb('VmHWM'):.1f}"


def process_level(args, work: Path) -> dict:
    setup = make_inputs(work, args.n, args.frames)
    data = work / f"points_n{args.n}_f{args.frames}"
    data.mkdir(exist_ok=True)
    if not (data / "points.npy").is_file():
        export_points(setup / "anim.usdc", setup / "mesh.usdc", data)
    out = work / "out"
    out.mkdir(exist_ok=True)
    transfer = [sys.executable, __file__, "--cli", "transfer", "--mesh", str(setup / "mesh.usdc"),
                "--capture", str(setup / "capture.usdc"), "--binding", str(setup / "binding.usda"),
                "--analysis", str(setup / "analysis.usdc"), "-o", str(out / "anim_transfer.usdc")]
    baseline = [sys.executable, __file__, "--baseline", str(data), str(out / "anim_baseline.usdc"),
                str(setup / "mesh.usdc")]
    runs: dict = {"baseline": [], "transfer": []}
    for _ in range(args.repeat):
        for name, cmd in (("baseline", baseline), ("transfer", transfer)):
            runs[name].append(timed_process(cmd))
            r = runs[name][-1]
            print(f"    {name:9s} {r['seconds']:7.2f} s wall  {r['cpu']:6.2f} s CPU  peak {r['maxrss_mb']:6.0f} MB",
                  flush=True)
    n_points = np.load(data / "points.npy", mmap_mode="r").shape[1]
    return {"runs": runs, "points": n_points, "frames": args.frames}


# ------------------------------------------------------------------------------------------------
# in-process measurement (where the time goes)


def grid_face(n_side: int):
    """A curved quad grid standing in for a dense face scan (cm), and 41 marker points on it."""
    from usdface.model.mesh import FaceMesh

    u, v = np.meshgrid(np.linspace(-8, 8, n_side), np.linspace(-10, 10, n_side))
    z = 6.0 * np.cos(u / 10.0) * np.cos(v / 14.0)
    points = np.stack([u.ravel(), v.ravel(), z.ravel()], axis=1)
    idx = np.arange(n_side * n_side).reshape(n_side, n_side)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], axis=-1).reshape(-1, 4)
    mesh = FaceMesh(points, np.full(len(quads), 4), quads.ravel(), units="cm", name="grid")
    rng = np.random.default_rng(0)
    markers = rng.choice(points.shape[0], 41, replace=False)
    return mesh, markers


def _streams_positions(solver) -> bool:
    """Whether this usdface's iter_chunks adds the rest points and extents in the product (0.3 on)."""
    import inspect

    return "offset" in inspect.signature(solver.iter_chunks).parameters


def child(mode: str, n_side: int, frames: int, out_dir: str) -> dict:
    """One in-process measurement in a fresh process (so the peak RSS is this job's)."""
    import usdface  # noqa: F401
    from usdface.distance import euclidean_at_sources, euclidean_distances
    from usdface.rbf import RBFTransfer
    from usdface.usd.analysis_layer import write_animation_layer
    from usdface.usd.mesh_layer import write_mesh_layer

    mesh, markers = grid_face(n_side)
    mesh_path = Path(out_dir) / "mesh.usdc"
    write_mesh_layer(mesh_path, mesh, [], prov={})
    tri = np.repeat(markers[:, None], 3, axis=1)
    bary = np.tile([1.0, 0.0, 0.0], (41, 1))
    rng = np.random.default_rng(1)
    disp = np.cumsum(rng.normal(scale=0.02, size=(frames, 41, 3)), axis=0)
    settings = {"mode": "interpolate", "kernel": "gaussian", "distanceMethod": "euclidean",
                "markerNames": [f"m{i}" for i in range(41)], "widths": np.full(41, 2.0)}
    t0 = time.perf_counter()
    if mode == "baseline":
        block = np.zeros((CHUNK, mesh.n_points, 3), dtype=np.float32)
        chunks = ((slice(a, min(a + CHUNK, frames)), block[: min(CHUNK, frames - a)]) for a in range(0, frames, CHUNK))
    else:
        d_vc = euclidean_distances(mesh.points, tri, bary)
        d_cc = euclidean_at_sources(mesh.points, tri, bary)
        try:
            from usdface.rbf import RBFCentres, RBFSettings
        except ImportError:                    # older usdface (the "before" numbers): keyword options
            solver = RBFTransfer(d_vc, d_cc, widths=2.0, n_markers=41).fit()
        else:
            solver = RBFTransfer(d_vc, d_cc, settings=RBFSettings(widths=2.0), centres=RBFCentres(n_markers=41)).fit()
        if _streams_positions(solver):         # the transfer processor's path: rest and extents in the product
            chunks = solver.iter_chunks(disp, chunk_frames=CHUNK, offset=mesh.points, extents=True,
                                        blas_threads=1, buffers=3)
        else:                                  # older usdface (the "before" numbers)
            chunks = solver.iter_chunks(disp, chunk_frames=CHUNK)
    if mode == "compute":
        for _ in chunks:
            pass
    else:
        absolute = mode == "transfer" and _streams_positions(solver)
        from usdface.model.timing import FrameRange

        write_animation_layer(Path(out_dir) / f"anim_{mode}.usdc", chunks, mesh_path=mesh_path,
                              rest_points=None if absolute else mesh.points, frames=FrameRange(0, 60.0, frames),
                              units="cm", transfer=settings, prov={})
    seconds = time.perf_counter() - t0
    return {"seconds": seconds, "maxrss_mb": float(peak_line().split()[1]), "points": mesh.n_points}


def in_process(args, work: Path) -> dict:
    results = {}
    for mode in ("baseline", "compute", "transfer"):
        out = subprocess.run([sys.executable, __file__, "--child", mode, str(args.side), str(args.frames),
                              "--out", str(work)], capture_output=True, text=True, check=True, env=child_env())
        results[mode] = json.loads(out.stdout.strip().splitlines()[-1])
    return results


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=7, help="refinement of the MakeHuman face (7 -> 95,380 vertices)")
    parser.add_argument("--side", type=int, default=317, help="grid side of the in-process rows (317 -> 100,489)")
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--work", default=None, help="keep inputs here between runs (default: a temporary folder)")
    parser.add_argument("--skip-in-process", action="store_true")
    parser.add_argument("--child", nargs=3, metavar=("MODE", "SIDE", "FRAMES"), help=argparse.SUPPRESS)
    parser.add_argument("--baseline", nargs=3, metavar=("DATA", "OUT", "MESH"), help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    if argv is None and sys.argv[1:2] == ["--cli"]:      # `usdface ...` in this process, then its peak RSS
        from usdface.cli import main as usdface_main
        rc = usdface_main(sys.argv[2:])
        print(peak_line(), file=sys.stderr)
        return rc
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.child[0], int(args.child[1]), int(args.child[2]), args.out)))
        return 0
    if args.baseline:
        baseline_writer(Path(args.baseline[0]), Path(args.baseline[1]), Path(args.baseline[2]))
        print(peak_line(), file=sys.stderr)
        return 0
    import usdface
    print(f"usdface {usdface.__version__} from {Path(usdface.__file__).parent}; machine: {os.cpu_count()} CPUs, "
          f"{platform.processor() or platform.machine()}, Python {platform.python_version()}; "
          f"load average {os.getloadavg()[0]:.1f}")
    keep = args.work is not None
    work = Path(args.work) if keep else Path(tempfile.mkdtemp(prefix="usdface-bench-transfer-"))
    work.mkdir(parents=True, exist_ok=True)
    need = (95_000 if args.n == 7 else 2020 * args.n ** 2) * 12 * args.frames * 5
    print(f"free disk in {work}: {shutil.disk_usage(work).free / 1e9:.1f} GB (needs ~{need / 1e9:.1f} GB)")
    try:
        print("process level (fresh processes, alternating; each row one run):")
        pl = process_level(args, work)
        med = {k: float(np.median([r["seconds"] for r in v])) for k, v in pl["runs"].items()}
        cpu = {k: float(np.median([r["cpu"] for r in v])) for k, v in pl["runs"].items()}
        peak = {k: max(r["maxrss_mb"] for r in v) for k, v in pl["runs"].items()}
        mb = pl["points"] * 12 * pl["frames"] / 1e6
        print(f"  {pl['points']} vertices x {pl['frames']} frames = {mb:.0f} MB of float32 points")
        for k, label in (("baseline", "P0 baseline writer (precomputed points)"),
                         ("transfer", "P1 usdface transfer (default options)")):
            print(f"  {label:42s} median {med[k]:7.2f} s wall ({mb / med[k]:4.0f} MB/s), {cpu[k]:6.2f} s CPU, "
                  f"peak RSS {peak[k]:5.0f} MB")
        per_run = ", ".join(f"{t['seconds'] / b['seconds']:.2f}"
                            for t, b in zip(pl["runs"]["transfer"], pl["runs"]["baseline"]))
        print(f"  ratio P1 / P0 (median of {args.repeat}): {med['transfer'] / med['baseline']:.2f}   "
              f"(per run: {per_run}); CPU ratio {cpu['transfer'] / cpu['baseline']:.2f}")
        if not args.skip_in_process:
            r = in_process(args, work)
            n = r["transfer"]["points"]
            mb = n * 12 * args.frames / 1e6
            print(f"in process ({n}-vertex grid x {args.frames} frames = {mb:.0f} MB):")
            for mode, label in (("baseline", "(b) write_animation_layer, zero displacements"),
                                ("compute", "(c) RBF evaluation only"),
                                ("transfer", "(a) write_animation_layer fed by the RBF")):
                x = r[mode]
                print(f"  {label:48s} {x['seconds']:7.2f} s  {mb / x['seconds']:7.0f} MB/s  peak {x['maxrss_mb']:6.0f} MB")
            print(f"  ratio (a) / (b): {r['transfer']['seconds'] / r['baseline']['seconds']:.2f}; "
                  f"RBF compute is {r['compute']['seconds'] / r['transfer']['seconds']:.0%} of (a)")
    finally:
        if not keep:
            shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
