"""Speed of the whole-take blend-shape solve against a per-frame scipy ``lsq_linear`` loop.

The take: ``--frames`` (default 10,000) of smooth random weights over the observable shapes of the
real 52-shape MakeHuman ARKit rig, 41 markers, 0.5 mm noise, 5% of samples missing
(:mod:`usdface.blendshape.synthetic`). Ours: :class:`usdface.blendshape.solver.CurveSolver` with
default options (smoothing, sparsity, left/right prior, refit), set-up included, best of
``--repeat``. Baseline, same run: ``scipy.optimize.lsq_linear`` per frame on the frame's valid
markers with bounds [0, 1] (no smoothing: frames independent), timed on the first
``--baseline-frames`` frames and reported per frame. Wall time and process CPU time are both
printed: the machine is shared, and CPU time is what the solve itself costs.

    python benchmarks/bench_blendshape_solve.py [--frames 10000] [--baseline-frames 1000]
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None) -> int:
    from scipy.optimize import lsq_linear
    from threadpoolctl import threadpool_limits

    from blendshape_synthetic import load, mesh_error
    from usdface.blendshape.mirror import find_mirror_pairs
    from usdface.blendshape.solver import CurveSolver
    from usdface.blendshape.synthetic import observable_shapes, random_weight_curves, synthetic_take
    from usdface.blendshape.take import DEFAULT_EXCLUDE, resolve_exclude

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=10000)
    ap.add_argument("--baseline-frames", type=int, default=1000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)

    rig, binding, basis = load()
    truth = random_weight_curves(args.frames, rig.n_shapes, shapes=observable_shapes(rig.names), seed=args.seed)
    take = synthetic_take(basis, truth, seed=args.seed + 1)
    pairs = find_mirror_pairs(rig).symmetric_pairs
    exclude = resolve_exclude(DEFAULT_EXCLUDE, rig.names)
    CurveSolver(basis, names=rig.names, symmetric_pairs=pairs, exclude=exclude).solve(
        take.displacements[:200], rate=take.rate)  # compile the numba kernels outside the timing
    best_wall = best_cpu = np.inf
    sol = None
    for _ in range(args.repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        solver = CurveSolver(basis, names=rig.names, marker_names=binding.names, symmetric_pairs=pairs, exclude=exclude)
        sol = solver.solve(take.displacements, rate=take.rate)
        best_wall = min(best_wall, time.perf_counter() - w0)
        best_cpu = min(best_cpu, time.process_time() - c0)
    f = args.frames
    print(f"ours (whole take, defaults: smoothing {solver.smoothing_hz} Hz, sparsity {solver.sparsity}, symmetry "
          f"{solver.symmetry}, refit): {f} frames x {rig.n_shapes} shapes x {binding.n_markers} markers, "
          f"{sol.iterations} iterations")
    print(f"  wall {best_wall:.3f} s = {f / best_wall:,.0f} frames/s; CPU {best_cpu:.3f} s = {f / best_cpu:,.0f} frames/s")

    nb = min(args.baseline_frames, f)
    a = basis.transpose(0, 2, 1).reshape(3 * binding.n_markers, rig.n_shapes)
    d = take.displacements.reshape(f, -1)
    est = np.zeros((nb, rig.n_shapes))
    w0, c0 = time.perf_counter(), time.process_time()
    with threadpool_limits(1, "blas"):
        for i in range(nb):
            ok = np.isfinite(d[i])
            est[i] = lsq_linear(a[ok], d[i, ok], bounds=(0.0, 1.0)).x
    bw, bc = time.perf_counter() - w0, time.process_time() - c0
    print(f"baseline (scipy lsq_linear per frame, bounds [0, 1], valid markers): {nb} frames")
    print(f"  wall {bw:.3f} s = {nb / bw:,.0f} frames/s; CPU {bc:.3f} s = {nb / bc:,.0f} frames/s")
    print(f"speed-up: {(f / best_wall) / (nb / bw):.1f}x wall, {(f / best_cpu) / (nb / bc):.1f}x CPU")
    rms_ours = float(np.sqrt(((sol.weights[:nb] - truth[:nb]) ** 2).mean()))
    rms_base = float(np.sqrt(((est - truth[:nb]) ** 2).mean()))
    print(f"accuracy on the first {nb} frames: weight RMS ours {rms_ours:.4f}, baseline {rms_base:.4f}; mesh error ours "
          f"{100 * mesh_error(rig.deltas, truth[:nb], rig.deltas, sol.weights[:nb]):.2f}%, baseline "
          f"{100 * mesh_error(rig.deltas, truth[:nb], rig.deltas, est):.2f}%")
    return 0


if __name__ == "__main__":
    import os
    import sys

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    raise SystemExit(main())
