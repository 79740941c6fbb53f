"""Playblast frames rendered by workers: the same movie whatever the workers, and workers that stop
quietly."""
from __future__ import annotations

import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pytest

from usdface.playblast.pipeline import render_in_order

REPO = Path(__file__).resolve().parents[2]


def test_the_first_frame_is_rendered_before_any_worker_starts():
    """What the first frame fills (region bands measured on the pose it draws, text sprites) must
    not depend on which worker gets there first."""
    seen = {}

    def render(job):
        seen[job] = threading.current_thread() is threading.main_thread()
        return job

    assert list(render_in_order(range(12), render, workers=2)) == list(range(12))
    assert seen[0] and not any(seen[k] for k in range(1, 12))


def test_threads_and_processes_give_the_movie_one_worker_gives(shots, cli, tmp_path):
    """Byte for byte: a playblast must not depend on the render workers or their timing (with two
    threads the region bands were measured on whichever of frames 0 and 1 was drawn first)."""
    pytest.importorskip("av")
    shot = shots["hybrid"] / "shot.usda"
    movies = {}
    for label, extra in (("one", ["--workers", 1]), ("threads", ["--workers", 2]),
                         ("processes", ["--workers", 2, "--parallel", "processes"])):
        movies[label] = tmp_path / f"{label}.mp4"
        assert cli("playblast", shot, "-o", movies[label], "--range", 300, 340, "--size", "320x180", "-q",
                   *extra) == 0
    one = movies["one"].read_bytes()
    assert movies["threads"].read_bytes() == one and movies["processes"].read_bytes() == one


def test_process_workers_stop_quietly_when_the_movie_stops_early():
    """The command's SIGTERM handler (raise Interrupted, to clean up) is not the workers': a pool
    stopped while they render ends them without a traceback each."""
    script = textwrap.dedent("""
        import signal, time
        from usdface.playblast.pipeline import render_in_order

        def stop(signum, frame):
            raise KeyboardInterrupt  # as the command does: SIGTERM interrupts the work

        def slow(job):
            time.sleep(0.3)
            return job

        signal.signal(signal.SIGTERM, stop)
        frames = render_in_order(range(40), slow, workers=2, mode="processes")
        for k, _ in zip(range(3), frames):
            pass
        frames.close()  # the movie stops early (an error, Ctrl-C): the busy workers are terminated
        print("done")
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 0 and proc.stdout.strip() == "done", proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
