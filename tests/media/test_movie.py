"""MovieWriter: H.264 yuv420p faststart mp4 decoded back frame by frame; atomic; clear errors."""
from __future__ import annotations

import struct
import sys

import numpy as np
import pytest

from usdface.errors import DependencyError, InputError, OptionError
from usdface.media import MovieWriter, movie_info, read_movie

av = pytest.importorskip("av")


def bar_frame(k, size=(320, 240)):
    """A white 10-px bar at x = 3k on black: its position encodes the frame number."""
    w, h = size
    img = np.zeros((h, w, 3), np.uint8)
    img[:, 3 * k:3 * k + 10] = 255
    return img


def top_level_atoms(path):
    atoms, data = [], open(path, "rb").read()
    i = 0
    while i + 8 <= len(data):
        size, kind = struct.unpack(">I4s", data[i:i + 8])
        atoms.append(kind.decode("latin-1"))
        if size < 8:
            break
        i += size
    return atoms


def test_round_trip_count_rate_motion_and_container(tmp_path):
    out = tmp_path / "bars.mp4"
    with MovieWriter(out, (320, 240), 60) as w:
        for k in range(90):
            w.write(bar_frame(k))
    info = movie_info(out)
    assert info["codec"] == "h264" and info["pixelFormat"] == "yuv420p"
    assert (info["width"], info["height"]) == (320, 240)
    assert info["rate"] == pytest.approx(60.0) and info["frames"] == 90
    assert info["duration"] == pytest.approx(1.5, abs=1e-6)
    frames = list(read_movie(out))
    assert len(frames) == 90
    for k, img in frames:  # the bar is where frame k put it: no frame dropped, doubled or reordered
        col = img[120, :, 0].astype(int)
        assert abs(int(np.argmax(col > 128)) - 3 * k) <= 1
    atoms = top_level_atoms(out)
    assert atoms.index("moov") < atoms.index("mdat")  # faststart: the index comes first


def test_ntsc_rate_is_exact(tmp_path):
    out = tmp_path / "ntsc.mp4"
    with MovieWriter(out, (64, 64), 29.97) as w:
        for k in range(30):
            w.write(np.full((64, 64, 3), k * 8, np.uint8))
    info = movie_info(out)
    assert info["rate"] == pytest.approx(30000 / 1001) and info["frames"] == 30


def test_failure_midway_leaves_nothing(tmp_path):
    out = tmp_path / "broken.mp4"
    with pytest.raises(RuntimeError):
        with MovieWriter(out, (64, 64), 24) as w:
            w.write(np.zeros((64, 64, 3), np.uint8))
            raise RuntimeError("render failed")
    assert list(tmp_path.iterdir()) == []


def test_an_old_movie_survives_a_failed_write(tmp_path):
    out = tmp_path / "keep.mp4"
    with MovieWriter(out, (64, 64), 24) as w:
        w.write(np.zeros((64, 64, 3), np.uint8))
    before = out.read_bytes()
    with pytest.raises(OptionError, match="expected \\(64, 64, 3\\) uint8"):
        with MovieWriter(out, (64, 64), 24) as w:
            w.write(np.zeros((32, 32, 3), np.uint8))
    assert out.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["keep.mp4"]


@pytest.mark.parametrize("size, match", [((321, 240), "even width and height"), ((8, 8), "16 or more")])
def test_bad_sizes(tmp_path, size, match):
    with pytest.raises(OptionError, match=match):
        MovieWriter(tmp_path / "x.mp4", size, 24)


def test_bad_output_paths(tmp_path):
    with pytest.raises(OptionError, match="mp4"):
        MovieWriter(tmp_path / "x.avi", (64, 64), 24)
    with pytest.raises(InputError, match="does not exist"):
        MovieWriter(tmp_path / "nowhere" / "x.mp4", (64, 64), 24)
    with pytest.raises(InputError, match="cannot write movie"):
        MovieWriter("/proc/usdface-test.mp4", (64, 64), 24)  # not writable, even by root


def test_missing_pyav_names_the_extra(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "av", None)  # import av -> ImportError
    with pytest.raises(DependencyError, match=r'pip install "usdface\[media\]"'):
        MovieWriter(tmp_path / "x.mp4", (64, 64), 24)
    assert list(tmp_path.iterdir()) == []


def test_missing_h264_encoder_names_the_extra(monkeypatch, tmp_path):
    real = av.codec.Codec

    def no_x264(name, mode="r"):
        if name == "libx264":
            raise ValueError("unknown codec")
        return real(name, mode)

    monkeypatch.setattr(av.codec, "Codec", no_x264)
    with pytest.raises(DependencyError, match=r"no libx264 \(H.264\) encoder.*usdface\[media\]"):
        MovieWriter(tmp_path / "x.mp4", (64, 64), 24)
