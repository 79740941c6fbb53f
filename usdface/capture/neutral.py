"""Neutral frame and rest pose: choose the neutral frame, set it, and average the rest pose over
the still stretch around it.

:func:`set_rest_pose` is the step every displacement depends on: from the neutral frame (the
first frame by default, the automatic choice below, a frame the user names) it finds the still
stretch around it (:func:`usdface.capture.rest.still_stretch`), or takes the frames the user names,
and records it on the capture, whose :attr:`~usdface.model.capture.Capture.neutral` is then the
robust average over it. :func:`parse_neutral` and :func:`check_neutral_frames` are the
``--neutral F|START:END|auto`` option's parser and range check.

Readers set the neutral frame to 0 (takes usually start neutral). :func:`choose_neutral` finds it
from the data instead: the calmest stretch of a take is often a *held expression* (in the AnimFace
Eyebrows take it is a brow raise), so calmness alone is not enough. The per-marker median pose over
the take is close to neutral whenever the performer returns to rest between actions (and actions
move markers in different directions), so the choice is: among calm frames, the one whose window
is nearest the median pose.

Steps (all vectorised over frames):

1. Unless ``align=False``, remove the head's rigid motion first (positions of a capture without
   ``head_motion`` are stabilised with :func:`usdface.capture.stabilize.stabilize`), so head
   movement counts neither as motion nor as distance from the median.
2. Speed per frame: RMS over valid markers of the central-difference velocity (units/s).
3. Calmness: mean speed over a centred window of ``window`` frames (clipped at the ends).
4. Distance: RMS over valid markers of the distance to the per-marker median position, averaged
   over the same window.
5. Candidates: frames whose calmness is at most the ``calm_quantile`` quantile of the take's;
   the chosen frame is the candidate with the smallest distance.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import MarkerError, OptionError
from ..model.capture import Capture

__all__ = ["choose_neutral", "set_neutral", "NeutralReport", "parse_neutral", "check_neutral_frames",
           "set_rest_pose", "neutral_motion", "RestPoseReport", "NEUTRAL_MOTION_WARN_CM"]

#: warn when the markers move more than this over the neutral stretch (RMS deviation from the rest
#: pose, cm): twice the largest RMS found on the still stretches of the three AnimFace takes (0.25-0.6
#: mm, at their first frame and at their automatic neutral) and of 0.3 mm white noise (0.52 mm); a
#: third of the 3 mm RMS their smallest action shows (the Jaw take's small drop)
NEUTRAL_MOTION_WARN_CM = 0.1


@dataclass(frozen=True)
class NeutralReport:
    """Why :func:`choose_neutral` chose its frame.

    Attributes
    ----------
    frame : int
        Chosen frame index.
    calmest_frame : int
        Frame index of the calmest window (often a held expression, not neutral).
    window : int
        Window length in frames.
    speed : ndarray, shape (F,), float64
        Window-mean RMS marker speed per frame (units/s).
    distance : ndarray, shape (F,), float64
        Window-mean RMS distance to the median pose per frame (units).
    calm_threshold : float
        Speed at or below which a frame was a candidate.
    units : str or None
    """

    frame: int
    calmest_frame: int
    window: int
    speed: np.ndarray
    distance: np.ndarray
    calm_threshold: float
    units: str | None = None

    def summary(self) -> dict:
        return {
            "frame": self.frame,
            "calmest_frame": self.calmest_frame,
            "window": self.window,
            "speed": float(self.speed[self.frame]),
            "distance_to_median": float(self.distance[self.frame]),
            "calmest_distance_to_median": float(self.distance[self.calmest_frame]),
            "calm_threshold": self.calm_threshold,
            "units": self.units,
        }


def _window_mean(x, window):
    """Centred moving mean of a (F,) array with NaN ignored, windows clipped at the ends."""
    ok = np.isfinite(x)
    c = np.concatenate([[0.0], np.cumsum(np.where(ok, x, 0.0))])
    n = np.concatenate([[0], np.cumsum(ok)])
    f = np.arange(x.size)
    lo = np.clip(f - window // 2, 0, x.size)
    hi = np.clip(f - window // 2 + window, 0, x.size)
    cnt = n[hi] - n[lo]
    return np.divide(c[hi] - c[lo], cnt, out=np.full(x.size, np.nan), where=cnt > 0)


def _rms_over_markers(v):
    """(F, M, 3) -> (F,) RMS of vector lengths over valid markers (NaN if none)."""
    d2 = (v**2).sum(axis=2)
    ok = np.isfinite(d2)
    n = ok.sum(axis=1)
    return np.sqrt(np.divide(np.where(ok, d2, 0.0).sum(axis=1), n, out=np.full(n.size, np.nan), where=n > 0))


def choose_neutral(capture: Capture, *, window: int | None = None, calm_quantile: float = 0.5, align: bool = True):
    """Choose the neutral frame from the data (see the module docstring).

    Parameters
    ----------
    capture : Capture
        Input capture (not modified).
    window : int, optional
        Window length in frames (>= 1); default half a second (``round(rate / 2)``).
    calm_quantile : float
        Quantile (0 < q <= 1) of the window speeds below which frames are candidates.
    align : bool
        Remove the head's rigid motion before measuring (see step 1).

    Returns
    -------
    index : int
        Chosen frame index.
    report : NeutralReport
    """
    if window is None:
        window = max(1, int(round(capture.rate / 2)))
    if isinstance(window, (bool, np.bool_)) or not isinstance(window, (int, np.integer)) or window < 1:
        raise OptionError(f"window must be a number of frames >= 1; got {window!r}")
    if not (isinstance(calm_quantile, (int, float, np.floating)) and 0 < calm_quantile <= 1):
        raise OptionError(f"calm_quantile must be in (0, 1]; got {calm_quantile!r}")
    capture.check_not_all_invalid()
    pos = capture.positions
    if align and capture.head_motion is None and capture.n_frames > 1:
        from .stabilize import stabilize  # local: stabilize is the heavier module

        try:
            pos = stabilize(capture)[0].positions
        except MarkerError:
            pos = capture.positions  # too few markers to stabilise: measure as is
    if capture.n_frames >= 2:
        vel = np.gradient(pos, axis=0) * capture.rate
    else:
        vel = np.zeros_like(pos)
    speed = _window_mean(_rms_over_markers(vel), int(window))
    median = np.nanmedian(pos, axis=0) if np.isnan(pos).any() else np.median(pos, axis=0)
    dist = _window_mean(_rms_over_markers(pos - median[None]), int(window))
    if not np.isfinite(speed).any():
        speed = np.zeros(capture.n_frames)
    calm = np.where(np.isfinite(speed), speed, np.inf)
    threshold = float(np.quantile(speed[np.isfinite(speed)], calm_quantile))
    cand = (calm <= threshold) & np.isfinite(dist)
    if not cand.any():
        cand = np.isfinite(dist)
    frame = int(np.flatnonzero(cand)[np.argmin(dist[cand])])
    report = NeutralReport(
        frame=frame,
        calmest_frame=int(np.argmin(calm)),
        window=int(window),
        speed=speed,
        distance=dist,
        calm_threshold=threshold,
        units=capture.units,
    )
    return frame, report


def set_neutral(capture: Capture, frame="auto", *, how: str | None = None, **choose_options) -> Capture:
    """Set the capture's neutral frame.

    Parameters
    ----------
    capture : Capture
        Input capture (not modified).
    frame : int or "auto"
        Frame index (0-based, ``0 <= frame < F``), or ``"auto"`` for :func:`choose_neutral`.
    how : str, optional
        How the index was chosen, recorded as the history entry's ``"method"`` (e.g. ``"auto"``
        when the caller ran :func:`choose_neutral` itself); default ``"index"`` or ``"auto"``.
    **choose_options
        Options of :func:`choose_neutral` (only with ``"auto"``).

    Returns
    -------
    Capture
        ``neutral_frame`` changed; history ``{"step": "set_neutral", "from": ..., "to": ...,
        "method": how, or "index" / "auto", ...}``. Positions are unchanged: a capture stabilised on the
        old neutral frame stays expressed in that frame's head pose.
    """
    if how is not None and not isinstance(how, str):
        raise OptionError(f"how must be a short string for the history; got {how!r}")
    if isinstance(frame, str):
        if frame != "auto":
            raise OptionError(f"neutral frame must be a frame index or 'auto'; got {frame!r}")
        idx, rep = choose_neutral(capture, **choose_options)
        step = {"step": "set_neutral", "from": capture.neutral_frame, "to": idx, "method": how or "auto",
                "window": rep.window, **{k: v for k, v in choose_options.items() if k != "window"}}
    else:
        if choose_options:
            raise OptionError(f"set_neutral: options {sorted(choose_options)} only apply to frame='auto'")
        if isinstance(frame, (bool, np.bool_)) or not isinstance(frame, (int, np.integer)):
            raise OptionError(f"neutral frame must be a frame index or 'auto'; got {frame!r}")
        idx = int(frame)
        if not 0 <= idx < capture.n_frames:
            raise OptionError(f"neutral frame index {idx} outside 0..{capture.n_frames - 1}")
        step = {"step": "set_neutral", "from": capture.neutral_frame, "to": idx, "method": how or "index"}
    # a new neutral frame starts without a stretch (set_rest_pose finds one around it)
    return capture.replace(step=step, neutral_frame=idx, neutral_window=None)


# -- the rest pose ------------------------------------------------------------------------------

_NEUTRAL_FORMS = "a frame index F, a range START:END (0-based frame indices, END exclusive) or auto"


def parse_neutral(value):
    """The value of ``--neutral``: None, ``"auto"``, a frame index or a ``(start, end)`` range.

    Parameters
    ----------
    value : None, str, int or (int, int)
        ``"auto"``, ``"F"``, ``"START:END"`` (END exclusive, like ``--trim``), an int or a pair.

    Returns
    -------
    None, "auto", int or (int, int)

    Raises
    ------
    OptionError
        ``--neutral VALUE: expected a frame index F, a range START:END (0-based frame indices, END
        exclusive) or auto`` for anything else (negative numbers, empty ranges, text).
    """
    def bad(extra=""):
        return OptionError(f"--neutral {value}: expected {_NEUTRAL_FORMS}{extra}")

    if value is None or value == "auto":
        return value
    if isinstance(value, (bool, np.bool_)):
        raise bad()
    if isinstance(value, (int, np.integer)):
        if value < 0:
            raise bad()
        return int(value)
    if isinstance(value, (tuple, list)):
        parts = list(value)
    elif isinstance(value, str):
        parts = value.strip().split(":")
    else:
        raise bad()
    if len(parts) not in (1, 2):
        raise bad()
    try:
        nums = [int(p) if not isinstance(p, str) else int(p.strip()) for p in parts]
    except (TypeError, ValueError):
        raise bad() from None
    if any(isinstance(p, str) and not p.strip().isdigit() for p in parts) or any(n < 0 for n in nums):
        raise bad()
    if len(nums) == 1:
        return nums[0]
    if nums[0] >= nums[1]:
        raise bad(f"; START must be below END (END exclusive: {nums[0]}:{nums[0] + 1} is frame {nums[0]} alone)")
    return (nums[0], nums[1])


def check_neutral_frames(spec, n_frames: int, *, source: str = "") -> None:
    """Raise OptionError (exit 2) naming the take's range when ``spec`` names frames outside it.

    ``spec`` is :func:`parse_neutral`'s result; frames are 0-based indices after ``--trim``.
    """
    of = f" of {source}" if source else ""
    if spec is None or spec == "auto":
        return
    if isinstance(spec, tuple):
        a, b = spec
        if not 0 <= a < b <= n_frames:
            raise OptionError(f"--neutral {a}:{b}: frames {a}-{b - 1} are outside the take{of}, which has frames "
                              f"0-{n_frames - 1} (expected 0 <= START < END <= {n_frames}; 0-based, END exclusive, "
                              "after --trim)")
        return
    if not 0 <= spec < n_frames:
        raise OptionError(f"--neutral {spec}: frame {spec} is outside the take{of}, which has frames 0-{n_frames - 1} "
                          "(0-based, after --trim)")


@dataclass(frozen=True)
class RestPoseReport:
    """Which frames the rest pose came from and how still the face was there.

    Attributes
    ----------
    how : str
        "first" (the capture's neutral frame, the first unless trimmed or set), "frame" (a frame the
        user named), "auto" (:func:`choose_neutral`) or "range" (frames the user named).
    frame : int
        The neutral frame.
    start, end : int
        Frames ``start <= f < end`` averaged.
    motion_rms, motion_max : float
        RMS and largest deviation of the valid samples from the rest pose over those frames
        (capture units): noise, wander and any motion.
    units : str or None
    to_cm : float
        Capture units to cm (1.0 when the units are unknown: then read as cm).
    noise : float
        Measured white noise per coordinate (capture units).
    threshold : float or None
        Deviation (RMS over markers) up to which a frame counted as still; None for a named range.
    warnings : tuple of str
        Findings for the processor to log (the motion over the stretch above
        :data:`NEUTRAL_MOTION_WARN_CM`).
    """

    how: str
    frame: int
    start: int
    end: int
    motion_rms: float
    motion_max: float
    units: str | None
    to_cm: float
    noise: float
    threshold: float | None
    warnings: tuple = ()

    @property
    def n_frames(self) -> int:
        return self.end - self.start

    def summary(self) -> dict:
        return {"how": self.how, "frame": self.frame, "frames": [self.start, self.end - 1], "count": self.n_frames,
                "motionRmsCm": round(self.motion_rms * self.to_cm, 5),
                "motionMaxCm": round(self.motion_max * self.to_cm, 5),
                "noiseCm": round(self.noise * self.to_cm, 6),
                "thresholdCm": None if self.threshold is None else round(self.threshold * self.to_cm, 5),
                "warnings": list(self.warnings)}

    def text(self, warn_cm: float = NEUTRAL_MOTION_WARN_CM) -> str:
        """One line for the command's output: the frames, why those, and the motion there."""
        frames = f"frame {self.start}" if self.n_frames == 1 else f"frames {self.start}-{self.end - 1}"
        why = {"first": f"the still stretch around the first frame, {self.frame}",
               "frame": f"the still stretch around frame {self.frame}",
               "auto": f"the still stretch around frame {self.frame}, chosen automatically",
               "range": "the frames --neutral names"}.get(self.how, self.how)
        return (f"rest pose: {frames} ({why}); markers move {self.motion_rms * self.to_cm:.3f} cm RMS there, "
                f"{self.motion_max * self.to_cm:.3f} cm at most (warning above {warn_cm:g} cm RMS)")


