"""The local Dask cluster and the invariant checks of benchmarks/batch_faults.py: a `dask scheduler`
and `dask worker` processes to kill and restart, the OUTDIR lock audit, the cache reader, the state
of a shot folder."""
from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

DASK = shutil.which("dask", path=os.path.dirname(sys.executable)) or shutil.which("dask")


# -- the cluster ----------------------------------------------------------------------------------

def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Farm:
    """A `dask scheduler` and ``workers`` `dask worker` processes (each with its nanny) on 127.0.0.1."""

    def __init__(self, work: Path, env: dict, workers: int = 2, scheduler_env: dict | None = None,
                 nanny: bool = True):
        self.work, self.env, self.n, self.nanny = work, env, workers, nanny
        self.scheduler_env = dict(env, **(scheduler_env or {}))
        self.port = _free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.scheduler = None
        self.workers = []
        self.restarts = 0
        self.logs = work / "dask-logs"
        self.logs.mkdir(exist_ok=True)
        self.stopping = threading.Event()
        self.supervisor = threading.Thread(target=self._supervise, daemon=True)

    def _worker(self, i: int) -> subprocess.Popen:
        return self._spawn(f"worker{i}", "worker", self.address, "--nthreads", "1", "--nworkers", "1", "--host",
                           "127.0.0.1", "--no-dashboard", "--name", f"w{i}", *([] if self.nanny else ["--no-nanny"]))

    def _supervise(self) -> None:
        """As a farm's supervisor (systemd, Kubernetes) does: a `dask worker` that ended is started
        again (its nanny closes it when the scheduler goes away)."""
        while not self.stopping.wait(0.5):
            for i, p in enumerate(self.workers):
                if p.poll() is not None and not self.stopping.is_set():
                    self.workers[i] = self._worker(i)
                    self.restarts += 1

    def _spawn(self, name: str, *args, env: dict | None = None) -> subprocess.Popen:
        log = open(self.logs / f"{name}.log", "a")
        return subprocess.Popen([DASK, *args], env=env or self.env, stdout=log, stderr=subprocess.STDOUT, cwd=self.work)

    def start_scheduler(self) -> None:
        self.scheduler = self._spawn("scheduler", "scheduler", "--host", "127.0.0.1", "--port", str(self.port),
                                     "--dashboard-address", ":0", "--no-show", env=self.scheduler_env)

    def start(self) -> "Farm":
        self.start_scheduler()
        self.workers = [self._worker(i) for i in range(self.n)]
        self.wait_for_workers()
        self.supervisor.start()
        return self

    def wait_for_workers(self, timeout: float = 120.0) -> None:
        from distributed import Client

        deadline = time.time() + timeout
        while True:
            try:
                with Client(self.address, timeout="3s") as c:
                    c.wait_for_workers(self.n, timeout=max(1.0, deadline - time.time()))
                    return
            except (OSError, TimeoutError):
                if time.time() > deadline:
                    raise RuntimeError("the Dask cluster did not start; logs in " + str(self.logs)) from None
                time.sleep(0.5)

    def remove_worker(self, pid: int) -> str:
        """The scheduler declares the worker of process ``pid`` (a worker without a nanny) gone, as
        when it stops answering, without asking it (a paused worker cannot answer); returns its
        address."""
        from distributed import Client

        async def remove(address, dask_scheduler=None):
            return await dask_scheduler.remove_worker(address=address, stimulus_id="batch-faults-remove")

        name = next(f"w{i}" for i, p in enumerate(self.workers) if p.pid == pid)  # without a nanny
        with Client(self.address, timeout="10s") as c:
            workers = c.scheduler_info(n_workers=-1)["workers"]
            address = next(a for a, w in workers.items() if w.get("name") == name)
            c.run_on_scheduler(remove, address)
        return address

    def kill_scheduler(self) -> None:
        self.scheduler.send_signal(signal.SIGKILL)
        self.scheduler.wait()

    def stop(self) -> None:
        self.stopping.set()
        if self.supervisor.is_alive():
            self.supervisor.join()
        for p in [*self.workers, self.scheduler]:
            if p is not None and p.poll() is None:
                p.terminate()
        for p in [*self.workers, self.scheduler]:
            if p is None:
                continue
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


