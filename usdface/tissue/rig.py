"""Facial landmarks and the default muscle rig placed from them.

The rig is placed from landmarks that every face mesh with open eyes and mouth has, so the same
anatomy lands on any face:

- from the hole loops (:func:`usdface.mesh.topology.find_hole_regions`): the mouth corners (the
  mouth loop's extreme-x vertices), the mouth's upper and lower rims, the eye centres, inner and
  outer corners, tops and bottoms;
- from the surface, by "front projection" (the first hit of a ray along the face's backward
  axis): the brow ridge (the most forward point above each eye), the nose tip (most forward point
  on the midline between mouth and eyes), the chin (lowest midline point) and the forehead;
- when marker positions on the mesh are given (a marker layout or a binding: the 41 AnimFace
  markers), the brows, nose tip, chin and forehead come from the markers instead
  (``Leyebrow_Inside``, ``Leyebrow_M``, ``Leyebrow_Outside``, ``NoseHead``, ``Chin``,
  ``ForeHead_L``...).

Everything is expressed in a face frame (origin between the eye centres, x toward the performer's
left, y up, z forward, unit = inter-ocular distance D), so the rig scales and turns with the face.
A rig built on one face carries over to another through :func:`warp_rig` (a thin-plate RBF warp
driven by the two faces' landmarks or bound markers), as the paper warps its muscle system with
the generic model.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, MeshError, list_names
from ..model.mesh import FaceMesh
from .surface import length_scale_of, vertex_normals
from .muscles import Jaw, Muscle

#: landmark name -> marker names (AnimFace layout) that give it when markers are known
MARKER_LANDMARKS = {
    "browInner_L": ("Leyebrow_Inside",), "browInner_R": ("Reyebrow_Inside",),
    "browMid_L": ("Leyebrow_M",), "browMid_R": ("Reyebrow_M",),
    "browOuter_L": ("Leyebrow_Outside",), "browOuter_R": ("Reyebrow_Outside",),
    "noseTip": ("NoseHead",), "chin": ("Chin",),
    "forehead_L": ("ForeHead_L",), "forehead_R": ("ForeHead_R",), "forehead": ("ForeHead_M",),
}


@dataclass(frozen=True)
class FaceFrame:
    """Origin between the eyes; rows of ``axes`` = left (x), up (y), forward (z); ``scale`` = D."""

    origin: np.ndarray
    axes: np.ndarray
    scale: float

    def to_world(self, local) -> np.ndarray:
        return self.origin + self.scale * (np.asarray(local, dtype=np.float64) @ self.axes)

    def to_local(self, points) -> np.ndarray:
        return ((np.asarray(points, dtype=np.float64) - self.origin) @ self.axes.T) / self.scale

    def direction(self, local) -> np.ndarray:
        return np.asarray(local, dtype=np.float64) @ self.axes


def _regions_by_name(regions) -> dict:
    return {r.name: r for r in regions}


def _require_holes(mesh: FaceMesh, regions) -> dict:
    by = _regions_by_name(regions)
    missing = [n for n in ("mouth", "leftEye", "rightEye") if n not in by or by[n].loop is None]
    if missing:
        raise MeshError(f"mesh {mesh.source or mesh.name}: the muscle rig needs open eyes and mouth (hole regions "
                        f"mouth, leftEye, rightEye); missing {', '.join(missing)}. Found regions: "
                        f"{list_names(sorted(by)) or 'none'}")
    return by


def _ray_hits(points, triangles, origins, direction):
    """First hit of rays ``origins + t direction`` (t > 0) on the triangles; NaN rows for misses."""
    p = np.asarray(points)
    a, b, c = p[triangles[:, 0]], p[triangles[:, 1]], p[triangles[:, 2]]
    e1, e2 = b - a, c - a
    pv = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    ok = np.abs(det) > 1e-14
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    out = np.full((len(origins), 3), np.nan)
    for r, o in enumerate(np.asarray(origins, dtype=np.float64)):  # a few dozen rays at rig set-up
        tv = o - a
        u = np.einsum("ij,ij->i", tv, pv) * inv
        qv = np.cross(tv, e1)
        v = (qv @ direction) * inv
        t = np.einsum("ij,ij->i", e2, qv) * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        if hit.any():
            out[r] = o + t[hit].min() * direction
    return out


class _Surface:
    """Front projection and closest points on one mesh, in a face frame."""

    def __init__(self, mesh: FaceMesh, frame: FaceFrame):
        from ..mesh.closest import SurfaceLocator

        self.mesh, self.frame = mesh, frame
        self.tris = mesh.triangles()
        self.locator = SurfaceLocator(mesh.points, self.tris)
        self.normals = vertex_normals(mesh.points, self.tris)
        self.depth_extent = float(np.ptp(frame.to_local(mesh.points)[:, 2])) + 1.0

    def front(self, local_xy) -> np.ndarray:
        """Surface points hit by rays along -z through local (x, y); closest point when missed."""
        xy = np.atleast_2d(np.asarray(local_xy, dtype=np.float64))
        starts = self.frame.to_world(np.c_[xy, np.full(len(xy), 3.0 + self.depth_extent)])
        hits = _ray_hits(self.mesh.points, self.tris, starts, -self.frame.axes[2])
        miss = ~np.isfinite(hits).all(axis=1)
        if miss.any():  # through a hole or past the border: the closest surface point to the ray's line
            cand = self.frame.to_world(np.c_[xy[miss], np.zeros(miss.sum())])
            hits[miss] = self.snap(cand)
        return hits

    def snap(self, points) -> np.ndarray:
        _, _, pts, _ = self.locator.closest(np.atleast_2d(points))
        return pts

    def normal_at(self, points) -> np.ndarray:
        tri, bary, _, _ = self.locator.closest(np.atleast_2d(points))
        n = np.einsum("ik,ikd->id", bary, self.normals[self.tris[tri]])
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


def face_frame(mesh: FaceMesh, regions) -> FaceFrame:
    """The face frame from the eye and mouth loops."""
    by = _require_holes(mesh, regions)
    p = mesh.points
    eye_l = p[by["leftEye"].loop].mean(axis=0)
    eye_r = p[by["rightEye"].loop].mean(axis=0)
    mouth = p[by["mouth"].loop].mean(axis=0)
    x = eye_l - eye_r
    d = float(np.linalg.norm(x))
    if d <= 0:
        raise MeshError("the eye loops coincide: cannot place a face frame")
    x /= d
    centre = 0.5 * (eye_l + eye_r)
    up = centre - mouth
    y = up - (up @ x) * x
    y /= np.linalg.norm(y)
    z = np.cross(x, y)
    # z must point out of the face (toward the viewer): the surface normals' mean direction
    tris = mesh.triangles()
    fn = np.cross(p[tris[:, 1]] - p[tris[:, 0]], p[tris[:, 2]] - p[tris[:, 0]]).sum(axis=0)
    if fn @ z < 0:  # mesh wound inward or the eyes swapped (+x is the performer's left)
        z = -z
        x = -x
    return FaceFrame(origin=centre, axes=np.stack([x, y, z]), scale=d)


def face_landmarks(mesh: FaceMesh, regions=None, *, markers: dict | None = None) -> tuple[FaceFrame, dict]:
    """Landmarks of a face mesh for placing muscles.

    Parameters
    ----------
    mesh : FaceMesh
        A face looking toward +Z-ish with open eyes and mouth.
    regions : list of Region, optional
        Hole regions (default: :func:`usdface.mesh.topology.find_hole_regions`).
    markers : dict {name: (3,)}, optional
        Marker positions on this mesh (layout or bound points); see :data:`MARKER_LANDMARKS`.

    Returns
    -------
    frame : FaceFrame
    landmarks : dict {str: ndarray (3,)}
        World positions (mesh units): ``mouthCorner_L/_R``, ``mouthCentre``, ``upperLip``,
        ``lowerLip``, ``eyeCentre_L/_R``, ``eyeInner_L/_R``, ``eyeOuter_L/_R``, ``eyeTop_L/_R``,
        ``eyeBottom_L/_R``, ``browInner_L/_R``, ``browMid_L/_R``, ``browOuter_L/_R``,
        ``noseTip``, ``chin``, ``forehead``, ``forehead_L/_R``, ``top``.
    """
    if regions is None:
        from ..mesh.topology import find_hole_regions

        regions = find_hole_regions(mesh)
    by = _require_holes(mesh, regions)
    frame = face_frame(mesh, regions)
    surf = _Surface(mesh, frame)
    p = mesh.points
    loc = frame.to_local(p)
    lm: dict[str, np.ndarray] = {}
    mouth = by["mouth"].loop
    ml = loc[mouth]
    lm["mouthCorner_L"] = p[mouth[np.argmax(ml[:, 0])]]
    lm["mouthCorner_R"] = p[mouth[np.argmin(ml[:, 0])]]
    mid = np.abs(ml[:, 0]) < 0.25 * np.ptp(ml[:, 0])
    lm["upperLip"] = surf.front([[0.0, ml[mid, 1].max() + 0.05]])[0]
    lm["lowerLip"] = surf.front([[0.0, ml[mid, 1].min() - 0.05]])[0]
    lm["mouthCentre"] = 0.5 * (lm["mouthCorner_L"] + lm["mouthCorner_R"])
    for side, name in (("L", "leftEye"), ("R", "rightEye")):
        loop = by[name].loop
        el = loc[loop]
        lm[f"eyeCentre_{side}"] = p[loop].mean(axis=0)
        inner, outer = (np.argmin(el[:, 0]), np.argmax(el[:, 0])) if side == "L" else (np.argmax(el[:, 0]), np.argmin(el[:, 0]))
        lm[f"eyeInner_{side}"] = p[loop[inner]]
        lm[f"eyeOuter_{side}"] = p[loop[outer]]
        lm[f"eyeTop_{side}"] = p[loop[np.argmax(el[:, 1])]]
        lm[f"eyeBottom_{side}"] = p[loop[np.argmin(el[:, 1])]]
    # brows: a third of D above the eye's top, over its centre, inner corner and (lower) outer corner
    for side in ("L", "R"):
        c = frame.to_local(lm[f"eyeCentre_{side}"])
        brow_y = frame.to_local(lm[f"eyeTop_{side}"])[1] + 0.33
        inner_x = frame.to_local(lm[f"eyeInner_{side}"])[0]
        outer_x = frame.to_local(lm[f"eyeOuter_{side}"])[0]
        lm[f"browMid_{side}"] = surf.front([[c[0], brow_y]])[0]
        lm[f"browInner_{side}"] = surf.front([[inner_x, brow_y - 0.02]])[0]
        lm[f"browOuter_{side}"] = surf.front([[outer_x + 0.05 * np.sign(outer_x), brow_y - 0.08]])[0]
    # nose tip: most forward midline point between 40% of the way from the mouth up to the eyes
    mouth_y = frame.to_local(lm["mouthCentre"])[1]
    ys = np.linspace(mouth_y + 0.4 * (0.0 - mouth_y), 0.0, 30)
    col = frame.to_local(surf.front(np.c_[np.zeros(ys.size), ys]))
    lm["noseTip"] = frame.to_world(col[int(np.argmax(col[:, 2]))])
    # chin: lowest midline surface point; forehead and top: highest midline points
    near_mid = np.abs(loc[:, 0]) < 0.08
    lm["chin"] = surf.front([[0.0, loc[near_mid, 1].min() + 0.12]])[0]
    top_y = loc[near_mid, 1].max()
    lm["top"] = p[np.flatnonzero(near_mid)[np.argmax(loc[near_mid, 1])]]
    brow_y = frame.to_local(lm["browMid_L"])[1]
    fy = brow_y + 0.6 * (top_y - brow_y)
    lm["forehead"] = surf.front([[0.0, fy]])[0]
    lm["forehead_L"] = surf.front([[0.7, fy - 0.05]])[0]
    lm["forehead_R"] = surf.front([[-0.7, fy - 0.05]])[0]
    lm["topLine"] = frame.to_world([0.0, top_y, 0.0])
    if markers:
        for key, names in MARKER_LANDMARKS.items():
            for name in names:
                if name in markers:
                    lm[key] = surf.snap(np.asarray(markers[name], dtype=np.float64))[0]
                    break
    return frame, lm


# -- the default rig ------------------------------------------------------------------------------

#: default total force at full contraction per muscle (model force units)
DEFAULT_FORCES = {
    "zygomaticMajor": 28000.0, "risorius": 30000.0, "depressorAnguliOris": 6000.0, "depressorLabiiInferioris": 800.0,
    "mentalis": 400.0, "levatorLabiiSuperioris": 1500.0, "levatorLabiiAlaeque": 1700.0, "frontalisInner": 2400.0,
    "frontalisOuter": 3900.0, "corrugator": 700.0, "procerus": 600.0, "orbicularisOculi": 12000.0,
    "orbicularisOris": 30000.0,
}


@dataclass(frozen=True, eq=False)
class MuscleRig:
    """A muscle rig for one face: muscles, the jaw and the tissue settings.

    Attributes
    ----------
    muscles : tuple of Muscle
    jaw_pivot, jaw_axis : ndarray (3,)
        The jaw's rotation axis (mesh units); positive rotation opens the mouth.
    jaw_max_angle : float
        Degrees at jaw opening 1.
    tissue : dict
        :class:`~usdface.tissue.model.TissueOptions` overrides recorded with the rig.
    landmarks : dict {str: ndarray (3,)}
        The landmarks the rig was placed from (mesh units).
    placement : str
        ``"mesh"`` (hole loops and surface), ``"markers"`` (with marker positions) or ``"warp"``.
    units : str or None
    """

    muscles: tuple
    jaw_pivot: np.ndarray
    jaw_axis: np.ndarray
    jaw_max_angle: float = 25.0
    tissue: dict = field(default_factory=dict)
    landmarks: dict = field(default_factory=dict)
    placement: str = "mesh"
    units: str | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "muscles", tuple(self.muscles))
        names = [m.name for m in self.muscles]
        dups = sorted({n for n in names if names.count(n) > 1})
        if dups:
            raise InputError(f"muscle rig has duplicate muscle names: {list_names(dups)}")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.muscles)

    def muscle(self, name: str) -> Muscle:
        for m in self.muscles:
            if m.name == name:
                return m
        raise KeyError(name)

    def jaw_for(self, mesh: FaceMesh, regions=None) -> Jaw:
        """The jaw on ``mesh``: this rig's pivot and axis, weights from the mesh's mouth loop."""
        if regions is None:
            from ..mesh.topology import find_hole_regions

            regions = find_hole_regions(mesh)
        return Jaw(pivot=self.jaw_pivot, axis=self.jaw_axis, max_angle=self.jaw_max_angle,
                   weights=jaw_weights(mesh, regions))

    def replace(self, **changes) -> "MuscleRig":
        return dataclasses.replace(self, **changes)


def jaw_weights(mesh: FaceMesh, regions, *, slope: float = 0.3, band: float = 0.03, spread: float = 0.5,
                corner_band: float = 0.12, corner_drop: float = 0.04) -> np.ndarray:
    """How much each vertex's bone follows the jaw: the region below the mouth loop.

    Between the mouth corners the split is the mouth loop itself: a lip vertex goes with the rim it
    is nearer to along the surface (upper lip on the skull, lower lip on the jaw, a sharp boundary
    ``band`` D wide), blending toward the corners into a height rule ``corner_band`` D wide;
    beyond the corners the boundary runs from ``corner_drop`` D below the corner down and out with
    ``slope`` and widens into a smooth band (``spread`` D per D), so the corners stay mostly with
    the skull and the cheek beside the mouth stretches smoothly when the jaw opens.

    Returns
    -------
    ndarray (N,) in [0, 1]
    """
    frame = face_frame(mesh, regions)
    by = _regions_by_name(regions)
    loc = frame.to_local(mesh.points)
    ml = loc[by["mouth"].loop]
    half = 0.5 * np.ptp(ml[:, 0])
    cx = 0.5 * (ml[:, 0].max() + ml[:, 0].min())
    # mid-line of the mouth slit as a function of x: mean of the upper and lower rims
    order = np.argsort(ml[:, 0])
    xs = np.linspace(cx - half, cx + half, 41)
    upper = np.full(xs.size, -np.inf)
    lower = np.full(xs.size, np.inf)
    bins = np.clip(np.searchsorted(xs, ml[order, 0]), 0, xs.size - 1)
    for b, y in zip(bins, ml[order, 1]):  # a few dozen loop vertices
        upper[b] = max(upper[b], y)
        lower[b] = min(lower[b], y)
    has = np.isfinite(upper) & np.isfinite(lower)
    midline = np.interp(xs, xs[has], 0.5 * (upper[has] + lower[has]))
    corner_y = 0.5 * (ml[np.argmax(ml[:, 0]), 1] + ml[np.argmin(ml[:, 0]), 1])
    dx = np.abs(loc[:, 0] - cx)
    near_corner = np.clip(1.0 - (half - dx) / (0.3 * half), 0.0, 1.0)  # 0 mid-mouth, 1 at the corners
    # the mouth corners ride mostly with the skull: the boundary dips below them
    y_b = np.where(dx <= half, np.interp(loc[:, 0], xs, midline), corner_y - slope * (dx - half))
    y_b = y_b - corner_drop * np.minimum(near_corner + np.maximum(dx - half, 0.0) / (0.3 * half), 1.0)
    width = band + (corner_band - band) * near_corner + spread * np.maximum(dx - half, 0.0)
    s = np.clip((y_b - loc[:, 1]) / width + 0.5, 0.0, 1.0)
    w = s * s * (3 - 2 * s)
    # the lips themselves go by the surface, not by height: the lips touch in front of the slit
    # and roll in over it, so a vertex belongs to the lip whose rim it is nearer along the mesh
    lip = _lip_side(mesh, by["mouth"].loop, loc)
    if lip is not None:
        d_up, d_low = lip
        t = np.clip((d_up - d_low) / (2.0 * band * frame.scale) + 0.5, 0.0, 1.0)
        w_lip = t * t * (3 - 2 * t)
        # lip rule between the corners and close to the mouth, height rule toward the corners
        alpha = (dx <= half) * (1.0 - near_corner) * (np.minimum(d_up, d_low) < 0.35 * frame.scale)
        w = alpha * w_lip + (1.0 - alpha) * w
    return w


def _lip_side(mesh: FaceMesh, loop: np.ndarray, loc: np.ndarray):
    """Surface (edge-path) distances of every vertex to the upper and to the lower rim of the mouth.

    The loop is split at its two extreme-x vertices (the corners); the arc with the larger mean
    height is the upper rim. Returns (d_upper, d_lower) or None for a degenerate loop.
    """
    import scipy.sparse as sp
    from scipy.sparse.csgraph import dijkstra

    from .surface import triangle_edges

    lx = loc[loop, 0]
    a, b = int(np.argmin(lx)), int(np.argmax(lx))
    if a == b:
        return None
    i, j = sorted((a, b))
    arc1, arc2 = loop[i:j + 1], np.concatenate([loop[j:], loop[:i + 1]])
    up, low = (arc1, arc2) if loc[arc1, 1].mean() > loc[arc2, 1].mean() else (arc2, arc1)
    corners = loop[[a, b]]
    up, low = np.setdiff1d(up, corners), np.setdiff1d(low, corners)
    if up.size == 0 or low.size == 0:
        return None
    e = triangle_edges(mesh.triangles(), mesh.n_points)
    length = np.linalg.norm(mesh.points[e[:, 0]] - mesh.points[e[:, 1]], axis=1)
    g = sp.coo_matrix((length, (e[:, 0], e[:, 1])), shape=(mesh.n_points, mesh.n_points)).tocsr()
    d_up = dijkstra(g, directed=False, indices=up, min_only=True)
    d_low = dijkstra(g, directed=False, indices=low, min_only=True)
    return d_up, d_low


def _linear(name, surf, frame, insertion, origin, *, zone, depth, force, outer=1.3):
    """A linear muscle from surface insertion/origin points; the origin is pushed to the bone."""
    n = surf.normal_at(origin)[0]
    o = origin - depth * n
    ins = insertion - 0.375 * depth * surf.normal_at(insertion)[0]  # in the tissue, at the fascia
    length = float(np.linalg.norm(ins - o))
    return Muscle(name=name, type="linear", origin=o, insertion=ins, zone_angle=zone, inner_radius=length,
                  outer_radius=outer * length, max_force=force)


def default_rig(mesh: FaceMesh, regions=None, *, markers: dict | None = None, forces: dict | None = None,
                tissue: dict | None = None, bone_depth: float | None = None) -> MuscleRig:
    """The default rig of named anatomical muscles, placed from landmarks.

    Muscles (``_L`` on the performer's left, +x): zygomaticMajor, risorius, depressorAnguliOris,
    depressorLabiiInferioris, levatorLabiiSuperioris, levatorLabiiAlaeque (levator labii
    superioris alaeque nasi), frontalisInner, frontalisOuter, corrugator, orbicularisOculi (L/R);
    mentalis, procerus, orbicularisOris (single).

    Parameters
    ----------
    mesh : FaceMesh
    regions : list of Region, optional
        Hole regions (found when not given).
    markers : dict {name: (3,)}, optional
        Marker positions on this mesh (e.g. a layout's); brows, nose tip, chin and forehead then
        come from them.
    forces : dict {base name: float}, optional
        Overrides of :data:`DEFAULT_FORCES` (keys without ``_L``/``_R``).
    tissue : dict, optional
        Tissue option overrides to record with the rig.
    bone_depth : float, optional
        Depth of the linear muscles' origins under the skin (mesh units); default the tissue
        model's total depth (0.8 cm).

    Returns
    -------
    MuscleRig
    """
    if regions is None:
        from ..mesh.topology import find_hole_regions

        regions = find_hole_regions(mesh)
    frame, lm = face_landmarks(mesh, regions, markers=markers)
    surf = _Surface(mesh, frame)
    L = length_scale_of(mesh)
    depth = 0.8 * L if bone_depth is None else float(bone_depth)
    F = dict(DEFAULT_FORCES)
    F.update(forces or {})
    local = {k: frame.to_local(v) for k, v in lm.items()}
    D = frame.scale
    muscles = []

    def front(x, y):
        return surf.front([[x, y]])[0]

    def lin(name, ins_xy, org_xy, zone, base, outer=1.3):
        muscles.append(_linear(name, surf, frame, front(*ins_xy), front(*org_xy), zone=zone, depth=depth,
                               force=F[base], outer=outer))

    for side, sg in (("L", 1.0), ("R", -1.0)):
        mc = local[f"mouthCorner_{side}"]
        ec = local[f"eyeCentre_{side}"]
        ei = local[f"eyeInner_{side}"]
        eo = local[f"eyeOuter_{side}"]
        eb = local[f"eyeBottom_{side}"]
        bi, bm, bo = local[f"browInner_{side}"], local[f"browMid_{side}"], local[f"browOuter_{side}"]
        chin = local["chin"]
        ul, ll = local["upperLip"], local["lowerLip"]
        fy = local["forehead"][1]
        # mouth corner muscles insert at the modiolus, just outside the corner
        modiolus = (mc[0] + sg * 0.1, mc[1])
        lin(f"zygomaticMajor_{side}", modiolus, (eo[0] + sg * 0.22, eb[1] - 0.42), 18.0, "zygomaticMajor")
        lin(f"risorius_{side}", modiolus, (mc[0] + sg * 0.55, mc[1] - 0.05), 16.0, "risorius")
        lin(f"depressorAnguliOris_{side}", (mc[0] + sg * 0.02, mc[1] - 0.03),
            (mc[0] + sg * 0.14, chin[1] + 0.12), 18.0, "depressorAnguliOris")
        lin(f"depressorLabiiInferioris_{side}", (0.45 * mc[0], ll[1] - 0.02),
            (0.65 * mc[0], chin[1] + 0.2), 20.0, "depressorLabiiInferioris")
        lin(f"levatorLabiiSuperioris_{side}", (0.45 * mc[0], ul[1] + 0.03),
            (ec[0] - sg * 0.05, eb[1] - 0.2), 18.0, "levatorLabiiSuperioris")
        lin(f"levatorLabiiAlaeque_{side}", (sg * 0.22, 0.5 * (local["noseTip"][1] + ul[1]) - 0.02),
            (ei[0] - sg * 0.12, ec[1] - 0.05), 16.0, "levatorLabiiAlaeque")
        lin(f"frontalisInner_{side}", (bi[0] + sg * 0.05, bi[1] + 0.02),
            (bi[0] + sg * 0.05, fy + 0.15), 30.0, "frontalisInner", outer=1.5)
        lin(f"frontalisOuter_{side}", (bo[0], bo[1] + 0.02), (bo[0] - sg * 0.05, fy + 0.1), 30.0, "frontalisOuter",
            outer=1.5)
        lin(f"corrugator_{side}", (bm[0], bm[1] + 0.02), (sg * 0.1, ei[1] + 0.12), 25.0, "corrugator", outer=1.3)
        # orbicularis oculi: around the eye, from the brow to the upper cheek
        w = abs(eo[0] - ei[0])
        centre = lm[f"eyeCentre_{side}"]
        muscles.append(Muscle(name=f"orbicularisOculi_{side}", type="sphincter", centre=centre,
                              semi_axes=np.array([0.85 * w * D, 0.48 * D, 0.25 * D]),
                              inner_radius=0.45 * 0.85 * w * D, outer_radius=0.85 * w * D,
                              max_force=F["orbicularisOculi"]))
    chin, ll, ul = local["chin"], local["lowerLip"], local["upperLip"]
    lin("mentalis", (0.0, chin[1] + 0.25 * (ll[1] - chin[1])), (0.0, ll[1] - 0.35 * (ll[1] - chin[1])), 35.0,
        "mentalis", outer=1.6)
    lin("procerus", (0.0, local["browInner_L"][1] + 0.04), (0.0, local["eyeInner_L"][1] - 0.05), 30.0, "procerus")
    mw = float(np.linalg.norm(lm["mouthCorner_L"] - lm["mouthCorner_R"]))
    centre = surf.front([[0.5 * (local["mouthCorner_L"][0] + local["mouthCorner_R"][0]),
                          0.5 * (local["mouthCorner_L"][1] + local["mouthCorner_R"][1])]])[0]
    centre = 0.5 * (centre + lm["mouthCentre"])
    muscles.append(Muscle(name="orbicularisOris", type="sphincter", centre=centre,
                          semi_axes=np.array([0.5 * mw + 0.2 * D, 0.3 * D, 0.2 * D]),
                          inner_radius=0.5 * (0.5 * mw + 0.2 * D), outer_radius=0.5 * mw + 0.2 * D,
                          max_force=F["orbicularisOris"]))
    # semi-axes are along the mesh's X, Y, Z: rotate the face-frame extents into mesh axes
    muscles = [_axis_aligned(m, frame) for m in muscles]
    mcz = 0.5 * (local["mouthCorner_L"][2] + local["mouthCorner_R"][2])
    pivot = frame.to_world([0.0, local["mouthCentre"][1] + 0.45, mcz - 1.25])
    return MuscleRig(muscles=tuple(muscles), jaw_pivot=pivot, jaw_axis=frame.axes[0].copy(), jaw_max_angle=25.0,
                     tissue=dict(tissue or {}), landmarks=lm, placement="markers" if markers else "mesh",
                     units=mesh.units)


def _axis_aligned(m: Muscle, frame: FaceFrame) -> Muscle:
    """Sphincter semi-axes were given in the face frame: express them along the mesh axes."""
    if m.type != "sphincter":
        return m
    ax = np.abs(frame.axes)  # rows: frame axes in mesh coordinates
    semi = np.sqrt((ax.T ** 2) @ (m.semi_axes ** 2))
    return m.replace(semi_axes=semi)


def warp_rig(rig: MuscleRig, source_points, target_points, *, target_mesh: FaceMesh | None = None) -> MuscleRig:
    """Carry a rig to another face with a thin-plate RBF warp (affine part exact).

    Parameters
    ----------
    rig : MuscleRig
        Placed on the source face.
    source_points, target_points : ndarray (K, 3)
        Corresponding points on the two faces (landmarks, or the bound markers of the two faces'
        bindings), K >= 4, in each face's units.
    target_mesh : FaceMesh, optional
        Its units are recorded.

    Returns
    -------
    MuscleRig
        Points warped; radii and semi-axes scaled by the warp's local scale.
    """
    from scipy.interpolate import RBFInterpolator

    src = np.asarray(source_points, dtype=np.float64)
    dst = np.asarray(target_points, dtype=np.float64)
    if src.shape != dst.shape or src.ndim != 2 or src.shape[1] != 3 or src.shape[0] < 4:
        raise InputError(f"warp_rig needs two (K >= 4, 3) point sets of the same shape; got {src.shape}, {dst.shape}")
    ok = np.isfinite(src).all(axis=1) & np.isfinite(dst).all(axis=1)
    warp = RBFInterpolator(src[ok], dst[ok] - src[ok], kernel="thin_plate_spline", degree=1)

    def f(p):
        p = np.atleast_2d(p)
        return p + warp(p)

    def local_scale(p):
        eps = 0.05 * float(np.ptp(src[ok], axis=0).max())
        pts = np.asarray(p) + eps * np.vstack([np.zeros(3), np.eye(3)])
        q = f(pts)
        jac = (q[1:] - q[0]) / eps
        return float(abs(np.linalg.det(jac)) ** (1 / 3))

    out = []
    for m in rig.muscles:
        s = local_scale(m.anchor)
        if m.type == "linear":
            o, i = f(np.stack([m.origin, m.insertion]))
            out.append(m.replace(origin=o, insertion=i, inner_radius=m.inner_radius * s, outer_radius=m.outer_radius * s))
        else:
            out.append(m.replace(centre=f(m.centre)[0], semi_axes=m.semi_axes * s, inner_radius=m.inner_radius * s,
                                 outer_radius=m.outer_radius * s))
    pivot = f(rig.jaw_pivot)[0]
    axis_pt = f(rig.jaw_pivot + rig.jaw_axis)[0] - pivot
    lms = {k: f(v)[0] for k, v in rig.landmarks.items()}
    return rig.replace(muscles=tuple(out), jaw_pivot=pivot, jaw_axis=axis_pt / np.linalg.norm(axis_pt), landmarks=lms,
                       placement="warp", units=target_mesh.units if target_mesh is not None else rig.units)


def landmark_correspondence(rig_a: MuscleRig, rig_b_or_landmarks) -> tuple[np.ndarray, np.ndarray]:
    """Matching landmark positions of two rigs (or a rig and a landmark dict), for :func:`warp_rig`."""
    lb = rig_b_or_landmarks.landmarks if isinstance(rig_b_or_landmarks, MuscleRig) else rig_b_or_landmarks
    keys = sorted(set(rig_a.landmarks) & set(lb))
    return np.stack([rig_a.landmarks[k] for k in keys]), np.stack([lb[k] for k in keys])
