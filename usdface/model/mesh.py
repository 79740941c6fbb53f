"""In-memory face mesh, face regions and marker bindings.

Polygons are kept as USD keeps them (faceVertexCounts + faceVertexIndices), so quads stay quads;
:meth:`FaceMesh.triangles` gives a fixed fan triangulation for every computation that needs
triangles (closest points, geodesics, tissue prisms).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..errors import MeshError

#: largest coordinate a mesh may have: USD stores points as float32
FLOAT32_MAX = float(np.finfo(np.float32).max)
#: a vertex this many times farther from the mesh's centre than the median vertex is a corrupt coordinate
FAR_VERTEX_RATIO = 1000.0

#: region roles understood by usdface (the face-region schema's allowedTokens)
REGION_ROLES = ("outerBorder", "mouth", "eye", "geodesic", "pinned", "rigid", "other")


@dataclass(frozen=True, eq=False)
class FaceMesh:
    """A polygon mesh.

    Attributes
    ----------
    points : ndarray, shape (N, 3), float64
        Vertex positions in ``units``.
    face_vertex_counts : ndarray, shape (P,), int64
        Vertices per polygon (>= 3).
    face_vertex_indices : ndarray, shape (sum(face_vertex_counts),), int64
        Polygon vertex indices, concatenated.
    units : str or None
        Linear unit of the points, None when unknown.
    uvs : ndarray, shape (K, 2), float64, optional
        Texture coordinates, faceVarying: indexed by ``uv_indices``.
    uv_indices : ndarray, shape (sum(face_vertex_counts),), int64, optional
        Per face-vertex index into ``uvs``.
    name : str
        A short name (the source file's stem), for messages and default prim names.
    source : str
        The file the mesh came from.
    """

    points: np.ndarray
    face_vertex_counts: np.ndarray
    face_vertex_indices: np.ndarray
    units: str | None = None
    uvs: np.ndarray | None = None
    uv_indices: np.ndarray | None = None
    name: str = "Face"
    source: str = ""

    def __post_init__(self) -> None:
        pts = np.asarray(self.points, dtype=np.float64)
        counts = np.asarray(self.face_vertex_counts, dtype=np.int64).ravel()
        idx = np.asarray(self.face_vertex_indices, dtype=np.int64).ravel()
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "face_vertex_counts", counts)
        object.__setattr__(self, "face_vertex_indices", idx)
        where = f" {self.source}" if self.source else f" {self.name!r}"
        if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] == 0:
            raise MeshError(f"mesh{where}: points must have shape (N>0, 3); got {pts.shape}")
        if not np.isfinite(pts).all():
            raise MeshError(f"mesh{where}: {int((~np.isfinite(pts)).any(axis=1).sum())} vertices are NaN or infinite")
        beyond = np.abs(pts) > FLOAT32_MAX
        if beyond.any():
            i = int(np.flatnonzero(beyond.any(axis=1))[0])
            raise MeshError(f"mesh{where}: vertex {i} at ({', '.join(f'{x:.6g}' for x in pts[i])}) is beyond the range "
                            f"of the float32 coordinates USD stores (|x| <= {FLOAT32_MAX:.4g}); "
                            f"{int(beyond.any(axis=1).sum())} such vertices in all: a corrupt coordinate")
        if counts.size == 0:
            raise MeshError(f"mesh{where} has no faces")
        if (counts < 3).any():
            bad = np.flatnonzero(counts < 3)[:10].tolist()
            raise MeshError(f"mesh{where}: faces {bad} have fewer than 3 vertices")
        if counts.sum() != idx.size:
            raise MeshError(f"mesh{where}: faceVertexCounts sum to {counts.sum()} but there are {idx.size} indices")
        if idx.size and (idx.min() < 0 or idx.max() >= pts.shape[0]):
            raise MeshError(f"mesh{where}: face vertex indices outside 0..{pts.shape[0] - 1}")
        if self.uvs is not None:
            object.__setattr__(self, "uvs", np.asarray(self.uvs, dtype=np.float64))
            object.__setattr__(self, "uv_indices", np.asarray(self.uv_indices, dtype=np.int64).ravel())

    @property
    def n_points(self) -> int:
        return self.points.shape[0]

    @property
    def n_faces(self) -> int:
        return self.face_vertex_counts.size

    @cached_property
    def face_starts(self) -> np.ndarray:
        """(P,) offset of each polygon's first index in face_vertex_indices."""
        return np.concatenate([[0], np.cumsum(self.face_vertex_counts)[:-1]])

    @cached_property
    def _triangulation(self) -> tuple[np.ndarray, np.ndarray]:
        counts, starts, idx = self.face_vertex_counts, self.face_starts, self.face_vertex_indices
        ntri = counts - 2
        tri_face = np.repeat(np.arange(counts.size), ntri)
        # fan k of polygon p: (v0, v_{k+1}, v_{k+2}); quads split along the fixed diagonal v0-v2
        k = np.arange(tri_face.size) - np.repeat(np.cumsum(ntri) - ntri, ntri)
        s = starts[tri_face]
        tris = np.stack([idx[s], idx[s + k + 1], idx[s + k + 2]], axis=1)
        return tris, tri_face

    def triangles(self) -> np.ndarray:
        """(T, 3) int64 fan triangulation of every polygon (quad v0 v1 v2 v3 -> v0 v1 v2, v0 v2 v3)."""
        return self._triangulation[0]

    def triangle_faces(self) -> np.ndarray:
        """(T,) int64 polygon index of each triangle of :meth:`triangles`."""
        return self._triangulation[1]

    def with_points(self, points: np.ndarray) -> "FaceMesh":
        """The same topology with other points."""
        return dataclasses.replace(self, points=points)

    def check_degenerate(self, *, rel_area: float = 1e-12) -> None:
        """Raise MeshError naming polygons with (near) zero area."""
        tris = self.triangles()
        p = self.points
        area2 = np.linalg.norm(np.cross(p[tris[:, 1]] - p[tris[:, 0]], p[tris[:, 2]] - p[tris[:, 0]]), axis=1)
        face_area = np.bincount(self.triangle_faces(), weights=area2, minlength=self.n_faces)
        scale = np.ptp(p, axis=0).max() ** 2
        bad = np.flatnonzero(face_area <= rel_area * scale)
        if bad.size:
            where = f" {self.source}" if self.source else f" {self.name!r}"
            far, ratio = self.far_vertices()
            if far.size:  # one wild coordinate shrinks every face relative to the bounding box
                i = int(far[0])
                raise MeshError(f"mesh{where}: vertex {i} at ({', '.join(f'{x:.6g}' for x in p[i])}) is {ratio[0]:.3g} "
                                f"times farther from the mesh's centre than its median vertex ({far.size} such "
                                f"vertices): a corrupt coordinate, which makes {bad.size} faces look degenerate")
            raise MeshError(f"mesh{where}: {bad.size} degenerate (zero-area) face(s), e.g. faces {bad[:10].tolist()}")

    def far_vertices(self, *, ratio: float = FAR_VERTEX_RATIO) -> tuple[np.ndarray, np.ndarray]:
        """Vertices more than ``ratio`` times farther from the median point than the median vertex.

        Returns
        -------
        indices : ndarray, shape (K,), int64
            Such vertices, farthest first.
        ratios : ndarray, shape (K,), float64
            Their distance over the median distance.
        """
        p = self.points
        centre = np.median(p, axis=0)
        r = np.linalg.norm(p - centre, axis=1)
        typical = float(np.median(r))
        if not typical > 0:
            return np.zeros(0, np.int64), np.zeros(0)
        far = np.flatnonzero(r > ratio * typical)
        order = far[np.argsort(-r[far], kind="stable")]
        return order.astype(np.int64), r[order] / typical


@dataclass(frozen=True)
class Region:
    """A named set of vertices with a role (face-region schema instance).

    Attributes
    ----------
    name : str
        Instance name, a valid USD identifier (``mouth``, ``leftEye``, ``outerBorder``...).
    role : str
        One of :data:`REGION_ROLES`.
    indices : ndarray, shape (K,), int64
        Member vertex indices, sorted, unique.
    loop : ndarray, shape (L,), int64, optional
        For hole regions, the ordered boundary loop (vertex indices).
    """

    name: str
    role: str
    indices: np.ndarray
    loop: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.role not in REGION_ROLES:
            raise MeshError(f"region {self.name!r}: role {self.role!r} is not one of {', '.join(REGION_ROLES)}")
        object.__setattr__(self, "indices", np.unique(np.asarray(self.indices, dtype=np.int64)))
        if self.loop is not None:
            object.__setattr__(self, "loop", np.asarray(self.loop, dtype=np.int64))


@dataclass(frozen=True)
class Binding:
    """Markers bound to points on a mesh surface.

    Attributes
    ----------
    names : tuple of str, length M
        Marker names, in the capture's order.
    face_indices : ndarray, shape (M,), int64
        Polygon index holding each bound point.
    triangle_vertices : ndarray, shape (M, 3), int64
        Vertices of the triangle (of :meth:`FaceMesh.triangles`) holding each bound point.
    barycentrics : ndarray, shape (M, 3), float64
        Barycentric weights of the bound point in that triangle (sum to 1).
    nearest_vertices : ndarray, shape (M,), int64
        Mesh vertex nearest to each bound point.
    residuals : ndarray, shape (M,), float64
        Distance (mesh units) from the aligned marker (or layout point) to its bound point.
    retarget : str
        ``"displacement"`` (capture displacement rotated into the mesh frame, not scaled: the paper)
        or ``"similarity"`` (also scaled by the fitted similarity).
    capture_to_mesh : ndarray, shape (4, 4), float64
        Similarity transform (rotation, uniform scale, translation; column vectors) taking neutral
        capture positions, in capture units, to mesh space; includes the unit conversion.
    unit_scale : float
        Capture units to mesh units factor (1.0 when both are the same or unknown). With
        ``retarget="displacement"`` a capture displacement d becomes ``unit_scale * R @ d``;
        with ``"similarity"`` it becomes ``s * R @ d`` where (R, s) = :attr:`capture_rotation_scale`.
    method : str
        ``"layout"`` or ``"auto"``.
    """

    names: tuple[str, ...]
    face_indices: np.ndarray
    triangle_vertices: np.ndarray
    barycentrics: np.ndarray
    nearest_vertices: np.ndarray
    residuals: np.ndarray
    retarget: str = "displacement"
    capture_to_mesh: np.ndarray = field(default_factory=lambda: np.eye(4))
    unit_scale: float = 1.0
    method: str = "layout"

    def __post_init__(self) -> None:
        object.__setattr__(self, "names", tuple(self.names))
        for name, dtype in (("face_indices", np.int64), ("triangle_vertices", np.int64),
                            ("barycentrics", np.float64), ("nearest_vertices", np.int64),
                            ("residuals", np.float64), ("capture_to_mesh", np.float64)):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=dtype))
        if self.retarget not in ("displacement", "similarity"):
            raise MeshError(f"binding retarget must be 'displacement' or 'similarity'; got {self.retarget!r}")

    @property
    def n_markers(self) -> int:
        return len(self.names)

    def surface_points(self, points: np.ndarray) -> np.ndarray:
        """(M, 3) bound surface points evaluated on vertex positions ``points`` (N, 3)."""
        return np.einsum("mk,mkd->md", self.barycentrics, np.asarray(points)[self.triangle_vertices])

    def displacement_transform(self) -> np.ndarray:
        """(3, 3) matrix taking a capture displacement (capture units) to a mesh displacement."""
        rot, s = self.capture_rotation_scale
        return rot * (s if self.retarget == "similarity" else self.unit_scale)

    @property
    def capture_rotation_scale(self) -> tuple[np.ndarray, float]:
        """(R (3, 3), s): rotation and uniform scale of :attr:`capture_to_mesh`."""
        a = self.capture_to_mesh[:3, :3]
        s = float(np.cbrt(np.linalg.det(a)))
        return a / s, s
