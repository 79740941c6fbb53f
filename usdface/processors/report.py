"""`usdface report OUTDIR -o report.html`: a self-contained QC report of a shot; the batch report.

The HTML opens offline: plotly.js is inlined once, pictures are data URIs, and the playblast is
a relative link into a sibling folder ``<report>_media/``. Everything comes from OUTDIR (the
output folder of ``usdface run``). Files are written atomically: the media folder and the page
go to temporary names and are renamed into place only when complete.
"""
from __future__ import annotations

import argparse
import os
import secrets
import shutil
import time
from pathlib import Path

from ..errors import InputError, OptionError
from ..fileutil import probe_writable_folder, write_text_atomic
from ..options import PlayblastOptions

__all__ = ["batch_report", "register_cli", "report"]


def _check_output(output) -> Path:
    out = Path(output)
    if out.suffix.lower() not in (".html", ".htm"):
        raise OptionError(f"-o {out}: a report is an .html file")
    probe_writable_folder(out, what="report")  # fails now, before any rendering
    return out


def _media_name(out: Path) -> str:
    return f"{out.stem}_media"


def _commit_folder(tmp: Path, final: Path) -> None:
    """Rename a finished temporary folder over ``final`` (the old one, if any, is removed after)."""
    old = None
    if final.exists():
        old = final.with_name(f".{final.name}.old-{secrets.token_hex(4)}")
        os.replace(final, old)
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(tmp, 0o777 & ~mask)  # a plain folder's permissions (a temporary one is private)
    os.replace(tmp, final)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _temporary_folder(final: Path) -> Path:
    """A private folder beside ``final`` named for its owner (tidied if the owner dies)."""
    from ..fileutil import temporary_path

    tmp = temporary_path(final)
    tmp.mkdir()
    return tmp


def _finish(page, out: Path, tmp_media: Path | None) -> None:
    """Render the page, move the finished media folder into place, then the page (last: a page on
    disk always finds its movies)."""
    text = page.render()
    if tmp_media is not None:
        _commit_folder(tmp_media, out.parent / _media_name(out))
    write_text_atomic(out, text)


def shot_pictures(d, reader) -> dict:
    """The pictures of a shot's section (PNG bytes)."""
    import numpy as np

    from ..report.pictures import binding_picture, contact_sheet_picture, map_picture

    pics = {"contact": contact_sheet_picture(d, reader), "binding": binding_picture(d, reader)}
    if d.vertex_max is not None:
        pics["vertexMax"] = map_picture(reader, d.vertex_max, label=f"largest displacement ({d.units})",
                                        title=f"{d.name}: largest displacement")
    if reader.hybrid_weight is not None:
        pics["hybrid"] = map_picture(reader, np.asarray(reader.hybrid_weight), label="hybrid weight w",
                                     title=f"{d.name}: hybrid weight", vrange=(0.0, 1.0))
    return pics


def report(outdir, output, *, playblast=True, playblast_size=(640, 360), playblast_color="displacement",
           workers=None) -> dict:
    """Write the QC report of the run folder ``outdir`` to ``output`` (.html).

    Parameters
    ----------
    playblast : bool or path
        True: render a playblast into ``<output stem>_media/`` and embed it; a path: link that
        existing movie instead; False: no movie.
    playblast_size : (w, h)
    playblast_color : str
        Colour mode of the report's playblast (default displacement).
    """
    from ..report.build import add_shot_section
    from ..report.data import gather_shot
    from ..report.html import Page, plotly_js
    from ..usd.playback import ShotReader

    started = time.perf_counter()
    out = _check_output(output)
    plotly_js()  # a missing plotly fails before the work
    d = gather_shot(outdir)
    reader = ShotReader.open(d.shot)
    page = Page(f"usdface QC report: {d.name}", f"{d.outdir}")
    pictures = shot_pictures(d, reader)
    movie = None
    tmp_media = None
    try:
        if playblast is True:
            from .playblast import playblast as make_playblast

            tmp_media = _temporary_folder(out.parent / _media_name(out))
            movie_name = f"{d.name.replace('/', '_')}.mp4"
            make_playblast(d.shot, tmp_media / movie_name,
                           PlayblastOptions(size=playblast_size, color=playblast_color, workers=workers))
            movie = f"{_media_name(out)}/{movie_name}"
        elif playblast:
            p = Path(playblast)
            if not p.is_file():
                raise InputError(f"--playblast {p}: no such file")
            movie = os.path.relpath(p.resolve(), out.resolve().parent)
        add_shot_section(page, d, pictures, anchor="shot", movie=movie,
                         movie_caption=f"playblast, {playblast_color} colours" if playblast is True else "playblast")
        _finish(page, out, tmp_media)
        tmp_media = None
    finally:
        if tmp_media is not None:
            shutil.rmtree(tmp_media, ignore_errors=True)
    seconds = time.perf_counter() - started
    return {"output": str(out), "outdir": str(outdir), "movie": movie, "bytes": out.stat().st_size,
            "seconds": round(seconds, 3),
            "_text": [f"wrote {out} ({out.stat().st_size / 1e6:.1f} MB{', movie ' + movie if movie else ''}) "
                      f"in {seconds:.1f} s"]}


