"""File helpers shared by every writer (no pxr here).

- content digests and durable renames (:func:`file_digest`, :func:`fsync_file`, :func:`fsync_dir`);
- atomic writes of plain files (:func:`atomic_write`, or :func:`atomic_path` for a writer that
  takes a file name) and temporary names that say who owns them (:func:`temporary_path`,
  :func:`temporary_owner`), so the next writer of an output removes what a dead process left of it;
- the rule that no output is an input (:func:`same_file_problems`, :func:`refuse_overwriting_inputs`):
  paths compared after resolving ``..`` and symbolic links, existing files also by device and inode
  (hard links, bind mounts);
- one-line descriptions of file-system failures (:func:`failure_cause`, :func:`write_error`,
  :func:`describe_exception`): disk full, read-only file system, permission denied, out of memory.

Test hook (fault injection; documented for the test suite, inert unless set):
``USDFACE_TEST_FAULT="ERRNO[:POINT[:NAME]]"`` makes the atomic writers (this module's and
:class:`usdface.usd.layers.AtomicLayer`) raise ``OSError(ERRNO)`` at ``POINT`` (``create``: making
the temporary file; ``save``: writing it; ``replace``: renaming it into place; ``commit``: a run's
commit renaming the file into OUTDIR, see usdface.shot_commit; empty: every point) for
destination files whose name matches the glob ``NAME`` (empty: every file). ``ERRNO`` is a
name (``ENOSPC``, ``EROFS``, ``EACCES``, ...) or a number. Example:
``USDFACE_TEST_FAULT=ENOSPC:save:anim.usdc usdface run ...``.
"""
from __future__ import annotations

import contextlib
import errno
import fnmatch
import hashlib
import os
import re
from pathlib import Path

from .temporaries import (HOST_TAG, NAME_MAX, TEMPORARY_MAX_AGE, TEMPORARY_NAME_MAX,  # noqa: F401 - re-exported
                          is_temporary_name, owner_is_dead, process_alive, remove_dead_temporaries,
                          temporaries_of, temporary_owner, temporary_path)

#: environment variable of the fault-injection test hook (see the module docstring)
FAULT_ENV = "USDFACE_TEST_FAULT"
FAULT_POINTS = ("create", "save", "replace", "commit")


