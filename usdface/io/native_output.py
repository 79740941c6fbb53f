"""What C libraries print on stderr while usdface reads a file, kept off the user's terminal.

OpenCV's image codecs print straight to file descriptor 2, past Python: libpng writes "libpng
warning: iCCP: known incorrect sRGB profile" for many ordinary PNGs (the astronaut photo of the
shared data) and "libpng error: PNG input buffer is incomplete" before usdface's own one-line
error about a truncated file. No setting turns these off (OpenCV's log level and
OPENCV_FFMPEG_LOGLEVEL cover its own and FFmpeg's messages, not libpng's), so
:func:`native_stderr_to_log` points descriptor 2 at a temporary file while a decoder runs and
passes what was written to the log at debug level (``-vv`` shows it), naming the file read.
"""
from __future__ import annotations

import contextlib
import logging
import os
import sys
import tempfile
import threading

__all__ = ["native_stderr_to_log"]

log = logging.getLogger("usdface.io")

_lock = threading.RLock()
_depth = 0


@contextlib.contextmanager
def native_stderr_to_log(what: str):
    """Descriptor 2 goes to a temporary file while the block runs (the outermost block, when
    nested or used from several threads); its text is logged at debug level as ``"<what>: line"``.

    Python's own ``sys.stderr`` is flushed first; anything Python writes to it during the block is
    logged the same way (blocks are short: one decode call).
    """
    global _depth
    with _lock:
        outer = _depth == 0
        _depth += 1
        saved = capture = None
        if outer:
            try:
                sys.stderr.flush()
                capture = tempfile.TemporaryFile()
                saved = os.dup(2)
                os.dup2(capture.fileno(), 2)
            except (OSError, ValueError, AttributeError):  # no descriptor 2 (a daemon), or no room
                if capture is not None:
                    capture.close()
                saved = capture = None
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if saved is not None:
                with contextlib.suppress(OSError, ValueError, AttributeError):
                    sys.stderr.flush()
                os.dup2(saved, 2)
                os.close(saved)
                capture.seek(0)
                text = capture.read(1 << 16).decode("utf-8", "replace")
                capture.close()
                for line in text.splitlines():
                    if line.strip():
                        log.debug("%s: %s", what, line.strip())
