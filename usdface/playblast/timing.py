"""Which time code of each shot, and which frame of a source video, every playblast frame shows.

Pure functions on numbers (no USD, no images), and :func:`video_timing`, which reads what the run
recorded in the ``summary.json`` beside the shot.

- A playblast has one frame per time sample of its (first) shot, at that shot's rate, over
  ``--range FIRST LAST`` (time codes, inclusive) or the whole shot.
- A second shot side by side is aligned in **seconds** from each shot's time code 0 (time codes
  are frame indices from 0 unless ``--start-frame`` moved them; D2): its nearest time sample is
  shown. Where it has none (it is shorter, or starts later), its nearest end frame is **held**
  and the panel says so; the movie is as long as the first shot's range, never cut short.
- A source video: playblast frame ``k`` (the ``k``-th time sample from the shot's first) shows
  the video frame at ``trim_start / source_rate + k / rate`` seconds, so with no resampling it is
  video frame ``k + trim_start``; frames past the video's end are shown as missing.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import OptionError

__all__ = ["Alignment", "VideoTiming", "align_shots", "shot_times", "summary_beside", "video_frame_indices",
           "video_timing"]


def shot_times(start: int, end: int, frame_range=None, *, what: str = "shot") -> np.ndarray:
    """Time codes ``start..end`` (inclusive), or the sub-range ``frame_range = (first, last)``.

    Raises
    ------
    OptionError
        The range is reversed or reaches outside the shot.
    """
    start, end = int(start), int(end)
    if end < start:
        raise OptionError(f"{what}: empty time range {start}..{end}")
    if frame_range is None:
        return np.arange(start, end + 1)
    first, last = (int(v) for v in frame_range)
    if last < first:
        raise OptionError(f"--range {first} {last}: the last frame comes before the first")
    if first < start or last > end:
        raise OptionError(f"--range {first} {last}: outside the {what}'s frames {start}..{end} (time codes)")
    return np.arange(first, last + 1)


@dataclass(frozen=True)
class Alignment:
    """Time codes of a second shot for each playblast frame.

    Attributes
    ----------
    times : ndarray (F,) int
        The second shot's time code shown (clamped into its range).
    held : ndarray (F,) bool
        True where the second shot has no sample at that moment and holds its nearest end frame.
    """

    times: np.ndarray
    held: np.ndarray

    @property
    def n_held(self) -> int:
        return int(self.held.sum())


def align_shots(times: np.ndarray, rate: float, other_start: int, other_end: int, other_rate: float) -> Alignment:
    """Align a second shot (time codes ``other_start..other_end`` at ``other_rate``) with
    playblast time codes ``times`` of a shot at ``rate``: the same moment in seconds."""
    if not (rate > 0 and other_rate > 0):
        raise OptionError(f"shot rates must be positive; got {rate} and {other_rate}")
    t = np.asarray(times, dtype=np.float64)
    # exact when the rates are equal (no float round trip through seconds)
    want = t if rate == other_rate else np.floor(t * (other_rate / rate) + 0.5 + 1e-9)
    want = want.astype(np.int64)
    shown = np.clip(want, int(other_start), int(other_end))
    return Alignment(times=shown, held=shown != want)


@dataclass(frozen=True)
class VideoTiming:
    """How a shot's frames map to its source video (what the run recorded).

    Attributes
    ----------
    trim_start : int
        Source frames cut from the start (``--trim START``).
    source_rate : float
        Frame rate of the source before any resampling (the video's, for a video capture).
    rate : float
        The shot's rate (differs from ``source_rate`` after ``--resample``).
    shot_start : int
        The shot's first time code (``--start-frame``; 0 by default).
    recorded : bool
        False when the shot recorded nothing and the identity mapping was assumed.
    """

    trim_start: int = 0
    source_rate: float | None = None
    rate: float | None = None
    shot_start: int = 0
    recorded: bool = True


def video_frame_indices(times: np.ndarray, timing: VideoTiming, *, video_rate: float,
                        video_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Video frame index for each playblast time code, and whether the video has that frame.

    Returns
    -------
    index : ndarray (F,) int
        ``round((trim_start / source_rate + (t - shot_start) / rate) * video_rate)``; equal to
        ``t - shot_start + trim_start`` when all three rates agree.
    present : ndarray (F,) bool
        ``0 <= index < video_frames``.
    """
    k = np.asarray(times, dtype=np.int64) - int(timing.shot_start)
    rate = float(timing.rate or video_rate)
    source_rate = float(timing.source_rate or video_rate)
    if rate == source_rate == float(video_rate):
        index = k + int(timing.trim_start)
    else:
        # in video frames directly (not through seconds), nearest frame, halves rounded up
        pos = timing.trim_start * (float(video_rate) / source_rate) + k * (float(video_rate) / rate)
        index = np.floor(pos + 0.5 + 1e-9).astype(np.int64)
    present = (index >= 0) & (index < int(video_frames))
    return index, present


def summary_beside(shot_path) -> dict | None:
    """The run's ``summary.json`` beside a shot (None when missing or unreadable)."""
    from ..errors import UsdFaceError
    from ..inputfiles import read_json

    p = Path(shot_path).parent / "summary.json"
    if not p.is_file():
        return None
    try:
        data = read_json(p, label=str(p))  # bounded size and nesting (a shot folder is not always ours)
    except UsdFaceError:
        return None
    return data if isinstance(data, dict) else None


def video_timing(shot_path, *, shot_start: int, rate: float) -> VideoTiming:
    """How the shot's frames map to its source video, from the run's summary.json beside the shot.

    The run records ``steps.import-capture.reports.timing`` (trim start, source rate, resampled
    rate, first time code); older shots fall back to the options in its provenance and the
    tracker's rate. Without a summary the identity mapping is assumed (``recorded=False``).
    """
    summary = summary_beside(Path(shot_path))
    if summary is None:
        return VideoTiming(trim_start=0, source_rate=None, rate=rate, shot_start=shot_start, recorded=False)
    cap = summary.get("steps", {}).get("import-capture", {})
    rec = cap.get("reports", {}).get("timing")
    if rec:
        return VideoTiming(trim_start=int(rec.get("trimStart") or 0), source_rate=rec.get("sourceRate"),
                           rate=rec.get("rate") or rate, shot_start=int(rec.get("startTimeCode", shot_start)))
    options = summary.get("provenance", {}).get("options", {})
    if isinstance(options, str):
        try:
            options = json.loads(options)
        except ValueError:
            options = {}
    trim = options.get("trim") or [0, None]
    source_rate = summary.get("steps", {}).get("track", {}).get("rate")
    if source_rate is None and not options.get("resample"):
        source_rate = cap.get("rate", rate)
    return VideoTiming(trim_start=int(trim[0] or 0), source_rate=source_rate, rate=cap.get("rate", rate),
                       shot_start=int(cap.get("startTimeCode", shot_start)), recorded=source_rate is not None)
