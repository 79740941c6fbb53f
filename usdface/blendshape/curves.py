"""Curves animators can edit: resampling to a film rate and key reduction within a tolerance.

Weight curves come out of the solver at the capture rate (60 Hz for AnimFace). An animator wants
them at the scene's rate and with few keys:

- :func:`resample_curves` maps frame ``j`` of the new rate to time ``j / new_rate`` and
  interpolates linearly between solved frames (the solved curves are already smooth: the solver
  low-passes them at a few Hz, far below the Nyquist rate of 24 fps). Linear interpolation of
  values in [0, 1] stays in [0, 1]. Head motion is resampled with it (:func:`resample_rigid`:
  translation linearly, rotation by slerp).
- :func:`reduce_keys` keeps, per curve, the fewest keys a greedy left-to-right scan needs so that
  linear interpolation between kept keys stays within ``tolerance`` of every frame (the "sleeve"
  test: the slope from the last key must stay inside the cone of every frame passed since). Keys
  keep their frame's exact value, so reduced curves stay in [0, 1].
- :meth:`KeyedCurves.sample` evaluates reduced curves at any frames; at the union of every
  curve's keys it gives what a USD attribute holding all weights per time sample must store so
  that USD's linear interpolation reproduces every curve exactly.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import OptionError

__all__ = ["resample_curves", "resample_rigid", "interpolate_rigid", "resample_times", "reduce_keys", "reduce_curve", "KeyedCurves"]


def resample_times(n_frames: int, rate: float, new_rate: float) -> np.ndarray:
    """Source frame positions (float, 0-based) of the frames of the new rate covering the take.

    Frame j of the new rate is at time ``j / new_rate``; the take's last frame is at
    ``(n_frames - 1) / rate``, so ``floor((n_frames - 1) * new_rate / rate) + 1`` frames.
    """
    if not (np.isfinite(new_rate) and new_rate > 0):
        raise OptionError(f"--fps {new_rate}: expected a positive frame rate")
    count = int(np.floor((n_frames - 1) * new_rate / rate + 1e-9)) + 1
    return np.arange(count) * (rate / new_rate)


def resample_curves(values, rate: float, new_rate: float) -> np.ndarray:
    """Curves (F, K) at ``rate`` resampled to ``new_rate`` by linear interpolation.

    Returns
    -------
    ndarray, shape (F', K), float64
    """
    v = np.asarray(values, dtype=np.float64)
    pos = resample_times(v.shape[0], rate, new_rate)
    i0 = np.minimum(np.floor(pos).astype(np.int64), v.shape[0] - 1)
    i1 = np.minimum(i0 + 1, v.shape[0] - 1)
    t = (pos - i0)[:, None]
    return (1.0 - t) * v[i0] + t * v[i1]


def interpolate_rigid(times, matrices, new_times) -> np.ndarray:
    """Rigid motions (T, 4, 4) given at increasing ``times``, at ``new_times`` (clamped to the ends):
    translation linearly, rotation by spherical linear interpolation (scipy's Slerp)."""
    from scipy.spatial.transform import Rotation, Slerp

    m = np.asarray(matrices, dtype=np.float64)
    t_in = np.asarray(times, dtype=np.float64)
    t_new = np.clip(np.asarray(new_times, dtype=np.float64), t_in[0], t_in[-1])
    out = np.tile(np.eye(4), (t_new.size, 1, 1))
    if t_in.size == 1:
        out[:] = m[0]
        return out
    out[:, :3, :3] = Slerp(t_in, Rotation.from_matrix(m[:, :3, :3]))(t_new).as_matrix()
    for c in range(3):
        out[:, c, 3] = np.interp(t_new, t_in, m[:, c, 3])
    return out


def resample_rigid(matrices, rate: float, new_rate: float) -> np.ndarray:
    """Rigid motions (F, 4, 4) (column vectors) at ``rate`` resampled to ``new_rate``."""
    m = np.asarray(matrices, dtype=np.float64)
    return interpolate_rigid(np.arange(m.shape[0]), m, resample_times(m.shape[0], rate, new_rate))


def reduce_curve(values, tolerance: float) -> np.ndarray:
    """Frames to keep so linear interpolation between them stays within ``tolerance``.

    Parameters
    ----------
    values : array_like, shape (F,)
    tolerance : float
        Largest allowed ``|interpolated - value|`` at any frame (>= 0; 0 keeps only the frames
        collinear runs do not need).

    Returns
    -------
    ndarray of int64
        Sorted key frames, always including the first and the last.
    """
    y = np.asarray(values, dtype=np.float64)
    n = y.size
    if n <= 2:
        return np.arange(n, dtype=np.int64)
    tol = float(tolerance) + 1e-12  # exact-arithmetic ties (flat runs) must pass
    keys = [0]
    i = 0
    while i < n - 1:
        lo, hi = -np.inf, np.inf
        best = i + 1
        j = i + 1
        while j < n:
            dt = j - i
            slope = (y[j] - y[i]) / dt
            if lo <= slope <= hi:
                best = j
            # frame j constrains every later segment from i
            lo = max(lo, (y[j] - tol - y[i]) / dt)
            hi = min(hi, (y[j] + tol - y[i]) / dt)
            if lo > hi:
                break
            j += 1
        keys.append(best)
        i = best
    return np.asarray(keys, dtype=np.int64)


@dataclass
class KeyedCurves:
    """Per-curve keys (frames and values) of reduced curves.

    Attributes
    ----------
    names : tuple of str
    n_frames : int
    keys : list of ndarray (int64)
        Key frames of each curve.
    values : list of ndarray (float64)
        Key values of each curve.
    tolerance : float
    """

    names: tuple
    n_frames: int
    keys: list
    values: list
    tolerance: float

    def sample(self, frames=None) -> np.ndarray:
        """(len(frames), K) values of the reduced curves (default: every frame)."""
        f = np.arange(self.n_frames) if frames is None else np.asarray(frames, dtype=np.float64)
        return np.stack([np.interp(f, k, v) for k, v in zip(self.keys, self.values)], axis=1)

    def union_keys(self) -> np.ndarray:
        """Sorted frames where any curve has a key (the time samples of a USD weight array)."""
        return np.unique(np.concatenate(self.keys)) if self.keys else np.zeros(0, dtype=np.int64)

    def key_counts(self) -> dict:
        return {n: int(k.size) for n, k in zip(self.names, self.keys)}


def reduce_keys(curves, names, tolerance: float) -> KeyedCurves:
    """Reduce every curve (F, K) with :func:`reduce_curve`."""
    c = np.asarray(curves, dtype=np.float64)
    if not (np.isfinite(tolerance) and tolerance >= 0):
        raise OptionError(f"--key-tolerance {tolerance}: expected a number >= 0")
    keys = [reduce_curve(c[:, k], tolerance) for k in range(c.shape[1])]
    return KeyedCurves(tuple(names), c.shape[0], keys, [c[k, i] for i, k in enumerate(keys)], float(tolerance))
