"""What `usdface run` tells the user: its summary names the width it prints, options that only the
blend-shape deliverable reads warn when it is not asked for, an error names the command once."""
from __future__ import annotations

import logging

import pytest

LAYOUT = "makehuman_hm08_face.layout.json"
MESH = "makehuman_hm08_face_cm.obj"


def _run(cli, sample_assets, out, *argv):
    return cli("run", "--mesh", sample_assets / "meshes" / MESH, "--capture", sample_assets / "capture" / "JawMoCap.ma",
               "--method", "euclidean", "--trim", "0", "30", "-o", out, *argv)


def _warnings(caplog) -> list:
    return [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]


@pytest.mark.parametrize("argv, flags, kinds", [
    (["--livelink"], "--livelink: only the blendshapes deliverable uses it", "points,blendshapes"),
    (["--output-kind", "skel", "--fps", "24", "--livelink", "--sparsity", "0.5"],
     "--livelink, --sparsity, --fps: only the blendshapes deliverable uses them", "skel,blendshapes"),
])
def test_blendshape_options_without_the_blendshapes_deliverable_warn_once(argv, flags, kinds, cli, sample_assets,
                                                                          tmp_path, caplog):
    out = tmp_path / "shot"
    caplog.set_level(logging.WARNING, logger="usdface")
    assert _run(cli, sample_assets, out, "--layout", sample_assets / "layouts" / LAYOUT, *argv) == 0
    assert _warnings(caplog) == [f"{flags}; ignored (add it: --output-kind {kinds})"]
    assert not (out / "curves_livelink.csv").exists()


def test_run_prints_which_width_it_shows_and_stays_quiet_without_blendshape_options(cli, sample_assets, tmp_path,
                                                                                     capsys, caplog):
    caplog.set_level(logging.WARNING, logger="usdface")
    assert _run(cli, sample_assets, tmp_path / "shot", "--layout", sample_assets / "layouts" / LAYOUT) == 0
    captured = capsys.readouterr()
    (line,) = [x for x in captured.out.splitlines() if x.startswith("  transfer: ")]
    assert line.startswith("  transfer: interpolate gaussian, ") and line.endswith(
        " cm (median of the per-marker widths)"), line
    assert [w for w in _warnings(caplog) if "blendshapes deliverable" in w] == []
    assert _run(cli, sample_assets, tmp_path / "wide", "--layout", sample_assets / "layouts" / LAYOUT,
                "--stiffness", "2.5") == 0
    (line,) = [x for x in capsys.readouterr().out.splitlines() if x.startswith("  transfer: ")]
    assert line.endswith(", width 2.5 cm (--stiffness)"), line


def test_an_error_names_the_command_once(cli, sample_assets, tmp_path, capsys):
    assert _run(cli, sample_assets, tmp_path / "shot") == 2
    assert capsys.readouterr().err.splitlines() == [
        "usdface run: error: give exactly one of --layout LAYOUT.json or --auto"]
