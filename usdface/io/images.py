"""Read and write images and float maps (disparity, depth).

- 8/16-bit images (PNG, JPEG, TIFF, BMP...) go through OpenCV; arrays come back in OpenCV's
  channel order (BGR) unless ``rgb=True``.
- Float maps (disparity, depth) are written as OpenEXR (``.exr``, float32, one channel ``Y``,
  NaN kept) through OpenImageIO (``pip install OpenImageIO``), as 32-bit float TIFF (``.tif``,
  OpenCV), as PFM (``.pfm``, written here; NaN kept) or as NumPy ``.npy``; and read back from those
  and from ``.npz`` (first array, or ``key``).

Every write is atomic: a temporary file in the destination folder, then ``os.replace``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import FormatError, InputError, OptionError, UsdFaceError
from ..fileutil import atomic_path, check_output_file
from ..inputfiles import check_input_file
from .native_output import native_stderr_to_log

__all__ = ["IMAGE_SUFFIXES", "FLOAT_MAP_SUFFIXES", "read_image", "write_image", "read_float_map",
           "write_float_map", "check_image_output"]

#: suffixes :func:`read_image` / :func:`write_image` handle (8- or 16-bit)
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".ppm", ".pgm", ".webp")
#: suffixes of :func:`write_float_map`
FLOAT_MAP_SUFFIXES = (".exr", ".tif", ".tiff", ".pfm", ".npy")


def _cv2():
    import cv2

    return cv2


def _oiio():
    try:
        import OpenImageIO as oiio
    except ImportError as exc:
        raise UsdFaceError("EXR files need OpenImageIO: pip install OpenImageIO "
                           "(or write the map as .tif, .pfm or .npy)") from exc
    return oiio


def check_image_output(path, *, suffixes=IMAGE_SUFFIXES, option: str = "-o") -> Path:
    """Validate an output image path before any work (suffix, existing writable folder)."""
    return check_output_file(path, suffixes=suffixes, option=option)


def read_image(path, *, gray: bool = False, rgb: bool = False) -> np.ndarray:
    """Read an image file.

    Parameters
    ----------
    path : str or os.PathLike
    gray : bool
        Convert to one channel.
    rgb : bool
        Return RGB channel order instead of OpenCV's BGR.

    Returns
    -------
    ndarray, shape (H, W) or (H, W, 3), uint8 or uint16
        Alpha channels are dropped.

    Raises
    ------
    InputError
        Missing or unreadable file.
    """
    cv2 = _cv2()
    p = check_input_file(path, label=f"image {path}")
    data = np.fromfile(str(p), dtype=np.uint8)
    with native_stderr_to_log(f"image {p}"):  # libpng's warnings (usdface.io.native_output)
        img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if img is None:
        raise InputError(f"image {p}: cannot be read as an image (expected {', '.join(IMAGE_SUFFIXES)})")
    if img.ndim == 3 and img.shape[2] == 4:
        img = img[..., :3]
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[..., 0]
    if gray and img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    elif rgb and img.ndim == 3:
        img = img[..., ::-1].copy()
    return img


def write_image(path, image: np.ndarray, *, rgb: bool = False) -> Path:
    """Write an 8- or 16-bit image atomically (format from the suffix).

    Parameters
    ----------
    path : str or os.PathLike
    image : ndarray, shape (H, W) or (H, W, 3), uint8 or uint16
        BGR unless ``rgb=True``.
    """
    cv2 = _cv2()
    p = check_image_output(path)
    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.uint16):
        raise OptionError(f"write_image {p}: expected uint8 or uint16 pixels; got {img.dtype}")
    if rgb and img.ndim == 3:
        img = img[..., ::-1]
    ok, buf = cv2.imencode(p.suffix.lower(), np.ascontiguousarray(img))
    if not ok:
        raise InputError(f"could not encode {p}")
    with atomic_path(p) as tmp:
        buf.tofile(str(tmp))
    return p


def _write_pfm(path: Path, a: np.ndarray) -> None:
    h, w = a.shape
    with open(path, "wb") as f:
        f.write(f"Pf\n{w} {h}\n-1.0\n".encode("ascii"))  # negative scale: little-endian
        f.write(np.ascontiguousarray(a[::-1], dtype="<f4").tobytes())  # PFM rows go bottom-up


def _read_pfm(path: Path) -> np.ndarray:
    with open(path, "rb") as f:
        kind = f.readline(16).strip()
        if kind not in (b"Pf", b"PF"):
            raise FormatError(f"float map {path}: not a PFM file")
        try:
            dims = f.readline(64).split()
            scale = float(f.readline(64))
            w, h = int(dims[0]), int(dims[1])
            if w <= 0 or h <= 0 or scale == 0 or not np.isfinite(scale):
                raise ValueError
        except (ValueError, IndexError):
            raise FormatError(f"float map {path}: PFM header needs 'width height' (> 0) and a non-zero "
                              f"scale") from None
        ch = 3 if kind == b"PF" else 1
        size = path.stat().st_size - f.tell()
        if size != 4 * w * h * ch:  # before reading: the header's size against the file's
            raise FormatError(f"float map {path}: the header announces {w}x{h}x{ch} floats ({4 * w * h * ch:,} "
                              f"bytes) but the file holds {size:,} bytes")
        a = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    a = a.reshape(h, w, ch)[::-1]
    return np.ascontiguousarray(a[..., 0] if ch == 1 else a, dtype=np.float32)


def write_float_map(path, values: np.ndarray, *, option: str = "--disparity") -> Path:
    """Write a float map (H, W) as float32, atomically; NaN marks unknown pixels.

    Parameters
    ----------
    path : str or os.PathLike
        ``.exr`` (OpenImageIO), ``.tif``/``.tiff`` (32-bit float), ``.pfm`` or ``.npy``.
    values : ndarray, shape (H, W), float
    """
    p = check_image_output(path, suffixes=FLOAT_MAP_SUFFIXES, option=option)
    a = np.asarray(values, dtype=np.float32)
    if a.ndim != 2:
        raise OptionError(f"{option} {p}: expected a 2-D map; got shape {a.shape}")
    suffix = p.suffix.lower()
    with atomic_path(p) as tmp:
        if suffix == ".exr":
            oiio = _oiio()
            spec = oiio.ImageSpec(a.shape[1], a.shape[0], 1, oiio.FLOAT)
            spec.channelnames = ("Y",)
            spec.attribute("compression", "zip")
            out = oiio.ImageOutput.create(str(tmp))
            if out is None or not out.open(str(tmp), spec):
                raise InputError(f"cannot write {p}: {oiio.geterror()}")
            ok = out.write_image(np.ascontiguousarray(a.reshape(a.shape[0], a.shape[1], 1)))
            out.close()
            if not ok:
                raise InputError(f"cannot write {p}: {oiio.geterror()}")
        elif suffix in (".tif", ".tiff"):
            ok, buf = _cv2().imencode(suffix, np.ascontiguousarray(a))
            if not ok:
                raise InputError(f"could not encode {p}")
            buf.tofile(str(tmp))
        elif suffix == ".pfm":
            _write_pfm(tmp, a)
        else:
            with open(tmp, "wb") as f:
                np.save(f, a)
    return p


def read_float_map(path, *, key: str | None = None) -> np.ndarray:
    """Read a float map written by :func:`write_float_map` (or a float image, or an .npz array).

    Returns
    -------
    ndarray, shape (H, W), float32
    """
    p = check_input_file(path, label=f"float map {path}")
    suffix = p.suffix.lower()
    if suffix == ".exr":
        oiio = _oiio()
        inp = oiio.ImageInput.open(str(p))
        if inp is None:
            raise InputError(f"float map {p}: cannot be read ({oiio.geterror()})")
        a = inp.read_image(oiio.FLOAT)
        inp.close()
        a = np.asarray(a, dtype=np.float32)
        return a[..., 0] if a.ndim == 3 else a
    if suffix == ".pfm":
        return _read_pfm(p)
    if suffix == ".npy":
        try:  # a header announcing more than the file holds fails here, before any allocation
            a = np.load(p, allow_pickle=False, mmap_mode="r")
        except (ValueError, OSError) as exc:
            raise FormatError(f"float map {p}: not a readable .npy array ({exc})") from None
    elif suffix == ".npz":
        from .npz import load_npz, npz_members

        names = list(npz_members(p, label=f"float map {p}"))
        if not names:
            raise FormatError(f"float map {p}: the archive is empty")
        if key is not None and key not in names:
            raise FormatError(f"float map {p}: no array {key!r}; it has {', '.join(names)}")
        a = load_npz(p, label=f"float map {p}")[key or names[0]]
    else:
        cv2 = _cv2()
        with native_stderr_to_log(f"float map {p}"):
            a = cv2.imdecode(np.fromfile(str(p), dtype=np.uint8), cv2.IMREAD_UNCHANGED)
        if a is None:
            raise InputError(f"float map {p}: cannot be read")
    a = np.asarray(a, dtype=np.float32)
    if a.ndim == 3:
        a = a[..., 0]
    if a.ndim != 2:
        raise FormatError(f"float map {p}: expected a 2-D array; got shape {a.shape}")
    return a
