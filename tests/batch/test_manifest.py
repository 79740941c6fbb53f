"""Manifest parsing: keys, globs, placeholders, and bad input reported before any work."""
from __future__ import annotations

import json

from usdface.options import BatchOptions

import os

from pathlib import Path

import pytest

from usdface.pipeline.batch.manifest import key_line, load_manifest
from usdface.errors import FormatError, InputError


def test_globs_expand_to_mesh_x_capture_and_name_outputs(tmp_path, make_manifest):
    m = load_manifest(make_manifest(tmp_path))
    assert len(m.shots) == 7
    names = [s.name for s in m.shots]
    assert "makehuman_hm08_face_cm/JawMoCap" in names and "mediapipe_canonical_face_model_holes/NoseMoCap" in names
    s = next(s for s in m.shots if s.name == "makehuman_hm08_face_cm/JawMoCap")
    assert s.output == str(tmp_path / "out" / "makehuman_hm08_face_cm" / "JawMoCap")
    # CLI defaults and conversions, as `usdface run` would get them
    assert s.options["trim"] == [0, 120] and s.options["method"] == "hybrid" and s.options["stabilize"] == "auto"
    assert s.options["region_radius"] == 1.0 and s.options["layout"].endswith("makehuman_hm08_face.layout.json")
    assert m.cache == str(tmp_path / ".usdface-cache")


def test_cli_option_names_in_snake_case(tmp_path, make_manifest):
    p = make_manifest(tmp_path, broken=False, extra='pin_border = "all"\nstabilize = false\nregion_radius = 1.5\n'
                                                   'polynomial = true\nneutral = "auto"')
    s = load_manifest(p).shots[0]
    assert s.options["pin_border"] == "all" and s.options["stabilize"] is None
    assert s.options["region_radius"] == 1.5 and s.options["polynomial"] is True and s.options["neutral"] == "auto"


def test_unknown_key_named_with_its_line(tmp_path, make_manifest):
    p = make_manifest(tmp_path, broken=False)
    text = p.read_text().replace('capture = "', 'pinborder = "upper"\ncapture = "', 1)
    p.write_text(text)
    line = text.splitlines().index('pinborder = "upper"') + 1
    with pytest.raises(FormatError) as e:
        load_manifest(p)
    msg = str(e.value)
    assert f"line {line}" in msg and "'pinborder'" in msg and "did you mean 'pin_border'" in msg


def test_key_line_finds_the_right_table():
    text = '[defaults]\nmethod = "x"\n[[shots]]\nmesh = "a"\n[[shots]]\nmesh = "b"\n  foo = 1\n'
    assert key_line(text, "shots", 1, "foo") == 7
    assert key_line(text, "defaults", None, "method") == 2
    assert key_line(text, "shots", 0, "foo") is None


def test_bad_value_is_checked_by_the_options_and_names_the_line(tmp_path, make_manifest):
    p = make_manifest(tmp_path, broken=False, extra='method = "manhattan"')
    line = p.read_text().splitlines().index('method = "manhattan"') + 1
    with pytest.raises(InputError, match=rf"line {line}: --method manhattan: expected one of euclidean, geodesic, hybrid"):
        load_manifest(p)


def test_missing_files_listed_all_at_once(tmp_path, make_manifest):
    p = make_manifest(tmp_path, broken=False)
    text = p.read_text().replace("makehuman_hm08_face_cm.obj", "nope_face.obj").replace(
        "mediapipe_face_holes.layout.json", "nope.layout.json").replace("*MoCap.ma", "*NoSuchTake.ma", 1)
    p.write_text(text)
    with pytest.raises(InputError) as e:
        load_manifest(p)
    msg = str(e.value)
    assert "3 input file(s) not found" in msg
    assert "nope_face.obj" in msg and "nope.layout.json" in msg and "*NoSuchTake.ma matches no file" in msg


