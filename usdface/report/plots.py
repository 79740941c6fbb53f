"""The report's plots as plotly figure specifications (plain dicts: ``{"data": [...], "layout": {...}}``).

No plotly import here: the figures are JSON handed to plotly.js, which the HTML embeds once.
Numbers are rounded to 4 significant digits and NaN becomes ``null`` (a gap in a line).
"""
from __future__ import annotations

import numpy as np

__all__ = ["amplification_figure", "bar_figure", "compact", "displacement_figure", "line_figure",
           "marker_paths_figure", "shot_figures", "stabilization_figure", "trajectories_figure",
           "validity_figure"]

_PALETTE = ("#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1", "#ff9da7", "#9c755f",
            "#bab0ac")


def compact(values, digits: int = 4) -> list:
    """Numbers rounded to ``digits`` significant digits of their overall magnitude, NaN -> None
    (nested lists for arrays of more than one dimension)."""
    a = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(a)
    top = float(np.abs(a[finite]).max()) if finite.any() else 0.0
    decimals = int(max(0, digits - (np.floor(np.log10(top)) + 1))) if top > 0 else digits
    r = np.round(np.where(finite, a, 0.0), decimals)
    if finite.all():
        return r.tolist()
    return np.where(finite, r, None).tolist()


def _layout(title: str, xtitle: str, ytitle: str, **extra) -> dict:
    lay = {"title": {"text": title, "font": {"size": 15}}, "xaxis": {"title": {"text": xtitle}},
           "yaxis": {"title": {"text": ytitle}}, "margin": {"l": 60, "r": 20, "t": 40, "b": 45}, "height": 360,
           "legend": {"font": {"size": 10}}, "hovermode": "closest", "template": None,
           "paper_bgcolor": "#ffffff", "plot_bgcolor": "#f7f7f9"}
    lay.update(extra)
    return lay


def line_figure(title, traces, *, xtitle="frame", ytitle="", yrange=None, key="", shapes=None) -> dict:
    """Lines ``traces = [(name, x, y, visible)]``; hidden ones start as legend-only."""
    data = []
    for k, (name, x, y, visible) in enumerate(traces):
        data.append({"type": "scatter", "mode": "lines", "name": str(name), "x": compact(x), "y": compact(y),
                     "line": {"width": 1.3, "color": _PALETTE[k % len(_PALETTE)]},
                     "visible": True if visible else "legendonly"})
    lay = _layout(title, xtitle, ytitle)
    if yrange is not None:
        lay["yaxis"]["range"] = list(yrange)
    if shapes:
        lay["shapes"] = shapes
    return {"key": key, "data": data, "layout": lay}


def bar_figure(title, names, values, *, ytitle="", key="", reference=None, reference_name="") -> dict:
    lay = _layout(title, "", ytitle, xaxis={"tickangle": -60, "tickfont": {"size": 9}})
    if reference is not None:
        lay["shapes"] = [{"type": "line", "xref": "paper", "x0": 0, "x1": 1, "y0": reference, "y1": reference,
                          "line": {"dash": "dash", "color": "#e15759", "width": 1.5}}]
        lay["annotations"] = [{"xref": "paper", "x": 1, "y": reference, "text": reference_name, "showarrow": False,
                               "xanchor": "right", "yanchor": "bottom", "font": {"size": 10, "color": "#e15759"}}]
    return {"key": key, "data": [{"type": "bar", "x": list(names), "y": compact(values),
                                  "marker": {"color": "#4e79a7"}}], "layout": lay}


# -- the shot's figures ---------------------------------------------------------------------------------

def _rest(d) -> np.ndarray:
    """(M, 3) the rest pose the displacements are measured from (the neutral frame's positions
    when the data carries none)."""
    return d.rest if d.rest is not None else d.markers[d.neutral]


def trajectories_figure(d, *, shown: int = 8) -> dict:
    """Distance of each marker from its rest position over the take (stabilised)."""
    disp = np.linalg.norm(d.markers - _rest(d)[None], axis=2)  # (F, M)
    order = np.argsort(-np.nan_to_num(np.nanmax(np.where(np.isfinite(disp), disp, -np.inf), axis=0), nan=0))
    top = set(order[:shown].tolist())
    traces = [(n, d.frames, disp[:, m], m in top) for m, n in enumerate(d.marker_names)]
    return line_figure(f"Marker motion from the rest pose (stabilised, {d.units})", traces,
                       ytitle=f"distance ({d.units})", key="trajectories")


