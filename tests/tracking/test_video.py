"""usdface.io.video: movies through OpenCV, image sequences through OpenImageIO or OpenCV."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from usdface.errors import InputError, OptionError
from usdface.io.video import is_sequence_pattern, open_video


def _frames(n=5, w=64, h=48):
    rng = np.random.default_rng(0)
    return [rng.integers(0, 255, (h, w, 3), dtype=np.uint8) for _ in range(n)]


def test_movie_count_size_rate(clip, clip_files):
    v = open_video(clip_files["video"])
    assert (v.n_frames, v.width, v.height) == (clip.frames.shape[0], 512, 640)
    assert v.rate == pytest.approx(30.0)
    frames = [f for _, f in v]
    assert len(frames) == v.n_frames and frames[0].shape == (640, 512, 3) and frames[0].dtype == np.uint8
    # lossy but close to what was rendered
    assert np.abs(frames[10].astype(int) - clip.frames[10]).mean() < 6
    assert open_video(clip_files["video"], rate=24).rate == 24


def test_png_sequence_pattern_cv2_and_oiio(tmp_path, monkeypatch):
    frames = _frames()
    for i, f in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"shot.{i + 101:04d}.png"), f)
    for pattern in ("shot.####.png", "shot.%04d.png", "shot.@.png"):
        assert is_sequence_pattern(pattern)
        v = open_video(tmp_path / pattern, rate=25)
        assert (v.n_frames, v.first_frame, v.size, v.kind) == (5, 101, (64, 48), "sequence")
        got = [f for _, f in v]
        assert all(np.array_equal(a, b) for a, b in zip(got, frames))
    # without OpenImageIO: OpenCV reads the PNGs the same
    import usdface.io.video as video_mod

    monkeypatch.setattr(video_mod, "_oiio", lambda required_for=None: None)
    got = [f for _, f in open_video(tmp_path / "shot.####.png", rate=25)]
    assert all(np.array_equal(a, b) for a, b in zip(got, frames))


def test_exr_sequence_via_openimageio(tmp_path):
    oiio = pytest.importorskip("OpenImageIO")
    frames = _frames(3)
    for i, f in enumerate(frames):
        rgb = (f[:, :, ::-1].astype(np.float32) / 255.0)
        out = oiio.ImageOutput.create(str(tmp_path / f"plate.{i:04d}.exr"))
        out.open(str(tmp_path / f"plate.{i:04d}.exr"), oiio.ImageSpec(64, 48, 3, "float"))
        out.write_image(rgb)
        out.close()
    v = open_video(tmp_path / "plate.####.exr", rate=24)
    got = [f for _, f in v]
    assert len(got) == 3 and np.abs(got[1].astype(int) - frames[1]).max() <= 1


def test_errors(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        open_video(tmp_path / "missing.mp4")
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"this is not a video" * 100)
    with pytest.raises(InputError, match="bad.mp4"):
        open_video(bad)
    with pytest.raises(InputError, match="zero frames"):
        open_video(tmp_path / "nothing.####.png", rate=24)
    cv2.imwrite(str(tmp_path / "a.0001.png"), _frames(1)[0])
    with pytest.raises(OptionError, match="--rate"):
        open_video(tmp_path / "a.####.png")
    with pytest.raises(OptionError, match="--rate"):
        open_video(tmp_path / "a.####.png", rate=-3)
    with pytest.raises(InputError, match="single image"):
        open_video(tmp_path / "a.0001.png")
