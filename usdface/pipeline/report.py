"""`usdface report OUTDIR -o report.html`: a self-contained QC report of a shot; the batch report.

The HTML opens offline: plotly.js is inlined once, pictures are data URIs, and the playblast is a
relative link into a sibling folder ``<report>_media/``. Everything comes from OUTDIR (the output
folder of ``usdface run``). Files are written atomically: the media folder and the page go to
temporary names and are renamed into place only when complete.

A pipeline: the playblast is the `playblast` processor, called through :func:`usdface.registry.call`;
the shot stage and the capture layer are read here (:mod:`usdface.usd`) and handed to
:mod:`usdface.report` as a shot reader and plain data.
"""
from __future__ import annotations

import logging
import os
import time
from pathlib import Path

from .. import registry
from ..errors import InputError, OptionError, UsdFaceError
from ..options import PlayblastOptions, ReportOptions
from ..registry import Result
from ..report.output import MediaFolder, check_report_output, write_report

__all__ = ["BATCH_PLAYBLAST_COLOR", "REPORT_PLAYBLAST_COLOR", "batch_report", "check_report_output", "read_shot",
           "report"]

log = logging.getLogger("usdface")

#: colour mode of a report's playblast: the transfer's displacement, one scale over the take
REPORT_PLAYBLAST_COLOR = "displacement"
BATCH_PLAYBLAST_COLOR = "displacement"


def read_shot(outdir):
    """A run's output folder read for its report: (:class:`usdface.report.ShotData`, the shot's
    :class:`usdface.usd.playback.ShotReader`). Raises InputError naming what is missing."""
    from ..report.data import CAPTURE_FILE, find_shot, gather_shot, load_run_summary
    from ..usd.capture_layer import read_capture_layer
    from ..usd.identity import mixed_layers
    from ..usd.playback import ShotReader

    outdir = Path(outdir)
    summary = load_run_summary(outdir)
    shot = find_shot(outdir)
    reader = ShotReader.open(shot)
    capture_path = outdir / CAPTURE_FILE
    capture = read_capture_layer(capture_path) if capture_path.is_file() else None
    data = gather_shot(outdir, summary, reader, shot=shot, capture=capture)
    # a QC page shows a mix (first among its warnings) rather than refusing: it is where one looks
    data.mixed_layers = mixed_layers(shot)
    return data, reader


def _warn_mixed(d) -> None:
    """One line on the terminal for a shot whose layers disagree (the page lists them first)."""
    from ..usd.identity import mixed_layers_warning

    log.warning("%s", mixed_layers_warning(d.shot, d.mixed_layers))


def _render_playblast(shot, media: MediaFolder, name: str, *, size, color: str, workers) -> str:
    """The `playblast` processor's movie of ``shot`` into the media folder; its link from the page."""
    movie_name = f"{name.replace('/', '_')}.mp4"
    registry.call("playblast", str(shot), options=PlayblastOptions(size=size, color=color, workers=workers),
                  output=str(media.path / movie_name))
    return media.relative(movie_name)


def report(outdir, *, options: ReportOptions, output) -> Result:
    """Write the QC report of the run folder ``outdir`` to ``output`` (.html).

    ``options`` (:class:`usdface.options.ReportOptions`): by default a playblast
    (``playblast_size``, rendered by ``workers``) goes into ``<output stem>_media/`` and is embedded;
    ``playblast``: link that existing movie instead; ``no_playblast``: no movie.
    """
    from ..report.build import add_shot_section
    from ..report.html import Page, plotly_js
    from ..report.pictures import shot_pictures

    started = time.perf_counter()
    out = check_report_output(output)
    plotly_js()  # a missing plotly fails before the work
    d, reader = read_shot(outdir)
    page = Page(f"usdface QC report: {d.name}", f"{d.outdir}")
    pictures = shot_pictures(d, reader)
    render = not options.no_playblast and options.playblast is None
    if d.mixed_layers and not render:  # (the playblast says it when it renders)
        _warn_mixed(d)
    movie = media = None
    try:
        if render:
            media = MediaFolder(out)
            movie = _render_playblast(d.shot, media, d.name, size=options.playblast_size,
                                      color=REPORT_PLAYBLAST_COLOR, workers=options.workers)
        elif options.playblast is not None:
            p = Path(options.playblast)
            if not p.is_file():
                raise InputError(f"--playblast {p}: no such file")
            movie = os.path.relpath(p.resolve(), out.resolve().parent)
        add_shot_section(page, d, pictures, anchor="shot", movie=movie,
                         movie_caption=f"playblast, {REPORT_PLAYBLAST_COLOR} colours" if render else "playblast")
        write_report(page, out, media)
        media = None
    finally:
        if media is not None:
            media.discard()
    seconds = time.perf_counter() - started
    return Result.from_summary(
        {"output": str(out), "outdir": str(outdir), "movie": movie, "bytes": out.stat().st_size,
         "seconds": round(seconds, 3),
         "_text": [f"wrote {out} ({out.stat().st_size / 1e6:.1f} MB{', movie ' + movie if movie else ''}) "
                   f"in {seconds:.1f} s"]},
        files={"output": str(out)} | ({"media": str(out.parent / f"{out.stem}_media")} if render else {}))


# -- the batch report ---------------------------------------------------------------------------------

