"""Review media: H.264 movies (PyAV, the ``media`` extra) written atomically and read back.

No pxr and no cv2 here; PyAV is imported on first use, so ``import usdface`` works without it and
a missing encoder fails with the extra to install named.
"""
from ..lazy import lazy_exports

_EXPORTS = {"MOVIE_SUFFIXES": "formats", "MovieWriter": "movie", "movie_info": "movie", "read_movie": "movie",
            "require_encoder": "movie"}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())

__all__ = ["MOVIE_SUFFIXES", "MovieWriter", "movie_info", "read_movie", "require_encoder"]
