"""`usdface info` reports the capture's head motion truthfully, in a shot as in the capture layer.

Before: "head motion: no" on a stabilised shot (the shot shows the markers stabilised, so the
composed transform of /Capture is static, but the capture does carry the head motion)."""
from __future__ import annotations

import json

from usdface.cli import main


def _describe(path, capsys) -> dict:
    assert main(["info", str(path), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def _marker_set(path, capsys) -> dict:
    (entry,) = [p for p in _describe(path, capsys)["prims"] if "markerSet" in p]
    return entry["markerSet"]


def _face_transform(path, capsys) -> dict:
    (entry,) = [p for p in _describe(path, capsys)["prims"] if p["path"] == "/Face"]
    return entry.get("animatedTransform", {})


def test_info_head_motion_in_shot_and_capture(sample_assets, tmp_path, capsys):
    args = ["run", "--mesh", str(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj"), "--capture",
            str(sample_assets / "capture" / "JawMoCap.ma"), "--layout",
            str(sample_assets / "layouts" / "makehuman_hm08_face.layout.json"), "--trim", "0", "120", "-q"]
    assert main(args + ["-o", str(tmp_path / "stab")]) == 0
    shot = _marker_set(tmp_path / "stab" / "shot.usda", capsys)
    assert shot["headMotion"] and shot["headMotionFrames"] == 120
    assert _face_transform(tmp_path / "stab" / "shot.usda", capsys) == {"xformOp:transform": 120}
    cap = _marker_set(tmp_path / "stab" / "capture.usdc", capsys)
    assert cap["headMotion"] and cap["headMotionApplied"]
    assert main(["info", str(tmp_path / "stab" / "shot.usda")]) == 0
    text = capsys.readouterr().out
    assert "head motion: yes (removed by stabilisation" in text
    assert "xformOp:transform: 120 time samples (head motion)" in text
    assert main(args + ["--no-stabilize", "-o", str(tmp_path / "raw")]) == 0
    raw = _marker_set(tmp_path / "raw" / "shot.usda", capsys)
    assert not raw["headMotion"] and not raw["headMotionApplied"]
    assert _face_transform(tmp_path / "raw" / "shot.usda", capsys) == {}
