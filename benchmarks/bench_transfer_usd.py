"""End-to-end transfer: 1000 frames onto a 100k-vertex face, streamed into an animation .usdc.

Measures, in one run on this machine:
  (a) the whole `transfer` job (RBF fit + float32 evaluation + time-sampled .usdc write, streamed
      in chunks with a save per chunk), MB/s of output points and peak memory (maxrss of a child
      process, so the parent's data does not count);
  (b) the baseline: writing the same number of points (precomputed, no RBF) with the same writer;
  (c) the RBF compute alone (no write).
Ratios (a)/(b) and (c)/(a) say where the time goes. Run by hand:  python benchmarks/bench_transfer_usd.py
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def grid_face(n_side: int):
    """A curved quad grid standing in for a dense face scan (cm), and 41 marker points on it."""
    from usdface.mesh.model import FaceMesh

    u, v = np.meshgrid(np.linspace(-8, 8, n_side), np.linspace(-10, 10, n_side))
    z = 6.0 * np.cos(u / 10.0) * np.cos(v / 14.0)
    points = np.stack([u.ravel(), v.ravel(), z.ravel()], axis=1)
    idx = np.arange(n_side * n_side).reshape(n_side, n_side)
    quads = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], axis=-1).reshape(-1, 4)
    mesh = FaceMesh(points, np.full(len(quads), 4), quads.ravel(), units="cm", name="grid")
    rng = np.random.default_rng(0)
    markers = rng.choice(points.shape[0], 41, replace=False)
    return mesh, markers


def child(mode: str, n_side: int, frames: int, out_dir: str) -> dict:
    """One measurement in a fresh process (so maxrss is this job's peak)."""
    import resource

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
        block = np.zeros((64, mesh.n_points, 3), dtype=np.float32)
        chunks = ((slice(a, min(a + 64, frames)), block[: min(64, frames - a)]) for a in range(0, frames, 64))
    else:
        d_vc = euclidean_distances(mesh.points, tri, bary)
        d_cc = euclidean_at_sources(mesh.points, tri, bary)
        solver = RBFTransfer(d_vc, d_cc, widths=2.0, n_markers=41).fit()
        chunks = solver.iter_chunks(disp, chunk_frames=64)
    if mode == "compute":
        for _ in chunks:
            pass
    else:
        write_animation_layer(Path(out_dir) / f"anim_{mode}.usdc", chunks, mesh_path=mesh_path,
                              rest_points=mesh.points, start=0, rate=60.0, n_frames=frames, units="cm",
                              transfer=settings, prov={})
    seconds = time.perf_counter() - t0
    return {"seconds": seconds, "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "points": mesh.n_points}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", type=int, default=317, help="grid side (317 -> 100,489 vertices)")
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--child", nargs=3, metavar=("MODE", "SIDE", "FRAMES"), help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.child[0], int(args.child[1]), int(args.child[2]), args.out)))
        return 0
    free = os.statvfs(tempfile.gettempdir())
    need = args.side ** 2 * 12 * args.frames * 2.2
    print(f"machine: {os.cpu_count()} CPUs, {platform.processor() or platform.machine()}, Python {platform.python_version()}")
    print(f"free disk in {tempfile.gettempdir()}: {free.f_bavail * free.f_frsize / 1e9:.1f} GB (needs ~{need / 1e9:.1f} GB)")
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for mode in ("baseline", "compute", "transfer"):
            out = subprocess.run([sys.executable, __file__, "--child", mode, str(args.side), str(args.frames),
                                  "--out", tmp], capture_output=True, text=True, check=True)
            results[mode] = json.loads(out.stdout.strip().splitlines()[-1])
    n = results["transfer"]["points"]
    mb = n * 12 * args.frames / 1e6
    for mode, label in (("baseline", "write only (precomputed points)"), ("compute", "RBF compute only"),
                        ("transfer", "transfer = fit + compute + .usdc write")):
        r = results[mode]
        print(f"  {label:40s} {r['seconds']:7.2f} s  {mb / r['seconds']:7.0f} MB/s  "
              f"{1e3 * r['seconds'] / args.frames:6.2f} ms/frame  peak {r['maxrss_mb']:6.0f} MB")
    print(f"{n} vertices x {args.frames} frames = {mb:.0f} MB of float32 points")
    print(f"ratio transfer / write-only baseline: {results['transfer']['seconds'] / results['baseline']['seconds']:.2f}")
    print(f"RBF compute is {results['compute']['seconds'] / results['transfer']['seconds']:.0%} of the transfer")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
