"""Run a manifest's shots with dask.distributed: an in-process LocalCluster or a farm's scheduler.

Each shot is one Dask task that runs the same processors as the command line (``run``, then
``check`` if asked) through :func:`execute_shot`. A task never raises for a shot's own failure: it
returns the shot's record (status, timings, error), so one broken shot never stops the others; a
worker that dies is reported for the shots it was running. Workers compute with one BLAS and one
numba thread (one shot per core, and the same floating-point operation order on every machine).
"""
from __future__ import annotations

import json
import logging
import os
import sys
import time
import traceback
from pathlib import Path

from ... import __version__, registry
from ...errors import EnvironmentFault, OptionError, UsdFaceError
from ...options import BatchOptions, RunOptions
from .manifest import Manifest, Shot

log = logging.getLogger("usdface")

#: how long a client waits for a scheduler's TCP connection (seconds)
CONNECT_TIMEOUT = 3.0
#: the whole check that --scheduler is a Dask scheduler (connect, handshake, identity) stops after
#: this many seconds, so a wrong address fails within 10 s of starting the command
PROBE_TIMEOUT = 4.0
#: how long the client then waits for the scheduler it probed (seconds)
CLIENT_TIMEOUT = 10.0
#: thread variables fixed in every worker (before numpy loads where we start the process)
THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
              "NUMBA_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1", "NUMEXPR_NUM_THREADS": "1"}


# -- one shot (runs on a worker) ------------------------------------------------------------------

def execute_shot(shot: Shot, cache_root: str | None) -> dict:
    """Run one shot in this process; returns its record (never raises for the shot's errors)."""
    started = time.perf_counter()
    rec = {"name": shot.name, "output": shot.output, "mesh": shot.mesh, "capture": shot.capture,
           "status": "failed", "seconds": None, "error": None, "steps": {}, "cache": {},
           "host": _worker_name()}
    try:
        with single_threaded():
            cache = None
            if cache_root is not None:
                from ...cache import ContentCache

                cache = ContentCache(cache_root)
            capture = shot.capture  # `run` tracks and lifts video captures itself
            with registry.timed_calls() as clock:
                summary = registry.call("run", shot.mesh, capture, options=RunOptions.from_mapping(shot.options),
                                        output=shot.output, cache=cache).summary
            rec["steps"] = {k: clock.get(k, v.get("seconds")) for k, v in summary["steps"].items()}
            rec["steps"]["other"] = round(max(0.0, time.perf_counter() - started - sum(
                x for x in rec["steps"].values() if isinstance(x, (int, float)))), 3)
            rec["frames"] = summary["frames"]
            rec["vertices"] = summary["vertices"]
            rec["cache"] = {k: v["cache"]["status"] for k, v in summary["steps"].items() if "cache" in v}
            for step in shot.processors:
                if step not in ("run", "track"):
                    _run_batch_step(step, shot, rec)
            rec["status"] = "ok"
    except UsdFaceError as exc:
        rec["error"] = str(exc)
        rec["status"] = "unsupported" if getattr(exc, "unsupported", False) else "failed"
    except Exception as exc:  # noqa: BLE001 - a bug or a library error must not stop the batch
        from ...fileutil import describe_exception, is_environment_fault

        # file system, memory and USD errors: one line naming the file and the cause; a bug keeps
        # its traceback in the summary for the report
        rec["error"] = describe_exception(exc)
        if not is_environment_fault(exc):
            rec["traceback"] = traceback.format_exc(limit=8)
    rec["seconds"] = round(time.perf_counter() - started, 3)
    return rec


def _run_batch_step(step: str, shot: Shot, rec: dict) -> None:
    """A batch step a shot lists (``check``, a studio's processor): on the shot's stage, with its
    default options; a non-zero exit code fails the shot."""
    result = registry.call(step, str(Path(shot.output) / "shot.usda"))
    findings = result.legacy if isinstance(result.legacy, list) else None  # a validator's findings
    if findings is not None:
        errors = [str(f) for f in findings if f.severity == "error"]
        rec[step] = {"errors": len(errors), "findings": len(findings)}
        if errors:
            raise UsdFaceError(f"usdface {step} found {len(errors)} error(s) in shot.usda: {errors[0]}")
        return
    rec[step] = {"exitCode": result.exit_code}
    if result.exit_code:
        first = next((line for line in result.text if line.strip()), "")
        raise UsdFaceError(f"usdface {step} exited {result.exit_code} on shot.usda: {first}")