def batch_report(summary, output=None, *, playblasts=False, workers=None) -> dict:
    """Write the report of a batch (its summary dict or JSON file): a table of every shot with
    thumbnails and links, then each finished shot's section."""
    import json

    from ..report.build import add_shot_section
    from ..report.data import gather_shot
    from ..report.html import Page, esc, plotly_js
    from ..report.pictures import thumbnail
    from ..usd.playback import ShotReader

    started = time.perf_counter()
    if not isinstance(summary, dict):
        path = Path(summary)
        if not path.is_file():
            raise InputError(f"batch summary {path}: no such file")
        summary = json.loads(path.read_text())
    if output is None:
        sf = summary.get("summaryFile")
        if not sf:
            raise OptionError("batch report: no output file and the summary names no summaryFile")
        output = Path(sf).with_suffix(".html")
    out = _check_output(output)
    plotly_js()
    counts = summary.get("counts", {})
    page = Page("usdface batch report", f"{summary.get('manifest', '')}: " + ", ".join(
        f"{v} {k}" for k, v in counts.items() if v) + f" in {summary.get('seconds', 0):.1f} s "
        f"({summary.get('mode', '')}, {summary.get('workers', '')} worker(s))")
    rows, sections = [], []
    tmp_media = None
    try:
        for k, shot in enumerate(summary.get("shots", [])):
            anchor = f"shot-{k}"
            thumb = ""
            d = None
            if shot.get("status") in ("ok", "skipped") and shot.get("output"):
                try:
                    d = gather_shot(shot["output"])
                    d.name = shot.get("name") or d.name  # the batch's name tells meshes apart
                    reader = ShotReader.open(d.shot)
                    png = thumbnail(d, reader)
                    thumb = f'<a href="#{anchor}">' + page.picture(png, "", alt=f"{shot['name']} thumbnail",
                                                                   width=120) + "</a>"
                    sections.append((d, reader, anchor))
                except Exception as exc:  # the table still lists the shot
                    from ..errors import UsdFaceError

                    if not isinstance(exc, (UsdFaceError, OSError)):
                        raise
                    thumb = f'<span class="err">{esc(exc)}</span>'
            outdir = shot.get("output") or ""
            links = ""
            if outdir:
                rel = os.path.relpath(Path(outdir).resolve(), out.resolve().parent)
                links = (f'<a href="{esc(rel)}/shot.usda">shot.usda</a> · <a href="{esc(rel)}/summary.json">'
                         "summary.json</a>")
            status = shot.get("status", "")
            cls = "ok" if status == "ok" else ("err" if status == "failed" else "")
            step_times = shot.get("steps") or {}
            cache_status = shot.get("cache") or {}
            seconds = shot.get("seconds") or 0.0
            earlier = ""
            if status == "skipped" and d is not None:  # resumed: the run that made the shot timed it
                run_steps = d.summary.get("steps", {})
                step_times = {n: (v or {}).get("seconds") for n, v in run_steps.items()}
                cache_status = {n: v["cache"]["status"] for n, v in run_steps.items() if (v or {}).get("cache")}
                seconds = d.summary.get("seconds") or 0.0
                earlier = " (earlier run)"
            steps = ", ".join(f"{n} {v:.2f}" for n, v in step_times.items() if isinstance(v, (int, float)))
            cache = ", ".join(f"{n}: {v}" for n, v in cache_status.items())
            name = f'<a href="#{anchor}">{esc(shot.get("name", ""))}</a>' if d is not None else esc(shot.get("name", ""))
            frames = shot.get("frames") or (d.n_frames if d is not None else "")
            rows.append((thumb, name + "<br>" + links, f'<span class="{cls}">{esc(status)}</span>',
                         f"{seconds:.1f}{earlier}", esc(steps), esc(cache), esc(frames),
                         f'<span class="err">{esc(shot.get("error") or "")}</span>'))
        page.heading("Shots", 2)
        page.table(("", "shot", "status", "seconds", "step seconds", "cache", "frames", "error"), rows,
                   raw_columns=(0, 1, 2, 4, 5, 6, 7), numeric=(3,))
        cache = summary.get("cache") or {}
        if cache.get("steps"):
            page.note("cache: " + "; ".join(f"{k}: {v.get('hit', 0)} hit(s), {v.get('miss', 0)} computed"
                                            for k, v in cache["steps"].items()))
        if playblasts:
            from .playblast import playblast as make_playblast

            tmp_media = _temporary_folder(out.parent / _media_name(out))
        for d, reader, anchor in sections:
            movie = None
            if tmp_media is not None:
                name = d.name.replace("/", "_") + ".mp4"
                make_playblast(d.shot, tmp_media / name, PlayblastOptions(size=(480, 270), color="displacement",
                                                                          workers=workers))
                movie = f"{_media_name(out)}/{name}"
            add_shot_section(page, d, shot_pictures(d, reader), anchor=anchor, movie=movie,
                             movie_caption="playblast" if movie else "")
        _finish(page, out, tmp_media)
        tmp_media = None
    finally:
        if tmp_media is not None:
            shutil.rmtree(tmp_media, ignore_errors=True)
    seconds = time.perf_counter() - started
    return {"output": str(out), "shots": len(rows), "sections": len(sections), "seconds": round(seconds, 3),
            "_text": [f"wrote {out}: {len(rows)} shot(s), {len(sections)} with plots "
                      f"({out.stat().st_size / 1e6:.1f} MB) in {seconds:.1f} s"]}


