"""`usdface playblast`: movies decoded back and checked frame by frame against the shot."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from usdface.options import PlayblastOptions

from usdface.media import movie_info, read_movie

pytest.importorskip("av")


def frames_of(path):
    return [img.astype(np.float64) for _, img in read_movie(path)]


def displacement_curve(shot, times, *, stabilized=False):
    from usdface.usd.playback import ShotReader

    r = ShotReader.open(shot)
    return np.linalg.norm(r.face_points(times, stabilized=stabilized) - r.rest_points, axis=2).max(axis=1)


def stills_of(shot, times, options):
    """The movie frames at ``times`` as the playblast draws them (no encoding): the shots opened
    by the usd layer, the frames planned by the playblast package (what a pipeline may call)."""
    from usdface.playblast import plan_playblast
    from usdface.usd.playback import open_playblast_shots

    params = options.parameters()
    return plan_playblast(open_playblast_shots(shot, params), params).stills(times)


def test_every_time_sample_one_frame_and_the_motion_where_the_shot_has_it(shots, cli, tmp_path):

    shot = shots["hybrid"] / "shot.usda"
    out = tmp_path / "jaw.mp4"
    # --stabilized: the face as the transfer moved it (the head's own motion on /Face left out)
    assert cli("playblast", shot, "-o", out, "--range", 300, 480, "--size", "320x180", "--stabilized", "-q") == 0
    info = movie_info(out)
    assert info["codec"] == "h264" and info["pixelFormat"] == "yuv420p" and info["rate"] == pytest.approx(60.0)
    frames = frames_of(out)
    assert len(frames) == info["frames"] == 181
    # image change from the first frame follows the face's motion (largest vertex displacement)
    change = np.array([np.abs(f - frames[0])[40:].mean() for f in frames])  # below the burn-in
    motion = displacement_curve(shot, np.arange(300, 481), stabilized=True)
    assert np.corrcoef(change, motion - motion[0])[0, 1] > 0.9
    # the frames at known time codes: where the jaw opens (340-360) and closes (460) fast, decoded
    # frame k matches the still of time code 300 + k better than those of its neighbours, on the
    # pixels that move (elsewhere only the codec's noise differs)
    times = [340, 345, 350, 355, 360, 460]
    near = sorted({t + d for t in times for d in (-3, -1, 0, 1, 3)})
    stills = dict(zip(near, (s.astype(np.float64) for s in
                             stills_of(shot, near, PlayblastOptions(frame_range=(300, 480), size=(320, 180),
                                                                    stabilized=True)))))
    for t in times:
        moving = np.abs(stills[t - 3] - stills[t + 3]).max(axis=2) > 24
        moving[:40] = False  # the burn-in band
        assert moving.sum() > 100
        err = {d: np.abs(frames[t - 300] - stills[t + d])[moving].mean() for d in (-3, -1, 0, 1, 3)}
        assert err[0] < min(err[-1], err[1]) and err[0] < 0.6 * min(err[-3], err[3]), (t, err)
    # the open jaw (frame 389 of the take) is in the lower half of the picture, the forehead still
    f389 = frames[389 - 300]
    lower = np.abs(f389 - frames[0])[100:].mean()
    upper = np.abs(f389 - frames[0])[40:70].mean()
    assert lower > 4 * upper
    # by default the head's motion (D1: a time-sampled transform on /Face) plays too: the reader
    # gives world points = stabilised points carried by /Face's transform, markers likewise
    from usdface.usd.playback import ShotReader

    r = ShotReader.open(shot)
    head = r.head_motion([0, 389])
    np.testing.assert_allclose(head[0], np.eye(4), atol=1e-9)       # identity at the neutral frame
    assert np.abs(head[1][3, :3]).max() > 0.3                         # the head has moved by 389
    stab, world = r.face_points([389], stabilized=True)[0], r.face_points([389])[0]
    np.testing.assert_allclose(world, stab @ head[1][:3, :3] + head[1][3, :3], atol=1e-9)
    mk, bd = r.markers([389])[0], r.bound_points(world[None])[0]
    assert np.nanmedian(np.linalg.norm(mk - bd, axis=1)) < 1.2  # markers stay on the moving face (fit residual)


def test_default_playblast_of_the_main_job(shots, cli, tmp_path):
    """The must-show command (whole take, 960x540, default options), checked here for content; its
    speed (<= 60 s on 2 cores) is measured by hand and by benchmarks/bench_playblast.py."""
    out = tmp_path / "jaw.mp4"
    assert cli("playblast", shots["hybrid"] / "shot.usda", "-o", out, "--size", "960x540", "-q") == 0
    info = movie_info(out)
    assert (info["width"], info["height"], info["frames"]) == (960, 540, 1590)
    assert info["rate"] == pytest.approx(60.0)
    seen, prev, repeats = 0, None, 0
    for _, img in read_movie(out, every=1):
        seen += 1
        if prev is not None and np.array_equal(img, prev):
            repeats += 1
        prev = img
    assert seen == 1590 and repeats == 0  # every decoded frame differs from the one before (burn-in frame)


def test_skeleton_shot_is_skinned_by_usdskel(shots, cli, tmp_path):
    """A skeleton shot plays its skinning (UsdSkel evaluates it through the one reader,
    usdface.usd.face_evaluator.FaceEvaluator), not a still face."""
    from usdface.usd.playback import ShotReader

    shot = shots["hybrid"] / "shot_skel.usda"
    skel, cache = ShotReader.open(shot), ShotReader.open(shots["hybrid"] / "shot.usda")
    assert skel.animated
    times = [0, 389, 700]
    # one performance in both deliverables: the skinned face lands on the point cache (K = 8
    # influences: 0.066 cm in the README), head motion included
    assert np.abs(skel.face_points(times) - cache.face_points(times)).max() < 0.1
    moved = cache.face_points([389], stabilized=True)[0] - cache.rest_points
    assert np.linalg.norm(moved, axis=1).max() > 3.0  # the jaw opens (cm)
    out = tmp_path / "skel.mp4"
    assert cli("playblast", shot, "-o", out, "--range", 330, 389, "--size", "320x240", "-q") == 0
    frames = frames_of(out)
    assert len(frames) == 60
    change = np.abs(frames[-1] - frames[0])
    # the chin moves most (the skeleton's head joint also carries the head's motion until the
    # head-motion decision D1 lands, so the forehead moves a little too)
    assert change[140:].mean() > 4.0 and change[140:].mean() > 1.5 * change[40:100].mean()


def test_side_by_side_shots_of_different_length(shots, cli, tmp_path, capsys):
    out = tmp_path / "cmp.mp4"
    # the Euclidean run has 240 frames (0..239): from 240 on it holds its last frame
    assert cli("playblast", shots["hybrid"] / "shot.usda", "--compare", shots["euclidean"] / "shot.usda",
               "-o", out, "--range", 230, 245, "--size", "640x240", "--json") == 0
    import json

    summary = json.loads(capsys.readouterr().out)
    assert summary["frames"] == 16 and summary["held"] == 6
    assert any("6 frame(s) held" in n for n in summary["notes"])
    frames = frames_of(out)
    assert len(frames) == 16
    right = [f[:, 320:] for f in frames]
    left = [f[:, :320] for f in frames]
    held = max(np.abs(right[k] - right[10]).mean() for k in range(11, 16))  # 241..245 hold 239 like 240
    playing = np.abs(left[15] - left[10]).mean()  # while the first shot keeps playing
    assert held < 0.1 and playing > 5 * held, (held, playing)


def test_beside_its_source_video_frame_k_plus_trim(video_shot, cli, tmp_path):
    from usdface.io.video import open_video
    from usdface.preview.burnin import fit_into

    out = tmp_path / "side.mp4"
    assert cli("playblast", video_shot["shot"], "--video", video_shot["video"], "-o", out, "--size", "640x256",
               "--no-burnin", "-q") == 0
    frames = frames_of(out)
    assert len(frames) == 50  # the shot: source frames 10..59
    video = [fit_into(img, (320, 256)).astype(np.float64) for _, img in open_video(video_shot["video"])]
    for k in (0, 17, 33, 49):
        panel = frames[k][:, 320:]
        err = {d: np.abs(panel - video[k + 10 + d]).mean() for d in (-1, 0, 1) if 0 <= k + 10 + d < len(video)}
        assert min(err, key=err.get) == 0 and err[0] < 4.0


# -- bad input --------------------------------------------------------------------------------------

def _one_line_error(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("usdface playblast: error:")
    return err[0]


def test_a_layer_without_a_mesh(shots, cli, tmp_path, capsys):
    out = tmp_path / "x.mp4"
    assert cli("playblast", shots["hybrid"] / "capture.usdc", "-o", out) == 2
    assert "no Mesh prim" in _one_line_error(capsys)
    assert cli("playblast", shots["hybrid"] / "analysis.usdc", "-o", out) == 2
    assert "over-only layer" in _one_line_error(capsys)
    assert cli("playblast", shots["hybrid"] / "mesh.usdc", "-o", out) == 2
    assert "no animation" in _one_line_error(capsys)
    assert list(tmp_path.iterdir()) == []


def test_a_range_outside_the_shot(shots, cli, tmp_path, capsys):
    assert cli("playblast", shots["hybrid"] / "shot.usda", "-o", tmp_path / "x.mp4", "--range", 1500, 2000) == 2
    line = _one_line_error(capsys)
    assert "--range 1500 2000: outside the shot" in line and "frames 0..1589" in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("where", ["missing", "proc"])
def test_an_output_folder_that_cannot_be_written(shots, cli, tmp_path, capsys, where):
    out = tmp_path / "no" / "such" / "x.mp4" if where == "missing" else "/proc/usdface-playblast.mp4"
    # a folder that does not exist is a usage error (2); one that refuses files is the environment (1)
    assert cli("playblast", shots["hybrid"] / "shot.usda", "-o", out, "--range", 0, 3) == \
        (2 if where == "missing" else 1)
    assert "cannot write movie" in _one_line_error(capsys)


def test_a_missing_encoder_names_what_to_install(shots, cli, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "av", None)
    # a missing optional dependency is the environment's fault: exit 1, with what to install
    assert cli("playblast", shots["hybrid"] / "shot.usda", "-o", tmp_path / "x.mp4", "--range", 0, 3) == 1
    assert 'pip install "usdface[media]"' in _one_line_error(capsys)
    assert list(tmp_path.iterdir()) == []


def test_a_failure_while_rendering_leaves_nothing(shots, tmp_path, monkeypatch):
    from usdface import api
    from usdface.playblast import pipeline

    calls = {"n": 0}
    real = pipeline.Compositor.__call__

    def flaky(self, job):
        calls["n"] += 1
        if calls["n"] == 5:
            raise RuntimeError("renderer crashed")
        return real(self, job)

    monkeypatch.setattr(pipeline.Compositor, "__call__", flaky)
    with pytest.raises(RuntimeError):
        api.playblast(shots["hybrid"] / "shot.usda", PlayblastOptions(frame_range=(0, 20), size=(160, 90)),
                      output=tmp_path / "x.mp4")
    assert list(tmp_path.iterdir()) == []


def test_bad_options(shots, cli, tmp_path, capsys):
    shot = shots["hybrid"] / "shot.usda"
    assert cli("playblast", shot, "-o", tmp_path / "x.mp4", "--size", "961x540") == 2
    assert "even width and height" in _one_line_error(capsys)
    assert cli("playblast", shot, "-o", tmp_path / "x.mov.avi") == 2
    assert ".mp4" in _one_line_error(capsys)
    assert cli("playblast", shot, "-o", shot.with_name("shot.mp4"), "--video", shot.with_name("shot.mp4")) == 2
    assert "would overwrite it" in _one_line_error(capsys)
    assert cli("playblast", shots["euclidean"] / "shot.usda", "-o", tmp_path / "x.mp4", "--color",
               "hybrid-weight") == 2
    assert "hybridWeight" in _one_line_error(capsys)