class single_threaded:
    """One BLAS/OpenMP thread (threadpoolctl) and one numba thread while a shot runs."""

    def __enter__(self):
        from threadpoolctl import threadpool_limits

        self._limits = threadpool_limits(limits=1)
        self._numba = None
        try:
            import numba

            self._numba = numba.get_num_threads()
            numba.set_num_threads(1)
        except (ImportError, ValueError):
            pass
        return self

    def __exit__(self, *exc):
        self._limits.restore_original_limits()
        if self._numba is not None:
            import numba

            numba.set_num_threads(self._numba)
        return False


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return "local"


# -- resume ---------------------------------------------------------------------------------------

def shot_is_current(shot: Shot) -> tuple[bool, str]:
    """Whether OUTDIR holds this shot's outputs with matching provenance; (answer, reason).

    Checks: every output file exists; summary.json's run provenance equals this shot's (usdface
    version, the algorithms' revisions (:mod:`usdface.revisions`: a shot made by an older revision
    is stale), options, input names and sha256); and each layer's provenance names the usdface
    version, its processor's current revision and inputs whose sha256 equal the files in OUTDIR
    (the chain was not edited since).
    """
    from ...revisions import revision
    from ...usd.shot_record import read_shot_record, verify_shot
    from ..run import output_files, run_provenance

    out = Path(shot.output)
    opts = RunOptions.from_mapping(shot.options)
    try:
        summary = json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        summary = None
    files = summary.get("files") if isinstance(summary, dict) and summary.get("files") else \
        output_files(opts.output_kind, video=shot.is_video, options=opts)
    missing = [f for f in files if not (out / f).is_file()]
    if missing:
        return False, f"missing {', '.join(missing)}"
    if summary is None:
        return False, "summary.json unreadable"
    problems = verify_shot(out / "shot.usda")
    if problems:
        return False, f"mixed or incomplete shot: {problems[0]}"
    recorded = read_shot_record(out / "shot.usda") is not None
    capture = shot.capture
    if not Path(capture).is_file():
        return False, "capture missing"
    expected = run_provenance(shot.mesh, capture, opts)
    if summary.get("provenance") != expected:
        old = summary.get("provenance") or {}
        what = [k for k in ("usdfaceVersion", "revisions", "options", "inputs") if old.get(k) != expected.get(k)]
        return False, f"provenance differs ({', '.join(what) or 'absent'})"
    if recorded:  # every file is the one committed with the shot, and a commit holds one run's files
        return True, "outputs current"
    from ...usd.layers import file_digest

    digests = {}
    for name in [f for f in files if f.endswith((".usdc", ".usda")) and not f.startswith("shot")]:
        prov = _layer_provenance(out / name)
        if prov is None or prov.get("usdfaceVersion") != __version__:
            return False, f"{name}: provenance absent or from another usdface version"
        made_by, now = int(prov.get("revision", 1)), revision(str(prov.get("processor")))
        if made_by != now:
            return False, f"{name}: made by revision {made_by} of {prov.get('processor')}, now {now}"
        for role, rec in json.loads(prov.get("inputs", "{}")).items():
            f = out / rec["file"]
            if f.name in files:
                if f.name not in digests:
                    digests[f.name] = file_digest(f)
                if digests[f.name] != rec["sha256"]:
                    return False, f"{name}: its input {f.name} changed since it was written"
    return True, "outputs current"


def _layer_provenance(path: Path) -> dict | None:
    from ...usd.layers import layer_provenance

    return layer_provenance(path)


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
                records[shot.name] = rec = execute_shot(shot, cache_root)
                status_out.done(rec)
        else:
            _run_dask(todo, cache_root, workers if workers is not None else manifest.workers, scheduler,
                      records, info, status_out)
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


