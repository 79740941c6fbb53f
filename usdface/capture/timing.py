"""Timing: trim a capture to a frame range, move its time codes, resample it to another rate.

Frames and time codes
---------------------
A capture's frames are indexed ``0 .. F-1``; frame ``f`` has time code ``start_frame + f`` at
``rate`` codes per second (``Capture.times``). :func:`trim` takes frame *indices* (not time
codes), half-open like a Python slice: ``trim(c, start=10, end=20)`` keeps indices 10..19, whose
time codes are unchanged (the result's ``start_frame`` is ``c.start_frame + 10``).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation, RotationSpline, Slerp

from ..errors import OptionError
from ..findings import refuse
from ..io.limits import resample_finding
from ..model.capture import Capture
from .rigid import to_matrix

__all__ = ["trim", "offset", "resample", "RESAMPLE_METHODS"]

RESAMPLE_METHODS = ("cubic", "linear")


def _is_int(v):
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def trim(capture: Capture, *, start: int | None = None, end: int | None = None) -> Capture:
    """Keep the frames with indices ``start <= f < end``.

    Parameters
    ----------
    capture : Capture
        Input capture (not modified).
    start : int, optional
        First frame index kept (inclusive), ``0 <= start < F``; default 0.
    end : int, optional
        Frame index after the last one kept (exclusive), ``start < end <= F``; default F.

    Returns
    -------
    Capture
        ``end - start`` frames; time codes preserved (``start_frame`` grows by ``start``);
        ``neutral_frame``, ``neutral_window`` (clipped to the kept frames) and ``head_motion``
        follow; history ``{"step": "trim", ...}``.

    Raises
    ------
    OptionError
        Indices out of range or empty range, or the neutral frame would be trimmed away (set
        another neutral frame first with :func:`usdface.capture.neutral.set_neutral`).
    """
    n = capture.n_frames
    a = 0 if start is None else start
    b = n if end is None else end
    if not _is_int(a) or not _is_int(b):
        raise OptionError(f"trim: start and end must be integer frame indices; got start={start!r}, end={end!r}")
    a, b = int(a), int(b)
    if not (0 <= a < b <= n):
        raise OptionError(
            f"trim: need 0 <= start < end <= {n} (frame indices, end exclusive); got start={a}, end={b}"
        )
    nf = capture.neutral_frame
    if not a <= nf < b:
        raise OptionError(
            f"trim: the neutral frame (index {nf}, time code {capture.start_frame + nf}) lies outside the kept "
            f"range [{a}, {b}); set a neutral frame inside it first (usdface.capture.neutral.set_neutral)"
        )
    hm = None if capture.head_motion is None else capture.head_motion[a:b].copy()
    step = {"step": "trim", "start": a, "end": b, "start_frame": capture.start_frame + a}
    window = None
    if capture.neutral_window is not None:  # the rest pose keeps the stretch's frames that remain
        window = (max(capture.neutral_window[0], a) - a, min(capture.neutral_window[1], b) - a)
    return capture.replace(
        step=step,
        positions=capture.positions[a:b].copy(),
        head_motion=hm,
        start_frame=capture.start_frame + a,
        neutral_frame=nf - a,
        neutral_window=window,
    )


def offset(capture: Capture, *, start_frame: int) -> Capture:
    """Move the capture in time: frame 0 gets time code ``start_frame``.

    Parameters
    ----------
    capture : Capture
    start_frame : int
        New time code of the first frame (may be negative).

    Returns
    -------
    Capture
        Same samples, ``start_frame`` changed; history ``{"step": "offset", "from": ..., "to": ...}``.
    """
    if not _is_int(start_frame):
        raise OptionError(f"offset: start_frame must be an integer time code; got {start_frame!r}")
    step = {"step": "offset", "from": int(capture.start_frame), "to": int(start_frame)}
    return capture.replace(step=step, start_frame=int(start_frame))


def _grid_range(capture, rate):
    """First and last integer time code of the new rate inside the old time span."""
    r0 = capture.rate
    t0 = capture.start_frame / r0
    t1 = (capture.start_frame + capture.n_frames - 1) / r0
    eps = 1e-9
    return math.ceil(t0 * rate - eps), math.floor(t1 * rate + eps)


#: bytes per resampled frame and marker at the peak of :func:`resample` (float64 positions: the
#: result, the interpolated block and the spline's evaluation) and per frame (grid, masks, head motion)
_RESAMPLE_BYTES_PER_SAMPLE = 3 * 3 * 8
_RESAMPLE_BYTES_PER_FRAME = 40 + 4 * 16 * 8


def resample_memory(capture: Capture, rate: float) -> tuple[int, int]:
    """(frames, bytes): the frame count of ``capture`` resampled to ``rate`` and the memory
    :func:`resample` needs at its peak (an estimate), computed without allocating anything."""
    k0, k1 = _grid_range(capture, float(rate))
    frames = max(0, k1 - k0 + 1)
    return frames, frames * (capture.n_markers * _RESAMPLE_BYTES_PER_SAMPLE + _RESAMPLE_BYTES_PER_FRAME)


def _new_grid(capture, rate):
    """New integer time codes covering the old time span, and their positions in old frame units."""
    r0 = capture.rate
    k0, k1 = _grid_range(capture, rate)
    codes = np.arange(k0, k1 + 1)
    u = codes * (r0 / rate) - capture.start_frame  # fractional old frame index
    u = np.where(np.abs(u - np.round(u)) < 1e-9, np.round(u), u)
    return k0, codes, np.clip(u, 0.0, capture.n_frames - 1)


def _resample_runs(pos, u, method):
    """Interpolate (F, M, 3) at fractional frames u, within valid runs only."""
    n_frames, n_markers, _ = pos.shape
    valid = np.isfinite(pos).all(axis=2)
    out = np.full((u.size, n_markers, 3), np.nan)
    runs = {}
    for m in range(n_markers):
        d = np.diff(np.concatenate([[0], valid[:, m].astype(np.int8), [0]]))
        for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
            runs.setdefault((int(a), int(b)), []).append(m)
    for (a, b), ms in runs.items():
        sel = (u >= a) & (u <= b - 1)
        if not sel.any():
            continue
        block = pos[a:b][:, ms].reshape(b - a, -1)
        if b - a == 1:
            vals = np.repeat(block, sel.sum(), axis=0)
        elif method == "cubic" and b - a >= 3:
            vals = CubicSpline(np.arange(a, b), block, axis=0)(u[sel])
        else:
            x = np.arange(a, b)
            vals = np.stack([np.interp(u[sel], x, block[:, j]) for j in range(block.shape[1])], axis=1)
        out[np.flatnonzero(sel)[:, None], np.asarray(ms)[None, :]] = vals.reshape(-1, len(ms), 3)
    return out


def _resample_motion(head, u, method):
    """Interpolate (F, 4, 4) rigid transforms at fractional frames u (slerp / rotation spline)."""
    n = head.shape[0]
    if n == 1:
        return np.repeat(head, u.size, axis=0)
    x = np.arange(n, dtype=np.float64)
    rots = Rotation.from_matrix(head[:, :3, :3])
    trans = head[:, :3, 3]
    if method == "cubic" and n >= 3:
        r = RotationSpline(x, rots)(u).as_matrix()
        t = CubicSpline(x, trans, axis=0)(u)
    else:
        r = Slerp(x, rots)(u).as_matrix()
        t = np.stack([np.interp(u, x, trans[:, j]) for j in range(3)], axis=1)
    return to_matrix(r, 1.0, t)


def resample(capture: Capture, *, rate: float, method: str = "cubic", allow=frozenset()) -> Capture:
    """Resample a capture to another rate over the same time span.

    Parameters
    ----------
    capture : Capture
        Input capture (not modified).
    rate : float
        New rate in Hz (> 0).
    method : {"cubic", "linear"}
        Interpolation of positions within each valid run (cubic spline, not-a-knot; runs of 2
        samples are linear) and of ``head_motion`` (rotation spline / slerp for rotations, cubic /
        linear for translations).
    allow : set of str
        Plausibility codes accepted (``"resample"``: a rate outside 1-10000 Hz, a factor beyond
        100x either way or fewer than 2 frames left, see :mod:`usdface.io.limits`).

    Returns
    -------
    Capture
        New frames at integer time codes ``k`` of the new rate with ``k / rate`` inside the old
        span ``[start_frame, start_frame + F - 1] / old rate``; ``start_frame`` is the first such
        ``k``. A new sample is valid only if it lies within a run of valid old samples (between
        two valid neighbours, or exactly on a valid sample): invalid spans stay invalid and are
        never bridged. The neutral frame becomes the new frame nearest in time to the old one; a
        neutral window, the new frames within its time span.
        History ``{"step": "resample", "from_rate": ..., "rate": ..., "method": ...}``.
    """
    if method not in RESAMPLE_METHODS:
        raise OptionError(f"resample: unknown method {method!r}; expected one of {', '.join(RESAMPLE_METHODS)}")
    ok = isinstance(rate, (int, float, np.integer, np.floating)) and not isinstance(rate, bool)
    if not (ok and np.isfinite(rate) and rate > 0):
        raise OptionError(f"resample: rate must be a positive number of Hz; got {rate!r}")
    rate = float(rate)
    frames, need = resample_memory(capture, rate)
    where = f"capture {capture.source}" if capture.source else "capture"
    refuse([resample_finding(frames=capture.n_frames, rate=capture.rate, new_frames=frames, new_rate=rate,
                             what=where)], allow=allow)
    if frames > capture.n_frames:  # refuse an impossible rate with its size, before allocating
        from ..memory import check_memory

        check_memory(need, what=f"resample: {capture.n_frames} frames at {capture.rate:g} Hz to {rate:g} Hz make "
                                f"{frames:,} frames x {capture.n_markers} markers, which",
                     hint=f"choose a rate near the capture's {capture.rate:g} Hz (optical capture runs at "
                          "60-2000 Hz, high-speed systems to about 10 kHz, video at 24-240 fps)")
    k0, codes, u = _new_grid(capture, rate)
    if codes.size == 0:
        raise OptionError(
            f"resample: no frame of a {rate:g} Hz grid falls inside the capture's span "
            f"({capture.n_frames} frame(s) at {capture.rate:g} Hz from time code {capture.start_frame})"
        )
    pos = _resample_runs(capture.positions, u, method)
    head = None if capture.head_motion is None else _resample_motion(capture.head_motion, u, method)
    neutral_u = float(capture.neutral_frame)
    neutral = int(np.argmin(np.abs(u - neutral_u)))
    window = None
    if capture.neutral_window is not None:  # the new frames inside the stretch's time span
        lo, hi = capture.neutral_window
        inside = np.flatnonzero((u >= lo - 1e-9) & (u <= hi - 1 + 1e-9))
        first = int(inside[0]) if inside.size else neutral
        last = int(inside[-1]) if inside.size else neutral
        window = (min(first, neutral), max(last, neutral) + 1)
    step = {
        "step": "resample",
        "from_rate": float(capture.rate),
        "rate": rate,
        "method": method,
        "from_start_frame": int(capture.start_frame),
        "start_frame": int(k0),
        "frames": int(codes.size),
    }
    return capture.replace(step=step, positions=pos, head_motion=head, rate=rate, start_frame=int(k0),
                           neutral_frame=neutral, neutral_window=window)
