"""A shot is committed as a whole, OUTDIR is locked while a run writes, dead runs' leftovers go.

``usdface run`` writes every file of a shot into a private work folder inside OUTDIR,
``.usdface-run-<pid>@<host>-<token>``, and then commits (:meth:`ShotSession.commit`):

1. ``COMMIT.json`` is written into the work folder and flushed to disk: the run's files in commit
   order, and the previous run's files this run does not write. From here on the commit is only
   ever completed, never undone.
2. OUTDIR's shot stages (``shot.usda``, ``shot_skel.usda``, ...) are removed, so nothing in OUTDIR
   composes a mix of two runs while files are being replaced.
3. Files of the previous run that this run does not write are removed (``skel.usdc`` after a
   ``--output-kind skel`` run, when the new run writes points only).
4. Every file is renamed into OUTDIR: the layers and other files, then ``summary.json``, then the
   shot stages, last.
5. The work folder is removed.

Each shot stage lists the run's id and, for every file of the run, its sha256 and provenance id
(``customLayerData["usdface"]["shot"]``, a JSON string); ``usdface check OUTDIR/shot.usda``
compares them with the files beside it and exits 1 on a mixed or incomplete shot. So after a
crash at any moment a shot stage in OUTDIR gives the complete old shot or the complete new one
(between steps 2 and 4 there is none, and ``check`` says a commit was interrupted); the next run
into OUTDIR completes the interrupted commit before it starts (:func:`tidy`).

The run id is the first 16 hex digits of the sha256 of the run's provenance (usdface version,
options, input names and sha256): the same job gets the same id, so repeated runs stay
byte-identical.

OUTDIR is locked while a run writes: ``OUTDIR/.usdface-lock`` held with ``flock`` (released by the
system when the process dies, even by SIGKILL; network file systems map it to their own locks),
holding the host, pid and start time for the message a second run gets. The lock file is removed
when the run ends.

Temporaries (work folders, ``.<name>.tmp-<pid>@<host>-...`` files) are removed by the next run
into the folder, and by ``usdface batch`` for each shot folder and the cache, when their owner is
dead: named by a process of this host that no longer runs (or whose pid was reused since), or
older than :data:`TEMPORARY_MAX_AGE` (24 hours: owners on other hosts cannot be asked). A run
folder of this host found by a process holding the folder's lock is dead whatever its pid says
(a run keeps the lock while its folder lives; a long-lived Dask worker's pid outlives its shots).
A run folder holding ``COMMIT.json`` has its commit completed first.

Test hooks (tests and benchmarks only): ``USDFACE_TEST_KILL_AT=<step>`` makes the commit send
itself SIGKILL right after ``<step>``; :func:`commit_steps` lists the steps of a run's files.
``USDFACE_TEST_LOCK_LOG=<file>`` appends a JSON line to ``<file>`` each time an OUTDIR lock is
taken (after) or released (before), naming the folder, the process, why it locks (``run``,
``tidy``, ``probe``), and, when taken, the holder a killed process left in the lock file and the
live processes' run folders present: benchmarks/batch_faults.py checks from it that no two
writers ever held one folder.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import secrets
import shutil
import signal
import socket
import time
from pathlib import Path

from ..errors import LockedError
from ..fileutil import (HOST_TAG, TEMPORARY_MAX_AGE, format_bytes, fsync_dir, fsync_file, inject_fault, owner_is_dead,
                        same_file_problems, temporary_owner, write_error)
from ..usd.shot_record import MARKER_NAME, RUN_FOLDER_PREFIX, SUMMARY_NAME, is_shot_stage, leftovers, shot_record
from .stopping import signals_deferred

log = logging.getLogger("usdface")

LOCK_NAME = ".usdface-lock"
#: temporaries whose owner cannot be asked (another host) are removed after this many seconds
#: environment variable of the kill test hook (module docstring)
KILL_ENV = "USDFACE_TEST_KILL_AT"
#: environment variable of the lock audit hook (module docstring)
LOCK_LOG_ENV = "USDFACE_TEST_LOCK_LOG"


def run_id(provenance: dict) -> str:
    """The id of a run: 16 hex digits of the sha256 of its provenance (same job, same id)."""
    return hashlib.sha256(json.dumps(provenance, sort_keys=True, default=str).encode()).hexdigest()[:16]


def commit_order(files) -> list[str]:
    """The order files are renamed into OUTDIR: other files, ``summary.json``, the shot stages."""
    files = list(dict.fromkeys(files))
    rest = [f for f in files if not is_shot_stage(f) and f != SUMMARY_NAME]
    return rest + [f for f in files if f == SUMMARY_NAME] + [f for f in files if is_shot_stage(f)]


def commit_steps(files, *, stale: bool = False) -> list[str]:
    """The commit's steps for a run writing ``files`` (the names ``USDFACE_TEST_KILL_AT`` takes)."""
    return (["written", "marker", "unlink-shots"] + (["remove-stale"] if stale else [])
            + [f"rename:{f}" for f in commit_order(files)] + ["cleanup"])


