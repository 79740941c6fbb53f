"""Benchmark: RBF transfer of 41 markers onto 100k vertices for 1000 frames (compute part).

Run by hand (not in CI):  python benchmarks/bench_transfer.py [--vertices 100000] [--frames 1000]

Measures, in one run on this machine:
- usdface.rbf.RBFTransfer (interpolate mode, gaussian): fit() time and streamed evaluation time
  per frame (float32, chunks of frames), with and without invalid-marker frames;
- peak memory while streaming (tracemalloc peak of the loop and the process's ru_maxrss);
- baseline (a): the authors' plug-in style per-vertex Python loop over Eqs. 4-5 (math.exp per
  vertex and marker), timed on a sample of vertices and extrapolated (the paper reports about
  0.1 ms per vertex per frame in Maya);
- baseline (b): scipy.interpolate.RBFInterpolator (Euclidean, gaussian, the same width via
  epsilon = 1 / width, no polynomial) fitted on all frames at once and evaluated on every vertex;
and prints the ratios. Absolute times depend on the machine and its load (printed).

The compute loop is :func:`compute_chunks`, a generator of ``(frame slice, (f, N, 3) float32)``:
the .usdc writer (usdface.usd) consumes it as is for the end-to-end benchmark.
"""
from __future__ import annotations

import argparse
import gc
import math
import os
import platform
import resource
import statistics
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from usdface.rbf import RBFTransfer  # noqa: E402
from usdface.rbf.stiffness import DEFAULT_WIDTH_FACTOR  # noqa: E402


