"""Playblasts: a shot rendered frame by frame into a movie (see ``usdface playblast``).

- :mod:`.timing` — which time code of each shot and which source-video frame each movie frame shows;
- :mod:`.panel` — :class:`ShotPanel`, one shot's face rendered with a fixed style and framing;
- :mod:`.pipeline` — frames composed from panels, rendered in parallel and in order.

No USD here (the processor reads the shots through :mod:`usdface.usd.playback`).
"""
from .panel import COLORS, PanelStyle, ShotPanel
from .pipeline import Compositor, FrameJob, render_in_order
from .timing import Alignment, VideoTiming, align_shots, shot_times, video_frame_indices

__all__ = ["COLORS", "Alignment", "Compositor", "FrameJob", "PanelStyle", "ShotPanel", "VideoTiming", "align_shots",
           "render_in_order", "shot_times", "video_frame_indices"]
