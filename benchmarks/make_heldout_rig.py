"""The held-out rig for the blend-shape solve: a rig and a take nobody tuned the solver on.

The 52 MakeHuman ARKit shapes are carried onto the MediaPipe face with holes by usdface itself
(``usdface shapes transfer``: registration from the face's 20 landmarks, the target's topology
never used), then driven by generated curves with the committed seed below:

- 60 Hz, 60 s (3600 frames);
- the first 5 frames still (every weight 0), then at least 3 shapes active at every frame
  (:func:`usdface.blendshape.synthetic.layered_weight_curves`: 3 layers of cross-fading events,
  3 to 6 active at once), over the 41 shapes skin markers can see (all but ``tongueOut`` and the
  ``eyeLook*`` shapes, which ``usdface solve`` excludes by default);
- markers at the 41 points of the MediaPipe layout (``sample_assets/layouts``) moved by the rig,
  plus Gaussian noise of 0.3 mm per coordinate on every *position* (the neutral frames too, as a
  real capture has it);
- 5% of the (frame, marker) samples missing, in runs of 1-8 frames (occlusions); frame 0 is kept
  complete so that a one-frame neutral at frame 0 (usdface 0.2's default) can be measured too.

The MakeHuman rig (``benchmarks/blendshape_synthetic.py``) is the tuning rig; this one is held out:
report on it, never choose a default on it. ``--tuning`` makes the same kind of take on the tuning
rig (the MakeHuman face with its own 52 shapes and layout, seed ``TUNING_SEED``), so that what the
synthetic benchmark leaves out (noisy neutral frames, stabilisation, binding) can be tuned there.

Writes into ``--out`` (default ``out/heldout_rig``): ``rig.usdc`` (the transferred rig),
``take.usdc`` (the capture layer, cm, no head motion), ``truth.npz`` (``names``, ``weights`` (F, K),
``clean`` (F, M, 3) noise-free marker positions, ``rest`` (M, 3) the bound points, ``seed``);
with ``--tuning`` (default ``out/tuning_rig``) no ``rig.usdc`` (the rig is the sample npz).

    python benchmarks/make_heldout_rig.py [--out out/heldout_rig] [--tuning]
"""
from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ASSETS = ROOT / "sample_assets"
#: committed before any tuning of the solve on it; never change it to improve a figure
SEED = 19
#: the tuning take's seed (MakeHuman rig)
TUNING_SEED = 18
RATE = 60.0
FRAMES = 3600
STILL_FRAMES = 5
LAYERS = 3
NOISE_CM = 0.03  # 0.3 mm per coordinate
GAP_FRACTION = 0.05
GAP_RUN = (1, 8)
TARGET = ASSETS / "meshes" / "mediapipe_canonical_face_model_holes.obj"
LANDMARKS = ASSETS / "landmarks" / "mediapipe_face_holes.landmarks.layout.json"
LAYOUT = ASSETS / "layouts" / "mediapipe_face_holes.layout.json"
TUNING_MESH = ASSETS / "meshes" / "makehuman_hm08_face_cm.obj"
TUNING_SHAPES = ASSETS / "meshes" / "makehuman_hm08_face_units_cm.npz"
TUNING_LAYOUT = ASSETS / "layouts" / "makehuman_hm08_face.layout.json"


def gap_mask(n_frames: int, n_markers: int, *, fraction: float, run=GAP_RUN, rng) -> np.ndarray:
    """(F, M) bool validity with ``fraction`` of the samples missing in runs, frame 0 complete."""
    valid = np.ones((n_frames, n_markers), dtype=bool)
    want = int(round(fraction * n_frames * n_markers))
    while (~valid).sum() < want:
        m = int(rng.integers(n_markers))
        length = int(rng.integers(run[0], run[1] + 1))
        start = int(rng.integers(1, n_frames))
        valid[start:start + length, m] = False
    return valid


def transfer_rig(out: Path) -> Path:
    """``usdface shapes transfer`` onto the MediaPipe face (the command line, as a user runs it)."""
    rig = out / "rig.usdc"
    cmd = [sys.executable, "-m", "usdface", "shapes", "transfer", "--target", str(TARGET), "--landmarks",
           str(LANDMARKS), "-o", str(rig), "-q"]
    subprocess.run(cmd, check=True)
    return rig


def load_rig(out: Path, *, tuning: bool, make_rig: bool = False):
    """(rig, layout path): the transferred MediaPipe rig (held out) or the MakeHuman rig (tuning)."""
    from usdface.blendshape.rig import BlendShapeRig, load_npz_rig
    from usdface.io.meshes import read_mesh
    from usdface.usd.blendshape_layer import read_blendshape_rig

    if tuning:
        return load_npz_rig(TUNING_SHAPES, read_mesh(TUNING_MESH)), TUNING_LAYOUT
    usd = read_blendshape_rig(transfer_rig(out) if make_rig else out / "rig.usdc")
    return BlendShapeRig(tuple(usd.names), usd.deltas, usd.mesh), LAYOUT


