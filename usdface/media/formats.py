"""Movie formats and encoder settings the commands offer, without numpy or PyAV: building the
command line reads these."""
from __future__ import annotations

__all__ = ["X264_PRESETS", "MOVIE_SUFFIXES"]

#: x264 speed presets the playblast offers (``--preset``)
X264_PRESETS = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow", "slower")
#: the movie files usdface writes and reads
MOVIE_SUFFIXES = (".mp4", ".m4v", ".mov")
