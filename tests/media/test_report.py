"""`usdface report` and `usdface batch --report`: one HTML file built from OUTDIR alone, opened in a
real headless browser: screenshot, no console errors, every picture, plot and the movie present,
no request leaving file://."""
from __future__ import annotations

import json
import re
import shutil

import numpy as np
import pytest

from usdface import api
from usdface.errors import InputError, OptionError, WriteError
from usdface.options import ReportOptions

pytest.importorskip("plotly")
pytest.importorskip("av")

STANDARD = {"trajectories", "marker-paths", "validity", "stabilization", "binding", "displacement", "amplification"}


def figures_in(html: str) -> dict:
    out = {}
    for fid, payload in re.findall(r'<script type="application/json" id="(plot-\d+)-data">(.*?)</script>', html, re.S):
        out[fid] = json.loads(payload.replace("<\\/", "</"))
    return out


def keys_in(html: str) -> list:
    return re.findall(r'<div class="plot" id="plot-\d+" data-src="plot-\d+-data" data-key="([^"]*)"', html)


@pytest.fixture(scope="module")
def gaps_report(shots, tmp_path_factory):
    """The report of the take with filled gaps, with its playblast (300 frames, small)."""
    d = tmp_path_factory.mktemp("report")
    out = d / "jaw_gaps.html"
    result = api.report(shots["gaps"], ReportOptions(playblast_size=(320, 180)), output=out)
    return {"out": out, "summary": result.summary, "html": out.read_text()}


def test_report_is_one_offline_file_with_every_plot(gaps_report, shots):
    html = gaps_report["html"]
    assert html.count("plotly.js v") == 1  # the plot library, embedded once
    # nothing is fetched from anywhere: no remote src/href, only data: URIs and the relative movie
    markup = re.sub(r"<script\b[^>]*>.*?</script>", "", html, flags=re.S)  # the page itself, not plotly.js
    refs = re.findall(r'(?:src|href)="([^"]+)"', markup)
    assert refs and not [r for r in refs if re.match(r"\w+://", r)]
    assert {r.split(":")[0] for r in refs if ":" in r} == {"data"}
    keys = set(keys_in(html))
    assert STANDARD <= keys and "gaps" in keys
    figs = {f.get("layout", {}).get("title", {}).get("text", ""): f for f in figures_in(html).values()}
    # the numbers come from the run: the validity map holds the filled and the unfilled gaps
    validity = next(f for t, f in figs.items() if t.startswith("Marker validity"))
    z = np.array(validity["data"][0]["z"])
    names = validity["data"][0]["y"]
    assert (z == 1).sum() == 6 + 3  # Chin 100..105 and Mouth_DownL 150..152 filled
    assert (z[names.index("NoseTop"), 200:230] == 0).all() and (z == 0).sum() == 30  # too long: invalid
    binding = next(f for t, f in figs.items() if t.startswith("Binding"))
    summary = json.loads((shots["gaps"] / "summary.json").read_text())
    res = summary["steps"]["bind"]["residuals"]
    assert binding["data"][0]["x"] == list(res)
    np.testing.assert_allclose(binding["data"][0]["y"], list(res.values()), atol=5e-4 * max(res.values()))
    movie = gaps_report["out"].parent / "jaw_gaps_media" / "jaw_gaps.mp4"
    assert movie.is_file() and gaps_report["summary"]["movie"] == "jaw_gaps_media/jaw_gaps.mp4"


def test_stabilisation_plot_measures_what_the_fit_removed(gaps_report):
    figs = figures_in(gaps_report["html"])
    stab = next(f for f in figs.values() if f["layout"]["title"]["text"].startswith("Head stabilisation"))
    curves = {t["name"]: np.array([np.nan if v is None else v for v in t["y"]]) for t in stab["data"]}
    before, after = curves["stabilisation markers: before"], curves["stabilisation markers: after"]
    # the head-local frame is the rest pose (the still stretch around frame 0): the neutral frame
    # is near it, not exactly on it as when one frame was the reference
    assert np.nanmax(before) > 1.0 and np.nanmax(after) < 0.3 * np.nanmax(before)
    assert before[0] < 0.3 and after[0] < 0.3
    held_after = curves["held-out markers: after"]
    assert np.nanmax(held_after) < np.nanmax(curves["held-out markers: before"])


