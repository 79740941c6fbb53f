"""Batch under load and faults (issue 20, item 4) on a real local Dask cluster: a `dask scheduler`
and two `dask worker` processes started here, so they can be killed and restarted.

    python benchmarks/batch_faults.py                          # (a) 200 shots, (b)-(e) 40 shots each
    python benchmarks/batch_faults.py --scenarios b e --shots 10 --frames 30   # the test suite's version

Shots: the sample meshes x the three takes x windows of ``--frames`` frames (``trim``), each run and
checked (``processors = ["run", "check"]``); a tenth of them bad on purpose, one ``[[shots]]``
entry each: a broken capture, a truncated capture, a layout missing a marker, a layout far off the
mesh (unbindable), a window past the take's end, an empty mesh.

Scenarios (each on a fresh cluster, output folder and cache):
  a  every shot; b  a worker SIGKILLed mid-batch (its nanny restarts it); c  the scheduler SIGKILLed
  mid-batch and restarted on its port; d  two batches with different manifests (sharing one mesh)
  and one cache at once, one on the cluster, one on its own local cluster; e  the batch process
  SIGKILLed mid-batch, then ``--resume`` at once (the killed batch's running shots still finish on
  the workers).

Checked for every scenario (a failure is printed and the exit code is 1):
  - the summary accounts for every shot: each good shot ok, complete (its shot record matches its
    files) and `usdface check`-clean (the batch's check step), each bad one failed with the line of
    its manifest entry;
  - never two writers in one shot folder at once: every OUTDIR lock taken and released is recorded
    (``USDFACE_TEST_LOCK_LOG``); a lock is only taken over from a dead holder, and no live run's
    work folder is ever found by the next holder;
  - the cache is never corrupted: a reader polling the cache during the batch checks every entry
    the moment it appears (meta.json present, every file's size and sha256 as listed), and every
    entry again at the end;
  - (e) a shot complete before the kill is not recomputed by --resume: same files (mtime and
    sha256), same run id, and no run of it took its lock after the resume started.
"recomputed" counts the runs beyond one per shot (a killed worker's shot runs again).
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SA = REPO / "sample_assets"
MESHES = {"makehuman_hm08_face_cm": "makehuman_hm08_face", "makehuman_hm08_face_stylized_cm":
          "makehuman_hm08_face_stylized", "mediapipe_canonical_face_model_holes": "mediapipe_face_holes"}
TAKES = ("JawMoCap", "NoseMoCap", "EyebrowsMoCap")
SHORTEST_TAKE = 902  # frames of EyebrowsMoCap, the shortest take
LONG_SHOT_FRAMES = 1500  # scenario e's long shot (JawMoCap has 1590 frames)
PAUSE = 20.0  # scenario e: the longest the killed batch's worker stays paused once --resume runs (s)
#: each bad shot's kind: (what is wrong, a fragment of the error it must fail with)
BAD = {"broken-capture": "is not terminated by ';'", "truncated-capture": "is not terminated by ';'",
       "missing-marker": "has no entry for capture marker(s) ForeHead_L",
       "unbindable-layout": "far off the mesh surface", "window-past-end": "--trim 5000 5040: expected",
       "empty-mesh": "has no faces"}
ENV = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1", NUMBA_NUM_THREADS="1",
           PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))

sys.path.insert(0, str(Path(__file__).resolve().parent))
from batch_faults_checks import (DASK, CacheReader, Farm, audit_locks, cache_state,  # noqa: E402
                                 shot_state)


# -- inputs and manifests -------------------------------------------------------------------------

def prepare_inputs(work: Path) -> Path:
    """The sample meshes, layouts and takes copied into WORK/inputs, and the bad files."""
    inputs = work / "inputs"
    (inputs / "takes").mkdir(parents=True)
    (inputs / "bad").mkdir()
    for mesh, layout in MESHES.items():
        shutil.copy(SA / "meshes" / f"{mesh}.obj", inputs / f"{mesh}.obj")
        shutil.copy(SA / "layouts" / f"{layout}.layout.json", inputs / f"{layout}.layout.json")
    for take in TAKES:
        shutil.copy(SA / "capture" / f"{take}.ma", inputs / "takes" / f"{take}.ma")
    (inputs / "bad" / "BrokenCapture.ma").write_text("//Maya ASCII 2018 scene\nthis is not a Maya file {{{\n")
    data = (SA / "capture" / "NoseMoCap.ma").read_bytes()
    (inputs / "bad" / "TruncatedCapture.ma").write_bytes(data[: len(data) // 2])
    layout = json.loads((SA / "layouts" / "makehuman_hm08_face.layout.json").read_text())
    missing = dict(layout, markers={k: v for k, v in layout["markers"].items() if k != "ForeHead_L"})
    (inputs / "bad" / "missing_marker.layout.json").write_text(json.dumps(missing))
    far = dict(layout, markers={k: {"point": [v["point"][0] + 100, v["point"][1], v["point"][2] + 100]}
                                for k, v in layout["markers"].items()})
    (inputs / "bad" / "far.layout.json").write_text(json.dumps(far))
    (inputs / "bad" / "empty.obj").write_bytes(b"")
    return inputs


def _bad_entry(kind: str, mesh: str, frames: int) -> dict:
    layout = f"inputs/{MESHES[mesh]}.layout.json"
    entry = {"mesh": f"inputs/{mesh}.obj", "layout": layout, "capture": "inputs/takes/JawMoCap.ma",
             "trim": [0, frames]}
    if kind == "broken-capture":
        entry["capture"] = "inputs/bad/BrokenCapture.ma"
    elif kind == "truncated-capture":
        entry["capture"] = "inputs/bad/TruncatedCapture.ma"
    elif kind == "missing-marker":
        entry.update(mesh="inputs/makehuman_hm08_face_cm.obj", layout="inputs/bad/missing_marker.layout.json")
    elif kind == "unbindable-layout":
        entry.update(mesh="inputs/makehuman_hm08_face_cm.obj", layout="inputs/bad/far.layout.json")
    elif kind == "window-past-end":
        entry["trim"] = [5000, 5040]
    elif kind == "empty-mesh":
        entry["mesh"] = "inputs/bad/empty.obj"
    return entry


def write_manifest(path: Path, *, shots: int, frames: int, bad_fraction: float, meshes=tuple(MESHES),
                   tag: str = "", long_frames: int = 0) -> dict:
    """A manifest of ``shots`` shots (``bad_fraction`` of them bad; with ``long_frames``, one of the
    good ones is that long, with a skeleton too: out/long/JawMoCap, about 20 s); returns {output
    folder: expectation}: ``("ok", None)`` or ``("bad", (kind, manifest line))``."""
    n_bad = max(1, round(shots * bad_fraction)) if bad_fraction > 0 else 0
    n_good = shots - n_bad
    lines = ["[batch]", f'summary = "out{tag}/batch-summary.json"', "[defaults]", 'processors = ["run", "check"]',
             'method = "euclidean"']
    expect = {}
    if long_frames:
        lines += ["", "[[shots]]", f'mesh = "inputs/{meshes[0]}.obj"',
                  f'layout = "inputs/{MESHES[meshes[0]]}.layout.json"', 'capture = "inputs/takes/JawMoCap.ma"',
                  f"trim = [0, {long_frames}]", 'output_kind = "points,skel"', f'output = "out{tag}/long/{{capture}}"']
        expect[str((path.parent / f"out{tag}/long/JawMoCap").resolve())] = ("ok", None)
    k = 0
    while len(expect) < n_good:
        mesh = meshes[k % len(meshes)]
        window = k // len(meshes)
        start = (window * frames) % (SHORTEST_TAKE - frames)
        takes = TAKES[: min(len(TAKES), n_good - len(expect))]
        out = f"out{tag}/{mesh}/{{capture}}_w{window:03d}"
        lines += ["", "[[shots]]", f'mesh = "inputs/{mesh}.obj"', f'layout = "inputs/{MESHES[mesh]}.layout.json"',
                  f'capture = "inputs/takes/{takes[0] + ".ma" if len(takes) == 1 else "*MoCap.ma"}"',
                  f"trim = [{start}, {start + frames}]", f'output = "{out}"']
        if 1 < len(takes) < len(TAKES):
            lines[-3] = f'capture = "inputs/takes/[{"".join(t[0] for t in takes)}]*MoCap.ma"'
        for take in takes:
            expect[str((path.parent / out.format(capture=take)).resolve())] = ("ok", None)
        k += 1
    kinds = list(BAD)
    for j in range(n_bad):
        kind = kinds[j % len(kinds)]
        entry = _bad_entry(kind, meshes[j % len(meshes)], frames)
        out = f"out{tag}/bad/{kind}_{j:03d}"
        lines += ["", "[[shots]]"]
        expect[str((path.parent / out).resolve())] = ("bad", (kind, len(lines)))
        lines += [f"{key} = {json.dumps(value)}" for key, value in entry.items()] + [f'output = "{out}"']
    path.write_text("\n".join(lines) + "\n")
    return expect


# -- running a scenario ---------------------------------------------------------------------------

@dataclass
class Row:
    scenario: str
    shots: int = 0
    ok: int = 0
    failed_expected: int = 0
    recomputed: int = 0
    seconds: float = 0.0
    cache: str = ""
    notes: list = field(default_factory=list)
    problems: list = field(default_factory=list)


def start_batch(work: Path, manifest: Path, *args, env: dict, log: str = "batch") -> subprocess.Popen:
    out = open(work / f"{log}.log", "w")
    return subprocess.Popen([sys.executable, "-m", "usdface", "batch", str(manifest), *map(str, args)], env=env,
                            cwd=manifest.parent, stdout=out, stderr=subprocess.STDOUT)


def finished_shots(expect: dict) -> int:
    return sum((Path(out) / "summary.json").is_file() for out in expect)


def wait_until(predicate, batch: subprocess.Popen, timeout: float = 900.0) -> None:
    deadline = time.time() + timeout
    while not predicate():
        if batch.poll() is not None or time.time() > deadline:
            raise RuntimeError(f"the batch ended (or {timeout:g} s passed) before the fault could be injected")
        time.sleep(0.05)


def running_worker_pid(expect: dict) -> int | None:
    """The pid of a worker writing a shot now (its work folder names it)."""
    for out in expect:
        for work in Path(out).glob(".usdface-run-*"):
            if any(work.iterdir()):
                return int(work.name[len(".usdface-run-"):].split("@")[0])
    return None


def check_summary(summary_file: Path, expect: dict, row: Row) -> None:
    """Every shot accounted for: good ones ok, complete and check-clean; bad ones failed with their
    manifest line and the expected error."""
    from usdface.usd.shot_record import verify_shot

    summary = json.loads(summary_file.read_text())
    by_output = {str(Path(r["output"]).resolve()): r for r in summary["shots"]}
    if sorted(by_output) != sorted(expect) or len(summary["shots"]) != len(expect):
        row.problems.append(f"the summary lists {len(summary['shots'])} shot(s) ({len(by_output)} outputs) for "
                            f"{len(expect)} in the manifest")
    row.shots = len(expect)
    for out, (want, detail) in expect.items():
        rec = by_output.get(out)
        if rec is None:
            continue
        if want == "ok":
            checked = rec["status"] == "skipped" or rec.get("check", {}).get("errors") == 0  # the check step ran
            if rec["status"] not in ("ok", "skipped"):
                row.problems.append(f"{rec['name']}: {rec['status']} ({rec.get('error')})")
            elif verify_shot(Path(out) / "shot.usda") or not checked:
                row.problems.append(f"{rec['name']}: incomplete or not check-clean")
            else:
                row.ok += 1
        else:
            kind, line = detail
            if rec["status"] == "failed" and rec.get("manifestLine") == line and BAD[kind] in (rec.get("error") or ""):
                row.failed_expected += 1
            else:
                row.problems.append(f"{rec['name']} ({kind}, manifest line {line}): {rec['status']}, line "
                                    f"{rec.get('manifestLine')}, error {rec.get('error')!r}")


@dataclass
class Context:
    """One scenario's folder, environment (with the lock audit log) and options."""

    work: Path
    shots: int
    frames: int
    bad_fraction: float

    def __post_init__(self):
        self.work.mkdir(parents=True, exist_ok=True)
        if not (self.work / "inputs").exists():
            (self.work / "inputs").symlink_to(self.work.parent / "inputs", target_is_directory=True)
        self.lock_log = self.work / "locks.jsonl"
        self.env = dict(ENV, USDFACE_TEST_LOCK_LOG=str(self.lock_log))
        self.cache = self.work / "cache"

    def manifest(self, name: str = "shots.toml", **kw) -> tuple[Path, dict]:
        path = self.work / name
        kw.setdefault("shots", self.shots)
        return path, write_manifest(path, frames=self.frames, bad_fraction=self.bad_fraction, **kw)


