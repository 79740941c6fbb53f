"""A playblast planned: the frames each shot shows, the camera framing and colour range fitted on a
first pass, the panels, and the frame jobs the compositor renders.

No USD here: the shots come opened (:func:`usdface.usd.playback.open_playblast_shots` gives
:class:`PlayblastShots`; any object with the reader's methods will do). Two calls give a movie's
frames as pictures without encoding them::

    shots = open_playblast_shots("out/jaw/shot.usda", params)      # usdface.usd.playback
    stills = plan_playblast(shots, params).stills([120, 389])      # BGR images, as the movie draws them
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import OptionError
from .panel import PanelStyle, ShotPanel, framing_sample
from .pipeline import Compositor, FrameJob
from .timing import Alignment, VideoTiming, align_shots, summary_beside, video_frame_indices, video_timing

__all__ = ["CHUNK", "IN_MEMORY_LIMIT", "PlayblastParameters", "PlayblastPlan", "PlayblastShots", "plan_playblast"]

#: frames read from USD per chunk
CHUNK = 64
#: points kept in memory between the framing pass and the render pass (bytes, float32)
IN_MEMORY_LIMIT = 400 << 20


@dataclass(frozen=True)
class PlayblastParameters:
    """What a playblast shows and how (``PlayblastOptions.parameters()`` builds it).

    Attributes
    ----------
    style : PanelStyle
        Colours, markers, bound points, labels, legend, burn-in, supersampling, view, projection.
    size : (int, int)
        The movie frame; with ``compare`` or ``video`` each of the two panels gets half the width.
    frame_range : (first, last) or None
        Time codes to play, inclusive (default: the whole shot).
    stabilized : bool
        Draw the face without the head motion on its root prim (displacement and error colours
        always measure the stabilised face).
    compare, reference, video : path or None
        A second shot on the right; a shot with reference points (``error`` colours); the shot's
        source video on the right.
    """

    style: PanelStyle = PanelStyle()
    size: tuple = (960, 540)
    frame_range: tuple | None = None
    stabilized: bool = False
    compare: str | None = None
    reference: str | None = None
    video: str | None = None


@dataclass(frozen=True)
class PlayblastShots:
    """The shots of a playblast, opened: the shot and the time codes it plays, the reference
    shot (``error`` colours) and the second shot shown beside it, when given."""

    shot: object
    times: np.ndarray
    reference: object = None
    compare: object = None


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
            pts = r.face_points(t)
            stab = r.stabilize(pts, t) if self.need_stable else None
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


@dataclass
class _VideoPanel:
    """The source video beside the shot: the opened video and, per playblast frame, its frame
    index, whether the video has it, and the timing the mapping came from."""

    video: object
    index: np.ndarray
    present: np.ndarray
    timing: VideoTiming


@dataclass
class PlayblastPlan:
    """Everything a playblast renders, fitted on a first pass over the shot(s) (:func:`plan_playblast`).

    Attributes
    ----------
    reader : the shot's reader; ``times`` (F,) its time codes played
    notes : list of str, what the user should know (held frames, a missing summary.json...)
    alignment : Alignment or None, the second shot's time codes per frame
    compositor : Compositor, renders a :class:`FrameJob` into a movie frame
    video : the source video beside the shot, or None
    """

    reader: object
    times: np.ndarray
    compositor: Compositor
    frames: _Frames
    notes: list = field(default_factory=list)
    alignment: Alignment | None = None
    other_frames: _Frames | None = None
    reference_frames: _Frames | None = None
    video: _VideoPanel | None = None

    @property
    def video_map(self):
        """(index, present, timing) of the source video frames, or None."""
        return None if self.video is None else (self.video.index, self.video.present, self.video.timing)

    def jobs(self):
        """The frame jobs, in order (reading the shots chunk by chunk, decoding the video forward)."""
        times, alignment = self.times, self.alignment
        b_iter = self.other_frames.at(alignment.times) if self.other_frames is not None else None
        r_iter = self.reference_frames.chunks() if self.reference_frames is not None else None
        v = self.video
        v_iter = _video_frames(v.video, v.index, v.present) if v is not None else None
        b = r = None
        for item in self.frames.chunks():
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
                    job.video_index = int(v.index[n])
                yield job

    def stills(self, times) -> list:
        """The movie frames at the time codes ``times`` exactly as the movie draws them (same
        framing, colour range, burn-in), as BGR images, without encoding."""
        want = {int(t) for t in times}
        missing = want - {int(t) for t in self.times}
        if missing:
            raise OptionError(f"stills: time code(s) {sorted(missing)} are not in the playblast's range "
                              f"{int(self.times[0])}..{int(self.times[-1])}")
        return [self.compositor(job) for job in self.jobs() if int(self.times[job.index]) in want]


def plan_playblast(shots: PlayblastShots, params: PlayblastParameters) -> PlayblastPlan:
    """Fit the framing and colour range on a first pass over the shot(s) and prepare the frames.

    Parameters
    ----------
    shots : PlayblastShots
        The opened shots (:func:`usdface.usd.playback.open_playblast_shots`).
    params : PlayblastParameters
    """
    style = params.style
    reader, times = shots.shot, shots.times
    scalar_colors = style.color in ("displacement", "error")
    frames = _Frames(reader, times, markers=style.markers or style.labels, bound=style.bound,
                     stabilized=params.stabilized, need_stable=scalar_colors)
    ref_frames = None
    if shots.reference is not None:
        ref_frames = _Frames(shots.reference, times, markers=False, bound=False, stabilized=True)
    sample, top_disp, top_err = _survey(frames, reference_frames=ref_frames)
    top = top_err if style.color == "error" else top_disp
    plan = PlayblastPlan(reader=reader, times=times, compositor=None, frames=frames, reference_frames=ref_frames)
    samples = [sample]
    if shots.compare is not None:
        top = _add_compare(plan, shots.compare, params, samples, top)
    scalar_range = (0.0, top if top > 0 else 1.0)
    plan.compositor = _compositor(plan, shots, params, samples, scalar_range)
    return plan


def _add_compare(plan: PlayblastPlan, other, params: PlayblastParameters, samples: list, top: float) -> float:
    """The second shot aligned in seconds and surveyed: one colour scale for both sides, one
    framing when they show the same face (``samples`` gets its framing sample). Returns the
    colour range's top."""
    style, reader, times = params.style, plan.reader, plan.times
    plan.alignment = alignment = align_shots(times, reader.rate, other.start, other.end, other.rate)
    plan.other_frames = _Frames(other, alignment.times, markers=style.markers or style.labels, bound=style.bound,
                                stabilized=params.stabilized, need_stable=style.color in ("displacement", "error"))
    o_sample, o_disp, _ = _survey(plan.other_frames)
    if style.color != "error":
        top = max(top, o_disp)  # one colour scale for both sides
    same_mesh = other.rest_points.shape == reader.rest_points.shape and np.allclose(
        other.rest_points, reader.rest_points, atol=1e-6 * (1 + np.abs(reader.rest_points).max()))
    if same_mesh:  # one framing for both sides when they show the same face
        samples[0] = o_sample = np.concatenate([samples[0].reshape(-1, 3), o_sample.reshape(-1, 3)])
    samples.append(o_sample)
    if other.n_frames != len(times) or alignment.n_held:
        plan.notes.append(f"--compare {other.name}: {other.n_frames} frames at {other.rate:g} fps against "
                          f"{len(times)}; aligned in seconds from time code 0, {alignment.n_held} frame(s) held at "
                          "its nearest end (burn-in 'held'); the movie keeps the first shot's length")
    return top


