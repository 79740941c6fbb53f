"""Left/right shape pairs whose offsets mirror each other (the solver's symmetry prior).

A pair ``<stem>Left`` / ``<stem>Right`` gets the prior ``w_Left ~ w_Right`` only when both hold:

1. **Mirror**: reflecting the Right shape's offsets in the face's symmetry plane, read at each
   vertex's mirror vertex, gives the Left shape's offsets (relative error below
   :data:`MIRROR_TOLERANCE`).
2. **One-sided**: the two shapes move different vertices, i.e. each acts on its own side. Their
   *overlap* ``sum_v min(|dL_v|, |dR_v|) / sum_v max(|dL_v|, |dR_v|)`` is below
   :data:`MAX_OVERLAP`. ``jawLeft``/``jawRight`` and ``mouthLeft``/``mouthRight`` mirror each
   other too, but move the same vertices in opposite directions (overlap 0.82 and 0.79 on the
   MakeHuman rig, against 0.43 at most for the one-sided ARKit pairs): they are opposite motions
   and coupling them would cancel both, so they never get the prior.

The mirror vertex map comes from the neutral: its symmetry plane
(:func:`usdface.mesh.symmetry.mirror_plane`, normal near +X), each vertex reflected and matched to
its nearest vertex. A neutral that is not symmetric (median mismatch above
:data:`ASYMMETRY_TOLERANCE` of the mean edge length) gets no prior at all.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rig import BlendShapeRig

__all__ = ["MirrorPair", "MirrorReport", "find_mirror_pairs", "MIRROR_TOLERANCE", "MAX_OVERLAP"]

#: largest relative difference between a Left shape and its reflected Right shape
MIRROR_TOLERANCE = 0.1
#: largest overlap of a one-sided pair (see the module docstring)
MAX_OVERLAP = 0.6
#: median vertex mismatch of the reflected neutral, as a fraction of the mean edge length
ASYMMETRY_TOLERANCE = 0.25


@dataclass(frozen=True)
class MirrorPair:
    """One Left/Right name pair and the checks made on it.

    Attributes
    ----------
    left, right : str
        Shape names.
    mirror_error : float
        ``|dL - mirror(dR)| / |dL|`` (Frobenius norms over all vertices); NaN if not measured.
    overlap : float
        See the module docstring; NaN if not measured.
    symmetric : bool
        True when the pair gets the prior.
    reason : str
        Why it does or does not.
    """

    left: str
    right: str
    mirror_error: float
    overlap: float
    symmetric: bool
    reason: str

    def summary(self) -> dict:
        return {"left": self.left, "right": self.right, "mirrorError": _r(self.mirror_error),
                "overlap": _r(self.overlap), "prior": self.symmetric, "reason": self.reason}


@dataclass(frozen=True)
class MirrorReport:
    """Every Left/Right name pair of a rig, and the vertex mirror map used."""

    pairs: tuple[MirrorPair, ...]
    plane_normal: np.ndarray
    plane_point: np.ndarray
    asymmetry: float  # median reflected-vertex mismatch / mean edge length

    @property
    def symmetric_pairs(self) -> list[tuple[str, str]]:
        return [(p.left, p.right) for p in self.pairs if p.symmetric]

    def summary(self) -> dict:
        return {"pairs": [p.summary() for p in self.pairs], "neutralAsymmetry": _r(self.asymmetry),
                "prior": [f"{a}/{b}" for a, b in self.symmetric_pairs]}


def _r(v, nd=4):
    return None if not np.isfinite(v) else round(float(v), nd)


def _name_pairs(names) -> list[tuple[str, str]]:
    have = set(names)
    out = []
    for n in names:
        if n.endswith("Left") and len(n) > 4:
            r = n[:-4] + "Right"
            if r in have:
                out.append((n, r))
        elif n.endswith("_L") and len(n) > 2 and n[:-2] + "_R" in have:
            out.append((n, n[:-2] + "_R"))
    return out


def _mean_edge(mesh) -> float:
    t = mesh.triangles()
    p = mesh.points
    e = np.concatenate([p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 1]], p[t[:, 0]] - p[t[:, 2]]])
    return float(np.linalg.norm(e, axis=1).mean())


def find_mirror_pairs(rig: BlendShapeRig, *, mirror_tolerance: float = MIRROR_TOLERANCE,
                      max_overlap: float = MAX_OVERLAP) -> MirrorReport:
    """Check every ``...Left``/``...Right`` (or ``..._L``/``..._R``) pair of the rig.

    Parameters
    ----------
    rig : BlendShapeRig
    mirror_tolerance, max_overlap : float
        See :data:`MIRROR_TOLERANCE`, :data:`MAX_OVERLAP`.

    Returns
    -------
    MirrorReport
        ``symmetric_pairs`` are the pairs the solver couples.
    """
    from scipy.spatial import cKDTree

    from ..mesh.symmetry import mirror_plane

    p = rig.neutral
    normal, point, _ = mirror_plane(p, normal=(1.0, 0.0, 0.0))
    refl = p - 2.0 * ((p - point) @ normal)[:, None] * normal
    dist, mirror_of = cKDTree(p).query(refl)
    asym = float(np.median(dist)) / max(_mean_edge(rig.mesh), 1e-300)
    pairs = []
    for left, right in _name_pairs(rig.names):
        dl = rig.deltas[rig.index(left)]
        dr = rig.deltas[rig.index(right)]
        nl = float(np.linalg.norm(dl))
        nr = float(np.linalg.norm(dr))
        if nl == 0.0 or nr == 0.0:
            pairs.append(MirrorPair(left, right, np.nan, np.nan, False, "a shape of the pair moves nothing"))
            continue
        if asym > ASYMMETRY_TOLERANCE:
            pairs.append(MirrorPair(left, right, np.nan, np.nan, False,
                                    f"the neutral is not left/right symmetric (median mismatch {asym:.2f} edges)"))
            continue
        mr = dr[mirror_of]
        mr = mr - 2.0 * (mr @ normal)[:, None] * normal
        err = float(np.linalg.norm(dl - mr)) / nl
        al, ar = np.linalg.norm(dl, axis=1), np.linalg.norm(dr, axis=1)
        overlap = float(np.minimum(al, ar).sum() / max(np.maximum(al, ar).sum(), 1e-300))
        if err > mirror_tolerance:
            pairs.append(MirrorPair(left, right, err, overlap, False,
                                    f"offsets do not mirror each other (error {err:.2f} > {mirror_tolerance:g})"))
        elif overlap > max_overlap:
            pairs.append(MirrorPair(left, right, err, overlap, False,
                                    f"opposite motions of the same vertices (overlap {overlap:.2f} > {max_overlap:g})"))
        else:
            pairs.append(MirrorPair(left, right, err, overlap, True,
                                    f"one-sided mirror pair (error {err:.3f}, overlap {overlap:.2f})"))
    return MirrorReport(tuple(pairs), normal, point, asym)