def _step(name: str) -> None:
    """The kill test hook: SIGKILL this process right after step ``name`` when asked."""
    if os.environ.get(KILL_ENV) == name:
        os.kill(os.getpid(), getattr(signal, "SIGKILL", signal.SIGTERM))


# -- the lock -------------------------------------------------------------------------------------

class OutdirLock:
    """``FOLDER/.usdface-lock``: one writer at a time; the holder's host, pid and start time inside."""

    def __init__(self, folder, *, purpose: str = "run"):
        self.folder = Path(folder)
        self.path = self.folder / LOCK_NAME
        self.fd: int | None = None
        self.purpose = purpose  # what the lock is taken for (the audit hook's record)

    def acquire(self) -> None:
        """Take the lock or raise :class:`~usdface.errors.LockedError` naming the holder."""
        try:
            import fcntl
        except ImportError:  # no flock (Windows): an exclusive file whose owner is checked
            return self._acquire_exclusive()
        for _ in range(100):
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise write_error(self.path, exc) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _read_holder(fd)
                os.close(fd)
                raise LockedError(self._busy_message(holder)) from None
            except OSError:  # a file system without locks
                os.close(fd)
                return self._acquire_exclusive()
            try:  # the previous holder may have removed the file between our open and flock
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if same:
                self.fd = fd
                if os.environ.get(LOCK_LOG_ENV):
                    _audit(self, "acquire", _read_holder(fd))
                self._write_holder()
                return
            os.close(fd)
        raise LockedError(f"{self.folder}: its lock file {self.path} keeps changing; another process is using it")

    def _acquire_exclusive(self) -> None:
        for _ in range(3):
            try:
                self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
                self._write_holder()
                return
            except FileExistsError:
                try:
                    holder = json.loads(self.path.read_text() or "{}")
                    mtime = self.path.stat().st_mtime
                except (OSError, ValueError):
                    holder, mtime = {}, time.time()
                name = f".tmp-{holder.get('pid', 0)}@{holder.get('hostTag', '')}"
                dead = owner_is_dead(name, mtime) if holder.get("hostTag") else None
                if dead or (dead is None and time.time() - mtime > TEMPORARY_MAX_AGE):
                    with contextlib.suppress(FileNotFoundError):
                        self.path.unlink()
                    continue
                raise LockedError(self._busy_message(holder)) from None
            except OSError as exc:
                raise write_error(self.path, exc) from None
        raise LockedError(self._busy_message({}))

    def _write_holder(self) -> None:
        info = {"host": socket.gethostname(), "hostTag": HOST_TAG, "pid": os.getpid(),
                "started": time.strftime("%Y-%m-%d %H:%M:%S", time.localtime())}
        with contextlib.suppress(OSError):
            os.ftruncate(self.fd, 0)
            os.write(self.fd, json.dumps(info).encode())

    def _busy_message(self, holder: dict) -> str:
        who = (f"pid {holder['pid']} on {holder.get('host', '?')}, since {holder.get('started', '?')}"
               if holder.get("pid") else "another process")
        return (f"{self.folder} is being written by another usdface run ({who}); wait for it to finish or stop "
                "it (two runs into one folder would mix their files)")

    def release(self) -> None:
        if self.fd is None:
            return
        if os.environ.get(LOCK_LOG_ENV):
            _audit(self, "release")
        with contextlib.suppress(OSError):
            self.path.unlink()
        with contextlib.suppress(OSError):
            os.close(self.fd)
        self.fd = None


