"""Abstract muscles (seed 001 §5.2): linear (vector) muscles and ellipsoid (sphincter) muscles.

Linear muscle (Waters 1987): an origin attached to the bone and an insertion in the tissue. A
fascia node at rest position ``p`` is pulled toward the origin with weight ``w = A(mu) R(D)``:

- ``mu`` = angle between ``p - origin`` and ``insertion - origin``; ``A = cos(pi/2 mu / zone)``
  inside the angular zone ``mu < zone`` (``zoneAngle``), 0 outside (Waters uses ``cos(mu)`` with
  a hard edge; this falls smoothly to zero at the zone's edge);
- ``D = |p - origin|``; ``R = cos(pi/2 (1 - D/R_s))^3`` for ``D <= R_s`` (``innerRadius``, by
  default the muscle's length: strongest at the insertion, nothing at the bone) and
  ``R = cos(pi/2 (D - R_s) / (R_f - R_s))`` up to ``R_f`` (``outerRadius``), 0 beyond. Waters'
  ramp is cubed: his weights scale displacements, here they spread a force, and the cube keeps
  the pull where the muscle inserts instead of on the tissue near its origin.

Sphincter (ellipsoid) muscle: "a string bag": nodes are squeezed toward its centre, with a radial
weighting only. ``r = |(p - centre) / semiAxes|`` (semi-axes along the mesh's X, Y, Z); ``w = 1``
for ``r <= rho``, ``cos(pi/2 (r - rho) / (1 - rho))`` up to the ellipsoid's surface ``r = 1``;
``rho = innerRadius / outerRadius``. The squeeze acts in the ellipse's plane, weighted toward
its long axis (:attr:`Muscle.squeeze_metric`), so a contracting mouth ring gathers the lips
sideways and the volume preservation pushes them forward, the way lips purse.

Force on a fascia node: ``a F w_i A_i / sum_j w_j A_j`` toward the anchor, with
``a`` the contraction in [0, 1], ``F`` the muscle's ``maxForce`` (the total force at full
contraction, whatever the mesh resolution) and ``A`` the node's skin area.
"""
from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, OptionError, list_names

MUSCLE_TYPES = ("linear", "sphincter")
_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def _vec(v, what: str) -> np.ndarray | None:
    if v is None:
        return None
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    if a.size != 3 or not np.isfinite(a).all():
        raise InputError(f"{what} must be 3 finite numbers; got {v!r}")
    return a


