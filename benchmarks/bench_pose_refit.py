"""What the pose refit costs: ``solve_take`` with the default refit against none, same take, same run.

The take: the tuning rig's (``make_heldout_rig.py --tuning``: 3600 frames at 60 Hz, 41 markers,
52 shapes), conditioned like ``usdface solve`` (stabilised) with its rest pose. Timed: the call of
:func:`usdface.blendshape.take.solve_take`, pose refit off and at its default, interleaved
(off, on, off, on...), ``--repeat`` times each; printed: median wall and process CPU seconds and
their ratios, and the refit's rounds. The machine is shared: quote the load with the figures.

    python benchmarks/bench_pose_refit.py [--repeat 5]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from blendshape_heldout import conditioned, load  # noqa: E402
from make_heldout_rig import ROOT  # noqa: E402


def main(argv=None) -> int:
    import logging

    from usdface.blendshape.posefit import DEFAULT_POSE_REFIT_ROUNDS
    from usdface.blendshape.take import solve_take
    from usdface.mesh.judged_binding import bind_and_judge

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", default=str(ROOT / "out" / "tuning_rig"))
    args = ap.parse_args(argv)
    logging.getLogger("usdface").setLevel(logging.ERROR)
    rig, layout, take, _ = load(Path(args.out), tuning=True)
    cap, _ = conditioned(take, "robust")
    binding, _, _ = bind_and_judge(rig.mesh, cap, layout=layout)
    solve_take(rig, cap, binding, pose_refit=0)  # compile and warm the caches
    times = {0: [], DEFAULT_POSE_REFIT_ROUNDS: []}
    rounds = None
    for _ in range(args.repeat):
        for r in times:
            w0, c0 = time.perf_counter(), time.process_time()
            res = solve_take(rig, cap, binding, pose_refit=r)
            times[r].append((time.perf_counter() - w0, time.process_time() - c0))
            if r:
                rounds = res.pose_refit["rounds"]
    off = np.median(np.array(times[0]), axis=0)
    on = np.median(np.array(times[DEFAULT_POSE_REFIT_ROUNDS]), axis=0)
    print(f"{cap.n_frames} frames, {binding.n_markers} markers, {rig.n_shapes} shapes; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; medians of {args.repeat}, interleaved")
    print("| solve_take | wall (s) | CPU (s) |\n|---|---|---|")
    print(f"| pose refit off | {off[0]:.3f} | {off[1]:.3f} |")
    print(f"| pose refit {DEFAULT_POSE_REFIT_ROUNDS} (default; ran {rounds} rounds) | {on[0]:.3f} | {on[1]:.3f} |")
    print(f"| ratio | {on[0] / off[0]:.2f}x | {on[1] / off[1]:.2f}x |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
