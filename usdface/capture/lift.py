"""Lifting 2D image tracks of face markers to 3D motion on a character mesh.

Given tracked image points (pixels, y down or up: the fit absorbs it) of markers whose places on
the character mesh are known (a layout or a binding: the bound surface points b_j), and a neutral
frame where the face is at rest:

1. **Camera.** A weak-perspective (scaled orthographic) camera ``u = s R2 b + c`` (R2: two
   orthonormal rows, s pixels per mesh unit, c pixels) is fitted to the neutral tracks against the
   bound points: a least-squares affine camera first, then its 2 x 3 linear part is replaced by the
   nearest scaled rotation (SVD, s the mean singular value) and c refitted. The residual (pixels)
   says how well a rigid view explains the layout; the view direction is ``r3 = r1 x r2``.
2. **In-plane motion.** A marker's image displacement ``du = u_f - u_neutral`` maps to the mesh
   displacement in the image plane ``d = R2^T du / s`` (mesh units).
3. **Depth** (``depth=``): one image cannot see motion along the view direction.
   - ``"zero"`` (default): no depth change (``d' = d``).
   - ``"tangent"``: the marker slides on the skin: move d along the view direction onto
     the tangent plane at the bound point, ``d' = d - (n.d / n.r3) r3`` (n the surface normal),
     which projects to the same image displacement. Where the surface is seen at a grazing angle
     (``|n.r3| < min_cos``, default 0.5, 60 degrees from the view) ``n.r3`` is clamped to ``min_cos`` to bound the depth
     step.

   Measured on the real AnimFace Jaw take projected by a front camera onto the MakeHuman face:
   the in-plane motion is recovered exactly (1e-5 cm, float rounding); the depth motion is large
   in that take (rms 0.34 cm of a 0.49 cm rms marker displacement) and neither mode recovers it:
   marker rms error 0.340 cm (zero) and 0.339 cm (tangent), largest 3.2 cm and 2.7 cm; the
   transferred face: mean vertex error 0.109 cm (zero) and 0.120 cm (tangent), largest 3.6 cm and
   3.0 cm. ``zero`` is the default (no risk of amplifying tracking noise into depth).

The result is the markers' 3D positions in mesh space and units, ``b_j + d'_j(f)`` (NaN where
the track is invalid): a capture the transfer can use (bind it with the same layout: the neutral
frame sits exactly on the bound points). Head motion in the video is not removed here: stabilise
the tracks first (or track a head-mounted camera's video).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ComputeError, MarkerError, OptionError, list_names

DEPTH_MODES = ("tangent", "zero")
DEFAULT_MIN_COS = 0.5


@dataclass(frozen=True)
class WeakPerspectiveCamera:
    """``u = scale * rows @ X + offset`` (pixels from mesh-space points).

    Attributes
    ----------
    rows : ndarray (2, 3), orthonormal rows (image x and y axes in mesh space)
    scale : float, pixels per mesh unit
    offset : ndarray (2,), pixels
    residual_rms, residual_max : float, pixels, of the fit at the neutral frame
    """

    rows: np.ndarray
    scale: float
    offset: np.ndarray
    residual_rms: float = 0.0
    residual_max: float = 0.0

    @property
    def view_direction(self) -> np.ndarray:
        """(3,) unit vector along the view (``r1 x r2``; the sign follows the image axes)."""
        return np.cross(self.rows[0], self.rows[1])

    def project(self, points) -> np.ndarray:
        """(..., 2) pixels of mesh-space points (..., 3)."""
        return self.scale * np.asarray(points, dtype=np.float64) @ self.rows.T + self.offset

    def unproject_displacement(self, du) -> np.ndarray:
        """(..., 3) in-plane mesh displacement of image displacements (..., 2)."""
        return np.asarray(du, dtype=np.float64) @ self.rows / self.scale


def fit_weak_perspective(image_points, model_points) -> WeakPerspectiveCamera:
    """Fit a weak-perspective camera to 2D-3D correspondences (module docstring, step 1).

    Parameters
    ----------
    image_points : array (M, 2), pixels
    model_points : array (M, 3), mesh units; M >= 4, not all on one line

    Raises
    ------
    ComputeError
        Fewer than 4 correspondences, or points that do not determine the camera.
    """
    u = np.asarray(image_points, dtype=np.float64)
    x = np.asarray(model_points, dtype=np.float64)
    if u.shape[0] < 4:
        raise ComputeError(f"lift: the camera fit needs at least 4 markers valid at the neutral frame; got {u.shape[0]}")
    xc = x - x.mean(axis=0)
    uc = u - u.mean(axis=0)
    sv = np.linalg.svd(xc, compute_uv=False)
    if sv[1] <= 1e-9 * max(sv[0], 1e-300):
        raise ComputeError("lift: the markers' bound points are (nearly) collinear; the camera is undetermined")
    lin, *_ = np.linalg.lstsq(xc, uc, rcond=None)  # (3, 2): uc ~ xc @ lin
    a = lin.T  # (2, 3)
    uu, ss, vt = np.linalg.svd(a, full_matrices=False)
    rows = uu @ vt
    scale = float(ss.mean())
    if not scale > 0:
        raise ComputeError("lift: the neutral tracks do not determine an image scale (all tracks at one point?)")
    offset = u.mean(axis=0) - scale * x.mean(axis=0) @ rows.T
    cam = WeakPerspectiveCamera(rows=rows, scale=scale, offset=offset)
    res = np.linalg.norm(cam.project(x) - u, axis=1)
    return WeakPerspectiveCamera(rows=rows, scale=scale, offset=offset,
                                 residual_rms=float(np.sqrt((res ** 2).mean())), residual_max=float(res.max()))


def surface_normals(points, triangles, triangle_vertices, barycentrics) -> np.ndarray:
    """(M, 3) unit normals at bound surface points: area-weighted vertex normals interpolated.

    Parameters
    ----------
    points : (N, 3); triangles : (T, 3) int; triangle_vertices : (M, 3) int; barycentrics : (M, 3)
    """
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    fn = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])  # area-weighted
    vn = np.zeros_like(p)
    for k in range(3):
        np.add.at(vn, t[:, k], fn)
    n = np.einsum("mk,mkd->md", np.asarray(barycentrics, dtype=np.float64), vn[np.asarray(triangle_vertices)])
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    norm[norm == 0] = 1.0
    return n / norm


def lift_displacements(tracks, neutral_frame: int, camera: WeakPerspectiveCamera, *, normals=None,
                       depth: str = "zero", min_cos: float = DEFAULT_MIN_COS) -> np.ndarray:
    """Mesh-space displacements (F, M, 3) of 2D tracks (F, M, 2) (module docstring, steps 2-3).

    NaN where a track is invalid. ``normals`` (M, 3) are needed for ``depth="tangent"``.
    """
    if depth not in DEPTH_MODES:
        raise OptionError(f"--depth: expected one of {', '.join(DEPTH_MODES)}; got {depth!r}")
    if not 0 < min_cos <= 1:
        raise OptionError(f"min_cos: expected a number in (0, 1]; got {min_cos!r}")
    u = np.asarray(tracks, dtype=np.float64)[..., :2]
    d = camera.unproject_displacement(u - u[neutral_frame][None])
    if depth == "zero":
        return d
    if normals is None:
        raise OptionError("lift: depth='tangent' needs the surface normals at the bound points")
    n = np.asarray(normals, dtype=np.float64)
    r3 = camera.view_direction
    c = n @ r3  # (M,)
    c = np.where(np.abs(c) < min_cos, np.where(c < 0, -min_cos, min_cos), c)
    alpha = -np.einsum("fmc,mc->fm", d, n) / c[None]
    return d + alpha[:, :, None] * r3


def check_marker_sets(track_names, layout_names, *, tracks: str = "tracks", layout: str = "layout") -> None:
    """MarkerError unless both sets hold the same markers (naming the differences)."""
    t, l_ = list(track_names), list(layout_names)
    only_t = [n for n in t if n not in set(l_)]
    only_l = [n for n in l_ if n not in set(t)]
    if only_t or only_l:
        parts = []
        if only_l:
            parts.append(f"{list_names(only_l)} in the {layout} but not in the {tracks}")
        if only_t:
            parts.append(f"{list_names(only_t)} in the {tracks} but not in the {layout}")
        raise MarkerError(f"lift: the track and layout marker sets differ: {'; '.join(parts)} "
                          f"({tracks}: {len(t)} markers, {layout}: {len(l_)})")