def marker_paths_figure(d) -> dict:
    """Front view (x, y) of every marker's path over the take, stabilised, relative to its neutral."""
    rest = _rest(d)
    rel = d.markers - rest[None]
    data = []
    for m, n in enumerate(d.marker_names):
        x = rest[m, 0] + 4 * rel[:, m, 0]
        y = rest[m, 1] + 4 * rel[:, m, 1]
        data.append({"type": "scatter", "mode": "lines", "name": n, "x": compact(x), "y": compact(y),
                     "line": {"width": 1, "color": _PALETTE[m % len(_PALETTE)]}, "showlegend": False,
                     "hoverinfo": "name"})
    data.append({"type": "scatter", "mode": "markers+text", "name": "neutral", "x": compact(rest[:, 0]),
                 "y": compact(rest[:, 1]), "text": list(d.marker_names), "textposition": "top center",
                 "textfont": {"size": 8, "color": "#555"}, "marker": {"size": 4, "color": "#222"},
                 "showlegend": False})
    lay = _layout("Marker paths, front view (motion x4 around each neutral position)", f"x ({d.units})",
                  f"y ({d.units})", height=520)
    lay["yaxis"]["scaleanchor"] = "x"
    lay["xaxis"]["constrain"] = "domain"  # equal scales by narrowing the plot, not widening the range
    return {"key": "marker-paths", "data": data, "layout": lay}


def validity_figure(d) -> dict:
    """Markers x frames: valid, filled (gap filled by the run), invalid."""
    z = np.where(d.valid, 2.0, 0.0).T  # (M, F)
    for marker, a, b, _ in d.filled:
        if marker in d.marker_names:
            z[d.marker_names.index(marker), max(a, 0):min(b, z.shape[1])] = 1.0
    step = max(1, int(np.ceil(z.shape[1] / 2000)))  # columns = frames; keep the JSON small
    if step > 1:
        z = z[:, ::step] if not d.filled else np.minimum.reduceat(z, np.arange(0, z.shape[1], step), axis=1)
    data = [{"type": "heatmap", "z": z.astype(int).tolist(), "x": compact(d.frames[::step]), "y": list(d.marker_names),
             "zmin": 0, "zmax": 2, "showscale": True,
             "colorscale": [[0, "#d62728"], [0.333, "#d62728"], [0.333, "#f2b134"], [0.667, "#f2b134"],
                            [0.667, "#59a14f"], [1, "#59a14f"]],
             "colorbar": {"tickvals": [0.33, 1, 1.67], "ticktext": ["invalid", "filled", "valid"], "len": 0.6},
             "hovertemplate": "%{y} frame %{x}: %{z}<extra></extra>"}]
    lay = _layout("Marker validity over time", "frame", "", height=max(320, 12 * len(d.marker_names) + 90),
                  yaxis={"autorange": "reversed", "tickfont": {"size": 8}})
    return {"key": "validity", "data": data, "layout": lay}


def stabilization_figure(d) -> dict:
    """RMS distance of the stabilisation (and held-out) markers from the neutral frame, before and after."""
    traces = []
    for key, label in (("markers", "stabilisation markers"), ("holdout", "held-out markers")):
        if key in d.stab_rms:
            before, after = d.stab_rms[key]
            traces += [(f"{label}: before", d.frames, before, True), (f"{label}: after", d.frames, after, True)]
    return line_figure("Head stabilisation: rigid-marker motion before and after", traces,
                       ytitle=f"RMS from neutral ({d.units})", key="stabilization")


