"""QC reports: a shot's section (inputs, pictures, movie, plots) and the batch table, in one page."""
from __future__ import annotations

import numpy as np

from .html import Page, esc
from .plots import shot_figures
from .sections import sections_for

__all__ = ["add_shot_section", "shot_warnings"]

#: captions of the standard plots: what to look for
CAPTIONS = {
    "trajectories": "How far each marker moves from its neutral-frame position (head motion removed). The 8 that "
                    "move most are shown; click a name in the legend to add another. Spikes that last one frame are "
                    "tracking glitches; flat lines at zero on a moving face are dead markers.",
    "marker-paths": "Every marker's path seen from the front, its motion magnified 4 times around its neutral "
                    "position: crossing or jumping paths point at swapped or mislabelled markers.",
    "validity": "Which marker samples were valid (green), filled by the run's gap filling (amber) or left invalid "
                "(red: the transfer solves those frames with the valid markers only).",
    "gaps": "Samples filled per marker by --fill-gaps.",
    "stabilization": "Root mean square distance of the rigid markers from their neutral positions: before "
                     "stabilisation it is the head's motion; after, what the rigid fit leaves (skin sliding, noise). "
                     "The held-out markers were not used by the fit: their 'after' curve is an honest check.",
    "binding": "How far each marker lies from the face surface after the layout / alignment fit; the dashed line is "
               "the median. A marker far above the others is misplaced in the layout or mislabelled in the capture.",
    "displacement": "The spread of vertex motion at each frame: the band runs from the least to the most moved vertex. "
                    "A maximum far above the 95th percentile means a few vertices fly off (an unstable transfer).",
    "amplification": "The transfer's amplification (the largest sum of |weights| of a vertex: how much a unit marker "
                     "motion can be magnified) for each ridge term the run tried; above the bound the run regularises "
                     "(red bar: the one used).",
}


def _fmt(v, digits: int = 3) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        if not np.isfinite(v):
            return str(v)
        return f"{v:.{digits}g}"
    return str(v)


def shot_warnings(d, *, bound: float = 25.0) -> list[str]:
    """Things a reviewer should look at, from the numbers; layers that do not belong together first."""
    out = [f"mixed layers: {message}" for message in getattr(d, "mixed_layers", ())] + list(d.warnings)
    tr = d.transfer
    amp = tr.get("amplification")
    if amp is not None and amp > bound:
        out.append(f"transfer amplification {amp:.1f}x exceeds the bound {bound:g}x: vertices may be thrown far")
    if tr.get("regularization"):
        out.append(f"the transfer was regularised (lambda {tr['regularization']:g}): markers are reproduced within "
                   f"{100 * float(tr.get('markerResidual') or 0):.0f}%")
    if d.residuals:
        vals = np.array(list(d.residuals.values()), dtype=np.float64)
        med = float(np.median(vals))
        far = [n for n, v in d.residuals.items() if v > max(3 * med, med + 1.0)]
        if far:
            out.append(f"binding residual far above the median ({med:.2f} {d.units}) for: {', '.join(far)}")
    if d.valid is not None:
        invalid = int((~d.valid).sum())
        if invalid:
            out.append(f"{invalid} marker samples are invalid after conditioning "
                       f"({100 * invalid / d.valid.size:.2f}% of all samples)")
    for key, (before, after) in d.stab_rms.items():
        if np.nanmax(after) > np.nanmax(before):
            out.append(f"stabilisation did not reduce the {key} motion (max RMS {np.nanmax(before):.2f} -> "
                       f"{np.nanmax(after):.2f} {d.units})")
    return out


