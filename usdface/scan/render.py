"""A small textured, lit, z-buffered renderer for test data with exact ground truth.

No public face stereo pairs or annotated face sets can be used here, so usdface makes its own:
the sample face meshes rendered through pinhole cameras with a texture (the face photograph
mapped onto the mesh through its landmarks, and/or a procedural skin), Lambert lighting, and an
exact depth per pixel (the ray through the pixel centre intersected with the visible triangle).

Conventions (OpenCV's): camera x right, y down, z forward; ``K`` maps camera coordinates to
pixels, the centre of the top-left pixel is (0, 0); world-to-camera ``X_c = R X_w + t``.

The scan conversion is :func:`usdface.preview.raster.rasterize` (vectorised scanline, z-buffer);
this module adds exact per-pixel barycentrics and depth, texturing and shading.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import OptionError

__all__ = ["PinholeCamera", "RenderResult", "ViewStyle", "render_view", "skin_albedo", "value_noise", "cap_holes",
           "stereo_cameras", "photo_uv", "FaceTexture"]


@dataclass(frozen=True, eq=False)
class PinholeCamera:
    """A pinhole camera (OpenCV conventions).

    Attributes
    ----------
    K : ndarray, shape (3, 3)
        Intrinsics ``[[f, 0, cx], [0, f, cy], [0, 0, 1]]`` (pixels).
    R : ndarray, shape (3, 3)
        World-to-camera rotation.
    t : ndarray, shape (3,)
        World-to-camera translation (world units).
    size : (int, int)
        Image (width, height).
    """

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    size: tuple

    def __post_init__(self) -> None:
        object.__setattr__(self, "K", np.asarray(self.K, dtype=np.float64).reshape(3, 3))
        object.__setattr__(self, "R", np.asarray(self.R, dtype=np.float64).reshape(3, 3))
        object.__setattr__(self, "t", np.asarray(self.t, dtype=np.float64).reshape(3))
        object.__setattr__(self, "size", (int(self.size[0]), int(self.size[1])))

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world coordinates."""
        return -self.R.T @ self.t

    def to_camera(self, points) -> np.ndarray:
        return np.asarray(points, dtype=np.float64) @ self.R.T + self.t

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """(..., 3) world points -> (..., 2) pixels and (...,) depth z (world units)."""
        c = self.to_camera(points)
        z = c[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = c[..., 0] / z
            y = c[..., 1] / z
        u = self.K[0, 0] * x + self.K[0, 1] * y + self.K[0, 2]
        v = self.K[1, 1] * y + self.K[1, 2]
        return np.stack([u, v], axis=-1), z

    @classmethod
    def look_at(cls, eye, target, *, up=(0.0, 1.0, 0.0), f: float, size, principal=None) -> "PinholeCamera":
        """A camera at ``eye`` looking at ``target`` with world ``up`` appearing up in the image."""
        eye = np.asarray(eye, dtype=np.float64)
        fwd = np.asarray(target, dtype=np.float64) - eye
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, np.asarray(up, dtype=np.float64))
        if np.linalg.norm(right) < 1e-9:
            raise OptionError("look_at: up is parallel to the viewing direction")
        right /= np.linalg.norm(right)
        down = np.cross(fwd, right)
        R = np.stack([right, down, fwd])
        w, h = int(size[0]), int(size[1])
        cx, cy = ((w - 1) / 2.0, (h - 1) / 2.0) if principal is None else principal
        K = np.array([[f, 0, cx], [0, f, cy], [0, 0, 1.0]])
        return cls(K=K, R=R, t=-R @ eye, size=(w, h))

    def moved(self, offset_camera) -> "PinholeCamera":
        """The same camera translated by ``offset_camera`` expressed in its own axes."""
        return replace(self, t=self.t - np.asarray(offset_camera, dtype=np.float64))


def stereo_cameras(camera: PinholeCamera, baseline: float, *, vertical: bool = False):
    """A rectified stereo rig: ``camera`` and its copy moved by ``baseline`` to the right (or down).

    Returns
    -------
    first, second : PinholeCamera
    calibration : dict
        ``{"f", "cx", "cy", "baseline", "doffs": 0, "vertical"}`` (the rectified calibration JSON;
        ``baseline`` in world units).
    """
    off = np.array([0.0, baseline, 0.0]) if vertical else np.array([baseline, 0.0, 0.0])
    second = camera.moved(off)
    K = camera.K
    calib = {"f": float(K[0, 0]), "cx": float(K[0, 2]), "cy": float(K[1, 2]), "baseline": float(baseline),
             "doffs": 0.0, "vertical": bool(vertical)}
    return camera, second, calib


