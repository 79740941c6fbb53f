"""Label layout: text boxes beside their points that never overlap each other, the point glyphs or
reserved areas (legends, colour bar, title), and always lie inside the image.

Greedy placement, most crowded labels first: each label tries positions around its point at
growing distances (16 directions per ring, nearest first, the conventional upper right first
within a ring); the first free one wins. A label placed away from its point gets a leader line
(decided by the caller from :attr:`LabelPlacement.leader`). A label with no free position
anywhere in the image is left out (``placed`` False) rather than drawn over another.

Pure numpy; boxes are ``(x0, y0, x1, y1)`` in pixels, x right, y down, ``x1``/``y1`` exclusive.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["LabelPlacement", "boxes_overlap", "place_labels"]

# 16 directions, starting up-right and alternating around it (so near-equal candidates keep the
# conventional upper-right placement)
_ANGLES = np.deg2rad(np.array([-45, -22.5, -67.5, 0, -90, 22.5, -112.5, 45, -135, 67.5, -157.5, 90, 180, 112.5,
                               157.5, 135]))


@dataclass(frozen=True)
class LabelPlacement:
    """Where each label went.

    Attributes
    ----------
    boxes : ndarray (K, 4) float
        ``x0, y0, x1, y1`` of each label's box (NaN where not placed).
    placed : ndarray (K,) bool
    leader : ndarray (K,) bool
        The box is away from its point (draw a line from the point to the box).
    """

    boxes: np.ndarray
    placed: np.ndarray
    leader: np.ndarray

    @property
    def n_dropped(self) -> int:
        return int((~self.placed).sum())


def boxes_overlap(a: np.ndarray, b: np.ndarray, pad: float = 0.0) -> np.ndarray:
    """(len(a), len(b)) bool: box ``a[i]`` grown by ``pad`` intersects box ``b[j]``."""
    a = np.asarray(a, dtype=np.float64).reshape(-1, 4)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 4)
    return ((a[:, None, 0] - pad < b[None, :, 2]) & (b[None, :, 0] < a[:, None, 2] + pad)
            & (a[:, None, 1] - pad < b[None, :, 3]) & (b[None, :, 1] < a[:, None, 3] + pad))


def _box_at(anchor, size, angle, dist):
    """Boxes (len(angle), 4) touching the point ``dist`` from the anchor along ``angle`` with the
    corner or edge midpoint that faces the anchor (the cartographers' label positions)."""
    w, h = size
    c, s = np.cos(angle), np.sin(angle)
    px, py = anchor[0] + dist * c, anchor[1] + dist * s
    x0 = np.where(c > 0.38, px, np.where(c < -0.38, px - w, px - w / 2))
    y0 = np.where(s > 0.38, py, np.where(s < -0.38, py - h, py - h / 2))
    return np.stack([x0, y0, x0 + w, y0 + h], axis=-1)


def _box_point_distance(boxes: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(len(boxes), len(points)) distance from each box to each point (0 inside)."""
    dx = np.maximum(np.maximum(boxes[:, None, 0] - points[None, :, 0], points[None, :, 0] - boxes[:, None, 2]), 0.0)
    dy = np.maximum(np.maximum(boxes[:, None, 1] - points[None, :, 1], points[None, :, 1] - boxes[:, None, 3]), 0.0)
    return np.hypot(dx, dy)


@dataclass(frozen=True)
class _SearchRules:
    """Where a label may go (the settings of :func:`place_labels`, in pixels)."""

    obstacles: np.ndarray
    image: tuple
    gap: float
    pad: float
    leader_after: float
    max_distance: float
    own_nearest: bool


def _search(i, anchors, sizes, taken, rules: _SearchRules):
    """The first free box for label ``i`` (ring by ring) and whether it needs a leader line, or
    None; with ``own_nearest`` a box close enough to go without a leader line must be nearer to its
    own point than to any other (no label reads as another's; a leader line says whose it is)."""
    a, size = anchors[i], sizes[i]
    obstacles, gap, pad, leader_after = rules.obstacles, rules.gap, rules.pad, rules.leader_after
    max_distance, own_nearest = rules.max_distance, rules.own_nearest
    w_img, h_img = rules.image
    n_ang = _ANGLES.size
    others = np.delete(anchors, i, axis=0)
    others = others[np.isfinite(others).all(axis=1)]
    step = max(size[1] * 0.6, 2.0)
    dists = np.concatenate([[gap], gap + step * np.arange(1, int(max_distance / step) + 2)])
    for b0 in range(0, dists.size, 12):  # rings in blocks: one vectorised test per block
        ring = dists[b0:b0 + 12]
        cand = _box_at(a, size, np.tile(_ANGLES, ring.size), np.repeat(ring, n_ang))
        free = (cand[:, 0] >= 0) & (cand[:, 1] >= 0) & (cand[:, 2] <= w_img) & (cand[:, 3] <= h_img)
        if free.any() and taken.shape[0]:
            free[free] &= ~boxes_overlap(cand[free], taken, pad).any(axis=1)
        if free.any() and obstacles.shape[0]:
            free[free] &= ~boxes_overlap(cand[free], obstacles, 0.0).any(axis=1)
        near = np.repeat(ring, n_ang) <= leader_after
        if own_nearest and (free & near).any() and others.shape[0]:
            test = free & near
            own = _box_point_distance(cand[test], a[None])[:, 0]
            # clearly nearer: by half a gap (12.35 px against 12.8 px reads as either dot's)
            free[test] = own + 0.5 * gap <= _box_point_distance(cand[test], others).min(axis=1)
        hit = np.flatnonzero(free)
        if hit.size:
            j = hit[0]
            return cand[j], ring[j // n_ang] > leader_after
    return None


def place_labels(anchors, sizes, *, image_size, gap: float = 3.0, obstacles=None, pad: float = 1.0,
                 leader_after: float | None = None, max_distance: float | None = None,
                 own_nearest: bool = False) -> LabelPlacement:
    """Place label boxes of ``sizes`` next to ``anchors`` without overlaps, inside the image.

    Parameters
    ----------
    anchors : ndarray (K, 2)
        Label points (pixels).
    sizes : ndarray (K, 2)
        Box width and height of each label (pixels, text extent plus any outline).
    image_size : (int, int)
        (width, height); boxes stay inside ``[0, W) x [0, H)``.
    gap : float
        Distance from a point to its label's nearest edge in the first ring (the glyph radius
        plus a little).
    obstacles : ndarray (R, 4), optional
        Boxes labels must not cover: point glyphs, legends, colour bar, title.
    pad : float
        Minimum free space between two label boxes.
    leader_after : float, optional
        A label farther than this from its point is flagged for a leader line (default: 2 x gap).
    max_distance : float, optional
        Farthest ring searched (default: the image diagonal).
    own_nearest : bool
        A label placed without a leader line must be nearer to its own point than to any other (by
        half a ``gap`` at least), so it is never read as its neighbour's; where no such box is free,
        the label goes farther, with a leader line.

    Returns
    -------
    LabelPlacement
    """
    anchors = np.asarray(anchors, dtype=np.float64).reshape(-1, 2)
    sizes = np.asarray(sizes, dtype=np.float64).reshape(-1, 2)
    k = anchors.shape[0]
    w_img, h_img = (float(v) for v in image_size)
    obstacles = np.zeros((0, 4)) if obstacles is None else np.asarray(obstacles, dtype=np.float64).reshape(-1, 4)
    leader_after = 2.0 * gap if leader_after is None else float(leader_after)
    max_distance = float(np.hypot(w_img, h_img)) if max_distance is None else float(max_distance)
    boxes = np.full((k, 4), np.nan)
    placed = np.zeros(k, dtype=bool)
    leader = np.zeros(k, dtype=bool)
    if k == 0:
        return LabelPlacement(boxes, placed, leader)
    # crowded first: neighbours within two label heights
    d = np.hypot(*(anchors[:, None, :] - anchors[None, :, :]).transpose(2, 0, 1))
    crowd = (d < 2.5 * np.median(sizes[:, 1])).sum(axis=1)
    order = np.lexsort((anchors[:, 0], anchors[:, 1], -crowd))
    taken = np.zeros((0, 4))
    rules = _SearchRules(obstacles=obstacles, image=(w_img, h_img), gap=gap, pad=pad, leader_after=leader_after,
                         max_distance=max_distance, own_nearest=own_nearest)
    for i in order:
        if not np.isfinite(anchors[i]).all():
            continue
        found = _search(i, anchors, sizes, taken, rules)
        if found is not None:
            boxes[i], leader[i] = found
            placed[i] = True
            taken = np.vstack([taken, boxes[i][None]])
    return LabelPlacement(boxes, placed, leader)
