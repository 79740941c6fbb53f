"""`usdface run` with a video capture and with skeletal output."""
from __future__ import annotations

import json

import numpy as np


def test_run_from_video_tracks_lifts_and_transfers(sample_assets, tmp_path, cli):
    from pxr import Usd, UsdGeom

    out = tmp_path / "video"
    video = sample_assets / "video" / "animface_dots.mp4"
    code = cli("run", "--mesh", sample_assets / "meshes" / "makehuman_hm08_face_cm.obj", "--capture", video,
               "--layout", sample_assets / "layouts" / "makehuman_hm08_face.layout.json",
               "--seeds", sample_assets / "video" / "animface_dots.seeds.json", "-o", out, "-q")
    assert code == 0
    assert {"tracks.usdc", "capture.usdc", "anim.usdc", "shot.usda"} <= {p.name for p in out.iterdir()}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"]["track"]["validFraction"] > 0.95
    assert summary["steps"]["import-capture"]["stabilized"]  # the video's head motion is removed
    stage = Usd.Stage.Open(str(out / "shot.usda"))
    pts = UsdGeom.Mesh(stage.GetPrimAtPath("/Face/Geom")).GetPointsAttr()
    assert len(pts.GetTimeSamples()) == summary["frames"] == 72
    rest = np.asarray(pts.Get(Usd.TimeCode.Default()))
    moved = np.linalg.norm(np.asarray(pts.Get(24)) - rest, axis=1)
    assert 0.3 < moved.max() < 3.0  # the jaw opens; nothing flies away
    assert cli("check", out / "shot.usda", "-q") == 0


def test_video_capture_needs_a_layout_and_seeds(sample_assets, tmp_path, capsys, cli):
    video = sample_assets / "video" / "animface_dots.mp4"
    mesh = sample_assets / "meshes" / "makehuman_hm08_face_cm.obj"
    assert cli("run", "--mesh", mesh, "--capture", video, "--auto", "-o", tmp_path / "a") == 2
    assert "--layout" in capsys.readouterr().err
    assert cli("run", "--mesh", mesh, "--capture", video, "--layout",
               sample_assets / "layouts" / "makehuman_hm08_face.layout.json", "-o", tmp_path / "b") == 2
    assert "--seeds" in capsys.readouterr().err


def test_run_writes_skeleton_and_points(sample_assets, tmp_path, cli):
    out = tmp_path / "both"
    code = cli("run", "--mesh", sample_assets / "meshes" / "makehuman_hm08_face_cm.obj", "--capture",
               sample_assets / "capture" / "JawMoCap.usdc", "--layout",
               sample_assets / "layouts" / "makehuman_hm08_face.layout.json", "--trim", "0", "300",
               "--no-stabilize", "--output-kind", "both", "-o", out, "-q")
    assert code == 0
    names = {p.name for p in out.iterdir()}
    assert {"anim.usdc", "skel.usdc", "shot.usda", "shot_skel.usda"} <= names
    skel = json.loads((out / "summary.json").read_text())["steps"]["skel"]
    assert skel["maxInfluences"] == 8 and skel["joints"] == 42
    for name in ("skel.usdc", "shot_skel.usda"):
        assert cli("check", out / name, "-q") == 0
