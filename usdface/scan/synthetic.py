"""Synthetic face data with exact ground truth: stereo pairs and annotated face images.

Built from the sample meshes (MakeHuman hm08 face and its stylized variant, eye and mouth holes
capped so the eyes and the mouth slit render as surfaces) coloured by the face photograph mapped
through its hand-placed landmarks and/or a procedural skin, rendered by
:mod:`usdface.scan.render`:

- :func:`render_stereo_pair`: a rectified pair (horizontal or vertical) with the exact depth of
  every pixel of the first image and its rectified calibration;
- :func:`render_annotated_faces`: face images with varied pose, light, scale and expression
  (the sample expression shapes), each with the 20 landmarks projected exactly - training and
  test sets for the active appearance model.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import MeshError
from .landmarks import FACE_LANDMARKS
from .render import FaceTexture, PinholeCamera, ViewStyle, cap_holes, photo_uv, render_view, stereo_cameras

__all__ = ["FaceScene", "face_scene", "sample_face", "render_stereo_pair", "FaceVariation", "render_annotated_faces",
           "rotation_matrix", "surface_locations", "evaluate_locations"]


def rotation_matrix(yaw: float = 0.0, pitch: float = 0.0, roll: float = 0.0) -> np.ndarray:
    """Rotation (degrees) about y (yaw), then x (pitch), then z (roll)."""
    y, p, r = np.radians([yaw, pitch, roll])
    Ry = np.array([[np.cos(y), 0, np.sin(y)], [0, 1, 0], [-np.sin(y), 0, np.cos(y)]])
    Rx = np.array([[1, 0, 0], [0, np.cos(p), -np.sin(p)], [0, np.sin(p), np.cos(p)]])
    Rz = np.array([[np.cos(r), -np.sin(r), 0], [np.sin(r), np.cos(r), 0], [0, 0, 1]])
    return Rz @ Rx @ Ry


def surface_locations(points, triangles, queries):
    """(triangle index, barycentrics) of the closest surface point of each query."""
    from ..mesh.closest import SurfaceLocator

    tri, bary, _, _ = SurfaceLocator(points, triangles).closest(np.asarray(queries, dtype=np.float64))
    return tri, bary


def evaluate_locations(points, triangles, tri, bary) -> np.ndarray:
    """Positions of surface locations on (possibly moved) vertex positions."""
    t = np.asarray(triangles)[tri]
    return np.einsum("kj,kjd->kd", bary, np.asarray(points)[t])


@dataclass(frozen=True, eq=False)
class FaceScene:
    """A render-ready face.

    Attributes
    ----------
    points : ndarray, shape (N + 3, 3)
        Mesh vertices then the three cap centres, in world units (mm by default).
    triangles : ndarray, shape (T, 3)
    n_mesh_points : int
        N: the face mesh's own vertices come first.
    texture : FaceTexture
    landmark_tri, landmark_bary : ndarray
        The 20 landmarks as surface locations (triangles of ``triangles``).
    scale : float
        World units per mesh unit.
    """

    points: np.ndarray
    triangles: np.ndarray
    n_mesh_points: int
    texture: FaceTexture
    landmark_tri: np.ndarray
    landmark_bary: np.ndarray
    scale: float

    def landmarks(self, points=None) -> np.ndarray:
        """(20, 3) landmark positions on ``points`` (default the rest pose)."""
        return evaluate_locations(self.points if points is None else points, self.triangles,
                                  self.landmark_tri, self.landmark_bary)

    @property
    def centre(self) -> np.ndarray:
        return self.points[: self.n_mesh_points].mean(axis=0)


def face_scene(mesh, regions, landmark_points, *, photo=None, photo_landmarks=None, skin: bool = True,
               scale: float = 10.0, eye_depth: float = 3.0, seed: int = 0) -> FaceScene:
    """A render-ready face from a mesh with eye and mouth holes.

    Parameters
    ----------
    mesh : FaceMesh
    regions : list of Region
        Must hold ``leftEye``, ``rightEye`` and ``mouth`` with loops.
    landmark_points : ndarray, shape (20, 3)
        The :data:`FACE_LANDMARKS` on the mesh (mesh units).
    photo : ndarray (H, W, 3) uint8, optional
        Face photograph mapped onto the mesh through ``photo_landmarks`` (20, 2).
    skin : bool
        Add procedural skin detail (needed for stereo matching on a plain mesh).
    scale : float
        World units per mesh unit (10: cm -> mm).
    eye_depth : float
        How far (world units) the eye and mouth caps' centres sit behind their loops.
    """
    by = {r.name: r for r in regions}
    missing = [n for n in ("leftEye", "rightEye", "mouth") if n not in by or by[n].loop is None]
    if missing:
        raise MeshError(f"face scene: the mesh lacks hole region(s) {', '.join(missing)} with loops")
    pts, tris = cap_holes(mesh.points * scale, mesh.triangles(),
                          [by["leftEye"].loop, by["rightEye"].loop, by["mouth"].loop], depth=eye_depth)
    lm = np.asarray(landmark_points, dtype=np.float64) * scale
    tri, bary = surface_locations(pts, tris, lm)
    uv = None
    if photo is not None:
        uv = photo_uv(pts, lm, np.asarray(photo_landmarks, dtype=np.float64))
    tex = FaceTexture(photo=photo, vertex_uv=uv, skin=skin, unit_per_cm=scale, seed=seed)
    return FaceScene(points=pts, triangles=tris, n_mesh_points=mesh.n_points, texture=tex, landmark_tri=tri,
                     landmark_bary=bary, scale=scale)


def render_stereo_pair(scene: FaceScene, *, size=(640, 480), distance: float = 550.0, baseline: float = 60.0,
                       f: float | None = None, vertical: bool = False, light_dir=(0.3, 0.4, 1.0),
                       background_noise: float = 0.0, points=None) -> dict:
    """Render a rectified stereo pair of a face with exact depth.

    Parameters
    ----------
    scene : FaceScene
    size : (w, h)
    distance : float
        From the first camera to the face's nose-tip plane (world units).
    baseline : float
        Camera distance (world units), to the right (or down when ``vertical``).
    f : float, optional
        Focal length in pixels (default: the face's height fills ~80% of the image height).
    points : ndarray, optional
        Moved scene points (default the rest pose).

    Returns
    -------
    dict
        ``first``, ``second`` (uint8 BGR images), ``depth`` (exact depth of the first image,
        NaN off the face), ``calibration`` (rectified calibration dict), ``camera`` (the first
        PinholeCamera), ``points`` (scene points used).
    """
    pts = scene.points if points is None else points
    w, h = int(size[0]), int(size[1])
    face = pts[: scene.n_mesh_points]
    top_z = float(face[:, 2].max())
    c = face.mean(axis=0)
    height = float(np.ptp(face[:, 1]))
    if f is None:
        f = 0.8 * h * (distance + (top_z - c[2])) / height
    eye = np.array([c[0] - (baseline / 2 if not vertical else 0), c[1] + (baseline / 2 if vertical else 0),
                    top_z + distance])
    target = eye - np.array([0, 0, 1.0])
    cam = PinholeCamera.look_at(eye, target, f=f, size=(w, h))
    first, second, calib = stereo_cameras(cam, baseline, vertical=vertical)
    r1 = render_view(pts, scene.triangles, first, texture=scene.texture, texture_points=scene.points,
                     style=ViewStyle(light_dir=light_dir, background_noise=background_noise, seed=1))
    r2 = render_view(pts, scene.triangles, second, texture=scene.texture, texture_points=scene.points,
                     style=ViewStyle(light_dir=light_dir, background_noise=background_noise, seed=2))
    return {"first": r1.image, "second": r2.image, "depth": r1.depth, "calibration": calib, "camera": first,
            "points": pts, "mask": r1.mask}


@dataclass(frozen=True)
class FaceVariation:
    """How the images of :func:`render_annotated_faces` vary.

    Attributes
    ----------
    expression_scale : float
        Each image mixes up to three expression shapes with random weights in ``[0, expression_scale]``.
    yaw, pitch, roll : float
        Pose ranges (degrees, uniform in +-range).
    face_fraction : (lo, hi)
        Face height as a fraction of the image height.
    shift : float
        Random offset of the face centre as a fraction of the image size.
    distance : float
        Camera distance (world units).
    """

    expression_scale: float = 0.6
    yaw: float = 12.0
    pitch: float = 8.0
    roll: float = 8.0
    face_fraction: tuple = (0.55, 0.75)
    shift: float = 0.08
    distance: float = 600.0


def render_annotated_faces(scene: FaceScene, n: int, *, size=(256, 256), seed: int = 0, deltas=None,
                           variation: FaceVariation = FaceVariation()):
    """Face images with their 20 landmarks, for training and testing landmark fitting.

    Parameters
    ----------
    scene : FaceScene
    n : int
        Number of images.
    size : (w, h)
    seed : int
    deltas : ndarray, shape (S, N, 3), optional
        Expression shapes (mesh units, e.g. the sample "Face Units").
    variation : FaceVariation
        Ranges of expression, pose, face size and position.

    Returns
    -------
    images : list of ndarray (h, w, 3) uint8
    landmarks : ndarray, shape (n, 20, 2)
        Pixel positions (OpenCV convention) in :data:`FACE_LANDMARKS` order.
    """
    v = variation
    rng = np.random.default_rng(seed)
    w, h = int(size[0]), int(size[1])
    base = scene.points
    nm = scene.n_mesh_points
    centre = base[:nm].mean(axis=0)
    height = float(np.ptp(base[:nm, 1]))
    images, marks = [], []
    for _ in range(n):
        pts = base.copy()
        if deltas is not None and len(deltas):
            k = rng.choice(len(deltas), size=min(3, len(deltas)), replace=False)
            wts = rng.uniform(0, v.expression_scale, size=k.size)
            pts[:nm] += np.tensordot(wts, np.asarray(deltas)[k], axes=1) * scene.scale
        R = rotation_matrix(rng.uniform(-v.yaw, v.yaw), rng.uniform(-v.pitch, v.pitch), rng.uniform(-v.roll, v.roll))
        pts = (pts - centre) @ R.T + centre
        frac = rng.uniform(*v.face_fraction)
        f = frac * h * v.distance / height
        off = rng.uniform(-v.shift, v.shift, size=2) * np.array([w, h])
        eye = centre + np.array([0, 0, v.distance])
        cam = PinholeCamera.look_at(eye, centre, f=f, size=(w, h),
                                    principal=((w - 1) / 2 + off[0], (h - 1) / 2 + off[1]))
        light = np.array([rng.uniform(-0.6, 0.6), rng.uniform(-0.2, 0.6), 1.0])
        bg = tuple(int(c) for c in rng.integers(20, 200, size=3))
        ambient = rng.uniform(0.3, 0.5)  # drawn before the noise seed, as always (same images per seed)
        style = ViewStyle(light_dir=light, ambient=ambient, background=bg, background_noise=6.0,
                          seed=int(rng.integers(1 << 30)))
        r = render_view(pts, scene.triangles, cam, texture=scene.texture, texture_points=base, style=style)
        lm3 = scene.landmarks(pts)
        uv, _ = cam.project(lm3)
        images.append(r.image)
        marks.append(uv)
    return images, np.asarray(marks)


def sample_face(sample_assets, which: str = "stylized", *, photo=None, skin: bool = True):
    """The sample MakeHuman face (``"neutral"`` or ``"stylized"``) ready to render.

    Parameters
    ----------
    sample_assets : path
        The repository's ``sample_assets`` folder (meshes and landmarks).
    photo : path, optional
        Face photograph to map on (its landmarks: ``sample_assets/landmarks/<stem>.landmarks.json``).

    Returns
    -------
    mesh : FaceMesh
    regions : list of Region
    landmarks : ndarray, shape (20, 3)
        The generic (neutral) landmarks' surface locations evaluated on this mesh (same topology),
        so both faces carry the same anatomical points.
    scene : FaceScene
    """
    from pathlib import Path

    from ..io.meshes import read_mesh
    from ..mesh.layout import read_layout
    from ..mesh.topology import find_hole_regions
    from .landmarks import read_landmarks

    root = Path(sample_assets)
    neutral = read_mesh(root / "meshes" / "makehuman_hm08_face_cm.obj")
    mesh = neutral if which == "neutral" else read_mesh(root / "meshes" / "makehuman_hm08_face_stylized_cm.obj")
    regions = find_hole_regions(mesh)
    lay = read_layout(root / "landmarks" / "makehuman_hm08_face.landmarks.layout.json")
    tri, bary = surface_locations(neutral.points, neutral.triangles(), lay.positions(neutral, FACE_LANDMARKS))
    lm = evaluate_locations(mesh.points, mesh.triangles(), tri, bary)
    img = pl = None
    if photo is not None:
        from ..io.images import read_image

        img = read_image(photo)  # libpng's iCCP warning kept off stderr
        pl = read_landmarks(root / "landmarks" / (Path(photo).stem + ".landmarks.json")).image_array(FACE_LANDMARKS)
    scene = face_scene(mesh, regions, lm, photo=img, photo_landmarks=pl, skin=skin)
    return mesh, regions, lm, scene
