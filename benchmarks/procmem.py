"""This process's memory, read from /proc (Linux), for the benchmarks: resident now, its peak, and
a reset of the peak mark so each measured step gets its own peak."""
from __future__ import annotations

import resource


def status_mb(key: str) -> float:
    """A /proc/self/status line in MB ("VmRSS" now, "VmHWM" the peak since start or the last
    :func:`reset_peak`); elsewhere than Linux, ru_maxrss (the peak, never reset)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def reset_peak() -> float:
    """Reset the peak-RSS mark (``clear_refs`` 5); returns the resident memory now, in MB."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    except OSError:
        pass
    return status_mb("VmRSS")
