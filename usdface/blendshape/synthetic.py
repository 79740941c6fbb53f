"""Synthetic takes with exact truth: smooth random weight curves and the markers they move.

Used by the tests and benchmarks of the curve solver. Curves are a set of *events*: one shape
rising with a raised-cosine ramp, holding, and falling back (C1-smooth), at a random amplitude; an
event is only placed where it keeps at most ``max_active`` shapes active at every frame and does
not overlap another event of the same shape. Markers are the bound points moved by the shapes
(``basis``), plus Gaussian noise, with a fraction of samples made invalid (NaN).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SyntheticTake", "random_weight_curves", "layered_weight_curves", "synthetic_take", "observable_shapes"]


@dataclass(frozen=True)
class SyntheticTake:
    """Truth and measurements of a synthetic take.

    Attributes
    ----------
    weights : ndarray (F, K)
        True weights in [0, 1].
    displacements : ndarray (F, M, 3)
        Noisy marker displacements, NaN where missing.
    clean : ndarray (F, M, 3)
        Exact marker displacements.
    valid : ndarray (F, M) bool
    rate : float
    """

    weights: np.ndarray
    displacements: np.ndarray
    clean: np.ndarray
    valid: np.ndarray
    rate: float


def observable_shapes(names) -> list[int]:
    """Indices of the shapes 41 face markers can observe on an ARKit rig: all but ``tongueOut``
    and the ``eyeLook*`` shapes (the tongue and the eyeballs carry no markers)."""
    return [i for i, n in enumerate(names) if n != "tongueOut" and not n.startswith("eyeLook")]


def random_weight_curves(n_frames: int, n_shapes: int, *, shapes=None, max_active: int = 6, rate: float = 60.0,
                         rise=(0.15, 0.6), hold=(0.0, 1.5), amplitude=(0.2, 1.0), density: float = 3.0,
                         seed: int = 0) -> np.ndarray:
    """Smooth random weight curves (see the module docstring).

    Parameters
    ----------
    n_frames, n_shapes : int
    shapes : sequence of int, optional
        The shapes that may be active (default all).
    max_active : int
        At most this many shapes with a non-zero weight at any frame.
    rate : float
        Frames per second (durations below are in seconds).
    rise, hold, amplitude : (low, high)
        Uniform ranges of the ramp duration (each of rise and fall), the hold and the peak weight.
    density : float
        Events tried per second (placed only where they fit).
    seed : int

    Returns
    -------
    ndarray, shape (n_frames, n_shapes), float64 in [0, 1]
    """
    rng = np.random.default_rng(seed)
    pool = np.arange(n_shapes) if shapes is None else np.asarray(list(shapes), dtype=np.int64)
    w = np.zeros((n_frames, n_shapes))
    count = np.zeros(n_frames, dtype=np.int64)
    busy = np.zeros((n_frames, n_shapes), dtype=bool)
    tries = int(max(1, density * 4 * n_frames / rate))
    for _ in range(tries):
        k = int(pool[rng.integers(pool.size)])
        up = max(2, int(rng.uniform(*rise) * rate))
        flat = int(rng.uniform(*hold) * rate)
        down = max(2, int(rng.uniform(*rise) * rate))
        start = int(rng.uniform(-up, n_frames))
        t = np.arange(start, start + up + flat + down)
        inside = (t >= 0) & (t < n_frames)
        if not inside.any():
            continue
        span = t[inside]
        if (count[span] >= max_active).any() or busy[span, k].any():
            continue
        c = np.ones(t.size)
        c[:up] = 0.5 - 0.5 * np.cos(np.pi * np.arange(up) / up)
        c[up + flat:] = 0.5 + 0.5 * np.cos(np.pi * np.arange(down) / down)
        w[span, k] = rng.uniform(*amplitude) * c[inside]
        # a frame where the ramp is exactly 0 is not active
        active = w[span, k] > 0
        count[span[active]] += 1
        busy[span, k] = True
    return w


def _ramp_event(up: int, flat: int, down: int) -> np.ndarray:
    """Raised-cosine rise over ``up`` frames, hold ``flat``, fall over ``down`` (0 at the first
    frame, > 0 at every later frame of the event)."""
    c = np.ones(up + flat + down)
    c[:up] = 0.5 - 0.5 * np.cos(np.pi * np.arange(up) / up)
    c[up + flat:] = 0.5 + 0.5 * np.cos(np.pi * (np.arange(down) + 1) / (down + 1))
    return c


def layered_weight_curves(n_frames: int, n_shapes: int, *, shapes=None, layers: int = 3, still: int = 5,
                          rate: float = 60.0, rise=(0.15, 0.6), hold=(0.0, 1.5), amplitude=(0.2, 1.0),
                          seed: int = 0) -> np.ndarray:
    """Smooth weight curves with at least ``layers`` shapes active at every frame after ``still``.

    Each of ``layers`` layers is a chain of events (raised-cosine rise, hold, fall, as
    :func:`random_weight_curves`); the next event of a layer starts rising when the previous one
    starts falling (a cross-fade), so a layer always has a shape with a non-zero weight. An event
    takes a shape no other layer uses during its span. Frames ``0 .. still - 1`` are all zero (the
    still face a take starts with); the first events start rising at frame ``still - 1`` (weight 0
    there, > 0 from frame ``still``). At most ``2 * layers`` shapes are active at once.

    Parameters
    ----------
    n_frames, n_shapes : int
    shapes : sequence of int, optional
        The shapes that may be active (default all); needs more than ``2 * layers``.
    layers : int
        Shapes active at every frame from ``still`` on (>= 1).
    still : int
        Leading frames with every weight 0 (>= 1).
    rate : float
        Frames per second (durations below are in seconds).
    rise, hold, amplitude : (low, high)
        Uniform ranges of the ramp durations, the hold and the peak weight.
    seed : int

    Returns
    -------
    ndarray, shape (n_frames, n_shapes), float64 in [0, 1]
    """
    rng = np.random.default_rng(seed)
    pool = np.arange(n_shapes) if shapes is None else np.asarray(list(shapes), dtype=np.int64)
    if layers < 1 or still < 1:
        raise ValueError(f"layers and still must be >= 1; got {layers}, {still}")
    if pool.size <= 2 * layers:
        raise ValueError(f"{pool.size} shapes cannot keep {layers} layers of cross-fading events apart")
    w = np.zeros((n_frames, n_shapes))
    busy = np.zeros((n_frames, n_shapes), dtype=bool)
    for _ in range(layers):
        start = still - 1
        falling = 0  # frames the layer's previous event still falls for
        while start < n_frames:
            up = max(2, int(rng.uniform(*rise) * rate))
            # hold at least until the previous event has faded: two events of a layer at most
            flat = max(1, int(rng.uniform(*hold) * rate), falling - up + 1)
            down = max(2, int(rng.uniform(*rise) * rate))
            stop = min(start + up + flat + down, n_frames)
            free = [int(k) for k in pool if not busy[start:stop, k].any()]
            k = free[rng.integers(len(free))]
            curve = rng.uniform(*amplitude) * _ramp_event(up, flat, down)[:stop - start]
            w[start:stop, k] = curve
            busy[start:stop, k] = True
            start += up + flat  # the next event rises while this one falls
            falling = down
    return w


def synthetic_take(basis, weights, *, noise: float = 0.05, missing: float = 0.05, rate: float = 60.0,
                   seed: int = 0) -> SyntheticTake:
    """Marker displacements of the weights through ``basis`` (M, K, 3), with noise and gaps.

    Parameters
    ----------
    noise : float
        Standard deviation of the Gaussian noise on each coordinate (basis units; 0.05 cm = 0.5 mm).
    missing : float
        Fraction of (frame, marker) samples made invalid (NaN), uniformly at random.
    """
    rng = np.random.default_rng(seed)
    b = np.asarray(basis, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    clean = np.einsum("fk,mkd->fmd", w, b)
    noisy = clean + rng.normal(0.0, noise, clean.shape)
    valid = rng.random(clean.shape[:2]) >= missing
    noisy[~valid] = np.nan
    return SyntheticTake(w, noisy, clean, valid, float(rate))