# ------------------------------------------------------------------------------------------ data
def make_problem(n_vertices: int, n_markers: int, n_frames: int, seed: int = 0):
    """A face-sized sphere cap (10 cm radius, ~18 cm across), markers spread by farthest points.

    Returns vertices (N, 3), marker indices (M,), D_vc (N, M), D_cc (M, M) (Euclidean, cm) and
    smooth marker displacements (F, M, 3) (cm, up to ~1 cm).
    """
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(3 * n_vertices, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v = 10.0 * v[v[:, 2] > 0.45][:n_vertices]
    chosen = [0]
    d = np.linalg.norm(v - v[0], axis=1)
    for _ in range(n_markers - 1):
        chosen.append(int(np.argmax(d)))
        d = np.minimum(d, np.linalg.norm(v - v[chosen[-1]], axis=1))
    markers = np.array(chosen)
    mp = v[markers]
    D_vc = np.linalg.norm(v[:, None, :] - mp[None, :, :], axis=2)
    D_cc = np.linalg.norm(mp[:, None, :] - mp[None, :, :], axis=2)
    t = np.linspace(0.0, 1.0, n_frames)[:, None, None]
    a, w, p = rng.normal(size=(3, 1, n_markers, 3))
    disp = 0.5 * a * np.sin(2 * np.pi * (1 + 3 * np.abs(w)) * t + p)
    return v, markers, D_vc, D_cc, disp


def with_gaps(disp: np.ndarray, fraction: float = 0.02, seed: int = 1) -> np.ndarray:
    """A copy where ``fraction`` of the frames lose 1-3 markers (occlusions), in a few patterns."""
    rng = np.random.default_rng(seed)
    out = disp.copy()
    F, M = disp.shape[:2]
    patterns = [rng.choice(M, size=rng.integers(1, 4), replace=False) for _ in range(8)]
    for f in rng.choice(F, size=max(1, int(fraction * F)), replace=False):
        out[f, patterns[rng.integers(len(patterns))]] = np.nan
    return out


# ------------------------------------------------------------------------------------------ compute
def compute_chunks(rbf: RBFTransfer, displacements: np.ndarray, chunk_frames: int | None = None,
                   reuse_buffer: bool = False):
    """The compute loop: yields ``(frames, points)`` with points (f, N, 3) float32 displacements.

    A writer consumes it chunk by chunk (e.g. ``rest + points[k]`` -> Vec3fArray -> time sample),
    so memory stays bounded by a chunk or two. With ``reuse_buffer`` every chunk is the same
    buffer: the writer must have copied a chunk (FromNumpy copies) before taking the next.
    """
    yield from rbf.iter_chunks(displacements, chunk_frames=chunk_frames, reuse_buffer=reuse_buffer)


def consume(chunks) -> float:
    """Drain a chunk generator (touching one value per chunk); returns elapsed seconds."""
    t0 = time.perf_counter()
    s = 0.0
    for _frames, points in chunks:
        s += float(points[-1, -1, 0])
    return time.perf_counter() - t0


# ------------------------------------------------------------------------------------------ baselines
def plugin_loop_per_vertex_frame(D_vc, D_cc, widths, disp, n_sample_vertices: int, n_frames: int) -> float:
    """Seconds per vertex per frame of the plug-in's pure-Python Eqs. 4-5 (sampled, extrapolated).

    Per frame: the M x M RBF matrix and the weights (Eq. 4, plug-in style loops), then for every
    vertex the sum over markers of W_j exp(-d^2 / s_j^2) (Eq. 5). The per-frame Eq. 4 cost is
    spread over all N vertices.
    """
    N, M = D_vc.shape
    Dl = D_vc[:n_sample_vertices].tolist()
    Dcc = D_cc.tolist()
    s = [float(x) for x in widths]
    eq4 = eq5 = 0.0
    for f in range(n_frames):
        D = disp[f].tolist()
        t0 = time.perf_counter()
        rbf = [[0.0] * M for _ in range(M)]
        for i in range(M):
            for j in range(i, M):
                r = math.exp(-(Dcc[i][j] ** 2 / s[i] ** 2))
                rbf[i][j] = r
                rbf[j][i] = r
        W = []
        for i in range(M):
            tot = [0.0, 0.0, 0.0]
            for j in range(M):
                tot[0] += rbf[i][j]
                tot[1] += rbf[i][j]
                tot[2] += rbf[i][j]
            W.append([D[i][0] / tot[0], D[i][1] / tot[1], D[i][2] / tot[2]])
        t1 = time.perf_counter()
        out = []
        for i in range(n_sample_vertices):
            acc = [0.0, 0.0, 0.0]
            row = Dl[i]
            for c in range(M):
                r = math.exp(-(row[c] ** 2 / s[c] ** 2))
                acc[0] += W[c][0] * r
                acc[1] += W[c][1] * r
                acc[2] += W[c][2] * r
            out.append(acc)
        t2 = time.perf_counter()
        eq4 += t1 - t0
        eq5 += t2 - t1
    return eq5 / (n_sample_vertices * n_frames) + eq4 / (N * n_frames)


def scipy_rbfinterpolator(marker_points, vertices, disp, width):
    """scipy RBFInterpolator on all frames at once: (seconds, (F, N, 3) float64 result)."""
    from scipy.interpolate import RBFInterpolator

    F, M = disp.shape[:2]
    t0 = time.perf_counter()
    values = disp.transpose(1, 0, 2).reshape(M, 3 * F)
    interp = RBFInterpolator(marker_points, values, kernel="gaussian", epsilon=1.0 / width, degree=-1)
    out = interp(vertices)
    dt = time.perf_counter() - t0
    return dt, out.reshape(len(vertices), F, 3)


# ------------------------------------------------------------------------------------------ report
def machine() -> str:
    cpu = platform.processor() or "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    blas = "?"
    try:
        from threadpoolctl import threadpool_info

        info = [i for i in threadpool_info() if i.get("user_api") == "blas"]
        blas = "; ".join(f"{Path(i['filepath']).name} {i.get('version')} {i.get('architecture')} x{i['num_threads']}" for i in info)
    except Exception:  # pragma: no cover
        pass
    return (f"{cpu}, {os.cpu_count()} logical CPUs, {platform.system()} {platform.release()}, Python "
            f"{platform.python_version()}, numpy {np.__version__}; BLAS pools: {blas}")


def loadavg() -> str:
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:  # pragma: no cover
        return "?"


def maxrss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--vertices", type=int, default=100_000)
    ap.add_argument("--markers", type=int, default=41)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--chunk-frames", type=int, default=None)
    ap.add_argument("--plugin-sample", type=int, default=2000, help="vertices timed for baseline (a)")
    ap.add_argument("--skip-scipy", action="store_true")
    args = ap.parse_args(argv)
    N, M, F = args.vertices, args.markers, args.frames

    print(f"machine: {machine()}")
    print(f"load average at start: {loadavg()}")
    v, markers, D_vc, D_cc, disp = make_problem(N, M, F)
    gappy = with_gaps(disp)
    n_partial = int((~np.isfinite(gappy).all(axis=2)).any(axis=1).sum())
    print(f"problem: N = {N} vertices, M = {M} markers, F = {F} frames; output {F * N * 12 / 1e9:.2f} GB float32")
    print(f"rss after set-up: {maxrss_mb():.0f} MB")

    t0 = time.perf_counter()
    rbf = RBFTransfer(D_vc, D_cc).fit()
    t_fit = time.perf_counter() - t0
    width = float(rbf.widths[0])
    print(f"\nusdface RBFTransfer (interpolate, gaussian, width {width:.3f} cm = {DEFAULT_WIDTH_FACTOR:g} x median marker spacing, "
          f"cond {rbf.condition_number:.3g})")
    print(f"  set-up + fit (SVD, LU, B = Phi_vc A^-1):{t_fit * 1e3:8.1f} ms")

    consume(compute_chunks(rbf, disp[: min(F, 50)], args.chunk_frames))  # warm-up
    times = [consume(compute_chunks(rbf, disp, args.chunk_frames)) for _ in range(args.repeats)]
    best, med = min(times), statistics.median(times)
    ours = best / F
    print(f"  stream {F} frames, all valid:           best {best:.3f} s, median {med:.3f} s "
          f"-> {ours * 1e3:.3f} ms/frame, {ours / N * 1e9:.2f} ns/vertex/frame "
          f"[target <= 2 ms/frame: {'PASS' if ours <= 2e-3 else 'FAIL'}]")
    print(f"  throughput: {F * N * 12 / best / 1e9:.2f} GB/s of float32 points")
    rtimes = [consume(compute_chunks(rbf, disp, args.chunk_frames, reuse_buffer=True)) for _ in range(args.repeats)]
    print(f"  same with reuse_buffer=True (no page faults): best {min(rtimes):.3f} s, median "
          f"{statistics.median(rtimes):.3f} s -> {min(rtimes) / F * 1e3:.3f} ms/frame")

    gtimes = [consume(compute_chunks(rbf, gappy, args.chunk_frames)) for _ in range(max(1, args.repeats // 2))]
    print(f"  stream with {n_partial} frames missing markers: best {min(gtimes):.3f} s "
          f"-> {min(gtimes) / F * 1e3:.3f} ms/frame; cache {rbf.cache_info()}")

    gc.collect()
    rss_before = maxrss_mb()
    for reuse in (False, True):
        tracemalloc.start()
        consume(compute_chunks(rbf, disp, args.chunk_frames, reuse_buffer=reuse))
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        print(f"  memory while streaming (reuse_buffer={reuse}): tracemalloc peak {peak / 2**20:.0f} MiB for the loop "
              f"(the whole output would be {F * N * 12 / 2**20:.0f} MiB)")
    print(f"  process maxrss before/after the streaming runs: {rss_before:.0f} -> {maxrss_mb():.0f} MB")

    # float64 path for reference
    t0 = time.perf_counter()
    for _ in rbf.iter_chunks(disp, dtype=np.float64):
        pass
    t64 = time.perf_counter() - t0
    print(f"  float64 path (accuracy checks):       {t64 / F * 1e3:.3f} ms/frame")

    # baseline (a)
    n_sample = min(args.plugin_sample, N)
    per_vf = plugin_loop_per_vertex_frame(D_vc, D_cc, rbf.widths, disp, n_sample, 2)
    print(f"\nbaseline (a) plug-in style per-vertex Python loop (Eqs. 4-5), {n_sample} vertices x 2 frames sampled:")
    print(f"  {per_vf * 1e9:.0f} ns/vertex/frame ({per_vf * 1e3:.5f} ms per vertex; paper: ~0.1 ms per vertex in Maya)"
          f" -> projected {per_vf * N * F:.0f} s for {F} x {N}")
    print(f"  ratio baseline (a) / usdface: {per_vf * N / ours:,.0f}x")

    if not args.skip_scipy:
        t_sp, ref = scipy_rbfinterpolator(v[markers], v, disp, width)
        mine = rbf.apply(disp[:5], dtype=np.float64)
        err = np.abs(ref[:, :5].transpose(1, 0, 2) - mine).max() / np.abs(mine).max()
        del ref
        gc.collect()
        print(f"\nbaseline (b) scipy.interpolate.RBFInterpolator (gaussian, epsilon = 1/width, degree=-1), all {F} frames "
              f"at once on {N} vertices:")
        print(f"  {t_sp:.2f} s -> {t_sp / F * 1e3:.3f} ms/frame, {t_sp / F / N * 1e9:.2f} ns/vertex/frame "
              f"(float64; max rel. difference to usdface on 5 frames {err:.1e})")
        print(f"  ratio baseline (b) / usdface: {t_sp / best:.1f}x (usdface fit + stream: {t_sp / (best + t_fit):.1f}x)")
    print(f"\nload average at end: {loadavg()}; process maxrss {maxrss_mb():.0f} MB")


if __name__ == "__main__":
    main()