@dataclass(frozen=True, eq=False)
class RenderResult:
    """Output of :func:`render_view`.

    Attributes
    ----------
    image : ndarray, shape (H, W, 3), uint8
        BGR picture.
    depth : ndarray, shape (H, W), float64
        Camera z of the visible surface at each pixel centre (world units); NaN for background.
    triangle : ndarray, shape (H, W), int32
        Visible triangle, -1 for background.
    bary : ndarray, shape (H, W, 3), float64
        Barycentric weights of the visible point in that triangle.
    """

    image: np.ndarray
    depth: np.ndarray
    triangle: np.ndarray
    bary: np.ndarray

    @property
    def mask(self) -> np.ndarray:
        return self.triangle >= 0


def _raycast(points, triangles, camera: PinholeCamera):
    from ..preview.raster import rasterize

    w, h = camera.size
    xy, z = camera.project(points)
    with np.errstate(divide="ignore", invalid="ignore"):
        zkey = np.where(z > 0, -1.0 / z, np.nan)
    tri_img, _ = rasterize(xy + 0.5, zkey, triangles, (w, h))  # rasterize puts pixel centres at +0.5
    cov = tri_img >= 0
    ii, jj = np.nonzero(cov)
    t = tri_img[cov]
    # exact ray / triangle-plane intersection in camera coordinates (Moller-Trumbore)
    Kinv = np.linalg.inv(camera.K)
    d = np.stack([jj, ii, np.ones_like(jj)], axis=1).astype(np.float64) @ Kinv.T
    pc = camera.to_camera(points)
    a, b, c = pc[triangles[t, 0]], pc[triangles[t, 1]], pc[triangles[t, 2]]
    e1, e2 = b - a, c - a
    pvec = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pvec)
    det = np.where(np.abs(det) < 1e-15, 1e-15, det)
    tvec = -a
    u = np.einsum("ij,ij->i", tvec, pvec) / det
    qvec = np.cross(tvec, e1)
    v = np.einsum("ij,ij->i", d, qvec) / det
    s = np.einsum("ij,ij->i", e2, qvec) / det  # ray parameter: the point is s * d, depth = s (d_z = 1)
    bary = np.zeros((h, w, 3))
    bary[cov] = np.stack([1 - u - v, u, v], axis=1)
    depth = np.full((h, w), np.nan)
    depth[cov] = s
    return tri_img, bary, depth


def value_noise(positions, frequency: float, *, seed: int = 0) -> np.ndarray:
    """Smooth 3-D value noise in [0, 1] (trilinear interpolation of hashed lattice values).

    Parameters
    ----------
    positions : ndarray, shape (K, 3)
    frequency : float
        Lattice cells per world unit.
    """
    q = np.asarray(positions, dtype=np.float64) * frequency
    i0 = np.floor(q).astype(np.int64)
    f = q - i0
    u = f * f * (3.0 - 2.0 * f)
    out = np.zeros(q.shape[0])
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                ix, iy, iz = i0[:, 0] + dx, i0[:, 1] + dy, i0[:, 2] + dz
                hsh = (ix * 73856093) ^ (iy * 19349663) ^ (iz * 83492791) ^ (seed * 2654435761)
                hsh = (hsh ^ (hsh >> 13)) * 1274126177
                hsh = hsh ^ (hsh >> 16)
                val = (hsh & 0xFFFF).astype(np.float64) / 65535.0
                wgt = ((u[:, 0] if dx else 1 - u[:, 0]) * (u[:, 1] if dy else 1 - u[:, 1])
                       * (u[:, 2] if dz else 1 - u[:, 2]))
                out += wgt * val
    return out