def _finish(row: Row, ctx: Context, expect: dict, summary: Path, readers, *, since: float = 0.0) -> Row:
    check_summary(summary, expect, row)
    shots = [r for r in json.loads(summary.read_text())["shots"] if r["status"] == "ok" and r.get("steps")]
    if shots:  # a shot waiting for a dead worker's cache lock shows here
        slow = max(shots, key=lambda r: r["seconds"])
        step, secs = max(((k, v) for k, v in slow["steps"].items() if isinstance(v, (int, float))),
                         key=lambda kv: kv[1])
        row.notes.append(f"slowest shot {slow['seconds']:.1f} s ({step} {secs:.1f} s)")
    runs, problems = audit_locks(ctx.lock_log, since=since)
    row.problems += problems
    row.recomputed = sum(len(v) - 1 for v in runs.values())
    states = [cache_state(ctx.cache, r) for r in readers]
    row.cache = states[0][0]
    for _, p in states:
        row.problems += p
    left = [str(p.relative_to(ctx.work)) for p in ctx.work.glob("out*/**/.usdface-*")]
    if left:
        row.notes.append(f"left in shot folders (the next run removes them): {', '.join(left[:4])}")
    return row


def _batch_rc(p: subprocess.Popen, row: Row, expected: int = 1, timeout: float = 1800.0) -> None:
    rc = p.wait(timeout=timeout)
    if rc != expected:
        row.problems.append(f"batch exit code {rc}, expected {expected} (log: {p.args})")


