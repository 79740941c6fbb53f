"""Expressions and contraction timelines (seed 001 §5.3-5.4).

"Expressions are the combination of various muscle contractions ... To animate the face from a
neutral state, one needs only to progressively scale these contraction values from zero to unity
over time." A preset is a set of contractions (and a jaw opening); :func:`expression_timeline`
ramps it from 0 to 1 and holds it. A :class:`Timeline` is keyframed contractions per muscle,
linear between keys; it reads and writes the timeline JSON::

    {"rate": 24,
     "keys": {"zygomaticMajor_L": [[0, 0.0], [12, 1.0], [36, 1.0], [48, 0.0]],
              "zygomaticMajor_R": [[0, 0.0], [12, 1.0]],
              "jawOpen": [[0, 0.0], [12, 0.3]]}}

``rate`` is frames per second; frames are numbers (time codes at that rate; fractions allowed);
values are contractions in [0, 1]. ``jawOpen`` is the jaw opening in [0, 1] (a fraction of the
rig's maximum jaw angle). Before its first key a muscle holds its first value, after its last key
its last value; muscles without keys stay at 0. Optional ``"frames": [first, last]`` sets the
frame range (default: first to last key).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import FormatError, InputError, OptionError, list_names
from .presets import JAW_KEY, PRESET_NAMES, PRESETS  # noqa: F401 (re-exported: the presets' home was here)


def preset_contractions(name: str, muscle_names, *, intensity: float = 1.0) -> tuple[np.ndarray, float]:
    """Contractions (M,) and jaw opening of a preset for a rig's muscles.

    A preset's base names (``zygomaticMajor``) drive both sides (``zygomaticMajor_L``,
    ``zygomaticMajor_R``); names the rig lacks are skipped.

    Raises
    ------
    OptionError
        Unknown preset, or intensity outside [0, 1].
    """
    if name not in PRESETS:
        raise OptionError(f"unknown expression {name!r}; presets: {', '.join(PRESET_NAMES)}")
    if not (np.isfinite(intensity) and 0 <= intensity <= 1):
        raise OptionError(f"expression intensity must be in [0, 1]; got {intensity!r}")
    names = list(muscle_names)
    a = np.zeros(len(names))
    jaw = 0.0
    for base, value in PRESETS[name].items():
        if base == JAW_KEY:
            jaw = value * intensity
            continue
        for i, n in enumerate(names):
            if n == base or n.rsplit("_", 1)[0] == base and n.rsplit("_", 1)[-1] in ("L", "R"):
                a[i] = value * intensity
    return a, jaw


@dataclass(frozen=True)
class Timeline:
    """Keyframed contractions.

    Attributes
    ----------
    rate : float
        Frames per second.
    keys : dict {str: ndarray (K, 2)}
        Per muscle (or ``jawOpen``), rows ``(frame, value)`` with increasing frames.
    frames : (float, float) or None
        First and last frame to simulate (default: the keys' range).
    source : str
    """

    rate: float
    keys: dict
    frames: tuple | None = None
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        where = f" {self.source}" if self.source else ""
        if not (isinstance(self.rate, (int, float)) and math.isfinite(self.rate) and self.rate > 0):
            raise FormatError(f"timeline{where}: rate must be a positive number of frames per second; got {self.rate!r}")
        if not self.keys:
            raise FormatError(f"timeline{where} has no keys")
        clean = {}
        for name, rows in self.keys.items():
            try:
                arr = np.asarray(rows, dtype=np.float64)
            except (TypeError, ValueError):
                raise FormatError(f"timeline{where}: keys of {name!r} must be [[frame, value], ...]") from None
            if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] == 0:
                raise FormatError(f"timeline{where}: keys of {name!r} must be a non-empty list of [frame, value] pairs")
            if not np.isfinite(arr).all():
                raise FormatError(f"timeline{where}: keys of {name!r} hold non-finite numbers")
            if (np.diff(arr[:, 0]) <= 0).any():
                raise FormatError(f"timeline{where}: frames of {name!r} must increase; got {arr[:, 0].tolist()}")
            bad = np.flatnonzero((arr[:, 1] < 0) | (arr[:, 1] > 1))
            if bad.size:
                what = "jaw opening" if name == JAW_KEY else "contraction"
                items = [f"frame {arr[i, 0]:g}: {arr[i, 1]:g}" for i in bad]
                raise OptionError(f"timeline{where}: {what} of {name!r} must be in [0, 1]; {list_names(items)}")
            clean[str(name)] = arr
        object.__setattr__(self, "keys", clean)
        if self.frames is not None:
            f0, f1 = (float(v) for v in self.frames)
            if not (math.isfinite(f0) and math.isfinite(f1) and f1 >= f0):
                raise FormatError(f"timeline{where}: frames must be [first, last] with last >= first; got {self.frames}")
            object.__setattr__(self, "frames", (f0, f1))

    @property
    def first_frame(self) -> float:
        """Frame 0 (usdface's time codes are frame indices from 0: before its first key a timeline
        holds the first key's values), an earlier key's frame, or ``frames[0]`` when given."""
        return self.frames[0] if self.frames else min(0.0, min(float(k[0, 0]) for k in self.keys.values()))

    @property
    def last_frame(self) -> float:
        return self.frames[1] if self.frames else max(float(k[-1, 0]) for k in self.keys.values())

    def frame_numbers(self) -> np.ndarray:
        """Whole frames from the first to the last (inclusive)."""
        return np.arange(math.floor(self.first_frame), math.ceil(self.last_frame) + 1, dtype=np.float64)

    def check_names(self, muscle_names, *, has_jaw: bool = True) -> None:
        """Refuse keys for muscles the rig does not have."""
        known = set(muscle_names) | ({JAW_KEY} if has_jaw else set())
        unknown = sorted(set(self.keys) - known)
        if unknown:
            where = f" {self.source}" if self.source else ""
            raise InputError(f"timeline{where} has keys for muscle(s) not in the rig: {list_names(unknown)}; the rig "
                             f"has {list_names(sorted(muscle_names))}" + (f" and {JAW_KEY}" if has_jaw else ""))

    def evaluate(self, frame: float, muscle_names) -> tuple[np.ndarray, float]:
        """Contractions (M,) and jaw opening at ``frame`` (linear between keys, held outside)."""
        a = np.zeros(len(muscle_names))
        for i, n in enumerate(muscle_names):
            k = self.keys.get(n)
            if k is not None:
                a[i] = np.interp(frame, k[:, 0], k[:, 1])
        jk = self.keys.get(JAW_KEY)
        jaw = float(np.interp(frame, jk[:, 0], jk[:, 1])) if jk is not None else 0.0
        return a, jaw

    def sample(self, muscle_names, frames=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(frames (F,), contractions (F, M), jaw (F,))."""
        frames = self.frame_numbers() if frames is None else np.asarray(frames, dtype=np.float64)
        a = np.zeros((frames.size, len(muscle_names)))
        jaw = np.zeros(frames.size)
        for f, fr in enumerate(frames):
            a[f], jaw[f] = self.evaluate(fr, muscle_names)
        return frames, a, jaw

    def to_dict(self) -> dict:
        d = {"rate": self.rate, "keys": {n: [[float(f), float(v)] for f, v in k] for n, k in self.keys.items()}}
        if self.frames is not None:
            d["frames"] = list(self.frames)
        return d


def read_timeline(path) -> Timeline:
    """Read a timeline JSON file (see the module docstring)."""
    from ..inputfiles import read_json

    p = Path(path)
    data = read_json(p, label=f"timeline {p}")  # a regular file, bounded size and nesting, UTF-8
    if not isinstance(data, dict):
        raise FormatError(f"timeline {p}: expected a JSON object with \"rate\" and \"keys\"")
    extra = sorted(set(data) - {"rate", "keys", "frames", "format", "comment"})
    if extra:
        raise FormatError(f"timeline {p}: unknown field(s) {list_names(extra)}; expected rate, keys, frames")
    if "keys" not in data or not isinstance(data["keys"], dict):
        raise FormatError(f"timeline {p}: \"keys\" must be an object {{muscle: [[frame, contraction], ...]}}")
    return Timeline(rate=data.get("rate", 24), keys=data["keys"], frames=data.get("frames"), source=str(p))


def write_timeline(path, timeline: Timeline) -> Path:
    """Write a timeline JSON file (atomically)."""
    from ..fileutil import write_text_atomic

    return write_text_atomic(path, json.dumps(timeline.to_dict(), indent=1) + "\n")


def expression_timeline(name: str, muscle_names, *, rate: float = 24.0, ramp_frames: int = 12,
                        hold_frames: int = 12, intensity: float = 1.0, start_frame: int = 0) -> Timeline:
    """A preset ramped from 0 to its contractions over ``ramp_frames``, then held ``hold_frames``.

    The ramp is linear, as in the paper ("progressively scale these contraction values from zero
    to unity over time"). Muscles the preset does not use get no keys (they stay at 0).
    """
    if ramp_frames < 1 or hold_frames < 0:
        raise OptionError(f"ramp_frames must be >= 1 and hold_frames >= 0; got {ramp_frames}, {hold_frames}")
    a, jaw = preset_contractions(name, muscle_names, intensity=intensity)
    f0, f1, f2 = start_frame, start_frame + ramp_frames, start_frame + ramp_frames + hold_frames
    keys = {n: [[f0, 0.0], [f1, float(v)]] for n, v in zip(muscle_names, a) if v > 0}
    if jaw > 0:
        keys[JAW_KEY] = [[f0, 0.0], [f1, float(jaw)]]
    if not keys:  # neutral: one flat key keeps the timeline well formed
        names = list(muscle_names)
        keys = {names[0] if names else JAW_KEY: [[f0, 0.0], [f1, 0.0]]}
    return Timeline(rate=rate, keys=keys, frames=(f0, f2), source=f"expression {name}")
