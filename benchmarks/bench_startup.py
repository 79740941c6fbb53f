"""Is this tree slower than another for what users run most? ``usdface --help`` and the README's
main job, each a fresh process, interleaved (before, after, before, after, ...) so that the load of a
shared machine falls on both alike; medians and their ratio.

    python benchmarks/bench_startup.py --before 9e2e68a            # 10 rounds
    python benchmarks/bench_startup.py --before 9e2e68a --runs 20

Both trees run from a temporary checkout (``git archive``; this working tree is used as it is for
"after"), each warmed up once first (numba compiles and caches its kernels on a first run).
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
SA = HERE / "sample_assets"


def checkout(rev: str, where: Path) -> Path:
    archive = subprocess.run(["git", "-C", str(HERE), "archive", rev], check=True, capture_output=True).stdout
    where.mkdir(parents=True, exist_ok=True)
    subprocess.run(["tar", "-x", "-C", str(where)], input=archive, check=True)
    return where


def timed(tree: Path, argv: list[str]) -> float:
    env = dict(os.environ, PYTHONPATH=str(tree))
    t0 = time.perf_counter()
    # cwd=tree: `python -m` puts the working folder first on sys.path, before PYTHONPATH
    proc = subprocess.run([sys.executable, "-m", "usdface", *argv], env=env, capture_output=True, text=True, cwd=tree)
    seconds = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{tree}: usdface {' '.join(argv[:1])} failed: {proc.stderr.strip()[-300:]}")
    return seconds


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="git revision to compare with")
    ap.add_argument("--runs", type=int, default=10, help="interleaved rounds (default 10)")
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="usdface-startup-"))
    try:
        trees = {"before": checkout(args.before, tmp / "before"), "after": HERE}
        job = ["run", "--mesh", str(SA / "meshes" / "makehuman_hm08_face_cm.obj"),
               "--capture", str(SA / "capture" / "JawMoCap.ma"),
               "--layout", str(SA / "layouts" / "makehuman_hm08_face.layout.json"), "-q"]
        commands = {"usdface --help": ["--help"], "main job (usdface run)": job}
        times = {(c, s): [] for c in commands for s in trees}
        for side, tree in trees.items():  # warm-up: compile caches, OS file cache
            timed(tree, job + ["-o", str(tmp / f"warm-{side}")])
        for r in range(args.runs):
            for command, argv_ in commands.items():
                order = ("before", "after") if r % 2 == 0 else ("after", "before")
                for side in order:
                    extra = ["-o", str(tmp / f"out-{side}")] if command.startswith("main") else []
                    times[(command, side)].append(timed(trees[side], argv_ + extra))
        print(f"{args.runs} interleaved rounds, load average {os.getloadavg()[0]:.1f} at the end")
        print(f"| command | {args.before} (median s) | this tree (median s) | ratio |\n|---|---|---|---|")
        for command in commands:
            b = statistics.median(times[(command, "before")])
            a = statistics.median(times[(command, "after")])
            print(f"| {command} | {b:.3f} | {a:.3f} | {a / b:.3f} |")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