def skin_albedo(positions, *, unit_per_cm: float = 1.0, seed: int = 0, tone=(0.55, 0.66, 0.86)) -> np.ndarray:
    """Procedural skin albedo: a skin tone with blotches, pores and freckles (solid texture).

    Parameters
    ----------
    positions : ndarray, shape (K, 3)
        Surface points (world units).
    unit_per_cm : float
        World units per centimetre (10 for mm), so the texture has the same size on any scale.
    tone : (b, g, r)
        Base colour in [0, 1] (BGR).

    Returns
    -------
    ndarray, shape (K, 3), float64
        BGR albedo in [0, 1]. The same point always gets the same colour, so two cameras see
        the same texture (stereo pairs).
    """
    p = np.asarray(positions, dtype=np.float64) / unit_per_cm
    n = np.zeros(p.shape[0])
    amp_total = 0.0
    for k, (freq, amp) in enumerate(((0.6, 0.35), (1.7, 0.25), (4.0, 0.2), (9.0, 0.12), (20.0, 0.08))):
        n += amp * (value_noise(p, freq, seed=seed + 17 * k) - 0.5)
        amp_total += amp
    n /= amp_total
    freckles = np.clip((value_noise(p, 6.0, seed=seed + 999) - 0.72) * 6.0, 0, 1)
    base = np.asarray(tone, dtype=np.float64)
    col = base[None, :] * (1.0 + 0.9 * n[:, None])
    col *= 1.0 - 0.35 * freckles[:, None] * np.array([1.0, 0.9, 0.6])[None, :]
    return np.clip(col, 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class FaceTexture:
    """How a face is coloured: a photograph mapped through per-vertex pixel positions, a
    procedural skin, or both (the photo with skin detail multiplied in).

    Attributes
    ----------
    photo : ndarray (H, W, 3) uint8 BGR, optional
    vertex_uv : ndarray (N, 2), optional
        Pixel position in ``photo`` of every vertex (OpenCV convention).
    skin : bool
        Multiply procedural skin detail (solid noise) into the colour.
    skin_strength : float
        How strongly the skin detail modulates the photo (0..1).
    unit_per_cm : float
        World units per cm (10 when rendering in mm).
    seed : int
    """

    photo: np.ndarray | None = None
    vertex_uv: np.ndarray | None = None
    skin: bool = True
    skin_strength: float = 0.35
    unit_per_cm: float = 1.0
    seed: int = 0
    tone: tuple = (0.55, 0.66, 0.86)


@dataclass(frozen=True)
class ViewStyle:
    """Light and background of a :func:`render_view`.

    Attributes
    ----------
    light_dir : 3-vector
        Direction the light travels, in *camera* coordinates (default: from upper left behind the
        camera toward the scene).
    ambient, specular : float
        Ambient fraction and Blinn-Phong specular strength.
    background : (b, g, r)
        Background colour (0..255).
    background_noise : float
        Standard deviation of grey-level noise added to the background (0 = flat).
    seed : int
        Seed of the background noise.
    """

    light_dir: tuple = (0.3, 0.4, 1.0)
    ambient: float = 0.35
    specular: float = 0.08
    background: tuple = (40, 40, 46)
    background_noise: float = 0.0
    seed: int = 0


def render_view(points, triangles, camera: PinholeCamera, *, texture: FaceTexture | None = None,
                texture_points=None, vertex_colors=None, style: ViewStyle = ViewStyle()) -> RenderResult:
    """Render a textured, lit triangle mesh with an exact depth map.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
        World positions.
    triangles : ndarray, shape (T, 3), int
    camera : PinholeCamera
    texture : FaceTexture, optional
        Colouring (default: procedural skin).
    texture_points : ndarray, shape (N, 3), optional
        Where the solid skin texture is evaluated (default ``points``): pass the rest pose to
        keep the texture stuck to the skin when the face moves.
    vertex_colors : ndarray, shape (N, 3), optional
        BGR in [0, 1], instead of a texture.
    style : ViewStyle
        Light and background.

    Returns
    -------
    RenderResult
    """
    from ..preview.render import vertex_normals

    pts = np.asarray(points, dtype=np.float64)
    tris = np.asarray(triangles, dtype=np.int64)
    w, h = camera.size
    tri_img, bary, depth = _raycast(pts, tris, camera)
    cov = tri_img >= 0
    t = tri_img[cov]
    b = bary[cov]
    tv = tris[t]

    def interp(attr):
        a = np.asarray(attr, dtype=np.float64)
        return np.einsum("kj,kjd->kd", b, a[tv])

    normals_cam = vertex_normals(pts, tris) @ camera.R.T
    n = interp(normals_cam)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    ii, jj = np.nonzero(cov)
    view = np.stack([jj, ii, np.ones_like(jj)], axis=1).astype(np.float64) @ np.linalg.inv(camera.K).T
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    n = np.where((np.einsum("ij,ij->i", n, view) > 0)[:, None], -n, n)  # face the camera (two-sided)
    if vertex_colors is not None:
        albedo = interp(vertex_colors)
    else:
        tex = texture or FaceTexture()
        src = pts if texture_points is None else np.asarray(texture_points, dtype=np.float64)
        surf = interp(src)
        albedo = None
        if tex.photo is not None and tex.vertex_uv is not None:
            import cv2

            uv = interp(tex.vertex_uv).astype(np.float32)
            ph = tex.photo.astype(np.float32) / 255.0
            k = uv.shape[0]
            cols = 1024
            rows = -(-k // cols)
            grid = np.zeros((rows * cols, 2), np.float32)
            grid[:k] = uv
            grid = grid.reshape(rows, cols, 2)
            albedo = cv2.remap(ph, grid[..., 0], grid[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            albedo = albedo.reshape(-1, 3)[:k].astype(np.float64)
        if tex.skin:
            sk = skin_albedo(surf, unit_per_cm=tex.unit_per_cm, seed=tex.seed, tone=tex.tone)
            if albedo is None:
                albedo = sk
            else:
                detail = sk / np.asarray(tex.tone)[None, :]
                albedo = albedo * (1.0 + tex.skin_strength * (detail - 1.0))
        if albedo is None:
            albedo = np.full((t.size, 3), 0.7)
    L = -np.asarray(style.light_dir, dtype=np.float64)
    L /= np.linalg.norm(L)
    lam = np.clip(n @ L, 0.0, None)
    half = L[None, :] - view
    half /= np.maximum(np.linalg.norm(half, axis=1, keepdims=True), 1e-12)
    spec = style.specular * np.clip(np.einsum("ij,ij->i", n, half), 0, None) ** 24
    col = albedo * (style.ambient + (1.0 - style.ambient) * lam)[:, None] + spec[:, None]
    img = np.empty((h, w, 3), dtype=np.float64)
    img[:] = np.asarray(style.background, dtype=np.float64)[None, None, :] / 255.0
    if style.background_noise > 0:
        rng = np.random.default_rng(style.seed)
        img += rng.normal(0, style.background_noise / 255.0, size=(h, w, 1))
    img[cov] = col
    out = np.clip(np.round(img * 255.0), 0, 255).astype(np.uint8)
    return RenderResult(image=out, depth=depth, triangle=tri_img, bary=bary)


def cap_holes(points, triangles, loops, *, depth: float = 0.0, direction=(0.0, 0.0, -1.0)):
    """Close hole loops with triangle fans around their centroid (eyes and mouth of a face mask).

    Parameters
    ----------
    points : ndarray, shape (N, 3)
    triangles : ndarray, shape (T, 3)
    loops : list of ndarray
        Ordered boundary loops (vertex indices) to close.
    depth : float
        The fan's centre is moved by ``depth`` along ``direction`` (recessed eyes).

    Returns
    -------
    points : ndarray, shape (N + len(loops), 3)
    triangles : ndarray, shape (T + sum(len(loop)), 3)
    """
    pts = [np.asarray(points, dtype=np.float64)]
    tris = [np.asarray(triangles, dtype=np.int64)]
    n = pts[0].shape[0]
    dvec = np.asarray(direction, dtype=np.float64)
    for k, loop in enumerate(loops):
        loop = np.asarray(loop, dtype=np.int64)
        c = pts[0][loop].mean(axis=0) + depth * dvec
        pts.append(c[None, :])
        ci = n + k
        tris.append(np.stack([np.full(loop.size, ci), loop, np.roll(loop, -1)], axis=1))
    return np.concatenate(pts), np.concatenate(tris)


def photo_uv(points, mesh_landmarks, photo_landmarks, *, smoothing: float = 0.0) -> np.ndarray:
    """Pixel position in a frontal photo of every mesh point, by a 2-D thin-plate spline.

    The spline maps the front projection ``(x, y)`` of the mesh's landmarks onto the photo's
    landmarks exactly (``smoothing = 0``) and everything else smoothly, so the photo's eyes,
    brows, nose and mouth land on the mesh's.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
    mesh_landmarks : ndarray, shape (M, 3)
    photo_landmarks : ndarray, shape (M, 2)

    Returns
    -------
    ndarray, shape (N, 2)
    """
    from .warp import ThinPlateSpline

    tps = ThinPlateSpline(np.asarray(mesh_landmarks)[:, :2], np.asarray(photo_landmarks), smoothing=smoothing)
    return tps(np.asarray(points)[:, :2])