def _run_dask(todo, cache_root, workers, scheduler, records, info, status_out) -> None:
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise OptionError("usdface batch needs dask.distributed: pip install \"dask[distributed]\"") from None
    import dask

    # Dask logs at INFO to the root logger; keep its chatter out unless usdface is verbose
    level = logging.getLogger("usdface").getEffectiveLevel()
    for name in ("distributed", "bokeh", "tornado"):
        logging.getLogger(name).setLevel(max(level, logging.WARNING) if level > logging.DEBUG else logging.INFO)
    cluster = None
    if scheduler:  # run_batch checked it is a Dask scheduler (probe_scheduler)
        try:
            with dask.config.set({"distributed.comm.timeouts.connect": f"{CLIENT_TIMEOUT}s"}):
                client = Client(scheduler, timeout=f"{CLIENT_TIMEOUT}s", set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise EnvironmentFault(f"--scheduler {scheduler}: the Dask scheduler stopped answering within "
                                   f"{CLIENT_TIMEOUT:g} s ({type(exc).__name__})") from None
        info.update(mode="scheduler", scheduler=scheduler)
    else:
        n = workers or min(os.cpu_count() or 1, len(todo))
        n = max(1, min(n, len(todo)))
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                               env=dict(THREAD_ENV), silence_logs=logging.ERROR)
        client = Client(cluster, set_as_default=False)
        info.update(mode="local", scheduler=cluster.scheduler_address)
    try:
        info["workers"] = len(client.scheduler_info(n_workers=-1).get("workers", {})) \
            if _takes_n_workers(client) else len(client.scheduler_info().get("workers", {}))
        info["dashboard"] = _dashboard(client)
        status_out.note(f"dask: {info['mode']} scheduler {info['scheduler']}, {info['workers']} worker(s)"
                        + (f", dashboard {info['dashboard']}" if info["dashboard"] else
                           " (dashboard: pip install bokeh)"))
        if info["workers"] == 0:
            status_out.note("dask: the scheduler has no workers yet; shots wait until one connects")
        futures = {}
        # longest first (LPT): a big character's takes submitted last would run one after the other
        # at the end while the other workers sit idle; records stay in manifest order
        for rank, shot in enumerate(sorted(todo, key=shot_cost, reverse=True)):
            fut = client.submit(execute_shot, shot, cache_root, key=f"usdface-shot-{shot.name}-{id(shot)}",
                                pure=False, retries=0, priority=len(todo) - rank)
            futures[fut] = shot
            status_out.start(shot)
        for fut in as_completed(list(futures), loop=client.loop):
            shot = futures[fut]
            try:
                rec = fut.result()
            except Exception as exc:  # noqa: BLE001 - KilledWorker, a worker out of memory...
                rec = {"name": shot.name, "output": shot.output, "mesh": shot.mesh, "capture": shot.capture,
                       "status": "failed", "seconds": None, "cache": {},
                       "error": f"the Dask task failed: {type(exc).__name__}: {exc}"}
            records[shot.name] = rec
            status_out.done(rec)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def shot_cost(shot: Shot) -> float:
    """A relative estimate of a shot's run time, to hand out the longest shots first.

    Writing the time-sampled points dominates a shot: its cost grows with vertices x frames. The
    mesh file's size stands for the vertex count and the trimmed frame count (or the capture
    file's size) for the frames; only the order matters.
    """
    def size(path) -> float:
        try:
            return float(os.path.getsize(path))
        except (OSError, TypeError):
            return 1.0

    trim = shot.options.get("trim")
    frames = float(trim[1] - trim[0]) if isinstance(trim, (list, tuple)) and len(trim) == 2 else size(shot.capture)
    return size(shot.mesh) * max(frames, 1.0)