def test_report_opened_in_a_real_browser(gaps_report, browser, page_opener, tmp_path):
    page = page_opener(browser, gaps_report["out"])
    state = page["state"]
    assert state is not None and state["errors"] == [] and state["plots"] >= 8
    severe = [e for e in page["console"] if e.get("level") == "SEVERE"]
    assert severe == [], severe
    external = [u for u in page["requests"] if not u.startswith(("file:", "data:", "blob:", "about:", "chrome:",
                                                                 "devtools:"))]
    assert external == [], external
    drawn = browser.execute_script(
        "return Array.from(document.querySelectorAll('div.plot')).map(d => "
        "[d.dataset.key, d.querySelectorAll('.main-svg').length, d.querySelectorAll('path, rect').length])")
    assert len(drawn) == state["plots"] and all(n_svg >= 1 and n_shapes > 5 for _, n_svg, n_shapes in drawn), drawn
    images = browser.execute_script(
        "return Array.from(document.images).map(i => [i.alt, i.complete, i.naturalWidth, i.naturalHeight])")
    assert len(images) >= 4 and all(ok and w > 50 and h > 50 for _, ok, w, h in images), images
    video = browser.execute_script(
        "var v = document.querySelector('video'); return new Promise(function(done) {"
        " function report() { done([v.readyState, v.duration, v.videoWidth, v.videoHeight,"
        "  v.error ? v.error.code : null]); }"
        " if (v.readyState >= 1) report(); else { v.addEventListener('loadedmetadata', report);"
        "  v.addEventListener('error', report); v.load(); } });")
    ready, duration, vw, vh, err = video
    assert err is None and ready >= 1 and (vw, vh) == (320, 180)
    assert duration == pytest.approx(300 / 60, abs=0.05)  # the take: 300 frames at 60 fps
    height = browser.execute_script("return document.body.scrollHeight")
    browser.set_window_size(1400, min(int(height), 16000))
    shot = tmp_path / "report.png"
    assert browser.save_screenshot(str(shot)) and shot.stat().st_size > 50_000


def test_blend_shape_solve_hook(shots, tmp_path):
    """A run folder with curves.csv and a per-frame residual gets the blend-shape section."""
    d = tmp_path / "bs"
    shutil.copytree(shots["gaps"], d)
    frames = np.arange(300)
    rng = np.random.default_rng(5)
    jaw = np.clip(np.sin(frames / 40.0), 0, 1)
    rows = ["frame,time,jawOpen,mouthSmileLeft,tongueOut"] + [
        f"{f},{f / 60:.6f},{jaw[f]:.4f},{0.3 * rng.random():.4f},0" for f in frames]
    (d / "curves.csv").write_text("\n".join(rows) + "\n")
    summary = json.loads((d / "summary.json").read_text())
    summary["steps"]["solve"] = {"residualPerFrame": list(np.round(0.05 + 0.01 * jaw, 4)), "seconds": 1.0}
    (d / "summary.json").write_text(json.dumps(summary))
    out = tmp_path / "bs.html"
    api.report(d, ReportOptions(no_playblast=True), output=out)
    html = out.read_text()
    keys = keys_in(html)
    assert "blendshape-curves" in keys and "blendshape-residual" in keys
    figs = figures_in(html)
    curves = next(f for f in figs.values() if f["layout"]["title"]["text"] == "Blend-shape weight curves")
    by_name = {t["name"]: t for t in curves["data"]}
    assert set(by_name) == {"jawOpen", "mouthSmileLeft", "tongueOut"}
    assert by_name["tongueOut"]["visible"] == "legendonly" and by_name["jawOpen"]["visible"] is True
    np.testing.assert_allclose(by_name["jawOpen"]["y"], jaw, atol=6e-4)  # 4 significant digits


def test_batch_report_table_thumbnails_and_links(shots, sample_assets, tmp_path, cli, browser, page_opener):
    manifest = tmp_path / "two.toml"
    mesh = sample_assets / "meshes" / "makehuman_hm08_face_cm.obj"
    layout = sample_assets / "layouts" / "makehuman_hm08_face.layout.json"
    manifest.write_text(f"""
[batch]
cache = false
summary = "out/batch.json"
[defaults]
trim = [0, 120]
method = "euclidean"
output = "out/{{capture}}"
[[shots]]
mesh = "{mesh}"
layout = "{layout}"
capture = "{sample_assets / 'capture' / 'JawMoCap.ma'}"
[[shots]]
mesh = "{mesh}"
layout = "{layout}"
capture = "{tmp_path / 'missing.ma'}"
""")
    # a missing capture is refused before any work: the batch and its report are not written
    assert cli("batch", manifest, "--workers", 0, "--report", "-q") == 2
    assert not (tmp_path / "out").exists()
    manifest.write_text(manifest.read_text().replace(str(tmp_path / "missing.ma"),
                                                     str(sample_assets / "capture" / "NoseMoCap.ma")))
    assert cli("batch", manifest, "--workers", 0, "--report", "-q") == 0
    out = tmp_path / "out" / "batch.html"
    html = out.read_text()
    assert html.count("plotly.js v") == 1
    for name in ("JawMoCap", "NoseMoCap"):
        assert f'href="{name}/shot.usda"' in html and f'href="{name}/summary.json"' in html
    assert html.count('JawMoCap thumbnail"') == 1 and html.count('<section class="shot"') == 2
    assert len([k for k in keys_in(html) if k == "binding"]) == 2
    page = page_opener(browser, out)
    assert page["state"]["errors"] == [] and [e for e in page["console"] if e.get("level") == "SEVERE"] == []
    rows = browser.execute_script("return document.querySelectorAll('table')[0].rows.length")
    assert rows == 3  # header + 2 shots
    images = browser.execute_script("return Array.from(document.images).map(i => i.complete && i.naturalWidth > 0)")
    assert images and all(images)


