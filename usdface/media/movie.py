"""H.264 movies that browsers and editors play, written and read back with PyAV.

PyAV (pip ``av``, BSD-3-Clause) ships FFmpeg and the x264 encoder inside its wheel, so no system
FFmpeg is needed: ``pip install "usdface[media]"``. Movies are H.264 (libx264), yuv420p (the
chroma layout every player decodes), in an .mp4 whose index sits at the front (``faststart``,
so a browser starts playing before the whole file has arrived), one frame per time sample at a
constant rate. OpenCV's ``mp4v`` writer is not used: browsers do not play MPEG-4 part 2.

Writes are atomic: frames go to a temporary file in the destination folder, which is renamed
over the destination only when the movie is complete; a failure or an interruption removes it.
"""
from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path

import numpy as np

from ..errors import DependencyError, InputError, OptionError, ResourceError
from ..fileutil import fsync_dir, fsync_file, set_default_mode, temporary_path
from .formats import MOVIE_SUFFIXES, X264_PRESETS  # noqa: F401 (X264_PRESETS re-exported)


__all__ = ["MOVIE_SUFFIXES", "MovieWriter", "movie_info", "read_movie", "require_encoder"]

#: the extra that installs PyAV
EXTRA = "media"
_INSTALL = f'pip install "usdface[{EXTRA}]" (PyAV, which ships FFmpeg with the x264 encoder in its wheel)'


def _av():
    try:
        import av
    except ImportError as exc:
        raise DependencyError(f"movies need PyAV, which is not installed: {_INSTALL}") from exc
    return av


def require_encoder(codec: str = "libx264"):
    """PyAV, checked to have the H.264 encoder; a clear error naming what to install otherwise."""
    av = _av()
    try:
        av.codec.Codec(codec, "w")
    except Exception:  # av raises its own UnknownCodecError (a ValueError subclass in some versions)
        raise DependencyError(f"the FFmpeg inside PyAV {getattr(av, '__version__', '?')} has no {codec} (H.264) "
                              f"encoder: {_INSTALL}; a PyAV built against a system FFmpeg without x264 cannot "
                              "write browser-playable movies") from None
    return av


def rate_fraction(rate: float) -> Fraction:
    """The frame rate as a fraction (29.97 -> 30000/1001, 60 -> 60)."""
    r = float(rate)
    if not (np.isfinite(r) and 0 < r <= 1000):
        raise OptionError(f"movie frame rate {rate}: expected 0 < rate <= 1000")
    if abs(round(r) - r) < 1e-6 * r:
        return Fraction(round(r))
    num = round(r * 1.001)  # NTSC-style rates written to 2-3 decimals: 29.97, 59.94, 23.976
    if num % 1 == 0 and abs(num * 1000 / 1001 - r) < 1e-4 * r:
        return Fraction(num * 1000, 1001)
    return Fraction(r).limit_denominator(100000)


