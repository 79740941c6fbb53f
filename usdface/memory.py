"""How much memory a piece of work needs, against what the machine has (no pxr, no cv2).

Work whose size the user sets (a resampling rate, a frame range) is estimated before it starts, so
an impossible request is refused with the estimate instead of dying in the middle with a
MemoryError.
"""
from __future__ import annotations

import os

from .errors import ResourceError
from .fileutil import format_bytes


def available_memory() -> int | None:
    """Bytes of memory available to this process now, or None when unknown.

    Reads ``MemAvailable`` from ``/proc/meminfo`` (Linux); falls back to
    ``os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")``.
    """
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(estimate: float, *, what: str, hint: str = "", memory_limit: int | None = None) -> int:
    """Raise :class:`ResourceError` when ``estimate`` bytes exceed the memory available.

    Parameters
    ----------
    estimate : float
        Bytes the work holds at its peak.
    what : str
        The work, for the message ("resampling to 1e+06 Hz: 26500001 frames x 41 markers").
    hint : str
        What to do instead, appended to the message.
    memory_limit : int, optional
        Bytes allowed (default: :func:`available_memory`); tests pass a small value.

    Returns
    -------
    int
        The estimate, in bytes.
    """
    estimate = int(estimate)
    limit = available_memory() if memory_limit is None else int(memory_limit)
    if limit is not None and estimate > limit:
        raise ResourceError(f"{what} needs about {format_bytes(estimate)} of memory but only {format_bytes(limit)} "
                            f"{'is available' if memory_limit is None else 'is allowed'}" + (f"; {hint}" if hint else ""))
    return estimate
