"""Marker-swap detection: two markers exchanging identity (labelling errors of the tracker).

At a swap, both markers jump, each to where the other was expected. Per marker and frame, the
position expected from the two previous frames (constant velocity; constant position when only
one previous frame is valid) is compared with the measured one. A frame where two markers both
jump by more than ``min_jump`` and the exchanged assignment explains the measurements much better
(``swapped error < ratio * kept error``) is a swap event. Detection walks forward through the
take: after an event the labels are exchanged from that frame on (as :func:`fix_swaps` would) so
that the corrected track is checked for the next event; a swap that is later undone is therefore
reported as two events on the same pair.

A swap where one of the two markers is invalid at the swap frame or the frame before is not
detected (there is nothing to compare).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import OptionError
from ..model.capture import Capture

__all__ = ["SwapEvent", "detect_swaps", "fix_swaps", "default_min_jump"]

MAX_EVENTS = 10000


@dataclass(frozen=True)
class SwapEvent:
    """Markers ``marker_a`` and ``marker_b`` exchange identities from frame index ``frame`` on.

    ``jump`` is the smaller of the two markers' jumps at that frame (capture units) and
    ``swapped_error`` the summed distance to the expected positions with the labels exchanged.
    """

    frame: int
    marker_a: str
    marker_b: str
    jump: float = float("nan")
    swapped_error: float = float("nan")

    def summary(self) -> dict:
        """JSON-serialisable form."""
        return {"frame": int(self.frame), "marker_a": self.marker_a, "marker_b": self.marker_b,
                "jump": float(self.jump), "swapped_error": float(self.swapped_error)}


def default_min_jump(capture: Capture) -> float:
    """Half the smallest nearest-neighbour distance between markers' median positions.

    A swap moves each marker by the distance between the two, so every swap jumps by at least
    twice this; ordinary motion between two frames is far smaller (AnimFace, 60 Hz: expected-
    position errors under 0.26 cm; closest markers 1.5 cm apart).
    """
    med = np.nanmedian(capture.positions, axis=0) if np.isnan(capture.positions).any() else np.median(capture.positions, axis=0)
    ok = np.isfinite(med).all(axis=1)
    med = med[ok]
    if med.shape[0] < 2:
        return float("inf")
    d = np.linalg.norm(med[:, None] - med[None], axis=2)
    np.fill_diagonal(d, np.inf)
    return 0.5 * float(d.min())


def _expected(pos):
    """(F, M, 3) expected positions from the two previous frames; NaN where none is valid."""
    exp = np.full_like(pos, np.nan)
    if pos.shape[0] >= 2:
        exp[1:] = pos[:-1]  # constant position
    if pos.shape[0] >= 3:
        cv = 2 * pos[1:-1] - pos[:-2]  # constant velocity
        ok = np.isfinite(cv).all(axis=2)
        exp[2:][ok] = cv[ok]
    return exp


def _first_event(pos, start, min_jump, ratio):
    """Earliest swap frame >= start on the current tracks: (frame, [(a, b, jump, swapped_err)]) or None."""
    lo = max(start - 2, 0)
    exp = _expected(pos[lo:])
    err = np.linalg.norm(pos[lo:] - exp, axis=2)  # NaN where either is invalid
    jump = np.where(np.isfinite(err), err, 0.0) > min_jump
    jump[: start - lo] = False
    frames = np.flatnonzero(jump.sum(axis=1) >= 2)
    for fr in frames:
        ms = np.flatnonzero(jump[fr])
        p = pos[lo + fr, ms]
        e = exp[fr, ms]
        cross = np.linalg.norm(p[:, None, :] - e[None, :, :], axis=2)  # |p_i - exp_j|
        kept = err[fr, ms]
        pairs = []
        for i in range(len(ms)):
            for j in range(i + 1, len(ms)):
                sw = cross[i, j] + cross[j, i]
                if sw < ratio * (kept[i] + kept[j]):
                    pairs.append((sw, i, j))
        if not pairs:
            continue
        pairs.sort()
        used, events = set(), []
        for sw, i, j in pairs:
            if i in used or j in used:
                continue
            used.update((i, j))
            events.append((int(ms[i]), int(ms[j]), float(min(kept[i], kept[j])), float(sw)))
        return lo + int(fr), events
    return None


def detect_swaps(capture: Capture, *, min_jump: float | None = None, ratio: float = 0.3) -> list:
    """Find frames where two markers exchange identities.

    Parameters
    ----------
    capture : Capture
        Input capture (not modified).
    min_jump : float, optional
        Smallest jump (distance from the expected position, capture units) of both markers at a
        swap. Default :func:`default_min_jump` (half the closest marker spacing).
    ratio : float
        A pair is swapped when the exchanged labels' error is below ``ratio`` times the kept
        labels' error (0 < ratio < 1).

    Returns
    -------
    list of SwapEvent
        In frame order. Apply them in that order (cumulatively) with :func:`fix_swaps`.
    """
    if min_jump is None:
        min_jump = default_min_jump(capture)
    elif not (isinstance(min_jump, (int, float, np.integer, np.floating)) and np.isfinite(min_jump) and min_jump > 0):
        raise OptionError(f"min_jump must be a positive distance in capture units; got {min_jump!r}")
    if not (isinstance(ratio, (int, float, np.integer, np.floating)) and 0 < ratio < 1):
        raise OptionError(f"ratio must be between 0 and 1; got {ratio!r}")
    pos = capture.positions.copy()
    events, start = [], 1
    while len(events) < MAX_EVENTS:
        found = _first_event(pos, start, float(min_jump), float(ratio))
        if found is None:
            break
        fr, pairs = found
        for a, b, jump, sw in pairs:
            events.append(SwapEvent(fr, capture.names[a], capture.names[b], jump, sw))
            pos[fr:, [a, b]] = pos[fr:, [b, a]]
        start = fr + 1
    return events


def fix_swaps(capture: Capture, events=None, **detect_options):
    """Undo marker swaps by exchanging the two markers' samples from each event's frame on.

    Parameters
    ----------
    capture : Capture
        Input capture (not modified).
    events : list of SwapEvent, optional
        Events to undo, applied in the given order; default: :func:`detect_swaps` with
        ``detect_options``.

    Returns
    -------
    capture : Capture
        History ``{"step": "fix_swaps", "events": [[frame, a, b], ...]}``.
    events : list of SwapEvent
    """
    if events is None:
        events = detect_swaps(capture, **detect_options)
    elif detect_options:
        raise OptionError(f"fix_swaps: detection options {sorted(detect_options)} given with explicit events")
    pos = capture.positions.copy()
    for ev in events:
        if not 0 <= ev.frame < capture.n_frames:
            raise OptionError(f"swap event frame {ev.frame} outside 0..{capture.n_frames - 1}")
        a, b = capture.index(ev.marker_a), capture.index(ev.marker_b)
        pos[ev.frame:, [a, b]] = pos[ev.frame:, [b, a]]
    step = {"step": "fix_swaps", "events": [[int(e.frame), e.marker_a, e.marker_b] for e in events]}
    return capture.replace(step=step, positions=pos), list(events)
