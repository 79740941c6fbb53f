"""Stopping a running shot cleanly, in the command's main thread or in a batch worker's thread.

A command stops on SIGINT, SIGTERM or SIGHUP by raising :class:`~usdface.errors.Interrupted` in
its main thread (the console installs the handlers), so every ``finally`` of the running shot
removes its partial work. A Dask worker runs shots in threads, where no signal handler runs: a
stop is *asked* of the threads running shots (:func:`request_stop`) and raised in them as
:class:`StopRequested` (CPython's ``PyThreadState_SetAsyncExc``), which unwinds the shot exactly as
a Ctrl-C unwinds the command. Like a signal handler, it is raised between two Python bytecodes: a
long C call (a USD save) finishes first.

A shot's commit (:mod:`usdface.pipeline.shot_commit`) is never stopped half-way: in
:func:`signals_deferred`, signals (main thread) and stop requests (shot threads) wait until the
block ends, then act.

In a batch worker, :func:`install_worker_handlers` (run by a Dask worker plugin) makes SIGTERM and
SIGHUP stop the worker's shots, wait for them to remove their partial work, then do what the
signal did before (end the process); SIGINT is left to the batch command, which stops its shots
itself (a Ctrl-C reaches every process of the terminal's foreground group).
"""
from __future__ import annotations

import asyncio
import contextlib
import ctypes
import signal
import sys
import threading
import time
from dataclasses import dataclass

from ..errors import Interrupted, stop_signals
from ..fileutil import stop_signals_deferred

__all__ = ["StopRequested", "running_shot", "request_stop", "running_shots", "signals_deferred",
           "install_worker_handlers", "stop_shots", "STOP_WAIT"]

#: how long a worker waits for its stopped shots to remove their partial work (seconds) before it
#: ends anyway (a shot in a long C call, say a USD save, notices the stop when the call returns)
STOP_WAIT = 30.0


class StopRequested(Interrupted):
    """A stop asked of a shot running in a worker thread (:func:`request_stop`); its signal is the
    one the worker (or the batch) received. Raised in the shot's thread, which the shot's own
    clean-up unwinds like a Ctrl-C."""

    def __init__(self, signum: int | None = None):
        if signum is None:  # raised asynchronously: the class is instantiated without arguments
            with _lock:
                state = _shots.get(threading.get_ident())
            signum = state.signum if state is not None and state.signum else signal.SIGTERM
        super().__init__(signum)


@dataclass
class _ShotThread:
    output: str
    deferring: int = 0            # depth of signals_deferred blocks (a commit)
    signum: int | None = None     # the stop asked of this shot
    raised: bool = False          # StopRequested sent to the thread


_lock = threading.Lock()
_shots: dict[int, _ShotThread] = {}  # thread id -> the shot it runs


def _raise_in(ident: int, exc_type: type | None) -> None:
    """Raise ``exc_type`` in thread ``ident`` at its next bytecode (None: cancel a pending one)."""
    set_async = ctypes.pythonapi.PyThreadState_SetAsyncExc
    set_async.argtypes = (ctypes.c_ulong, ctypes.py_object)
    set_async.restype = ctypes.c_int
    set_async(ident, ctypes.py_object() if exc_type is None else ctypes.py_object(exc_type))


@contextlib.contextmanager
def running_shot(output):
    """The calling thread runs the shot writing ``output`` until the block ends: a stop request
    for it raises :class:`StopRequested` in the block (never after it)."""
    ident = threading.get_ident()
    with _lock:
        _shots[ident] = _ShotThread(str(output))
    try:
        yield
    finally:
        _leave(ident)


def _leave(ident: int) -> None:
    while True:
        try:
            with _lock:
                _shots.pop(ident, None)
                _raise_in(ident, None)  # a stop asked as the shot ended is not raised in the caller
            return
        except StopRequested:  # delivered while leaving: the shot is over anyway
            continue


def running_shots() -> list[str]:
    """The outputs of the shots running in this process's threads."""
    with _lock:
        return [s.output for s in _shots.values()]


def request_stop(signum: int, outputs=None) -> list[int]:
    """Stop the shots running in this process's threads (those writing one of ``outputs``, or all):
    :class:`StopRequested` is raised in each, at once or when its commit ends. Returns their
    thread ids."""
    wanted = None if outputs is None else {str(o) for o in outputs}
    idents = []
    with _lock:
        for ident, state in _shots.items():
            if wanted is not None and state.output not in wanted:
                continue
            idents.append(ident)
            if state.signum is None:
                state.signum = int(signum)
        _deliver(idents)
    return idents


