"""Tracking benchmark (run by hand, not in CI): accuracy and throughput at 1280x720.

    python benchmarks/bench_tracking.py [--frames 150] [--keep DIR]

Renders a 1280x720 clip from the real AnimFace JawMoCap capture over the astronaut photo
(usdface.tracking.synthetic: dots of radius 6 px at 30 px/cm, head sway and jerk, lighting change,
motion blur, noise, hand occluder, distractors, mp4v compression), then times in the same run:

- baseline: a plain decode-only loop over the same video (OpenCV, the floor for any tracker);
- tracking: decode + detect + track (what `usdface track` does, minus writing);

and prints frames/s of both, their ratio, the machine's load average, and the accuracy numbers
against the exact ground truth.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--keep", help="folder to keep the rendered clip in")
    ap.add_argument("--repeat", type=int, default=3, help="timing repeats (best of)")
    args = ap.parse_args()

    from usdface.io.video import open_video
    from usdface.tracking.synthetic import animface_clip, score_tracks, write_clip
    from usdface.tracking.tracker import initialise_from_seeds, track_frames

    folder = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench_tracking_"))
    folder.mkdir(parents=True, exist_ok=True)
    video = folder / "bench_1280x720.mp4"
    t = time.perf_counter()
    clip = animface_clip(REPO / "sample_assets", n_frames=args.frames, start=180, step=2, size=(1280, 720),
                         px_per_cm=30.0, radius=6.0, sway=120.0, jerk=60.0)
    write_clip(video, clip)
    print(f"rendered {args.frames} frames 1280x720 in {time.perf_counter() - t:.1f} s -> {video} "
          f"({video.stat().st_size / 1e6:.1f} MB)")

    reader = open_video(video)
    first = reader.read(0)
    seeds = clip.seeds(0, jitter=1.5, seed=1)
    # warm-up (numba compile / cache load)
    det, names, xy, area = initialise_from_seeds(first, seeds, radius=(4, 9))
    track_frames([first, first], det, names, xy, initial_area=area, rate=reader.rate, size=reader.size)

    decode, tracking, result = [], [], None
    for _ in range(args.repeat):
        t = time.perf_counter()
        n = 0
        for _, frame in reader:
            n += 1
        decode.append(n / (time.perf_counter() - t))
        det, names, xy, area = initialise_from_seeds(first, seeds, radius=(4, 9))
        t = time.perf_counter()
        result = track_frames(reader, det, names, xy, initial_area=area, rate=reader.rate, size=reader.size)
        tracking.append(n / (time.perf_counter() - t))
    load = os.getloadavg()
    score = score_tracks(result.positions, clip.truth, clip.visible)
    print(f"machine: {os.cpu_count()} cores, load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    print(f"decode only      : {max(decode):7.1f} frames/s (best of {args.repeat}: {', '.join(f'{v:.1f}' for v in decode)})")
    print(f"decode + tracking: {max(tracking):7.1f} frames/s (best of {args.repeat}: {', '.join(f'{v:.1f}' for v in tracking)})")
    print(f"ratio tracking / decode-only: {max(tracking) / max(decode):.2f}")
    print(f"accuracy: mean {score['mean_error']:.3f} px, p99 {score['p99_error']:.3f} px, max {score['max_error']:.3f} px, "
          f"found {100 * score['found']:.2f}% of {score['n_visible']} visible, identity switches "
          f"{score['identity_switches']}, occluded marked invalid {100 * score['occluded_invalid']:.1f}% of "
          f"{score['n_occluded']}")
    print(f"tracker stats: {result.stats}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
