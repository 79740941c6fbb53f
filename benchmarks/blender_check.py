"""By hand: import a run's deliverables into Blender and compare what Blender plays with usdface.

    python benchmarks/blender_check.py OUTDIR [--blender-python PY] [--frames F ...]

OUTDIR is a `usdface run` folder (any --output-kind). Every deliverable there is imported ALONE
into an empty Blender scene (``tests/dcc/blender_import.py``, the script the test suite runs, in a
subprocess: bpy carries its own USD) and Blender's evaluated mesh, in the layer's world space, is
compared at frame 0, the frame of largest Chin displacement, the 5 frames where UsdSkel's
skinning is furthest from the point cache, and any --frames:

- shot.usda, anim.usdc, shot_skel.usda, skel.usdc: against the point cache (shot.usda through
  usdface's evaluator, head motion included);
- blendshapes.usdc, shot_blendshapes.usda: against usdface's own evaluation of that layer.

The Blender Python is --blender-python, else $USDFACE_BLENDER_PYTHON, else this interpreter (if it
has bpy). Prints a table (cm) and Blender's version. Not run by the tests (`tests/dcc/` is the
suite's short version on 300 frames).
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "tests" / "dcc" / "blender_import.py"
POINT_CACHE = ("shot.usda", "anim.usdc", "shot_skel.usda", "skel.usdc")
OWN = ("blendshapes.usdc", "shot_blendshapes.usda")


def _to_layer_world(points_b, layer) -> np.ndarray:
    """Blender world (metres, Z up) -> the layer's world space (its units and up axis)."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(layer))
    p = np.asarray(points_b, dtype=np.float64) / UsdGeom.GetStageMetersPerUnit(stage)
    if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y:
        p = np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)
    return p


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("outdir")
    ap.add_argument("--blender-python")
    ap.add_argument("--frames", type=int, nargs="*", default=[])
    args = ap.parse_args()
    python = args.blender_python or os.environ.get("USDFACE_BLENDER_PYTHON") or (
        sys.executable if importlib.util.find_spec("bpy") else None)
    if python is None:
        sys.exit("no Blender: pip install 'bpy==4.5.*' (Python 3.11) somewhere and pass --blender-python")

    import usdface  # noqa: F401
    from usdface.usd.capture_layer import read_capture_layer
    from usdface.usd.face_evaluator import FaceEvaluator

    out = Path(args.outdir)
    cache_ev = FaceEvaluator.open(out / "shot.usda") if (out / "anim.usdc").exists() else None
    frames = {0, *args.frames}
    cap = read_capture_layer(out / "capture.usdc")
    chin = cap.positions[:, cap.index("Chin")]
    frames.add(int(cap.start_frame + np.nanargmax(np.linalg.norm(chin - chin[cap.neutral_frame], axis=1))))
    if cache_ev is not None and (out / "shot_skel.usda").exists():
        cache = cache_ev.points_range()
        skinned = FaceEvaluator.open(out / "shot_skel.usda").points_range()
        worst = np.argsort(np.linalg.norm(skinned - cache, axis=2).max(axis=1))[::-1][:5]
        frames |= {int(cache_ev.default_times()[i]) for i in worst}
    frames = sorted(frames)
    print(f"{out}: frames {frames}")
    print(f"{'file':24s} {'Blender':10s} {'rest (cm)':>10s} {'max (cm)':>10s}  per frame")
    with tempfile.TemporaryDirectory() as tmp:
        for name in POINT_CACHE + OWN:
            layer = out / name
            if not layer.exists() or (name in POINT_CACHE and cache_ev is None):
                continue
            ev = cache_ev if name in POINT_CACHE else FaceEvaluator.open(layer)
            expected = ev.points_range([float(f) for f in frames])
            npz = Path(tmp) / f"{layer.stem}.npz"
            proc = subprocess.run([python, str(SCRIPT), str(layer), str(npz), "--frames", *map(str, frames)],
                                  capture_output=True, text=True)
            if proc.returncode:
                print(f"{name:24s} import failed: {proc.stderr.strip().splitlines()[-1]}")
                continue
            with np.load(npz) as z:
                info = json.loads(str(z["info"]))
                i = next(k for k, m in enumerate(info["meshes"]) if m["vertices"] == ev.n_points)
                got, rest = z[f"points_{i}"], z[f"rest_{i}"]
            err = np.linalg.norm(_to_layer_world(got, layer) - expected, axis=2).max(axis=1)
            rest_err = np.linalg.norm(_to_layer_world(rest, layer) - ev.rest_points(space="world", time=frames[0]),
                                      axis=1).max()
            print(f"{name:24s} {info['blender'].split()[0]:10s} {rest_err:10.2g} {err.max():10.4f}  "
                  f"{np.round(err, 4).tolist()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
