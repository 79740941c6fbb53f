"""A content-addressed cache for expensive intermediates, safe with concurrent writers.

Layout on disk::

    ROOT/<kind>/<key[:2]>/<key>/          one entry (a folder), never modified once in place
        meta.json                         written last: the entry's metadata + size and sha256 of each file
        <files...>                        the payload (an .npz of arrays, a copied layer, ...)
    ROOT/<kind>/.tmp-<pid>@<host>-<token>/  an entry being written (removed by the next batch once its
                                          writer is dead: :meth:`ContentCache.tidy`)
    ROOT/locks/<kind>-<key>.lock          advisory locks (flock): one process computes a value, the others wait

An entry is written into a temporary folder beside its final place, every file fsynced, and the
folder renamed into place in one ``os.rename``: readers see a whole entry or none. When two
writers race, the first rename wins and the second discards its copy. A write that runs out of
disk space removes its temporary folder and raises :class:`~usdface.errors.ResourceError`; the
cache is left without the entry, never with a partial one. A reader that finds an entry whose
files do not match meta.json (a disk error, a hand edit) removes it and reports a miss.

Keys are sha256 digests of the inputs that determine the value (see :func:`content_key`),
including usdface's version and the algorithms' revision (:mod:`usdface.revisions`), so neither a
new release nor a changed algorithm reads an old one's values.
"""
from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import logging
import os
import secrets
import shutil
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import __version__
from .errors import OptionError, ResourceError
from .fileutil import HOST_TAG, TEMPORARY_MAX_AGE, file_digest, fsync_dir, owner_is_dead

log = logging.getLogger("usdface")

#: how often a process waiting for another's computation of an entry looks again (seconds)
LOCK_POLL = 0.05
#: extra free space (bytes) kept on the cache's disk beyond an entry's size
FREE_SPACE_MARGIN = 64 << 20
_DISK_FULL = {errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC), errno.EFBIG}


def content_key(kind: str, *parts) -> str:
    """sha256 over ``kind``, usdface's version, the revision of the processor that makes ``kind``
    (:data:`usdface.revisions.CACHE_KINDS`; above 1 only, so revision-1 keys stay as they were) and
    ``parts`` (arrays by dtype, shape and bytes; everything else as canonical JSON)."""
    from .revisions import CACHE_KINDS, revision

    h = hashlib.sha256()
    h.update(f"usdface-cache/1\0{kind}\0{__version__}\0".encode())
    made_by = revision(CACHE_KINDS[kind]) if kind in CACHE_KINDS else 1
    if made_by > 1:  # an entry an older revision made is never read
        h.update(f"revision\0{made_by}\0".encode())
    for part in parts:
        _update(h, part)
    return h.hexdigest()


def _update(h, part) -> None:
    if isinstance(part, np.ndarray):
        a = np.ascontiguousarray(part)
        h.update(f"ndarray\0{a.dtype.str}\0{a.shape}\0".encode())
        h.update(a.tobytes())
    elif isinstance(part, (list, tuple)) and any(isinstance(p, np.ndarray) for p in part):
        h.update(f"seq\0{len(part)}\0".encode())
        for p in part:
            _update(h, p)
    else:
        h.update(b"json\0" + json.dumps(part, sort_keys=True, default=str).encode() + b"\0")


@dataclass
class Entry:
    """A cache entry found on disk: its folder and metadata (``meta["files"]`` lists the payload)."""

    path: Path
    meta: dict

    def file(self, name: str) -> Path:
        return self.path / name

    def arrays(self, name: str = "arrays.npz") -> dict:
        with np.load(self.path / name, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}


@dataclass
class CacheStats:
    hits: int = 0
    misses: int = 0
    stores: int = 0
    races: int = 0
    by_kind: dict = field(default_factory=dict)

    def count(self, kind: str, what: str) -> None:
        setattr(self, what, getattr(self, what) + 1)
        self.by_kind.setdefault(kind, {}).setdefault(what, 0)
        self.by_kind[kind][what] += 1


