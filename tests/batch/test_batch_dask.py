"""The Must-show: a real `dask scheduler` + two `dask worker` processes on localhost, a manifest of
7 shots (two meshes x three takes + one broken take), outputs byte-identical to serial runs,
distances computed once per mesh and binding, and a --resume run that does nothing; then the same
manifest on the default LocalCluster with no options."""
from __future__ import annotations

from usdface.options import BatchOptions

import json
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from usdface import cli

LAYERS = ("mesh.usdc", "capture.usdc", "binding.usda", "analysis.usdc", "anim.usdc", "shot.usda")
DASK = shutil.which("dask", path=os.path.dirname(sys.executable)) or shutil.which("dask")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def dask_farm(repo_root, tmp_path):
    """`dask scheduler` and two `dask worker` subprocesses on 127.0.0.1; stopped at the end."""
    if DASK is None:
        pytest.skip("the dask command is not installed (pip install \"dask[distributed]\")")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, PYTHONPATH=str(repo_root) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    logs = tmp_path / "dask-logs"
    logs.mkdir()
    procs = []

    def start(name, *args):
        f = open(logs / f"{name}.log", "w")
        procs.append((subprocess.Popen([DASK, *args], env=env, stdout=f, stderr=subprocess.STDOUT,
                                       cwd=tmp_path), f))

    start("scheduler", "scheduler", "--host", "127.0.0.1", "--port", str(port), "--dashboard-address", ":0",
          "--no-show")
    for i in range(2):
        start(f"worker{i}", "worker", address, "--nthreads", "1", "--nworkers", "1", "--host", "127.0.0.1",
              "--no-dashboard", "--name", f"w{i}")
    try:
        from distributed import Client

        deadline = time.time() + 60
        while True:
            try:
                with Client(address, timeout="2s") as c:
                    c.wait_for_workers(2, timeout=max(1, deadline - time.time()))
                    break
            except (OSError, TimeoutError):
                if time.time() > deadline:
                    pytest.fail("the Dask scheduler and workers did not start:\n" +
                                "\n".join(p.read_text()[-2000:] for p in logs.iterdir()))
                time.sleep(0.5)
        yield address
    finally:
        for p, f in reversed(procs):
            p.terminate()
        for p, f in reversed(procs):
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
            f.close()


def _batch(*args) -> tuple[int, dict]:
    rc = cli.main(["batch", *map(str, args), "-q"])
    return rc, None


def _summary(path) -> dict:
    return json.loads(Path(path).read_text())


def test_farm_matches_serial_caches_and_resumes(tmp_path, make_manifest, dask_farm, capsys):
    serial_dir, farm_dir = tmp_path / "serial", tmp_path / "farm"
    serial_dir.mkdir()
    farm_dir.mkdir()
    manifest = make_manifest(tmp_path)
    # serial reference: one shot after the other in this process, its own cache
    rc = cli.main(["batch", str(manifest), "--workers", "0", "--out-root", str(serial_dir), "-q"])
    assert rc == 1
    t0 = time.perf_counter()
    rc = cli.main(["batch", str(manifest), "--scheduler", dask_farm, "--out-root", str(farm_dir), "-q"])
    farm_seconds = time.perf_counter() - t0
    assert rc == 1  # the broken shot
    s = _summary(farm_dir / "usdface-batch-summary.json")
    assert s["mode"] == "scheduler" and s["workers"] == 2
    by = {r["name"]: r for r in s["shots"]}
    assert len(by) == 7
    broken = by["makehuman_hm08_face_cm/BrokenMoCap"]
    assert broken["status"] == "failed" and "BrokenMoCap.ma" in broken["error"]
    ok = [r for r in s["shots"] if r["status"] == "ok"]
    assert len(ok) == 6
    assert len({r["host"] for r in s["shots"]}) == 2, "both workers ran shots"
    # distance matrices computed once per mesh and binding, reused for the other takes
    assert s["cache"]["steps"]["distances"] == {"hit": 4, "miss": 2}
    # every layer byte-identical to the serial run's
    for r in ok:
        rel = Path(r["output"]).relative_to(farm_dir)
        for name in LAYERS:
            a, b = (serial_dir / rel / name).read_bytes(), (farm_dir / rel / name).read_bytes()
            assert a == b, f"{rel}/{name} differs between serial and farm runs"
    # and to a plain `usdface run` of the same shot (no cache) with one BLAS thread; with the
    # machine's default BLAS threads the float32 GEMM sums in another order: last-bit differences
    from usdface.pipeline.batch.shot import single_threaded

    shot = next(r for r in ok if r["name"] == "makehuman_hm08_face_cm/JawMoCap")
    sa = Path(shot["mesh"]).parents[1]
    argv = ["run", "--mesh", shot["mesh"], "--capture", shot["capture"], "--layout",
            str(sa / "layouts" / "makehuman_hm08_face.layout.json"), "--trim", "0", "120", "-q", "-o"]
    with single_threaded():
        assert cli.main(argv + [str(tmp_path / "plain")]) == 0
    for name in LAYERS:
        assert (tmp_path / "plain" / name).read_bytes() == (Path(shot["output"]) / name).read_bytes(), name
    assert cli.main(argv + [str(tmp_path / "plain-threads")]) == 0
    for name in ("mesh.usdc", "capture.usdc", "binding.usda", "analysis.usdc"):
        assert (tmp_path / "plain-threads" / name).read_bytes() == (Path(shot["output"]) / name).read_bytes(), name
    from pxr import Usd
    import numpy as np

    a = Usd.Stage.Open(str(tmp_path / "plain-threads" / "anim.usdc"))
    b = Usd.Stage.Open(str(Path(shot["output"]) / "anim.usdc"))
    pa, pb = (s.GetPrimAtPath("/Face/Geom").GetAttribute("points") for s in (a, b))
    worst = max(float(np.abs(np.asarray(pa.Get(t)) - np.asarray(pb.Get(t))).max()) for t in range(120))
    assert worst < 1e-4, worst  # cm: float32 rounding only
    # a second run with --resume does nothing (the broken shot is retried and fails again)
    capsys.readouterr()
    t0 = time.perf_counter()
    rc = cli.main(["batch", str(manifest), "--scheduler", dask_farm, "--out-root", str(farm_dir), "--resume"])
    out = capsys.readouterr().out
    s2 = _summary(farm_dir / "usdface-batch-summary.json")
    assert [r["status"] for r in s2["shots"]].count("skipped") == 6
    assert s2["counts"]["failed"] == 1 and rc == 1
    assert "6 skipped, 1 failed" in out and "BrokenMoCap" in out
    resume_seconds = time.perf_counter() - t0
    # --force redoes a current shot; a changed option makes --resume redo it
    print(f"farm {farm_seconds:.1f} s, resume {resume_seconds:.1f} s")