@dataclass(frozen=True, eq=False)
class Muscle:
    """One abstract muscle (the FaceMuscleAPI values).

    Attributes
    ----------
    name : str
        A USD identifier, e.g. ``zygomaticMajor_L``.
    type : {"linear", "sphincter"}
    origin, insertion : ndarray (3,), linear muscles
        Bone attachment and tissue insertion (mesh units).
    centre, semi_axes : ndarray (3,), sphincter muscles
        Ellipsoid centre and semi-axes along X, Y, Z (mesh units).
    zone_angle : float
        Linear: half-angle of the zone of influence (degrees, 0 < zone <= 90).
    inner_radius, outer_radius : float
        Radial falloff start and end (mesh units). Defaults: linear ``|insertion - origin|`` and
        1.35 times that; sphincter half and all of the largest semi-axis.
    max_force : float
        Total force at full contraction (model force units).
    """

    name: str
    type: str = "linear"
    origin: np.ndarray | None = None
    insertion: np.ndarray | None = None
    centre: np.ndarray | None = None
    semi_axes: np.ndarray | None = None
    zone_angle: float = 40.0
    inner_radius: float | None = None
    outer_radius: float | None = None
    max_force: float = 1.0

    def __post_init__(self) -> None:
        what = f"muscle {self.name!r}"
        if not isinstance(self.name, str) or not _IDENT.match(self.name):
            raise InputError(f"{what}: the name must be a USD identifier (letters, digits, _)")
        if self.type not in MUSCLE_TYPES:
            raise InputError(f"{what}: type must be one of {', '.join(MUSCLE_TYPES)}; got {self.type!r}")
        for f in ("origin", "insertion", "centre", "semi_axes"):
            object.__setattr__(self, f, _vec(getattr(self, f), f"{what} {f}"))
        if self.type == "linear":
            if self.origin is None or self.insertion is None:
                raise InputError(f"{what}: a linear muscle needs an origin and an insertion")
            length = float(np.linalg.norm(self.insertion - self.origin))
            if length <= 0:
                raise InputError(f"{what}: origin and insertion coincide")
            if not 0 < self.zone_angle <= 90:
                raise InputError(f"{what}: zoneAngle must be in (0, 90] degrees; got {self.zone_angle}")
            inner = length if self.inner_radius is None else float(self.inner_radius)
            outer = 1.35 * inner if self.outer_radius is None else float(self.outer_radius)
        else:
            if self.centre is None or self.semi_axes is None:
                raise InputError(f"{what}: a sphincter muscle needs a centre and semi-axes")
            if (self.semi_axes <= 0).any():
                raise InputError(f"{what}: semi-axes must be positive; got {self.semi_axes.tolist()}")
            big = float(self.semi_axes.max())
            outer = big if self.outer_radius is None else float(self.outer_radius)
            inner = 0.5 * outer if self.inner_radius is None else float(self.inner_radius)
        if not (np.isfinite(inner) and np.isfinite(outer) and 0 < inner < outer):
            raise InputError(f"{what}: need 0 < innerRadius < outerRadius; got {inner}, {outer}")
        object.__setattr__(self, "inner_radius", inner)
        object.__setattr__(self, "outer_radius", outer)
        if not (np.isfinite(self.max_force) and self.max_force >= 0):
            raise InputError(f"{what}: maxForce must be a number >= 0; got {self.max_force}")
        object.__setattr__(self, "zone_angle", float(self.zone_angle))
        object.__setattr__(self, "max_force", float(self.max_force))

    @property
    def anchor(self) -> np.ndarray:
        """The point nodes are pulled toward: origin (linear) or centre (sphincter)."""
        return self.origin if self.type == "linear" else self.centre

    @property
    def squeeze_metric(self) -> np.ndarray:
        """(3, 3) metric ``P`` of the pull ``-P d / |d|_P`` toward the anchor.

        Linear muscles: the identity (straight toward the origin). Sphincters: diagonal along X, Y,
        Z with ``(s_k / s_max)^4`` and 0 along the shortest semi-axis — the squeeze acts in the
        ellipse's plane, most along its long axis (a mouth ring gathers the lips sideways rather
        than pressing one lip over the other; an eye ring closes the lids).
        """
        if self.type == "linear":
            return np.eye(3)
        w = (self.semi_axes / self.semi_axes.max()) ** 4
        w[int(np.argmin(self.semi_axes))] = 0.0
        return np.diag(w)

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.insertion - self.origin)) if self.type == "linear" else 0.0

    def replace(self, **changes) -> "Muscle":
        return dataclasses.replace(self, **changes)

    def scaled(self, factor: float) -> "Muscle":
        """The muscle with its lengths multiplied by ``factor`` (unit conversion)."""
        s = lambda v: None if v is None else v * factor  # noqa: E731
        return dataclasses.replace(self, origin=s(self.origin), insertion=s(self.insertion), centre=s(self.centre),
                                   semi_axes=s(self.semi_axes), inner_radius=self.inner_radius * factor,
                                   outer_radius=self.outer_radius * factor)

    def to_dict(self) -> dict:
        d = {"name": self.name, "type": self.type, "zoneAngle": self.zone_angle, "innerRadius": self.inner_radius,
             "outerRadius": self.outer_radius, "maxForce": self.max_force}
        for key, v in (("origin", self.origin), ("insertion", self.insertion), ("centre", self.centre),
                       ("semiAxes", self.semi_axes)):
            if v is not None:
                d[key] = [float(c) for c in v]
        return d


def linear_muscle_weights(points, origin, insertion, *, zone_angle, inner_radius, outer_radius):
    """Waters-style linear muscle weights (angular zone x radial falloff).

    Parameters
    ----------
    points : ndarray (n, 3)
        Rest positions of the nodes the muscle may act on (mesh units).
    origin, insertion : ndarray (3,)
    zone_angle : float
        Half-angle of the zone (degrees).
    inner_radius, outer_radius : float
        ``R_s`` and ``R_f`` (mesh units).

    Returns
    -------
    ndarray (n,) in [0, 1]
    """
    p = np.asarray(points, dtype=np.float64) - origin
    axis = np.asarray(insertion, dtype=np.float64) - origin
    axis = axis / np.linalg.norm(axis)
    dist = np.linalg.norm(p, axis=1)
    cosmu = np.divide(p @ axis, dist, out=np.ones_like(dist), where=dist > 0)
    mu = np.degrees(np.arccos(np.clip(cosmu, -1.0, 1.0)))
    ang = np.where(mu < zone_angle, np.cos(0.5 * np.pi * mu / zone_angle), 0.0)
    rad = np.where(dist <= inner_radius, np.cos(0.5 * np.pi * (1.0 - np.minimum(dist / inner_radius, 1.0))) ** 3,
                   np.cos(0.5 * np.pi * np.clip((dist - inner_radius) / (outer_radius - inner_radius), 0.0, 1.0)))
    rad = np.where(dist > outer_radius, 0.0, rad)
    return np.clip(ang * rad, 0.0, 1.0)


