"""The layered tissue model of seed 001 §5.1: epidermis, fascia and bone nodes, prisms and springs.

Construction (the paper's four steps, Fig. 3):

1. a vertex normal at every mesh vertex; the vertex is an **epidermis** node;
2. a **fascia** node ``fascia_depth`` below it along the normal;
3. a **bone** node a further ``bone_depth`` below, attached to the skull (or the jaw);
4. every triangle of the mesh (quads split along their fixed v0-v2 diagonal, see
   :meth:`usdface.mesh.FaceMesh.triangles`) is a triangular **prism element** spanning the three
   layers: an upper (dermal) prism epidermis-fascia and a lower (muscle) prism fascia-bone.
   Springs run along the prism edges — the triangle edges in the epidermis and fascia layers,
   the vertical edges epidermis-fascia and fascia-bone — and along both cross-diagonals of every
   side face of each prism.

Bone-bone springs are left out: both ends are moved kinematically, so they never exert a force.
The model counts 6 E + 2 N springs for a mesh of N vertices and E triangle edges.

Node order: epidermis ``0..N-1``, fascia ``N..2N-1``, bone ``2N..3N-1`` (node ``k*N + i`` lies
below vertex ``i``).

Units: lengths in mesh units; forces in model force units; masses in model mass units; time in
seconds. ``length_scale`` (1 cm expressed in mesh units) makes the defaults independent of the
mesh's unit: spring force ``k (l - l0) / length_scale``, mass ``density * area / length_scale**2``.

This module holds the options, the model and its construction; the surface checks (winding,
normals, areas) are in :mod:`usdface.tissue.surface`, the prism geometry and the offset field in
:mod:`usdface.tissue.prisms`.
"""
from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field

import numpy as np

from ..errors import OptionError, list_names
from ..model.mesh import FaceMesh
from .prisms import offset_field, prism_volumes
from .surface import length_scale_of, mesh_where, prepare_mesh, triangle_edges, vertex_areas, vertex_normals

log = logging.getLogger("usdface")

EPIDERMIS, FASCIA, BONE = 0, 1, 2
LAYER_NAMES = ("epidermis", "fascia", "bone")
#: spring kinds: index into TissueOptions' stiffness per kind
SPRING_KINDS = ("epidermis", "fascia", "dermis", "deep")


