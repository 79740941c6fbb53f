"""Conditioning a capture: the optional steps `import-capture` (and every command that reads a raw
take) applies, in one fixed order."""
from __future__ import annotations

import logging

from dataclasses import dataclass
from typing import Any

from ..errors import OptionError
from ..model.capture import Capture

log = logging.getLogger("usdface")

__all__ = ["Conditioning", "condition_capture"]


@dataclass(frozen=True)
class Conditioning:
    """The conditioning steps to apply (None or empty: the step is skipped); the options of
    `import-capture` build it (:meth:`usdface.options.CaptureOptions.conditioning`).

    ``trim`` (START, END) frame indices; ``fill_gaps`` longest gap filled (frames); ``filter``
    "butterworth" or "savgol" with ``cutoff`` (Hz); ``resample`` new rate (Hz); ``neutral`` where
    the rest pose comes from: None (the still stretch around the first frame), "auto" (around the
    automatically chosen frame), a frame index F (around F) or a range (START, END) (exactly those
    frames, END exclusive), frame indices after trimming (:func:`usdface.capture.neutral.parse_neutral`
    also takes "F" and "START:END"); ``stabilize`` "auto" or marker names; ``start_frame`` the first
    time code; ``allow`` plausibility findings accepted; ``drop_outliers`` outlier samples become gaps.
    """

    trim: tuple | None = None
    fill_gaps: int | None = None
    filter: str | None = None
    cutoff: float = 8.0
    resample: float | None = None
    neutral: Any = None
    stabilize: Any = None
    start_frame: int | None = None
    allow: tuple = ()
    drop_outliers: bool = False


