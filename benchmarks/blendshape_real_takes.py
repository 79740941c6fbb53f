"""The three real AnimFace takes solved on the MakeHuman ARKit rig: residuals, checks, plots.

Each take is read from its Maya ASCII file, stabilised, given its rest pose (the still stretch at
the first frame, :func:`usdface.capture.neutral.set_rest_pose`; ``--one-frame-neutral``: the first
frame alone and no pose refit, as usdface 0.2), bound with the sample layout and solved with
``usdface solve``'s defaults (:func:`usdface.blendshape.take.solve_take`). Printed per take:
the mean per-frame marker residual against a still face's (all weights 0), the largest weights,
and the two timing checks of issue 11:

- Jaw: jawOpen's maximum inside the wide-open hold = the frames where the Chin marker's
  displacement exceeds 80% of its maximum;
- Eyebrows: browInnerUp's maximum inside the raises = the frames where the two inner-brow markers
  are raised (mean upward displacement) by more than a fraction of their largest raise (50% and
  25% are both reported; the rig's browInnerUp reaches 1 while the actor's brows are still rising,
  so the weight is flat at its maximum from the raise's onset).

Writes ``curves.png`` (the curves of each take with the check spans shaded, and the residuals) and
``sheet.png`` (the posed rig at chosen frames with the markers it should reach) into ``--out``.

    python benchmarks/blendshape_real_takes.py --out out/blendshape
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHEET_FRAMES = {"Jaw": (0, 410, 650, 900, 1200, 1450), "Eyebrows": (250, 450, 650), "Nose": (150, 500, 800)}


def _spans(mask, times):
    idx = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return [(times[a], times[b - 1]) for a, b in zip(idx[::2], idx[1::2])]


def main(argv=None) -> int:
    from usdface.blendshape.rig import load_npz_rig
    from usdface.blendshape.parameters import TakeParameters
    from usdface.blendshape.take import solve_take
    from usdface.io.meshes import read_mesh
    from usdface.mesh.binding import bind_layout
    from usdface.mesh.layout import read_layout
    from usdface.preview import PointSet, RenderStyle, ScalarColors, contact_sheet, fit_camera, render_mesh, write_png
    from usdface.preview.curves import CurveStyle, plot_curves, stack_panels
    from usdface.capture.conditioning import Conditioning, condition_capture
    from usdface.usd.inputs import load_capture

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out/blendshape")
    ap.add_argument("--one-frame-neutral", action="store_true",
                    help="measure from the first frame alone and skip the pose refit (usdface 0.2)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    a = ROOT / "sample_assets"
    mesh = read_mesh(a / "meshes/makehuman_hm08_face_cm.obj")
    rig = load_npz_rig(a / "meshes/makehuman_hm08_face_units_cm.npz", mesh)
    layout = read_layout(a / "layouts/makehuman_hm08_face.layout.json")
    panels, cells, captions = [], [], []
    camera = None
    for take in ("Jaw", "Eyebrows", "Nose"):
        steps = Conditioning(stabilize="auto", neutral=(0, 1) if args.one_frame_neutral else None)
        cap, reports = condition_capture(load_capture(a / f"capture/{take}MoCap.ma"), steps)
        if not args.one_frame_neutral:
            print(f"\n{take}: {reports['restPose']['text']}")
        binding = bind_layout(mesh, layout, cap)
        res = solve_take(rig, cap, binding, TakeParameters(pose_refit=0) if args.one_frame_neutral else TakeParameters())
        sol, d = res.solution, res.displacements
        w = sol.weights
        t = np.arange(w.shape[0]) / cap.rate
        r, s = np.nanmean(sol.residual), np.nanmean(sol.still_residual)
        top = list(np.argsort(w.max(axis=0))[::-1][:6])
        print(f"\n## {take}: {w.shape[0]} frames at {cap.rate:g} Hz, solved in {sol.seconds:.3f} s ({sol.iterations} "
              f"iterations)")
        print(f"marker residual mean {r:.3f} cm vs still face {s:.3f} cm ({100 * r / s:.0f}%); max {np.nanmax(sol.residual):.3f} cm")
        print("largest weights: " + ", ".join(f"{rig.names[k]} {w[:, k].max():.2f}" for k in top))
        spans, span_label, focus = [], "", None
        if take == "Jaw":
            chin = np.linalg.norm(d[:, binding.names.index("Chin")], axis=1)
            hold = chin > 0.8 * np.nanmax(chin)
            k = rig.index("jawOpen")
            f = int(np.argmax(w[:, k]))
            print(f"jawOpen max {w[f, k]:.3f} at frame {f}: inside the wide-open hold (Chin > 80% of its max, frames "
                  f"{np.flatnonzero(hold)[0]}-{np.flatnonzero(hold)[-1]}, {int(hold.sum())} frames): {bool(hold[f])}")
            spans, span_label, focus = _spans(hold, t), "Chin > 80% max", k
        if take == "Eyebrows":
            inner = [binding.names.index("Leyebrow_Inside"), binding.names.index("Reyebrow_Inside")]
            up = d[:, inner, 1].mean(axis=1)
            k = rig.index("browInnerUp")
            f = int(np.argmax(w[:, k]))
            at_max = w[:, k] >= w[:, k].max() - 1e-3
            for frac in (0.5, 0.25):
                raised = up > frac * np.nanmax(up)
                print(f"browInnerUp max {w[f, k]:.3f} first at frame {f}; raises = inner brows up > {frac:.0%} of their "
                      f"largest raise ({int(raised.sum())} frames): argmax inside {bool(raised[f])}, "
                      f"{100 * raised[at_max].mean():.1f}% of the {int(at_max.sum())} frames at the maximum inside")
            print(f"the actor's inner brows rise {np.nanmax(up):.2f} cm; the rig's browInnerUp moves those markers "
                  f"{res.basis[inner, k, 1].mean():.2f} cm")
            spans, span_label, focus = _spans(up > 0.5 * np.nanmax(up), t), "brows up > 50% max", k
        shown = ([focus] if focus is not None and focus not in top else []) + top
        panels.append(plot_curves(t, w[:, shown], [rig.names[k] for k in shown], title=f"{take}: weights",
                                  y_range=(0, 1), spans=spans, span_label=span_label))
        panels.append(plot_curves(t, np.stack([sol.residual, sol.still_residual], axis=1),
                                  ["solved", "still face"], title=f"{take}: marker residual (cm, RMS per frame)",
                                  style=CurveStyle(size=(1200, 200))))
        for fr in SHEET_FRAMES[take]:
            posed = rig.evaluate(w[fr])
            target = binding.surface_points(mesh.points) + np.nan_to_num(d[fr])
            if camera is None:
                camera = fit_camera([mesh.points, posed], view="front", size=(360, 360), colorbar=True)
            cells.append(render_mesh(posed, mesh.triangles(), camera=camera, style=RenderStyle(legend=False),
                                     colors=ScalarColors(np.linalg.norm(posed - mesh.points, axis=1), range=(0, 3),
                                                         label="cm"),
                                     markers=PointSet(target, name="capture"),
                                     extra=PointSet(binding.surface_points(posed), name="posed rig")))
            k = int(np.argmax(w[fr]))
            captions.append(f"{take} {fr}: {rig.names[k]} {w[fr, k]:.2f}" if w[fr, k] > 0 else f"{take} {fr}: neutral")
    write_png(out / "curves.png", stack_panels(panels))
    write_png(out / "sheet.png", contact_sheet(cells, captions, columns=4,
                                               title="MakeHuman ARKit rig posed by the solved weights (dots: capture "
                                                     "markers; diamonds: the rig's bound points)"))
    print(f"\nwrote {out / 'curves.png'} and {out / 'sheet.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
