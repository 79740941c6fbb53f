"""Which vertices act as zero-displacement RBF centres (pinned and rigid regions)."""
from __future__ import annotations

import numpy as np

from .model import Region


def sample_loop(points: np.ndarray, loop: np.ndarray, spacing: float) -> np.ndarray:
    """Vertices of a closed loop spaced about ``spacing`` apart along it.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
    loop : ndarray, shape (L,), int
        Ordered closed loop of vertex indices.
    spacing : float
        Target arc length between chosen vertices (mesh units).

    Returns
    -------
    ndarray, shape (K,), int64, K >= 3 (or L when the loop is shorter)
    """
    loop = np.asarray(loop, dtype=np.int64)
    if loop.size <= 3:
        return loop.copy()
    p = points[loop]
    seg = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)[:-1]])
    length = float(seg.sum())
    k = max(3, int(round(length / max(spacing, 1e-12))))
    targets = np.arange(k) * (length / k)
    picks = np.searchsorted(arc, targets, side="left")
    return np.unique(loop[np.clip(picks, 0, loop.size - 1)])


def sample_spread(points: np.ndarray, indices: np.ndarray, spacing: float) -> np.ndarray:
    """Farthest-point sample of ``indices`` with no two chosen vertices closer than ``spacing``."""
    idx = np.asarray(indices, dtype=np.int64)
    if idx.size == 0:
        return idx
    p = points[idx]
    chosen = [0]
    dist = np.linalg.norm(p - p[0], axis=1)
    while True:
        j = int(dist.argmax())
        if dist[j] < spacing:
            break
        chosen.append(j)
        dist = np.minimum(dist, np.linalg.norm(p - p[j], axis=1))
    return np.sort(idx[chosen])


def constraint_vertices(points: np.ndarray, regions: list[Region], *, spacing: float,
                        pin_border: bool = True, exclude_near: np.ndarray | None = None,
                        clearance: float = 0.0) -> tuple[np.ndarray, dict[str, int]]:
    """Vertices that become zero-displacement RBF centres.

    Pinned and rigid regions, and the outer border when ``pin_border``, thinned to about
    ``spacing`` apart: every border vertex as a centre makes the kernel matrix singular (two
    centres much closer than the kernel width), while centres spaced like the markers pin the
    border just as well.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
    regions : list of Region
    spacing : float
        Target spacing (mesh units), e.g. the median nearest-marker distance.
    pin_border : bool
        Treat the ``outerBorder`` region as pinned.
    exclude_near : ndarray, shape (M, 3), optional
        Points (the bound markers) that constraint centres must keep ``clearance`` away from:
        a marker bound next to a pinned vertex would fight it.
    clearance : float
        Minimum distance from any ``exclude_near`` point (mesh units).

    Returns
    -------
    vertices : ndarray, shape (P,), int64
    counts : dict region name -> number of centres taken from it
    """
    chosen, counts = [], {}
    for region in regions:
        pinned = region.role in ("pinned", "rigid") or (pin_border and region.role == "outerBorder")
        if not pinned:
            continue
        if region.loop is not None and region.role == "outerBorder":
            picks = sample_loop(points, region.loop, spacing)
        else:
            picks = sample_spread(points, region.indices, spacing)
        if exclude_near is not None and len(exclude_near) and clearance > 0:
            d = np.linalg.norm(points[picks][:, None, :] - np.asarray(exclude_near)[None], axis=2).min(axis=1)
            picks = picks[d >= clearance]
        counts[region.name] = int(picks.size)
        chosen.append(picks)
    if not chosen:
        return np.zeros(0, dtype=np.int64), counts
    return np.unique(np.concatenate(chosen)), counts
