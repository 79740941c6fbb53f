"""Crash consistency of `usdface run`'s commit (issue 12): SIGKILL at each step of the commit and at
random times, then `usdface check` and the next run.

    python benchmarks/crash_consistency.py [--trials 20] [--random 20] [--out /tmp/crash]

OUTDIR starts as a complete shot of job A (30 frames); the killed run is job B (40 frames), so a
mix of the two is visible byte for byte (the reference digests of both are measured in this run).
For every kill it records the state OUTDIR is left in (A complete, B complete, or mixed), whether
a shot stage is present and what ``usdface check OUTDIR/shot.usda`` says; then runs job B again
(the next run) and records whether it leaves the complete shot B, a clean check and no temporary
(no ``.usdface-run-*`` folder, no ``.*.tmp-*`` file, no lock file). Kills at a step use the test
hook ``USDFACE_TEST_KILL_AT``; random kills land anywhere in the run (start-up, work, commit).

Must hold: 0 mixed shots accepted by check, 0 shot stages composing a mix, every next run clean.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SA = REPO / "sample_assets"
ENV = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1", NUMBA_NUM_THREADS="1")


def run_args(frames: int, out: Path) -> list[str]:
    return ["run", "--mesh", str(SA / "meshes" / "makehuman_hm08_face_cm.obj"), "--capture",
            str(SA / "capture" / "JawMoCap.ma"), "--layout", str(SA / "layouts" / "makehuman_hm08_face.layout.json"),
            "--method", "euclidean", "--trim", "0", str(frames), "-o", str(out), "-q"]


def cli(argv) -> int:
    from usdface.cli import main

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return main(argv)


def digests(folder: Path, names) -> dict:
    from usdface.fileutil import file_digest

    return {n: file_digest(folder / n) if (folder / n).is_file() else None for n in names}


def state(folder: Path, refs: dict, names) -> str:
    now = digests(folder, names)
    for k, ref in refs.items():
        if now == ref:
            return k
    return "mixed"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trials", type=int, default=20, help="kills per commit step (default 20)")
    ap.add_argument("--random", type=int, default=20, help="kills at random times (default 20)")
    ap.add_argument("--out", default="/tmp/usdface-crash-consistency", help="scratch folder (emptied)")
    ap.add_argument("--seed", type=int, default=12)
    args = ap.parse_args()
    os.environ.update({k: v for k, v in ENV.items() if k.endswith("_THREADS")})
    from usdface.pipeline.shot_commit import KILL_ENV, LOCK_NAME, commit_steps
    from usdface.usd.shot_record import interrupted_commit, leftovers

    root = Path(args.out)
    shutil.rmtree(root, ignore_errors=True)
    root.mkdir(parents=True)
    refs, durations = {}, []
    for name, frames in (("A", 30), ("B", 40)):
        t0 = time.perf_counter()
        p = subprocess.run([sys.executable, "-m", "usdface", *run_args(frames, root / name)], env=ENV,
                           capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        durations.append(time.perf_counter() - t0)
    files = json.loads((root / "B" / "summary.json").read_text())["files"]
    names = [f for f in files if f != "summary.json"]  # summary.json holds timings: compared by run id
    for k in ("A", "B"):
        refs[k] = digests(root / k, names)
    # the same job run again gives the same bytes (so "B complete" is well defined)
    p = subprocess.run([sys.executable, "-m", "usdface", *run_args(40, root / "B2")], env=ENV, capture_output=True)
    assert p.returncode == 0 and digests(root / "B2", names) == refs["B"], "runs of one job differ: set threads to 1"
    steps = commit_steps(files)
    rng = random.Random(args.seed)
    plan = [(s, i) for s in steps for i in range(args.trials)] + [("random", i) for i in range(args.random)]
    rows = {s: Counter() for s in steps + ["random"]}
    print(f"job A 30 frames, job B 40 frames; one run of B takes {durations[1]:.1f} s; files: {', '.join(files)}")
    print(f"{len(plan)} kills: {args.trials} at each of {len(steps)} commit steps + {args.random} at random times")
    started = time.perf_counter()
    for n, (step, i) in enumerate(plan):
        out = root / "out"
        shutil.rmtree(out, ignore_errors=True)
        shutil.copytree(root / "A", out)
        env = dict(ENV)
        cmd = [sys.executable, "-m", "usdface", *run_args(40, out)]
        if step == "random":
            env.pop(KILL_ENV, None)
            proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            time.sleep(rng.uniform(0.0, 1.1 * durations[1]))
            proc.send_signal(signal.SIGKILL)
            proc.wait()
        else:
            env[KILL_ENV] = step
            proc = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        r = rows[step]
        r["trials"] += 1
        r["killed"] += proc.returncode == -signal.SIGKILL
        st = state(out, refs, names)
        shot = (out / "shot.usda").is_file()
        check = cli(["check", str(out / "shot.usda"), "-q"])
        r[f"left {st if shot or st != 'mixed' else 'no shot'}"] += 1
        r["commit pending"] += interrupted_commit(out) is not None
        r["check ok"] += check == 0
        r["MIXED ACCEPTED"] += check == 0 and st == "mixed"
        r["MIXED SHOT STAGE"] += shot and st == "mixed"
        r["check ok, not A/B"] += check == 0 and st not in ("A", "B")
        # the next run
        rc = cli(run_args(40, out))
        clean = rc == 0 and leftovers(out) == [] and not (out / LOCK_NAME).exists() and \
            sorted(p.name for p in out.iterdir()) == sorted(files)
        r["next run clean"] += clean and state(out, refs, names) == "B" and cli(["check", str(out / "shot.usda"), "-q"]) == 0
        if (n + 1) % 20 == 0:
            print(f"  {n + 1}/{len(plan)} kills, {time.perf_counter() - started:.0f} s", flush=True)
    cols = ["trials", "killed", "left A", "left B", "left no shot", "commit pending", "check ok", "MIXED ACCEPTED",
            "MIXED SHOT STAGE", "next run clean"]
    print()
    print("| kill at | " + " | ".join(cols) + " |")
    print("|---" * (len(cols) + 1) + "|")
    total = Counter()
    for s, r in rows.items():
        total.update(r)
        print(f"| {s} | " + " | ".join(str(r[c]) for c in cols) + " |")
    print("| **all** | " + " | ".join(str(total[c]) for c in cols) + " |")
    ok = total["MIXED ACCEPTED"] == 0 and total["MIXED SHOT STAGE"] == 0 and total["next run clean"] == total["trials"] \
        and total["check ok, not A/B"] == 0
    print(f"\n{'PASS' if ok else 'FAIL'}: {total['MIXED ACCEPTED']} mixed shots accepted by check, "
          f"{total['MIXED SHOT STAGE']} shot stages composing a mix, {total['next run clean']}/{total['trials']} next "
          f"runs clean (complete shot B, check ok, no temporary) in {time.perf_counter() - started:.0f} s")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
