"""Video input: movie files through OpenCV, image sequences through OpenImageIO (or OpenCV).

- Movies (``.mp4``, ``.m4v``, ``.avi``, ``.mov``, ``.mkv``) are decoded with OpenCV's FFmpeg
  back-end; the frame rate comes from the container unless ``rate`` is given.
- Image sequences (``.png``, ``.jpg``, ``.tif``, ``.exr``, ``.dpx``...) are given as a pattern
  ``shot.####.png`` (``#`` = one digit, padded), ``shot.%04d.png``, ``shot.@.png`` (any number),
  or as a folder of images of one suffix. They read through OpenImageIO when it is installed
  (``pip install OpenImageIO``; needed for EXR and DPX), else through OpenCV. Float and 16-bit
  frames are converted to 8 bits (float values 0..1 are taken as display-referred). A sequence
  has no rate of its own: ``rate`` is required.

Every frame comes back as an ``(H, W, 3)`` uint8 BGR array (OpenCV's channel order).

Example
-------
>>> with open_video("face.mp4") as video:                     # doctest: +SKIP
...     print(video.n_frames, video.size, video.rate)
...     for index, frame in video:
...         ...
"""
from __future__ import annotations

import contextlib
import glob
import os
import re
from pathlib import Path

import numpy as np

from ..errors import InputError, OptionError
from ..inputfiles import check_input_file
from .native_output import native_stderr_to_log

__all__ = ["MOVIE_SUFFIXES", "SEQUENCE_SUFFIXES", "VideoReader", "open_video", "is_sequence_pattern", "is_video"]

MOVIE_SUFFIXES = (".mp4", ".m4v", ".avi", ".mov", ".mkv", ".mpg", ".mpeg", ".webm")
SEQUENCE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr", ".dpx", ".bmp")
_NEEDS_OIIO = (".exr", ".dpx")


#: OpenCV's log level while it probes and decodes (its "[ WARN:0@...] global cap.cpp" lines would
#: precede usdface's own one-line error); 2 = ERROR in cv2.utils.logging
_CV2_QUIET_LEVEL = 2


def _cv2():
    # FFmpeg (inside OpenCV) prints "moov atom not found" and the like to stderr; OpenCV reads
    # this variable when its FFmpeg back-end starts (AV_LOG_QUIET = -8). A user who asked for
    # FFmpeg's messages (either variable set) keeps them.
    if "OPENCV_FFMPEG_LOGLEVEL" not in os.environ and "OPENCV_FFMPEG_DEBUG" not in os.environ:
        os.environ["OPENCV_FFMPEG_LOGLEVEL"] = "-8"
    import cv2

    return cv2


def _log_level_functions(cv2):
    """OpenCV's (set, get) log level: ``cv2.utils.logging`` in the builds that have it (4.12 and
    later dropped the top-level ``cv2.setLogLevel``), else the top-level pair; (None, None) when
    the build has neither."""
    for owner in (getattr(getattr(cv2, "utils", None), "logging", None), cv2):
        setter = getattr(owner, "setLogLevel", None)
        if setter is not None:
            return setter, getattr(owner, "getLogLevel", None)
    return None, None


@contextlib.contextmanager
def _quiet(cv2):
    """OpenCV's own warnings off while the block runs (usdface says what went wrong)."""
    setter, getter = _log_level_functions(cv2)
    if setter is None:
        yield
        return
    previous = getter() if getter is not None else None
    returned = setter(_CV2_QUIET_LEVEL)
    previous = returned if previous is None else previous
    try:
        yield
    finally:
        if previous is not None:
            setter(previous)


def _oiio(required_for: str | None = None):
    try:
        import OpenImageIO as oiio
    except ImportError:
        if required_for:
            raise InputError(f"{required_for} needs OpenImageIO: pip install OpenImageIO") from None
        return None
    return oiio


def is_video(path) -> bool:
    """A movie file, an image-sequence pattern (name.####.png) or a folder of frames."""
    p = Path(path)
    return p.suffix.lower() in MOVIE_SUFFIXES or is_sequence_pattern(str(path)) or p.is_dir()


def is_sequence_pattern(path: str) -> bool:
    """True if ``path`` names an image sequence (``#``, ``@`` or ``%0Nd`` placeholder)."""
    name = os.path.basename(str(path))
    return bool(re.search(r"#+|@|%0?\d*d", name))