def add_shot_section(page: Page, d, pictures: dict, *, anchor: str, movie: str | None = None,
                     movie_caption: str = "", bound: float = 25.0, heading_level: int = 2) -> None:
    """Append one shot's report to ``page``.

    ``pictures``: {"contact": (png, times), "binding": png|None, "vertexMax": png|None, "hybrid": png|None}.
    """
    s = d.summary
    page.add(f'<section class="shot" id="{esc(anchor)}">')
    page.heading(d.name, heading_level)
    page.note(f"{d.outdir}  ·  shot {d.shot.name}")
    duration = d.n_frames / d.rate if d.rate else 0
    page.cards([("frames", f"{d.n_frames} ({int(d.frames[0])}..{int(d.frames[-1])})"), ("rate", f"{d.rate:g} fps"),
                ("duration", f"{duration:.1f} s"), ("markers", s.get("markers", len(d.marker_names))),
                ("vertices", s.get("vertices", "-")),
                ("method", " ".join(str(x) for x in (s.get("method"), s.get("rbf"), s.get("kernel")) if x)),
                ("run time", f"{s.get('seconds', 0):.1f} s")])
    for w in shot_warnings(d, bound=bound):
        page.warning(w)

    page.heading("Inputs and provenance")
    rows = []
    for role, info in sorted((d.inputs or {}).items()):
        if info:
            rows.append((role, info.get("file", ""), f"<code>{esc(str(info.get('sha256', ''))[:16])}</code>"))
    page.table(("input", "file", "sha256 (first 16)"), rows, raw_columns=(2,))
    page.note(f"usdface {esc(s.get('provenance', {}).get('usdfaceVersion', '?'))}; given as "
              f"<code>{esc(s.get('mesh', ''))}</code>, <code>{esc(s.get('capture', ''))}</code>", raw=True)
    opts = sorted((k, v) for k, v in (d.options or {}).items() if v not in (None, False, [], ""))
    page.add("<details><summary>options of the run</summary>")
    page.table(("option", "value"), [(k, json_value(v)) for k, v in opts])
    page.add("</details>")
    step_rows = [(name, _fmt((st or {}).get("seconds")), (st or {}).get("cache", {}).get("status", "") if st else "")
                 for name, st in s.get("steps", {}).items()]
    page.add("<details><summary>steps (seconds, cache)</summary>")
    page.table(("step", "seconds", "cache"), step_rows, numeric=(1,))
    page.add("</details>")

    page.heading("Pictures and movie")
    if movie:
        page.video(movie, movie_caption)
    items = []
    contact = pictures.get("contact")
    if contact:
        png, times = contact
        items.append(page.picture(png, f"contact sheet: frames {', '.join(str(t) for t in times)}",
                                  alt="contact sheet"))
    if pictures.get("binding"):
        items.append(page.picture(pictures["binding"], "binding: regions and the markers' bound points",
                                  alt="binding", width=640))
    if pictures.get("vertexMax"):
        items.append(page.picture(pictures["vertexMax"], "largest displacement of each vertex over the take",
                                  alt="largest displacement", width=440))
    if pictures.get("hybrid"):
        items.append(page.picture(pictures["hybrid"], "hybrid weight w (1: geodesic distances, 0: Euclidean)",
                                  alt="hybrid weight", width=440))
    page.pictures(items)

    figs = shot_figures(d, bound=bound)
    groups = [("Markers", ("trajectories", "marker-paths")), ("Validity and gaps", ("validity", "gaps")),
              ("Head stabilisation", ("stabilization",)), ("Binding", ("binding",)),
              ("Transfer", ("displacement", "amplification"))]
    for title, keys in groups:
        present = [k for k in keys if k in figs]
        if title == "Validity and gaps" and "gaps" not in figs and d.valid is not None:
            gaps_note = ("no gaps were filled" + ("" if s.get("steps", {}).get("import-capture", {})
                                                  .get("reports", {}).get("gaps") else " (--fill-gaps was not used)"))
        else:
            gaps_note = ""
        if title == "Head stabilisation" and not present:
            page.heading(title)
            page.note("not stabilised (--no-stabilize, or a capture without head motion)")
            continue
        if not present:
            continue
        page.heading(title)
        for k in present:
            page.figure(figs[k], CAPTIONS.get(k, ""))
        if gaps_note:
            page.note(gaps_note)
        if title == "Transfer":
            tr = d.transfer
            page.table(("transfer", "value"), [
                ("mode / kernel / distances", f"{tr.get('mode', '-')} / {tr.get('kernel', '-')} / "
                                              f"{tr.get('distanceMethod', '-')}"),
                ("kernel width (median)", f"{_fmt(tr.get('widthMedian'))} {tr.get('units', '')}"),
                ("amplification used / exact", f"{_fmt(tr.get('amplification'))} / {_fmt(tr.get('exactAmplification'))}"),
                ("regularisation lambda", _fmt(tr.get("regularization"))),
                ("marker residual (|B - I| max)", _fmt(tr.get("markerResidual"))),
                ("condition number", _fmt(tr.get("conditionNumber"))),
                ("frames re-solved for invalid markers", _fmt(tr.get("framesWithInvalidMarkers"))),
            ])
    for sec in sections_for(d):
        page.heading(sec.title)
        if sec.text:
            page.note(sec.text)
        for fig in sec.figures:
            page.figure(fig)
        if sec.table:
            page.table(("", ""), sec.table)
    page.add("</section>")


def json_value(v) -> str:
    import json

    return v if isinstance(v, str) else json.dumps(v)
