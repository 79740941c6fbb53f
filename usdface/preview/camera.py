"""Preview cameras: orthographic or perspective views that frame a set of points.

Conventions
-----------
- The face looks along ``forward`` (default +Z) with ``up`` (default +Y) up, as usdface meshes and
  captures do; +X is the performer's left.
- Image coordinates are continuous pixels: x to the right in [0, W], y down in [0, H]; pixel
  (row i, column j) covers [j, j+1) x [i, i+1) and its centre is (j + 0.5, i + 0.5).
- Depth is the distance along the viewing direction from the camera (larger = farther).

Named views (yaw of the camera about ``up``, from in front of the face), one list for
``usdface preview`` and ``usdface playblast`` (:data:`VIEW_CHOICES`):

============= ===== ==========================================================
view          yaw   what it shows
============= ===== ==========================================================
front         0     the face head-on, looking along -Z
three-quarter +35   three-quarter view of the face's left side (alias ``left``)
side          +90   profile from the face's left (alias ``side_left``)
turntable     swing the camera swings from -75 to +75 degrees and back (sinusoidal) over
                    a period; in a still image (a preview) it is the front view
left          +35   three-quarter view of the face's left side (camera toward +X)
right         -35   three-quarter view of the face's right side (camera toward -X)
side_right    -90   profile from the face's right
============= ===== ==========================================================

A number instead of a name is a yaw in degrees. ``pitch`` (degrees, positive = camera above the
face looking down) tilts any view. :func:`view_yaw` gives the yaw of a view at a phase of the
turntable's period.

For an animation, frame once and reuse the camera so every frame shares the framing:
``Camera.fit(frames)`` with ``frames`` of shape (F, N, 3) frames the union of all frames;
``Camera.fit(frames[0])`` frames the first one.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import OptionError, list_names
from .choices import VIEW_CHOICES  # noqa: F401 (the views offered)

#: yaw in degrees of each named view (``turntable``: its still, the front)
VIEWS = {"front": 0.0, "three-quarter": 35.0, "side": 90.0, "turntable": 0.0, "left": 35.0, "right": -35.0,
         "side_left": 90.0, "side_right": -90.0}
#: the turntable swings the camera between -TURNTABLE_SWING and +TURNTABLE_SWING degrees of yaw
TURNTABLE_SWING = 75.0


def view_yaw(view: str | float, phase: float = 0.0) -> float:
    """Yaw in degrees of ``view`` at ``phase`` (turns of the turntable period; other views ignore it).

    The turntable swings sinusoidally, ``TURNTABLE_SWING * sin(2 pi phase)``: front at phases 0 and
    0.5, the face's left at 0.25, its right at 0.75 (an open face mask is never seen from behind).
    """
    if isinstance(view, str):
        if view not in VIEWS:
            raise OptionError(f"unknown view {view!r}; expected one of {list_names(VIEW_CHOICES)} or a yaw in degrees")
        if view == "turntable":
            return TURNTABLE_SWING * math.sin(2.0 * math.pi * float(phase))
        return VIEWS[view]
    try:
        return float(view)
    except (TypeError, ValueError):
        raise OptionError(f"view must be a name ({list_names(VIEW_CHOICES)}) or a yaw in degrees; "
                          f"got {view!r}") from None
PROJECTIONS = ("orthographic", "perspective")


def _unit(v, what: str) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64).reshape(3)
    n = float(np.linalg.norm(v))
    if not np.isfinite(n) or n == 0:
        raise OptionError(f"camera {what} must be a non-zero 3-vector; got {v.tolist()}")
    return v / n


def _rotate(v: np.ndarray, axis: np.ndarray, deg: float) -> np.ndarray:
    """Rodrigues rotation of v about the unit axis by deg degrees (right-handed)."""
    a = math.radians(deg)
    return v * math.cos(a) + np.cross(axis, v) * math.sin(a) + axis * np.dot(axis, v) * (1 - math.cos(a))


def _size(size) -> tuple[int, int]:
    try:
        w, h = (int(s) for s in size)
    except (TypeError, ValueError):
        raise OptionError(f"image size must be (width, height); got {size!r}") from None
    if w < 1 or h < 1:
        raise OptionError(f"image size must be positive; got {size!r}")
    return w, h


def _gather_points(points) -> np.ndarray:
    """Finite rows of points given as one (..., 3) array or a list of them."""
    if isinstance(points, (list, tuple)):
        arrs = [np.asarray(p, dtype=np.float64) for p in points if p is not None]
        arrs = [a.reshape(-1, 3) for a in arrs if a.size]
        pts = np.concatenate(arrs) if arrs else np.zeros((0, 3))
    else:
        pts = np.asarray(points, dtype=np.float64)
        if pts.shape[-1:] != (3,):
            raise OptionError(f"points to frame must have shape (..., 3); got {pts.shape}")
        pts = pts.reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if pts.shape[0] == 0:
        raise OptionError("no finite points to frame")
    return pts


@dataclass(frozen=True, eq=False)
class Camera:
    """A pinhole (perspective) or orthographic camera producing ``size`` images.

    Attributes
    ----------
    size : (int, int)
        Image (width, height) in pixels.
    eye : ndarray, shape (3,)
        Camera position (world units).
    rotation : ndarray, shape (3, 3)
        World-to-camera rotation; rows are the camera's right, up and viewing (forward) directions.
    projection : str
        ``"orthographic"`` or ``"perspective"``.
    scale : float
        Orthographic: pixels per world unit. Perspective: focal length in pixels.
    principal : (float, float)
        Image position (x, y) of the optical axis, usually the image centre.
    """

    size: tuple[int, int]
    eye: np.ndarray
    rotation: np.ndarray
    projection: str = "orthographic"
    scale: float = 1.0
    principal: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "size", _size(self.size))
        object.__setattr__(self, "eye", np.asarray(self.eye, dtype=np.float64).reshape(3))
        object.__setattr__(self, "rotation", np.asarray(self.rotation, dtype=np.float64).reshape(3, 3))
        if self.projection not in PROJECTIONS:
            raise OptionError(f"projection must be one of {list_names(PROJECTIONS)}; got {self.projection!r}")
        if not (np.isfinite(self.scale) and self.scale > 0):
            raise OptionError(f"camera scale must be a positive number; got {self.scale}")
        if self.principal is None:
            object.__setattr__(self, "principal", (self.size[0] / 2.0, self.size[1] / 2.0))
        else:
            object.__setattr__(self, "principal", (float(self.principal[0]), float(self.principal[1])))

    # ------------------------------------------------------------------------------------------
    @property
    def right(self) -> np.ndarray:
        return self.rotation[0]

    @property
    def up(self) -> np.ndarray:
        return self.rotation[1]

    @property
    def forward(self) -> np.ndarray:
        """Viewing direction (unit, world space)."""
        return self.rotation[2]

    @property
    def perspective(self) -> bool:
        return self.projection == "perspective"

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """(..., 3) world points -> (..., 3) camera coordinates (right, up, depth)."""
        return (np.asarray(points, dtype=np.float64) - self.eye) @ self.rotation.T

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project world points into the image.

        Parameters
        ----------
        points : ndarray, shape (..., 3)

        Returns
        -------
        xy : ndarray, shape (..., 2), float64
            Continuous image coordinates (x right, y down; pixel centres at +0.5).
        depth : ndarray, shape (...,), float64
            Distance along the viewing direction; for a perspective camera points with
            depth <= 0 are behind the camera and get NaN image coordinates.
        """
        c = self.to_camera(points)
        depth = c[..., 2]
        if self.perspective:
            with np.errstate(divide="ignore", invalid="ignore"):
                inv = np.where(depth > 0, self.scale / np.where(depth > 0, depth, 1.0), np.nan)
            x, y = c[..., 0] * inv, c[..., 1] * inv
        else:
            x, y = c[..., 0] * self.scale, c[..., 1] * self.scale
        xy = np.stack([self.principal[0] + x, self.principal[1] - y], axis=-1)
        return xy, depth

    def resized(self, factor: float) -> "Camera":
        """The same view rendered at ``factor`` times the resolution (for supersampling)."""
        w, h = self.size
        return replace(self, size=(int(round(w * factor)), int(round(h * factor))), scale=self.scale * factor,
                       principal=(self.principal[0] * factor, self.principal[1] * factor))

    # ------------------------------------------------------------------------------------------
    @staticmethod
    def view_rotation(view: str | float = "front", *, pitch: float = 0.0, up=(0.0, 1.0, 0.0),
                      forward=(0.0, 0.0, 1.0)) -> np.ndarray:
        """(3, 3) world-to-camera rotation of a named view (see the module docstring)."""
        yaw = view_yaw(view)
        up_v = _unit(up, "up")
        fwd = _unit(forward, "forward")
        fwd = fwd - up_v * np.dot(fwd, up_v)
        if np.linalg.norm(fwd) < 1e-9:
            raise OptionError("camera forward and up directions are parallel")
        fwd /= np.linalg.norm(fwd)
        to_cam = _rotate(fwd, up_v, yaw)  # from the face toward the camera
        side = np.cross(to_cam, up_v)  # axis for pitch: camera goes up for pitch > 0
        to_cam = _rotate(to_cam, side / np.linalg.norm(side), pitch)
        view_dir = -to_cam
        right = np.cross(view_dir, up_v)
        right /= np.linalg.norm(right)
        cam_up = np.cross(right, view_dir)
        return np.stack([right, cam_up, view_dir])

    @classmethod
    def fit(cls, points, *, view: str | float = "front", size=(512, 512), projection: str = "orthographic",
            margin: float = 0.06, fov: float = 30.0, pitch: float = 0.0, up=(0.0, 1.0, 0.0),
            forward=(0.0, 0.0, 1.0)) -> "Camera":
        """A camera of the given view that frames ``points``.

        Parameters
        ----------
        points : ndarray, shape (..., 3), or a list of such arrays
            Everything to keep in frame: mesh points, markers, or all frames of an animation
            ((F, N, 3) frames the union, so the camera can be reused for every frame). Rows with
            NaN are ignored.
        view : str or float
            A name from :data:`VIEWS` or a yaw in degrees.
        size : (int, int)
            Image (width, height) in pixels.
        projection : str
            ``"orthographic"`` (default: no perspective distortion, good for comparing shapes) or
            ``"perspective"``.
        margin : float
            Free border on each side, as a fraction of the image size (0 <= margin < 0.5).
        fov : float
            Perspective only: vertical field of view in degrees.
        pitch : float
            Degrees; positive puts the camera above the face, looking down.
        up, forward : 3-vectors
            The face's up and facing directions (world space).
        """
        w, h = _size(size)
        if not (0 <= margin < 0.5):
            raise OptionError(f"margin must be in [0, 0.5); got {margin}")
        if projection not in PROJECTIONS:
            raise OptionError(f"projection must be one of {list_names(PROJECTIONS)}; got {projection!r}")
        rot = cls.view_rotation(view, pitch=pitch, up=up, forward=forward)
        pts = _gather_points(points)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        target = (lo + hi) / 2
        diag = float(np.linalg.norm(hi - lo)) or 1.0
        q = (pts - target) @ rot.T  # right, up, depth relative to the target
        aw, ah = w * (1 - 2 * margin), h * (1 - 2 * margin)
        if projection == "orthographic":
            qmin, qmax = q.min(axis=0), q.max(axis=0)
            ext = np.maximum(qmax - qmin, 1e-12 * diag)
            scale = float(min(aw / ext[0], ah / ext[1]))
            if not np.isfinite(scale) or ext[0] <= 1e-9 * diag and ext[1] <= 1e-9 * diag:
                scale = min(aw, ah) / diag
            centre = np.array([(qmin[0] + qmax[0]) / 2, (qmin[1] + qmax[1]) / 2, qmin[2] - diag])
            eye = target + centre @ rot
            return cls(size=(w, h), eye=eye, rotation=rot, projection=projection, scale=scale)
        if not (0 < fov < 179):
            raise OptionError(f"fov must be in (0, 179) degrees; got {fov}")
        focal = (h / 2) / math.tan(math.radians(fov) / 2)
        tx, ty = (aw / 2) / focal, (ah / 2) / focal  # tangent of the usable half-angles
        cx = cy = 0.0
        for _ in range(4):  # distance for the current centre, then re-centre the projected extent
            dist = float(max(np.max(np.abs(q[:, 0] - cx) / tx - q[:, 2]),
                             np.max(np.abs(q[:, 1] - cy) / ty - q[:, 2])))
            dist = max(dist, float(np.max(-q[:, 2])) + 1e-3 * diag)
            d = dist + q[:, 2]
            u, v = (q[:, 0] - cx) / d, (q[:, 1] - cy) / d
            cx += (u.min() + u.max()) / 2 * dist
            cy += (v.min() + v.max()) / 2 * dist
        dist = float(max(np.max(np.abs(q[:, 0] - cx) / tx - q[:, 2]),
                         np.max(np.abs(q[:, 1] - cy) / ty - q[:, 2])))
        dist = max(dist, float(np.max(-q[:, 2])) + 1e-3 * diag)
        eye = target + np.array([cx, cy, -dist]) @ rot
        return cls(size=(w, h), eye=eye, rotation=rot, projection=projection, scale=focal)
