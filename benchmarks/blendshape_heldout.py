"""The blend-shape solve on the held-out rig (``benchmarks/make_heldout_rig.py``): figures nobody tuned.

The take is read from its capture layer and solved the way ``usdface solve --layout`` does it
(conditioning with ``stabilize="auto"``, the layout binding judged like ``bind``, then
:func:`usdface.blendshape.take.solve_take` with the solver's defaults); the neutral is the one
frame the capture names (``--neutral frame``: usdface 0.2) or the still stretch around it
(``--neutral robust``), without and with the pose refit (:mod:`usdface.blendshape.posefit`). Also
two plain references (issue 19): every frame solved alone by bounded least squares, with frame 0
as the neutral and with the mean of the 5 still frames.

Printed: weight RMS (all shapes, all frames), mesh error (frames whose mean true displacement
exceeds 0.5 mm: sum of mean vertex errors over sum of mean true displacements) and the mean
per-frame marker residual (cm), per variant. The figures go through the compute functions the
processor calls; ``--cli`` adds a row for ``usdface solve`` itself with every option at its default.

    python benchmarks/blendshape_heldout.py [--tuning] [--out DIR] [--neutral frame|robust|both]
        [--smoothing HZ] [--sparsity B] [--symmetry G] [--no-refit] [--pose-refit N] [--references] [--cli]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_heldout_rig import ROOT, STILL_FRAMES, ensure  # noqa: E402
from solve_metrics import mesh_error, per_frame_bounded_lsq, weight_rms  # noqa: E402


def load(out: Path, *, tuning: bool = False):
    """(rig, layout, take path, truth) of the held-out rig, or of the tuning rig's take."""
    files = ensure(out, tuning=tuning)
    return files["rig"], files["layout"], files["take"], np.load(files["truth"])


def conditioned(take: Path, neutral: str):
    """The take conditioned like ``usdface solve`` (its default options); ``neutral``: "frame" (the
    first frame alone, ``--neutral 0:1``: usdface 0.2) or "robust" (the default rest pose)."""
    from dataclasses import replace

    from usdface.capture.conditioning import condition_capture
    from usdface.options import SolveOptions
    from usdface.usd.inputs import load_capture

    steps = SolveOptions().conditioning()
    if neutral == "frame":
        steps = replace(steps, neutral=(0, 1))
    cap, reports = condition_capture(load_capture(take), steps)
    if neutral == "frame":
        reports.pop("restPose", None)
    return cap, reports


def take_parameters(options: dict):
    """``usdface solve``'s defaults (:meth:`usdface.options.SolveOptions.take_parameters`) with the
    overrides ``options`` (solver fields, and ``pose_refit``)."""
    from dataclasses import replace

    from usdface.options import SolveOptions

    params = SolveOptions().take_parameters()
    solver = {k: v for k, v in options.items() if k != "pose_refit"}
    return replace(params, solver=replace(params.solver, **solver),
                   pose_refit=options.get("pose_refit", params.pose_refit))


def solve_variant(rig, layout, take, truth, neutral: str, options: dict) -> dict:
    from usdface.blendshape.take import solve_take
    from usdface.mesh.judged_binding import bind_and_judge

    cap, reports = conditioned(take, neutral)
    binding, _, _ = bind_and_judge(rig.mesh, cap, layout=layout)
    t0 = time.perf_counter()
    res = solve_take(rig, cap, binding, take_parameters(options))
    seconds = time.perf_counter() - t0
    w = res.weights
    return {"weightRMS": weight_rms(truth["weights"], w),
            "meshError": mesh_error(rig.deltas, truth["weights"], rig.deltas, w),
            "markerResidual": float(np.nanmean(res.solution.residual)), "seconds": seconds,
            "rest": reports.get("restPose"), "weights": w, "displacements": res.displacements}


def references(rig, layout, truth, take) -> dict:
    """Issue 19's per-frame bounded least squares, frame 0 vs the still frames' mean as neutral."""
    from usdface.blendshape.rig import marker_basis
    from usdface.blendshape.synthetic import observable_shapes
    from usdface.mesh.layout import read_layout
    from usdface.mesh.layout_binding import binding_from_layout
    from usdface.usd.inputs import load_capture

    cap = load_capture(take)
    binding = binding_from_layout(rig.mesh, read_layout(layout))
    basis = marker_basis(rig, binding)
    pos = cap.positions[:, [cap.names.index(n) for n in binding.names]]
    keep = observable_shapes(rig.names)
    out = {}
    for label, neutral in (("frame 0", pos[0]), (f"mean of the {STILL_FRAMES} still frames",
                                                 np.nanmean(pos[:STILL_FRAMES], axis=0))):
        d = pos - neutral[None]
        w = per_frame_bounded_lsq(basis, d, keep)
        fit = np.einsum("fk,mkd->fmd", w, basis)
        r = np.sqrt(np.nanmean(((fit - d) ** 2).sum(axis=2), axis=1))
        out[f"per-frame bounded LSQ, neutral = {label}"] = {
            "weightRMS": weight_rms(truth["weights"], w), "meshError": mesh_error(rig.deltas, truth["weights"], rig.deltas, w),
            "markerResidual": float(np.nanmean(r)), "seconds": float("nan")}
    return out