def register_cli(subparsers) -> None:
    from ..cliargs import add_common_options

    p = subparsers.add_parser(
        "report", help="a self-contained HTML QC report of a run's output folder (plots, pictures, playblast)",
        description="Write one HTML file that opens offline (plotly.js inlined once) with the shot's inputs and "
                    "provenance, a contact sheet, the binding, a playblast (in a sibling folder <report>_media/), "
                    "and plots of marker trajectories, validity and gaps filled, stabilisation before/after, "
                    "binding residual per marker, per-frame displacement range, transfer amplification and "
                    "regularisation, and a blend-shape solve's curves when the folder has one. Needs the 'media' "
                    "extra (plotly, PyAV).",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("outdir", help="output folder of `usdface run` (shot.usda, capture.usdc, summary.json ...)")
    p.add_argument("-o", "--output", required=True, help="HTML file to write")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--playblast", metavar="MOVIE", help="link this existing movie instead of rendering one")
    g.add_argument("--no-playblast", action="store_true", help="no movie (faster)")
    p.add_argument("--playblast-size", default="640x360", help="size of the rendered playblast (default 640x360)")
    p.add_argument("--workers", type=int, metavar="N", help="playblast render workers (default: the usable cores)")
    add_common_options(p)
    p.set_defaults(func=_cmd_report)


def _cmd_report(args) -> dict:
    pb = False if args.no_playblast else (args.playblast or True)
    size = PlayblastOptions(size=args.playblast_size).size  # checked as the playblast's --size
    return report(args.outdir, args.output, playblast=pb, playblast_size=size, workers=args.workers)
