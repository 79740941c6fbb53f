"""Facial landmarks: the file format, the standard 20-point set, and landmarks of a hole mesh.

Landmarks JSON (``usdface`` landmarks file)::

    {
      "Reye_Outside": {"image": [191.5, 100.5]},
      "NoseHead": {"scan": [3.1, -12.0, -612.4]}
    }

- ``"image"``: a pixel position ``[u, v]`` in the image the file belongs to (x right, y down,
  OpenCV's convention: the centre of the top-left pixel is ``(0, 0)``);
- ``"scan"``: a 3-D position ``[x, y, z]`` in the scan layer's space and units.

A ``detect`` features file (``{"format": "usdface-features/1", ..., "landmarks": {...}}``) is read
as its ``"landmarks"`` object. The generic mesh's landmarks are a marker layout
(:mod:`usdface.mesh.layout`, ``usdface-layout/1``) with the same names.

The standard set (:data:`FACE_LANDMARKS`, 20 points, names as the AnimFace markers where they
exist; ``L`` = the person's left, image right in a frontal photo): eye corners and lids (8),
brow ends (4), nose tip and wings (3), mouth corners, upper and lower lip (4), chin (1) — the
"about 20 hand-placed points" of seed 001, section 3.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..fileutil import write_text_atomic
from ..errors import FormatError, InputError, MeshError, list_names
from ..inputfiles import FLOAT32_MAX, check_input_file, read_json

__all__ = ["FACE_LANDMARKS", "EYE_LANDMARKS", "Landmarks", "read_landmarks", "write_landmarks",
           "interocular_distance", "mesh_face_landmarks", "read_pts", "write_pts"]

#: the standard 20 facial landmarks, in a fixed order (AAM point order)
FACE_LANDMARKS = (
    "Reye_Outside", "Reye_Inside", "Reye_Up", "Reye_Down",
    "Leye_Inside", "Leye_Outside", "Leye_Up", "Leye_Down",
    "Reyebrow_Outside", "Reyebrow_Inside", "Leyebrow_Inside", "Leyebrow_Outside",
    "NoseHead", "NoseHead_R", "NoseHead_L",
    "Mouth_Rend", "Mouth_Lend", "Mouth_Up", "Mouth_Down",
    "Chin",
)
#: landmarks averaged to give each eye centre (right eye, left eye), for the inter-ocular distance
EYE_LANDMARKS = (("Reye_Outside", "Reye_Inside", "Reye_Up", "Reye_Down"),
                 ("Leye_Inside", "Leye_Outside", "Leye_Up", "Leye_Down"))


@dataclass(frozen=True)
class Landmarks:
    """Named 2-D image points and/or 3-D scan points.

    Attributes
    ----------
    image : dict {name: (u, v)}
        Pixel positions (OpenCV convention: the top-left pixel's centre is (0, 0)).
    scan : dict {name: (x, y, z)}
        Positions in the scan's space and units.
    source : str
        The file they came from (for messages).
    """

    image: dict
    scan: dict
    source: str = ""

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(list(self.image) + [n for n in self.scan if n not in self.image])

    def image_array(self, names=None) -> np.ndarray:
        """(M, 2) image points in the order of ``names`` (default: file order)."""
        names = list(self.image) if names is None else list(names)
        missing = [n for n in names if n not in self.image]
        if missing:
            raise InputError(f"landmarks {self.source}: no image point for {list_names(missing)}")
        return np.array([self.image[n] for n in names], dtype=np.float64).reshape(-1, 2)

    @classmethod
    def from_image_points(cls, names, points, *, source: str = "") -> "Landmarks":
        pts = np.asarray(points, dtype=np.float64)
        return cls(image={str(n): (float(p[0]), float(p[1])) for n, p in zip(names, pts)}, scan={}, source=source)

    def check_inside(self, size, *, what: str = "image") -> None:
        """Raise InputError naming every image landmark outside an image of ``size`` (w, h)."""
        w, h = size
        bad = [f"{n} ({u:.1f}, {v:.1f})" for n, (u, v) in self.image.items()
               if not (-0.5 <= u <= w - 0.5 and -0.5 <= v <= h - 0.5)]
        if bad:
            raise InputError(f"landmarks {self.source}: {len(bad)} point(s) outside the {w}x{h} {what}: "
                             f"{list_names(bad)}")


def _finite_list(value, n) -> bool:
    """``n`` numbers, finite and within float32's range (what USD and images store)."""
    return (isinstance(value, list) and len(value) == n
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                    and abs(x) <= FLOAT32_MAX for x in value))