def test_batch_report_from_a_summary_with_movies_and_failures(shots, tmp_path):
    """What `usdface batch --report` calls (usdface.pipeline.report.batch_report): a failed shot and an
    unreadable one are listed with their errors and get no section; with ReportOptions each finished
    shot also gets its playblast (the playblast processor, through the registry) in <report>_media/."""
    from usdface.media import movie_info
    from usdface.pipeline.report import batch_report

    empty = tmp_path / "empty"
    empty.mkdir()
    summary = {"manifest": "m.toml", "counts": {"ok": 2, "failed": 1}, "seconds": 12.5, "mode": "serial",
               "workers": 0, "summaryFile": str(tmp_path / "b.json"),
               "shots": [{"name": "gaps", "status": "ok", "output": str(shots["gaps"]), "seconds": 3.0,
                          "steps": {"bind": 0.5}, "frames": 300},
                         {"name": "broken", "status": "failed", "error": "boom"},
                         {"name": "unreadable", "status": "ok", "output": str(empty)}]}
    result = batch_report(summary)  # beside the summary file, no movies
    out = tmp_path / "b.html"
    assert result.files == {"output": str(out)} and (result.summary["shots"], result.summary["sections"]) == (3, 1)
    assert result.text[0].startswith(f"wrote {out}: 3 shot(s), 1 with plots")
    html = out.read_text()
    assert html.count('<section class="shot"') == 1 and html.count('id="shot-0"') == 1
    assert '<span class="err">boom</span>' in html and "no summary.json" in html
    assert "<video" not in html and not (tmp_path / "b_media").exists()
    result = batch_report(summary, tmp_path / "m.html", options=ReportOptions(playblast_size=(160, 90)))
    movie = tmp_path / "m_media" / "gaps.mp4"
    info = movie_info(movie)
    assert (info["width"], info["height"], info["frames"]) == (160, 90, 300)
    assert 'src="m_media/gaps.mp4"' in (tmp_path / "m.html").read_text()
    assert result.files["media"] == str(tmp_path / "m_media")
    with pytest.raises(OptionError, match="renders each shot's movie itself"):
        batch_report(summary, tmp_path / "x.html", options=ReportOptions(playblast=str(movie)))
    with pytest.raises(InputError, match=r"batch summary .*none.json: no such file"):
        batch_report(tmp_path / "none.json")
    with pytest.raises(OptionError, match="names no summaryFile"):
        batch_report({"shots": []})
    assert not (tmp_path / "x.html").exists()


# -- bad input ---------------------------------------------------------------------------------------

def test_report_bad_input_leaves_nothing(shots, tmp_path, cli, capsys):
    with pytest.raises(InputError, match="no summary.json"):
        api.report(shots["dir"], output=tmp_path / "r.html")
    with pytest.raises(InputError, match="no such folder"):
        api.report(tmp_path / "nowhere", output=tmp_path / "r.html")
    with pytest.raises(OptionError, match=r"\.html"):
        api.report(shots["gaps"], output=tmp_path / "r.pdf")
    with pytest.raises(WriteError, match="cannot write report"):   # the environment's fault: exit 1
        api.report(shots["gaps"], output="/proc/usdface-report.html")
    with pytest.raises(InputError, match="does not exist"):
        api.report(shots["gaps"], output=tmp_path / "no" / "r.html")
    with pytest.raises(InputError, match="--playblast .*: no such file"):
        api.report(shots["gaps"], ReportOptions(playblast=str(tmp_path / "none.mp4")), output=tmp_path / "r.html")
    assert list(tmp_path.iterdir()) == []
    assert cli("report", shots["gaps"], "-o", "/proc/r.html", "--no-playblast") == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("usdface report: error: cannot write report")


def test_a_failed_playblast_leaves_no_report_and_no_media(shots, tmp_path, monkeypatch):
    from usdface.processors import playblast as pb

    def broken(*args, **kwargs):
        raise InputError("renderer exploded")

    monkeypatch.setattr(pb, "playblast", broken)  # the registry finds the processor when it runs
    with pytest.raises(InputError, match="renderer exploded"):
        api.report(shots["gaps"], output=tmp_path / "r.html")
    assert list(tmp_path.iterdir()) == []


def test_a_run_with_blend_shapes_reports_its_curves_and_residual(sample_assets, tmp_path, cli):
    out = tmp_path / "bs"
    assert cli("run", "--mesh", sample_assets / "meshes" / "makehuman_hm08_face_cm.obj", "--capture",
               sample_assets / "capture" / "JawMoCap.ma", "--layout",
               sample_assets / "layouts" / "makehuman_hm08_face.layout.json", "--shapes",
               sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz", "--output-kind", "blendshapes",
               "--trim", 0, 120, "-o", out, "-q") == 0
    assert cli("report", out, "-o", tmp_path / "r.html", "--no-playblast", "-q") == 0
    html = (tmp_path / "r.html").read_text()
    assert "blendshape-curves" in html and "blendshape-residual" in html
