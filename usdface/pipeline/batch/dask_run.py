"""A batch's shots on Dask: handed out longest first, collected as they finish, handed out again
when their worker stopped them (SIGTERM: a farm draining a node) or when the scheduler went away
and came back (a restarted scheduler forgets every task); a batch that stops leaves no partial
work (:mod:`.cluster`).
"""
from __future__ import annotations

import logging
import os
import time
from concurrent.futures import CancelledError

from ...errors import EnvironmentFault
from . import cluster
from .manifest import Shot
from .shot import execute_shot, shot_cost, with_manifest_line

log = logging.getLogger("usdface")

#: times a shot stopped on its worker (a farm draining a node: SIGTERM) is handed out again
SHOT_ATTEMPTS = 3
#: how long a batch waits for a scheduler that went away to come back (seconds; a farm's
#: supervisor restarts it); the shots it had are then handed out again
SCHEDULER_WAIT = 120.0


def run_on_dask(todo: list, cache_root, *, workers, scheduler, resume: bool, records: dict, info: dict,
                status_out) -> None:
    """Run ``todo`` (shots, longest first) on a local cluster of ``workers`` processes or on the
    Dask ``scheduler``; their records go to ``records`` as they finish."""
    n = workers or min(os.cpu_count() or 1, len(todo))
    client, local, connected = cluster.connect(scheduler, max(1, min(n, len(todo))))
    info.update(connected)
    batch = _DaskBatch(client, local, scheduler, cache_root, resume, records, status_out)
    batch.unfinished = {shot.name: shot for shot in todo}
    try:
        batch.run(todo, info)
    except KeyboardInterrupt as exc:  # Ctrl-C, SIGTERM, SIGHUP: stop the shots, then say so
        from ..stopping import signals_deferred

        with signals_deferred():
            batch.stop(exc)
        raise
    except BaseException:
        batch.close()
        raise
    batch.close()


class _DaskBatch:
    """One batch's client, its shots in flight and their attempts."""

    def __init__(self, client, local, scheduler, cache_root, resume, records, status_out):
        self.client, self.local, self.scheduler = client, local, scheduler
        self.cache_root, self.resume = cache_root, resume
        self.records, self.status_out = records, status_out
        self.futures: dict = {}
        self.unfinished: dict = {}
        self.attempts: dict[str, int] = {}

    def run(self, todo: list, info: dict) -> None:
        info["workers"] = cluster.n_workers_of(self.client)
        info["dashboard"] = cluster.dashboard_of(self.client)
        self.status_out.note(f"dask: {info['mode']} scheduler {info['scheduler']}, {info['workers']} worker(s)"
                             + (f", dashboard {info['dashboard']}" if info["dashboard"] else
                                " (dashboard: pip install bokeh)"))
        if info["workers"] == 0:
            self.status_out.note("dask: the scheduler has no workers yet; shots wait until one connects")
        for shot in todo:
            self.status_out.start(shot)
        lost = list(todo)
        while lost:
            lost = self._round(lost)
            for shot, why in [(s, w) for s, w in lost if self.attempts[s.name] >= SHOT_ATTEMPTS]:
                self._finish(shot, _failed(shot, f"the Dask task was lost {SHOT_ATTEMPTS} times ({why})"))
            lost = [s for s, _ in lost if self.attempts[s.name] < SHOT_ATTEMPTS]
            if lost and not self._reconnected(len(lost)):
                for shot in lost:
                    self._finish(shot, _failed(shot, f"the Dask scheduler {self.scheduler or ''} went away during the "
                                                     f"batch and was not back within {SCHEDULER_WAIT:g} s "
                                                     "(usdface batch --resume runs the shots left)"))
                return

    def _submit(self, shot: Shot, priority: int):
        self.attempts[shot.name] = self.attempts.get(shot.name, 0) + 1
        key = f"usdface-shot-{shot.name}-{id(shot)}-{self.attempts[shot.name]}"
        fut = self.client.submit(execute_shot, shot, self.cache_root, self.resume, pure=False, retries=0,
                                 priority=priority, key=key)
        self.futures[fut] = shot
        return fut

    def _round(self, shots: list) -> list:
        """Hand out ``shots`` (longest first: LPT) and collect them; returns (shot, why) of those
        whose futures were lost with the scheduler (a shot done then runs again)."""
        from distributed import as_completed


        ordered = sorted(shots, key=shot_cost, reverse=True)
        pending = as_completed([self._submit(shot, len(ordered) - rank) for rank, shot in enumerate(ordered)],
                               loop=self.client.loop)
        lost = []
        for fut in pending:
            shot = self.futures.pop(fut)
            try:
                rec = fut.result()
            except (CancelledError, OSError) as exc:  # the scheduler went away: its tasks are forgotten
                lost.append((shot, f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"))
                continue
            except Exception as exc:  # noqa: BLE001 - KilledWorker, a worker out of memory...
                rec = _failed(shot, f"the Dask task failed: {type(exc).__name__}: {exc}")
            if rec["status"] == "interrupted" and self.attempts[shot.name] < SHOT_ATTEMPTS:
                log.info("%s: %s; handed out again", shot.name, rec["error"])
                pending.add(self._submit(shot, len(ordered)))
                continue
            if rec["status"] == "interrupted":
                rec["status"] = "failed"
            self._finish(shot, rec)
        return lost

    def _finish(self, shot: Shot, rec: dict) -> None:
        self.records[shot.name] = rec = with_manifest_line(rec, shot)
        self.unfinished.pop(shot.name, None)
        self.status_out.done(rec)

    def _reconnected(self, n_lost: int) -> bool:
        """Wait (at most SCHEDULER_WAIT) until the client talks to a scheduler again (Dask's own
        reconnection, else a new client); usdface's worker plugin registered again."""
        if not self.scheduler:
            return False
        self.status_out.note(f"dask: the scheduler {self.scheduler} went away; {n_lost} shot(s) are handed out again "
                             f"when it is back (waiting up to {SCHEDULER_WAIT:g} s)")
        deadline = time.monotonic() + SCHEDULER_WAIT
        while time.monotonic() < deadline:
            if self.client.status == "running":
                try:
                    cluster.register_stop_plugin(self.client, ignore_interrupt=False)
                    return True
                except (OSError, TimeoutError):
                    pass
            elif self.client.status in ("closed", "closing"):
                cluster.close(self.client, None)
                try:
                    self.client = cluster.connect(self.scheduler, 0)[0]
                    return True
                except (OSError, TimeoutError, EnvironmentFault):
                    pass
            time.sleep(0.5)
        return False

    def stop(self, exc: BaseException) -> None:
        outputs = [s.output for s in self.unfinished.values()]
        cluster.stop(self.client, self.futures, outputs, exc)
        self.close()

    def close(self) -> None:
        cluster.close(self.client, self.local)
        cluster.tidy_shot_folders([s.output for s in self.unfinished.values()])


def _failed(shot: Shot, error: str) -> dict:
    return {"name": shot.name, "output": shot.output, "mesh": shot.mesh, "capture": shot.capture,
            "status": "failed", "seconds": None, "cache": {}, "error": error}