def sphincter_weights(points, centre, semi_axes, *, inner_radius, outer_radius):
    """Ellipsoid (sphincter) muscle weights: radial only.

    Parameters
    ----------
    points : ndarray (n, 3)
    centre, semi_axes : ndarray (3,)
    inner_radius, outer_radius : float
        Their ratio ``rho`` is where the falloff starts, as a fraction of the ellipsoid.

    Returns
    -------
    ndarray (n,) in [0, 1]
    """
    r = np.linalg.norm((np.asarray(points, dtype=np.float64) - centre) / semi_axes, axis=1)
    rho = inner_radius / outer_radius
    w = np.where(r <= rho, 1.0, np.cos(0.5 * np.pi * np.clip((r - rho) / (1.0 - rho), 0.0, 1.0)))
    return np.where(r >= 1.0, 0.0, w)


def muscle_weights(muscle: Muscle, points) -> np.ndarray:
    """Weights of one muscle on nodes at ``points`` (see the module docstring)."""
    if muscle.type == "linear":
        return linear_muscle_weights(points, muscle.origin, muscle.insertion, zone_angle=muscle.zone_angle,
                                     inner_radius=muscle.inner_radius, outer_radius=muscle.outer_radius)
    return sphincter_weights(points, muscle.centre, muscle.semi_axes, inner_radius=muscle.inner_radius,
                             outer_radius=muscle.outer_radius)


@dataclass(frozen=True)
class Jaw:
    """The jaw: bone nodes below the mouth rotate about ``pivot`` around ``axis``.

    Attributes
    ----------
    pivot : ndarray (3,)
        A point on the rotation axis (mesh units); by default behind the mouth corners, about
        where the temporomandibular joints are (see :func:`usdface.tissue.rig.default_jaw`).
    axis : ndarray (3,)
        Unit rotation axis; positive rotation opens the mouth.
    max_angle : float
        Rotation (degrees) at jaw opening 1.
    weights : ndarray (N,)
        Per vertex, how much its bone node follows the jaw (1 on the mandible, 0 on the skull,
        a smooth band between away from the mouth).
    """

    pivot: np.ndarray
    axis: np.ndarray
    max_angle: float
    weights: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "pivot", _vec(self.pivot, "jaw pivot"))
        ax = _vec(self.axis, "jaw axis")
        if np.linalg.norm(ax) == 0:
            raise InputError("jaw axis must not be zero")
        object.__setattr__(self, "axis", ax / np.linalg.norm(ax))
        if not (np.isfinite(self.max_angle) and 0 <= self.max_angle <= 45):
            raise InputError(f"jaw maxAngle must be in [0, 45] degrees; got {self.max_angle}")
        object.__setattr__(self, "weights", np.clip(np.asarray(self.weights, dtype=np.float64), 0.0, 1.0))

    def rotation(self, opening: float) -> np.ndarray:
        """(3, 3) rotation for an opening in [0, 1]."""
        return rotation_matrix(self.axis, math.radians(self.max_angle * float(opening)))


def rotation_matrix(axis, angle: float) -> np.ndarray:
    """Rodrigues rotation about a unit axis by ``angle`` radians."""
    a = np.asarray(axis, dtype=np.float64)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


@dataclass(frozen=True, eq=False)
class MuscleSet:
    """Muscles compiled against a tissue model: the sparse node weights the engine uses.

    Attributes
    ----------
    muscles : tuple of Muscle
    nodes : ndarray (K,) int64
        Fascia node of each entry.
    muscle : ndarray (K,) int64
        Muscle index of each entry.
    base : ndarray (K,) float64
        Force of each entry at full contraction: ``F w_i A_i / sum_j w_j A_j``.
    weights : ndarray (K,) float64
        The raw weights ``w_i``.
    anchors : ndarray (M, 3)
        Rest anchor of each muscle.
    metric : ndarray (M, 3, 3)
        Squeeze metric of each muscle (:attr:`Muscle.squeeze_metric`).
    on_jaw : ndarray (M,) float64
        How much each anchor follows the jaw (the jaw weight of the vertex nearest to it).
    """

    muscles: tuple
    nodes: np.ndarray
    muscle: np.ndarray
    base: np.ndarray
    weights: np.ndarray
    anchors: np.ndarray
    metric: np.ndarray
    on_jaw: np.ndarray

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.muscles)

    @property
    def n_muscles(self) -> int:
        return len(self.muscles)

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise OptionError(f"no muscle {name!r} in the rig; it has {list_names(self.names)}") from None

    def coefficients(self, contraction) -> np.ndarray:
        """(K,) entry forces for contractions (M,) in [0, 1]."""
        a = check_contractions(contraction, self.names)
        return a[self.muscle] * self.base

    def vertex_weights(self, name: str, n_vertices: int) -> np.ndarray:
        """(N,) weight of muscle ``name`` per mesh vertex (for previews)."""
        k = self.index(name)
        sel = self.muscle == k
        w = np.zeros(n_vertices)
        w[self.nodes[sel] - n_vertices] = self.weights[sel]
        return w


