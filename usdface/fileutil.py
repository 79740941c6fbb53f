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


class StagedOutputs:
    """Write several output files so that either all of them appear or none does.

    Each output is written to a temporary name in its own folder (same suffix, so format-by-suffix
    writers such as USD work); :meth:`commit` renames them all into place, and leaving the
    ``with`` block on an error removes every temporary. A crash between two renames of
    :meth:`commit` can still leave a subset (renames are atomic one by one, not as a group).

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

    def path(self, final: str | os.PathLike) -> Path:
        import secrets

        p = Path(final)
        tmp = p.with_name(f".{p.stem}.tmp-{os.getpid()}-{secrets.token_hex(4)}{p.suffix}")
        self._pairs.append((tmp, p))
        return tmp

    def commit(self) -> None:
        mask = os.umask(0)
        os.umask(mask)
        for tmp, final in self._pairs:
            fsync_file(tmp)
            os.chmod(tmp, 0o666 & ~mask)  # temporaries may come out 0600
        for tmp, final in self._pairs:
            os.replace(tmp, final)
            fsync_dir(final.parent)
        self.committed = True

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
    """Write ``text`` to ``path`` through a temporary file in the same folder and one rename."""
    with StagedOutputs() as staged:
        staged.path(path).write_text(text)
        staged.commit()
    return Path(path)
