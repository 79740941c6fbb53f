"""`usdface track`: end to end, outputs, and bad input (clear errors, exit 2, nothing left behind)."""
from __future__ import annotations

import json

import numpy as np

from usdface.io.csv_format import read_csv
from usdface.tracking.synthetic import score_tracks
from usdface.usd.track_layer import read_track_layer


def test_track_writes_layer_csv_preview(cli, clip, clip_files, tmp_path):
    out, csv, png = tmp_path / "tracks.usdc", tmp_path / "tracks.csv", tmp_path / "preview.png"
    rc = cli("track", clip_files["video"], "--seeds", clip_files["seeds"], "--radius", 4, 9, "-o", out,
             "--csv", csv, "--preview", png, "-q")
    assert rc == 0 and out.is_file() and csv.is_file() and png.is_file()
    cap, info = read_track_layer(out)
    assert cap.units == "px" and info["image_size"] == (512, 640) and cap.rate == 30
    assert cap.positions.shape == (clip.frames.shape[0], len(clip.names), 3)
    assert np.all(cap.positions[cap.valid][:, 2] == 0)
    assert info["confidence"].shape == cap.valid.shape and (info["confidence"][~cap.valid] == 0).all()
    order = [cap.names.index(n) for n in clip.names]
    s = score_tracks(cap.positions[:, order, :2], clip.truth, clip.visible)
    assert s["mean_error"] <= 0.3 and s["identity_switches"] == 0 and s["occluded_invalid"] == 1.0
    # the layer never holds NaN: invalid samples hold the last value
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(out))
    pts = UsdGeom.Points(stage.GetPrimAtPath("/Capture/Markers")).GetPointsAttr()
    assert all(np.isfinite(np.asarray(pts.Get(t))).all() for t in pts.GetTimeSamples())
    assert stage.GetPrimAtPath("/Capture/Markers").GetAttribute("usdface:markerSet:dimensions").Get() == 2
    # CSV: the foundation's 2D wide form, same numbers (pixels have no CSV unit token: pass one to read)
    text = csv.read_text().splitlines()
    assert text[1].startswith("frame,ForeHead_M_x,ForeHead_M_y,")
    back = read_csv(csv, units="mm")
    assert back.history[0]["dims"] == 2
    assert np.allclose(back.positions, cap.positions, equal_nan=True, atol=1e-4)


def test_auto_with_layout_cli(cli, clip, clip_files, tmp_path):
    lay = clip.truth[0] * 0.033
    layout = tmp_path / "layout.json"
    layout.write_text(json.dumps({"format": "usdface-layout/1", "units": "cm", "markers": {
        n: {"point": [float(x), float(-y), 10.0]} for n, (x, y) in zip(clip.names, lay)}}))
    out = tmp_path / "auto.usdc"
    rc = cli("track", clip_files["video"], "--auto", len(clip.names), "--layout", layout, "--radius", 4, 9,
             "-o", out, "-q")
    assert rc == 0
    cap, _ = read_track_layer(out)
    assert set(cap.names) == set(clip.names)
    order = [cap.names.index(n) for n in clip.names]
    s = score_tracks(cap.positions[:, order, :2], clip.truth, clip.visible)
    assert s["identity_switches"] == 0 and s["found"] >= 0.99


def _no_outputs(tmp_path):
    return not any(p.suffix in (".usdc", ".csv", ".png") for p in tmp_path.iterdir())


def test_bad_input_clear_errors_nothing_partial(cli, clip_files, tmp_path, capsys):
    out, csv = tmp_path / "t.usdc", tmp_path / "t.csv"
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(b"\x00garbage" * 500)
    assert cli("track", bad, "--auto", 3, "-o", out, "--csv", csv) == 2
    assert "broken.mp4" in capsys.readouterr().err
    assert cli("track", tmp_path / "none.####.png", "--rate", 24, "--auto", 3, "-o", out) == 2
    assert "zero frames" in capsys.readouterr().err
    seeds = tmp_path / "outside.json"
    seeds.write_text(json.dumps({"Chin": [100, 100], "Nose": [900, -5]}))
    assert cli("track", clip_files["video"], "--seeds", seeds, "-o", out, "--csv", csv) == 2
    assert "outside" in (err := capsys.readouterr().err) and "Nose" in err
    ghost = json.loads(clip_files["seeds"].read_text())
    ghost["Ghost_Marker"] = [5.0, 320.0]
    seeds.write_text(json.dumps(ghost))
    assert cli("track", clip_files["video"], "--seeds", seeds, "--radius", 4, 9, "-o", out, "--csv", csv) == 2
    assert "Ghost_Marker" in capsys.readouterr().err
    assert cli("track", clip_files["video"], "--seeds", clip_files["seeds"], "--radius", 9, 4, "-o", out) == 2
    assert "impossible radius range" in capsys.readouterr().err
    assert cli("track", clip_files["video"], "--seeds", clip_files["seeds"], "--radius", 200, 300, "-o", out) == 2
    assert "impossible radius range" in capsys.readouterr().err
    assert _no_outputs(tmp_path)
    assert not any(p.name.startswith(".") for p in tmp_path.iterdir())


