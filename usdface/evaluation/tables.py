"""Summaries and markdown tables of a :class:`~usdface.evaluation.results.QualityReport`."""
from __future__ import annotations

import numpy as np

from .configs import REGION_NAMES, TABLE_REGIONS
from .metrics import jaw_drop_mouth_error, mesh_error
from .results import ConfigResult, QualityReport

__all__ = ["summary_rows", "CLAIM_CASES", "claim_numbers", "format_summary_table", "format_claim_table",
           "format_shape_table", "format_overshoot_table", "format_report"]


def _baseline(report: QualityReport, res: ConfigResult) -> ConfigResult | None:
    """The Euclidean result with the same mode/kernel/width/pin as ``res`` (None if absent)."""
    for other in report.results:
        if other.config.method == "euclidean" and other.config.same_except_method(res.config):
            return other
    return None


def summary_rows(report: QualityReport) -> list[dict]:
    """One row per configuration: errors averaged over the shapes.

    Per region of :data:`TABLE_REGIONS`: ``meanCm`` (mean over shapes of the per-shape mean
    error), ``meanPct`` (mean over shapes of the per-shape mean error as % of the shape's mean
    displacement), ``maxCm`` (largest vertex error over all shapes), ``maxPct`` (mean over shapes
    of the per-shape max error as % of the shape's mean displacement). ``winsMouth`` / ``winsEyes``:
    shapes where this config's mean mouth / eye error is lower than the Euclidean config with the
    same mode, kernel, width and pin (None for Euclidean rows). ``stillMotionCm``: mean over shapes
    of the mean predicted displacement of still vertices. ``overshoot``: mean over shapes of
    predicted max / marker max.
    """
    rows = []
    F = len(report.shape_names)
    for res in report.results:
        c = res.config
        row = {"label": c.label, "method": c.method_label, "mode": c.mode, "kernel": c.kernel_label,
               "pin": c.pin_label, "widthCm": round(res.width_cm, 4), "constraints": res.n_constraints,
               "conditionNumber": res.condition_number, "minEigenvalue": res.min_eigenvalue}
        for rn in TABLE_REGIONS:
            i = REGION_NAMES.index(rn)
            row[rn] = {"meanCm": float(np.nanmean(res.mean_error[:, i])),
                       "meanPct": float(np.nanmean(report.percent(res, rn))),
                       "maxCm": float(np.nanmax(res.max_error[:, i])),
                       "maxPct": float(np.nanmean(report.percent(res, rn, "max")))}
        base = _baseline(report, res)
        for key, rn in (("winsMouth", "mouth"), ("winsEyes", "eyes"), ("winsFace", "face")):
            if base is None or c.method == "euclidean":
                row[key] = None
            else:
                i = REGION_NAMES.index(rn)
                row[key] = int((res.mean_error[:, i] < base.mean_error[:, i]).sum())
        row["shapes"] = F
        row["stillMotionCm"] = float(np.nanmean(res.still_motion))
        row["overshoot"] = float(np.mean(res.predicted_max / np.maximum(report.marker_max, 1e-12)))
        rows.append(row)
    return rows


#: the claim's measurements: (shape, region) pairs
CLAIM_CASES = (("jawOpen", "upperLip"), ("eyeBlinkLeft", "leftLowerLid"), ("eyeBlinkRight", "rightLowerLid"))


def claim_numbers(report: QualityReport) -> list[dict]:
    """The paper's claim, per configuration: upper lip on jawOpen, lower lid on eyeBlink.

    Returns
    -------
    list of dict
        One per configuration: ``label``, and per case ``"<shape>/<region>"`` a dict with
        ``meanCm``, ``maxCm`` (vertex error over the region), ``predDyCm``, ``trueDyCm`` (mean y
        displacement over the region, predicted and true) and ``vsEuclidean`` (mean error / the
        matching Euclidean config's, None for Euclidean rows). Cases whose shape was not evaluated
        are left out.
    """
    out = []
    for res in report.results:
        row = {"label": res.config.label, "method": res.config.method_label, "mode": res.config.mode,
               "kernel": res.config.kernel_label, "pin": res.config.pin_label}
        base = _baseline(report, res)
        for shape, region in CLAIM_CASES:
            if shape not in report.shape_names:
                continue
            f = report.shape(shape)
            i = REGION_NAMES.index(region)
            e = float(res.mean_error[f, i])
            row[f"{shape}/{region}"] = {
                "meanCm": e, "maxCm": float(res.max_error[f, i]),
                "predDyCm": float(res.mean_dy[f, i]), "trueDyCm": float(report.truth_dy[f, i]),
                "vsEuclidean": None if (base is None or res.config.method == "euclidean")
                else e / float(base.mean_error[f, i]),
            }
        out.append(row)
    return out


def _f(v, nd=3) -> str:
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "-"
    return f"{v:.{nd}f}"


