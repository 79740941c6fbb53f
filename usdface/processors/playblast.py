"""`usdface playblast`: a shot (or two, or a shot and its source video) to an H.264 movie.

One movie frame per time sample of the shot, at the shot's rate; the face is rendered by the
software renderer of ``usdface preview`` (same views, colour modes, markers, bound points), with a
burn-in of the shot's name, transfer method, frame and timecode. Frames are rendered in parallel
and encoded with PyAV (the ``media`` extra); the movie is written atomically.
"""
from __future__ import annotations

import argparse
import json
import time as _time
from pathlib import Path

import numpy as np

from ..errors import InputError, OptionError
from ..fileutil import probe_writable_folder
from ..options import PlayblastOptions

__all__ = ["playblast", "playblast_stills", "register_cli", "video_timing"]

#: frames read from USD per chunk
CHUNK = 64
#: points kept in memory between the framing pass and the render pass (bytes, float32)
IN_MEMORY_LIMIT = 400 << 20


def _playblast_options(options) -> PlayblastOptions:
    if options is None:
        return PlayblastOptions()
    if isinstance(options, PlayblastOptions):
        return options
    if isinstance(options, dict):
        return PlayblastOptions.from_mapping(options, what="playblast options")
    raise OptionError(f"playblast options: expected a PlayblastOptions (usdface.options); got {type(options).__name__}")


def _summary_beside(shot_path: Path) -> dict | None:
    p = Path(shot_path).parent / "summary.json"
    if not p.is_file():
        return None
    try:
        return json.loads(p.read_text())
    except (OSError, ValueError):
        return None


def video_timing(shot_path, *, shot_start: int, rate: float):
    """How the shot's frames map to its source video, from the run's summary.json beside the shot.

    The run records ``steps.import-capture.reports.timing`` (trim start, source rate, resampled
    rate, first time code); older shots fall back to the options in its provenance and the
    tracker's rate. Without a summary the identity mapping is assumed (``recorded=False``).
    """
    from ..playblast.timing import VideoTiming

    summary = _summary_beside(Path(shot_path))
    if summary is None:
        return VideoTiming(trim_start=0, source_rate=None, rate=rate, shot_start=shot_start, recorded=False)
    cap = summary.get("steps", {}).get("import-capture", {})
    rec = cap.get("reports", {}).get("timing")
    if rec:
        return VideoTiming(trim_start=int(rec.get("trimStart") or 0), source_rate=rec.get("sourceRate"),
                           rate=rec.get("rate") or rate, shot_start=int(rec.get("startTimeCode", shot_start)))
    options = summary.get("provenance", {}).get("options", {})
    if isinstance(options, str):
        try:
            options = json.loads(options)
        except ValueError:
            options = {}
    trim = options.get("trim") or [0, None]
    source_rate = summary.get("steps", {}).get("track", {}).get("rate")
    if source_rate is None and not options.get("resample"):
        source_rate = cap.get("rate", rate)
    return VideoTiming(trim_start=int(trim[0] or 0), source_rate=source_rate, rate=cap.get("rate", rate),
                       shot_start=int(cap.get("startTimeCode", shot_start)), recorded=source_rate is not None)


