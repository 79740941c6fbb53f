"""The rest pose of a capture: a robust average over a still stretch, not one frame.

Every displacement usdface measures is ``p_f - rest``; with one frame as the rest pose, that
frame's noise and wander are added to every frame of the take. Here (pure numpy on (F, M, 3)
arrays, NaN where a sample is invalid):

- :func:`robust_rest_pose`: per marker, a Huber M-estimate of its position over the frames
  (iteratively reweighted mean; weight ``min(1, k s / r)`` with r the sample's distance to the
  estimate and s the marker's robust scale), so one outlier sample moves it by at most
  ``k s / N`` and blinks on the lid markers barely count;
- :func:`white_noise_level`: the measurement noise per coordinate from second differences
  (``x[f+1] - 2 x[f] + x[f-1]`` of white noise has variance ``6 sigma^2``; smooth motion at capture
  rates contributes little), robust (median absolute value);
- :func:`still_stretch`: the stretch of frames around a seed frame where the face is still,
  grown until a frame's deviation from the stretch's rest pose leaves the spread the stretch's own
  frames show (noise plus the wander of a face at rest, both measured on the take), so no
  constant in capture units decides it;
- :func:`residual_motion`: how much the markers still move over the stretch (RMS and largest
  deviation from the rest pose).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# the estimator lives with the capture model, which computes its rest pose with it
from ..model.rest import HUBER_K, robust_rest_pose

__all__ = ["robust_rest_pose", "frame_deviation", "white_noise_level", "face_size", "still_stretch",
           "residual_motion", "without_rigid_motion", "StillStretch", "HUBER_K", "STILL_SPREADS", "CORE_SECONDS",
           "FACE_FLOOR"]

#: a frame is still while its deviation from the rest pose stays within this many robust spreads
#: (1.4826 MAD) of the stretch's own deviations above their median: the usual 3-sigma outlier rule
STILL_SPREADS = 3.0
#: the stretch starts from the seed frame +- this many seconds (at least one frame each side)
CORE_SECONDS = 0.05
#: the spread never counts as smaller than this fraction of the face size (noise-free data)
FACE_FLOOR = 1e-3


def frame_deviation(positions, rest) -> np.ndarray:
    """(F,) RMS over the valid markers of ``|p_f - rest|`` (NaN for a frame with none)."""
    d2 = ((np.asarray(positions, dtype=np.float64) - np.asarray(rest)[None]) ** 2).sum(axis=2)
    ok = np.isfinite(d2)
    n = ok.sum(axis=1)
    return np.sqrt(np.divide(np.where(ok, d2, 0.0).sum(axis=1), n, out=np.full(n.size, np.nan), where=n > 0))


def white_noise_level(positions) -> float:
    """Per-coordinate standard deviation of white measurement noise, from second differences.

    ``sigma = 1.4826 median|x[f+1] - 2 x[f] + x[f-1]| / sqrt(6)`` over every valid triple of
    every marker and coordinate (the second difference of white noise has variance ``6 sigma^2``).
    Smooth motion adds ``a / rate^2`` (a few hundredths of a millimetre for a face at 60 Hz), so
    the estimate is the noise where it dominates and near 0 for filtered or noise-free data.
    0.0 for fewer than 3 frames.
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.shape[0] < 3:
        return 0.0
    d2 = p[2:] - 2.0 * p[1:-1] + p[:-2]
    vals = np.abs(d2[np.isfinite(d2)])
    return float(1.4826 * np.median(vals) / np.sqrt(6.0)) if vals.size else 0.0


def face_size(points) -> float:
    """RMS distance of the valid markers from their centroid (units of ``points``), 0.0 if none."""
    p = np.asarray(points, dtype=np.float64)
    p = p[np.isfinite(p).all(axis=1)]
    if not len(p):
        return 0.0
    return float(np.sqrt(((p - p.mean(axis=0)) ** 2).sum(axis=1).mean()))


def without_rigid_motion(positions, rest) -> np.ndarray:
    """``positions`` (F, M, 3) with each frame's rigid motion relative to ``rest`` (M, 3) taken
    out (least-squares fit over the markers valid in both; a frame with fewer than 3 is left as it
    is): what remains is the face's own motion."""
    from .rigid import fit_rigid_batch

    p = np.asarray(positions, dtype=np.float64)
    rot, _, t = fit_rigid_batch(np.asarray(rest, dtype=np.float64), p)
    fitted = np.isfinite(rot).all(axis=(1, 2))
    local = np.einsum("fji,fmj->fmi", np.where(fitted[:, None, None], rot, np.eye(3)),
                      p - np.where(fitted[:, None], t, 0.0)[:, None, :])
    return local