def condition_capture(capture: Capture, steps: Conditioning = Conditioning()) -> tuple[Capture, dict]:
    """Apply the optional conditioning ``steps`` in a fixed order; returns (capture, reports).

    Order: trim -> plausibility checks (:mod:`usdface.capture.plausibility`; ``drop_outliers``
    turns outlier samples into gaps; ``allow`` accepts findings by code) -> marker-swap detection
    (reported) -> gap filling -> noise filter -> neutral frame (or named frames) -> resample -> head
    stabilisation (relative to the neutral frame; judged on held-out markers) -> rest pose (the still
    stretch around the neutral frame, or the named frames, averaged robustly:
    :func:`usdface.capture.neutral.set_rest_pose`; ``reports["restPose"]``, and a warning logged
    when the markers move more than :data:`usdface.capture.neutral.NEUTRAL_MOTION_WARN_CM` there)
    -> time offset (time code = frame index from 0, or from ``start_frame``).

    Raises PlausibilityError on a plausibility error that ``allow`` does not accept, OptionError
    (exit 2) when ``neutral`` names frames outside the take (after trimming).
    """
    from . import gaps, neutral as neutral_mod, plausibility, swaps, timing

    trim, fill_gaps, filter, cutoff, resample = steps.trim, steps.fill_gaps, steps.filter, steps.cutoff, steps.resample
    neutral, stabilize, start_frame = steps.neutral, steps.stabilize, steps.start_frame
    allow, drop_outliers = steps.allow, steps.drop_outliers
    reports: dict = {}
    # how the conditioned frames map to the source's (a playblast beside the source video needs it)
    timing_report = {"sourceRate": float(capture.rate), "sourceFrames": int(capture.n_frames),
                     "trimStart": int(trim[0]) if trim is not None else 0}
    if trim is not None:
        start, end = trim
        stop = capture.n_frames if end is None else end
        if not (0 <= start < stop <= capture.n_frames):
            raise OptionError(f"--trim {start} {end}: expected 0 <= START < END <= {capture.n_frames} "
                              f"(the capture {capture.source} has {capture.n_frames} frames)")
        if not (start <= capture.neutral_frame < stop):
            # the file's neutral (its first frame) is cut away: start from the first kept frame;
            # --neutral, applied below, still overrides
            capture = neutral_mod.set_neutral(capture, max(int(start), 0), how="trim")
        capture = timing.trim(capture, start=start, end=end)
    allow = plausibility.parse_allow(allow)
    findings = plausibility.check_capture(capture)
    if drop_outliers:
        capture, dropped = plausibility.drop_outliers(capture, findings)
        if dropped:
            reports["droppedOutliers"] = dropped
            # dropped samples are gaps now: the finding is reported, not raised
            allow = allow | {"outliers"}
            findings = [f if f.code != "outliers" else plausibility.Finding(
                "outliers", "warning", f.message.replace("; --drop-outliers makes them gaps, --allow outliers keeps them",
                                                         f": {dropped} sample(s) made gaps (--drop-outliers)"),
                f.markers, f.frames) for f in findings]
    checked = plausibility.report(findings, allow=allow)
    events = swaps.detect_swaps(capture)
    if events:
        reports["swaps"] = [e.summary() if hasattr(e, "summary") else e.__dict__ for e in events]
        for e in events:
            log.warning("possible marker swap at frame %s: %s <-> %s", e.frame, e.marker_a, e.marker_b)
    if fill_gaps is not None:
        capture, report = gaps.fill_gaps(capture, max_gap=fill_gaps)
        reports["gaps"] = report.summary()
    if filter is not None:
        from . import filtering

        # a Savitzky-Golay filter is set by its window, not a cutoff frequency
        cutoff_option = {"cutoff_hz": cutoff} if filter == "butterworth" else {}
        capture = filtering.filter_noise(capture, method=filter, **cutoff_option)
    # the neutral frame (or the named frames) is chosen on the capture's own frames (after
    # trimming), then resampling carries it to the nearest new frame (the frames in its time span)
    capture, rest_how = _set_neutral(capture, neutral, reports)
    if resample is not None:
        capture = timing.resample(capture, rate=resample, allow=frozenset(allow))
    if stabilize is not None:
        from .stabilize import stabilize as stabilize_fn

        markers = None if stabilize == "auto" else list(stabilize)
        capture, report = stabilize_fn(capture, markers=markers)
        reports["stabilize"] = report.summary()
        finding = plausibility.stabilize_finding(reports["stabilize"], what=plausibility._where(capture),
                                                 units=capture.units)
        if finding is not None:
            checked += plausibility.report([finding], allow=allow)
    # the rest pose: averaged over the still stretch (found on the stabilised positions, so head
    # motion does not count as motion) or over the named frames
    capture, rest = neutral_mod.set_rest_pose(capture, capture.neutral_frames if rest_how == "range" else None,
                                              how=rest_how)
    reports["restPose"] = dict(rest.summary(), text=rest.text())
    for message in rest.warnings:
        log.warning("%s", message)
    if checked:
        reports["plausibility"] = checked
    # one time-code convention for every output: frame index from 0 unless --start-frame says
    # otherwise (C3D counts from 1, TRC from its first time; the source's number is in the history)
    target = 0 if start_frame is None else start_frame
    if capture.start_frame != target:
        reports["timeCodes"] = {"sourceStart": int(capture.start_frame), "start": int(target)}
        capture = timing.offset(capture, start_frame=target)
    timing_report.update(rate=float(capture.rate), frames=int(capture.n_frames),
                         startTimeCode=int(capture.start_frame))
    reports["timing"] = timing_report
    return capture, reports


def _set_neutral(capture: Capture, neutral, reports: dict) -> tuple[Capture, str | None]:
    """The neutral frame (or a named range of frames) set on ``capture``; returns it and how the
    rest pose is to be labelled ("auto", "frame", "range", or None: the first frame)."""
    from . import neutral as neutral_mod

    spec = neutral_mod.parse_neutral(neutral)
    neutral_mod.check_neutral_frames(spec, capture.n_frames, source=capture.source)
    if spec == "auto":
        index, report = neutral_mod.choose_neutral(capture)
        reports["neutral"] = report.summary()
        return neutral_mod.set_neutral(capture, index, how="auto"), "auto"
    if isinstance(spec, tuple):
        a, b = spec
        capture = neutral_mod.set_neutral(capture, (a + b - 1) // 2, how="option")
        return capture.replace(neutral_window=(a, b)), "range"
    if spec is not None:
        return neutral_mod.set_neutral(capture, spec, how="option"), "frame"
    return capture, None
