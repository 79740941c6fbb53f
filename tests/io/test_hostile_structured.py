"""Hostile structured inputs through the command line (issue 20, items 3 and 5): a batch manifest,
track seeds, run --stiffness, a simulate timeline and a report's summary.json that are a named
pipe, nested 100000 deep, not UTF-8 or huge. Each is one line naming the file and what was
expected, exit 2, the file untouched (before: a RecursionError traceback, or "no such file" for a
pipe that exists)."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.hostile import assert_one_line, digest, run_in_process

SA = Path(__file__).resolve().parents[2] / "sample_assets"
MESH, TAKE = SA / "meshes" / "makehuman_hm08_face_cm.obj", SA / "capture" / "JawMoCap.ma"
LAYOUT = SA / "layouts" / "makehuman_hm08_face.layout.json"


def _hostile(folder: Path, kind: str, suffix: str) -> tuple[Path, str]:
    """A hostile file of ``kind`` and the words the one error line must hold."""
    import os

    p = folder / f"{kind}{suffix}"
    if kind == "pipe":
        os.mkfifo(p)
        return p, "is a named pipe (FIFO), not a regular file"
    if kind == "deep":
        p.write_text(("a = " if suffix == ".toml" else "") + "[" * 100000)
        return p, "nested deeper than 64 levels"
    if kind == "latin":
        p.write_bytes(b'[batch]\nsummary = "r\xe9sum\xe9.json"\n' if suffix == ".toml" else b'{"Chin": [1, 2], "N\xe9": 1}')
        return p, "not UTF-8 text (byte 0xe9 at line"
    with open(p, "wb") as f:
        f.truncate(64 * 1024 * 1024 + 1)
    return p, "67,108,865 bytes; a usdface"


KINDS = ["pipe", "deep", "latin", "huge"]


def _check(capsys, path, argv, command, label, expected):
    before = None if path.is_fifo() else digest(path)
    rc, lines = run_in_process(capsys, *argv)
    assert_one_line(rc, lines, code=2, command=command, contains=[f"{label} {path}: {expected}"])
    assert before is None or digest(path) == before


@pytest.mark.parametrize("kind", KINDS)
def test_batch_manifest(tmp_path, capsys, kind):
    path, expected = _hostile(tmp_path, kind, ".toml")
    _check(capsys, path, ["batch", path, "--workers", "0"], "batch", "manifest", expected)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no summary, no cache


@pytest.mark.parametrize("kind", KINDS)
def test_track_seeds(tmp_path, capsys, kind):
    path, expected = _hostile(tmp_path, kind, ".json")
    _check(capsys, path, ["track", SA / "video" / "animface_dots.mp4", "--seeds", path, "-o", tmp_path / "t.usdc"],
           "track", "--seeds", expected)


@pytest.mark.parametrize("kind", KINDS)
def test_run_stiffness(tmp_path, capsys, kind):
    path, expected = _hostile(tmp_path, kind, ".json")
    _check(capsys, path, ["run", "--mesh", MESH, "--capture", TAKE, "--layout", LAYOUT, "--stiffness", path,
                          "-o", tmp_path / "out"], "run", "--stiffness", expected)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("kind", KINDS)
def test_simulate_timeline(tmp_path, capsys, kind, cli):
    path, expected = _hostile(tmp_path, kind, ".json")
    rig = tmp_path / "rig.usda"
    assert cli("muscles", "--mesh", SA / "meshes" / "makehuman_hm08_face_cm.usdc", "--layout", LAYOUT, "-o", rig,
               "-q") == 0
    _check(capsys, path, ["simulate", "--mesh", SA / "meshes" / "makehuman_hm08_face_cm.usdc", "--rig", rig,
                          "--timeline", path, "-o", tmp_path / "sim.usdc"], "simulate", "timeline", expected)


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    from usdface.cli import main

    out = tmp_path_factory.mktemp("shot") / "shot"
    assert main(["run", "--mesh", str(MESH), "--capture", str(TAKE), "--layout", str(LAYOUT), "--method", "euclidean",
                 "--trim", "0", "10", "-o", str(out), "-q"]) == 0
    return out


@pytest.mark.parametrize("kind", KINDS)
def test_report_of_a_folder_whose_summary_is_hostile(tmp_path, capsys, kind, shot):
    folder = tmp_path / "shot"
    shutil.copytree(shot, folder)
    (folder / "summary.json").unlink()
    path, expected = _hostile(folder, kind, ".json")
    path.rename(folder / "summary.json")
    path = folder / "summary.json"
    _check(capsys, path, ["report", folder, "-o", tmp_path / "r.html", "--no-playblast"], "report", "report", expected)
    assert not (tmp_path / "r.html").exists()


def test_batch_report_of_a_hostile_summary(tmp_path):
    from usdface.errors import FormatError, InputError
    from usdface.pipeline.report import batch_report

    for kind in KINDS:
        path, expected = _hostile(tmp_path, kind, ".json")
        with pytest.raises((FormatError, InputError)) as info:
            batch_report(path, tmp_path / "r.html")
        assert str(info.value).startswith(f"batch summary {path}: {expected}"), str(info.value)
    (tmp_path / "list.json").write_text("[1, 2]")
    with pytest.raises(InputError, match=r"list\.json: expected the JSON object `usdface batch` writes"):
        batch_report(tmp_path / "list.json", tmp_path / "r.html")