def _audit(lock: OutdirLock, event: str, previous: dict | None = None) -> None:
    """The lock audit hook (module docstring): one JSON line, appended in one write."""
    record = {"t": time.time(), "event": event, "purpose": lock.purpose, "folder": str(lock.folder.resolve()),
              "pid": os.getpid(), "host": HOST_TAG}
    if event == "acquire":
        stale = (previous or {}).get("pid")
        if stale is not None and (previous or {}).get("hostTag") == HOST_TAG:
            from ..fileutil import process_alive

            record["previous"] = {"pid": stale, "alive": process_alive(int(stale))}
        record["liveRunFolders"] = [p.name for p in leftovers(lock.folder) if p.name.startswith(RUN_FOLDER_PREFIX)
                                    and owner_is_dead(p.name, p.lstat().st_mtime) is False
                                    and (temporary_owner(p.name) or (0,))[0] != os.getpid()]
    fd = os.open(os.environ[LOCK_LOG_ENV], os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        os.write(fd, (json.dumps(record) + "\n").encode())
    finally:
        os.close(fd)


def _read_holder(fd: int) -> dict:
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        return json.loads(os.read(fd, 4096).decode() or "{}")
    except (OSError, ValueError):
        return {}


def folder_in_use(folder) -> bool:
    """Whether a live process holds FOLDER's lock (a run writes it); the lock is taken for a moment
    to tell."""
    lock = OutdirLock(folder, purpose="probe")
    if not lock.path.exists():
        return False
    try:
        lock.acquire()
    except LockedError:
        return True
    except OSError:
        return False
    lock.release()
    return False


# -- commit, roll-forward, tidying ----------------------------------------------------------------

def _apply(work: Path, folder: Path, plan: dict, *, hooks: bool = False) -> None:
    """Steps 2-4 of the commit (module docstring); idempotent, so an interrupted commit is completed
    by running it again."""
    order = plan["files"]
    stages = [f for f in order if is_shot_stage(f)] + [f for f in plan.get("stale", []) if is_shot_stage(f)]
    for name in stages:  # old stages out first: none may compose a half-replaced folder
        if (work / name).exists() or name in plan.get("stale", []):
            _remove(folder / name)
    fsync_dir(folder)
    if hooks:
        _step("unlink-shots")
    if plan.get("stale"):
        for name in plan["stale"]:
            _remove(folder / name)
        if hooks:
            _step("remove-stale")
    for name in order:
        if is_shot_stage(name) and not any(is_shot_stage(n) for n in order[:order.index(name)]):
            fsync_dir(folder)  # every other file is in place before the first shot stage appears
        src, dst = work / name, folder / name
        if src.exists():
            if hooks:
                inject_fault("commit", dst)
            dst.parent.mkdir(parents=True, exist_ok=True)  # a deliverable may live in a subfolder
            if dst.is_dir() and not dst.is_symlink():
                # a folder deliverable (frames of a playblast): the old one goes into the work folder first
                os.replace(dst, work / f".replaced-{name.replace('/', '_')}-{secrets.token_hex(2)}")
            os.replace(src, dst)
        if hooks:
            _step(f"rename:{name}")
    fsync_dir(folder)


def _remove(path: Path) -> None:
    """Remove a file or a folder; nothing when it is not there."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def _fsync_tree(path: Path) -> None:
    if path.is_dir():
        for root, _, names in os.walk(path):
            for n in names:
                fsync_file(os.path.join(root, n))
        fsync_dir(path)
    else:
        fsync_file(path)


def roll_forward(work: Path, folder: Path) -> str | None:
    """Complete the commit recorded in ``work/COMMIT.json``; returns its run id (None: no commit)."""
    try:
        plan = json.loads((work / MARKER_NAME).read_text())
    except (OSError, ValueError):
        return None
    try:
        _apply(work, folder, plan)
    except OSError as exc:
        raise write_error(folder / (exc.filename or ""), exc) from None
    return plan.get("runId")


def _tree_size(path: Path) -> int:
    total = 0
    for root, _, names in os.walk(path):
        for n in names:
            with contextlib.suppress(OSError):
                total += os.lstat(os.path.join(root, n)).st_size
    return total


def _newest_mtime(path: Path) -> float:
    newest = path.lstat().st_mtime
    if path.is_dir():
        for entry in os.scandir(path):
            with contextlib.suppress(OSError):
                newest = max(newest, entry.stat(follow_symlinks=False).st_mtime)
    return newest


def tidy(folder, *, keep=(), max_age: float = TEMPORARY_MAX_AGE) -> dict:
    """Complete interrupted commits and remove temporaries whose owner is dead (module docstring).

    Call it holding the folder's lock (a run does, at its start, before making its own work folder;
    ``keep`` names entries to leave alone). Returns what was done:
    ``{"completed": [run ids], "removed": [names], "bytes": freed, "kept": [names of live owners']}``.
    """
    folder = Path(folder)
    report = {"completed": [], "removed": [], "bytes": 0, "kept": []}
    now = time.time()
    for path in leftovers(folder):
        if path.name in keep:
            continue
        try:
            mtime = _newest_mtime(path)
        except OSError:
            continue
        dead = owner_is_dead(path.name, path.lstat().st_mtime)
        if path.name.startswith(RUN_FOLDER_PREFIX) and (temporary_owner(path.name) or (0, None))[1] == HOST_TAG:
            dead = True  # the caller holds the lock that every run of this host holds while its folder lives
        if dead is False or (dead is None and now - mtime < max_age):
            report["kept"].append(path.name)
            continue
        if path.is_dir():
            if (path / MARKER_NAME).exists():
                rid = roll_forward(path, folder)
                if rid:
                    report["completed"].append(rid)
                    log.warning("%s: completed the commit of run %s, interrupted earlier", folder, rid)
            size = _tree_size(path)
            shutil.rmtree(path, ignore_errors=True)
        else:
            size = path.lstat().st_size
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
        report["removed"].append(path.name)
        report["bytes"] += size
    if report["removed"]:
        log.info("%s: removed %d temporar%s left by stopped processes (%s)", folder, len(report["removed"]),
                 "y" if len(report["removed"]) == 1 else "ies", format_bytes(report["bytes"]))
    return report


def tidy_unlocked_folder(folder) -> dict | None:
    """:func:`tidy` ``folder`` under its lock, unless a live run holds it (then None); a lock file
    that nobody holds (its run was killed) is removed with the lock."""
    folder = Path(folder)
    if not folder.is_dir() or not (leftovers(folder) or (folder / LOCK_NAME).exists()):
        return None
    lock = OutdirLock(folder, purpose="tidy")
    try:
        lock.acquire()
    except LockedError:
        return None
    try:
        return tidy(folder)
    finally:
        lock.release()


# -- one run's session ----------------------------------------------------------------------------

class ShotSession:
    """OUTDIR locked, tidied and given a private work folder for one run; :meth:`commit` puts the
    run's files in place as a whole, :meth:`close` removes what is left and releases the lock.

    Examples
    --------
    >>> with ShotSession(out, run_id(prov)) as work:      # doctest: +SKIP
    ...     write_everything(work); session.commit(files)
    """

    def __init__(self, folder, run: str, *, inputs: dict | None = None):
        self.folder = Path(folder)
        self.run_id = run
        self.inputs = inputs or {}
        self.lock = OutdirLock(self.folder)
        self.work: Path | None = None
        self.tidied: dict = {}
        self.committed = False

    def open(self) -> Path:
        """Lock the folder, tidy it, make the work folder; returns the work folder."""
        self.lock.acquire()
        try:
            self.tidied = tidy(self.folder)
            self.work = self.folder / f"{RUN_FOLDER_PREFIX}{os.getpid()}@{HOST_TAG}-{secrets.token_hex(4)}"
            try:
                os.mkdir(self.work)
            except OSError as exc:
                self.work = None
                raise write_error(self.folder, exc) from None
        except BaseException:
            self.lock.release()
            raise
        return self.work

    def __enter__(self) -> Path:
        return self.open()

    def __exit__(self, *exc) -> bool:
        self.close()
        return False

    def record(self, files) -> dict:
        """The shot record of the files written so far in the work folder (:func:`shot_record`)."""
        return shot_record(self.work, files, self.run_id)

    def write_text(self, name: str, text: str) -> Path:
        """A text file in the work folder, flushed to disk."""
        path = self.work / name
        try:
            inject_fault("save", self.folder / name)
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
                f.flush()
                os.fsync(f.fileno())
        except OSError as exc:
            raise write_error(self.folder / name, exc) from None
        return path

    def _stale(self, files) -> list[str]:
        """Files the previous run wrote (its summary.json lists them) that this run does not."""
        try:
            old = json.loads((self.folder / SUMMARY_NAME).read_text()).get("files") or []
        except (OSError, ValueError, AttributeError):
            return []
        inputs = {k: v for k, v in self.inputs.items() if v is not None}
        stale = []
        for name in old:
            if not isinstance(name, str) or name in files or name.startswith((".", "/")) or ".." in name.split("/"):
                continue
            path = self.folder / name
            if path.exists() and not same_file_problems({"old": path}, inputs):
                stale.append(name)
        return stale

    def commit(self, files) -> None:
        """Put ``files`` (all written in the work folder) in place as a whole (module docstring)."""
        order = commit_order(files)
        missing = [f for f in order if not (self.work / f).exists()]
        if missing:
            raise RuntimeError(f"commit: {', '.join(missing)} not written")  # a bug, not a user error
        plan = {"runId": self.run_id, "files": order, "stale": self._stale(order), "pid": os.getpid(),
                "host": HOST_TAG}
        with signals_deferred():
            try:
                for name in order:
                    _fsync_tree(self.work / name)
                _step("written")
                marker = self.work / MARKER_NAME
                with open(marker, "w", encoding="utf-8") as f:
                    json.dump(plan, f)
                    f.flush()
                    os.fsync(f.fileno())
                fsync_dir(self.work)
                _step("marker")
                _apply(self.work, self.folder, plan, hooks=True)
            except OSError as exc:
                # the commit stays recorded: the next run into the folder completes it
                raise write_error(self.folder / Path(exc.filename or "").name, exc) from None
            self.committed = True
            try:  # the shot is in place; what is left in the work folder is intermediate files
                marker.unlink()
                shutil.rmtree(self.work)
                fsync_dir(self.folder)
            except OSError as exc:
                log.warning("%s: could not remove the run's work folder %s (%s); the next run removes it",
                            self.folder, self.work.name, exc.strerror or exc)
            _step("cleanup")

    def close(self) -> None:
        """Remove the work folder unless a commit is pending in it, and release the lock."""
        try:
            if self.work is not None and self.work.exists() and not (self.work / MARKER_NAME).exists():
                shutil.rmtree(self.work, ignore_errors=True)
        finally:
            self.lock.release()


# -- outputs of a run are never its inputs --------------------------------------------------------

def check_run_paths(folder, files, inputs: dict) -> None:
    """Refuse, before any work, a run whose OUTDIR files (or OUTDIR itself) are inputs.

    ``inputs``: ``{option: path or None}``; USD inputs are followed into the files they compose.
    """
    from ..errors import OptionError
    from ..usd.layers import with_composed_files

    folder = Path(folder)
    outputs = [("-o", folder)] + [(f"-o {folder}: its file", folder / name) for name in files]
    problems = same_file_problems(outputs, with_composed_files({k: v for k, v in inputs.items() if v is not None}))
    if problems:
        raise OptionError("; ".join(problems)
                          + f" (a run writes {', '.join(files)} into {folder})")
