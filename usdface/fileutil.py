"""File helpers shared by every writer: content digests and durable renames (no pxr here)."""
from __future__ import annotations

import hashlib
import os
from pathlib import Path


def file_digest(path: str | os.PathLike) -> str:
    """sha256 of a file's bytes (provenance, caches)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
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


def probe_writable_folder(path: str | os.PathLike, *, what: str) -> Path:
    """The folder of the output ``path``, checked to exist and to take a new file (a temporary file
    is created and removed: permission bits do not tell, root ignores them and read-only mounts
    refuse anyway). Raises InputError naming ``what`` ("movie", "report"...) and the folder."""
    import tempfile

    from .errors import InputError

    out = Path(path)
    folder = out.parent if str(out.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"cannot write {what} {out}: folder {folder} does not exist")
    if out.is_dir():
        raise InputError(f"cannot write {what} {out}: it is a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{out.stem}.probe-", dir=folder)
    except OSError as exc:
        raise InputError(f"cannot write {what} {out}: folder {folder}: {exc.strerror or exc}") from None
    os.close(fd)
    os.unlink(probe)
    return folder
