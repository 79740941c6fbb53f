"""Benchmark: `usdface playblast` frames per second against a bare loop encoding the same frames.

Run by hand (not in CI):

    python benchmarks/bench_playblast.py [SHOT] [--frames 300] [--size 960x540]

SHOT defaults to the README's main job (``usdface run`` on the Jaw take, made in a temporary
folder when not given). Measured in one run on this machine, same encoder settings throughout
(libx264, yuv420p, the playblast's default crf and preset):

- playblast of the first N frames with 2 render threads (the default), 1 thread, and 2 worker
  processes: wall time and frames/s;
- baseline: a bare loop writing the same N frames (decoded back from the playblast into memory
  beforehand) with the same MovieWriter: the cost of encoding alone;
- render alone: the same frames as stills (``plan_playblast(...).stills``, one thread, no encoder).

Prints the ratios playblast / bare encode (1.0 = rendering costs nothing on top of the encode;
the goal is <= 2.0: rendering no more than the encode) and the machine's load, since the machine
is shared and noisy.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from usdface import api  # noqa: E402
from usdface.media import MovieWriter, read_movie  # noqa: E402
from usdface.options import PlayblastOptions  # noqa: E402
from usdface.playblast import plan_playblast  # noqa: E402
from usdface.usd.playback import open_playblast_shots  # noqa: E402


def playblast(shot, output, options):
    """`usdface playblast` through the Python API (the command's own function)."""
    return api.playblast(shot, options, output=output)


def playblast_stills(shot, times, options):
    """The same frames as the movie, rendered in this thread and not encoded."""
    params = options.parameters()
    return plan_playblast(open_playblast_shots(shot, params), params).stills(times)


def main_job(folder: Path) -> Path:
    out = folder / "jaw"
    a = REPO / "sample_assets"
    subprocess.run([sys.executable, "-m", "usdface", "run", "--mesh", a / "meshes" / "makehuman_hm08_face_cm.obj",
                    "--capture", a / "capture" / "JawMoCap.ma", "--layout",
                    a / "layouts" / "makehuman_hm08_face.layout.json", "-o", out, "-q"], check=True)
    return out / "shot.usda"


def timed(fn):
    t0, c0 = time.perf_counter(), time.process_time()
    result = fn()
    return time.perf_counter() - t0, time.process_time() - c0, result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("shot", nargs="?")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--size", default="960x540")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    size = PlayblastOptions(size=args.size).size
    with tempfile.TemporaryDirectory(prefix="usdface-bench-playblast-") as tmp:
        tmp = Path(tmp)
        shot = Path(args.shot) if args.shot else main_job(tmp)
        rng = (0, args.frames - 1)
        print(f"shot {shot}, frames {rng[0]}..{rng[1]} at {size[0]}x{size[1]}; cores usable: "
              f"{len(os.sched_getaffinity(0))}; load average {os.getloadavg()[0]:.2f}")
        playblast(shot, tmp / "warm.mp4", PlayblastOptions(frame_range=(0, 9), size=size))  # compile the kernels
        playblast(shot, tmp / "pb.mp4", PlayblastOptions(frame_range=rng, size=size))
        frames = [img for _, img in read_movie(tmp / "pb.mp4")]
        times = list(range(rng[0], rng[1] + 1))

        def bare():
            with MovieWriter(tmp / "bare.mp4", size, 60.0) as w:
                for img in frames:
                    w.write(img)

        opts = PlayblastOptions(frame_range=rng, size=size)
        cases = [("playblast, 2 threads (default)",
                  lambda: playblast(shot, tmp / "pb.mp4", opts.replace(workers=2))),
                 ("playblast, 1 thread", lambda: playblast(shot, tmp / "pb.mp4", opts.replace(workers=1))),
                 ("playblast, 2 processes",
                  lambda: playblast(shot, tmp / "pb.mp4", opts.replace(workers=2, parallel="processes"))),
                 ("bare encode loop (same frames)", bare),
                 ("render only (stills, 1 thread)", lambda: playblast_stills(shot, times, opts))]
        walls = {label: [] for label, _ in cases}
        cpus = {label: [] for label, _ in cases}
        for _ in range(args.repeat):  # interleaved, so a burst of load hits every case alike
            for label, fn in cases:
                wall, cpu, _ = timed(fn)
                walls[label].append(wall)
                cpus[label].append(cpu)
        n = len(frames)
        enc = float(np.median(walls["bare encode loop (same frames)"]))
        print(f"median of {args.repeat} interleaved runs")
        print(f"{'':34s} {'wall s':>8s} {'cpu s':>8s} {'frames/s':>9s} {'x bare encode':>14s}")
        for label, _ in cases:
            wall, cpu = float(np.median(walls[label])), float(np.median(cpus[label]))
            print(f"{label:34s} {wall:8.2f} {cpu:8.2f} {n / wall:9.1f} {wall / enc:14.2f}")
        print("(cpu s: this process only; processes' workers are not counted)")
        print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
