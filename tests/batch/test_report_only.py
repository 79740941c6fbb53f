"""`usdface batch --report-only`: the HTML report of a finished batch rebuilt from its summary, with
no shot run or checked (issue 20: `batch --report` re-ran the shots unless --resume)."""
from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import pytest

from usdface.cli import main
from usdface.fileutil import file_digest

pytest.importorskip("plotly", reason="the batch report needs the 'media' extra")

SA = Path(__file__).resolve().parents[2] / "sample_assets"


def _without_pictures(html: bytes) -> str:
    """The page with its embedded pictures left out: the pictures a process that ran shots renders
    differ from a fresh process's by a few levels on some pixels (the renderer's, not the batch's)."""
    return re.sub(r"data:image/[a-z]+;base64,[A-Za-z0-9+/=]+", "data:image", html.decode())


def _snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): (p.stat().st_mtime_ns, file_digest(p))
            for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def finished_batch(tmp_path_factory):
    """A finished serial batch (two shots and a broken capture) with its report; its inputs are
    then deleted, so any attempt to run or check a shot would fail."""
    root = tmp_path_factory.mktemp("finished")
    inputs = root / "inputs"
    inputs.mkdir()
    for p in (SA / "meshes" / "makehuman_hm08_face_cm.obj", SA / "layouts" / "makehuman_hm08_face.layout.json",
              SA / "capture" / "JawMoCap.ma", SA / "capture" / "NoseMoCap.ma"):
        shutil.copy(p, inputs / p.name)
    (inputs / "BrokenMoCap.ma").write_text("//Maya ASCII 2018 scene\nthis is not a Maya file at all {{{\n")
    manifest = root / "shots.toml"
    manifest.write_text("\n".join([
        "[batch]", 'summary = "out/batch.json"', 'cache = "out/cache"',
        "[defaults]", "trim = [0, 40]", 'method = "euclidean"', 'output = "out/{capture}"',
        "[[shots]]", 'mesh = "inputs/makehuman_hm08_face_cm.obj"', 'layout = "inputs/makehuman_hm08_face.layout.json"',
        'capture = "inputs/*MoCap.ma"']) + "\n")
    assert main(["batch", str(manifest), "--workers", "0", "--report", "-q"]) == 1  # the broken shot fails
    shutil.rmtree(inputs)
    return root, manifest


def test_report_only_rebuilds_the_report_without_touching_a_shot(finished_batch, capsys):
    root, manifest = finished_batch
    summary = json.loads((root / "out" / "batch.json").read_text())
    assert summary["counts"] == {"ok": 2, "skipped": 0, "failed": 1, "unsupported": 0}
    original = (root / "out" / "batch.html").read_bytes()
    (root / "out" / "batch.html").unlink()
    before = _snapshot(root / "out")
    capsys.readouterr()
    assert main(["batch", str(manifest), "--report-only"]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert out.startswith(f"wrote {root / 'out' / 'batch.html'}: 3 shot(s), 2 with plots")
    # the same page as the one written after the shots, from the summary alone
    rebuilt = (root / "out" / "batch.html").read_bytes()
    assert _without_pictures(rebuilt) == _without_pictures(original)
    after = _snapshot(root / "out")
    assert after.pop("batch.html") and after == before  # no shot folder, cache entry or summary touched
    assert "is not terminated by &#x27;;&#x27;: the file is truncated or malformed" in rebuilt.decode()
    # elsewhere, with --json
    other = root / "out" / "again.html"
    assert main(["batch", str(manifest), "--report-only", "--report", str(other), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["report"] == str(other) and result["shots"] == 3 and result["sections"] == 2
    assert result["summaryFile"] == str(root / "out" / "batch.json")
    assert _without_pictures(other.read_bytes()) == _without_pictures(rebuilt)
    other.unlink()


def test_report_only_with_another_summary_and_api(finished_batch, tmp_path):
    from usdface import api
    from usdface.options import BatchOptions

    root, manifest = finished_batch
    moved = tmp_path / "kept.json"
    shutil.copy(root / "out" / "batch.json", moved)
    result = api.batch(str(manifest), options=BatchOptions(report_only=True), summary=str(moved))
    assert result.exit_code == 0 and result.files["report"] == str(tmp_path / "kept.html")
    assert (tmp_path / "kept.html").stat().st_size > 10_000


@pytest.mark.parametrize("args,message", [
    (["--resume"], "usdface batch: error: --report-only writes the report of the finished batch from its summary "
                   "and runs no shot: leave out --resume"),
    (["--workers", "2", "--no-cache"], "usdface batch: error: --report-only writes the report of the finished batch "
                                       "from its summary and runs no shot: leave out --workers, --no-cache"),
    (["--summary", "{tmp}/none.json"], "usdface batch: error: batch summary {tmp}/none.json: no such file (run the "
                                       "batch first; --report-only rebuilds the report of a finished batch)"),
    (["--summary", "{tmp}/bad.json"], "usdface batch: error: batch summary {tmp}/bad.json: not JSON (Expecting value: "
                                      "line 1 column 1 (char 0))"),
    (["--summary", "{tmp}/list.json"], "usdface batch: error: batch summary {tmp}/list.json: not a usdface batch "
                                       "summary (expected a JSON object with a \"shots\" list)"),
    (["--report", "{tmp}/r.txt"], "usdface batch: error: -o {tmp}/r.txt: a report is an .html file"),
])
def test_report_only_bad_input(finished_batch, tmp_path, capsys, args, message):
    root, manifest = finished_batch
    (tmp_path / "bad.json").write_text("nope")
    (tmp_path / "list.json").write_text("[1, 2]")
    before = _snapshot(root)
    capsys.readouterr()
    assert main(["batch", str(manifest), "--report-only", *[a.format(tmp=tmp_path) for a in args]]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [message.format(tmp=tmp_path)]
    assert _snapshot(root) == before


def test_report_only_never_replaces_the_manifest(finished_batch, capsys):
    root, manifest = finished_batch
    text = manifest.read_bytes()
    renamed = manifest.with_suffix(".html")
    os.link(manifest, renamed)  # the manifest under an .html name: the report would replace it
    try:
        assert main(["batch", str(manifest), "--report-only", "--report", str(renamed)]) == 2
    finally:
        renamed.unlink()
    assert "would overwrite the input" in capsys.readouterr().err
    assert manifest.read_bytes() == text
