"""Zero-phase noise filtering of marker trajectories.

Each marker's trajectory is filtered per axis along time, forward and backward so there is no
phase lag (a held expression stays where it is in time). Invalid samples split a trajectory into
valid runs that are filtered separately, so a NaN never spreads and no value is invented across a
gap; a run too short for the filter is left as it is (and reported in the history).

``"butterworth"``
    Butterworth low-pass of ``order`` with cutoff ``cutoff_hz``, applied with
    :func:`scipy.signal.sosfiltfilt` (effective order doubles; gain at the cutoff is 1/2, -6 dB).
    Runs not longer than sosfiltfilt's edge padding (``3 * (2 * n_sections + 1)`` samples, 15 for
    order 4) are left unfiltered.
``"savgol"``
    Savitzky–Golay smoothing (local polynomial of degree ``order`` over ``window`` frames, odd),
    symmetric hence zero-phase; runs shorter than ``window`` are left unfiltered.
"""
from __future__ import annotations

import numpy as np
from scipy import signal

from ..errors import OptionError
from ..model.capture import Capture

__all__ = ["filter_noise", "filter_array", "FILTERS"]

FILTERS = ("butterworth", "savgol")
#: default Butterworth cutoff: keeps facial motion (mostly below 5 Hz), removes jitter
DEFAULT_CUTOFF_HZ = 8.0


def _valid_runs(valid_col):
    """Half-open [start, stop) runs of True in a 1-D mask."""
    d = np.diff(np.concatenate([[0], valid_col.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _check_int(name, value, lo):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < lo:
        raise OptionError(f"{name} must be an integer >= {lo}; got {value!r}")
    return int(value)


def _make_filter(method, rate, cutoff_hz, order, window):
    """Return (apply(x (N, K) along axis 0) -> (N, K), min_len)."""
    if method == "butterworth":
        order = _check_int("order", 4 if order is None else order, 1)
        cutoff_hz = DEFAULT_CUTOFF_HZ if cutoff_hz is None else cutoff_hz
        nyq = rate / 2.0
        ok = isinstance(cutoff_hz, (int, float, np.integer, np.floating)) and not isinstance(cutoff_hz, bool)
        if not (ok and np.isfinite(cutoff_hz) and 0 < cutoff_hz < nyq):
            raise OptionError(
                f"cutoff_hz must be between 0 and the Nyquist frequency {nyq:g} Hz (capture rate {rate:g} Hz); got {cutoff_hz!r}"
            )
        sos = signal.butter(order, cutoff_hz, btype="low", fs=rate, output="sos")
        # sosfiltfilt's default padlen; its input must be longer than that
        padlen = 3 * (2 * len(sos) + 1 - min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum()))
        return (lambda x: signal.sosfiltfilt(sos, x, axis=0)), padlen + 1, {"cutoff_hz": float(cutoff_hz), "order": order}
    if method == "savgol":
        window = _check_int("window", 9 if window is None else window, 3)
        if window % 2 == 0:
            raise OptionError(f"window must be odd for the savgol filter; got {window}")
        order = _check_int("order", 3 if order is None else order, 0)
        if order >= window:
            raise OptionError(f"order must be smaller than window for the savgol filter; got order={order}, window={window}")
        if cutoff_hz is not None:
            raise OptionError("cutoff_hz applies to the butterworth filter only; savgol is set by window and order")
        return (lambda x: signal.savgol_filter(x, window, order, axis=0, mode="interp")), window, {"window": window, "order": order}
    raise OptionError(f"method: unknown filter {method!r}; expected one of {', '.join(FILTERS)}")


def filter_array(positions, *, rate, method="butterworth", cutoff_hz=None, order=None, window=None):
    """Zero-phase filter (F, M, 3) trajectories along axis 0, run by valid run.

    Parameters
    ----------
    positions : ndarray, shape (F, M, 3), float
        Trajectories; NaN marks invalid samples (a sample is invalid if any coordinate is NaN).
    rate : float
        Sample rate in Hz.
    method, cutoff_hz, order, window
        See :func:`filter_noise`.

    Returns
    -------
    filtered : ndarray, shape (F, M, 3), float64
        New array; invalid samples stay NaN, runs shorter than the filter needs are copied.
    n_short : int
        Number of valid runs left unfiltered because they were too short.
    params : dict
        The filter parameters used (defaults filled in).
    """
    pos = np.asarray(positions, dtype=np.float64)
    apply, min_len, params = _make_filter(method, float(rate), cutoff_hz, order, window)
    out = pos.copy()
    valid = np.isfinite(pos).all(axis=2)
    out[~valid] = np.nan
    n_short = 0
    # markers with identical validity are filtered together: one call per distinct run
    if valid.all():
        if pos.shape[0] >= min_len:
            out = apply(pos.reshape(pos.shape[0], -1)).reshape(pos.shape)
        else:
            n_short = pos.shape[1]
        return out, n_short, params
    runs = {}
    for m in range(pos.shape[1]):
        for a, b in _valid_runs(valid[:, m]):
            runs.setdefault((int(a), int(b)), []).append(m)
    for (a, b), ms in runs.items():
        if b - a < min_len:
            n_short += len(ms)
            continue
        block = pos[a:b][:, ms].reshape(b - a, -1)
        out[a:b, ms] = apply(block).reshape(b - a, len(ms), 3)
    return out, n_short, params


def filter_noise(capture: Capture, *, method: str = "butterworth", cutoff_hz: float | None = None,
                 order: int | None = None, window: int | None = None) -> Capture:
    """Remove measurement noise with a zero-phase low-pass filter.

    Parameters
    ----------
    capture : Capture
        Input capture (not modified). Its positions are filtered as stored (head-local if the
        capture was stabilised; ``head_motion`` is left untouched).
    method : {"butterworth", "savgol"}
        Filter (see the module docstring).
    cutoff_hz : float or None
        Butterworth cutoff in Hz (0 < cutoff < rate / 2); default 8 Hz, which keeps facial motion
        (mostly below 5 Hz) and removes jitter. Must be left None for ``"savgol"``.
    order : int, optional
        Butterworth order (default 4) or Savitzky–Golay polynomial degree (default 3).
    window : int, optional
        Savitzky–Golay window in frames, odd (default 9). Not used by ``"butterworth"``.

    Returns
    -------
    Capture
        Filtered positions (F, M, 3); invalid samples stay invalid; a history entry
        ``{"step": "filter_noise", "method": ..., <parameters>, "short_runs": n}``.
    """
    out, n_short, params = filter_array(
        capture.positions, rate=capture.rate, method=method, cutoff_hz=cutoff_hz, order=order, window=window
    )
    step = {"step": "filter_noise", "method": method, **params, "short_runs": int(n_short)}
    return capture.replace(step=step, positions=out)
