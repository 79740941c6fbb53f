"""Limits on a capture's timing: rate, frame count, resampling, judged before any allocation.

A capture's frame numbers and rate are untrusted numbers that size the arrays a reader fills: a
CSV whose last row is frame 2000000000 asked for 1.79 TiB, a rate of 1e300 Hz or Maya keys 1e-9
frame apart (2.4e10 Hz) passed with a speed warning, ``--resample 1e-9`` made 200 frames into 1.
These checks are plausibility findings (:mod:`usdface.findings`): an error names the
file (and the line or key) and the ``--allow CODE`` that accepts it; what is accepted is still
checked against the memory it needs (:func:`usdface.memory.check_memory`).

=================  ====================================================================  =================
code               error when                                                            override
=================  ====================================================================  =================
``rate``           a capture rate (declared, given with ``--rate`` or inferred from      ``--allow rate``
                   key spacing) outside 1-10000 Hz
``frame-count``    more than 1,000,000 frames, or frame numbers spanning more than       ``--allow
                   100 x the rows (keys) read + 1000 frames (a typo'd frame number)     frame-count``
``resample``       ``--resample`` to a rate outside 1-10000 Hz, by a factor beyond      ``--allow resample``
                   100 either way, or to fewer than 2 frames of a longer take
=================  ====================================================================  =================

The bounds: optical capture runs at 60-2000 Hz (high-speed systems up to about 10 kHz), video at
24-240 fps; 1,000,000 frames is 4.6 h at 60 Hz and 17 min at 1 kHz (the sample takes are 1590
frames at 60 Hz); a real take's rows cover its frame range, apart from dropped frames.
"""
from __future__ import annotations

import math

from ..errors import ResourceError
from ..findings import Finding, refuse

__all__ = ["RATE_HZ", "MAX_CAPTURE_FRAMES", "SPAN_PER_SAMPLE", "SPAN_SLACK", "MAX_RESAMPLE_FACTOR",
           "READ_BYTES_PER_SAMPLE", "rate_finding", "frame_count_finding", "resample_finding", "check_read_size"]

#: plausible capture rates, Hz
RATE_HZ = (1.0, 10000.0)
#: most frames a capture plausibly holds
MAX_CAPTURE_FRAMES = 1_000_000
#: frame numbers may span at most SPAN_PER_SAMPLE x the rows (keys) read + SPAN_SLACK frames
SPAN_PER_SAMPLE = 100
SPAN_SLACK = 1000
#: largest resampling factor either way
MAX_RESAMPLE_FACTOR = 100.0
#: bytes a reader holds per frame and marker at its peak (float64 positions, the rotated copy,
#: validity masks and the Capture the conditioning steps copy)
READ_BYTES_PER_SAMPLE = 4 * 3 * 8


def _duration(frames: float, rate: float | None) -> str:
    if not rate or not math.isfinite(rate) or rate <= 0:
        return ""
    seconds = frames / rate
    for unit, size in (("days", 86400), ("h", 3600), ("min", 60)):
        if seconds >= size:
            return f", {seconds / size:.3g} {unit} at {rate:g} Hz"
    return f", {seconds:.3g} s at {rate:g} Hz"


def rate_finding(rate: float, *, what: str, origin: str = "declared") -> Finding | None:
    """``rate`` finding when ``rate`` (Hz) is outside :data:`RATE_HZ`; ``origin`` says where the
    rate came from ("declared", "given with --rate", "inferred from the key spacing")."""
    lo, hi = RATE_HZ
    if lo <= rate <= hi:
        return None
    return Finding("rate", "error", f"{what}: a capture rate of {rate:g} Hz ({origin}) is outside the plausible "
                                    f"{lo:g}-{hi:g} Hz: a typo or the wrong unit? (--allow rate accepts it)")


def frame_count_finding(frames: float, *, what: str, samples: int | None = None, rate: float | None = None,
                        detail: str = "", noun: str = "rows") -> Finding | None:
    """``frame-count`` finding for a capture of ``frames`` frames read from ``samples`` rows
    (keys), or None. ``detail`` names where the extreme frame number is (", line 203: frame 2000000000")."""
    if samples is not None and frames > SPAN_PER_SAMPLE * samples + SPAN_SLACK:
        return Finding("frame-count", "error",
                       f"{what}: its frame numbers span {frames:,.0f} frames but it holds {samples:,} {noun}{detail}: a "
                       f"typo'd frame number? (--allow frame-count reads the frames between as gaps, if memory allows)")
    if frames > MAX_CAPTURE_FRAMES:
        return Finding("frame-count", "error",
                       f"{what}: {frames:,.0f} frames{_duration(frames, rate)}{detail} is more than the "
                       f"{MAX_CAPTURE_FRAMES:,} a take plausibly holds: a typo'd frame number or rate? "
                       f"(--allow frame-count accepts it if memory allows)")
    return None


def resample_finding(*, frames: int, rate: float, new_frames: int, new_rate: float, what: str) -> Finding | None:
    """``resample`` finding for resampling ``frames`` at ``rate`` to ``new_frames`` at ``new_rate``."""
    lo, hi = RATE_HZ
    factor = new_rate / rate
    problem = None
    if not lo <= new_rate <= hi:
        problem = f"{new_rate:g} Hz is outside the plausible {lo:g}-{hi:g} Hz"
    elif not 1.0 / MAX_RESAMPLE_FACTOR <= factor <= MAX_RESAMPLE_FACTOR:
        problem = f"a factor of {factor:.3g}, beyond {MAX_RESAMPLE_FACTOR:g}x either way"
    elif new_frames < 2 <= frames:
        problem = f"it leaves {new_frames} frame(s) of {frames}"
    if problem is None:
        return None
    return Finding("resample", "error", f"{what}: --resample {new_rate:g} Hz from {rate:g} Hz ({frames} frames -> "
                                        f"{new_frames}): {problem}: a typo? (--allow resample accepts it)")


def check_read_size(*, what: str, frames: float, markers: int, rate: float | None = None,
                    rate_origin: str = "declared", samples: int | None = None, detail: str = "",
                    noun: str = "rows", allow=frozenset()) -> int:
    """A reader's gate before it allocates (F, M, 3) positions: the rate and frame-count findings
    (raised unless ``allow`` accepts them), then the memory they need.

    Returns the frame count as an int. Raises PlausibilityError (exit 2) or ResourceError (exit 1).
    """
    from ..memory import check_memory

    findings = [rate_finding(rate, what=what, origin=rate_origin) if rate is not None else None,
                frame_count_finding(frames, what=what, samples=samples, rate=rate, detail=detail, noun=noun)]
    refuse(findings, allow=allow)
    if not frames <= 2**53:  # inf, or more than any float64 counts exactly: no memory holds it
        raise ResourceError(f"{what}: {frames:,.0f} frames x {markers} markers: more than any machine's memory")
    check_memory(frames * markers * READ_BYTES_PER_SAMPLE, what=f"{what}: {frames:,.0f} frames x {markers} markers",
                 hint="read a shorter range of the take")
    return int(frames)
