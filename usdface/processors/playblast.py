"""`usdface playblast`: a shot (or two, or a shot and its source video) to an H.264 movie.

One movie frame per time sample of the shot, at the shot's rate; the face is rendered by the
software renderer of ``usdface preview`` (same views, colour modes, markers, bound points), with a
burn-in of the shot's name, transfer method, frame and timecode. The shots are opened by
:func:`usdface.usd.playback.open_playblast_shots`, the frames planned by
:func:`usdface.playblast.plan_playblast`, rendered in parallel and encoded with PyAV (the ``media``
extra); the movie is written atomically.
"""
from __future__ import annotations

import logging
import time as _time
from pathlib import Path

from ..errors import OptionError
from ..fileutil import probe_writable_folder
from ..options import PlayblastOptions
from ..registry import Result

__all__ = ["playblast"]

log = logging.getLogger("usdface")


def _check_output(shot, output: Path, o: PlayblastOptions) -> None:
    if output.suffix.lower() != ".mp4":
        raise OptionError(f"-o {output}: a playblast is an .mp4 movie (H.264)")
    for label, p in (("shot", shot), ("--compare", o.compare), ("--video", o.video), ("--reference", o.reference)):
        if p is not None and Path(p).resolve() == output.resolve():
            raise OptionError(f"-o {output}: is the {label} input; the movie would overwrite it")


def playblast(shot, *, options: PlayblastOptions, output) -> Result:
    """Render ``shot`` frame by frame into the H.264 movie ``output``.

    Parameters
    ----------
    shot : path
        A shot stage (``OUTDIR/shot.usda``) or any layer with a face mesh.
    options : PlayblastOptions
        How to render: ``frame_range`` (time codes, inclusive), ``size`` (with ``compare`` or
        ``video`` each of the two panels gets half the width), ``view``, ``color``, ``markers``...
        ``stabilized`` draws the face without the head motion on its root prim (displacement and
        error colours always measure the stabilised face). ``compare``: a second shot on the
        right, aligned in seconds; where it has no frame it holds its nearest end frame (burn-in
        "held"). ``video``: the shot's source video on the right, playblast frame k showing video
        frame k + trim (through the trim, start frame and resampling the run recorded).
        ``workers`` render workers (default: the usable cores), ``parallel`` threads or
        processes; ``crf``, ``preset``: x264 quality and speed.
    output : path
        The ``.mp4`` to write (atomically).

    Returns
    -------
    Result
        ``files["output"]``, the summary (frames, range, rate, size, held frames, the movie's
        probed streams, notes) and the line printed.
    """
    from ..media.movie import MovieWriter, movie_info, require_encoder
    from ..playblast.pipeline import default_workers, render_in_order
    from ..playblast.plan import plan_playblast
    from ..progress import progress
    from ..usd.playback import open_playblast_shots

    started = _time.perf_counter()
    o = options
    output = Path(output)
    _check_output(shot, output, o)
    w, h = o.size
    require_encoder()  # a missing encoder fails before any work
    probe_writable_folder(output, what="movie")  # fails now, before the shot is read
    workers = default_workers() if o.workers is None else o.workers
    if o.color == "error" and o.reference is None:
        raise OptionError("--color error needs --reference SHOT (the points to compare against)")
    params = o.parameters()
    plan = plan_playblast(open_playblast_shots(shot, params), params)
    mixed = _mixed_layers(shot, o)
    reader, times = plan.reader, plan.times
    meta = {"title": reader.name, "comment": f"usdface playblast of {reader.path.name}"}
    bar = progress(total=len(times), desc="playblast", unit="frame")
    with MovieWriter(output, (w, h), reader.rate, crf=o.crf, preset=o.preset, metadata=meta) as writer:
        try:
            for img in render_in_order(plan.jobs(), plan.compositor, workers=workers, mode=o.parallel):
                writer.write(img)
                bar.update(1)
        finally:
            bar.close()
    seconds = _time.perf_counter() - started
    summary = _summary(shot, output, o, plan, workers=workers, seconds=seconds, info=movie_info(output))
    if mixed:
        summary["mixedLayers"] = mixed
    return Result.from_summary(summary, files={"output": str(output)})


def _mixed_layers(shot, o: PlayblastOptions) -> dict:
    """{shot: errors} of the shots played (and the reference) whose layers disagree, each warned on
    one line. A playblast renders what a shot composes, mixed or not: it is how one looks at a
    shot, and `usdface check` (exit 1) is the gate that refuses it."""
    from ..usd.identity import mixed_layers, mixed_layers_warning

    found = {}
    for path in (shot, o.compare, o.reference):
        if path is not None and str(path) not in found:
            errors = mixed_layers(path)
            if errors:
                log.warning("%s", mixed_layers_warning(path, errors))
                found[str(path)] = errors
    return found


def _summary(shot, output: Path, o: PlayblastOptions, plan, *, workers: int, seconds: float, info: dict) -> dict:
    """What ``--json`` prints, with the printed lines in ``_text``."""
    reader, times, (w, h) = plan.reader, plan.times, o.size
    summary = {
        "output": str(output), "shot": str(shot), "frames": len(times), "first": int(times[0]),
        "last": int(times[-1]), "rate": reader.rate, "size": [w, h], "view": o.view, "color": o.color,
        "compare": o.compare, "video": o.video,
        "held": 0 if plan.alignment is None else plan.alignment.n_held, "workers": workers, "parallel": o.parallel,
        "seconds": round(seconds, 3), "framesPerSecond": round(len(times) / seconds, 2), "movie": info,
        "notes": plan.notes,
    }
    if plan.video is not None:
        v = plan.video
        summary["videoFrames"] = {"first": int(v.index[0]), "last": int(v.index[-1]),
                                  "trimStart": v.timing.trim_start, "recorded": v.timing.recorded}
    summary["_text"] = [f"wrote {output}: {len(times)} frames ({int(times[0])}..{int(times[-1])}) at "
                        f"{reader.rate:g} fps, {w}x{h} H.264, {info['frames']} frames in the file; "
                        f"{seconds:.1f} s ({len(times) / seconds:.1f} frames/s, {workers} worker(s))"] + \
        [f"  {n}" for n in plan.notes]
    return summary
