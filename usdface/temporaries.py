"""Temporary names that say who owns them, and the owners' liveness (no pxr here).

Every temporary usdface writes is named ``.<stem>.tmp-<pid>@<host>-<token><suffix>`` (files),
``.usdface-run-<pid>@<host>-<token>`` (run folders) or ``.tmp-``/``.trash-<pid>@<host>-<token>``
(cache entries), short enough for a 255-byte output name; the next writer of an output removes the
temporaries of it a dead process left (:func:`temporary_path`, :func:`remove_dead_temporaries`).
usdface.fileutil's atomic writers use these names and re-export them.
"""
from __future__ import annotations

import contextlib
import os
import re
import secrets
import socket
from pathlib import Path

#: temporaries whose owner cannot be asked (another host) are removed once older than this (seconds)
TEMPORARY_MAX_AGE = 24 * 3600.0
#: this machine's name as it appears in temporary names (letters, digits and _ only)
HOST_TAG = re.sub(r"[^A-Za-z0-9_]", "_", socket.gethostname() or "localhost")[:48] or "localhost"
# ".<name>.tmp-<pid>[@<host>][-<token>][.<suffix>]", ".usdface-run-<pid>[@<host>][-<token>]" (and the
# cache's ".tmp-" / ".trash-" folders);
# names written before host tags existed (".x.tmp-<pid>-<token>.usdc") parse with host None
# (any suffixes: a writer's own, and USD's six random characters of the temporary it saves through)
_OWNER_RE = re.compile(r"(?:\.tmp-|^\.trash-|^\.usdface-run-)(?P<pid>\d+)(?:@(?P<host>[A-Za-z0-9_]+))?(?:-[0-9a-f]+)?"
                       r"(?:\.[A-Za-z0-9]+)*$")
_TEMP_FILE_RE = re.compile(r"^\..+\.tmp-")
_TEMP_NAME_RE = re.compile(r"^\.(?P<prefix>.+?)\.tmp-\d+(?:@[A-Za-z0-9_]+)?-[0-9a-f]+(?:\.[A-Za-z0-9]+)*$")


#: the longest file name most file systems take (bytes)
NAME_MAX = 255
#: the longest temporary name usdface makes: USD saves a layer through a temporary of its own named
#: after ours (``.<our name>.`` and six random characters), which must fit in NAME_MAX too
TEMPORARY_NAME_MAX = NAME_MAX - 40


def temporary_path(path: str | os.PathLike, *, suffix: str | None = None) -> Path:
    """A temporary name beside ``path`` (same suffix, so the same file format), naming its owner:
    ``.<stem>.tmp-<pid>@<host>-<token><suffix>``, the stem shortened so that the name fits in
    :data:`TEMPORARY_NAME_MAX` bytes whatever the output's name. Every temporary usdface writes is named so
    (run folders ``.usdface-run-<pid>@<host>-<token>``, cache entries ``.tmp-<pid>@<host>-<token>``).

    ``suffix`` replaces the output's suffix where a writer insists on its own (ezc3d appends
    ``.c3d`` to any other name). Temporaries of ``path`` left by a dead process (SIGKILL, a power
    cut) are removed first: the next command writing an output tidies what an earlier one left of it.
    """
    p = Path(path)
    remove_dead_temporaries(p)
    tail = f".tmp-{os.getpid()}@{HOST_TAG}-{secrets.token_hex(4)}{p.suffix if suffix is None else suffix}"
    return p.with_name("." + _name_prefix(p.stem, TEMPORARY_NAME_MAX - 1 - len(os.fsencode(tail))) + tail)


def _name_prefix(stem: str, budget: int) -> str:
    """The longest start of ``stem`` that fits in ``budget`` bytes (whole characters; never empty)."""
    encoded = os.fsencode(stem)[:max(budget, 1)]
    while encoded:
        try:
            return os.fsdecode(encoded) if encoded.decode("utf-8") else "_"
        except UnicodeDecodeError:
            encoded = encoded[:-1]  # a character cut in two
    return "_"


def temporaries_of(path: str | os.PathLike) -> list[Path]:
    """The temporaries beside ``path`` that are (or were) being written as ``path``: files, the
    temporaries USD saves them through (``.<stem>.tmp-...`` and six random characters) and folders (a report's media)."""
    p = Path(path)
    try:
        entries = list(os.scandir(p.parent if str(p.parent) else "."))
    except OSError:
        return []
    found = []
    for e in entries:
        m = _TEMP_NAME_RE.match(e.name)
        if m and p.stem.startswith(m.group("prefix")) and not e.is_symlink():
            found.append(Path(e.path))
    return found


def remove_dead_temporaries(path: str | os.PathLike) -> list[Path]:
    """Remove the temporaries of ``path`` whose owner is dead (this host) or, for another host's,
    older than :data:`TEMPORARY_MAX_AGE`; returns them. Live owners' temporaries stay.

    A name matches when its owner wrote it for an output of the same (possibly shortened) stem;
    only dead owners' files go, so a match of another output's stem removes garbage too, never work.
    """
    import shutil
    import time

    removed = []
    for t in temporaries_of(path):
        try:
            mtime = t.lstat().st_mtime
        except OSError:
            continue
        dead = owner_is_dead(t.name, mtime)
        if dead or (dead is None and time.time() - mtime > TEMPORARY_MAX_AGE):
            with contextlib.suppress(OSError):
                if t.is_dir():
                    shutil.rmtree(t)
                else:
                    t.unlink()
                removed.append(t)
    return removed


def is_temporary_name(name: str) -> bool:
    """Whether ``name`` is a usdface temporary file name (``.<name>.tmp-...``)."""
    return bool(_TEMP_FILE_RE.match(name))


def temporary_owner(name: str) -> tuple[int, str | None] | None:
    """(pid, host tag or None) of a temporary file or run folder name; None when it names no owner."""
    m = _OWNER_RE.search(name)
    if m is None:
        return None
    return int(m.group("pid")), m.group("host")


def process_alive(pid: int, *, since: float | None = None) -> bool:
    """Whether process ``pid`` of this machine is alive (and, with ``since``, started before it).

    A process that started after ``since`` (a temporary's modification time) cannot have written
    the temporary: the pid was reused, and the owner is dead.
    """
    if pid <= 0:
        return False
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, another user's
        pass
    except OSError:
        return True
    if since is not None:
        started = _process_start_time(pid)
        if started is not None and started > since + 2.0:
            return False
    return True


def _process_start_time(pid: int) -> float | None:
    """Start time (seconds since the epoch) of a process, from /proc; None where unknown."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            fields = f.read().rsplit(b")", 1)[1].split()
        ticks = int(fields[19])  # field 22 of stat(5); fields here start at field 3
        with open("/proc/stat", "rb") as f:
            boot = next(int(line.split()[1]) for line in f if line.startswith(b"btime"))
        return boot + ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, StopIteration):
        return None


def owner_is_dead(name: str, mtime: float) -> bool | None:
    """True when a temporary's owner is known dead (this host, no such process), False when it is
    alive, None when it cannot be told (another host, or a name without an owner)."""
    owner = temporary_owner(name)
    if owner is None or owner[1] is None or owner[1] != HOST_TAG:
        return None
    return not process_alive(owner[0], since=mtime)
