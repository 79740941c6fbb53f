"""One shot of a batch, as a worker runs it: `run` and the batch steps the shot lists, through the
registry, in one process with one BLAS and one numba thread; and whether a shot's outputs are
current (``--resume``).

A task never raises for a shot's own failure: it returns the shot's record (status, timings,
error), so one broken shot never stops the others. A shot whose folder another process is writing
(the task of a killed batch, still running on its worker) waits for it, then (``--resume``) skips
the shot if that run completed it.
"""
from __future__ import annotations

import json
import os
import time
import traceback
from pathlib import Path

from ... import __version__, registry
from ...errors import LockedError, UsdFaceError
from ...options import RunOptions
from ..stopping import StopRequested, running_shot
from .manifest import Shot

# -- one shot (runs on a worker) ------------------------------------------------------------------

#: how long a shot waits for another process writing its folder (seconds): the task of a killed
#: batch still running on its worker, a worker that is closing; then it fails naming the holder
LOCK_WAIT = 600.0
#: how often a waiting shot looks at the folder's lock again (seconds)
LOCK_POLL = 0.25


def execute_shot(shot: Shot, cache_root: str | None, resume: bool = False) -> dict:
    """Run one shot in this process; returns its record (never raises for the shot's errors).

    When another process writes the shot's folder, the shot waits for it (at most
    :data:`LOCK_WAIT`); with ``resume``, a shot whose outputs are current by then is skipped. In a worker
    thread, a stop asked of the worker (SIGTERM, SIGHUP, a stopping batch) ends the shot after it
    has removed its partial work: status ``interrupted``."""
    started = time.perf_counter()
    rec = {"name": shot.name, "output": shot.output, "mesh": shot.mesh, "capture": shot.capture,
           "status": "failed", "seconds": None, "error": None, "steps": {}, "cache": {},
           "host": _worker_name()}
    try:
        with running_shot(shot.output):
            _execute_when_free(shot, cache_root, rec, started, resume)
    except StopRequested as exc:
        rec["status"] = "interrupted"
        rec["error"] = f"stopped by {exc} on {rec['host']}; partial work removed"
    rec["seconds"] = round(time.perf_counter() - started, 3)
    return rec


def _execute_when_free(shot: Shot, cache_root, rec: dict, started: float, resume: bool) -> None:
    """:func:`_execute` once no other process writes the shot's folder."""
    from ..shot_commit import folder_in_use

    deadline = time.monotonic() + LOCK_WAIT
    while True:
        waited = False
        while folder_in_use(shot.output) and time.monotonic() < deadline:
            waited = True
            time.sleep(LOCK_POLL)
        # another run of this shot may have completed it since the batch looked (a killed batch's task)
        if resume and shot_is_current(shot)[0]:
            rec.update(status="skipped", reason="outputs current (resume): completed by "
                       + ("the run that was writing them" if waited else "another run since the batch started"))
            return
        try:
            _execute(shot, cache_root, rec, started)
            return
        except LockedError as exc:  # taken again between our look and the run's
            if time.monotonic() >= deadline:
                rec.update(status="failed", error=f"{exc} (waited {LOCK_WAIT:g} s)")
                return


def _execute(shot: Shot, cache_root: str | None, rec: dict, started: float) -> None:
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
    except LockedError:
        raise  # another process writes the folder: the caller waits for it
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


def with_manifest_line(rec: dict, shot: Shot) -> dict:
    """A failed shot's record names the line of its ``[[shots]]`` entry in the manifest
    (``manifestLine``), which its status line and the summary table show."""
    if rec.get("status") in ("failed", "unsupported") and shot.line:
        rec["manifestLine"] = shot.line
    return rec


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