class MovieWriter:
    """Write BGR frames (OpenCV order) into an H.264 mp4, atomically.

    Parameters
    ----------
    path : str or Path
        Destination, ``.mp4`` (or ``.m4v``/``.mov``); its folder must exist and be writable.
    size : (int, int)
        Frame (width, height) in pixels; both even (yuv420p halves the chroma planes).
    rate : float
        Frames per second (one frame per time sample).
    crf : int
        x264 constant rate factor (0 lossless .. 51; 18 looks lossless on these renders).
    preset : str
        x264 speed/size trade-off (``ultrafast`` .. ``veryslow``).
    threads : int
        Encoder threads (0: FFmpeg's choice).

    Use as a context manager: ``with MovieWriter(p, (960, 540), 60) as w: w.write(img)``; the
    movie exists at ``path`` only after a clean exit.
    """

    def __init__(self, path, size, rate: float, *, crf: int = 18, preset: str = "veryfast", threads: int = 0,
                 metadata: dict | None = None):
        self.path = Path(os.fspath(path))
        if self.path.suffix.lower() not in MOVIE_SUFFIXES:
            raise OptionError(f"-o {self.path}: a movie is an .mp4 file (H.264)")
        w, h = (int(v) for v in size)
        if w < 16 or h < 16 or w % 2 or h % 2:
            raise OptionError(f"--size {w}x{h}: H.264 (yuv420p) needs an even width and height, 16 or more")
        if not 0 <= int(crf) <= 51:
            raise OptionError(f"crf {crf}: expected 0..51")
        self.size = (w, h)
        self.rate = rate_fraction(rate)
        self._av = require_encoder()
        folder = self.path.parent if str(self.path.parent) else Path(".")
        if not folder.is_dir():
            raise InputError(f"cannot write movie {self.path}: folder {folder} does not exist")
        if self.path.is_dir():
            raise InputError(f"cannot write movie {self.path}: it is a folder")
        # the one temporary scheme (usdface.fileutil): named for its owner, so the next writer of this
        # movie removes what a killed one left; made here so a folder that takes no file fails now
        tmp = temporary_path(self.path)
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        except OSError as exc:
            raise InputError(f"cannot write movie {self.path}: {exc.strerror or exc}") from None
        self._tmp = tmp
        self.frames = 0
        try:
            self._container = self._av.open(str(self._tmp), "w", format="mp4", options={"movflags": "+faststart"})
            for k, v in (metadata or {}).items():
                self._container.metadata[str(k)] = str(v)
            stream = self._container.add_stream("libx264", rate=self.rate)
            stream.width, stream.height = w, h
            stream.pix_fmt = "yuv420p"
            stream.options = {"crf": str(int(crf)), "preset": str(preset)}
            stream.thread_count = int(threads)
            stream.codec_context.time_base = Fraction(1, 1) / self.rate
            self._stream = stream
        except BaseException:
            self._discard()
            raise

    def write(self, image: np.ndarray) -> None:
        """Append one (H, W, 3) uint8 BGR frame of the writer's size."""
        img = np.asarray(image)
        if img.shape != (self.size[1], self.size[0], 3) or img.dtype != np.uint8:
            raise OptionError(f"movie frame {self.frames}: expected ({self.size[1]}, {self.size[0]}, 3) uint8; "
                              f"got {img.shape} {img.dtype}")
        frame = self._av.VideoFrame.from_ndarray(np.ascontiguousarray(img), format="bgr24")
        frame.pts = self.frames
        self._mux(self._stream.encode(frame))
        self.frames += 1

    def _write_failure(self, exc: OSError):
        if exc.errno == 28:
            return ResourceError(f"cannot write movie {self.path}: disk full")
        return InputError(f"cannot write movie {self.path}: {exc.strerror or exc}")

    def _mux(self, packets) -> None:
        try:
            self._container.mux(packets)
        except OSError as exc:
            raise self._write_failure(exc) from None

    def close(self) -> Path:
        """Flush the encoder, finish the file and rename it into place; any failure or interruption
        on the way (the last packets, the faststart rewrite of the whole file) removes the temporary."""
        if self.frames == 0:
            self._discard()
            raise InputError(f"movie {self.path}: no frames to write")
        try:
            self._mux(self._stream.encode())
            self._container.close()
            self._container = None
            fsync_file(self._tmp)
            set_default_mode(self._tmp)
            os.replace(self._tmp, self.path)
        except OSError as exc:
            self._discard()
            raise self._write_failure(exc) from None
        except BaseException:  # an error above, or SIGINT/SIGTERM/SIGHUP (Interrupted)
            self._discard()
            raise
        fsync_dir(self.path.parent if str(self.path.parent) else ".")
        return self.path

    def _discard(self) -> None:
        container = getattr(self, "_container", None)
        if container is not None:
            try:
                container.close()
            except Exception:  # an encoder error leaves the container half-open: the file goes anyway
                pass
            self._container = None
        try:
            self._tmp.unlink()
        except (OSError, AttributeError):
            pass

    def __enter__(self) -> "MovieWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            self.close()
        else:
            self._discard()
        return False


def movie_info(path) -> dict:
    """Codec, pixel format, size, rate, frame count and duration of a movie's video stream."""
    av = _av()
    path = Path(path)
    if not path.is_file():
        raise InputError(f"movie {path}: no such file")
    try:
        with av.open(str(path)) as c:
            s = c.streams.video[0]
            info = {"codec": s.codec_context.name, "pixelFormat": s.codec_context.pix_fmt,
                    "width": s.codec_context.width, "height": s.codec_context.height,
                    "rate": float(s.average_rate) if s.average_rate else None, "frames": int(s.frames),
                    "duration": float(s.duration * s.time_base) if s.duration else None,
                    "format": c.format.name}
    except (av.error.FFmpegError if hasattr(av, "error") else OSError, IndexError) as exc:
        raise InputError(f"movie {path}: cannot be read ({exc})") from None
    return info


def read_movie(path, *, every: int = 1):
    """Yield ``(index, bgr_image)`` for every ``every``-th decoded frame of a movie (all by default)."""
    av = _av()
    with av.open(str(path)) as c:
        for i, frame in enumerate(c.decode(video=0)):
            if i % every == 0:
                yield i, frame.to_ndarray(format="bgr24")
