"""Playblasts: a shot rendered frame by frame into a movie (see ``usdface playblast``).

- :mod:`.timing` — which time code of each shot and which source-video frame each movie frame shows;
- :mod:`.panel` — :class:`ShotPanel`, one shot's face rendered with a fixed style and framing;
- :mod:`.plan` — :func:`plan_playblast`: framing and colour range fitted on a first pass, the
  frame jobs, stills;
- :mod:`.pipeline` — frames composed from panels, rendered in parallel and in order.

No USD here (the shots are opened by :func:`usdface.usd.playback.open_playblast_shots`).
"""
from ..lazy import lazy_exports

#: public name -> submodule, loaded on first use
_EXPORTS = {
    "COLORS": "panel", "PanelStyle": "panel", "ShotPanel": "panel", "Compositor": "pipeline", "FrameJob": "pipeline",
    "render_in_order": "pipeline", "Alignment": "timing", "VideoTiming": "timing", "align_shots": "timing",
    "shot_times": "timing", "video_frame_indices": "timing", "video_timing": "timing",
    "PlayblastParameters": "plan", "PlayblastPlan": "plan", "PlayblastShots": "plan", "plan_playblast": "plan",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())

__all__ = ["COLORS", "Alignment", "Compositor", "FrameJob", "PanelStyle", "PlayblastParameters", "PlayblastPlan",
           "PlayblastShots", "ShotPanel", "VideoTiming", "align_shots", "plan_playblast", "render_in_order",
           "shot_times", "video_frame_indices", "video_timing"]
