"""Neutral frame: choose the frame of the neutral (rest) pose, and set it.

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

__all__ = ["choose_neutral", "set_neutral", "NeutralReport"]


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
    return capture.replace(step=step, neutral_frame=idx)
