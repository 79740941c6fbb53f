"""Progress bars on a terminal, silence elsewhere (farm logs stay clean)."""
from __future__ import annotations

import logging
import sys


def progress(iterable=None, *, total=None, desc: str = "", unit: str = "it"):
    """tqdm on stderr when stderr is a terminal and logging is not quieted, else a plain iterator."""
    quiet = logging.getLogger("usdface").getEffectiveLevel() > logging.WARNING
    if quiet or not sys.stderr.isatty():
        return _Silent(iterable, total)
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, unit=unit, file=sys.stderr, leave=False, dynamic_ncols=True)


class _Silent:
    def __init__(self, iterable, total):
        self._it = iterable

    def __iter__(self):
        return iter(self._it)

    def update(self, n=1):
        pass

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False
