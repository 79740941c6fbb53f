"""Error regions of the quality evaluation (mouth, eyes, lips, lids: see
:mod:`usdface.evaluation.quality`) and the pinned constraint vertices of each pin variant."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..model.mesh import FaceMesh, Region
from .configs import REGION_NAMES

__all__ = ["EvaluationRegions", "loop_rims", "evaluation_regions", "pinned_vertices", "loop_of"]


@dataclass(frozen=True)
class EvaluationRegions:
    """Vertex masks of the error regions (see the module docstring).

    Attributes
    ----------
    masks : dict str -> ndarray (N,) bool
        One per name of :data:`REGION_NAMES` (absent holes give empty masks).
    radius : float
        Region radius (mesh units).
    corner_y : float or None
        y of the higher mouth corner (mesh units): the "upper" pin keeps border vertices above it.
    """

    masks: dict
    radius: float
    corner_y: float | None = None

    def __getitem__(self, name: str) -> np.ndarray:
        return self.masks[name]

    def counts(self) -> dict[str, int]:
        return {k: int(v.sum()) for k, v in self.masks.items()}


def loop_rims(points, loop) -> tuple[np.ndarray, np.ndarray]:
    """Split a closed hole loop into its upper and lower rim at its extreme-x vertices.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
    loop : ndarray, shape (L,), int
        Ordered closed loop (first vertex not repeated).

    Returns
    -------
    upper, lower : ndarray of int
        Vertex indices of each rim, both including the two corners; ``upper`` is the rim with the
        larger mean y.
    """
    loop = np.asarray(loop, dtype=np.int64)
    x = points[loop, 0]
    a, b = int(np.argmin(x)), int(np.argmax(x))
    rolled = np.roll(loop, -a)
    kb = (b - a) % loop.size
    r1 = rolled[: kb + 1]
    r2 = np.concatenate([rolled[kb:], rolled[:1]])
    if points[r1, 1].mean() >= points[r2, 1].mean():
        return r1, r2
    return r2, r1


def _rim_y(points, rim, x) -> np.ndarray:
    px, py = points[rim, 0], points[rim, 1]
    order = np.argsort(px, kind="stable")
    return np.interp(x, px[order], py[order])


def _split_by_centre_line(points, loop, mask) -> tuple[np.ndarray, np.ndarray]:
    """(above, below): vertices of ``mask`` between the loop's corners, above / below its centre line."""
    upper, lower = loop_rims(points, loop)
    x, y = points[:, 0], points[:, 1]
    xa, xb = points[loop, 0].min(), points[loop, 0].max()
    centre = 0.5 * (_rim_y(points, upper, x) + _rim_y(points, lower, x))
    inside = mask & (x > xa) & (x < xb)
    return inside & (y > centre), inside & (y < centre)


def evaluation_regions(mesh: FaceMesh, regions: list[Region], *, radius: float) -> EvaluationRegions:
    """Error-region masks of a face mesh (see the module docstring).

    Parameters
    ----------
    mesh : FaceMesh
    regions : list of Region
        Hole regions (``mouth`` role ``mouth``, eyes role ``eye`` named ``leftEye``/``rightEye``
        or any name, sorted to left/right by mean x).
    radius : float
        Region radius (mesh units), e.g. 1.5 cm.

    Returns
    -------
    EvaluationRegions
    """
    p = mesh.points
    n = p.shape[0]
    empty = np.zeros(n, dtype=bool)

    def near(loop):
        d, _ = cKDTree(p[np.asarray(loop)]).query(p, k=1)
        return d <= radius

    mouth_r = [r for r in regions if r.role == "mouth"]
    eye_r = [r for r in regions if r.role == "eye"]
    masks = {"face": np.ones(n, dtype=bool)}
    mouth = near(loop_of(mouth_r[0])) if mouth_r else empty.copy()
    masks["mouth"] = mouth
    eye_masks = {}
    for r in eye_r:
        eye_masks[r.name] = near(loop_of(r)) & ~mouth
    eyes = np.zeros(n, dtype=bool)
    for m in eye_masks.values():
        eyes |= m
    masks["eyes"] = eyes
    masks["rest"] = ~(mouth | eyes)
    corner_y = None
    if mouth_r:
        loop = loop_of(mouth_r[0])
        masks["upperLip"], masks["lowerLip"] = _split_by_centre_line(p, loop, mouth)
        x = p[loop, 0]
        corner_y = float(max(p[loop[np.argmin(x)], 1], p[loop[np.argmax(x)], 1]))
    else:
        masks["upperLip"], masks["lowerLip"] = empty.copy(), empty.copy()
    mid_x = 0.5 * (p[:, 0].min() + p[:, 0].max())
    for side in ("left", "right"):
        cands = [r for r in eye_r if (p[loop_of(r), 0].mean() > mid_x) == (side == "left")]
        if cands:
            r = max(cands, key=lambda r: loop_of(r).size)
            masks[f"{side}UpperLid"], masks[f"{side}LowerLid"] = _split_by_centre_line(p, loop_of(r), eye_masks[r.name])
        else:
            masks[f"{side}UpperLid"], masks[f"{side}LowerLid"] = empty.copy(), empty.copy()
    return EvaluationRegions({k: masks[k] for k in REGION_NAMES}, float(radius), corner_y)


def loop_of(region: Region) -> np.ndarray:
    return region.loop if region.loop is not None else region.indices


# ------------------------------------------------------------------------------------------------
# pinned centres
# ------------------------------------------------------------------------------------------------

def pinned_vertices(points, regions: list[Region], marker_points, *, spacing: float, corner_y: float | None
                    ) -> dict[str, np.ndarray]:
    """Constraint vertices of each pin variant, as the pipeline picks them.

    ``border``: :func:`usdface.mesh.regions.constraint_vertices` with ``pin_border="all"`` (the
    outer border thinned to ``spacing``, kept ``0.5 spacing`` from the markers) plus any
    pinned/rigid region; ``upper``: ``pin_border="upper"`` (outer-border picks above the mouth
    corners only: the pipeline's default); ``none``: the pinned/rigid regions only.

    Returns
    -------
    dict pin -> ndarray of int (sorted)
    """
    from ..mesh.regions import constraint_vertices

    pts = np.asarray(points, dtype=np.float64)
    kw = dict(spacing=spacing, exclude_near=marker_points, clearance=0.5 * spacing)
    out = {}
    for pin, policy in (("border", "all"), ("none", "none"), ("upper", "upper")):
        out[pin] = np.sort(constraint_vertices(pts, regions, pin_border=policy, **kw)[0]).astype(np.int64)
    return out