def residual_motion(positions, rest) -> tuple[float, float]:
    """(RMS, max) over the valid samples of ``|p_f - rest|`` (units of the positions)."""
    d = np.linalg.norm(np.asarray(positions, dtype=np.float64) - np.asarray(rest)[None], axis=2)
    d = d[np.isfinite(d)]
    return (float(np.sqrt((d ** 2).mean())), float(d.max())) if d.size else (0.0, 0.0)


@dataclass(frozen=True)
class StillStretch:
    """A still stretch found by :func:`still_stretch` (frame indices half-open: ``start <= f < end``).

    Attributes
    ----------
    start, end : int
    threshold : float
        Deviation (RMS over markers, position units) up to which a frame counted as still.
    level, spread : float
        Median and robust spread (1.4826 MAD) of the stretch's frame deviations.
    noise : float
        White measurement noise per coordinate (:func:`white_noise_level`).
    face_size : float
    rounds : int
        Grow-and-re-estimate rounds until the stretch stopped growing.
    """

    start: int
    end: int
    threshold: float
    level: float
    spread: float
    noise: float
    face_size: float
    rounds: int


def _extend(still: np.ndarray, a: int, b: int) -> tuple[int, int]:
    """``[a, b)`` extended on either side over the adjacent True entries of ``still``."""
    while a > 0 and still[a - 1]:
        a -= 1
    while b < still.size and still[b]:
        b += 1
    return a, b


def _median_of_3(x: np.ndarray) -> np.ndarray:
    """Running median over 3 samples, the ends repeated (scipy.ndimage.median_filter(x, 3,
    mode="nearest") without importing scipy.ndimage: ~30-60 ms of every command's start)."""
    padded = np.concatenate([x[:1], x, x[-1:]])
    return np.median(np.stack([padded[:-2], padded[1:-1], padded[2:]]), axis=0)


def still_stretch(positions, seed: int, *, rate: float) -> StillStretch:
    """The stretch of still frames around ``seed`` (see the module docstring).

    Starting from ``seed +- CORE_SECONDS``, repeat until the stretch stops growing: rest pose =
    :func:`robust_rest_pose` over the stretch; deviation of every frame from it
    (:func:`frame_deviation`, median of 3 frames so one glitching frame does not end the stretch);
    threshold = the stretch's median deviation (scaled by ``sqrt((N + 1) / (N - 1))``: a frame
    outside the N frames the rest pose was averaged over deviates that much more under white noise)
    + ``STILL_SPREADS`` x the robust spread of its deviations, the spread floored at the one white
    noise alone gives (measured) and at ``FACE_FLOOR`` of the face size; the stretch then takes in
    the adjacent frames below the threshold. It only grows, so it ends.

    Parameters
    ----------
    positions : array_like, shape (F, M, 3)
        Positions as the capture stores them (head-local when stabilised), NaN where invalid.
    seed : int
        Frame index the stretch is grown around (always in it).
    rate : float
        Capture rate (Hz): sets the starting core.

    Returns
    -------
    StillStretch
    """
    p = np.asarray(positions, dtype=np.float64)
    f_n, m_n = p.shape[:2]
    seed = int(seed)
    half = max(1, int(round(CORE_SECONDS * rate)))
    a, b = max(0, seed - half), min(f_n, seed + half + 1)
    noise = white_noise_level(p)
    size = face_size(robust_rest_pose(p[a:b])[0])
    # the deviation of a still frame is about sqrt(3) noise; over M markers its spread is
    # sqrt(3) noise / sqrt(6 M) (chi-square with 3M degrees of freedom)
    noise_spread = np.sqrt(3.0) * noise / np.sqrt(6.0 * max(m_n, 1))
    floor = max(noise_spread, FACE_FLOOR * size)
    threshold = level = spread = 0.0
    rounds = 0
    for rounds in range(1, f_n + 1):
        rest, _ = robust_rest_pose(p[a:b])
        dev = frame_deviation(p, rest)
        dev = np.where(np.isfinite(dev), dev, np.inf)  # a frame without markers: unknown, not still
        smooth = _median_of_3(dev) if f_n >= 3 else dev
        inside = dev[a:b][np.isfinite(dev[a:b])]
        n = inside.size
        level = float(np.median(inside)) if n else 0.0
        spread = float(1.4826 * np.median(np.abs(inside - level))) if n else 0.0
        out_of_sample = np.sqrt((n + 1) / (n - 1)) if n > 1 else 1.0
        threshold = level * out_of_sample + STILL_SPREADS * max(spread, floor)
        na, nb = _extend(smooth <= threshold, a, b)
        if (na, nb) == (a, b):
            break
        a, b = na, nb
    return StillStretch(int(a), int(b), float(threshold), level, spread, noise, size, rounds)