@dataclass(frozen=True)
class TissueOptions:
    """Material and construction options of the layered tissue model.

    Lengths are in centimetres and converted to mesh units with the model's ``length_scale``
    (so the defaults suit a face in any unit); ``None`` depth means the default.

    Attributes
    ----------
    fascia_depth : float
        Epidermis to fascia distance along the vertex normal (cm).
    bone_depth : float
        Fascia to bone distance along the vertex normal (cm).
    k_epidermis, k_fascia : float
        Stiffness of the springs within the epidermis and fascia layers (force per cm).
    k_dermis : float
        Stiffness of the epidermis-fascia springs (vertical and cross-diagonal).
    k_deep : float
        Stiffness of the fascia-bone springs (the muscle layer: soft, so the fascia slides).
    biphasic_strain : float or None
        Strain past which springs in tension stiffen (Lee-Terzopoulos-Waters' biphasic springs);
        None turns it off.
    biphasic_factor : float
        Stiffness multiplier past ``biphasic_strain``.
    node_damping : float
        Velocity damping ``-node_damping * m * v`` (1/s).
    spring_damping : float
        Stiffness-proportional (Rayleigh) damping ``beta`` (s): each spring is damped axially by
        ``beta k (v_j - v_i) . u``, each prism's volume change and the skull contact likewise. Forward
        Euler needs it: it is stable only for modes damped at a rate ``c >= h w^2``.
    k_volume : float
        Volume preservation stiffness per prism: energy ``c (V - V0)^2 / 2`` with
        ``c = 3 k_volume / |dV/dx|^2`` (the gradient at rest), so the prism resists volume change
        with a stiffness of ``3 k_volume`` (force per cm) along its stiffest direction, whatever
        its shape.
    k_skull : float
        Skull non-penetration penalty (force per cm); 0 turns it off.
    skull_margin : float
        Fraction of ``bone_depth`` a fascia node must stay above its bone node's tangent plane.
    density : float
        Mass per cm^2 of skin of one layer's nodes (epidermis and fascia).
    muscle_softening : float
        Within about this distance (cm) of its anchor a muscle's pull fades out (energy
        ``a F w sqrt(d^2 + eps^2)``), so tissue reaching the anchor does not chatter.
    lip_free_radius, eyelid_free_radius : float
        The lips and eyelids are not bound to bone: within these distances (cm) of the mouth and
        eye loops the deep springs weaken smoothly down to ``free_attachment`` times their
        stiffness at the loop.
    free_attachment : float
        Deep-spring factor at the mouth and eye loops.
    orient : {"fix", "error"}
        Inconsistently wound polygons are re-wound ("fix", with a warning naming them) or refused.
    min_depth_fraction : float
        Where the full depth would invert a prism (concave spots, lip and eyelid rims), the offset
        directions are smoothed and the depth of the vertices involved reduced, down to this
        fraction of the requested depth.
    min_mass_fraction : float
        Node masses are at least this fraction of the median node mass.
    max_folded_fraction : float
        Fraction of the polygons whose prisms may still be inverted at that depth (folds in the
        mesh, e.g. at sharp mouth corners): they are kept as they are, with a warning naming them;
        more is an error.
    """

    fascia_depth: float = 0.3
    bone_depth: float = 0.5
    k_epidermis: float = 60.0
    k_fascia: float = 30.0
    k_dermis: float = 30.0
    k_deep: float = 20.0
    biphasic_strain: float | None = 0.15
    biphasic_factor: float = 4.0
    node_damping: float = 25.0
    spring_damping: float = 0.001
    k_volume: float = 1000.0
    k_skull: float = 5000.0
    skull_margin: float = 0.6
    density: float = 0.025
    muscle_softening: float = 0.3
    lip_free_radius: float = 1.0
    eyelid_free_radius: float = 0.6
    free_attachment: float = 0.3
    orient: str = "fix"
    min_depth_fraction: float = 0.1
    min_mass_fraction: float = 0.5
    max_folded_fraction: float = 0.02

    def __post_init__(self) -> None:
        for name in ("fascia_depth", "bone_depth", "k_epidermis", "k_fascia", "k_dermis", "k_deep", "density",
                     "biphasic_factor"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise OptionError(f"tissue option {name} must be a positive number; got {v!r}")
        for name in ("node_damping", "spring_damping", "k_volume", "k_skull", "skull_margin", "muscle_softening",
                     "lip_free_radius", "eyelid_free_radius", "free_attachment"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise OptionError(f"tissue option {name} must be a number >= 0; got {v!r}")
        if self.biphasic_strain is not None and not (np.isfinite(self.biphasic_strain) and self.biphasic_strain > 0):
            raise OptionError(f"tissue option biphasic_strain must be > 0 or None; got {self.biphasic_strain!r}")
        if self.orient not in ("fix", "error"):
            raise OptionError(f"tissue option orient must be 'fix' or 'error'; got {self.orient!r}")
        if not 0 < self.min_depth_fraction <= 1:
            raise OptionError(f"tissue option min_depth_fraction must be in (0, 1]; got {self.min_depth_fraction!r}")

    def replace(self, **changes) -> "TissueOptions":
        """A copy with some options changed (None values are ignored)."""
        known = {f.name for f in dataclasses.fields(self)}
        bad = sorted(set(changes) - known)
        if bad:
            raise OptionError(f"unknown tissue option(s) {list_names(bad)}; known: {list_names(sorted(known))}")
        return dataclasses.replace(self, **{k: v for k, v in changes.items() if v is not None})

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @property
    def spring_stiffness(self) -> np.ndarray:
        """(4,) stiffness per spring kind (:data:`SPRING_KINDS`)."""
        return np.array([self.k_epidermis, self.k_fascia, self.k_dermis, self.k_deep])


@dataclass(frozen=True, eq=False)
class TissueModel:
    """A built layered tissue model (immutable; simulation state lives in the Simulator).

    Attributes
    ----------
    mesh : FaceMesh
        The (possibly re-wound) mesh the model was built from.
    options : TissueOptions
    length_scale : float
        1 cm in mesh units.
    triangles : ndarray (T, 3) int64
        Mesh triangles, outward (counter-clockwise seen from outside).
    normals : ndarray (N, 3) float64
        Unit outward vertex normals at rest.
    direction : ndarray (N, 3) float64
        Unit outward direction along which the fascia and bone nodes lie below each vertex (the
        normal, smoothed, see :func:`build_tissue_model`); also the skull's outward normal.
    depth : ndarray (N,) float64
        Per-vertex scale (0, 1] of the requested depths (1 except at concave spots).
    rest : ndarray (3N, 3) float64
        Rest positions of all nodes (epidermis, fascia, bone).
    mass : ndarray (3N,) float64
        Node masses; bone nodes carry ``inf`` (kinematic).
    springs : ndarray (S, 2) int64
        Node pairs.
    spring_kind : ndarray (S,) int8
        Index into :data:`SPRING_KINDS`.
    rest_length : ndarray (S,) float64
    stiffness : ndarray (S,) float64
        Spring constant in force per mesh unit (``k / length_scale``).
    prisms : ndarray (2T, 6) int64
        Sub-prism nodes (top triangle a b c, then the nodes below a b c): rows ``0..T-1`` are the
        dermal prisms (epidermis-fascia), ``T..2T-1`` the deep prisms (fascia-bone).
    rest_volume : ndarray (2T,) float64
        Signed rest volume of each prism (positive except at ``folded_faces``).
    volume_coef : ndarray (2T,) float64
        Volume preservation coefficient ``c_p`` (force / mesh unit^5): energy ``c_p (V - V0)^2 / 2``.
    attachment : ndarray (N,) float64
        Per vertex, the factor on its deep springs (and deep prisms' volume stiffness): 1 where the
        tissue is bound to the bone, down to ``free_attachment`` at the lip and eyelid margins.
    flipped_faces : ndarray (K,) int64
        Polygons that were re-wound to make the orientation consistent (input numbering).
    folded_faces : ndarray (J,) int64
        Polygons whose prisms are inverted at rest (folds in the mesh), kept as they are.
    """

    mesh: FaceMesh
    options: TissueOptions
    length_scale: float
    triangles: np.ndarray
    normals: np.ndarray
    direction: np.ndarray
    depth: np.ndarray
    rest: np.ndarray
    mass: np.ndarray
    springs: np.ndarray
    spring_kind: np.ndarray
    rest_length: np.ndarray
    stiffness: np.ndarray
    prisms: np.ndarray
    rest_volume: np.ndarray
    volume_coef: np.ndarray
    attachment: np.ndarray
    flipped_faces: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    folded_faces: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def n_vertices(self) -> int:
        return self.mesh.n_points

    @property
    def n_nodes(self) -> int:
        return self.rest.shape[0]

    @property
    def n_springs(self) -> int:
        return self.springs.shape[0]

    @property
    def n_elements(self) -> int:
        """Prism elements (one per triangle, each spanning the three layers)."""
        return self.triangles.shape[0]

    @property
    def n_free(self) -> int:
        """Simulated (non-kinematic) nodes: epidermis and fascia."""
        return 2 * self.n_vertices

    def layer(self, which: int | str) -> slice:
        """Node slice of a layer (0/"epidermis", 1/"fascia", 2/"bone")."""
        k = LAYER_NAMES.index(which) if isinstance(which, str) else int(which)
        n = self.n_vertices
        return slice(k * n, (k + 1) * n)

    @property
    def element_rest_volume(self) -> np.ndarray:
        """(T,) rest volume of each three-layer element (dermal + deep prism)."""
        t = self.n_elements
        return self.rest_volume[:t] + self.rest_volume[t:]

    def summary(self) -> dict:
        counts = np.bincount(self.spring_kind, minlength=len(SPRING_KINDS))
        return {"vertices": self.n_vertices, "nodes": self.n_nodes, "springs": self.n_springs,
                "springsPerKind": {k: int(c) for k, c in zip(SPRING_KINDS, counts)},
                "elements": self.n_elements, "prisms": int(self.prisms.shape[0]),
                "lengthScale": self.length_scale, "flippedFaces": self.flipped_faces.tolist(),
                "foldedFaces": self.folded_faces.tolist(),
                "reducedDepthVertices": int((self.depth < 1).sum())}



def _attachment(mesh, pts, tris, regions, L, opts) -> np.ndarray:
    """(N,) factor on the deep springs: ``free_attachment`` at the mouth and eye loops, rising smoothly
    to 1 at ``lip_free_radius`` / ``eyelid_free_radius`` (cm) from them."""
    from scipy.spatial import cKDTree

    out = np.ones(len(pts))
    for r in regions:
        if r.loop is None or r.role not in ("mouth", "eye"):
            continue
        radius = (opts.lip_free_radius if r.role == "mouth" else opts.eyelid_free_radius) * L
        if radius <= 0:
            continue
        d = cKDTree(pts[r.loop]).query(pts)[0]
        s = np.clip(d / radius, 0.0, 1.0)
        f = opts.free_attachment + (1.0 - opts.free_attachment) * s * s * (3 - 2 * s)
        out = np.minimum(out, f)
    return out


def build_tissue_model(mesh: FaceMesh, options: TissueOptions | None = None, *, regions=None,
                       **option_changes) -> TissueModel:
    """Build the three-layer prism model of a face mesh (seed 001 §5.1, Fig. 3).

    Parameters
    ----------
    mesh : FaceMesh
        The face, in any linear unit (``mesh.units`` sets the length scale; unknown units assume
        a face about 25 units across).
    options : TissueOptions, optional
    regions : list of Region, optional
        Hole regions of the mesh (:func:`usdface.mesh.topology.find_hole_regions`); the mouth and
        eye loops loosen the deep layer at the lips and eyelids. Found automatically when None;
        pass ``[]`` for none.
    **option_changes
        Individual :class:`TissueOptions` fields (e.g. ``fascia_depth=0.4``).

    Returns
    -------
    TissueModel

    Raises
    ------
    MeshError
        Zero-area faces, non-manifold or non-orientable meshes, inconsistent winding with
        ``orient="error"``, or prisms that stay inverted even at the smallest allowed depth
        (named).
    """
    opts = (options or TissueOptions()).replace(**option_changes)
    mesh, flipped = prepare_mesh(mesh, orient=opts.orient)
    if regions is None:
        from ..mesh.topology import find_hole_regions

        regions = find_hole_regions(mesh)
    L = length_scale_of(mesh)
    n = mesh.n_points
    tris = mesh.triangles()
    used = np.zeros(n, dtype=bool)
    used[tris.ravel()] = True
    if not used.all():
        log.info("mesh %s: %d vertices belong to no face; they stay still", mesh_where(mesh), int((~used).sum()))
    pts = mesh.points
    nrm = vertex_normals(pts, tris)
    nrm[~used] = 0.0
    d_f, d_b = opts.fascia_depth * L, opts.bone_depth * L
    e = triangle_edges(tris, n)

    t = tris.shape[0]
    prisms = np.concatenate([
        np.concatenate([tris, tris + n], axis=1),
        np.concatenate([tris + n, tris + 2 * n], axis=1),
    ])
    direction, depth, folded = offset_field(mesh, tris, e, nrm, used, prisms, depths=(d_f, d_b),
                                            min_fraction=opts.min_depth_fraction,
                                            max_inverted=opts.max_folded_fraction)
    rest = np.concatenate([pts, pts - (d_f * depth)[:, None] * direction,
                           pts - ((d_f + d_b) * depth)[:, None] * direction])

    a, b = e[:, 0], e[:, 1]
    vi = np.arange(n)[used]
    pairs = [
        (a, b, 0),                    # epidermis layer
        (a + n, b + n, 1),            # fascia layer
        (vi, vi + n, 2),              # vertical epidermis-fascia
        (a, b + n, 2), (b, a + n, 2),  # cross-diagonals of the dermal side faces
        (vi + n, vi + 2 * n, 3),      # vertical fascia-bone
        (a + n, b + 2 * n, 3), (b + n, a + 2 * n, 3),  # cross-diagonals of the deep side faces
    ]
    si = np.concatenate([p[0] for p in pairs]).astype(np.int64)
    sj = np.concatenate([p[1] for p in pairs]).astype(np.int64)
    kind = np.concatenate([np.full(p[0].size, p[2], dtype=np.int8) for p in pairs])
    springs = np.stack([si, sj], axis=1)
    rest_len = np.linalg.norm(rest[sj] - rest[si], axis=1)
    stiff = opts.spring_stiffness[kind] / L
    # the deep layer binds the tissue to the bone: loose at the free margins (lips, eyelids), and
    # scaled with the local depth (a thinned prism's cross-diagonals lie almost flat and would
    # otherwise pin the rim to the bone)
    attach = _attachment(mesh, pts, tris, regions, L, opts) if regions is not None else np.ones(n)
    deep = kind == 3
    vert_of = np.where(si < n, si, si - n) % n
    stiff[deep] *= (attach * depth)[vert_of[deep]]

    area = vertex_areas(pts, tris)
    # lumped skin area per node, floored so the slivers at lip and eyelid rims do not get tiny masses
    area = np.maximum(area, opts.min_mass_fraction * np.median(area[used]))
    m_layer = opts.density * area / L ** 2
    m_layer = np.where(used, m_layer, 1.0)
    mass = np.concatenate([m_layer, m_layer, np.full(n, np.inf)])
    vol = prism_volumes(rest, prisms)
    # E_p = 1/2 c_p (V - V0)^2 with c_p = 3 k_volume / (L |grad V0|^2): the prism's stiffest
    # direction then has stiffness 3 k_volume / L whatever its shape (a regular prism's uniform
    # thinning costs about as much as three vertical springs of stiffness k_volume); slivers at
    # the rims do not become stiff (they would ruin the stable step and the implicit solve)
    from .forces import prism_volume_gradients

    _, g0 = prism_volume_gradients(rest, prisms)
    gnorm2 = np.einsum("pkd,pkd->p", g0, g0)
    # slivers (tiny rest gradient) would stiffen without bound as they open up: floor the gradient
    floor = 0.25 * np.median(gnorm2[:t]), 0.25 * np.median(gnorm2[t:])
    gnorm2 = np.maximum(gnorm2, np.r_[np.full(t, floor[0]), np.full(t, floor[1])])
    vcoef = 3.0 * (opts.k_volume / L) / np.maximum(gnorm2, 1e-300)
    # the deep prisms of loosely attached tissue (lips, eyelids) hold loose connective tissue: they
    # are as compressible as they are loose
    vcoef[t:] *= attach[tris].mean(axis=1)
    # folded faces (prisms inverted at rest) get no volume term: preserving an inverted volume is
    # meaningless and their gradients are ill-conditioned
    if folded.size:
        bad = np.isin(mesh.triangle_faces(), folded)
        vcoef[np.concatenate([bad, bad])] = 0.0
    return TissueModel(mesh=mesh, options=opts, length_scale=L, triangles=tris, normals=nrm, direction=direction,
                       depth=depth, rest=rest, mass=mass, springs=springs, spring_kind=kind, rest_length=rest_len,
                       stiffness=stiff, prisms=prisms, rest_volume=vol, volume_coef=vcoef, attachment=attach,
                       flipped_faces=flipped, folded_faces=folded)
