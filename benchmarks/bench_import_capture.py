"""Benchmark: import of a Maya ASCII capture, against the least work any parser must do.

The issue asks that importing the 1590-frame AnimFace Jaw take be dominated by reading the file.
The baseline reads the same file and converts every key number (all ``setAttr ".ktv[a:b]"``
blocks) in one vectorised pass: one regex to cut out the key text, one ``numpy.fromstring``. The
ratio ``read_maya_ascii / baseline`` says how much the real reader (node graph, connections, time
grid, hierarchy, validation) costs on top; near 1 means the import is the file parse.

Run (from the repository root)::

    python benchmarks/bench_import_capture.py [file.ma] [--repeat N]

Times are the minimum and median over N runs in this process (the file stays in the page cache,
so "reading" is decoding and parsing, not disk). Nothing here gates CI.

Extension point: a later stage adds the USD write; time it with :func:`time_calls` on a function
taking the path, like :func:`usdface_parse`.
"""
from __future__ import annotations

import argparse
import os
import platform
import re
import statistics
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:  # the repository is not necessarily installed
    sys.path.insert(0, str(REPO))

from usdface.io.maya_ascii import read_maya_ascii  # noqa: E402

DEFAULT_TAKE = REPO.parent / "shared" / "data" / "animface" / "JawMoCap.ma"
_KEY_TEXT = re.compile(r'"\.ktv\[\d+:\d+\]"([^;]*);')


def baseline_parse(path) -> np.ndarray:
    """Read the file and convert all key numbers (times and values, interleaved) in one pass."""
    text = Path(path).read_bytes().decode("utf-8", errors="replace")
    return np.fromstring(" ".join(_KEY_TEXT.findall(text)), sep=" ")


def usdface_parse(path):
    """The import being measured: file -> Capture."""
    return read_maya_ascii(path)


def usdface_import_to_usdc(path):
    """The whole `usdface import-capture` job: file -> Capture -> .usdc capture layer on disk."""
    import tempfile

    from usdface.processors.import_capture import import_capture

    with tempfile.TemporaryDirectory() as tmp:
        import_capture(path, Path(tmp) / "capture.usdc")


def time_calls(function, path, repeat: int) -> list[float]:
    """Wall-clock seconds of ``repeat`` calls of ``function(path)`` (after one warm-up call)."""
    function(path)
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        function(path)
        times.append(time.perf_counter() - start)
    return times


def machine_description() -> str:
    cpu = platform.processor() or "unknown CPU"
    try:
        with open("/proc/cpuinfo") as handle:
            for line in handle:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return (f"{os.cpu_count()} logical CPUs ({cpu}); Python {platform.python_version()}, "
            f"numpy {np.__version__}, {platform.system()} {platform.release()}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("path", nargs="?", default=str(DEFAULT_TAKE), help="Maya ASCII take (default: AnimFace Jaw)")
    parser.add_argument("--repeat", type=int, default=7, help="timed runs per function (default 7)")
    args = parser.parse_args(argv)
    path = Path(args.path)
    if not path.is_file():
        print(f"{path}: not found", file=sys.stderr)
        return 2

    numbers = baseline_parse(path)
    capture = usdface_parse(path)
    print(f"machine: {machine_description()}")
    print(f"file: {path} ({path.stat().st_size / 1e6:.2f} MB), {numbers.size // 2} keys; capture "
          f"{capture.n_frames} frames x {capture.n_markers} markers at {capture.rate:g} Hz")
    results = {}
    for name, function in (("baseline (read + regex + np.fromstring)", baseline_parse),
                           ("read_maya_ascii", usdface_parse),
                           ("import-capture to .usdc (read + write)", usdface_import_to_usdc)):
        times = time_calls(function, path, args.repeat)
        results[name] = times
        print(f"  {name:42s} min {min(times) * 1e3:7.1f} ms   median {statistics.median(times) * 1e3:7.1f} ms"
              f"   ({args.repeat} runs)")
    base, ours, whole = results.values()
    print(f"ratio read_maya_ascii / baseline: {min(ours) / min(base):.2f} (min)   "
          f"{statistics.median(ours) / statistics.median(base):.2f} (median)")
    print(f"ratio import-capture to .usdc / baseline: {min(whole) / min(base):.2f} (min)   "
          f"{statistics.median(whole) / statistics.median(base):.2f} (median); "
          f"reading the file is {min(base) / min(whole):.0%} of the whole import")
    return 0


if __name__ == "__main__":
    sys.exit(main())