def make(out: Path, *, tuning: bool = False, seed: int | None = None) -> dict:
    from usdface.blendshape.rig import marker_basis
    from usdface.blendshape.synthetic import layered_weight_curves, observable_shapes
    from usdface.model.capture import Capture
    from usdface.mesh.layout import read_layout
    from usdface.mesh.layout_binding import binding_from_layout
    from usdface.usd.capture_layer import write_capture_layer
    from usdface.usd.layers import provenance

    out.mkdir(parents=True, exist_ok=True)
    rig, layout = load_rig(out, tuning=tuning, make_rig=True)
    if seed is not None and not tuning:
        raise ValueError("the held-out rig's seed is committed: --seed is for tuning takes only")
    seed = (TUNING_SEED if seed is None else int(seed)) if tuning else SEED
    binding = binding_from_layout(rig.mesh, read_layout(layout))
    basis = marker_basis(rig, binding)  # (M, K, 3) cm
    rest = binding.surface_points(rig.mesh.points)
    rng = np.random.default_rng(seed)
    weights = layered_weight_curves(FRAMES, rig.n_shapes, shapes=observable_shapes(rig.names), layers=LAYERS,
                                    still=STILL_FRAMES, rate=RATE, seed=int(rng.integers(2**31)))
    clean = rest[None] + np.einsum("fk,mkd->fmd", weights, basis)
    positions = clean + rng.normal(0.0, NOISE_CM, clean.shape)
    valid = gap_mask(FRAMES, binding.n_markers, fraction=GAP_FRACTION, rng=rng)
    positions[~valid] = np.nan
    capture = Capture(names=binding.names, positions=positions, rate=RATE, units="cm",
                      source="tuning_take" if tuning else "heldout_take",
                      history=({"step": "generate", "seed": seed, "noise_cm": NOISE_CM, "gaps": GAP_FRACTION},))
    write_capture_layer(out / "take.usdc", capture,
                        prov=provenance("benchmarks/make_heldout_rig", options={"seed": seed}, inputs={}))
    np.savez_compressed(out / "truth.npz", names=np.array(rig.names), weights=weights, clean=clean, rest=rest,
                        seed=seed)
    active = (weights > 0).sum(axis=1)
    return {"rig": rig, "layout": layout, "take": out / "take.usdc", "truth": out / "truth.npz", "frames": FRAMES,
            "shapes": rig.n_shapes, "markers": binding.n_markers, "activeMin": int(active[STILL_FRAMES:].min()),
            "activeMax": int(active.max()), "missing": float(1 - valid.mean()), "seed": seed}


def ensure(out: Path, *, tuning: bool = False) -> dict:
    """The rig, its layout, the take and the truth in ``out`` (made if a file is missing)."""
    files = [out / n for n in ("take.usdc", "truth.npz")] + ([] if tuning else [out / "rig.usdc"])
    if not all(f.is_file() for f in files):
        return make(out, tuning=tuning)
    rig, layout = load_rig(out, tuning=tuning)
    return {"rig": rig, "layout": layout, "take": out / "take.usdc", "truth": out / "truth.npz"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="folder (default out/heldout_rig, or out/tuning_rig with --tuning)")
    ap.add_argument("--tuning", action="store_true", help="the same kind of take on the tuning (MakeHuman) rig")
    ap.add_argument("--seed", type=int, help=f"another tuning take (default {TUNING_SEED}; --tuning only)")
    args = ap.parse_args(argv)
    if args.seed is not None and not args.tuning:
        ap.error("--seed: the held-out rig's seed is committed; --seed makes other tuning takes (--tuning)")
    out = Path(args.out) if args.out else ROOT / "out" / ("tuning_rig" if args.tuning else "heldout_rig")
    info = make(out, tuning=args.tuning, seed=args.seed)
    face = "MakeHuman face (tuning rig)" if args.tuning else "MediaPipe face (held-out rig)"
    print(f"{info['shapes']} shapes on the {face}, {info['markers']} markers, {info['frames']} frames at {RATE:g} Hz, "
          f"active shapes per frame {info['activeMin']}-{info['activeMax']} after {STILL_FRAMES} still frames, "
          f"{100 * info['missing']:.1f}% samples missing, seed {info['seed']}")
    print(f"wrote {', '.join(str(p) for p in sorted(out.iterdir()))}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
