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
"""
from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import MeshError, OptionError, list_names
from ..model.mesh import FaceMesh
from ..units import METERS_PER_UNIT

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


# -- mesh checks ----------------------------------------------------------------------------------

def length_scale_of(mesh: FaceMesh) -> float:
    """1 cm in the mesh's units; for unknown units, the bounding-box diagonal / 25 (a face ~25 cm)."""
    if mesh.units in METERS_PER_UNIT:
        return 0.01 / METERS_PER_UNIT[mesh.units]
    return float(np.linalg.norm(np.ptp(mesh.points, axis=0))) / 25.0


def _mesh_where(mesh: FaceMesh) -> str:
    return mesh.source or repr(mesh.name)


def _polygon_sides(mesh: FaceMesh):
    counts, starts, idx = mesh.face_vertex_counts, mesh.face_starts, mesh.face_vertex_indices
    nxt = np.arange(1, idx.size + 1)
    nxt[starts + counts - 1] = starts
    face = np.repeat(np.arange(counts.size), counts)
    return idx, idx[nxt], face


def inconsistent_faces(mesh: FaceMesh) -> tuple[np.ndarray, np.ndarray]:
    """Polygons whose winding disagrees with their neighbours.

    Two polygons sharing an edge are consistently wound when they run along it in opposite
    directions. Within each connected patch the polygons are split into two classes of equal
    winding; the smaller class is reported (it is the one to re-wind).

    Parameters
    ----------
    mesh : FaceMesh

    Returns
    -------
    flip : ndarray (K,) int64
        Polygons to re-wind (sorted).
    non_orientable : ndarray (J,) int64
        Polygons of patches that cannot be wound consistently (Möbius-like), empty normally.

    Raises
    ------
    MeshError
        The mesh has an edge shared by more than two polygons.
    """
    frm, to, face = _polygon_sides(mesh)
    n = np.int64(mesh.n_points)
    lo, hi = np.minimum(frm, to), np.maximum(frm, to)
    key = lo * n + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    uniq, start, cnt = np.unique(ks, return_index=True, return_counts=True)
    if (cnt > 2).any():
        bad = uniq[cnt > 2][:10]
        raise MeshError(f"mesh {_mesh_where(mesh)}: {int((cnt > 2).sum())} edge(s) shared by more than two faces "
                        f"(non-manifold), e.g. vertex pairs {[(int(b // n), int(b % n)) for b in bad]}")
    pair = start[cnt == 2]
    s1, s2 = order[pair], order[pair + 1]
    same_dir = frm[s1] == frm[s2]  # both run a->b: inconsistent winding
    f1, f2 = face[s1], face[s2]
    p = mesh.n_faces
    # doubled graph: node (f, s) = face f with winding state s; consistent pairs link equal states
    a = np.concatenate([f1, f1 + p])
    b = np.concatenate([np.where(same_dir, f2 + p, f2), np.where(same_dir, f2, f2 + p)])
    g = sp.coo_matrix((np.ones(a.size), (a, b)), shape=(2 * p, 2 * p))
    _, lab = connected_components(g, directed=False)
    non_orientable = np.flatnonzero(lab[:p] == lab[p:])
    # faces in the same patch: same label for state 0 -> same class
    base = np.minimum(lab[:p], lab[p:])
    cls = lab[:p] == base
    flip = []
    for comp in np.unique(base):
        members = np.flatnonzero(base == comp)
        c = cls[members]
        minority = members[c] if c.sum() < (~c).sum() else members[~c]
        flip.append(minority)
    flip = np.sort(np.concatenate(flip)) if flip else np.zeros(0, dtype=np.int64)
    flip = np.setdiff1d(flip, non_orientable)
    return flip.astype(np.int64), non_orientable.astype(np.int64)


