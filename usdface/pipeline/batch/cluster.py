"""A batch's shots on Dask: an in-process local cluster or a farm's scheduler; and a batch that
stops (Ctrl-C, SIGTERM, SIGHUP) leaving no partial work behind.

Stopping: the terminal sends Ctrl-C (and SIGHUP when it closes) to every process of its
foreground group, the local cluster's workers included. Those are spawned while the command
ignores both (a process keeps a signal ignored at its start ignored), so only the command reacts,
with one line: it cancels the shots not started, asks the workers to stop the running ones
(:func:`usdface.pipeline.stopping.stop_shots`: each removes its partial work), closes the cluster,
then tidies every shot folder that had not finished, as the next run would (a commit cut short is
completed, a dead worker's work folder and a lock nobody holds removed). Workers stopped by
SIGTERM or SIGHUP themselves (a farm draining a node) stop their shots the same way
(:func:`usdface.pipeline.stopping.install_worker_handlers`, installed by
:class:`~usdface.pipeline.batch.worker_plugin.StopPlugin`).
"""
from __future__ import annotations

import contextlib
import logging
import signal
import time

from ...errors import EnvironmentFault, Interrupted, OptionError, stop_signals
from ..stopping import STOP_WAIT, signals_deferred, stop_shots

log = logging.getLogger("usdface")

#: how long a client waits for a scheduler's TCP connection (seconds)
CONNECT_TIMEOUT = 3.0
#: the whole check that --scheduler is a Dask scheduler (connect, handshake, identity) stops after
#: this many seconds, so a wrong address fails within 10 s of starting the command
PROBE_TIMEOUT = 4.0
#: how long the client then waits for the scheduler it probed (seconds)
CLIENT_TIMEOUT = 10.0
#: how long a batch waits for its workers to confirm usdface's worker plugin (seconds)
PLUGIN_WAIT = 10.0
#: how long the local cluster's workers may take to start (seconds; a loaded machine is slow)
WORKER_START_TIMEOUT = 120.0
#: thread variables fixed in every worker (before numpy loads where we start the process)
THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
              "NUMBA_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1", "NUMEXPR_NUM_THREADS": "1"}
#: Dask's loggers with a level of their own (distributed.config sets each)
_DASK_LOGGERS = ("distributed", "distributed.client", "distributed.gc", "bokeh", "tornado", "tornado.application")


def _import_distributed():
    try:
        import distributed
    except ImportError:
        raise OptionError("usdface batch needs dask.distributed: pip install \"dask[distributed]\"") from None
    return distributed


def quiet_dask_logs() -> None:
    """Dask logs at INFO to the root logger; keep its chatter out unless usdface is verbose: its
    errors only by default (what a shot suffers is in the shot's record), warnings with ``-v``,
    everything with ``-vv``. Tornado's errors are Dask's internal callbacks (one fails when a Ctrl-C
    cuts a cluster's start short): with ``-v`` only."""
    level = logging.getLogger("usdface").getEffectiveLevel()
    for name in _DASK_LOGGERS:
        if level <= logging.DEBUG:
            shown = logging.INFO
        elif level <= logging.INFO:
            shown = logging.WARNING
        else:
            shown = logging.CRITICAL + 1 if name.startswith("tornado") else logging.ERROR
        logging.getLogger(name).setLevel(shown)


@contextlib.contextmanager
def _dask_silenced():
    """No Dask log lines while a stopping batch closes its cluster (workers it killed, closed
    connections): the command's one line says what happened."""
    loggers = [logging.getLogger(n) for n in _DASK_LOGGERS]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


def _start_local_cluster(distributed, n_workers: int):
    """A local cluster of ``n_workers`` processes that ignore SIGINT and SIGHUP from their start
    (the command stops them): the command ignores both only while the processes are spawned (a
    Ctrl-C then is lost; a fraction of a second), not while they start up."""
    import multiprocessing

    verbose = logging.getLogger("usdface").getEffectiveLevel() <= logging.INFO
    # the workers print to the command's stderr: errors with -v only (a worker cut off by a stop
    # logs its lost heartbeat; what a shot suffers is in the shot's record)
    cluster = distributed.LocalCluster(n_workers=0, threads_per_worker=1, processes=True, dashboard_address=":0",
                                       env=dict(THREAD_ENV),
                                       silence_logs=logging.ERROR if verbose else logging.CRITICAL + 1)
    try:
        before = {p.pid for p in multiprocessing.active_children()}
        previous = {}
        try:
            with contextlib.suppress(ValueError):  # not the main thread: the workers take the defaults
                for s in stop_signals():
                    if s != signal.SIGTERM:
                        previous[s] = signal.signal(s, signal.SIG_IGN)
            cluster.scale(n_workers)
            deadline = time.monotonic() + CLIENT_TIMEOUT
            # a Process has its pid once its program has started (spawn: fork and exec)
            while (len({p.pid for p in multiprocessing.active_children() if p.pid} - before) < n_workers
                   and time.monotonic() < deadline):
                time.sleep(0.005)
        finally:
            for s, handler in previous.items():
                signal.signal(s, handler)
        try:
            cluster.wait_for_workers(n_workers, timeout=WORKER_START_TIMEOUT)
        except (TimeoutError, OSError) as exc:
            raise EnvironmentFault(f"the local Dask cluster's {n_workers} worker(s) did not start within "
                                   f"{WORKER_START_TIMEOUT:g} s ({type(exc).__name__}: {exc})") from None
    except BaseException:
        with _dask_silenced():
            cluster.close()
        raise
    return cluster