def format_summary_table(report: QualityReport) -> list[str]:
    """Markdown: one row per configuration, errors averaged over the shapes."""
    F = len(report.shape_names)
    head = ("| distance | mode | kernel, width | pinned | face mean cm (%) | face max | mouth mean cm (%) | mouth max "
            "| eyes mean cm (%) | eyes max | rest mean cm (%) | rest max | still motion cm | mouth/eyes better than Eucl. |")
    lines = [head, "|" + "|".join(["---"] * (head.count("|") - 1)) + "|"]
    for row in summary_rows(report):
        cells = [row["method"], row["mode"], row["kernel"], row["pin"]]
        for rn in TABLE_REGIONS:
            r = row[rn]
            cells.append(f"{_f(r['meanCm'])} ({r['meanPct']:.1f}%)")
            cells.append(_f(r["maxCm"], 2))
        cells.append(_f(row["stillMotionCm"]))
        cells.append("-" if row["winsMouth"] is None else f"{row['winsMouth']}/{F}, {row['winsEyes']}/{F}")
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def format_claim_table(report: QualityReport) -> list[str]:
    """Markdown: the paper's claim numbers per configuration."""
    cases = [(s, r) for s, r in CLAIM_CASES if s in report.shape_names]
    head = ["distance", "mode", "kernel, width", "pinned"]
    for s, r in cases:
        head += [f"{s} {r} mean (max) cm", "pred dy (true)", "vs Eucl."]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join(["---"] * len(head)) + "|"]
    for row in claim_numbers(report):
        cells = [row["method"], row["mode"], row["kernel"], row["pin"]]
        for s, r in cases:
            c = row[f"{s}/{r}"]
            cells += [f"{_f(c['meanCm'])} ({_f(c['maxCm'], 2)})", f"{c['predDyCm']:+.3f} ({c['trueDyCm']:+.3f})",
                      "-" if c["vsEuclidean"] is None else f"{c['vsEuclidean']:.2f}x"]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def format_shape_table(report: QualityReport, configs=None, region: str = "face") -> list[str]:
    """Markdown: per shape, the mean error in ``region`` (cm and %) of each of ``configs``."""
    results = report.results if configs is None else [report.result(c) for c in configs]
    i = REGION_NAMES.index(region)
    head = ["shape", "mean / max true disp. cm"] + [f"{r.config.method_label} {r.config.mode} pin={r.config.pin_label}"
                                                     for r in results]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join(["---"] * len(head)) + "|"]
    best_of = np.nanargmin(np.stack([r.mean_error[:, i] for r in results], axis=1), axis=1)
    for f, name in enumerate(report.shape_names):
        cells = [name, f"{report.truth_mean[f]:.3f} / {report.truth_max[f]:.2f}"]
        for k, r in enumerate(results):
            e = r.mean_error[f, i]
            txt = f"{_f(e)} ({100 * e / report.truth_mean[f]:.0f}%)"
            cells.append(f"**{txt}**" if k == best_of[f] else txt)
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def format_overshoot_table(report: QualityReport, shape: str = "jawOpen") -> list[str]:
    """Markdown: kernel width and matrix diagnostics, and the largest predicted displacement vs the
    markers' and the truth's, per configuration."""
    if shape not in report.shape_names:
        return []
    f = report.shape(shape)
    head = ["distance", "mode", "kernel, width", "pinned", "width cm", "cond.", "min eig. Phi", f"{shape} pred max cm",
            "/ marker max", "all shapes: mean pred max / marker max", "worst (shape)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join(["---"] * len(head)) + "|",
             f"| truth | | | | | | | {report.truth_max[f]:.2f} (markers {report.marker_max[f]:.2f}) | | | |"]
    for res in report.results:
        c = res.config
        ratio = res.predicted_max / np.maximum(report.marker_max, 1e-12)
        w = int(np.argmax(ratio))
        cond = "-" if res.condition_number is None else f"{res.condition_number:.2g}"
        eig = "-" if res.min_eigenvalue is None else f"{res.min_eigenvalue:+.3f}"
        lines.append("| " + " | ".join([
            c.method_label, c.mode, c.kernel_label, c.pin_label, f"{res.width_cm:.2f}", cond, eig,
            f"{res.predicted_max[f]:.2f}", f"{res.predicted_max[f] / report.marker_max[f]:.2f}",
            f"{ratio.mean():.2f}", f"{ratio[w]:.2f} ({report.shape_names[w]})"]) + " |")
    return lines


