"""The left-right symmetry of a marker cloud or face, and the small rotations that align one.

:func:`mirror_plane` finds a cloud's mirror plane without correspondences; the rotation helpers
build the start rotations and plane alignments the automatic binding
(:mod:`usdface.mesh.auto_binding`) tries.
"""
from __future__ import annotations

import numpy as np

from ..capture.rigid import fit_rigid

__all__ = ["mirror_plane", "rotation_about_x", "rotation_about_y", "rotation_between", "rotation_from_vector"]


def rotation_about_x(deg: float) -> np.ndarray:
    """(3, 3) rotation by ``deg`` degrees about X."""
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rotation_about_y(deg: float) -> np.ndarray:
    """(3, 3) rotation by ``deg`` degrees about Y."""
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_from_vector(w: np.ndarray) -> np.ndarray:
    """(3, 3) rotation by ``|w|`` radians about the axis ``w`` (3,) (Rodrigues' formula)."""
    th = float(np.linalg.norm(w))
    if th < 1e-15:
        return np.eye(3)
    k = w / th
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(th) * kx + (1.0 - np.cos(th)) * kx @ kx


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotation taking unit vector a to unit vector b."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else rotation_from_vector(np.pi * _any_perpendicular(a))
    return rotation_from_vector(v / np.linalg.norm(v) * np.arctan2(np.linalg.norm(v), c))


def _any_perpendicular(a: np.ndarray) -> np.ndarray:
    v = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    return v / np.linalg.norm(v)


def mirror_plane(cloud, *, normal=(1.0, 0.0, 0.0), iterations: int = 30):
    """Estimate the left-right symmetry plane of a point cloud without correspondences.

    Reflects the cloud in the current plane, matches each reflected point to its nearest original
    point, fits the rigid motion taking the reflection onto the matches (robustly weighted), and
    reads the improved plane off the resulting improper isometry; repeats until stable.

    Parameters
    ----------
    cloud : ndarray, shape (M, 3)
    normal : sequence of 3 float
        Initial plane normal (default +X, the lateral axis of a face looking toward +Z).
    iterations : int

    Returns
    -------
    normal : ndarray, shape (3,)
        Unit normal, sign chosen along the initial ``normal``.
    point : ndarray, shape (3,)
        A point on the plane.
    residual : float
        Median distance from a reflected point to its nearest original point (cloud units): small
        (a few % of the cloud size) for a symmetric cloud.
    """
    from scipy.spatial import cKDTree

    x = np.asarray(cloud, dtype=np.float64)
    n0 = np.asarray(normal, dtype=np.float64)
    n = n0 / np.linalg.norm(n0)
    c = x.mean(axis=0)
    tree = cKDTree(x)
    res = np.inf
    for _ in range(iterations):
        refl = x - 2.0 * ((x - c) @ n)[:, None] * n
        d, j = tree.query(refl)
        sigma = max(2.5 * float(np.median(d)), 1e-9)
        w = 1.0 / (1.0 + (d / sigma) ** 2)
        rot, _, t = fit_rigid(refl, x[j], weights=w)
        # composite x -> rot (x - 2((x - c).n) n) + t = A x + b, A = rot (I - 2 n n^T)
        a = rot @ (np.eye(3) - 2.0 * np.outer(n, n))
        b = rot @ (2.0 * np.dot(c, n) * n) + t
        _, evecs = np.linalg.eigh(0.5 * (a + a.T))
        n_new = evecs[:, 0]
        if np.dot(n_new, n0) < 0:
            n_new = -n_new
        c_new = 0.5 * (x.mean(axis=0) + (a @ x.mean(axis=0) + b))
        moved = float(np.linalg.norm(n_new - n)) + float(abs(np.dot(c_new - c, n_new)))
        n, c = n_new, c_new
        res = float(np.median(d))
        if moved < 1e-10:
            break
    refl = x - 2.0 * ((x - c) @ n)[:, None] * n
    res = float(np.median(tree.query(refl)[0]))
    return n, c, res
