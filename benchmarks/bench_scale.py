"""Scale: `usdface run` on a film-resolution face, time and peak memory per step (by hand).

    python benchmarks/bench_scale.py [--n 32] [--trim 0 300] [--backend fmm] [--out /tmp/usdface-scale]

The MakeHuman face refined 1-to-n^2 (n = 32: 1,983,230 vertices, 3,960,832 triangles; the surface,
its holes and its marker layout are the original's) is written as an OBJ, then the whole pipeline
runs in this process on it with the real Jaw take (trimmed), as `usdface run --mesh FACE.obj
--capture JawMoCap.ma --layout makehuman_hm08_face.layout.json --trim 0 300` would. Each step is
timed (wall and CPU, all threads) and its peak resident memory measured (the peak mark is reset
before the step: /proc/self/clear_refs). Output sizes and free disk are printed too.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
SAMPLES = REPO / "sample_assets"

from procmem import reset_peak, status_mb  # noqa: E402  (benchmarks/procmem.py)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=32)
    ap.add_argument("--trim", type=int, nargs=2, default=(0, 300))
    ap.add_argument("--backend", default=None, help="geodesic back-end (default: the run's default)")
    ap.add_argument("--method", default="hybrid")
    ap.add_argument("--out", default="/tmp/usdface-scale")
    args = ap.parse_args()
    import usdface
    from usdface.distance.graph import refine_triangles
    from usdface.io.meshes import read_mesh

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"usdface from {Path(usdface.__file__).parent}; {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.1f}; free disk {shutil.disk_usage(out).free / 1e9:.0f} GB in {out}")
    obj = out / f"face_n{args.n}.obj"
    if not obj.is_file():
        t0 = time.perf_counter()
        m = read_mesh(SAMPLES / "meshes" / "makehuman_hm08_face_cm.obj")
        p, t = refine_triangles(m.points, m.triangles(), args.n)
        with open(obj, "w") as fh:
            for a in range(0, len(p), 200_000):
                fh.write("".join(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in p[a:a + 200_000]))
            for a in range(0, len(t), 200_000):
                fh.write("".join(f"f {i + 1} {j + 1} {k + 1}\n" for i, j, k in t[a:a + 200_000] ))
        print(f"wrote {obj}: {len(p)} vertices, {len(t)} triangles, {obj.stat().st_size / 1e6:.0f} MB "
              f"({time.perf_counter() - t0:.0f} s)")
        del p, t
    from usdface import api, registry

    rows = []
    call = registry.call

    def measured(name, *a, **k):
        """Every step `run` calls through the registry, timed with its memory."""
        if name == "run":
            return call(name, *a, **k)
        reset_peak()
        before = status_mb("VmRSS")
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            return call(name, *a, **k)
        finally:
            rows.append((name, time.perf_counter() - t0, time.process_time() - c0, before, status_mb("VmHWM")))
            print(f"  {name:15s} {rows[-1][1]:8.1f} s wall {rows[-1][2]:8.1f} s CPU   RSS before "
                  f"{before:7.0f} MB, peak {rows[-1][4]:7.0f} MB", flush=True)

    registry.call = measured
    capture = REPO.parent / "shared" / "data" / "animface" / "JawMoCap.ma"
    if not capture.is_file():
        capture = SAMPLES / "capture" / "JawMoCap.ma"
    options = {"method": args.method, "layout": str(SAMPLES / "layouts" / "makehuman_hm08_face.layout.json"),
               "trim": list(args.trim)}
    if args.backend:
        options["backend"] = args.backend
    print(f"run --mesh {obj.name} --capture {capture.name} --layout makehuman_hm08_face.layout.json "
          f"--trim {args.trim[0]} {args.trim[1]} --method {args.method}"
          f"{' --backend ' + args.backend if args.backend else ''}:")
    t0, c0 = time.perf_counter(), time.process_time()
    result = api.run(str(obj), str(capture), options, output=str(out / "shot"))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"  {'whole run':15s} {wall:8.1f} s wall {cpu:8.1f} s CPU   peak RSS of the process "
          f"{max(r[4] for r in rows):.0f} MB")
    for line in result.text:
        print("  " + line)
    sizes = {f.name: f.stat().st_size for f in (out / "shot").iterdir() if f.is_file()}
    print("outputs: " + ", ".join(f"{k} {v / 1e6:.0f} MB" for k, v in sorted(sizes.items())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