class _Frames:
    """A shot's points over the playblast's time codes, read in chunks (kept in memory when small).

    Items are ``(start index, points, markers, bound, stabilised)``: points (f, N, 3) as drawn,
    markers and bound points (f, M, 3) or None, and the points without the head motion (f, N, 3;
    None when they are the drawn points): displacement colours measure what the transfer did,
    not the head's motion.
    """

    def __init__(self, reader, times, *, markers: bool, bound: bool, stabilized: bool = False,
                 need_stable: bool = True):
        self.reader, self.times = reader, np.asarray(times)
        self.want_markers, self.want_bound, self.stabilized = markers, bound, stabilized
        self.need_stable = need_stable  # only displacement / error colours and their range need them
        n = reader.rest_points.shape[0]
        self._keep = len(self.times) * n * 24 <= IN_MEMORY_LIMIT
        self._cache = None

    def _read(self, t):
        r = self.reader
        if self.stabilized:
            pts, stab = r.face_points(t, stabilized=True), None
            mk = r.markers(t, stabilized=True) if self.want_markers else None
        else:
            pts, stab = r.face_points(t), None
            if self.need_stable:
                head = r.head_motion(t)
                if not np.allclose(head, np.eye(4)[None]):
                    from ..usd.playback import remove_head_motion

                    stab = remove_head_motion(pts, head)
            mk = r.markers(t) if self.want_markers else None
        bd = r.bound_points(pts) if self.want_bound else None
        return pts, mk, bd, stab

    def chunks(self):
        if self._cache is not None:
            yield from self._cache
            return
        keep = [] if self._keep else None
        for i in range(0, len(self.times), CHUNK):
            pts, mk, bd, stab = self._read(self.times[i:i + CHUNK])
            if keep is not None:
                pts = pts.astype(np.float32)
                stab = None if stab is None else stab.astype(np.float32)
            item = (i, pts, mk, bd, stab)
            if keep is not None:
                keep.append(item)
            yield item
        if keep is not None:
            self._cache = keep

    def at(self, index_times):
        """Items for arbitrary time codes of this shot (the aligned second shot), chunk by chunk."""
        for i in range(0, len(index_times), CHUNK):
            yield (i,) + self._read(index_times[i:i + CHUNK])


def _stable(item):
    """The head-stabilised points of a chunk item."""
    return item[4] if item[4] is not None else item[1]


