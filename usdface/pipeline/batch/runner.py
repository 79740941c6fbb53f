"""Run a manifest's shots: one after the other in this process, or with dask.distributed (an
in-process LocalCluster or a farm's scheduler: :mod:`.dask_run`); skip current ones (``--resume``);
write the batch summary and print its table.

Each shot is one Dask task that runs the same processors as the command line (``run``, then
``check`` if asked) through :func:`.shot.execute_shot`. A task never raises for a shot's own
failure: it returns the shot's record (status, timings, error), so one broken shot never stops the
others; a worker that dies is reported for the shots it was running. Workers compute with one BLAS
and one numba thread (one shot per core, and the same floating-point operation order on every
machine).
"""
from __future__ import annotations

import json
import logging
import sys
import time
from pathlib import Path

from ... import __version__
from ...errors import OptionError
from ...options import BatchOptions
from .cluster import probe_scheduler
from .manifest import Manifest, Shot
from .shot import execute_shot, shot_cost, shot_is_current, with_manifest_line  # noqa: F401 (shot_cost re-exported)

log = logging.getLogger("usdface")

# -- the batch ------------------------------------------------------------------------------------

def run_batch(manifest: Manifest, options: BatchOptions = BatchOptions(), *, summary_path: str | None = None) -> dict:
    """Run every shot; returns the batch summary (also written to the summary JSON file).

    ``options`` (:class:`usdface.options.BatchOptions`, the command's flags):

    workers : int, optional
        LocalCluster size (default: the manifest's, else the number of cores, at most the number
        of shots). 0 runs the shots one after the other in this process, without Dask.
    scheduler : str, optional
        ``tcp://HOST:PORT`` of a running Dask scheduler (a farm); its workers must see the
        manifest's paths (a shared file system) and have usdface installed.
    resume : bool
        Skip shots whose outputs are current (:func:`shot_is_current`).
    force : bool
        Redo every shot (overrides ``resume``).
    cache : str, False or None
        Cache folder; False for none; None for the manifest's (default ``.usdface-cache``).

    ``summary_path``: the batch summary file (default: the manifest's). A quiet logger (``-q``)
    prints no status lines.
    """
    workers, scheduler, resume, force, cache = (options.workers, options.scheduler, options.resume, options.force,
                                                options.cache)
    started = time.perf_counter()
    t0 = time.time()
    scheduler = scheduler or manifest.scheduler
    if scheduler:  # a wrong --scheduler fails now, within seconds, before any other work
        if not scheduler.startswith(("tcp://", "tls://", "ws://", "wss://", "inproc://", "ucx://")):
            raise OptionError(f"--scheduler {scheduler}: expected an address like tcp://HOST:8786")
        probe_scheduler(scheduler)
    cache_root = manifest.cache if cache is None else (None if cache is False else str(Path(cache).resolve()))
    if cache_root is not None:
        from ...cache import ContentCache

        ContentCache(cache_root).tidy()  # create it / fail early; remove dead writers' temporaries
    summary_path = Path(summary_path or manifest.summary)
    records: dict[str, dict] = {}
    todo: list[Shot] = []
    from ..shot_commit import tidy_unlocked_folder

    for shot in manifest.shots:
        # complete interrupted commits and remove dead runs' temporaries, skipped shots' too
        tidy_unlocked_folder(shot.output)
        if resume and not force:
            current, reason = shot_is_current(shot)
            if current:
                records[shot.name] = {"name": shot.name, "output": shot.output, "mesh": shot.mesh,
                                      "capture": shot.capture, "status": "skipped", "seconds": 0.0,
                                      "error": None, "reason": "outputs current (resume)", "cache": {}}
                continue
        todo.append(shot)
    for shot in todo:
        Path(shot.output).parent.mkdir(parents=True, exist_ok=True)

    info = {"mode": "serial", "workers": 0, "dashboard": None, "scheduler": None}
    status_out = _StatusPrinter(len(manifest.shots))
    for rec in records.values():
        status_out.done(rec)
    if todo:
        if workers == 0 and not scheduler:
            for shot in todo:
                status_out.start(shot)
                records[shot.name] = rec = with_manifest_line(execute_shot(shot, cache_root, resume and not force),
                                                              shot)
                status_out.done(rec)
        else:
            from .dask_run import run_on_dask

            run_on_dask(todo, cache_root, workers=workers if workers is not None else manifest.workers,
                        scheduler=scheduler, resume=resume and not force, records=records, info=info,
                        status_out=status_out)
    status_out.close()
    ordered = [records[s.name] for s in manifest.shots]
    counts = {k: sum(r["status"] == k for r in ordered) for k in ("ok", "skipped", "failed", "unsupported")}
    cache_counts = {}
    for r in ordered:
        for step, st in r.get("cache", {}).items():
            cache_counts.setdefault(step, {"hit": 0, "miss": 0})
            cache_counts[step][st] = cache_counts[step].get(st, 0) + 1
    summary = {
        "manifest": str(manifest.path), "usdfaceVersion": __version__,
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(t0)),
        "seconds": round(time.perf_counter() - started, 3), **info,
        "cache": {"folder": cache_root, "steps": cache_counts},
        "counts": counts, "shots": ordered, "summaryFile": str(summary_path),
    }
    _write_json(summary_path, summary)
    summary["_text"] = summary_table(summary)
    summary["_exit"] = 1 if counts["failed"] or counts["unsupported"] else 0
    return summary