class ContentCache:
    """A folder of content-addressed entries shared by shots, runs and processes.

    Parameters
    ----------
    root : path
        The cache folder (created if missing; its parent must exist).
    lock : {"auto", "file", "dask", "none"}
        How :meth:`lock` serialises computations of one key (only to avoid computing a value twice:
        entries are written atomically, so racing writers never corrupt one): ``file`` takes an
        advisory lock (``fcntl.flock``) on a file in ROOT/locks, which the system releases the
        moment its holder dies (every host of a network file system that supports locks, NFSv4
        for one); ``dask`` a ``distributed.Lock`` on the Dask scheduler, for a shared file system
        without locks (a dead holder blocks the others until its lease times out, 30 s by default,
        and a restarted scheduler forgets every lock); ``auto`` the file lock, or the Dask lock in
        a Dask worker where the cache's file system refuses file locks.

    Examples
    --------
    >>> cache = ContentCache("cache")                         # doctest: +SKIP
    >>> key = content_key("distances", points, faces, "hybrid")  # doctest: +SKIP
    >>> with cache.lock("distances", key):                   # doctest: +SKIP
    ...     entry = cache.get("distances", key) or cache.put("distances", key, arrays=compute(), meta={})
    """

    def __init__(self, root: str | os.PathLike, *, lock: str = "auto"):
        self.root = Path(root)
        if lock not in ("auto", "file", "dask", "none"):
            raise OptionError(f"cache lock {lock!r}: expected auto, file, dask or none")
        self.lock_kind = lock
        self.stats = CacheStats()
        if not self.root.exists():
            try:
                self.root.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise OptionError(f"cache folder {self.root}: cannot create it ({exc.strerror})") from None
        elif not self.root.is_dir():
            raise OptionError(f"cache folder {self.root}: exists and is not a folder")

    def __getstate__(self):  # picklable for Dask: a fresh stats object on the other side
        return {"root": str(self.root), "lock_kind": self.lock_kind}

    def __setstate__(self, state):
        self.root = Path(state["root"])
        self.lock_kind = state["lock_kind"]
        self.stats = CacheStats()

    def __repr__(self) -> str:
        return f"ContentCache({str(self.root)!r})"

    # -- reading ---------------------------------------------------------------------------------

    def entry_path(self, kind: str, key: str) -> Path:
        return self.root / kind / key[:2] / key

    def get(self, kind: str, key: str, *, verify: bool = True, count: bool = True) -> Entry | None:
        """The entry for ``key``, or None (a miss). With ``verify``, file sizes and sha256 are checked."""
        path = self.entry_path(kind, key)
        meta_path = path / "meta.json"
        try:
            meta = json.loads(meta_path.read_text())
        except FileNotFoundError:
            if count:
                self.stats.count(kind, "misses")
            return None
        except (OSError, ValueError) as exc:
            log.warning("cache entry %s unreadable (%s): removing it", path, exc)
            self._discard(path)
            if count:
                self.stats.count(kind, "misses")
            return None
        if verify and not self._intact(path, meta):
            log.warning("cache entry %s does not match its meta.json: removing it", path)
            self._discard(path)
            if count:
                self.stats.count(kind, "misses")
            return None
        if count:
            self.stats.count(kind, "hits")
        return Entry(path, meta)

    @staticmethod
    def _intact(path: Path, meta: dict) -> bool:
        for name, info in meta.get("files", {}).items():
            f = path / name
            try:
                if f.stat().st_size != info["size"] or file_digest(f) != info["sha256"]:
                    return False
            except (OSError, KeyError):
                return False
        return True

    def _discard(self, path: Path) -> None:
        trash = path.with_name(f".trash-{os.getpid()}@{HOST_TAG}-{secrets.token_hex(4)}")
        try:
            os.rename(path, trash)  # out of the way atomically, then delete
        except OSError:
            return
        shutil.rmtree(trash, ignore_errors=True)

    # -- writing ---------------------------------------------------------------------------------

    def put(self, kind: str, key: str, *, meta: dict, arrays: dict | None = None,
            files: dict | None = None) -> Entry:
        """Store an entry atomically; returns it (the other writer's entry if one won a race).

        Parameters
        ----------
        meta : dict
            JSON-serialisable metadata returned with the entry.
        arrays : dict of str -> ndarray, optional
            Stored uncompressed in ``arrays.npz``.
        files : dict of str -> path, optional
            Files copied into the entry under the given names.

        Raises
        ------
        ResourceError
            The cache's disk has too little free space (checked first), or filled up while
            writing; no entry is left behind.
        """
        final = self.entry_path(kind, key)
        if (final / "meta.json").exists():
            return self.get(kind, key, verify=False, count=False)
        arrays = arrays or {}
        files = {name: Path(p) for name, p in (files or {}).items()}
        need = sum(int(a.nbytes) for a in arrays.values()) + sum(p.stat().st_size for p in files.values()) + 4096
        kind_dir = self.root / kind
        self._mkdir(kind_dir)
        free = shutil.disk_usage(kind_dir).free
        if free < need + FREE_SPACE_MARGIN:
            raise ResourceError(self._full_message(kind, need, free))
        tmp = kind_dir / f".tmp-{os.getpid()}@{HOST_TAG}-{threading.get_ident():x}{secrets.token_hex(4)}"
        try:
            tmp.mkdir()
            listing = {}
            if arrays:
                with open(tmp / "arrays.npz", "wb") as f:
                    np.savez(f, **{k: np.asarray(v) for k, v in arrays.items()})
                    f.flush()
                    os.fsync(f.fileno())
                listing["arrays.npz"] = tmp / "arrays.npz"
            for name, src in files.items():
                dst = tmp / name
                with open(src, "rb") as fi, open(dst, "wb") as fo:
                    shutil.copyfileobj(fi, fo, 1 << 20)
                    fo.flush()
                    os.fsync(fo.fileno())
                listing[name] = dst
            record = dict(meta)
            record["files"] = {n: {"size": p.stat().st_size, "sha256": file_digest(p)} for n, p in listing.items()}
            record["kind"] = kind
            record["key"] = key
            record["usdfaceVersion"] = __version__
            with open(tmp / "meta.json", "w") as f:
                f.write(json.dumps(record, sort_keys=True, indent=1, default=str))
                f.flush()
                os.fsync(f.fileno())
            self._mkdir(final.parent)
            try:
                os.rename(tmp, final)
            except OSError as exc:
                if exc.errno in (errno.EEXIST, errno.ENOTEMPTY) or final.exists():
                    self.stats.count(kind, "races")  # another writer got there first: keep theirs
                    shutil.rmtree(tmp, ignore_errors=True)
                    return self.get(kind, key, verify=False, count=False)
                raise
            fsync_dir(final.parent)
        except OSError as exc:
            shutil.rmtree(tmp, ignore_errors=True)
            if exc.errno in _DISK_FULL:
                raise ResourceError(self._full_message(kind, need, shutil.disk_usage(self.root).free,
                                                       while_writing=True)) from None
            raise ResourceError(f"cache folder {self.root}: cannot write a {kind} entry ({exc.strerror or exc}); "
                                "fix the folder, point --cache elsewhere, or use --no-cache") from None
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        self.stats.count(kind, "stores")
        return Entry(final, record)

    def _full_message(self, kind, need, free, while_writing=False) -> str:
        when = "filled up while writing" if while_writing else "has too little free space for"
        return (f"cache folder {self.root} {when} a {kind} entry of {_mb(need)} "
                f"({_mb(free)} free, {_mb(FREE_SPACE_MARGIN)} kept in reserve); no entry was written. "
                "Free disk space, point --cache at a bigger disk, or use --no-cache")

    def _mkdir(self, path: Path) -> None:
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            if exc.errno in _DISK_FULL:
                raise ResourceError(f"cache folder {self.root}: disk full ({exc.strerror})") from None
            raise ResourceError(f"cache folder {self.root}: cannot create {path} ({exc.strerror}); "
                                "point --cache elsewhere or use --no-cache") from None

    # -- locking ---------------------------------------------------------------------------------

    @contextlib.contextmanager
    def lock(self, kind: str, key: str, timeout: float | None = None):
        """Hold a lock on (kind, key) so one process computes a value while the others wait for it."""
        how = self.lock_kind
        if how in ("auto", "file"):
            fd = self._file_lock(kind, key, required=how == "file")
            if fd is not None:
                try:
                    yield
                finally:
                    _unlock(fd)
                return
            how = "dask" if _in_dask_worker() else "none"  # auto, on a file system without locks
        if how == "none":
            yield
            return
        from distributed import Lock

        lk = Lock(f"usdface-cache-{kind}-{key}")
        lk.acquire(timeout=timeout)
        try:
            yield
        finally:
            with contextlib.suppress(Exception):  # a restarted scheduler forgot the lock: nothing to release
                lk.release()

    def _file_lock(self, kind: str, key: str, *, required: bool) -> int | None:
        """An exclusive flock on ROOT/locks/<kind>-<key>.lock (its fd), or None where the file
        system has no locks (unless ``required``)."""
        import fcntl

        locks = self.root / "locks"
        self._mkdir(locks)
        fd = os.open(locks / f"{kind}-{key}.lock", os.O_RDWR | os.O_CREAT, 0o666)
        try:
            while True:  # polled, so a stopped shot (Ctrl-C, a stop asked of a worker thread) stops waiting
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except BlockingIOError:
                    time.sleep(LOCK_POLL)
        except OSError as exc:
            os.close(fd)
            if required or exc.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL):
                raise
            return None
        except BaseException:
            os.close(fd)
            raise
        return fd

    # -- housekeeping ----------------------------------------------------------------------------

    def entries(self, kind: str | None = None) -> list[Path]:
        kinds = [kind] if kind else [p.name for p in self.root.iterdir() if p.is_dir() and p.name != "locks"]
        out = []
        for k in kinds:
            base = self.root / k
            if base.is_dir():
                out += sorted(p.parent for p in base.glob("??/*/meta.json"))
        return out

    def size(self) -> int:
        return sum(f.stat().st_size for f in self.root.rglob("*") if f.is_file())

    def tidy(self, *, max_age: float | None = None) -> list[str]:
        """Remove entries being written or discarded by processes that are dead (this host: no such
        process; other hosts: older than usdface.fileutil.TEMPORARY_MAX_AGE); returns their names."""
        max_age = TEMPORARY_MAX_AGE if max_age is None else max_age
        removed = []
        for kind_dir in (p for p in self.root.iterdir() if p.is_dir() and p.name != "locks"):
            for p in kind_dir.iterdir():
                if not p.name.startswith((".tmp-", ".trash-")):
                    continue
                try:
                    mtime = p.lstat().st_mtime
                except OSError:
                    continue
                dead = owner_is_dead(p.name, mtime)
                if dead or (dead is None and time.time() - mtime > max_age):
                    shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
                    removed.append(f"{kind_dir.name}/{p.name}")
        if removed:
            log.info("cache %s: removed %d entries left half-written by stopped processes", self.root, len(removed))
        return removed


def _unlock(fd: int) -> None:
    import fcntl

    try:
        fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


def _in_dask_worker() -> bool:
    try:
        from distributed import get_worker
    except ImportError:
        return False
    try:
        get_worker()
        return True
    except ValueError:
        return False


def _mb(n: int) -> str:
    return f"{n / 1e6:.1f} MB"
