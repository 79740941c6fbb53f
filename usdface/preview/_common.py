"""Small helpers shared by the preview modules: OpenCV on first use, colour arguments, the
compiled kernels."""
from __future__ import annotations

from ..errors import OptionError, UsdFaceError


def _cv2():
    try:
        import cv2
    except ImportError as exc:  # pragma: no cover - cv2 is a dependency of usdface
        raise UsdFaceError("usdface previews need OpenCV: pip install opencv-contrib-python-headless") from exc
    return cv2


def _compiled():
    """The numba kernels module, or None without numba (imported on first use: numba is slow to import)."""
    from . import _kernels

    return _kernels if _kernels.AVAILABLE else None


def _rgb(c, what: str) -> tuple[int, int, int]:
    try:
        r, g, b = (int(round(float(v))) for v in c)
    except (TypeError, ValueError):
        raise OptionError(f"preview: {what} must be an (r, g, b) colour in 0..255; got {c!r}") from None
    if not all(0 <= v <= 255 for v in (r, g, b)):
        raise OptionError(f"preview: {what} must be an (r, g, b) colour in 0..255; got {c!r}")
    return r, g, b


def _bgr(rgb) -> tuple[int, int, int]:
    return int(rgb[2]), int(rgb[1]), int(rgb[0])
