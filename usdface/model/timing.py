"""Where a layer's frames sit in time."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FrameRange:
    """``frames`` frames at ``rate`` Hz from time code ``start`` (time code = frame index at the
    rate); ``end`` is the last frame's time code."""

    start: float
    rate: float
    frames: int

    @property
    def end(self) -> float:
        return self.start + self.frames - 1