def read_landmarks(path) -> Landmarks:
    """Read a landmarks JSON file (or the ``"landmarks"`` of a ``detect`` features file).

    Raises
    ------
    InputError
        Missing file.
    FormatError
        Not JSON, an entry that is not ``{"image": [u, v]}`` or ``{"scan": [x, y, z]}``, or no
        landmarks at all (the message names the file and the entry).
    """
    p = Path(os.fspath(path))
    data = read_json(p, label=f"landmarks file {p}")
    if isinstance(data, dict) and data.get("format", "").startswith("usdface-features/"):
        data = data.get("landmarks") or {}
        if not data:
            raise FormatError(f"features file {p} has no landmarks (run `usdface detect` with --aam)")
    if isinstance(data, dict) and data.get("format", "").startswith("usdface-layout/"):
        raise FormatError(f"{p} is a marker layout; scan landmarks are {{\"name\": {{\"image\": [u, v]}}}} or "
                          "{\"name\": {\"scan\": [x, y, z]}} (a layout gives the generic mesh's landmarks)")
    if not isinstance(data, dict) or not data:
        raise FormatError(f"landmarks file {p}: expected a non-empty object of name -> "
                          "{\"image\": [u, v]} or {\"scan\": [x, y, z]}")
    image, scan = {}, {}
    for name, entry in data.items():
        if not isinstance(entry, dict) or not entry or any(k not in ("image", "scan") for k in entry):
            raise FormatError(f"landmarks file {p}, landmark {name!r}: expected {{\"image\": [u, v]}} or "
                              f"{{\"scan\": [x, y, z]}}; got {json.dumps(entry)}")
        if "image" in entry:
            if not _finite_list(entry["image"], 2):
                raise FormatError(f"landmarks file {p}, landmark {name!r}: image must be 2 finite numbers (float32); "
                                  f"got {json.dumps(entry['image'])}")
            image[name] = tuple(float(x) for x in entry["image"])
        if "scan" in entry:
            if not _finite_list(entry["scan"], 3):
                raise FormatError(f"landmarks file {p}, landmark {name!r}: scan must be 3 finite numbers (float32); "
                                  f"got {json.dumps(entry['scan'])}")
            scan[name] = tuple(float(x) for x in entry["scan"])
    return Landmarks(image=image, scan=scan, source=str(p))


def _landmarks_dict(lm: Landmarks, decimals: int) -> dict:
    out = {}
    for n in lm.names:
        e = {}
        if n in lm.image:
            e["image"] = [round(float(x), decimals) for x in lm.image[n]]
        if n in lm.scan:
            e["scan"] = [round(float(x), decimals) for x in lm.scan[n]]
        out[n] = e
    return out


