"""Numba's on-disk cache for usdface's kernels: a writable home wherever usdface is installed, and
a one-line notice while a kernel compiles.

Numba caches a compiled kernel next to its source (``__pycache__``), or in numba's user cache
folder when the package folder is read-only (a system-wide or container install). When both are
read-only (a service account without a home, ``HOME=/``), ``@njit(cache=True)`` would raise at
import; :func:`configure` then points numba at a usdface cache folder that is writable
(``$XDG_CACHE_HOME/usdface/numba``, ``~/.cache/usdface/numba``, or
``<tmp>/usdface-numba-<uid>``) and exports it as ``NUMBA_CACHE_DIR`` so worker processes
(``usdface batch``) reuse the same compiled code. ``NUMBA_CACHE_DIR`` set by the user always wins.

A first run compiles the kernels it calls (the geodesic search, the tracker, the tissue model, the
renderer, the blend-shape solver: seconds each); every compile of a usdface kernel is announced on
stderr as it starts (once per group) and :func:`compile_report` gives the measured total after,
instead of leaving the terminal silent or guessing.
"""
from __future__ import annotations

import logging
import os
import sys
import tempfile
import time
from pathlib import Path

__all__ = ["AVAILABLE", "CACHE", "cache_dir", "compile_report", "configure", "is_cached", "njit", "notice_compiling",
           "reset_compile_report"]

_PACKAGE = Path(__file__).resolve().parent
_configured: dict = {}
_noticed: set = set()


def _writable(path: Path) -> bool:
    """Whether ``path`` exists (or can be created) and accepts a new file."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
        return True
    except OSError:
        return False


def _numba_user_cache() -> Path | None:
    try:
        from numba.misc.appdirs import AppDirs
    except ImportError:  # pragma: no cover - numba moved it
        return None
    return Path(AppDirs(appname="numba", appauthor=False).user_cache_dir)


def _fallbacks() -> list[Path]:
    out = []
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg:
        out.append(Path(xdg) / "usdface" / "numba")
    home = os.path.expanduser("~")
    if home and home != "~":
        out.append(Path(home) / ".cache" / "usdface" / "numba")
    uid = os.getuid() if hasattr(os, "getuid") else os.getpid()
    out.append(Path(tempfile.gettempdir()) / f"usdface-numba-{uid}")
    return out


def configure() -> bool:
    """Make sure numba can cache usdface's kernels; call before any ``@njit(cache=...)`` kernel.

    Returns
    -------
    bool
        True when kernels can be cached on disk (pass it as ``cache=``); False when no folder is
        writable at all (kernels then compile in every process).
    """
    if "cache" in _configured:
        return _configured["cache"]
    ok = True
    if not os.environ.get("NUMBA_CACHE_DIR"):
        # numba's own order: next to the source, then its user cache folder
        user = _numba_user_cache()
        if not (_writable(_PACKAGE / "distance" / "__pycache__") or (user is not None and _writable(user))):
            ok = False
            for path in _fallbacks():
                if _writable(path):
                    os.environ["NUMBA_CACHE_DIR"] = str(path)
                    try:
                        from numba.core import config
                        config.CACHE_DIR = str(path)
                    except ImportError:  # pragma: no cover
                        pass
                    ok = True
                    break
    _configured["cache"] = ok
    return ok


def cache_dir(dispatcher) -> str | None:
    """The folder a numba kernel is cached in (None when not cached)."""
    cache = getattr(dispatcher, "_cache", None)
    return getattr(cache, "_cache_path", None)


def is_cached(dispatcher) -> bool | None:
    """Whether calling ``dispatcher`` will load compiled code (in memory or from the disk cache)
    rather than compile: True, False, or None when numba's internals do not tell."""
    try:
        if dispatcher.overloads:
            return True
        cache = dispatcher._cache
        index = cache._cache_file._load_index()      # {} when absent or stale (source changed)
        magic = dispatcher.targetctx.codegen().magic_tuple()
        return any(key[1] == magic for key in index)
    except Exception:  # noqa: BLE001 - private numba API: no notice rather than a failure
        return None