def connect(scheduler: str | None, n_workers: int):
    """(client, local cluster or None, info): a client of ``scheduler`` (checked by
    :func:`probe_scheduler` before) or of a new local cluster of ``n_workers`` processes; every
    worker gets usdface's stop handlers."""
    distributed = _import_distributed()
    import dask

    quiet_dask_logs()
    cluster = None
    if scheduler:
        try:
            with dask.config.set({"distributed.comm.timeouts.connect": f"{CLIENT_TIMEOUT}s"}):
                client = distributed.Client(scheduler, timeout=f"{CLIENT_TIMEOUT}s", set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise EnvironmentFault(f"--scheduler {scheduler}: the Dask scheduler stopped answering within "
                                   f"{CLIENT_TIMEOUT:g} s ({type(exc).__name__})") from None
        info = {"mode": "scheduler", "scheduler": scheduler}
    else:
        cluster = _start_local_cluster(distributed, n_workers)
        try:
            client = distributed.Client(cluster, set_as_default=False)
        except BaseException:
            with _dask_silenced():
                cluster.close()
            raise
        info = {"mode": "local", "scheduler": cluster.scheduler_address}
    try:
        register_stop_plugin(client, ignore_interrupt=cluster is not None)
    except BaseException:
        close(client, cluster)
        raise
    return client, cluster, info


def register_stop_plugin(client, *, ignore_interrupt: bool) -> None:
    """usdface's :class:`~usdface.pipeline.batch.worker_plugin.StopPlugin` on every worker of the
    client's scheduler (again after the scheduler restarted: it forgets its plugins).

    The scheduler keeps the plugin, for the workers that join later too, before it sends it to
    its workers; their answers are awaited at most :data:`PLUGIN_WAIT` seconds: a worker that does
    not answer (hung, paused, on a lost network) must not hold the batch, which goes on without
    its answer (that worker's shots then stop as Dask's do)."""
    import threading

    from .worker_plugin import StopPlugin

    failure = []

    def register():
        try:
            client.register_plugin(StopPlugin(ignore_interrupt=ignore_interrupt))
        except Exception as exc:  # noqa: BLE001 - a worker that refused or went away: said below
            failure.append(exc)

    thread = threading.Thread(target=register, name="usdface-register-plugin", daemon=True)
    thread.start()
    thread.join(PLUGIN_WAIT)
    if thread.is_alive() or failure:
        log.info("dask: not every worker confirmed usdface's stop handlers (%s); the batch goes on",
                 f"{type(failure[0]).__name__}: {failure[0]}" if failure else f"no answer within {PLUGIN_WAIT:g} s")


def stop(client, futures, outputs, exc: BaseException) -> None:
    """A batch asked to stop: shots not started are cancelled, running ones (writing one of
    ``outputs``) stopped on their workers, which wait until each has removed its partial work.
    Further Ctrl-C/SIGTERM/SIGHUP wait until this is done (a few seconds)."""
    signum = exc.signum if isinstance(exc, Interrupted) else signal.SIGINT
    with signals_deferred(), _dask_silenced():
        with contextlib.suppress(Exception):
            client.cancel(list(futures), force=True)
        with contextlib.suppress(Exception):
            client.run(stop_shots, [str(o) for o in outputs], int(signum), STOP_WAIT, on_error="ignore")


def close(client, cluster) -> None:
    """Close the client and the local cluster (its workers are gone when this returns)."""
    with _dask_silenced():
        with contextlib.suppress(Exception):
            client.close()
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close(timeout=STOP_WAIT)


def tidy_shot_folders(outputs) -> int:
    """Tidy the folders of shots that did not finish, as the next run into them would (a commit
    cut short completed, dead runs' work folders and a lock nobody holds removed); folders a live
    run holds are left to it. Returns the number of folders tidied."""
    from ..shot_commit import tidy_unlocked_folder

    done = 0
    for out in outputs:
        try:
            done += tidy_unlocked_folder(out) is not None
        except (OSError, EnvironmentFault) as exc:
            log.warning("%s: could not tidy it after the batch stopped (%s); the next run into it will", out, exc)
    return done


def n_workers_of(client) -> int:
    import inspect

    if "n_workers" in inspect.signature(client.scheduler_info).parameters:
        return len(client.scheduler_info(n_workers=-1).get("workers", {}))
    return len(client.scheduler_info().get("workers", {}))


def dashboard_of(client) -> str | None:
    try:
        services = client.scheduler_info().get("services", {})
        if "dashboard" not in services:
            return None
        return client.dashboard_link
    except Exception:  # noqa: BLE001
        return None


def probe_scheduler(address: str, *, timeout: float = PROBE_TIMEOUT) -> dict:
    """Check that ``address`` is a Dask scheduler within ``timeout`` seconds; returns its identity.

    A TCP connection first (a port where nothing listens fails at once), then Dask's handshake and
    an identity request under one deadline: a server speaking another protocol (HTTP: the
    dashboard's port 8787, SSH, ...) or one that never answers fails with a clear
    :class:`~usdface.errors.EnvironmentFault` instead of hanging.
    """
    import asyncio
    import socket

    from distributed.comm import connect as dask_connect
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
        comm = await dask_connect(address, timeout=max(0.5, timeout - (time.monotonic() - started)))
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