def _atomic_text(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_text_atomic(path, text)


def write_landmarks(path, landmarks: Landmarks, *, decimals: int = 3) -> Path:
    """Write a landmarks JSON file atomically, one landmark per line."""
    d = _landmarks_dict(landmarks, decimals)
    text = "{\n" + ",\n".join(f"  {json.dumps(k)}: {json.dumps(v)}" for k, v in d.items()) + "\n}\n"
    return _atomic_text(Path(os.fspath(path)), text)


def read_pts(path) -> np.ndarray:
    """Read an ibug/IMM ``.pts`` point file (``version: 1``, ``n_points: N``, ``{ x y ... }``).

    Returns
    -------
    ndarray, shape (N, 2), float64
    """
    p = check_input_file(os.fspath(path), label=f"point file {os.fspath(path)}")
    lines = [ln.strip() for ln in p.read_text(encoding="utf-8", errors="replace").splitlines() if ln.strip()]
    try:
        n = int(next(ln for ln in lines if ln.lower().startswith("n_points")).split(":")[1])
        start = lines.index("{") + 1
        stop = lines.index("}")
        pts = np.array([[float(v) for v in ln.split()[:2]] for ln in lines[start:stop]])
    except (StopIteration, ValueError, IndexError):
        raise FormatError(f"point file {p}: expected 'n_points: N' and '{{ x y ... }}' lines") from None
    if pts.shape != (n, 2):
        raise FormatError(f"point file {p}: header says {n} points, found {len(pts)}")
    return pts


def write_pts(path, points) -> Path:
    """Write an ibug ``.pts`` point file."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    text = f"version: 1\nn_points: {len(pts)}\n{{\n" + "".join(f"{x:.3f} {y:.3f}\n" for x, y in pts) + "}\n"
    return _atomic_text(Path(os.fspath(path)), text)


def interocular_distance(points, names=FACE_LANDMARKS) -> float | np.ndarray:
    """Distance between the eye centres (mean of each eye's 4 landmarks).

    Parameters
    ----------
    points : ndarray, shape (..., M, D)
        Landmarks in the order of ``names``.
    """
    pts = np.asarray(points, dtype=np.float64)
    names = list(names)
    r = pts[..., [names.index(n) for n in EYE_LANDMARKS[0]], :].mean(axis=-2)
    left = pts[..., [names.index(n) for n in EYE_LANDMARKS[1]], :].mean(axis=-2)
    return np.linalg.norm(r - left, axis=-1)


# ================================================================================================
# landmarks of a face mesh with eye and mouth holes
# ================================================================================================
def _front_hit(locator, x, y, z_top):
    """First surface hit of the ray from (x, y, z_top) along -Z (closest point of a dense probe)."""
    zs = np.linspace(z_top, z_top - 30.0, 1200)
    q = np.stack([np.full_like(zs, x), np.full_like(zs, y), zs], axis=1)
    _, _, cp, d = locator.closest(q)
    # the first probe point within a small distance of the surface
    tol = max(0.02, float(d.min()) + 0.02)
    k = int(np.flatnonzero(d <= tol)[0])
    return cp[k]


def mesh_face_landmarks(mesh, regions=None) -> dict:
    """The 20 standard landmarks (:data:`FACE_LANDMARKS`) placed on a face mesh from its holes.

    For a mesh in cm (or any unit), +Y up, +Z forward, person's left = +X, with hole regions
    ``leftEye``, ``rightEye`` and ``mouth`` (:func:`usdface.mesh.topology.find_hole_regions`):

    - eye corners: the eye loop's extreme-x vertices; lids: the loop's highest and lowest vertex
      in the middle third of the eye's width; each taken where a frontal view sees it (the front
      projection of the vertex: the lids and lips hide the corner vertices themselves, up to 6 mm
      deeper, from a camera);
    - brow ends: above each eye corner, 0.21 inter-ocular distances (IOD) above the eye's centre
      line (ratios measured on the face photograph of sample_assets/landmarks);
    - nose tip: the most forward vertex near the midline between the eyes and the mouth; wings:
      0.22 IOD either side of the midline, 0.09 IOD below the tip;
    - mouth corners: the mouth loop's extreme-x vertices (front-projected); upper and lower lip: on the midline,
      0.14 and 0.21 mouth widths above and below the mouth loop's centre;
    - chin: on the midline 0.55 mouth widths below the mouth centre.

    Points off the loops are the first surface hit of a ray along -Z ("front projection").

    Returns
    -------
    dict {name: ndarray (3,)}
        Positions in the mesh's space and units.
    """
    from ..mesh.closest import SurfaceLocator
    from ..mesh.topology import find_hole_regions

    regions = find_hole_regions(mesh) if regions is None else regions
    by_name = {r.name: r for r in regions}
    missing = [n for n in ("leftEye", "rightEye", "mouth") if n not in by_name]
    if missing:
        raise MeshError(f"mesh {mesh.source or mesh.name}: no {', '.join(missing)} hole region(s); landmarks "
                        f"need eye and mouth holes (regions found: {list_names(by_name) or 'none'})")
    p = mesh.points
    loc = SurfaceLocator(p, mesh.triangles())
    z_top = float(p[:, 2].max()) + 1.0
    out = {}

    def loop_pts(name):
        r = by_name[name]
        return p[r.loop if r.loop is not None else r.indices]

    centres = {}
    for side, region in (("R", "rightEye"), ("L", "leftEye")):
        lp = loop_pts(region)
        inner_is_min = side == "L"  # left eye (+x): inner corner has the smaller x
        i_min, i_max = lp[:, 0].argmin(), lp[:, 0].argmax()
        inner, outer = (lp[i_min], lp[i_max]) if inner_is_min else (lp[i_max], lp[i_min])
        x0, x1 = lp[:, 0].min(), lp[:, 0].max()
        mid = np.abs(lp[:, 0] - 0.5 * (x0 + x1)) <= (x1 - x0) / 6.0
        up = lp[mid][lp[mid][:, 1].argmax()]
        down = lp[mid][lp[mid][:, 1].argmin()]
        for key, v in (("Inside", inner), ("Outside", outer), ("Up", up), ("Down", down)):
            out[f"{side}eye_{key}"] = _front_hit(loc, v[0], v[1], z_top)
        centres[side] = np.mean([inner, outer, up, down], axis=0)
    iod = float(np.linalg.norm(centres["L"] - centres["R"]))
    for side in ("R", "L"):
        for part in ("Inside", "Outside"):
            corner = out[f"{side}eye_{part}"]
            out[f"{side}eyebrow_{part}"] = _front_hit(loc, corner[0], centres[side][1] + 0.21 * iod, z_top)
    ml = loop_pts("mouth")
    mr, mleft = ml[ml[:, 0].argmin()], ml[ml[:, 0].argmax()]
    width = float(mleft[0] - mr[0])
    mouth_y = 0.5 * (ml[:, 1].max() + ml[:, 1].min())
    out["Mouth_Rend"] = _front_hit(loc, mr[0], mr[1], z_top)
    out["Mouth_Lend"] = _front_hit(loc, mleft[0], mleft[1], z_top)
    out["Mouth_Up"] = _front_hit(loc, 0.0, mouth_y + 0.14 * width, z_top)
    out["Mouth_Down"] = _front_hit(loc, 0.0, mouth_y - 0.21 * width, z_top)
    out["Chin"] = _front_hit(loc, 0.0, mouth_y - 0.55 * width, z_top)
    eye_y = 0.5 * (centres["L"][1] + centres["R"][1])
    band = (np.abs(p[:, 0]) < 0.08 * iod) & (p[:, 1] < eye_y - 0.3 * iod) & (p[:, 1] > mouth_y + 0.2 * width)
    if not band.any():
        raise MeshError(f"mesh {mesh.source or mesh.name}: no vertices on the midline between eyes and mouth")
    tip = p[band][p[band][:, 2].argmax()]
    out["NoseHead"] = _front_hit(loc, 0.0, tip[1], z_top)
    for side, sx in (("R", -1.0), ("L", 1.0)):
        out[f"NoseHead_{side}"] = _front_hit(loc, sx * 0.22 * iod, tip[1] - 0.09 * iod, z_top)
    return {n: np.asarray(out[n], dtype=np.float64) for n in FACE_LANDMARKS}