def test_degenerate_seed_colour_is_regularised(cli, clip_files, tmp_path):
    seeds = json.loads(clip_files["seeds"].read_text())
    name, xy = next(iter(seeds.items()))
    one = tmp_path / "one.json"
    # a single seed: the colour model comes from a handful of pixels; it is regularised, tracking works
    one.write_text(json.dumps({name: xy}))
    out = tmp_path / "one.usdc"
    assert cli("track", clip_files["video"], "--seeds", one, "--radius", 4, 9, "-o", out, "--json") == 0
    cap, _ = read_track_layer(out)
    assert cap.names == (name,) and cap.valid.mean() > 0.95


def test_sample_asset_clip_against_its_truth(cli, sample_assets, tmp_path):
    d = sample_assets / "video"
    out = tmp_path / "sample.usdc"
    assert cli("track", d / "animface_dots.mp4", "--seeds", d / "animface_dots.seeds.json", "--radius", 4, 9,
               "-o", out, "-q") == 0
    cap, _ = read_track_layer(out)
    truth = read_csv(d / "animface_dots.truth.csv", units="mm")
    order = [cap.names.index(n) for n in truth.names]
    got = cap.positions[:, order, :2]
    ok = truth.valid
    err = np.linalg.norm(got - truth.positions[..., :2], axis=2)[ok]
    assert np.isfinite(err).mean() >= 0.99
    e = err[np.isfinite(err)]
    assert e.mean() <= 0.3 and np.percentile(e, 99) <= 1.0


def test_track_and_lift_in_memory(cli, clip_files, sample_assets, tmp_path, monkeypatch):
    """The Python API: tracks and the lifted capture authored in memory (no file written, in a
    read-only working folder) hold what the command writes to files."""
    from pxr import Sdf

    from usdface import api
    from usdface.options import LiftOptions, TrackOptions
    from usdface.usd.capture_layer import read_capture_layer

    mesh = sample_assets / "meshes" / "makehuman_hm08_face_cm.obj"
    layout = sample_assets / "layouts" / "makehuman_hm08_face.layout.json"
    video = sample_assets / "video" / "animface_dots.mp4"
    seeds = sample_assets / "video" / "animface_dots.seeds.json"
    tracks, lifted = tmp_path / "tracks.usdc", tmp_path / "lifted.usdc"
    assert cli("track", video, "--seeds", seeds, "--radius", 4, 9, "-o", tracks, "-q") == 0
    assert cli("lift", tracks, "--mesh", mesh, "--layout", layout, "-o", lifted, "-q") == 0
    readonly = tmp_path / "readonly"
    readonly.mkdir()
    readonly.chmod(0o555)
    monkeypatch.chdir(readonly)
    try:
        t = api.track(video, TrackOptions(seeds=str(seeds), radius=(4, 9)))
        assert isinstance(t.layer, Sdf.Layer) and t.files == {}
        in_memory, _ = read_track_layer(t.layer)
        on_disk, _ = read_track_layer(tracks)
        assert in_memory.names == on_disk.names
        assert np.array_equal(in_memory.positions, on_disk.positions, equal_nan=True)
        lift = api.lift(t.layer, mesh, LiftOptions(layout=str(layout)))
        assert lift.summary["frames"] == in_memory.n_frames
        assert np.allclose(read_capture_layer(lift.layer).positions, read_capture_layer(lifted).positions,
                           atol=1e-6, equal_nan=True)
        assert list(readonly.iterdir()) == []
    finally:
        readonly.chmod(0o755)