# -- the invariants -------------------------------------------------------------------------------

def verify_entry(entry: Path) -> str | None:
    """A problem of one cache entry (a folder), or None when it is whole."""
    from usdface.fileutil import file_digest

    try:
        meta = json.loads((entry / "meta.json").read_text())
    except FileNotFoundError:
        return f"{entry}: an entry without meta.json (partial)"
    except (OSError, ValueError) as exc:
        return f"{entry}: meta.json unreadable ({exc})"
    for name, info in meta.get("files", {}).items():
        f = entry / name
        if not f.is_file() or f.stat().st_size != info["size"] or file_digest(f) != info["sha256"]:
            return f"{entry}: {name} does not match meta.json"
    return None


class CacheReader(threading.Thread):
    """Polls a cache folder and checks each entry the moment it appears (a reader never sees a
    partial entry)."""

    def __init__(self, root: Path):
        super().__init__(daemon=True)
        self.root, self.seen, self.problems, self.done = root, set(), [], threading.Event()

    def run(self) -> None:
        while not self.done.is_set():
            self.scan()
            time.sleep(0.05)
        self.scan()

    def scan(self) -> None:
        if not self.root.is_dir():
            return
        for kind in [p for p in self.root.iterdir() if p.is_dir() and p.name != "locks"]:
            for entry in kind.glob("??/*"):
                if entry.name.startswith(".") or entry in self.seen or not entry.is_dir():
                    continue
                self.seen.add(entry)
                problem = verify_entry(entry)
                if problem:
                    self.problems.append(problem)


def cache_state(root: Path, reader: CacheReader) -> tuple[str, list]:
    """('N entries verified, ...', problems) of a cache after a scenario."""
    problems = list(reader.problems)
    entries = [p.parent for p in root.glob("*/??/*/meta.json")]
    problems += [p for p in (verify_entry(e) for e in entries) if p]
    temporaries = [p for p in root.glob("*/.*") if p.name.startswith((".tmp-", ".trash-"))]
    text = f"{len(entries)} entries, all whole" if not problems else f"{len(problems)} BAD of {len(entries)}"
    if temporaries:
        text += f"; {len(temporaries)} temporar{'y' if len(temporaries) == 1 else 'ies'} of killed writers"
    return text, problems


def audit_locks(log: Path, *, since: float = 0.0) -> tuple[dict, list]:
    """({folder: runs}, problems) from the lock audit log: a lock taken while another process held
    it (and was alive), or a live run's work folder found by the next holder."""
    events = [json.loads(line) for line in log.read_text().splitlines()] if log.is_file() else []
    events.sort(key=lambda e: e["t"])
    holders, runs, problems = {}, {}, []
    for e in events:
        folder = e["folder"]
        if e["event"] == "acquire":
            held = holders.get(folder)
            previous = e.get("previous") or {}
            if held is not None and not (previous.get("pid") == held["pid"] and previous.get("alive") is False):
                problems.append(f"{folder}: taken by pid {e['pid']} at {e['t']:.3f} while pid {held['pid']} held it "
                                f"since {held['t']:.3f} ({'alive' if previous.get('alive') else 'no release'})")
            if e.get("liveRunFolders"):
                problems.append(f"{folder}: pid {e['pid']} found live runs' work folders {e['liveRunFolders']}")
            holders[folder] = e
            if e["purpose"] == "run" and e["t"] >= since:
                runs.setdefault(folder, []).append(e)
        elif holders.get(folder, {}).get("pid") == e["pid"]:
            holders.pop(folder)
    return runs, problems


def shot_state(folder: Path) -> dict | None:
    """{file: (mtime_ns, sha256)} and the run id of a complete shot folder (None when incomplete)."""
    from usdface.fileutil import file_digest
    from usdface.usd.shot_record import read_shot_record, verify_shot

    if not (folder / "shot.usda").is_file() or verify_shot(folder / "shot.usda"):
        return None
    files = {p.name: (p.stat().st_mtime_ns, file_digest(p)) for p in sorted(folder.iterdir()) if p.is_file()}
    return {"files": files, "runId": read_shot_record(folder / "shot.usda")["runId"]}