def format_figures_table(report: QualityReport) -> list[str]:
    """Markdown: issue 19's whole-set figures per configuration (:mod:`usdface.evaluation.metrics`)."""
    from .metrics import JAW_DROP_SHAPE, MESH_ERROR_MIN_MEAN_CM, jaw_drop_mouth_error, mesh_error

    moving = int((report.truth_mean > MESH_ERROR_MIN_MEAN_CM).sum())
    head = ["distance", "mode", "kernel, width", "pinned", f"mesh error ({moving} shapes moving > "
            f"{10 * MESH_ERROR_MIN_MEAN_CM:g} mm)", f"mesh error (all {len(report.shape_names)} shapes)",
            f"jaw-drop mouth error cm ({JAW_DROP_SHAPE})"]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join(["---"] * len(head)) + "|"]
    for res in report.results:
        c = res.config
        cells = [c.method_label, c.mode, c.kernel_label, c.pin_label, _f(mesh_error(report, res), 1) + "%",
                 _f(mesh_error(report, res, min_mean_cm=0.0), 1) + "%", _f(jaw_drop_mouth_error(report, res))]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def format_report(report: QualityReport, *, shape_configs=None) -> list[str]:
    """The full markdown report: settings, summary table, claim table, overshoot, per-shape table."""
    s = report.settings
    F = len(report.shape_names)
    lines = [
        f"Ground truth: {F} expression shapes on a {s['vertices']}-vertex face, {s['markers']} markers "
        f"(median spacing h = {s['markerSpacingCm']:.2f} cm). Skipped: "
        + (", ".join(f"{k} ({v})" for k, v in report.skipped.items()) or "none") + ".",
        f"Error regions: mouth / eyes = vertices within {s['regionRadiusCm']:g} cm of the mouth / eye loops "
        f"({report.regions.counts()['mouth']} / {report.regions.counts()['eyes']} vertices), rest = the other "
        f"{report.regions.counts()['rest']}. % = of the shape's mean vertex displacement. Means are over the shapes; "
        "max = largest vertex error over all shapes.",
        f"Hybrid: radius {s['hybridRadiusCm']:g} cm, sigma {s['hybridSigmaCm']:g} cm, threshold {s['hybridThreshold']:g}. "
        "Kernel widths: 0.7l3 = per marker, 0.7 x its mean distance to its 3 nearest markers in the row's own "
        "metric (the interpolate default); 1.1h = 1.1 x the median Euclidean nearest-marker distance h for every "
        "centre (the paper-mode default, and every mode's before). "
        f"Pinned centres: border {s['pinnedCentres']['border']}, upper (above the mouth corners) "
        f"{s['pinnedCentres']['upper']}, none {s['pinnedCentres']['none']}; paper mode ignores them (zero weight).",
        "",
        "### Errors against the ground truth (mean over shapes)",
        "",
        *format_summary_table(report),
        "",
        "### The paper's claim: jawOpen upper lip, eyeBlink lower lid",
        "",
        *format_claim_table(report),
        "",
        "### Whole-set figures (issue 19: sum of mean vertex errors / sum of mean true displacements)",
        "",
        *format_figures_table(report),
    ]
    ov = format_overshoot_table(report)
    if ov:
        lines += ["", "### Kernel matrix and overshoot", "", *ov]
    if shape_configs is not None:
        lines += ["", "### Per shape (face mean error)", "", *format_shape_table(report, shape_configs)]
    return lines


def report_summary(report: QualityReport) -> dict:
    """JSON-ready summary of ``report`` (per config: per-shape numbers and aggregates): what
    ``usdface evaluate --json`` prints."""
    out = {"settings": report.settings, "shapes": list(report.shape_names), "skipped": dict(report.skipped),
           "regionVertices": report.regions.counts(),
           "truthMeanCm": _r(report.truth_mean), "truthMaxCm": _r(report.truth_max),
           "markerMaxCm": _r(report.marker_max),
           "summary": summary_rows(report), "claim": claim_numbers(report), "configs": []}
    for res in report.results:
        c = res.config
        out["configs"].append({
            "label": c.label, "method": c.method, "backend": c.backend if c.method != "euclidean" else None,
            "mode": c.mode, "kernel": c.kernel, "widthCm": res.width_cm, "widthRule": c.width_cm is None,
            "polynomial": c.polynomial, "pin": c.pin_label, "constraints": res.n_constraints,
            "conditionNumber": res.condition_number, "minEigenvalue": res.min_eigenvalue,
            "meanErrorCm": {rn: _r(res.mean_error[:, i]) for i, rn in enumerate(REGION_NAMES)},
            "maxErrorCm": {rn: _r(res.max_error[:, i]) for i, rn in enumerate(REGION_NAMES)},
            "predictedMaxCm": _r(res.predicted_max), "stillMotionCm": _r(res.still_motion),
            "meshErrorPct": _r([mesh_error(report, res)], 4)[0],
            "meshErrorAllShapesPct": _r([mesh_error(report, res, min_mean_cm=0.0)], 4)[0],
            "jawDropMouthErrorCm": _r([jaw_drop_mouth_error(report, res)])[0],
        })
    return out


def _r(a, nd=5):
    return [None if not np.isfinite(v) else round(float(v), nd) for v in np.asarray(a).ravel()]