class _StatusPrinter:
    """An overall progress bar (on a terminal) and one status line per finished shot on stderr."""

    def __init__(self, total: int):
        from ...progress import progress

        self.quiet = logging.getLogger("usdface").getEffectiveLevel() > logging.WARNING
        self.total = total
        self.finished = 0
        self.bar = progress(total=total, desc="shots", unit="shot")

    def _write(self, line: str) -> None:
        if self.quiet:
            return
        if hasattr(self.bar, "write"):
            self.bar.write(line, file=sys.stderr)
        else:
            print(line, file=sys.stderr, flush=True)

    def note(self, line: str) -> None:
        self._write(line)

    def start(self, shot) -> None:
        log.info("queued %s", shot.name)

    def done(self, rec: dict) -> None:
        self.finished += 1
        self.bar.update(1)
        secs = f"{rec['seconds']:.1f} s" if rec.get("seconds") else ""
        err = f"  {_error_line(rec)}" if rec.get("error") else ""
        self._write(f"[{self.finished}/{self.total}] {rec['status']:<11} {rec['name']} {secs}{err}")

    def close(self) -> None:
        self.bar.close()


def summary_table(summary: dict) -> list[str]:
    """The batch summary as terminal lines: one row per shot (with seconds per step), then totals."""
    rows = [("shot", "status", "seconds", "capture", "distances", "steps (s)", "error")]
    for r in summary["shots"]:
        c = r.get("cache", {})
        err = _error_line(r) if r.get("error") else (r.get("reason") or "").split("\n")[0]
        rows.append((r["name"], r["status"], f"{r['seconds']:.1f}" if r.get("seconds") is not None else "-",
                     c.get("import-capture", "-"), c.get("distances", "-"), step_times(r.get("steps")), err[:100]))
    widths = [max(len(row[i]) for row in rows) for i in range(6)]
    lines = ["  ".join(v.ljust(w) for v, w in zip(row[:6], widths)) + "  " + row[6] for row in rows]
    lines.insert(1, "  ".join("-" * w for w in widths) + "  -----")
    n = summary["counts"]
    cc = summary["cache"]["steps"]
    cache_txt = "; ".join(f"{k}: {v.get('hit', 0)} hit(s), {v.get('miss', 0)} computed" for k, v in cc.items())
    lines.append(f"{n['ok']} ok, {n['skipped']} skipped, {n['failed']} failed"
                 + (f", {n['unsupported']} unsupported" if n["unsupported"] else "")
                 + f" in {summary['seconds']:.1f} s ({scheduling_text(summary.get('mode'), summary.get('workers'))})"
                 + (f"; cache {cache_txt}" if cache_txt else ""))
    lines.append(f"summary: {summary['summaryFile']}")
    return lines


def scheduling_text(mode, workers) -> str:
    """How a batch ran, for a summary line: ``serial``, or ``local, 2 workers``."""
    if mode == "serial" or workers in (None, ""):
        return str(mode or "")
    return f"{mode}, {workers} worker{'' if workers == 1 else 's'}"


def _error_line(rec: dict) -> str:
    """A failed shot's first error line, after its manifest line: ``line 12: bind step failed: ...``."""
    first = rec["error"].splitlines()[0] if rec["error"].strip() else rec["error"]
    return f"line {rec['manifestLine']}: {first}" if rec.get("manifestLine") else first


def step_times(steps) -> str:
    """``{"import-mesh": 0.41, "transfer": 5.2}`` -> ``"import-mesh 0.4, transfer 5.2"`` ("-" if none)."""
    if not steps:
        return "-"
    return ", ".join(f"{k} {v:.1f}" for k, v in steps.items() if isinstance(v, (int, float)))


def _write_json(path: Path, data: dict) -> None:
    from ...fileutil import atomic_write, write_error

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise write_error(path, exc) from None
    with atomic_write(path) as f:
        f.write(json.dumps(data, indent=2, default=str) + "\n")