def batch_report(summary, output=None, *, options: ReportOptions | None = None) -> Result:
    """Write the report of a batch: a table of every shot with thumbnails and links, then each
    finished shot's section.

    Parameters
    ----------
    summary : dict or path
        The batch summary (what ``usdface batch`` writes), or its JSON file.
    output : path, optional
        The ``.html`` to write; default: the summary's ``summaryFile`` with ``.html``.
    options : ReportOptions, optional
        Without: no movies (what ``usdface batch --report`` writes). With: each shot's playblast
        (``playblast_size``, ``workers``) in ``<report>_media/``, unless ``no_playblast``.
    """
    from ..report.html import Page, plotly_js
    from .batch.runner import scheduling_text

    started = time.perf_counter()
    summary = _batch_summary(summary)
    out = check_report_output(_batch_output(summary, output))
    movies = options is not None and not options.no_playblast
    if options is not None and options.playblast is not None:
        raise OptionError(f"--playblast {options.playblast}: a batch report renders each shot's movie itself "
                          "(or none: --no-playblast)")
    plotly_js()
    counts = summary.get("counts", {})
    page = Page("usdface batch report", f"{summary.get('manifest', '')}: " + ", ".join(
        f"{v} {k}" for k, v in counts.items() if v) + f" in {summary.get('seconds', 0):.1f} s "
        f"({scheduling_text(summary.get('mode'), summary.get('workers'))})")
    media = None
    try:
        rows, sections = _batch_table(page, summary, out)
        if movies:
            media = MediaFolder(out)
        _batch_sections(page, sections, media, options)
        write_report(page, out, media)
        media = None
    finally:
        if media is not None:
            media.discard()
    seconds = time.perf_counter() - started
    return Result.from_summary(
        {"output": str(out), "shots": len(rows), "sections": len(sections), "seconds": round(seconds, 3),
         "_text": [f"wrote {out}: {len(rows)} shot(s), {len(sections)} with plots "
                   f"({out.stat().st_size / 1e6:.1f} MB) in {seconds:.1f} s"]},
        files={"output": str(out)} | ({"media": str(out.parent / f"{out.stem}_media")} if movies else {}))


def _batch_summary(summary) -> dict:
    if isinstance(summary, dict):
        return summary
    from ..inputfiles import read_json

    path = Path(summary)
    data = read_json(path, label=f"batch summary {path}")  # a regular file, bounded size and nesting, UTF-8
    if not isinstance(data, dict):
        raise InputError(f"batch summary {path}: expected the JSON object `usdface batch` writes")
    return data


def _batch_output(summary: dict, output):
    if output is not None:
        return output
    sf = summary.get("summaryFile")
    if not sf:
        raise OptionError("batch report: no output file and the summary names no summaryFile")
    return Path(sf).with_suffix(".html")


def _batch_table(page, summary: dict, out: Path) -> tuple[list, list]:
    """The table of every shot (thumbnail, links, status, times, cache, frames, error), then the
    cache note. Returns (rows, [(ShotData, reader, anchor)] of the shots with a section)."""
    rows, sections = [], []
    for k, shot in enumerate(summary.get("shots", [])):
        anchor = f"shot-{k}"
        d, reader, thumb = _batch_shot(page, shot, anchor)
        if reader is not None:
            sections.append((d, reader, anchor))
        rows.append(_batch_row(shot, d, thumb, anchor, out))
    page.heading("Shots", 2)
    page.table(("", "shot", "status", "seconds", "step seconds", "cache", "frames", "error"), rows,
               raw_columns=(0, 1, 2, 4, 5, 6, 7), numeric=(3,))
    cache = summary.get("cache") or {}
    if cache.get("steps"):
        page.note("cache: " + "; ".join(f"{k}: {v.get('hit', 0)} hit(s), {v.get('miss', 0)} computed"
                                        for k, v in cache["steps"].items()))
    return rows, sections


def _batch_shot(page, shot: dict, anchor: str) -> tuple:
    """A finished shot read, with its thumbnail linking to its section: (ShotData, reader, cell
    HTML). A shot that failed: (None, None, ""); one that cannot be read or drawn: the reader is
    None and the cell shows the error (the ShotData, when it was read)."""
    from ..report.html import esc
    from ..report.pictures import thumbnail

    if shot.get("status") not in ("ok", "skipped") or not shot.get("output"):
        return None, None, ""
    d = None
    try:
        d, reader = read_shot(shot["output"])
        d.name = shot.get("name") or d.name  # the batch's name tells meshes apart
        png = thumbnail(d, reader)
    except (UsdFaceError, OSError) as exc:  # the table still lists the shot
        return d, None, f'<span class="err">{esc(exc)}</span>'
    thumb = f'<a href="#{anchor}">' + page.picture(png, "", alt=f"{shot['name']} thumbnail", width=120) + "</a>"
    return d, reader, thumb


def _batch_row(shot: dict, d, thumb: str, anchor: str, out: Path) -> tuple:
    """One row of the batch table; a resumed shot shows the times of the run that made it."""
    from ..report.html import esc

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
    return (thumb, name + "<br>" + links, f'<span class="{cls}">{esc(status)}</span>',
            f"{seconds:.1f}{earlier}", esc(steps), esc(cache), esc(frames),
            f'<span class="err">{esc(shot.get("error") or "")}</span>')


def _batch_sections(page, sections: list, media: MediaFolder | None, options: ReportOptions | None) -> None:
    """Each finished shot's section, with its playblast when there is a media folder."""
    from ..report.build import add_shot_section
    from ..report.pictures import shot_pictures

    for d, reader, anchor in sections:
        movie = None
        if d.mixed_layers and media is None:  # (the playblast says it when it renders)
            _warn_mixed(d)
        if media is not None:
            movie = _render_playblast(d.shot, media, d.name, size=options.playblast_size, color=BATCH_PLAYBLAST_COLOR,
                                      workers=options.workers)
        add_shot_section(page, d, shot_pictures(d, reader), anchor=anchor, movie=movie,
                         movie_caption="playblast" if movie else "")