def notice_compiling(what: str, *dispatchers) -> bool:
    """Print one line on stderr when ``dispatchers`` are about to compile (first run only).

    Silent when usdface's logger is quieted (``-q``), when the kernels are cached, and after the
    first notice for ``what`` in this process. Returns whether the notice was printed.
    """
    if what in _noticed:
        return False
    if logging.getLogger("usdface").getEffectiveLevel() > logging.WARNING:
        return False
    if not any(is_cached(d) is False for d in dispatchers):
        return False
    _noticed.add(what)
    where = cache_dir(dispatchers[0])
    tail = f"; cached in {where} for later runs" if where else ""
    print(f"usdface: compiling {what} (first run only){tail}", file=sys.stderr, flush=True)
    return True


#: how a first run names the kernels it compiles, by module
KERNEL_GROUPS = {"usdface.distance": "the geodesic search kernels", "usdface.preview": "the preview renderer's kernels",
                 "usdface.tracking": "the tracker's kernels", "usdface.tissue": "the tissue model's kernels",
                 "usdface.blendshape": "the blend-shape solver's kernels"}
_compiled = {"kernels": 0, "seconds": 0.0, "depth": 0, "started": 0.0, "groups": []}


def _group(module: str) -> str | None:
    return next((what for prefix, what in KERNEL_GROUPS.items() if module.startswith(prefix)),
                "usdface's kernels" if module.startswith("usdface") else None)


def _listen_to_compiles() -> None:
    """Every compile of a usdface kernel (numba's "numba:compile" event: a cache miss, never a cache
    load) is announced once per group (:func:`notice_compiling`) and timed; :func:`compile_report`
    says the total afterwards."""
    from numba.core import event

    class Listener(event.Listener):
        def on_start(self, ev):
            what = _group(getattr(ev.data["dispatcher"].py_func, "__module__", "") or "")
            if what is None:
                return
            if _compiled["depth"] == 0:
                _compiled["started"] = time.perf_counter()
            _compiled["depth"] += 1
            if what not in _compiled["groups"]:
                _compiled["groups"].append(what)
                _announce(what, ev.data["dispatcher"])

        def on_end(self, ev):
            if _group(getattr(ev.data["dispatcher"].py_func, "__module__", "") or "") is None:
                return
            _compiled["depth"] -= 1
            _compiled["kernels"] += 1
            if _compiled["depth"] == 0:  # a kernel calling another compiles both: time the outer once
                _compiled["seconds"] += time.perf_counter() - _compiled["started"]

    event.register("numba:compile", Listener())


def _announce(what: str, dispatcher) -> None:
    if what in _noticed or logging.getLogger("usdface").getEffectiveLevel() > logging.WARNING:
        return
    _noticed.add(what)
    where = cache_dir(dispatcher)
    tail = f"; cached in {where} for later runs" if where else ""
    print(f"usdface: compiling {what} (first run only){tail}", file=sys.stderr, flush=True)


def reset_compile_report() -> None:
    """Start counting compiles afresh (each ``usdface`` command reports its own)."""
    _compiled.update(kernels=0, seconds=0.0, groups=[])


def compile_report() -> str | None:
    """The measured time of the kernels compiled in this process so far, as a line for the user
    (None when nothing compiled: every kernel came from the cache)."""
    if not _compiled["kernels"]:
        return None
    n = _compiled["kernels"]
    return (f"usdface: compiled {n} kernel{'s' if n > 1 else ''} ({', '.join(_compiled['groups'])}) in "
            f"{_compiled['seconds']:.1f} s, first run only: later runs load them from the cache")


#: ``cache=`` for usdface's numba kernels (see :func:`configure`)
CACHE = configure()

try:  # numba is a dependency; without it the kernels' callers run their numpy paths
    import numba as _numba
    AVAILABLE = True
    _listen_to_compiles()
except ImportError:  # pragma: no cover - exercised only without numba
    _numba = None
    AVAILABLE = False


def njit(*args, **kwargs):
    """``numba.njit`` for usdface's kernels: ``cache=True`` caches on disk only where
    :func:`configure` found a writable folder (a read-only install compiles in memory instead of
    failing at import). Without numba it returns the Python function unchanged (check
    :data:`AVAILABLE` to choose a numpy path)."""
    if _numba is None:
        def keep(f):
            return f
        return keep(args[0]) if args and callable(args[0]) else keep
    if kwargs.get("cache"):
        kwargs["cache"] = CACHE
    return _numba.njit(*args, **kwargs)