def _survey(frames: _Frames, *, reference_frames=None):
    """One pass over a shot: the frames to frame the camera on and the largest displacement / error."""
    from ..playblast.panel import framing_sample

    rest = frames.reader.rest_points
    sample, top_disp, top_err = [], 0.0, 0.0
    n = len(frames.times)
    stride = max(1, n // 24)
    ref_iter = reference_frames.chunks() if reference_frames is not None else None
    spread_best = []
    for item in frames.chunks():
        i, pts, mk = item[:3]
        d = np.linalg.norm(_stable(item) - rest, axis=2)
        top_disp = max(top_disp, float(np.nanmax(d)) if d.size else 0.0)
        for k in range(pts.shape[0]):
            if (i + k) % stride == 0:
                sample.append(pts[k] if mk is None else np.concatenate([pts[k], mk[k]]))
        spread = d.max(axis=1)
        k = int(np.argmax(spread))
        spread_best.append((float(spread[k]), pts[k] if mk is None else np.concatenate([pts[k], mk[k]])))
        if ref_iter is not None:
            ref = _stable(next(ref_iter))
            top_err = max(top_err, float(np.nanmax(np.linalg.norm(_stable(item) - ref, axis=2))))
    spread_best.sort(key=lambda s: s[0])
    extra = [p for _, p in spread_best[-2:]]
    pts_sample = framing_sample(np.stack(sample + extra)) if sample else rest[None]
    return pts_sample, top_disp, top_err


def playblast(shot, output, options: PlayblastOptions | dict | None = None) -> dict:
    """Render ``shot`` frame by frame into the H.264 movie ``output``.

    Parameters
    ----------
    shot : path
        A shot stage (``OUTDIR/shot.usda``) or any layer with a face mesh.
    output : path
        The ``.mp4`` to write (atomically).
    options : PlayblastOptions or dict, optional
        How to render (:class:`usdface.options.PlayblastOptions`, the fields of the command's
        flags): ``frame_range`` (time codes, inclusive), ``size`` (with ``compare`` or ``video``
        each of the two panels gets half the width), ``view``, ``color``, ``markers``... ``stabilized``
        draws the face without the head motion on its root prim (displacement and error colours
        always measure the stabilised face). ``compare``: a second shot on the right, aligned in
        seconds; where it has no frame it holds its nearest end frame (burn-in "held"). ``video``:
        the shot's source video on the right, playblast frame k showing video frame k + trim
        (through the trim, start frame and resampling the run recorded). ``workers`` render
        workers (default: the usable cores), ``parallel`` threads or processes; ``crf``, ``preset``:
        x264 quality and speed.

    Returns
    -------
    dict
        The summary (``_text`` lines for the terminal).
    """
    from ..media.movie import MovieWriter, movie_info, require_encoder
    from ..playblast.pipeline import default_workers, render_in_order
    from ..progress import progress

    started = _time.perf_counter()
    o = _playblast_options(options)
    output = Path(output)
    if output.suffix.lower() != ".mp4":
        raise OptionError(f"-o {output}: a playblast is an .mp4 movie (H.264)")
    for label, p in (("shot", shot), ("--compare", o.compare), ("--video", o.video), ("--reference", o.reference)):
        if p is not None and Path(p).resolve() == output.resolve():
            raise OptionError(f"-o {output}: is the {label} input; the movie would overwrite it")
    w, h = o.size
    require_encoder()  # a missing encoder fails before any work
    probe_writable_folder(output, what="movie")  # fails now, before the shot is read
    workers = default_workers() if o.workers is None else o.workers
    plan = _plan(shot, o)
    reader, times, notes, alignment, vmap = plan.reader, plan.times, plan.notes, plan.alignment, plan.vmap
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
    info = movie_info(output)
    summary = {
        "output": str(output), "shot": str(shot), "frames": len(times), "first": int(times[0]),
        "last": int(times[-1]), "rate": reader.rate, "size": [w, h], "view": o.view, "color": o.color,
        "compare": o.compare, "video": o.video,
        "held": 0 if alignment is None else alignment.n_held, "workers": workers, "parallel": o.parallel,
        "seconds": round(seconds, 3), "framesPerSecond": round(len(times) / seconds, 2), "movie": info,
        "notes": notes,
    }
    if vmap is not None:
        summary["videoFrames"] = {"first": int(vmap[0][0]), "last": int(vmap[0][-1]),
                                  "trimStart": vmap[2].trim_start, "recorded": vmap[2].recorded}
    summary["_text"] = [f"wrote {output}: {len(times)} frames ({int(times[0])}..{int(times[-1])}) at "
                        f"{reader.rate:g} fps, {w}x{h} H.264, {info['frames']} frames in the file; "
                        f"{seconds:.1f} s ({len(times) / seconds:.1f} frames/s, {workers} worker(s))"] + \
        [f"  {n}" for n in notes]
    return summary



def playblast_stills(shot, times, options: PlayblastOptions | dict | None = None) -> list:
    """The movie frames at the time codes ``times`` exactly as :func:`playblast` with the same
    ``options`` draws them (same framing, colour range, burn-in), as BGR images, without encoding."""
    plan = _plan(shot, _playblast_options(options))
    want = {int(t) for t in times}
    missing = want - {int(t) for t in plan.times}
    if missing:
        raise OptionError(f"stills: time code(s) {sorted(missing)} are not in the playblast's range "
                          f"{int(plan.times[0])}..{int(plan.times[-1])}")
    return [plan.compositor(job) for job in plan.jobs() if int(plan.times[job.index]) in want]


def _plan(shot, o: PlayblastOptions):
    """Read the shot(s), fit the framing and colour range, and prepare the frame jobs."""
    from types import SimpleNamespace

    from ..playblast.panel import PanelStyle, ShotPanel
    from ..playblast.pipeline import Compositor, FrameJob
    from ..playblast.timing import align_shots, shot_times, video_frame_indices
    from ..usd.playback import ShotReader

    frame_range, (w, h), color, reference = o.frame_range, o.size, o.color, o.reference
    compare, video, stabilized = o.compare, o.video, o.stabilized
    markers, bound, labels = o.markers, o.bound, o.labels
    style = PanelStyle(color=color, markers=o.markers, bound=o.bound, labels=o.labels, legend=o.legend,
                       burnin=o.burnin, supersample=o.supersample, view=o.view, projection=o.projection,
                       turntable_period=o.turntable_period)
    if color == "error" and reference is None:
        raise OptionError("--color error needs --reference SHOT (the points to compare against)")
    reader = ShotReader.open(shot)
    if not reader.animated:
        raise InputError(f"shot {shot}: the face has no animation (no time-sampled points, no skinning); "
                         "use `usdface preview` for a still")
    times = shot_times(reader.start, reader.end, frame_range, what=f"shot {shot}")
    panels_n = 1 + (compare is not None or video is not None)
    pw = [w // 2, w - w // 2] if panels_n == 2 else [w]
    scalar_colors = color in ("displacement", "error")
    frames = _Frames(reader, times, markers=markers or labels, bound=bound, stabilized=stabilized,
                     need_stable=scalar_colors)
    ref_frames = None
    if reference is not None:
        ref_reader = ShotReader.open(reference)
        if ref_reader.rest_points.shape != reader.rest_points.shape:
            raise InputError(f"--reference {reference}: {ref_reader.rest_points.shape[0]} points; the shot has "
                             f"{reader.rest_points.shape[0]}")
        shot_times(ref_reader.start, ref_reader.end, (times[0], times[-1]), what=f"reference {reference}")
        ref_frames = _Frames(ref_reader, times, markers=False, bound=False, stabilized=True)
    sample, top_disp, top_err = _survey(frames, reference_frames=ref_frames)
    top = top_err if color == "error" else top_disp
    units = reader.units or "units"
    notes = []
    other = other_frames = alignment = None
    if compare is not None:
        other = ShotReader.open(compare)
        if not other.animated:
            raise InputError(f"--compare {compare}: the face has no animation")
        alignment = align_shots(times, reader.rate, other.start, other.end, other.rate)
        other_frames = _Frames(other, alignment.times, markers=markers or labels, bound=bound, stabilized=stabilized,
                               need_stable=scalar_colors)
        o_sample, o_disp, _ = _survey(other_frames)
        if color != "error":
            top = max(top, o_disp)  # one colour scale for both sides
        same_mesh = other.rest_points.shape == reader.rest_points.shape and np.allclose(
            other.rest_points, reader.rest_points, atol=1e-6 * (1 + np.abs(reader.rest_points).max()))
        if same_mesh:  # one framing for both sides when they show the same face
            sample = o_sample = np.concatenate([sample.reshape(-1, 3), o_sample.reshape(-1, 3)])
        if other.n_frames != len(times) or alignment.n_held:
            notes.append(f"--compare {other.name}: {other.n_frames} frames at {other.rate:g} fps against "
                         f"{len(times)}; aligned in seconds from time code 0, {alignment.n_held} frame(s) held at "
                         "its nearest end (burn-in 'held'); the movie keeps the first shot's length")
    scalar_range = (0.0, top if top > 0 else 1.0)

    def panel(r, width, frame_points, first):
        summary = _summary_beside(r.path) or {}
        return ShotPanel(name=r.name, method=r.method or str(summary.get("method", "")), rate=r.rate,
                         triangles=r.triangles, rest_points=r.rest_points, size=(width, h), style=style,
                         frame_points=frame_points, regions=r.regions, hybrid_weight=r.hybrid_weight,
                         marker_names=r.marker_names, scalar_range=scalar_range, units=units, first_time=first)

    panels = [panel(reader, pw[0], sample, int(times[0]))]
    if other is not None:
        panels.append(panel(other, pw[1], o_sample, int(alignment.times[0])))
    vid = vmap = None
    if video is not None:
        from ..io.video import open_video

        vid = open_video(video)
        timing = video_timing(reader.path, shot_start=reader.start, rate=reader.rate)
        index, present = video_frame_indices(times, timing, video_rate=vid.rate, video_frames=vid.n_frames)
        vmap = (index, present, timing)
        if not timing.recorded:
            notes.append(f"--video: {reader.path.parent / 'summary.json'} not found: playblast frame k shows video "
                         "frame k (no trim or resampling known)")
        missing = int((~present).sum())
        if missing:
            notes.append(f"--video: {missing} playblast frame(s) past the video's {vid.n_frames} frames show "
                         "'no video frame'")
    compositor = Compositor(panels=panels, video_size=(pw[1], h) if video is not None else None,
                            video_name=Path(video).name if video is not None else "",
                            video_rate=vid.rate if vid is not None else 0.0, burnin=o.burnin)

    def jobs():
        b_iter = other_frames.at(alignment.times) if other is not None else None
        r_iter = ref_frames.chunks() if ref_frames is not None else None
        v_iter = _video_frames(vid, vmap[0], vmap[1]) if vid is not None else None
        b = r = None
        for item in frames.chunks():
            i, pts, mk, bd, _ = item
            stab = _stable(item)
            if b_iter is not None:
                b = next(b_iter)
            if r_iter is not None:
                r = _stable(next(r_iter))
            for k in range(pts.shape[0]):
                n = i + k
                job = FrameJob(index=n)
                job.panels.append(dict(time=float(times[n]), points=pts[k], markers=None if mk is None else mk[k],
                                       bound=None if bd is None else bd[k], stabilized=stab[k],
                                       reference=None if r is None else r[k]))
                if b is not None:
                    held = bool(alignment.held[n])
                    job.panels.append(dict(time=float(alignment.times[n]), points=b[1][k],
                                           markers=None if b[2] is None else b[2][k],
                                           bound=None if b[3] is None else b[3][k], stabilized=_stable(b)[k],
                                           note="held" if held else ""))
                if v_iter is not None:
                    job.video, job.video_note = next(v_iter)
                    job.video_index = int(vmap[0][n])
                yield job

    return SimpleNamespace(reader=reader, times=times, notes=notes, alignment=alignment, vmap=vmap,
                           compositor=compositor, jobs=jobs)


def _video_frames(vid, index, present):
    """(frame, note) for each playblast frame, decoding the video once, forward."""
    it = iter(vid)
    cur_i, cur = -1, None
    for idx, ok in zip(index.tolist(), present.tolist()):
        if not ok:
            yield None, f"no video frame {idx} (video has 0..{vid.n_frames - 1})"
            continue
        if idx < cur_i:  # going back (resampling down) never happens by more than a frame: reopen
            it, cur_i, cur = iter(vid), -1, None
        while cur_i < idx:
            nxt = next(it, None)
            if nxt is None:
                break
            cur_i, cur = nxt
        if cur_i != idx:
            yield None, f"video frame {idx} could not be decoded"
        else:
            yield cur, ""


def register_cli(subparsers) -> None:
    from ..cliargs import add_common_options, add_options

    p = subparsers.add_parser(
        "playblast", help="render a shot to an H.264 movie (browser-playable mp4), side by side or beside its video",
        description="Render every frame of a shot (or --range) with the software renderer of `usdface preview` into "
                    "an H.264 mp4 (yuv420p, faststart) at the shot's rate: one movie frame per time sample, with a "
                    "burn-in of shot, method, frame and timecode. --compare puts a second shot on the right "
                    "(e.g. euclidean vs hybrid); --video the shot's source clip (frame k + trim). Needs the "
                    "'media' extra (PyAV).",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("shot", help="shot stage (OUTDIR/shot.usda) or any layer with a face mesh")
    p.add_argument("-o", "--output", required=True, help="movie to write (.mp4)")
    add_options(p, PlayblastOptions)
    add_common_options(p)
    p.set_defaults(func=_cmd_playblast)


def _cmd_playblast(args) -> dict:
    from ..cliargs import options_from_args

    return playblast(args.shot, args.output, options_from_args(PlayblastOptions, args))
