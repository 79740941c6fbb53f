"""Hostile videos: empty, text and truncated movies, named pipes. One usdface line, no FFmpeg or
OpenCV chatter (run as subprocesses: FFmpeg's logging is set up once per process)."""
from __future__ import annotations

import os

import pytest

from ..hostile import assert_one_line, run_subprocess


@pytest.mark.parametrize("name, content, problem", [
    ("empty.mp4", b"", "the file is empty (0 bytes)"),
    ("text.mp4", b"hello\n", "cannot be opened as a video (truncated, or not one of .mp4"),
    ("cut.mp4", None, "cannot be opened as a video (truncated, or not one of .mp4"),
])
def test_broken_movies_give_one_line(sample_assets, tmp_path, name, content, problem):
    # issue 20 (13): FFmpeg's "moov atom not found" and OpenCV's "[ WARN:0@...] global cap.cpp:212" first
    video = tmp_path / name
    video.write_bytes(content if content is not None else
                      (sample_assets / "video" / "animface_dots.mp4").read_bytes()[:20000])
    rc, lines = run_subprocess("track", video, "--seeds", sample_assets / "video" / "animface_dots.seeds.json",
                               "-o", tmp_path / "t.usdc", timeout=120)
    assert_one_line(rc, lines, code=2, command="track", contains=(f"video {video}: {problem}",))


def test_named_pipe_video_is_refused(sample_assets, tmp_path):
    fifo = tmp_path / "take.mp4"
    os.mkfifo(fifo)
    rc, lines = run_subprocess("track", fifo, "--seeds", sample_assets / "video" / "animface_dots.seeds.json",
                               "-o", tmp_path / "t.usdc", timeout=60)
    assert_one_line(rc, lines, code=2, command="track", contains=(f"video {fifo}: is a named pipe (FIFO)",))


def test_a_good_movie_still_reads(sample_assets):
    from usdface.io.video import open_video

    with open_video(sample_assets / "video" / "animface_dots.mp4") as video:
        assert video.n_frames > 0 and video.rate > 0
        assert video.read(0).shape == (video.height, video.width, 3)


@pytest.mark.parametrize("build", ["utils.logging only (OpenCV 4.12+)", "top level only (OpenCV 4.11)", "neither"])
def test_opencv_is_quieted_whichever_log_level_api_the_build_has(build):
    """OpenCV 4.12 and later have no top-level cv2.setLogLevel (every video read was an
    AttributeError traceback with the wheel pip installs today); 4.11 has no cv2.utils.logging.
    The level is set while the block runs and put back after, whichever the build offers."""
    from types import SimpleNamespace

    from usdface.io.video import _CV2_QUIET_LEVEL, _quiet

    calls, level = [], [4]

    def set_level(value):
        calls.append(value)
        previous, level[0] = level[0], value
        return previous

    api = SimpleNamespace(setLogLevel=set_level, getLogLevel=lambda: level[0])
    cv2 = {"utils.logging only (OpenCV 4.12+)": SimpleNamespace(utils=SimpleNamespace(logging=api)),
           "top level only (OpenCV 4.11)": SimpleNamespace(setLogLevel=set_level),
           "neither": SimpleNamespace()}[build]
    with _quiet(cv2):
        inside = level[0]
    if build == "neither":
        assert calls == [] and level == [4]
    else:
        assert inside == _CV2_QUIET_LEVEL and calls == [_CV2_QUIET_LEVEL, 4] and level == [4]