def _compositor(plan: PlayblastPlan, shots: PlayblastShots, params: PlayblastParameters, samples: list,
                scalar_range: tuple) -> Compositor:
    """The panels (one per shot, the left one half the width when something is on the right) and
    the source video, composed left to right."""
    w, h = params.size
    two = shots.compare is not None or params.video is not None
    widths = [w // 2, w - w // 2] if two else [w]
    units = plan.reader.units or "units"

    def panel(r, width, frame_points, first):
        summary = summary_beside(r.path) or {}
        return ShotPanel(name=r.name, method=r.method or str(summary.get("method", "")), rate=r.rate,
                         triangles=r.triangles, rest_points=r.rest_points, size=(width, h), style=params.style,
                         frame_points=frame_points, regions=r.regions, hybrid_weight=r.hybrid_weight,
                         marker_names=r.marker_names, scalar_range=scalar_range, units=units, first_time=first)

    panels = [panel(plan.reader, widths[0], samples[0], int(plan.times[0]))]
    if shots.compare is not None:
        panels.append(panel(shots.compare, widths[1], samples[1], int(plan.alignment.times[0])))
    if params.video is not None:
        plan.video = _open_video(plan, params.video)
    vid = plan.video.video if plan.video is not None else None
    return Compositor(panels=panels, video_size=(widths[1], h) if params.video is not None else None,
                      video_name=Path(params.video).name if params.video is not None else "",
                      video_rate=vid.rate if vid is not None else 0.0, burnin=params.style.burnin)


def _open_video(plan: PlayblastPlan, path) -> _VideoPanel:
    """The source video and the frame each playblast frame shows (frame k + trim, resampling
    included, from what the run recorded)."""
    from ..io.video import open_video

    reader, times = plan.reader, plan.times
    vid = open_video(path)
    timing = video_timing(reader.path, shot_start=reader.start, rate=reader.rate)
    index, present = video_frame_indices(times, timing, video_rate=vid.rate, video_frames=vid.n_frames)
    if not timing.recorded:
        plan.notes.append(f"--video: {reader.path.parent / 'summary.json'} not found: playblast frame k shows video "
                          "frame k (no trim or resampling known)")
    missing = int((~present).sum())
    if missing:
        plan.notes.append(f"--video: {missing} playblast frame(s) past the video's {vid.n_frames} frames show "
                          "'no video frame'")
    return _VideoPanel(video=vid, index=index, present=present, timing=timing)


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
