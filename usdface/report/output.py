"""Where a report goes: the ``.html`` page and its sibling media folder ``<report>_media/``, both
written atomically: the media folder is made under a temporary name and renamed into place when
complete, then the page (last: a page on disk always finds its movies)."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

from ..errors import OptionError
from ..fileutil import probe_writable_folder, temporary_path, write_text_atomic

__all__ = ["MediaFolder", "check_report_output", "media_name", "write_report"]


def check_report_output(output) -> Path:
    """``output`` as a Path, checked to be an ``.html`` file in a folder that takes new files
    (before any work: a batch checks its report before its shots run)."""
    out = Path(output)
    if out.suffix.lower() not in (".html", ".htm"):
        raise OptionError(f"-o {out}: a report is an .html file")
    probe_writable_folder(out, what="report")  # fails now, before any rendering
    return out


def media_name(out: Path) -> str:
    """The media folder of report ``out``: ``<stem>_media`` beside it."""
    return f"{out.stem}_media"


class MediaFolder:
    """A report's media folder under construction: a private temporary folder beside the final
    one (named for its owner, tidied if the owner dies), committed by :func:`write_report` or
    removed by :meth:`discard`. ``relative(name)`` is a file's link from the page."""

    def __init__(self, out: Path):
        self.final = out.parent / media_name(out)
        self.path = temporary_path(self.final)
        self.path.mkdir()

    def relative(self, name: str) -> str:
        return f"{self.final.name}/{name}"

    def commit(self) -> None:
        """Rename the finished folder over the final one (the old one, if any, is removed after)."""
        old = None
        if self.final.exists():
            old = temporary_path(self.final)  # the old folder, named for its owner until removed
            os.replace(self.final, old)
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(self.path, 0o777 & ~mask)  # a plain folder's permissions (a temporary one is private)
        try:
            os.replace(self.path, self.final)
        except BaseException:  # a failure or an interruption: the old media folder goes back
            if old is not None:
                os.replace(old, self.final)
            raise
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)

    def discard(self) -> None:
        shutil.rmtree(self.path, ignore_errors=True)


def write_report(page, out: Path, media: MediaFolder | None) -> None:
    """Render the page, move the finished media folder into place, then write the page."""
    text = page.render()
    if media is not None:
        media.commit()
    write_text_atomic(out, text)