def _sequence_files(path: str) -> tuple[list[Path], list[int]]:
    """Files and frame numbers of a sequence pattern or a folder, sorted by frame."""
    p = Path(path)
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if f.suffix.lower() in SEQUENCE_SUFFIXES and f.is_file())
        suffixes = {f.suffix.lower() for f in files}
        if len(suffixes) > 1:
            raise InputError(f"video {p}: folder holds images of several kinds ({', '.join(sorted(suffixes))}); "
                             f"give a pattern such as {p}/name.####.png")
        numbers = []
        for i, f in enumerate(files):
            m = re.search(r"(\d+)(?=\D*$)", f.stem)
            numbers.append(int(m.group(1)) if m else i)
        order = np.argsort(numbers, kind="stable")
        return [files[i] for i in order], [numbers[i] for i in order]
    name = p.name
    m = re.search(r"(#+)|(@)|%0?(\d*)d", name)
    head, tail = name[:m.start()], name[m.end():]
    if m.group(1):
        digits = r"\d{%d,}" % len(m.group(1))
    elif m.group(3):
        digits = r"\d{%d,}" % int(m.group(3))
    else:
        digits = r"\d+"
    rx = re.compile("^" + re.escape(head) + "(" + digits + ")" + re.escape(tail) + "$")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"video {path}: folder {folder} does not exist")
    found = []
    for f in glob.glob(os.path.join(glob.escape(str(folder)), glob.escape(head) + "*" + glob.escape(tail))):
        mm = rx.match(os.path.basename(f))
        if mm and os.path.isfile(f):  # a named pipe matching the pattern would block the decoder
            found.append((int(mm.group(1)), Path(f)))
    found.sort()
    return [f for _, f in found], [n for n, _ in found]