def through_the_command(rig, layout, take, truth, *, tuning: bool) -> dict:
    """``usdface solve`` itself, every option at its default, in a fresh process; the weights read
    back from its ``--csv`` (columns by shape name)."""
    import csv
    import subprocess
    import tempfile

    from make_heldout_rig import TUNING_MESH, TUNING_SHAPES

    with tempfile.TemporaryDirectory() as tmp:
        rig_args = ["--mesh", str(TUNING_MESH), "--shapes", str(TUNING_SHAPES)] if tuning else \
            ["--mesh", str(Path(take).with_name("rig.usdc"))]
        argv = [sys.executable, "-m", "usdface", "solve", *rig_args, "--capture", str(take), "--layout", str(layout),
                "-o", str(Path(tmp) / "curves.usdc"), "--csv", str(Path(tmp) / "curves.csv"), "-q"]
        t0 = time.perf_counter()
        subprocess.run(argv, check=True)
        seconds = time.perf_counter() - t0
        with open(Path(tmp) / "curves.csv", newline="") as f:
            rows = list(csv.DictReader(f))
    w = np.array([[float(row[name]) for name in rig.names] for row in rows])
    if w.shape != truth["weights"].shape:
        raise SystemExit(f"usdface solve wrote {w.shape[0]} frames x {w.shape[1]} shapes, the truth has "
                         f"{truth['weights'].shape}")
    return {"weightRMS": weight_rms(truth["weights"], w),
            "meshError": mesh_error(rig.deltas, truth["weights"], rig.deltas, w),
            "markerResidual": float("nan"), "seconds": seconds}


def table(rows: dict) -> None:
    print("| variant | weight RMS | mesh error | marker residual (cm) | solve (s) |")
    print("|---|---|---|---|---|")
    for label, r in rows.items():
        print(f"| {label} | {r['weightRMS']:.4f} | {100 * r['meshError']:.2f}% | {r['markerResidual']:.4f} | "
              f"{r['seconds']:.2f} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="folder of the rig (default out/heldout_rig, or out/tuning_rig with --tuning)")
    ap.add_argument("--tuning", action="store_true", help="the tuning rig's take instead (MakeHuman)")
    ap.add_argument("--neutral", choices=["frame", "robust", "both"], default="both")
    ap.add_argument("--smoothing", type=float, help="override the solver's smoothing (Hz; 0 = off)")
    ap.add_argument("--sparsity", type=float)
    ap.add_argument("--symmetry", type=float)
    ap.add_argument("--no-refit", action="store_true")
    ap.add_argument("--pose-refit", type=int, help="override the pose refit rounds of the robust-neutral solve")
    ap.add_argument("--references", action="store_true", help="also the per-frame bounded least squares of issue 19")
    ap.add_argument("--cli", action="store_true", help="also `usdface solve` itself (defaults) in a fresh process")
    args = ap.parse_args(argv)
    import logging

    # the synthetic takes have no head motion, so every stabilisation is reported as not reducing
    # it: a true finding, said once here instead of once per variant
    logging.getLogger("usdface").setLevel(logging.ERROR)
    options = {}
    if args.smoothing is not None:
        options["smoothing_hz"] = args.smoothing or None
    if args.sparsity is not None:
        options["sparsity"] = args.sparsity
    if args.symmetry is not None:
        options["symmetry"] = args.symmetry
    if args.no_refit:
        options["refit"] = False
    if args.pose_refit is not None:
        options["pose_refit"] = args.pose_refit
    out = Path(args.out) if args.out else ROOT / "out" / ("tuning_rig" if args.tuning else "heldout_rig")
    rig, layout, take, truth = load(out, tuning=args.tuning)
    what = "tuning rig (MakeHuman face" if args.tuning else "held-out rig (MediaPipe face, never tuned on"
    print(f"{what}, {rig.n_shapes} shapes): {truth['weights'].shape[0]} frames, solver options "
          f"{options or 'defaults'}; conditioned with stabilize=auto (the take has no head motion: whatever "
          "the stabilisation removes is error)\n")
    rows = {}
    variants = {"frame": [("usdface 0.2: one-frame neutral, no pose refit", "frame", {"pose_refit": 0})],
                "robust": [("robust neutral, no pose refit", "robust", {"pose_refit": 0}),
                           ("robust neutral + pose refit (defaults)", "robust", {})]}
    chosen = variants["frame"] + variants["robust"] if args.neutral == "both" else variants[args.neutral]
    for label, neutral, extra in chosen:
        r = solve_variant(rig, layout, take, truth, neutral, {**extra, **options})
        if r["rest"]:
            label += f" (neutral frames {r['rest']['frames'][0]}-{r['rest']['frames'][1]})"
        rows[label] = r
    if args.cli:
        rows["`usdface solve` (the command, defaults; seconds = the whole process)"] = through_the_command(
            rig, layout, take, truth, tuning=args.tuning)
    if args.references:
        rows.update(references(rig, layout, truth, take))
    table(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
