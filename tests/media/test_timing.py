"""Which shot time code and which video frame every playblast frame shows."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.errors import OptionError
from usdface.playblast.timing import VideoTiming, align_shots, shot_times, video_frame_indices


def test_shot_times_and_ranges():
    np.testing.assert_array_equal(shot_times(0, 4), [0, 1, 2, 3, 4])
    np.testing.assert_array_equal(shot_times(10, 59, (20, 22)), [20, 21, 22])
    with pytest.raises(OptionError, match=r"--range 0 5000: outside the shot's frames 0..1589"):
        shot_times(0, 1589, (0, 5000), what="shot")
    with pytest.raises(OptionError, match="comes before the first"):
        shot_times(0, 10, (5, 2))


def test_align_same_rate_holds_past_the_end():
    a = align_shots(np.arange(230, 246), 60.0, 0, 239, 60.0)
    np.testing.assert_array_equal(a.times, [230, 231, 232, 233, 234, 235, 236, 237, 238, 239] + [239] * 6)
    np.testing.assert_array_equal(a.held, [False] * 10 + [True] * 6)
    assert a.n_held == 6


def test_align_in_seconds_across_rates():
    # 60 fps playblast against a 30 fps shot starting at time code 5: t/60 s -> frame t/2 at 30 fps
    a = align_shots(np.arange(0, 13), 60.0, 5, 100, 30.0)
    assert a.times.tolist() == [5] * 11 + [6, 6]   # nearest frame, halves up: t = 9 is 4.5 -> 5
    assert a.held.tolist() == [True] * 9 + [False] * 4  # before its first sample (0.167 s)


def test_video_frames_through_trim_start_frame_and_resample():
    # no resampling: playblast frame k shows video frame k + trim, whatever the shot's first time code
    t = VideoTiming(trim_start=10, source_rate=30.0, rate=30.0, shot_start=10)
    idx, ok = video_frame_indices(np.arange(10, 60), t, video_rate=30.0, video_frames=72)
    np.testing.assert_array_equal(idx, np.arange(10, 60))
    assert ok.all()
    t = VideoTiming(trim_start=10, source_rate=30.0, rate=30.0, shot_start=100)  # --start-frame 100
    idx, _ = video_frame_indices(np.array([100, 101, 149]), t, video_rate=30.0, video_frames=72)
    assert idx.tolist() == [10, 11, 59]
    # resampled to 60 Hz: two shot frames per video frame, rounded to the nearest
    t = VideoTiming(trim_start=10, source_rate=30.0, rate=60.0, shot_start=0)
    idx, _ = video_frame_indices(np.arange(0, 6), t, video_rate=30.0, video_frames=72)
    assert idx.tolist() == [10, 11, 11, 12, 12, 13]
    # past the video's end
    t = VideoTiming(trim_start=70, source_rate=30.0, rate=30.0, shot_start=0)
    idx, ok = video_frame_indices(np.arange(0, 4), t, video_rate=30.0, video_frames=72)
    assert idx.tolist() == [70, 71, 72, 73] and ok.tolist() == [True, True, False, False]


def test_one_view_list_and_the_turntable():
    from usdface.cli import build_parser
    from usdface.playblast.panel import PanelStyle, ShotPanel
    from usdface.preview import VIEW_CHOICES, Camera, view_yaw

    assert {"front", "three-quarter", "side", "turntable"} <= set(VIEW_CHOICES)
    # preview and playblast offer the same list
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    for cmd in ("preview", "playblast"):
        view = next(a for a in sub.choices[cmd]._actions if a.dest == "view")
        assert tuple(view.choices) == VIEW_CHOICES
    assert view_yaw("three-quarter") == 35.0 and view_yaw("side") == 90.0 and view_yaw("turntable") == 0.0
    assert view_yaw("turntable", 0.25) == pytest.approx(75.0) and view_yaw("turntable", 0.75) == pytest.approx(-75.0)
    # a turntable panel turns with time, at one scale (the face does not zoom in and out)
    g = np.stack(np.meshgrid(np.linspace(-1, 1, 5), np.linspace(-1, 1, 5)), -1).reshape(-1, 2)
    pts = np.c_[g, 0.3 * (1 - (g ** 2).sum(1))]
    tris = np.array([[0, 1, 5]])
    panel = ShotPanel(name="t", method="", rate=24.0, triangles=tris, rest_points=pts, size=(200, 200),
                      style=PanelStyle(view="turntable", turntable_period=2.0), frame_points=pts[None])
    cams = [panel.camera_at(t) for t in (0, 12, 24, 36)]  # phases 0, 0.25, 0.5, 0.75
    fwd = [c.forward for c in cams]
    np.testing.assert_allclose(fwd[0], Camera.view_rotation("front")[2], atol=1e-9)
    np.testing.assert_allclose(fwd[1], Camera.view_rotation(75.0)[2], atol=1e-9)
    np.testing.assert_allclose(fwd[3], Camera.view_rotation(-75.0)[2], atol=1e-9)
    assert len({round(c.scale, 9) for c in cams}) == 1