def scenario_a(ctx: Context) -> Row:
    """Every shot, no fault."""
    row = Row("a: 10% bad shots")
    manifest, expect = ctx.manifest()
    farm = Farm(ctx.work, ctx.env).start()
    reader = CacheReader(ctx.cache)
    reader.start()
    try:
        t0 = time.time()
        p = start_batch(ctx.work, manifest, "--scheduler", farm.address, "--cache", ctx.cache, "-q", env=ctx.env)
        _batch_rc(p, row)
        row.seconds = time.time() - t0
    finally:
        reader.done.set()
        reader.join()
        farm.stop()
    return _finish(row, ctx, expect, ctx.work / "out" / "batch-summary.json", [reader])


def _with_fault(ctx: Context, row: Row, fault) -> Row:
    """A batch on the cluster with ``fault(farm, expect, batch)`` injected once a quarter of the
    shots are done and one is being written."""
    manifest, expect = ctx.manifest()
    farm = Farm(ctx.work, ctx.env).start()
    reader = CacheReader(ctx.cache)
    reader.start()
    try:
        t0 = time.time()
        p = start_batch(ctx.work, manifest, "--scheduler", farm.address, "--cache", ctx.cache, "-q", env=ctx.env)
        wait_until(lambda: finished_shots(expect) >= len(expect) // 4 and running_worker_pid(expect), p)
        row.notes.append(fault(farm, expect, p, t0))
        _batch_rc(p, row)
        row.seconds = time.time() - t0
    finally:
        reader.done.set()
        reader.join()
        farm.stop()
    return _finish(row, ctx, expect, ctx.work / "out" / "batch-summary.json", [reader])


def scenario_b(ctx: Context) -> Row:
    """A worker SIGKILLed while it writes a shot; its nanny starts a new one."""
    def kill_worker(farm, expect, batch, t0):
        pid = running_worker_pid(expect)
        done = finished_shots(expect)
        os.kill(pid, signal.SIGKILL)
        return f"worker pid {pid} SIGKILLed at {time.time() - t0:.1f} s, {done} shots done"
    return _with_fault(ctx, Row("b: worker SIGKILLed"), kill_worker)


def scenario_c(ctx: Context) -> Row:
    """The scheduler SIGKILLed mid-batch and started again on its port."""
    def restart_scheduler(farm, expect, batch, t0):
        done = finished_shots(expect)
        farm.kill_scheduler()
        at = time.time() - t0
        time.sleep(2.0)
        farm.start_scheduler()
        return f"scheduler SIGKILLed at {at:.1f} s ({done} shots done), restarted 2 s later"
    return _with_fault(ctx, Row("c: scheduler restarted"), restart_scheduler)


def scenario_d(ctx: Context) -> Row:
    """Two batches at once, different manifests (one mesh in common), one cache: one on the cluster
    (Dask locks), one on its own local cluster (file locks): their cache locks never meet."""
    row = Row("d: two batches, one cache")
    half = max(2, ctx.shots // 2)
    names = list(MESHES)
    m1, e1 = ctx.manifest("first.toml", shots=half, meshes=tuple(names[:2]), tag="-first")
    m2, e2 = ctx.manifest("second.toml", shots=ctx.shots - half, meshes=tuple(names[1:]), tag="-second")
    farm = Farm(ctx.work, ctx.env).start()
    reader = CacheReader(ctx.cache)
    reader.start()
    try:
        t0 = time.time()
        p1 = start_batch(ctx.work, m1, "--scheduler", farm.address, "--cache", ctx.cache, "-q", env=ctx.env,
                         log="first")
        p2 = start_batch(ctx.work, m2, "--workers", "1", "--cache", ctx.cache, "-q", env=ctx.env, log="second")
        _batch_rc(p1, row)
        _batch_rc(p2, row)
        row.seconds = time.time() - t0
    finally:
        reader.done.set()
        reader.join()
        farm.stop()
    other = Row("")
    _finish(row, ctx, e1, ctx.work / "out-first" / "batch-summary.json", [reader])
    check_summary(ctx.work / "out-second" / "batch-summary.json", e2, other)
    computed = {}
    for tag in ("first", "second"):
        summary = json.loads((ctx.work / f"out-{tag}" / "batch-summary.json").read_text())
        for step, n in summary["cache"]["steps"].items():
            computed[step] = computed.get(step, 0) + n.get("miss", 0)
    kinds = {"import-capture": "capture", "distances": "distances"}
    row.notes.append("computed by both batches: " + ", ".join(
        f"{step} {n} time(s) for {len(list((ctx.cache / kinds.get(step, step)).glob('??/*/meta.json')))} entries"
        for step, n in computed.items()))
    row.shots += other.shots
    row.ok += other.ok
    row.failed_expected += other.failed_expected
    row.problems += other.problems
    return row


def scenario_e(ctx: Context) -> Row:
    """The batch process SIGKILLed mid-batch, then `--resume` at once, while the killed batch's task
    still writes the long shot: its worker is paused (SIGSTOP) as soon as it writes it, the batch
    killed once a fifth of the shots are done, the paused worker dropped by the scheduler (as an
    unresponsive one is) and let go only once the resume has done the others (or after PAUSE s).
    Workers without a nanny (which would SIGKILL the paused one)."""
    from usdface.pipeline.shot_commit import folder_in_use

    row = Row("e: batch SIGKILLed, --resume")
    manifest, expect = ctx.manifest(long_frames=LONG_SHOT_FRAMES)
    long_shot = next(out for out in expect if "/long/" in out)
    others = [out for out, (want, _) in expect.items() if want == "ok" and out != long_shot]
    farm = Farm(ctx.work, ctx.env, nanny=False).start()
    reader = CacheReader(ctx.cache)
    reader.start()
    paused = None
    try:
        t0 = time.time()
        p = start_batch(ctx.work, manifest, "--scheduler", farm.address, "--cache", ctx.cache, "-q", env=ctx.env)
        wait_until(lambda: running_worker_pid({long_shot: None}), p)
        paused = running_worker_pid({long_shot: None})
        os.kill(paused, signal.SIGSTOP)
        wait_until(lambda: finished_shots(expect) >= max(1, len(expect) // 5), p)  # on the other worker
        p.kill()
        p.wait()
        killed_at = time.time() - t0
        complete = {out: s for out in expect if (s := shot_state(Path(out))) is not None}
        farm.remove_worker(paused)
        resumed = time.time()
        q = start_batch(ctx.work, manifest, "--scheduler", farm.address, "--cache", ctx.cache, "--resume", "-q",
                        env=ctx.env, log="resume")
        deadline = time.time() + PAUSE
        wait_until(lambda: all((Path(o) / "summary.json").is_file() for o in others) or time.time() > deadline, q)
        held = folder_in_use(long_shot)
        os.kill(paused, signal.SIGCONT)
        paused = None
        _batch_rc(q, row)
        row.seconds = time.time() - t0
    finally:
        if paused is not None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(paused, signal.SIGCONT)
        reader.done.set()
        reader.join()
        farm.stop()
    holder = "the killed batch still held the long shot when" if held else "the long shot was free before"
    row.notes.append(f"batch SIGKILLed at {killed_at:.1f} s with {len(complete)} shot(s) complete and the long shot's "
                     f"worker paused; {holder} --resume had done the others; --resume took "
                     f"{row.seconds - killed_at:.1f} s")
    _finish(row, ctx, expect, ctx.work / "out" / "batch-summary.json", [reader])
    runs, _ = audit_locks(ctx.lock_log, since=resumed)
    for out, before in complete.items():
        if shot_state(Path(out)) != before:
            row.problems.append(f"{out}: complete before --resume, changed by it")
        if runs.get(out):
            row.problems.append(f"{out}: complete before --resume, run again by it (pid {runs[out][0]['pid']})")
    summary = json.loads((ctx.work / "out" / "batch-summary.json").read_text())
    row.notes.append(f"--resume skipped {summary['counts']['skipped']} shot(s)")
    return row


SCENARIOS = {"a": scenario_a, "b": scenario_b, "c": scenario_c, "d": scenario_d, "e": scenario_e}


def print_table(rows: list[Row]) -> None:
    head = ("scenario", "shots", "ok", "failed as expected", "recomputed", "wall (s)", "cache", "invariants")
    table = [head] + [(r.scenario, str(r.shots), str(r.ok), str(r.failed_expected), str(r.recomputed),
                       f"{r.seconds:.1f}", r.cache, "hold" if not r.problems else f"{len(r.problems)} BROKEN")
                      for r in rows]
    widths = [max(len(t[i]) for t in table) for i in range(len(head))]
    for t in table:
        print("  ".join(v.ljust(w) for v, w in zip(t, widths)))
    for r in rows:
        for note in r.notes:
            print(f"  {r.scenario}: {note}")
        for problem in r.problems:
            print(f"  {r.scenario}: BROKEN: {problem}")


def run(scenarios, work: Path, *, shots: int, shots_a: int, frames: int, bad_fraction: float) -> list[Row]:
    """Run the scenarios in ``work`` (made fresh); returns their rows."""
    from usdface.fileutil import path_digest

    if DASK is None:
        raise SystemExit("the dask command is not installed (pip install \"dask[distributed]\")")
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    inputs = prepare_inputs(work)
    before = path_digest(inputs)
    rows = []
    for key in scenarios:
        ctx = Context(work / key, shots_a if key == "a" else shots, frames, bad_fraction)
        started = time.time()
        try:
            row = SCENARIOS[key](ctx)
        except Exception as exc:  # noqa: BLE001 - a scenario that cannot finish is a failure to report
            row = Row(key, problems=[f"{type(exc).__name__}: {exc}"], seconds=time.time() - started)
        if path_digest(inputs) != before:
            row.problems.append("the inputs changed")
        rows.append(row)
        print(f"[{key}] {row.scenario}: {time.time() - started:.0f} s, "
              f"{'invariants hold' if not row.problems else 'BROKEN'}", file=sys.stderr, flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=list(SCENARIOS))
    ap.add_argument("--shots-a", type=int, default=200, help="shots of scenario a (default 200)")
    ap.add_argument("--shots", type=int, default=40, help="shots of scenarios b-e (default 40)")
    ap.add_argument("--frames", type=int, default=40, help="frames per shot (default 40)")
    ap.add_argument("--bad", type=float, default=0.1, help="fraction of bad shots (default 0.1)")
    ap.add_argument("--work", type=Path, default=Path("/tmp/usdface-batch-faults"),
                    help="working folder (replaced)")
    ap.add_argument("--json", type=Path, help="also write the rows as JSON")
    a = ap.parse_args(argv)
    sys.path.insert(0, str(REPO))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"batch faults: {os.cpu_count()} cores, load {load:.1f} at the start; shots of {a.frames} frames")
    rows = run(a.scenarios, a.work, shots=a.shots, shots_a=a.shots_a, frames=a.frames, bad_fraction=a.bad)
    print_table(rows)
    if a.json:
        a.json.write_text(json.dumps([r.__dict__ for r in rows], indent=1))
    return 1 if any(r.problems for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