def _deliver(idents) -> None:
    """Raise StopRequested in the threads asked to stop that are not in a commit and have not got
    it yet (or lost it, :func:`_lost_stop`). Called holding ``_lock``."""
    for ident in idents:
        state = _shots.get(ident)
        if state is not None and state.signum is not None and not state.deferring and not state.raised:
            state.raised = True
            _raise_in(ident, StopRequested)


def _lost_stop(unraisable) -> bool:
    """A StopRequested raised where Python ignores exceptions (a garbage-collector callback, a
    ``__del__``) is lost: the shot will be asked again. True when ``unraisable`` was one."""
    if unraisable.exc_type is None or not issubclass(unraisable.exc_type, StopRequested):
        return False
    with _lock:
        state = _shots.get(threading.get_ident())
        if state is not None:
            state.raised = False
    return True


def wait_for_threads(idents, timeout: float = STOP_WAIT) -> bool:
    """Wait until none of the threads ``idents`` runs a shot (asking again those that lost the
    stop); False if ``timeout`` passed first."""
    deadline = time.monotonic() + timeout
    while True:
        with _lock:
            if not any(i in _shots for i in idents):
                return True
            _deliver(idents)
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)


@contextlib.contextmanager
def signals_deferred():
    """SIGINT, SIGTERM and SIGHUP (main thread), or a stop request (a shot's thread), wait until
    the block ends (a commit is never stopped half-way), then act."""
    if threading.current_thread() is threading.main_thread():
        with stop_signals_deferred():  # the one main-thread deferral (fileutil)
            yield
        return
    ident = threading.get_ident()
    with _lock:
        state = _shots.get(ident)
        if state is not None:
            if state.signum is not None:  # asked before the block: stop now, not in it
                state.raised = True
                _raise_in(ident, None)
                raise StopRequested(state.signum)
            state.deferring += 1
    try:
        yield
    finally:
        if state is not None:
            with _lock:
                state.deferring -= 1
                stop = state.signum is not None and not state.deferring and not state.raised
                state.raised = state.raised or stop
            if stop:
                raise StopRequested(state.signum)


# -- batch workers --------------------------------------------------------------------------------

_previous_handlers: dict[int, object] = {}


def _on_stop_signal(signum, frame) -> None:
    """A worker's SIGTERM/SIGHUP: its shots remove their partial work, then the signal does what
    it did before usdface's handler (by default: end the process)."""
    wait_for_threads(request_stop(signum))
    previous = _previous_handlers.get(signum, signal.SIG_DFL)
    if callable(previous):
        previous(signum, frame)
    elif previous == signal.SIG_DFL:
        signal.signal(signum, signal.SIG_DFL)
        signal.raise_signal(signum)


def install_worker_handlers(*, ignore_interrupt: bool) -> bool:
    """In a Dask worker process: SIGTERM and SIGHUP stop its shots cleanly (:func:`_on_stop_signal`);
    with ``ignore_interrupt`` (a worker of the command's own local cluster) SIGINT and SIGHUP are
    ignored, the command stops the shots. Returns False where handlers cannot be set (not the main thread)."""
    if threading.current_thread() is not threading.main_thread():
        return False
    for s in stop_signals():
        if ignore_interrupt and s != signal.SIGTERM:
            # Ctrl-C and a hang-up reach the whole process group: the command handles them and
            # stops the shots (it may itself ignore SIGHUP: nohup)
            signal.signal(s, signal.SIG_IGN)
        elif s == signal.SIGINT:
            continue
        elif signal.getsignal(s) is not _on_stop_signal:
            _previous_handlers[s] = signal.getsignal(s)
            signal.signal(s, _on_stop_signal)
    if not getattr(sys.unraisablehook, "usdface_stop", False):
        previous_hook = sys.unraisablehook

        def hook(unraisable):
            if not _lost_stop(unraisable):
                previous_hook(unraisable)

        hook.usdface_stop = True
        sys.unraisablehook = hook
    return True


async def stop_shots(outputs, signum: int, timeout: float = STOP_WAIT) -> list[str]:
    """Run on every worker by a batch that stops (``client.run``), or by a worker that closes:
    stop the shots writing one of ``outputs`` (None: all) and wait (without blocking the worker's
    event loop) until they have removed their partial work. Returns the outputs stopped."""
    idents = request_stop(signum, outputs)
    with _lock:
        stopped = [s.output for i, s in _shots.items() if i in idents]
    deadline = time.monotonic() + timeout
    while not wait_for_threads(idents, timeout=0) and time.monotonic() < deadline:
        await asyncio.sleep(0.05)
    return stopped