def probe_scheduler(address: str, *, timeout: float = PROBE_TIMEOUT) -> dict:
    """Check that ``address`` is a Dask scheduler within ``timeout`` seconds; returns its identity.

    A TCP connection first (a port where nothing listens fails at once), then Dask's handshake and
    an identity request under one deadline: a server speaking another protocol (HTTP: the
    dashboard's port 8787, SSH, ...) or one that never answers fails with a clear
    :class:`~usdface.errors.EnvironmentFault` instead of hanging.
    """
    import asyncio
    import socket

    from distributed.comm import connect
    from distributed.comm.addressing import parse_address, parse_host_port

    hint = (f"start one with `dask scheduler` (it listens on 8786 by default; 8787 is its dashboard) and workers "
            f"with `dask worker {address}`, or leave out --scheduler to run on this machine")
    started = time.monotonic()
    scheme, loc = parse_address(address)
    if scheme in ("tcp", "tls"):
        try:
            host, port = parse_host_port(loc)
            socket.create_connection((host, port), timeout=min(CONNECT_TIMEOUT, timeout)).close()
        except (OSError, ValueError, TypeError) as exc:
            why = getattr(exc, "strerror", None) or ("timed out" if isinstance(exc, TimeoutError) else str(exc))
            raise EnvironmentFault(f"--scheduler {address}: nothing listens there ({why}); {hint}") from None

    async def identity():
        comm = await connect(address, timeout=max(0.5, timeout - (time.monotonic() - started)))
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    not_dask = f"--scheduler {address}: the server there does not answer as a Dask scheduler"
    try:
        answer = asyncio.run(asyncio.wait_for(identity(), max(0.5, timeout - (time.monotonic() - started))))
    except (asyncio.TimeoutError, TimeoutError):
        raise EnvironmentFault(f"{not_dask} within {timeout:g} s (a web server, such as the dashboard on 8787, or "
                               f"another service); {hint}") from None
    except Exception:  # noqa: BLE001 - closed connection, garbage frames: not Dask's protocol
        raise EnvironmentFault(f"{not_dask} (it closed the connection or replied in another protocol); "
                               f"{hint}") from None
    if not isinstance(answer, dict) or answer.get("type") != "Scheduler":
        kind = answer.get("type") if isinstance(answer, dict) else type(answer).__name__
        raise EnvironmentFault(f"--scheduler {address}: the server is a Dask {kind}, not a scheduler; {hint}")
    return answer


def _takes_n_workers(client) -> bool:
    import inspect

    return "n_workers" in inspect.signature(client.scheduler_info).parameters


def _dashboard(client) -> str | None:
    try:
        services = client.scheduler_info().get("services", {})
        if "dashboard" not in services:
            return None
        return client.dashboard_link
    except Exception:  # noqa: BLE001
        return None


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
        err = f"  {rec['error'].splitlines()[0]}" if rec.get("error") else ""
        self._write(f"[{self.finished}/{self.total}] {rec['status']:<11} {rec['name']} {secs}{err}")

    def close(self) -> None:
        self.bar.close()


def summary_table(summary: dict) -> list[str]:
    """The batch summary as terminal lines: one row per shot (with seconds per step), then totals."""
    rows = [("shot", "status", "seconds", "capture", "distances", "steps (s)", "error")]
    for r in summary["shots"]:
        c = r.get("cache", {})
        err = (r.get("error") or r.get("reason") or "").splitlines()
        rows.append((r["name"], r["status"], f"{r['seconds']:.1f}" if r.get("seconds") is not None else "-",
                     c.get("import-capture", "-"), c.get("distances", "-"), step_times(r.get("steps")),
                     (err[0] if err else "")[:100]))
    widths = [max(len(row[i]) for row in rows) for i in range(6)]
    lines = ["  ".join(v.ljust(w) for v, w in zip(row[:6], widths)) + "  " + row[6] for row in rows]
    lines.insert(1, "  ".join("-" * w for w in widths) + "  -----")
    n = summary["counts"]
    cc = summary["cache"]["steps"]
    cache_txt = "; ".join(f"{k}: {v.get('hit', 0)} hit(s), {v.get('miss', 0)} computed" for k, v in cc.items())
    lines.append(f"{n['ok']} ok, {n['skipped']} skipped, {n['failed']} failed"
                 + (f", {n['unsupported']} unsupported" if n["unsupported"] else "")
                 + f" in {summary['seconds']:.1f} s ({summary['mode']}, {summary['workers']} worker(s))"
                 + (f"; cache {cache_txt}" if cache_txt else ""))
    lines.append(f"summary: {summary['summaryFile']}")
    return lines


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
