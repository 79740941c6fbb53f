"""What usdface's checks cost when it opens a USD file (usdface.usd.layers.open_stage): the
file checks, opening the composed layers ahead of the stage (named pipes, parse errors, cycles)
and trapping USD's diagnostics, against a bare ``Usd.Stage.Open`` of the same file.

    python benchmarks/usd_open_checks.py [--repeats 15]

The file is a binding layer made from the sample mesh and take (it sublayers the mesh layer and
references the capture layer, as shot stages do). Interleaved repeats, medians, a fresh layer
registry each time (the layers are released between opens). Prints both medians and the ratio.
"""
from __future__ import annotations

import argparse
import gc
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SA = REPO / "sample_assets"


def _binding(folder: Path) -> Path:
    out = folder / "b.usda"
    subprocess.run([sys.executable, "-m", "usdface", "bind", "--mesh", SA / "meshes" / "makehuman_hm08_face_cm.usdc",
                    "--capture", SA / "capture" / "JawMoCap.usdc", "--layout",
                    SA / "layouts" / "makehuman_hm08_face.layout.json", "-o", out, "-q"], check=True, cwd=REPO)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=15)
    args = ap.parse_args()
    sys.path.insert(0, str(REPO))
    import usdface  # noqa: F401  (registers the schemas first)
    from pxr import Usd

    from usdface.usd.layers import open_stage

    with tempfile.TemporaryDirectory() as tmp:
        path = _binding(Path(tmp))
        bare, checked = [], []
        for _ in range(args.repeats):
            for fn, out in ((lambda: Usd.Stage.Open(str(path), Usd.Stage.LoadAll), bare),
                            (lambda: open_stage(path, what="binding"), checked)):
                gc.collect()
                t0 = time.perf_counter()
                stage = fn()
                stage.GetPrimAtPath("/Face/Geom")
                out.append(time.perf_counter() - t0)
                del stage
    b, c = statistics.median(bare), statistics.median(checked)
    print(f"bare Usd.Stage.Open: {b * 1e3:.2f} ms; open_stage with its checks: {c * 1e3:.2f} ms; "
          f"ratio {c / b:.2f} (median of {args.repeats}, interleaved)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