def test_resume_redoes_changed_and_tampered_shots(tmp_path, make_manifest):
    from usdface.pipeline.batch.manifest import load_manifest
    from usdface.pipeline.batch.runner import run_batch

    p = make_manifest(tmp_path, broken=False, trim=(0, 40))
    m = load_manifest(p)
    m.shots = m.shots[:3]
    assert run_batch(m, BatchOptions(workers=0))["counts"]["ok"] == 3
    # tamper with one shot's analysis layer, change another's options
    a = Path(m.shots[0].output) / "analysis.usdc"
    a.write_bytes(a.read_bytes() + b"\0")
    m.shots[1].options["threshold"] = 0.5
    s = run_batch(m, BatchOptions(workers=0, resume=True))
    assert [r["status"] for r in s["shots"]] == ["ok", "ok", "skipped"]
    s = run_batch(m, BatchOptions(workers=0, resume=True, force=True))
    assert [r["status"] for r in s["shots"]] == ["ok", "ok", "ok"]


def test_default_local_cluster_no_options(tmp_path, make_manifest, capsys):
    manifest = make_manifest(tmp_path)
    rc = cli.main(["batch", str(manifest)])
    captured = capsys.readouterr()
    assert rc == 1
    s = _summary(tmp_path / "usdface-batch-summary.json")
    assert s["mode"] == "local" and s["workers"] >= 1
    assert s["counts"] == {"ok": 6, "skipped": 0, "failed": 1, "unsupported": 0}
    assert s["cache"]["steps"]["distances"] == {"hit": 4, "miss": 2}
    assert "dask: local scheduler" in captured.err and "[7/7]" in captured.err
    assert "6 ok, 0 skipped, 1 failed" in captured.out
    assert (tmp_path / ".usdface-cache" / "distances").is_dir()


def test_unreachable_scheduler_fails_fast(tmp_path, make_manifest, capsys):
    manifest = make_manifest(tmp_path, broken=False)
    t0 = time.perf_counter()
    rc = cli.main(["batch", str(manifest), "--scheduler", f"tcp://127.0.0.1:{_free_port()}"])
    seconds = time.perf_counter() - t0
    err = capsys.readouterr().err
    assert rc == 1 and seconds < 10, seconds  # an environment fault, found within 10 s (README)
    assert "nothing listens there" in err


def test_example_manifest_runs_as_written(repo_root, tmp_path):
    example = repo_root / "sample_assets" / "batch" / "example.toml"
    from usdface.pipeline.batch.manifest import load_manifest

    m = load_manifest(example, out_root=tmp_path)
    assert len(m.shots) == 6 and {Path(s.mesh).name for s in m.shots} == {
        "makehuman_hm08_face_cm.obj", "mediapipe_canonical_face_model_holes.obj"}
    rc = cli.main(["batch", str(example), "--out-root", str(tmp_path), "--workers", "2", "-q"])
    assert rc == 0
    s = _summary(tmp_path / "out" / "batch-summary.json")
    assert s["counts"]["ok"] == 6 and s["cache"]["steps"]["distances"] == {"hit": 4, "miss": 2}