def set_rest_pose(capture: Capture, neutral=None, *, how: str | None = None,
                  warn_cm: float = NEUTRAL_MOTION_WARN_CM):
    """Average the rest pose over the still stretch around the neutral frame, or named frames.

    Parameters
    ----------
    capture : Capture
        Input capture (not modified); stabilise it first so that head motion is not counted as
        motion (the rest pose is taken in the positions' space either way).
    neutral : None, "auto", int, (int, int) or str
        None: the capture's own neutral window when it has one of 2 frames or more (set before
        resampling or stabilising, which carry it), else the stretch around the capture's neutral
        frame (the first frame unless trimmed or set); ``"auto"``: around :func:`choose_neutral`'s
        frame; F: around frame F; ``(START, END)`` or ``"START:END"``: exactly those frames (END
        exclusive). Parsed by :func:`parse_neutral`, checked by :func:`check_neutral_frames`
        (OptionError, exit 2).
    how : str, optional
        The report's and history's label for how the frame was chosen (e.g. "auto" when the caller
        set the frame with :func:`choose_neutral` before stabilising); default from ``neutral``.
    warn_cm : float
        The report warns when the RMS motion over the frames exceeds this (cm).

    Returns
    -------
    capture : Capture
        ``neutral_frame`` (the seed frame; a range's middle frame) and ``neutral_window`` set;
        history ``{"step": "rest_pose", "how": ..., "frames": [start, end - 1], "motionRmsCm": ...,
        ...}``.
    report : RestPoseReport
    """
    from . import rest as rest_mod

    spec = parse_neutral(neutral)
    check_neutral_frames(spec, capture.n_frames, source=capture.source)
    capture.check_not_all_invalid()
    threshold = None
    noise = rest_mod.white_noise_level(capture.positions)
    window = capture.neutral_window
    if spec is None and window is not None and window[1] - window[0] > 1:
        # a range named before resampling or stabilising, carried by them
        label, frame, (a, b) = "range", capture.neutral_frame, window
    elif isinstance(spec, tuple):
        label, frame, (a, b) = "range", (spec[0] + spec[1] - 1) // 2, spec
    else:
        if spec == "auto":
            label, frame = "auto", choose_neutral(capture)[0]
        elif spec is None:
            label, frame = "first", capture.neutral_frame
        else:
            label, frame = "frame", int(spec)
        stretch = rest_mod.still_stretch(capture.positions, frame, rate=capture.rate)
        a, b, threshold = stretch.start, stretch.end, stretch.threshold
    how = how or label
    out = capture.replace(neutral_frame=frame, neutral_window=(a, b))
    rms, top = neutral_motion(out)
    to_cm = _to_cm(capture.units)
    warnings = []
    if rms * to_cm > warn_cm:
        frames = f"frame {a}" if b - a == 1 else f"frames {a}-{b - 1}"
        where = f"capture {capture.source}: " if capture.source else ""
        warnings.append(f"{where}the face moves over the neutral stretch ({frames}): markers {rms * to_cm:.3f} cm RMS "
                        f"from the rest pose ({top * to_cm:.3f} cm at most), more than {warn_cm:g} cm; name still "
                        "frames with --neutral START:END")
    report = RestPoseReport(how, int(frame), int(a), int(b), rms, top, capture.units, to_cm, noise, threshold,
                            tuple(warnings))
    step = {"step": "rest_pose", "how": how, "frame": int(frame), "frames": [int(a), int(b) - 1],
            "motionRmsCm": report.summary()["motionRmsCm"], "motionMaxCm": report.summary()["motionMaxCm"]}
    return out.replace(step=step), report


def neutral_motion(capture: Capture) -> tuple[float, float]:
    """(RMS, max) distance of the markers from the rest pose over the capture's neutral stretch
    (position units). A capture that is not stabilised has each frame's rigid motion taken out
    first: the head moving is not the face moving (stabilising removes it from the positions;
    here it is only left out of the measure)."""
    from . import rest as rest_mod

    a, b = capture.neutral_frames
    positions = capture.positions[a:b]
    if capture.head_motion is None and b - a > 1:
        positions = rest_mod.without_rigid_motion(positions, capture.neutral)
    return rest_mod.residual_motion(positions, capture.neutral)


def _to_cm(units) -> float:
    """Capture units -> cm; 1.0 for unknown units and image pixels (read as they are)."""
    from ..units import METERS_PER_UNIT, scale_between

    return scale_between(units, "cm") if units in METERS_PER_UNIT else 1.0
