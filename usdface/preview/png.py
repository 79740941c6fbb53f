"""PNG output: atomic files and in-memory bytes."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import InputError, OptionError
from ._common import _cv2


def encode_jpeg(image: np.ndarray, quality: int = 88) -> bytes:
    """JPEG bytes of a BGR uint8 image (pictures embedded in reports: about 5x smaller than PNG
    on shaded renders)."""
    cv2 = _cv2()
    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(image), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise OptionError(f"cannot encode an image of shape {np.shape(image)} as JPEG")
    return buf.tobytes()


def encode_png(image: np.ndarray) -> bytes:
    """PNG bytes of a BGR (OpenCV order) uint8 image (for embedding in HTML)."""
    cv2 = _cv2()
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(image))
    if not ok:
        raise OptionError(f"cannot encode an image of shape {np.shape(image)} as PNG")
    return buf.tobytes()


def write_png(path, image: np.ndarray) -> Path:
    """Write an image as PNG atomically.

    The image goes to a temporary ``.png`` file in the destination folder, is flushed to disk
    (fsync), renamed over ``path`` (``os.replace``: readers see the old file or the new one, never
    a partial one) and given mode 0644.

    Parameters
    ----------
    path : str or Path
        Destination, ending in ``.png``; its folder must exist.
    image : ndarray, shape (H, W), (H, W, 3) or (H, W, 4), uint8 or uint16
        Channel order BGR / BGRA (OpenCV's).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        The folder does not exist or is not writable, or the file cannot be replaced.
    OptionError
        ``path`` does not end in ``.png`` or ``image`` is not an image array.
    ResourceError
        The disk is full.
    """
    cv2 = _cv2()
    path = Path(os.fspath(path))
    if path.suffix.lower() != ".png":
        raise OptionError(f"PNG output {str(path)!r} must end in .png")
    img = np.asarray(image)
    if not (img.ndim == 2 or (img.ndim == 3 and img.shape[2] in (1, 3, 4))) or img.size == 0:
        raise OptionError(f"cannot write {str(path)!r}: image must have shape (H, W), (H, W, 3) or (H, W, 4); "
                          f"got {img.shape}")
    if img.dtype not in (np.uint8, np.uint16):
        raise OptionError(f"cannot write {str(path)!r}: image must be uint8 or uint16; got {img.dtype}")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"cannot write PNG {str(path)!r}: folder {str(folder)!r} does not exist")
    if path.is_dir():
        raise InputError(f"cannot write PNG {str(path)!r}: it is a folder")
    try:
        ok, encoded = cv2.imencode(".png", np.ascontiguousarray(img))
    except cv2.error as exc:
        raise InputError(f"cannot write PNG {str(path)!r}: OpenCV failed: {exc}") from exc
    if not ok:
        raise InputError(f"cannot write PNG {str(path)!r}: OpenCV could not encode the image")
    from ..fileutil import atomic_write

    with atomic_write(path, "wb") as fh:  # file-system failures: one WriteError naming the file and cause
        fh.write(encoded.tobytes())
    return path