def rewind_faces(mesh: FaceMesh, faces) -> FaceMesh:
    """``mesh`` with the given polygons' vertex order reversed (v0 kept first: v0 v3 v2 v1).

    Keeping v0 first keeps a quad's fixed v0-v2 diagonal, so the triangulation has the same edges.
    """
    faces = np.asarray(faces, dtype=np.int64)
    if faces.size == 0:
        return mesh
    idx = mesh.face_vertex_indices.copy()
    uv_idx = None if mesh.uv_indices is None else mesh.uv_indices.copy()
    for f in faces.tolist():  # per flipped polygon (few): not the engine
        s, c = int(mesh.face_starts[f]), int(mesh.face_vertex_counts[f])
        sel = np.concatenate([[s], np.arange(s + c - 1, s, -1)])
        idx[s:s + c] = mesh.face_vertex_indices[sel]
        if uv_idx is not None:
            uv_idx[s:s + c] = mesh.uv_indices[sel]
    return dataclasses.replace(mesh, face_vertex_indices=idx, uv_indices=uv_idx)


def _tri_normals(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    p = points
    return np.cross(p[tris[:, 1]] - p[tris[:, 0]], p[tris[:, 2]] - p[tris[:, 0]])  # length = 2 area


def vertex_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Angle-weighted unit vertex normals.

    Parameters
    ----------
    points : ndarray (N, 3)
    triangles : ndarray (T, 3) int

    Returns
    -------
    ndarray (N, 3) float64
        Unit normals (zero for unreferenced vertices).
    """
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(triangles)
    fn = _tri_normals(p, t)
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    out = np.zeros_like(p)
    for c in range(3):
        e1 = p[t[:, (c + 1) % 3]] - p[t[:, c]]
        e2 = p[t[:, (c + 2) % 3]] - p[t[:, c]]
        cosang = np.einsum("ij,ij->i", e1, e2) / np.maximum(np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1), 1e-300)
        ang = np.arccos(np.clip(cosang, -1.0, 1.0))
        np.add.at(out, t[:, c], fn * ang[:, None])
    nrm = np.linalg.norm(out, axis=1, keepdims=True)
    return np.divide(out, nrm, out=np.zeros_like(out), where=nrm > 0)


def vertex_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(N,) lumped area per vertex (a third of each adjacent triangle's area)."""
    a = 0.5 * np.linalg.norm(_tri_normals(points, triangles), axis=1)
    return np.bincount(np.asarray(triangles).ravel(), weights=np.repeat(a / 3.0, 3), minlength=len(points))


def prepare_mesh(mesh: FaceMesh, *, orient: str = "fix") -> tuple[FaceMesh, np.ndarray]:
    """Check a mesh for the tissue model: no zero-area faces, consistent outward winding.

    Parameters
    ----------
    mesh : FaceMesh
    orient : {"fix", "error"}
        What to do with inconsistently wound polygons.

    Returns
    -------
    mesh : FaceMesh
        Consistently wound, normals pointing away from the mesh's interior (for a face mask:
        toward the viewer).
    flipped : ndarray (K,) int64
        Polygons re-wound (input numbering; all of them when the whole mesh was inside out).

    Raises
    ------
    MeshError
        Zero-area faces, non-manifold edges, a non-orientable patch, or (orient="error")
        inconsistent winding — each naming the faces.
    """
    mesh.check_degenerate()
    tris = mesh.triangles()
    a2 = np.linalg.norm(_tri_normals(mesh.points, tris), axis=1)
    scale = np.ptp(mesh.points, axis=0).max() ** 2
    bad_tri = np.flatnonzero(a2 <= 1e-12 * scale)
    if bad_tri.size:  # a polygon with area but a degenerate fan triangle (e.g. a folded quad)
        faces = np.unique(mesh.triangle_faces()[bad_tri])
        raise MeshError(f"mesh {_mesh_where(mesh)}: {faces.size} face(s) have a zero-area triangle in their fixed "
                        f"v0-v2 split, e.g. faces {faces[:10].tolist()}; the tissue model needs a prism per triangle")
    flip, non_orientable = inconsistent_faces(mesh)
    if non_orientable.size:
        raise MeshError(f"mesh {_mesh_where(mesh)}: {non_orientable.size} face(s) form a non-orientable patch, "
                        f"e.g. faces {non_orientable[:10].tolist()}")
    if flip.size:
        if orient == "error":
            raise MeshError(f"mesh {_mesh_where(mesh)}: {flip.size} face(s) are wound against their neighbours "
                            f"(inconsistent normals): faces {list_names(flip.tolist(), 20)}")
        log.warning("mesh %s: re-wound %d face(s) with inconsistent normals: %s", _mesh_where(mesh), flip.size,
                    list_names(flip.tolist(), 20))
        mesh = rewind_faces(mesh, flip)
    # global orientation: normals should point away from the interior (centroid behind a face mask)
    tris = mesh.triangles()
    fn = _tri_normals(mesh.points, tris)
    centre = mesh.points[np.unique(tris)].mean(axis=0)
    tc = mesh.points[tris].mean(axis=1)
    if np.einsum("ij,ij->", fn, tc - centre) < 0:
        log.warning("mesh %s: faces are wound inward; re-winding all of them", _mesh_where(mesh))
        allf = np.arange(mesh.n_faces)
        mesh = rewind_faces(mesh, allf)
        flip = np.setdiff1d(allf, flip)
    return mesh, flip


# -- construction ---------------------------------------------------------------------------------

def triangle_edges(triangles: np.ndarray, n_points: int) -> np.ndarray:
    """(E, 2) unique undirected edges (a < b) of a triangle list."""
    t = np.asarray(triangles, dtype=np.int64)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    e.sort(axis=1)
    key = np.unique(e[:, 0] * np.int64(n_points) + e[:, 1])
    return np.stack([key // n_points, key % n_points], axis=1)


def prism_volumes(x: np.ndarray, prisms: np.ndarray) -> np.ndarray:
    """Signed volume of triangular prisms, split into three tetrahedra.

    Parameters
    ----------
    x : ndarray (n, 3)
        Node positions.
    prisms : ndarray (P, 6) int
        Top triangle ``a b c`` (outward, counter-clockwise seen from outside) and the nodes
        ``a' b' c'`` below them.

    Returns
    -------
    ndarray (P,)
        ``V = V(a,b,c,a') + V(b,c,a',b') + V(c,a',b',c')`` with the sign chosen so that a
        prism whose bottom lies below its outward top has positive volume.
    """
    p = [x[prisms[:, k]] for k in range(6)]
    return -(_tet(p[0], p[1], p[2], p[3]) + _tet(p[1], p[2], p[3], p[4]) + _tet(p[2], p[3], p[4], p[5]))


def _tet(a, b, c, d):
    return np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) / 6.0


def prisms_valid(x: np.ndarray, prisms: np.ndarray) -> np.ndarray:
    """(P,) bool: prism has positive volume and its bottom triangle is not flipped against its top."""
    top = _tri_normals(x, prisms[:, :3])
    bottom = _tri_normals(x, prisms[:, 3:])
    return (prism_volumes(x, prisms) > 0) & (np.einsum("ij,ij->i", top, bottom) > 0)


def _tets_signed(x, prisms):
    p = [x[prisms[:, k]] for k in range(6)]
    return np.stack([-_tet(p[0], p[1], p[2], p[3]), -_tet(p[1], p[2], p[3], p[4]), -_tet(p[2], p[3], p[4], p[5])], 1)


def _sphere_centre(points: np.ndarray) -> np.ndarray:
    """Least-squares sphere through the points (the skull's rough centre for a face)."""
    a = np.c_[2.0 * points, np.ones(len(points))]
    sol = np.linalg.lstsq(a, (points ** 2).sum(axis=1), rcond=None)[0]
    return sol[:3]


def _keep_in_cone(d: np.ndarray, nrm: np.ndarray, min_cos: float) -> np.ndarray:
    """Unit directions turned toward ``nrm`` until their cosine with it is at least ``min_cos``."""
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    c = np.einsum("ij,ij->i", d, nrm)
    low = c < min_cos
    if low.any():
        tang = d[low] - c[low, None] * nrm[low]
        tn = np.linalg.norm(tang, axis=1, keepdims=True)
        tang = np.divide(tang, tn, out=np.zeros_like(tang), where=tn > 1e-12)
        s = np.sqrt(1.0 - min_cos ** 2)
        d[low] = min_cos * nrm[low] + s * tang
    return d


def _offset_field(mesh, pts, tris, edges, nrm, used, prisms, d_f, d_b, min_fraction, max_inverted):
    """Directions and per-vertex depth scales giving non-inverted prisms.

    Start from the vertex normal smoothed over the surface, blended half-and-half with the direction
    toward the best-fit sphere's centre (offset rays then cannot cross under the surface); where a
    prism is still inverted (lip and eyelid rims rolled into the holes), turn its vertices' directions
    toward their own normals and shrink their depth, down to ``min_fraction`` of the request.
    """
    n = len(pts)
    adj = sp.coo_matrix((np.ones(2 * len(edges)), (np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]])),
                        shape=(n, n)).tocsr()
    smooth = nrm.copy()
    for _ in range(20):
        smooth = smooth + adj @ smooth
        smooth /= np.maximum(np.linalg.norm(smooth, axis=1, keepdims=True), 1e-300)
    centre = _sphere_centre(pts[used])
    radial = pts - centre
    radial /= np.maximum(np.linalg.norm(radial, axis=1, keepdims=True), 1e-300)
    direction = _keep_in_cone(smooth + radial, nrm, 0.5)
    direction[~used] = 0.0
    depth = np.ones(n)
    t = len(tris)
    deg = np.asarray(adj.sum(axis=1)).ravel()
    for it in range(200):
        rest = np.concatenate([pts, pts - (d_f * depth)[:, None] * direction,
                               pts - ((d_f + d_b) * depth)[:, None] * direction])
        bad = np.flatnonzero(~prisms_valid(rest, prisms))
        if bad.size == 0:
            return direction, depth, np.zeros(0, dtype=np.int64)
        verts = np.unique(tris[bad % t].ravel())
        if depth[verts].min() <= min_fraction + 1e-12:
            faces = np.unique(mesh.triangle_faces()[bad % t])
            if faces.size > max_inverted * mesh.n_faces:
                raise MeshError(
                    f"mesh {_mesh_where(mesh)}: {faces.size} face(s) give inverted tissue prisms even at "
                    f"{min_fraction:.0%} of the depth (folded or very sharply curved), e.g. faces "
                    f"{faces[:10].tolist()}; smooth the mesh there or lower fascia_depth/bone_depth")
            log.info("mesh %s: %d face(s) are folded (their tissue prisms are inverted at rest; they keep "
                     "that shape): %s", _mesh_where(mesh), faces.size, list_names(faces.tolist(), 20))
            return direction, depth, faces
        # smooth the directions around the bad prisms (shear comes from diverging directions) ...
        nb = direction + (adj @ direction) / np.maximum(deg, 1)[:, None]
        nb = _keep_in_cone(nb, nrm, 0.5)
        direction[verts] = nb[verts]
        # ... and thin the tissue there, smoothly (a depth step also shears prisms)
        depth[verts] = np.maximum(depth[verts] * 0.9, min_fraction)
        depth = np.minimum(depth, 0.5 * (depth + (adj @ depth) / np.maximum(deg, 1)) + 0.5 * depth)
    raise MeshError(f"mesh {_mesh_where(mesh)}: could not build non-inverted tissue prisms")


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
        log.info("mesh %s: %d vertices belong to no face; they stay still", _mesh_where(mesh), int((~used).sum()))
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
    direction, depth, folded = _offset_field(mesh, pts, tris, e, nrm, used, prisms, d_f, d_b,
                                             opts.min_depth_fraction, opts.max_folded_fraction)
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