def test_read_only_output_folder_reported_before_work(tmp_path, make_manifest):
    if os.geteuid() == 0:  # root writes through permissions: use a file system that takes no files
        target = "/proc/usdface-batch-test/{mesh}/{capture}"
    else:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        target = str(ro / "{mesh}" / "{capture}")
    p = make_manifest(tmp_path, broken=False)
    p.write_text(p.read_text().replace('output = "out/{mesh}/{capture}"', f'output = "{target}"'))
    with pytest.raises(InputError, match="read-only"):
        load_manifest(p)


def test_outputs_must_differ(tmp_path, make_manifest):
    p = make_manifest(tmp_path, broken=False)
    p.write_text(p.read_text().replace('output = "out/{mesh}/{capture}"', 'output = "out/{mesh}"'))
    with pytest.raises(InputError, match="share an output folder"):
        load_manifest(p)


def test_video_capture_is_tracked_lifted_and_transferred(tmp_path, sample_assets):
    from usdface.pipeline.batch.runner import run_batch

    v = sample_assets / "video"
    p = tmp_path / "video.toml"
    p.write_text(f'[[shots]]\nmesh = "{sample_assets}/meshes/makehuman_hm08_face_cm.obj"\n'
                 f'layout = "{sample_assets}/layouts/makehuman_hm08_face.layout.json"\n'
                 f'capture = "{v}/animface_dots.mp4"\nseeds = "{v}/animface_dots.seeds.json"\n'
                 f'output = "out/{{capture}}"\n')
    m = load_manifest(p)
    assert m.shots[0].is_video
    s = run_batch(m, BatchOptions(workers=0))
    assert s["shots"][0]["status"] == "ok", s["shots"][0]["error"]
    out = Path(s["shots"][0]["output"])
    assert (out / "tracks.usdc").is_file() and (out / "anim.usdc").is_file()
    assert s["_exit"] == 0


def test_shots_of_one_mesh_and_capture_are_told_apart(tmp_path, sample_assets, capsys):
    """Windows of one take (two entries, same mesh and capture): each shot its own name and record;
    the summary accounts for both (one overwrote the other's record), a failed one names its
    manifest line."""
    from usdface.cli import main

    sa = sample_assets
    shot = (f'mesh = "{sa}/meshes/makehuman_hm08_face_cm.obj"\n'
            f'layout = "{sa}/layouts/makehuman_hm08_face.layout.json"\n'
            f'capture = "{sa}/capture/JawMoCap.ma"\nmethod = "euclidean"\n')
    p = tmp_path / "windows.toml"
    p.write_text(f'[batch]\nsummary = "out/s.json"\n\n[[shots]]\n{shot}trim = [0, 30]\noutput = "out/a"\n\n'
                 f'[[shots]]\n{shot}trim = [30, 60]\noutput = "out/b"\n\n[[shots]]\n{shot}trim = [5000, 5030]\n'
                 'output = "out/past_the_end"\n')
    names = [s.name for s in load_manifest(p).shots]
    assert names == ["makehuman_hm08_face_cm/JawMoCap (out/a)", "makehuman_hm08_face_cm/JawMoCap (out/b)",
                     "makehuman_hm08_face_cm/JawMoCap (out/past_the_end)"]
    capsys.readouterr()
    assert main(["batch", str(p), "--workers", "0"]) == 1
    err = capsys.readouterr().err
    summary = json.loads((tmp_path / "out" / "s.json").read_text())
    assert [r["name"] for r in summary["shots"]] == names
    assert [r["status"] for r in summary["shots"]] == ["ok", "ok", "failed"]
    assert [r["output"] for r in summary["shots"]] == [str(tmp_path / "out" / n) for n in ("a", "b", "past_the_end")]
    assert "manifestLine" not in summary["shots"][0] and summary["shots"][2]["manifestLine"] == 20
    assert ("failed      makehuman_hm08_face_cm/JawMoCap (out/past_the_end) " in err
            and "  line 20: import-capture step failed: --trim 5000 5030: expected" in err)
