"""Helpers for the hostile-input tests: run the command (in-process or, where the old code hung,
as a subprocess with a timeout) and check the one-line rule."""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path


def terminal_signals() -> None:
    """``preexec_fn`` for a command the test signals: SIGINT and SIGHUP as a terminal session gives
    them. A test run started in the background (`pytest &`, nohup, some CI runners) passes them
    ignored to its children, and usdface keeps an inherited ignore (as `nohup usdface ...` asks)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGHUP, signal.SIG_DFL)


def code_root() -> Path:
    """The source tree of the usdface under test (PYTHONPATH decides; a baseline tree works too)."""
    import usdface

    return Path(usdface.__file__).resolve().parents[1]


def digest(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def run_in_process(capsys, *args) -> tuple[int, list[str]]:
    """`usdface ARGS` in this process: (exit code, non-empty stderr lines)."""
    import logging

    from usdface.cli import main

    # pytest's own log handlers make main's logging.basicConfig a no-op: show the log on this
    # test's stderr as the command line would, for this call only
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("usdface: %(levelname)s: %(message)s"))
    handler.setLevel(logging.WARNING)
    logging.root.addHandler(handler)
    capsys.readouterr()
    try:
        rc = main([os.fsdecode(a) if isinstance(a, bytes) else str(a) for a in args])
    finally:
        logging.root.removeHandler(handler)
    err = capsys.readouterr().err
    return rc, [line for line in err.splitlines() if line.strip()]


#: address space a hostile-input subprocess may use (a reader that trusts a lying header would
#: otherwise allocate tens of GB on a shared machine before failing)
MEMORY_LIMIT = 4 * 1024**3


def _limit_memory():
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def run_subprocess(*args, timeout: float = 60, cwd=None) -> tuple[int | None, list[str]]:
    """`python -m usdface ARGS` with a timeout (None as exit code when it had to be killed) and
    at most :data:`MEMORY_LIMIT` of address space."""
    env = dict(os.environ, PYTHONPATH=str(code_root()) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    argv = [sys.executable, "-m", "usdface", *(a if isinstance(a, bytes) else os.fsencode(str(a)) for a in args)]
    try:
        p = subprocess.run(argv, capture_output=True, timeout=timeout, env=env, cwd=cwd, preexec_fn=_limit_memory)
    except subprocess.TimeoutExpired:
        return None, ["(killed after the timeout)"]
    err = p.stderr.decode("utf-8", "backslashreplace")
    return p.returncode, [line for line in err.splitlines() if line.strip()]


def assert_one_line(rc, lines, *, code: int, command: str, contains=()):
    """Exit ``code``, exactly one stderr line ``usdface COMMAND: error: ...`` holding ``contains``."""
    assert rc == code, (rc, lines)
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"usdface {command}: error: "), lines
    for text in contains:
        assert text in lines[0], (text, lines[0])
    return lines[0]
