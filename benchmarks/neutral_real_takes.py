"""The rest pose on the three real AnimFace takes: which frames, how still, and the jitter at rest.

Each take is read from its Maya ASCII file and conditioned as ``usdface import-capture --stabilize``
does it (:func:`usdface.capture.conditioning.condition_capture`: stabilised relative to the neutral
frame, then the rest pose averaged over the still stretch around it), with the first frame as the
neutral (the default) and with the automatic choice (``--neutral auto``). Printed per take and mode:

- the frames used and the residual motion there (RMS and largest deviation of the markers from the
  rest pose, cm) and the measured white noise;
- the jitter of the displacement at rest: the RMS marker displacement over the stretch's frames,
  measured from the one-frame neutral (usdface 0.2) and from the rest pose;
- the same held out: the stretch cut into 0.1 s blocks, the rest pose averaged over the even blocks
  and the displacement measured on the odd ones (the one-frame neutral taken from an even block
  too), so the rest pose is not judged on the frames it was averaged over.

The frames and the motion are what the command prints and the capture layer records.

    python benchmarks/neutral_real_takes.py
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TAKES = ("Jaw", "Eyebrows", "Nose")
BLOCK_SECONDS = 0.1


def jitter(positions, reference) -> float:
    """RMS over the valid samples of ``|p_f - reference|`` (cm)."""
    d2 = ((positions - reference[None]) ** 2).sum(axis=2)
    return float(np.sqrt(np.nanmean(d2)))


def held_out(positions, seed_in_block: int, rate: float) -> tuple[float, float]:
    """(one frame, rest pose) jitter on the odd 0.1 s blocks, both references from the even blocks."""
    from usdface.capture.rest import robust_rest_pose

    n = positions.shape[0]
    block = max(1, int(round(BLOCK_SECONDS * rate)))
    even = (np.arange(n) // block) % 2 == 0
    if even.all():
        return float("nan"), float("nan")
    one = positions[min(seed_in_block, n - 1)] if even[min(seed_in_block, n - 1)] else positions[0]
    rest = robust_rest_pose(positions[even])[0]
    return jitter(positions[~even], one), jitter(positions[~even], rest)


def main(argv=None) -> int:
    from usdface.capture.neutral import NEUTRAL_MOTION_WARN_CM
    from usdface.capture.conditioning import Conditioning, condition_capture
    from usdface.usd.inputs import load_capture

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.parse_args(argv)
    print(f"warning threshold: {NEUTRAL_MOTION_WARN_CM:g} cm RMS over the stretch\n")
    print("| take | neutral | frames used | s | motion RMS / max (cm) | noise (cm) | jitter at rest, one frame -> "
          "rest pose (cm) | held out: one frame -> rest pose (cm) |")
    print("|---|---|---|---|---|---|---|---|")
    for take in TAKES:
        for mode in (None, "auto"):
            # conditioned exactly as `usdface import-capture --stabilize [--neutral auto]` does it
            cap, reports = condition_capture(load_capture(ROOT / "sample_assets" / "capture" / f"{take}MoCap.ma"),
                                             Conditioning(stabilize="auto", neutral=mode))
            rest = reports["restPose"]
            (a, b), frame = cap.neutral_window, cap.neutral_frame
            p = cap.positions[a:b]
            one = jitter(p, cap.positions[frame])
            robust = jitter(p, cap.neutral)
            h_one, h_rest = held_out(p, frame - a, cap.rate)
            flag = " (warned)" if rest["warnings"] else ""
            print(f"| {take} | {'first frame' if mode is None else 'auto'} (frame {frame}) | {a}-{b - 1} | "
                  f"{(b - a) / cap.rate:.2f} | {rest['motionRmsCm']:.3f} / {rest['motionMaxCm']:.3f}{flag} "
                  f"| {rest['noiseCm']:.5f} | {one:.3f} -> {robust:.3f} ({100 * (1 - robust / one):.0f}% less) | "
                  f"{h_one:.3f} -> {h_rest:.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
