"""Face and feature detection with cascades of boosted Haar classifiers (seed 001, section 4).

OpenCV's Viola-Jones detectors (cv2.CascadeClassifier) with the cascades that ship with
opencv-contrib-python-headless (``cv2.data.haarcascades``):

- face: ``haarcascade_frontalface_default.xml`` (``alt2`` as a fallback);
- eyes: ``haarcascade_eye.xml``, searched in the upper 60% of the face box;
- mouth: OpenCV ships **no mouth cascade** (the old ``haarcascade_mcs_mouth.xml`` was never part
  of opencv's data); ``haarcascade_smile.xml`` is the one lower-face cascade shipped, so the
  mouth is looked for with it in the lower 40% of the face box, and reported as missing when it
  does not fire (it needs a visible mouth, best an open or smiling one).

Features file (``usdface detect``), ``usdface-features/1``::

    {"format": "usdface-features/1", "image": "photo.png", "size": [512, 512],
     "faces": [{"box": [x, y, w, h], "eyes": [[x, y, w, h], ...], "mouth": [x, y, w, h] | null}],
     "landmarks": {"Reye_Outside": {"image": [u, v]}, ...}}

``landmarks`` (when an AAM model was given) is a landmarks object usable as ``register
--landmarks``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import OptionError, UsdFaceError

__all__ = ["FEATURES_FORMAT", "FaceDetection", "cascade", "detect_faces", "detect_features", "largest_face_box",
           "draw_detections", "features_dict"]

FEATURES_FORMAT = "usdface-features/1"

CASCADES = {
    "face": "haarcascade_frontalface_default.xml",
    "face-alt2": "haarcascade_frontalface_alt2.xml",
    "eye": "haarcascade_eye.xml",
    "smile": "haarcascade_smile.xml",
}
_CACHE: dict = {}


def cascade(name: str):
    """A cv2.CascadeClassifier of the cascades shipped with OpenCV (:data:`CASCADES` keys or a file)."""
    import cv2

    if name in _CACHE:
        return _CACHE[name]
    path = Path(name) if name not in CASCADES else Path(cv2.data.haarcascades) / CASCADES[name]
    if not path.is_file():
        raise UsdFaceError(f"Haar cascade {path} not found (opencv-contrib-python-headless ships them in "
                           f"cv2.data.haarcascades)")
    clf = cv2.CascadeClassifier(str(path))
    if clf.empty():
        raise UsdFaceError(f"Haar cascade {path} could not be loaded")
    _CACHE[name] = clf
    return clf


@dataclass(frozen=True)
class FaceDetection:
    """A detected face.

    Attributes
    ----------
    box : (x, y, w, h)
        Face box, pixels.
    eyes : list of (x, y, w, h)
        Eye boxes (image coordinates), at most 2, left to right in the image.
    mouth : (x, y, w, h) or None
        Mouth box from the smile cascade (no mouth cascade ships with OpenCV), if it fired.
    neighbours : int
        The face cascade's detection strength (number of merged raw detections).
    """

    box: tuple
    eyes: list = field(default_factory=list)
    mouth: tuple | None = None
    neighbours: int = 0


def _gray(image):
    import cv2

    img = np.asarray(image)
    if img.dtype != np.uint8:
        raise OptionError(f"detection needs an 8-bit image; got {img.dtype}")
    g = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img
    return cv2.equalizeHist(g)


def detect_faces(image, *, min_size: int | None = None, scale_factor: float = 1.1, min_neighbors: int = 5,
                 features: bool = True, which: str = "face") -> list[FaceDetection]:
    """Detect frontal faces (and their eyes and mouth) with Haar cascades.

    Parameters
    ----------
    image : ndarray, shape (H, W) or (H, W, 3), uint8
    min_size : int, optional
        Smallest face side in pixels (default: 1/12 of the image's smaller side, at least 24).
    scale_factor, min_neighbors :
        cv2.CascadeClassifier.detectMultiScale options.
    features : bool
        Also look for eyes and mouth inside each face.
    which : str
        Face cascade: ``"face"`` (frontalface_default) or ``"face-alt2"``.

    Returns
    -------
    list of FaceDetection
        Largest first; empty when no face is found.
    """
    g = _gray(image)
    h, w = g.shape
    if min_size is None:
        min_size = max(24, min(h, w) // 12)
    boxes, _, weights = cascade(which).detectMultiScale3(g, scaleFactor=scale_factor, minNeighbors=min_neighbors,
                                                         minSize=(min_size, min_size), outputRejectLevels=True)
    out = []
    order = np.argsort([-(b[2] * b[3]) for b in boxes]) if len(boxes) else []
    for i in order:
        box = tuple(int(v) for v in boxes[i])
        det = FaceDetection(box=box, neighbours=int(round(float(weights[i]))) if len(weights) else 0)
        if features:
            det = detect_features(g, det, equalized=True)
        out.append(det)
    return out


def detect_features(image, face: FaceDetection, *, equalized: bool = False) -> FaceDetection:
    """Eyes (upper 60% of the face box) and mouth (smile cascade, lower 40%) of a detected face."""
    g = image if equalized else _gray(image)
    x, y, w, h = face.box
    upper = g[y:y + int(0.6 * h), x:x + w]
    eyes = []
    if upper.size:
        e = cascade("eye").detectMultiScale(upper, scaleFactor=1.1, minNeighbors=5,
                                            minSize=(max(8, w // 10), max(8, w // 10)), maxSize=(w // 2, w // 2))
        e = sorted((tuple(int(v) for v in b) for b in e), key=lambda b: -(b[2] * b[3]))[:2]
        eyes = sorted(((ex + x, ey + y, ew, eh) for ex, ey, ew, eh in e), key=lambda b: b[0])
    y0 = y + int(0.6 * h)
    lower = g[y0:y + h, x:x + w]
    mouth = None
    if lower.size:
        m = cascade("smile").detectMultiScale(lower, scaleFactor=1.1, minNeighbors=15,
                                              minSize=(max(10, w // 5), max(6, h // 10)))
        if len(m):
            mx, my, mw, mh = max((tuple(int(v) for v in b) for b in m), key=lambda b: b[2] * b[3])
            mouth = (mx + x, my + y0, mw, mh)
    return FaceDetection(box=face.box, eyes=eyes, mouth=mouth, neighbours=face.neighbours)


def largest_face_box(image, **kwargs):
    """The largest face box ``(x, y, w, h)`` or None (a detector for :func:`usdface.scan.aam.train_aam`)."""
    faces = detect_faces(image, features=False, **kwargs)
    return faces[0].box if faces else None


def features_dict(image_name: str, size, faces: list[FaceDetection], landmarks: dict | None = None) -> dict:
    """The ``usdface-features/1`` JSON object."""
    out = {"format": FEATURES_FORMAT, "image": image_name, "size": [int(size[0]), int(size[1])],
           "faces": [{"box": list(f.box), "eyes": [list(e) for e in f.eyes],
                      "mouth": list(f.mouth) if f.mouth else None} for f in faces]}
    if landmarks:
        out["landmarks"] = {n: {"image": [round(float(u), 3), round(float(v), 3)]} for n, (u, v) in landmarks.items()}
    return out


def draw_detections(image, faces: list[FaceDetection], landmarks=None, *, names=None, scale: float | None = None,
                    zoom: bool = True):
    """A BGR preview: face boxes (green), eyes (cyan), mouth (magenta), landmarks (yellow dots).

    Parameters
    ----------
    landmarks : ndarray, shape (P, 2), optional
    names : sequence of str, optional
        Labels drawn next to the landmarks.
    scale : float, optional
        Upscale factor for small images (default: so the longer side is at least 768 px).
    zoom : bool
        Crop to the faces (with a margin of half a face) so the landmarks can be seen.
    """
    import cv2

    img = np.asarray(image)
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    if zoom and faces:
        bx = np.array([f.box for f in faces], dtype=np.float64)
        m = 0.5 * bx[:, 2:].max()
        x0 = int(max(0, (bx[:, 0]).min() - m))
        y0 = int(max(0, (bx[:, 1]).min() - m))
        x1 = int(min(img.shape[1], (bx[:, 0] + bx[:, 2]).max() + m))
        y1 = int(min(img.shape[0], (bx[:, 1] + bx[:, 3]).max() + m))
        img = img[y0:y1, x0:x1]

        def sh(b):
            return (b[0] - x0, b[1] - y0, b[2], b[3])

        faces = [FaceDetection(box=sh(f.box), eyes=[sh(e) for e in f.eyes], mouth=sh(f.mouth) if f.mouth else None,
                               neighbours=f.neighbours) for f in faces]
        if landmarks is not None:
            landmarks = np.asarray(landmarks, dtype=np.float64) - [x0, y0]
    h, w = img.shape[:2]
    s = scale or max(1.0, 768.0 / max(h, w))
    out = cv2.resize(img, (int(round(w * s)), int(round(h * s))), interpolation=cv2.INTER_CUBIC) if s != 1 else img.copy()
    th = max(1, int(round(s)))

    def rect(b, col):
        x, y, bw, bh = b
        cv2.rectangle(out, (int(x * s), int(y * s)), (int((x + bw) * s), int((y + bh) * s)), col, th, cv2.LINE_AA)

    for f in faces:
        rect(f.box, (60, 220, 60))
        for e in f.eyes:
            rect(e, (230, 220, 40))
        if f.mouth:
            rect(f.mouth, (220, 60, 220))
    if landmarks is not None:
        for i, (u, v) in enumerate(np.asarray(landmarks, dtype=np.float64)):
            c = (int(round(u * s)), int(round(v * s)))
            cv2.circle(out, c, max(2, int(1.5 * s)), (0, 0, 0), -1, cv2.LINE_AA)
            cv2.circle(out, c, max(1, int(1.0 * s)), (40, 230, 255), -1, cv2.LINE_AA)
            if names is not None:
                cv2.putText(out, str(names[i]), (c[0] + 4, c[1] - 3), cv2.FONT_HERSHEY_SIMPLEX, 0.32, (40, 230, 255), 1,
                            cv2.LINE_AA)
    label = f"{len(faces)} face(s)" if faces else "no face found"
    cv2.putText(out, label, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 2, cv2.LINE_AA)
    return out
