"""Points projected onto a face mesh's surface: the triangle and polygon holding each, its
barycentric weights and the polygon's nearest vertex (what a marker binding records)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import OptionError
from ..model.mesh import FaceMesh
from .closest import SurfaceLocator

__all__ = ["SurfacePoints", "locator_for", "project_to_surface"]


@dataclass(frozen=True)
class SurfacePoints:
    """Points projected onto a mesh surface.

    Attributes
    ----------
    face_indices : ndarray, shape (M,), int64
        Polygon holding each projected point.
    triangle_vertices : ndarray, shape (M, 3), int64
        Vertices of the triangle (of :meth:`FaceMesh.triangles`) holding it.
    barycentrics : ndarray, shape (M, 3), float64
        Barycentric weights in that triangle.
    nearest_vertices : ndarray, shape (M,), int64
        Vertex of the holding polygon nearest to the projected point.
    points : ndarray, shape (M, 3), float64
        The projected points (mesh units).
    distances : ndarray, shape (M,), float64
        Distance from each input point to its projection (mesh units).
    """

    face_indices: np.ndarray
    triangle_vertices: np.ndarray
    barycentrics: np.ndarray
    nearest_vertices: np.ndarray
    points: np.ndarray
    distances: np.ndarray


def locator_for(mesh: FaceMesh, locator: SurfaceLocator | None) -> SurfaceLocator:
    if locator is None:
        return SurfaceLocator(mesh.points, mesh.triangles())
    if locator.triangles.shape != mesh.triangles().shape or locator.points.shape != mesh.points.shape:
        raise OptionError("locator was built for another mesh (triangle count differs)")
    return locator


def project_to_surface(mesh: FaceMesh, points, *, locator: SurfaceLocator | None = None) -> SurfacePoints:
    """Project points onto the closest point of the mesh surface.

    Parameters
    ----------
    mesh : FaceMesh
    points : ndarray, shape (M, 3)
        Points in the mesh's space and units.
    locator : SurfaceLocator, optional
        Reuse a locator built on ``mesh.points`` and ``mesh.triangles()``.

    Returns
    -------
    SurfacePoints
    """
    loc = locator_for(mesh, locator)
    tri, bary, cp, dist = loc.closest(np.asarray(points, dtype=np.float64).reshape(-1, 3))
    tv = loc.triangles[tri]
    faces = mesh.triangle_faces()[tri]
    # nearest vertex among the holding polygon's vertices
    counts, starts, idx = mesh.face_vertex_counts, mesh.face_starts, mesh.face_vertex_indices
    width = int(counts[faces].max()) if faces.size else 3
    k = np.arange(width)
    cols = starts[faces][:, None] + np.minimum(k[None, :], counts[faces][:, None] - 1)
    cand = idx[cols]  # (M, width), short polygons repeat their last vertex
    d2 = np.sum((mesh.points[cand] - cp[:, None, :]) ** 2, axis=2)
    nearest = cand[np.arange(cand.shape[0]), np.argmin(d2, axis=1)]
    return SurfacePoints(faces, tv, bary, nearest, cp, dist)
