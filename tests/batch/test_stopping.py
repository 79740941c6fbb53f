"""A stop asked of a shot running in a worker thread (usdface.pipeline.stopping): it unwinds like
a Ctrl-C (its work folder and lock removed), never in the middle of a commit, and is asked again
when Python swallowed it (a garbage-collector callback)."""
from __future__ import annotations

import signal
import sys
import threading
import time
import types

from usdface.pipeline import shot_commit
from usdface.pipeline.shot_commit import ShotSession
from usdface.pipeline.stopping import StopRequested, request_stop, running_shot, running_shots, wait_for_threads


def _shot_thread(target, *args):
    """Run ``target`` in a thread as a batch worker runs a shot; returns (thread, outcome dict)."""
    outcome = {}

    def body():
        try:
            with running_shot(args[0]):
                target(*args, outcome)
            outcome["ended"] = "normally"
        except StopRequested as exc:
            outcome["ended"] = exc

    t = threading.Thread(target=body)
    t.start()
    return t, outcome


def _writing(folder, outcome):
    """A run writing into its work folder until stopped."""
    s = ShotSession(folder, "r1")
    work = s.open()
    outcome["work"] = work
    try:
        i = 0
        while True:
            (work / f"part{i % 10}.usdc").write_bytes(b"x" * 1000)
            i += 1
            time.sleep(0.001)
    finally:
        s.close()


def _wait_for(predicate, timeout=10.0):
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.005)


def test_a_stopped_shot_removes_its_work_folder_and_lock(tmp_path):
    t, outcome = _shot_thread(_writing, tmp_path)
    _wait_for(lambda: "work" in outcome and any(outcome["work"].iterdir()))
    assert running_shots() == [str(tmp_path)]
    idents = request_stop(signal.SIGTERM, [str(tmp_path / "another-shot")])  # only the shots named
    assert idents == [] and t.is_alive()
    idents = request_stop(signal.SIGTERM, [str(tmp_path)])
    assert wait_for_threads(idents, timeout=10)
    t.join(10)
    assert isinstance(outcome["ended"], StopRequested) and outcome["ended"].exit_code == 143
    assert list(tmp_path.iterdir()) == []  # no work folder, no lock
    assert running_shots() == []


def test_a_stop_during_a_commit_waits_for_its_end(tmp_path, monkeypatch):
    """Asked at the commit's first rename: every file is put in place, then the shot stops."""
    files = {"mesh.usdc": b"m", "anim.usdc": b"a", "summary.json": b"{}", "shot.usda": b"#usda 1.0\n"}
    seen = []

    def on_step(name):
        seen.append(name)
        if name == "rename:mesh.usdc":
            request_stop(signal.SIGHUP)
            time.sleep(0.05)  # time for an exception to arrive if it were not deferred

    monkeypatch.setattr(shot_commit, "_step", on_step)

    def commit(folder, outcome):
        s = ShotSession(folder, "r1")
        work = s.open()
        try:
            for name, data in files.items():
                (work / name).write_bytes(data)
            s.commit(list(files))
        finally:
            s.close()

    t, outcome = _shot_thread(commit, tmp_path)
    t.join(10)
    assert isinstance(outcome["ended"], StopRequested) and outcome["ended"].exit_code == 129
    assert seen[-1] == "cleanup"  # the commit ran to its end
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(files)
    assert {n: (tmp_path / n).read_bytes() for n in files} == files


def test_a_stop_asked_before_a_commit_stops_the_shot_before_it(tmp_path):
    from usdface.pipeline.stopping import _lock, _shots, signals_deferred

    entered = []

    def body(folder, outcome):
        with _lock:  # the stop arrives while the shot is not looking (it is asked, not yet raised)
            _shots[threading.get_ident()].signum = signal.SIGTERM
            _shots[threading.get_ident()].raised = True
        with signals_deferred():
            entered.append(True)

    t, outcome = _shot_thread(body, tmp_path)
    t.join(10)
    assert isinstance(outcome["ended"], StopRequested) and not entered


def test_a_swallowed_stop_is_asked_again(tmp_path, monkeypatch):
    """Python ignores an exception raised in a garbage-collector callback or a __del__ (it calls
    sys.unraisablehook): the worker's hook marks the stop lost and the waiting handler asks again."""
    from usdface.pipeline.stopping import install_worker_handlers

    monkeypatch.setattr(sys, "unraisablehook", sys.unraisablehook)
    previous = {s: signal.getsignal(s) for s in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT)}
    try:
        assert install_worker_handlers(ignore_interrupt=False)
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
    swallowed = []

    def body(folder, outcome):
        while True:
            try:
                while True:
                    time.sleep(0.001)
            except StopRequested as exc:  # as a gc callback would: reported as unraisable, then lost
                if swallowed:
                    raise
                swallowed.append(exc)
                sys.unraisablehook(types.SimpleNamespace(exc_type=type(exc), exc_value=exc, exc_traceback=None,
                                                         err_msg="Exception ignored in", object=None))

    t, outcome = _shot_thread(body, tmp_path)
    _wait_for(lambda: running_shots())
    assert wait_for_threads(request_stop(signal.SIGTERM), timeout=10)
    t.join(10)
    assert len(swallowed) == 1 and isinstance(outcome["ended"], StopRequested)


def test_no_stop_escapes_a_finished_shot(tmp_path):
    """A stop asked as a shot ends is raised in the shot or not at all, never in the worker's own
    code after it."""
    ended = []

    def body():
        for _ in range(300):
            try:
                with running_shot(tmp_path):
                    sum(range(50))
            except StopRequested:
                pass  # raised in the shot: what a stop does
            sum(range(50))  # the worker's own code: a stop raised here would end the thread
        ended.append("all shots")

    t = threading.Thread(target=body)
    t.start()
    while t.is_alive():
        request_stop(signal.SIGTERM)
        time.sleep(0.0002)
    t.join()
    assert ended == ["all shots"]
