"""Compose playblast frames from panels and render them in parallel, in order, into an encoder.

The main thread reads the shot (USD is read in one thread) and encodes; rendering runs in a pool of
worker threads (the rasteriser and shader are compiled numba kernels that release the GIL, and
OpenCV's drawing releases it too) or worker processes. A bounded window of frames in flight keeps
memory flat on long takes.
"""
from __future__ import annotations

import os
import signal
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from ..preview.burnin import burn_in, fit_into, hstack_panels, placeholder, timecode
from .panel import ShotPanel

__all__ = ["Compositor", "FrameJob", "default_workers", "render_in_order"]


@dataclass
class FrameJob:
    """What one playblast frame shows: per panel, a time code and its points (or a note saying
    why there is nothing), and optionally a source video frame."""

    index: int
    panels: list = field(default_factory=list)   # per shot panel: dict(time, points, markers, bound, reference, note)
    video: np.ndarray | None = None              # BGR frame of the source video
    video_note: str = ""
    video_index: int | None = None               # its frame number in the video


@dataclass
class Compositor:
    """Renders a :class:`FrameJob` into one movie frame: shot panels, then the video panel, left to right."""

    panels: list                 # ShotPanel per shot
    video_size: tuple | None = None  # (w, h) of the video panel, or None
    video_name: str = ""
    video_rate: float = 0.0
    burnin: bool = True

    def __call__(self, job: FrameJob) -> np.ndarray:
        images = []
        for panel, data in zip(self.panels, job.panels):
            panel: ShotPanel
            if data.get("points") is None:
                images.append(panel.missing(data.get("note") or "no frame"))
            else:
                images.append(panel.render(data["time"], data["points"], markers=data.get("markers"),
                                           bound=data.get("bound"), reference=data.get("reference"),
                                           stabilized=data.get("stabilized"), note=data.get("note", "")))
        if self.video_size is not None:
            if job.video is None:
                img = placeholder(self.video_size, job.video_note or "no video frame")
            else:
                img = fit_into(job.video, self.video_size)
            if self.burnin and job.video_index is not None:
                burn_in(img, [self.video_name, "source video"],
                        [f"video frame {job.video_index}", f"{timecode(job.video_index, self.video_rate)}  "
                                                           f"{self.video_rate:g} fps"])
            images.append(img)
        return images[0] if len(images) == 1 else hstack_panels(images)


def default_workers() -> int:
    """Render workers: the cores this process may use (2 on the reference machine)."""
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        n = os.cpu_count() or 1
    return max(1, n)


_WORKER_RENDER = None


def _init_process(render):
    global _WORKER_RENDER
    _WORKER_RENDER = render
    # a worker inherits the command's handlers (SIGTERM raises Interrupted, for clean-up in the
    # main process); the pool stops its workers with SIGTERM, which must end them quietly
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the main process's to handle
    from ..preview.render import _compiled

    _compiled()  # load the compiled kernels once per process


def _render_in_process(job):
    return _WORKER_RENDER(job)


def render_in_order(jobs, render, *, workers: int = 1, mode: str = "threads", window: int | None = None):
    """Yield ``render(job)`` for every job, in the jobs' order, computed by ``workers`` workers.

    Parameters
    ----------
    jobs : iterable
        Consumed lazily (at most ``window`` ahead of the frame being yielded).
    render : callable
        ``job -> image``; for ``mode="processes"`` it must be picklable.
    workers : int
        0 or 1: render in this thread.
    mode : {"threads", "processes"}
    window : int, optional
        Frames in flight (default ``3 * workers``).
    """
    it = iter(jobs)
    if workers <= 1:
        for job in it:
            yield render(job)
        return
    # the first frame in this thread, before any worker starts: what it fills (the region colours'
    # bands, measured on the first pose drawn; text sprites) is then the same for every frame and
    # every run, as with one worker, instead of depending on which worker got there first
    first = next(it, None)
    if first is None:
        return
    yield render(first)
    window = window or 3 * workers
    if mode == "processes":
        import multiprocessing as mp

        ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
        pool = ctx.Pool(workers, initializer=_init_process, initargs=(render,))
        try:
            yield from pool.imap(_render_in_process, it, chunksize=2)
        finally:
            pool.terminate()
            pool.join()
        return
    with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="usdface-render") as ex:
        pending = deque()
        for job in it:
            pending.append(ex.submit(render, job))
            if len(pending) >= window:
                break
        while pending:
            img = pending.popleft().result()
            nxt = next(it, None)
            if nxt is not None:
                pending.append(ex.submit(render, nxt))
            yield img