def check_contractions(contraction, names, *, where: str = "") -> np.ndarray:
    """Contractions as an (M,) float array, refusing values outside [0, 1] or not finite."""
    a = np.asarray(contraction, dtype=np.float64).reshape(-1)
    if a.size != len(names):
        raise OptionError(f"{where}expected {len(names)} contractions ({list_names(names)}); got {a.size}")
    bad = np.flatnonzero(~np.isfinite(a) | (a < 0) | (a > 1))
    if bad.size:
        items = [f"{names[i]}={a[i]:g}" for i in bad]
        raise OptionError(f"{where}contraction must be in [0, 1]: {list_names(items)}")
    return a


def compile_muscles(model, muscles, *, jaw: Jaw | None = None, max_origin_distance: float | None = None) -> MuscleSet:
    """Weights of each muscle on the model's fascia nodes.

    Parameters
    ----------
    model : TissueModel
    muscles : sequence of Muscle
    jaw : Jaw, optional
        Anchors near jaw vertices follow the jaw.
    max_origin_distance : float, optional
        Largest allowed distance (mesh units) from a linear muscle's origin to the bone layer, from
        its insertion to the skin, and from a sphincter's centre to the skin beyond its largest
        semi-axis. Default 2 cm.

    Returns
    -------
    MuscleSet

    Raises
    ------
    InputError
        Duplicate names, a muscle far from the mesh (named, with its distance), or a muscle that
        acts on no tissue.
    """
    from scipy.spatial import cKDTree

    muscles = tuple(muscles)
    names = [m.name for m in muscles]
    dups = sorted({n for n in names if names.count(n) > 1})
    if dups:
        raise InputError(f"duplicate muscle names: {list_names(dups)}")
    n = model.n_vertices
    L = model.length_scale
    limit = 2.0 * L if max_origin_distance is None else float(max_origin_distance)
    fascia = model.rest[model.layer("fascia")]
    skin = model.rest[model.layer("epidermis")]
    bone = model.rest[model.layer("bone")]
    skin_tree, bone_tree = cKDTree(skin), cKDTree(bone)
    area = model.mass[:n] * L ** 2 / model.options.density
    nodes, mus, base, wts, far, empty = [], [], [], [], [], []
    anchors = np.zeros((len(muscles), 3))
    metric = np.zeros((len(muscles), 3, 3))
    on_jaw = np.zeros(len(muscles))
    for k, m in enumerate(muscles):
        if m.type == "linear":
            d_o = bone_tree.query(m.origin)[0]
            d_i = skin_tree.query(m.insertion)[0]
            if d_o > limit:
                far.append(f"{m.name} (origin {d_o / L:.2f} cm from the bone layer)")
            if d_i > limit:
                far.append(f"{m.name} (insertion {d_i / L:.2f} cm from the skin)")
        else:
            d_c = skin_tree.query(m.centre)[0]
            if d_c > limit + float(m.semi_axes.max()):
                far.append(f"{m.name} (centre {d_c / L:.2f} cm from the skin)")
        w = muscle_weights(m, fascia)
        sel = np.flatnonzero(w > 1e-6)
        if sel.size == 0 or m.type == "linear" and w.max() < 1e-3:
            empty.append(m.name)
            continue
        wa = w[sel] * area[sel]
        nodes.append(sel + n)
        mus.append(np.full(sel.size, k))
        base.append(m.max_force * wa / wa.sum())
        wts.append(w[sel])
        anchors[k] = m.anchor
        metric[k] = m.squeeze_metric
        if jaw is not None:
            on_jaw[k] = jaw.weights[int(skin_tree.query(m.anchor)[1])]
    if far:
        raise InputError(f"muscle(s) far from the mesh (more than {limit / L:.2f} cm): {list_names(far)}")
    if empty:
        raise InputError(f"muscle(s) acting on no tissue (no fascia node inside their zone): {list_names(empty)}")
    cat = lambda parts, dt: np.concatenate(parts).astype(dt) if parts else np.zeros(0, dt)  # noqa: E731
    return MuscleSet(muscles=muscles, nodes=cat(nodes, np.int64), muscle=cat(mus, np.int64),
                     base=cat(base, np.float64), weights=cat(wts, np.float64), anchors=anchors, metric=metric,
                     on_jaw=on_jaw)
