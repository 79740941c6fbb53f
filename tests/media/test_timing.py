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