def file_digest(path: str | os.PathLike) -> str:
    """sha256 of a file's bytes (provenance, caches)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def path_digest(path: str | os.PathLike) -> str:
    """sha256 of a file, or of a folder (its files' relative names and sha256, in sorted order)."""
    p = Path(path)
    if not p.is_dir():
        return file_digest(p)
    h = hashlib.sha256(b"usdface-folder/1\0")
    for f in sorted(q for q in p.rglob("*") if q.is_file()):
        h.update(f"{f.relative_to(p).as_posix()}\0{file_digest(f)}\0".encode())
    return h.hexdigest()


def fsync_file(path: str | os.PathLike) -> None:
    """Flush a file's data to disk (before renaming it over a good one)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_dir(path: str | os.PathLike) -> None:
    """Flush a folder's entries (after a rename into it); a no-op where folders cannot be opened."""
    try:
        fd = os.open(Path(path), os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def set_default_mode(path: str | os.PathLike) -> None:
    """Give a file the permissions a plain ``open(path, "w")`` would (temporary files come out 0600)."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(path, 0o666 & ~mask)


# -- atomic writes and fault injection ------------------------------------------------------------

def inject_fault(point: str, path: str | os.PathLike) -> None:
    """The fault-injection test hook (module docstring): raise the configured OSError here."""
    spec = os.environ.get(FAULT_ENV)
    if not spec:
        return
    code, _, rest = spec.partition(":")
    where, _, pattern = rest.partition(":")
    if where and where != point:
        return
    if pattern and not fnmatch.fnmatch(Path(path).name, pattern):
        return
    number = int(code) if code.isdigit() else getattr(errno, code.strip().upper(), errno.EIO)
    raise OSError(number, os.strerror(number), str(path))


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "w", *, encoding: str | None = "utf-8"):
    """Write a plain file atomically: a temporary beside it, fsynced, renamed over ``path``.

    A failure leaves ``path`` as it was and no temporary; file-system failures become a
    :class:`~usdface.errors.WriteError` naming ``path`` and the cause.

    Examples
    --------
    >>> with atomic_write("summary.json") as f:   # doctest: +SKIP
    ...     f.write(text)
    """
    binary = "b" in mode
    with atomic_path(path) as tmp, open(tmp, mode, **({} if binary else {"encoding": encoding})) as f:
        yield f


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, *, suffix: str | None = None):
    """A temporary path (:func:`temporary_path`) for a writer that takes a file name (USD, ezc3d,
    OpenImageIO, a CSV writer), renamed over ``path`` when the ``with`` block succeeds: fsynced,
    given a plain file's permissions, then the folder fsynced.

    A failure (or SIGINT, SIGTERM, SIGHUP, which raise :class:`~usdface.errors.Interrupted`) leaves
    ``path`` as it was and removes the temporary; file-system failures become a
    :class:`~usdface.errors.WriteError` naming ``path``. After a SIGKILL the next writer of ``path``
    removes the temporary (its name says its owner is dead).

    Examples
    --------
    >>> with atomic_path("take.c3d", suffix=".c3d") as tmp:   # doctest: +SKIP
    ...     c3d.write(str(tmp))
    """
    path = Path(os.fspath(path))
    tmp = temporary_path(path, suffix=suffix)
    try:
        inject_fault("create", path)
        yield tmp
        inject_fault("save", path)
        fsync_file(tmp)
        set_default_mode(tmp)
        inject_fault("replace", path)
        os.replace(tmp, path)
        fsync_dir(path.parent)
    except OSError as exc:
        raise write_error(path, exc) from None
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink()


# -- output paths checked before any work ----------------------------------------------------------

def check_output_file(path: str | os.PathLike, *, suffixes, option: str = "-o", joiner: str = ", ",
                      unwritable=None) -> Path:
    """``path`` as a Path once its suffix is one of ``suffixes`` and its folder exists and is
    writable; else an OptionError naming ``option`` (``unwritable(path)`` makes the error for a
    folder that is not writable, when given)."""
    from .errors import OptionError

    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise OptionError(f"{option} {p}: expected a file ending in {joiner.join(suffixes)}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise OptionError(f"{option} {p}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise unwritable(p) if unwritable is not None else OptionError(f"{option} {p}: folder {folder} is not writable")
    return p


# -- outputs are never inputs ---------------------------------------------------------------------

def _resolved(path) -> str:
    return os.path.realpath(os.path.abspath(os.path.expanduser(os.fspath(path))))


def _identity(path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return st.st_dev, st.st_ino


def same_file_problems(outputs: dict, inputs: dict) -> list[str]:
    """One message per output that is an input (or would replace one).

    Parameters
    ----------
    outputs, inputs : dict
        ``{label: path}`` (``None`` paths are skipped); labels name the option, e.g. ``"-o"`` or
        ``"--capture"``. An input label may map to a list of paths (the files a USD input composes);
        ``outputs`` may also be a list of ``(label, path)`` pairs (one label, many files).

    Two paths are one file when they resolve to the same absolute path (``..``, symbolic links)
    or, for existing files, have the same device and inode (hard links, bind mounts).
    """
    problems = []
    flat = []
    for label, value in inputs.items():
        for p in (value if isinstance(value, (list, tuple)) else [value]):
            if p is not None:
                flat.append((label, p, _resolved(p), _identity(p)))
    for out_label, out in (outputs.items() if isinstance(outputs, dict) else outputs):
        if out is None:
            continue
        o_res, o_id = _resolved(out), _identity(out)
        for in_label, inp, i_res, i_id in flat:
            if o_res == i_res:
                how = "" if os.path.abspath(os.fspath(out)) == os.path.abspath(os.fspath(inp)) else \
                    f", both being {o_res}"
            elif o_id is not None and o_id == i_id:
                how = ", the same file under another name (a hard link or another mount of it)"
            else:
                continue
            problems.append(f"{out_label} {out} would overwrite the input {inp} ({in_label}){how}; choose another "
                            "output path")
            break
    return problems


def refuse_overwriting_inputs(outputs: dict, inputs: dict) -> None:
    """Raise :class:`~usdface.errors.OptionError` naming every output that is an input."""
    problems = same_file_problems(outputs, inputs)
    if problems:
        from .errors import OptionError

        raise OptionError("; ".join(problems))


# -- one line for a failure -----------------------------------------------------------------------

_CAUSES = {
    errno.ENOSPC: "disk full",
    getattr(errno, "EDQUOT", -1): "disk quota exceeded",
    errno.EFBIG: "file too large for the file system",
    errno.EROFS: "read-only file system",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.EIO: "input/output error (a failing disk or network file system)",
    errno.ENOENT: "no such file or folder",
    errno.ENOTDIR: "a part of the path is not a folder",
    errno.EISDIR: "is a folder",
    errno.EMFILE: "too many open files",
    errno.ENAMETOOLONG: "file name too long",
    errno.ENOMEM: "out of memory",
}
_TEXT_CAUSES = (("no space left", errno.ENOSPC), ("quota", getattr(errno, "EDQUOT", errno.ENOSPC)),
                ("read-only file system", errno.EROFS), ("permission denied", errno.EACCES),
                ("insufficient permissions", errno.EACCES), ("input/output error", errno.EIO))
#: below this many free bytes a failed write is put down to a full disk
_NEARLY_FULL = 1 << 20


def format_bytes(n: float) -> str:
    """A byte count for people: 512 B, 38.2 MB, 1.5 GB (powers of 1000)."""
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if abs(n) < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000.0
    return f"{n:.1f} PB"  # pragma: no cover


def _existing_folder(path: Path) -> Path:
    p = Path(os.path.abspath(path))
    while not p.exists() and p != p.parent:
        p = p.parent
    return p if p.is_dir() else p.parent


def _errno_of(exc: BaseException | None) -> int | None:
    if isinstance(exc, OSError) and exc.errno:
        return exc.errno
    text = str(exc or "").lower()
    for needle, number in _TEXT_CAUSES:
        if needle in text:
            return number
    return None


def os_error_cause(exc: BaseException) -> str:
    """Why an operation failed, in a few words, from the error alone (no path to probe: a standard
    stream, a pipe)."""
    number = _errno_of(exc)
    return _CAUSES.get(number) or getattr(exc, "strerror", None) or _short(str(exc)) or type(exc).__name__


def failure_cause(path: str | os.PathLike, exc: BaseException | None = None, *, writing: bool = True) -> str:
    """Why writing (or reading) ``path`` failed, in a few words: from the error number, else from
    the message (USD's errors carry none), else, for a write, from the file system of ``path``'s
    folder (read-only flag, free space, write permission)."""
    folder = _existing_folder(Path(path).parent)
    number = _errno_of(exc)
    probe = _probe_folder(folder) if writing else None
    if number in (errno.EACCES, errno.EPERM) and probe == "read-only file system":
        number = errno.EROFS  # USD says "insufficient permissions" on a read-only mount
    if number is None and probe is not None:
        return probe
    cause = _CAUSES.get(number) if number is not None else None
    if cause is None:
        detail = getattr(exc, "strerror", None) or _short(str(exc or "")) or "the write failed without a reason given"
        return detail
    if number in (errno.ENOSPC, getattr(errno, "EDQUOT", -1)):
        free = _free_bytes(folder)
        if free is not None:
            cause += f" ({format_bytes(free)} free on the file system of {folder})"
    return cause


def _probe_folder(folder: Path) -> str | None:
    try:
        st = os.statvfs(folder)
    except (OSError, AttributeError):
        return None
    if st.f_flag & getattr(os, "ST_RDONLY", 1):
        return "read-only file system"
    free = st.f_bavail * st.f_frsize
    if free < _NEARLY_FULL:
        return f"disk full ({format_bytes(free)} free on the file system of {folder})"
    if not os.access(folder, os.W_OK):
        return "permission denied"
    return None


def _free_bytes(folder: Path) -> int | None:
    try:
        st = os.statvfs(folder)
    except (OSError, AttributeError):
        return None
    return st.f_bavail * st.f_frsize


def _short(text: str) -> str:
    """The first meaningful line of a (possibly multi-line, C++-decorated) message."""
    quoted = re.findall(r" : '(.+)'\s*$", text, flags=re.MULTILINE)
    lines = [q.strip() for q in quoted] or [ln.strip() for ln in text.splitlines() if ln.strip()]
    return lines[0] if lines else ""


def write_error(path: str | os.PathLike, exc: BaseException | None = None):
    """A :class:`~usdface.errors.WriteError` "cannot write PATH: CAUSE" for a failed write."""
    from .errors import WriteError

    return WriteError(f"cannot write {path}: {failure_cause(path, exc)}")


def is_environment_fault(exc: BaseException) -> bool:
    """Whether ``exc`` is a fault of the environment (the file system, memory, USD's C++ layer) that
    reaches the user as one line and exit 1, rather than a bug whose traceback a report needs. The
    one classifier the command line, `run` and batch use."""
    return isinstance(exc, (OSError, MemoryError)) or type(exc).__module__.startswith("pxr")


def environment_fault(exc: BaseException, prefix: str = ""):
    """The usdface error an environment fault becomes: ResourceError (memory), WriteError (file
    system) or EnvironmentFault (USD), with :func:`describe_exception`'s line after ``prefix``."""
    from .errors import EnvironmentFault, ResourceError, WriteError

    kind = ResourceError if isinstance(exc, MemoryError) else WriteError if isinstance(exc, OSError) \
        else EnvironmentFault
    return kind(prefix + describe_exception(exc))


def describe_exception(exc: BaseException) -> str:
    """One line for any error reaching the user: usdface's own message, or the file and cause of
    an OSError, the size of a failed allocation, the first line of a USD (Tf) error."""
    from .errors import UsdFaceError

    if isinstance(exc, UsdFaceError):
        return str(exc)
    if isinstance(exc, MemoryError):
        detail = str(exc).strip()
        return ("out of memory" + (f": {detail}" if detail else "")
                + " (use fewer frames, a smaller mesh, or a machine with more memory)")
    if isinstance(exc, OSError):
        if exc.filename is None:
            return failure_cause(".", exc, writing=False)
        extra = f" -> {exc.filename2}" if getattr(exc, "filename2", None) else ""
        return f"{exc.filename}{extra}: {failure_cause(exc.filename, exc, writing=False)}"
    if type(exc).__module__.startswith("pxr"):  # Tf.ErrorException: C++ decorations, no errno
        line = _short(str(exc)) or type(exc).__name__
        number = _errno_of(exc)
        cause = _CAUSES.get(number) if number is not None else None
        return f"USD error: {line}" + (f" ({cause})" if cause and cause not in line.lower() else "")
    return f"{type(exc).__name__}: {exc}"


def probe_writable_folder(path: str | os.PathLike, *, what: str) -> Path:
    """The folder of the output ``path``, checked to exist and to take a new file (a temporary file
    is created and removed: permission bits do not tell, root ignores them and read-only mounts
    refuse anyway). Raises InputError naming ``what`` ("movie", "report"...) and the folder."""
    from .errors import InputError

    out = Path(path)
    folder = out.parent if str(out.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"cannot write {what} {out}: folder {folder} does not exist")
    if out.is_dir():
        raise InputError(f"cannot write {what} {out}: it is a folder")
    probe = temporary_path(out)  # named for its owner: a SIGKILL between the two calls leaves nothing for long
    try:
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
    except OSError as exc:  # read-only, permission, disk full: an environment fault (exit 1)
        raise write_error(f"{what} {out}", exc) from None
    os.unlink(probe)
    return folder


@contextlib.contextmanager
def stop_signals_deferred():
    """SIGINT, SIGTERM and SIGHUP wait until the block ends (a few renames are never stopped
    half-way), then act as they would have. Only the main thread can; elsewhere a no-op."""
    import signal
    import threading

    from .errors import stop_signals

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    previous = {}
    try:
        for s in stop_signals():
            previous[s] = signal.signal(s, lambda signum, frame: pending.append(signum))
    except ValueError:  # not the main interpreter
        for s, handler in previous.items():
            signal.signal(s, handler)
        yield
        return
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        if pending:
            signal.raise_signal(pending[0])


class StagedOutputs:
    """Write several output files so that either all of them appear or none does.

    Each output is written to a temporary name in its own folder (same suffix, so format-by-suffix
    writers such as USD work); :meth:`commit` renames them all into place, and leaving the
    ``with`` block on an error or an interruption removes every temporary. SIGINT, SIGTERM and
    SIGHUP wait for :meth:`commit` to finish (:func:`stop_signals_deferred`); a crash (SIGKILL, a
    power cut) between two of its renames can still leave a subset.

    Examples
    --------
    >>> with StagedOutputs() as staged:                     # doctest: +SKIP
    ...     write_layer(staged.path("out/curves.usdc"))
    ...     write_text(staged.path("out/curves.csv"), text)
    ...     staged.commit()
    """

    def __init__(self) -> None:
        self._pairs: list[tuple[Path, Path]] = []
        self.committed = False

    def path(self, final):
        """The temporary to write ``final`` to; a target that is no path (an in-memory layer) is
        returned as it is (nothing to stage)."""
        if not isinstance(final, (str, bytes, os.PathLike)):
            return final
        p = Path(os.fsdecode(final))
        tmp = temporary_path(p)  # names its owner, so a dead owner's leftovers can be tidied
        self._pairs.append((tmp, p))
        return tmp

    def commit(self) -> None:
        with stop_signals_deferred():
            self._rename_all()
        self.committed = True

    def _rename_all(self) -> None:
        try:
            for tmp, final in self._pairs:
                fsync_file(tmp)
                set_default_mode(tmp)  # temporaries may come out 0600
            for tmp, final in self._pairs:
                inject_fault("replace", final)
                os.replace(tmp, final)
                fsync_dir(final.parent)
        except OSError as exc:
            raise write_error(getattr(exc, "filename", None) or self._pairs[0][1], exc) from None

    def __enter__(self) -> "StagedOutputs":
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        for tmp, _ in self._pairs:
            try:
                tmp.unlink()
            except FileNotFoundError:
                pass
        return False


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (:func:`atomic_write`)."""
    with atomic_write(path) as f:
        f.write(text)
    return Path(path)
