"""Image landmarks onto a stereo scan: each landmark clicked or fitted on the first image of the
pair takes the depth the scan has at that pixel, seen through the camera the scan was made from
(seed 001, section 4.2: the registration's landmark correspondences)."""
from __future__ import annotations

import numpy as np

from ..errors import InputError, list_names

__all__ = ["lift_image_landmarks"]


def lift_image_landmarks(image_points: dict, scan_points, scan_triangles, camera: dict, *, radius: int = 2,
                         scan_source: str = "scan") -> dict:
    """Image landmarks -> 3-D scan points through the scan's depth seen by its camera.

    The scan mesh is rendered (z-buffer, exact ray intersection) from the first rectified camera it
    was made from; each landmark takes the depth interpolated at its sub-pixel position, or, next
    to a hole (eye corners and lip lines often are), the depth of the nearest surface pixel within
    ``radius`` pixels.

    Parameters
    ----------
    image_points : dict
        ``{name: (u, v)}`` pixels on the first image (OpenCV convention); on the original image
        when the camera records a rectification.
    scan_points : ndarray, shape (N, 3)
        Scan vertices (scan frame: x right, y up, z toward the camera; calibration units).
    scan_triangles : ndarray, shape (T, 3), int
    camera : dict
        The scan's camera (:func:`usdface.scan.calibration.scan_camera_dict`): ``f``, ``cx``,
        ``cy`` (pixels), ``width``, ``height``, optionally ``rectification``.
    radius : int
        Pixels searched around a landmark that falls on a hole.
    scan_source : str
        How messages name the scan.

    Returns
    -------
    dict
        ``{name: ndarray (3,)}`` scan points (scan frame and units).

    Raises
    ------
    InputError
        A landmark is outside the image or has no scan surface around it (a hole).
    """
    from .render import PinholeCamera, _raycast
    from .surface import scan_to_camera

    w, h = int(camera["width"]), int(camera["height"])
    names = list(image_points)
    uv = np.array([image_points[n] for n in names], dtype=np.float64).reshape(-1, 2)
    rc = camera.get("rectification")
    if rc:
        from .calibration import rectify_image_points

        uv = rectify_image_points(uv, rc["K1"], rc["D1"], rc["R1"], rc["P1"])
    outside = [f"{n} ({u:.1f}, {v:.1f})" for n, (u, v) in zip(names, uv)
               if not (-0.5 <= u <= w - 0.5 and -0.5 <= v <= h - 0.5)]
    if outside:
        raise InputError(f"landmarks outside the {w}x{h} image of {scan_source}: {list_names(outside)}")
    K = np.array([[camera["f"], 0, camera["cx"]], [0, camera["f"], camera["cy"]], [0, 0, 1.0]])
    cam = PinholeCamera(K=K, R=np.diag([1.0, -1.0, -1.0]), t=np.zeros(3), size=(w, h))
    _, _, depth = _raycast(np.asarray(scan_points, dtype=np.float64), np.asarray(scan_triangles, dtype=np.int64), cam)
    out, holes = {}, []
    for n, (u, v) in zip(names, uv):
        zc = _depth_at(depth, u, v, radius)
        if zc is None:
            holes.append(f"{n} ({u:.1f}, {v:.1f})")
            continue
        pc = np.array([(u - camera["cx"]) * zc / camera["f"], (v - camera["cy"]) * zc / camera["f"], zc])
        out[n] = scan_to_camera(pc[None])[0]
    if holes:
        raise InputError(f"{len(holes)} landmark(s) fall on holes of {scan_source} (no surface within {radius} px): "
                         f"{list_names(holes)}; move them onto the surface or give them as scan points")
    return out


def _depth_at(depth, u, v, radius):
    """Depth at a sub-pixel position: bilinear between the 4 pixel centres around it when all are
    on the surface, else the valid pixel nearest to it within ``radius`` (None: a hole)."""
    h, w = depth.shape
    j0, i0 = int(np.floor(u)), int(np.floor(v))
    if 0 <= i0 < h - 1 and 0 <= j0 < w - 1:
        q = depth[i0:i0 + 2, j0:j0 + 2]
        if np.isfinite(q).all():
            a, b = u - j0, v - i0
            return float(q[0, 0] * (1 - a) * (1 - b) + q[0, 1] * a * (1 - b) + q[1, 0] * (1 - a) * b + q[1, 1] * a * b)
    best = None
    for i in range(max(0, int(round(v)) - radius), min(h, int(round(v)) + radius + 1)):
        for j in range(max(0, int(round(u)) - radius), min(w, int(round(u)) + radius + 1)):
            if np.isfinite(depth[i, j]):
                d2 = (i - v) ** 2 + (j - u) ** 2
                if best is None or d2 < best[0]:
                    best = (d2, float(depth[i, j]))
    return None if best is None else best[1]