def displacement_figure(d) -> dict:
    """Per-frame range of the face's displacement from rest: min-max band, 95th percentile, median."""
    s = d.displacement
    f = compact(d.frames)
    data = [
        {"type": "scatter", "mode": "lines", "name": "min", "x": f, "y": compact(s[:, 0]),
         "line": {"width": 0.5, "color": "#9bbcd9"}},
        {"type": "scatter", "mode": "lines", "name": "max", "x": f, "y": compact(s[:, 3]), "fill": "tonexty",
         "fillcolor": "rgba(78,121,167,0.18)", "line": {"width": 1, "color": "#4e79a7"}},
        {"type": "scatter", "mode": "lines", "name": "95th percentile", "x": f, "y": compact(s[:, 2]),
         "line": {"width": 1.2, "color": "#f28e2b"}},
        {"type": "scatter", "mode": "lines", "name": "median", "x": f, "y": compact(s[:, 1]),
         "line": {"width": 1.2, "color": "#59a14f"}},
    ]
    return {"key": "displacement", "data": data,
            "layout": _layout("Face displacement from rest, per frame", "frame", f"displacement ({d.units})")}


def amplification_figure(d, bound: float) -> dict | None:
    """Amplification (max row sum of |B|) against the ridge term tried, the bound and the choice."""
    params = d.transfer.get("layer:parameters") or {}
    auto = params.get("regularizationAuto") or {}
    tried = {float(k): float(v) for k, v in (auto.get("tried") or {}).items()}
    used = d.transfer.get("regularization", d.transfer.get("layer:regularization"))
    amp = d.transfer.get("amplification", params.get("amplification"))
    if not tried and amp is None:
        return None
    if not tried:
        tried = {float(used or 0.0): float(amp)}
    lams = sorted(tried)
    xs = ["0 (exact)" if lam == 0 else f"{lam:g}" for lam in lams]
    colors = ["#e15759" if (used is not None and abs(lam - float(used)) < 1e-15) else "#4e79a7" for lam in lams]
    data = [{"type": "bar", "x": xs, "y": compact([tried[lam] for lam in lams]), "marker": {"color": colors},
             "width": [0.5] * len(xs),
             "name": "amplification", "hovertemplate": "lambda %{x}: %{y}x<extra></extra>"}]
    lay = _layout("Transfer amplification per ridge term tried (red: used)", "regularisation lambda",
                  "amplification (x)", xaxis={"type": "category"})
    lay["shapes"] = [{"type": "line", "xref": "paper", "x0": 0, "x1": 1, "y0": bound, "y1": bound,
                      "line": {"dash": "dash", "color": "#e15759", "width": 1.5}}]
    lay["annotations"] = [{"xref": "paper", "x": 1, "y": bound, "text": f"auto bound {bound:g}x", "showarrow": False,
                           "xanchor": "right", "yanchor": "bottom", "font": {"size": 10, "color": "#e15759"}}]
    top = max(max(tried.values()), bound)
    if top > 50 * min(max(min(tried.values()), 1e-9), bound):
        lay["yaxis"]["type"] = "log"
    return {"key": "amplification", "data": data, "layout": lay}


def shot_figures(d, *, bound: float = 25.0) -> dict:
    """Every standard figure the data allows, by key."""
    figs = {}
    if d.markers is not None and len(d.marker_names):
        figs["trajectories"] = trajectories_figure(d)
        figs["marker-paths"] = marker_paths_figure(d)
        figs["validity"] = validity_figure(d)
        if d.filled:
            per = {}
            for marker, a, b, _ in d.filled:
                per[marker] = per.get(marker, 0) + (b - a)
            names = sorted(per, key=lambda n: -per[n])
            figs["gaps"] = bar_figure("Gap filling: samples filled per marker", names, [per[n] for n in names],
                                      ytitle="samples", key="gaps")
    if d.stab_rms:
        figs["stabilization"] = stabilization_figure(d)
    if d.residuals:
        names = list(d.residuals)
        vals = np.array([d.residuals[n] for n in names], dtype=np.float64)
        kind = {"layout-fit": "layout fit residual"}.get(d.residual_kind, d.residual_kind or "residual")
        figs["binding"] = bar_figure(f"Binding: {kind} per marker ({d.units})", names, vals, ytitle=d.units,
                                     key="binding", reference=float(np.median(vals)), reference_name="median")
    if d.displacement is not None:
        figs["displacement"] = displacement_figure(d)
    amp = amplification_figure(d, bound)
    if amp is not None:
        figs["amplification"] = amp
    return figs