def _to_uint8_bgr(img: np.ndarray, *, rgb_order: bool) -> np.ndarray:
    a = np.asarray(img)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.shape[2] == 1:
        a = np.repeat(a, 3, axis=2)
    elif a.shape[2] >= 4:
        a = a[:, :, :3]
    if a.dtype == np.uint8:
        out = a
    elif a.dtype == np.uint16:
        out = (a.astype(np.float32) * (255.0 / 65535.0) + 0.5).astype(np.uint8)
    else:
        f = np.nan_to_num(a.astype(np.float32), nan=0.0, posinf=1.0, neginf=0.0)
        out = (np.clip(f, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    if rgb_order:
        out = out[:, :, ::-1]
    return np.ascontiguousarray(out)


class VideoReader:
    """Frames of a movie or an image sequence, in order.

    Use :func:`open_video` to make one. Iterating yields ``(index, frame)`` with ``index`` 0-based
    and ``frame`` an ``(H, W, 3)`` uint8 BGR array; a reader can be iterated more than once.

    Attributes
    ----------
    source : str
        The path or pattern as given.
    kind : {"movie", "sequence"}
    n_frames : int
        Number of frames (for movies: counted by decoding when the container's count is absent
        or wrong).
    width, height : int
        Frame size in pixels.
    rate : float
        Frames per second.
    first_frame : int
        Frame number of the first image of a sequence (0 for movies).
    """

    def __init__(self, source, *, rate: float | None = None):
        self.source = os.fspath(source)
        if rate is not None and not (np.isfinite(rate) and rate > 0):
            raise OptionError(f"--rate: expected a positive number of frames per second; got {rate}")
        self._files: list[Path] = []
        self.first_frame = 0
        src = self.source
        suffix = Path(src).suffix.lower()
        if is_sequence_pattern(src) or Path(src).is_dir():
            self.kind = "sequence"
            self._files, numbers = _sequence_files(src)
            if not self._files:
                raise InputError(f"video {src}: zero frames (no image matches the pattern)")
            self.first_frame = numbers[0]
            self._suffix = self._files[0].suffix.lower()
            first = self._read_image(self._files[0])
            self.height, self.width = first.shape[:2]
            self.n_frames = len(self._files)
            if rate is None:
                raise OptionError(f"video {src}: an image sequence has no frame rate: pass --rate HZ")
            self.rate = float(rate)
            return
        p = check_input_file(src, label=f"video {src}")
        if suffix in SEQUENCE_SUFFIXES:
            raise InputError(f"video {src}: a single image, not a video; for an image sequence give a pattern "
                             f"such as name.####{suffix}")
        if p.stat().st_size == 0:
            raise InputError(f"video {src}: the file is empty (0 bytes)")
        self.kind = "movie"
        cv2 = _cv2()
        with _quiet(cv2):
            cap = cv2.VideoCapture(src, cv2.CAP_FFMPEG)
            try:
                if not cap.isOpened():
                    raise InputError(f"video {src}: cannot be opened as a video (truncated, or not one of "
                                     f"{', '.join(MOVIE_SUFFIXES)}; an image sequence is given as a pattern)")
                ok, frame = cap.read()
                if not ok or frame is None:
                    raise InputError(f"video {src}: zero frames (nothing could be decoded)")
                self.height, self.width = frame.shape[:2]
                container_rate = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
                count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
            finally:
                cap.release()
        if rate is not None:
            self.rate = float(rate)
        elif np.isfinite(container_rate) and 0 < container_rate < 10000:
            self.rate = container_rate
        else:
            raise OptionError(f"video {src}: the container has no frame rate: pass --rate HZ")
        if count <= 0:
            count = sum(1 for _ in self._decode())
        self.n_frames = count

    # -- sequence frames --------------------------------------------------------------------------
    def _read_image(self, path: Path) -> np.ndarray:
        suffix = path.suffix.lower()
        oiio = _oiio(f"video frame {path} ({suffix})" if suffix in _NEEDS_OIIO else None)
        if oiio is not None:
            inp = oiio.ImageInput.open(str(path))
            if inp is None:
                raise InputError(f"video frame {path}: cannot be read ({oiio.geterror().strip()})")
            try:
                spec = inp.spec()
                fmt = oiio.UINT8 if spec.format == oiio.TypeDesc("uint8") else (
                    oiio.UINT16 if spec.format == oiio.TypeDesc("uint16") else oiio.FLOAT)
                data = inp.read_image(0, 0, 0, min(spec.nchannels, 3), fmt)
            finally:
                inp.close()
            if data is None:
                raise InputError(f"video frame {path}: cannot be decoded")
            return _to_uint8_bgr(np.asarray(data), rgb_order=True)
        cv2 = _cv2()
        with native_stderr_to_log(f"video frame {path}"):  # libpng's warnings
            img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise InputError(f"video frame {path}: cannot be read as an image")
        return _to_uint8_bgr(img, rgb_order=False)

    # -- movie frames ------------------------------------------------------------------------------
    def _decode(self):
        cv2 = _cv2()
        with _quiet(cv2):
            cap = cv2.VideoCapture(self.source, cv2.CAP_FFMPEG)
        try:
            while True:
                with _quiet(cv2):
                    ok, frame = cap.read()
                if not ok or frame is None:
                    return
                yield frame
        finally:
            cap.release()

    # -- public ------------------------------------------------------------------------------------
    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return self.width, self.height

    def __len__(self) -> int:
        return self.n_frames

    def __iter__(self):
        if self.kind == "sequence":
            for i, f in enumerate(self._files):
                img = self._read_image(f)
                if img.shape[:2] != (self.height, self.width):
                    raise InputError(f"video {self.source}: frame {f.name} is {img.shape[1]}x{img.shape[0]}; "
                                     f"the first frame is {self.width}x{self.height}")
                yield i, img
            return
        n = 0
        for n, frame in enumerate(self._decode()):
            yield n, frame
        # containers sometimes over-report the count; trust what was decoded
        if n + 1 < self.n_frames:
            self.n_frames = n + 1

    def read(self, index: int = 0) -> np.ndarray:
        """One frame by index (a sequence reads that file; a movie decodes up to it)."""
        if not 0 <= index < self.n_frames:
            raise OptionError(f"video {self.source}: frame {index} outside 0..{self.n_frames - 1}")
        if self.kind == "sequence":
            return self._read_image(self._files[index])
        cv2 = _cv2()
        with _quiet(cv2):
            cap = cv2.VideoCapture(self.source, cv2.CAP_FFMPEG)
            try:
                if index:
                    cap.set(cv2.CAP_PROP_POS_FRAMES, index)
                ok, frame = cap.read()
            finally:
                cap.release()
        if not ok:
            raise InputError(f"video {self.source}: frame {index} cannot be decoded")
        return frame

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def __repr__(self) -> str:
        return (f"VideoReader({self.source!r}, kind={self.kind!r}, n_frames={self.n_frames}, "
                f"size={self.width}x{self.height}, rate={self.rate:g})")


def open_video(path, *, rate: float | None = None) -> VideoReader:
    """Open a movie file or an image sequence.

    Parameters
    ----------
    path : str or os.PathLike
        A movie (``.mp4``, ``.avi``, ``.mov``...), an image sequence pattern (``name.####.png``,
        ``name.%04d.exr``, ``name.@.dpx``) or a folder of images.
    rate : float, optional
        Frames per second; overrides the container's rate; required for image sequences.

    Returns
    -------
    VideoReader

    Raises
    ------
    InputError
        Missing or unreadable file, or zero frames.
    OptionError
        Bad or missing ``rate``.
    """
    return VideoReader(path, rate=rate)
