"""Options of `usdface batch`: how a manifest's shots run (the shots' own options are `run`'s)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..errors import OptionError
from .fields import Options, option
from .values import boolean, path, shown


def workers_value(value, flag):
    from .values import number

    n = number(value, flag, kind=int, what="0 (serial, no Dask) or more workers")
    if n < 0:
        raise OptionError(f"{flag} {n}: expected 0 (serial, no Dask) or more")
    return n


def cache_value(value, flag):
    """A cache folder, or False for no cache."""
    if value is False:
        return False
    if isinstance(value, bool):
        raise OptionError(f"{flag} {shown(value)}: expected a folder, or false for no cache")
    return path(value, flag)


@dataclass(frozen=True)
class BatchOptions(Options):
    """How `usdface batch` runs a manifest (each overrides the manifest's [batch] table)."""

    workers: int | None = option(None, flag="--workers", coerce=workers_value, type=int, metavar="N",
                                 group="scheduling",
                                 help="local worker processes (default: the manifest's, else one per core); 0: one "
                                      "shot after the other in this process, without Dask")
    scheduler: str | None = option(None, flag="--scheduler", coerce=path, metavar="tcp://HOST:PORT",
                                   group="scheduling", help="run on this Dask scheduler's workers (a farm)")
    resume: bool = option(False, flag="--resume", coerce=boolean, group="scheduling",
                          help="skip shots whose outputs exist with matching provenance (inputs, options, version)")
    force: bool = option(False, flag="--force", coerce=boolean, group="scheduling",
                         help="redo every shot, even current ones")
    cache: Any = option(None, flag="--cache", coerce=cache_value, metavar="DIR", negate=("--no-cache", False), group="cache",
                        help="cache folder (default: the manifest's, else .usdface-cache)")
    out_root: str | None = option(None, flag="--out-root", coerce=path, metavar="DIR", group="paths",
                                  help="resolve relative outputs, cache and summary against DIR instead of the "
                                       "manifest's folder")
    report_only: bool = option(False, flag="--report-only", coerce=boolean, group="paths",
                               help="only write the HTML report of the finished batch from its summary (beside it, "
                                    "or --report FILE.html): no shot is run or checked")

    def validate(self) -> None:
        super().validate()
        if self.workers is not None and self.scheduler:
            raise OptionError("--workers sizes the local cluster; with --scheduler the farm's workers run the shots")
        if self.report_only:
            running = [flag for flag, given in (("--workers", self.workers is not None),
                                                ("--scheduler", self.scheduler is not None),
                                                ("--resume", self.resume), ("--force", self.force),
                                                ("--no-cache" if self.cache is False else "--cache",
                                                 self.cache is not None)) if given]
            if running:
                raise OptionError(f"--report-only writes the report of the finished batch from its summary and runs "
                                  f"no shot: leave out {', '.join(running)}")
