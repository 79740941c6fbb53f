"""Report hooks: optional sections a run's folder may call for (the blend-shape solve first).

A hook is a pair of functions registered with :func:`register`:

- ``gather(data: ShotData) -> None`` reads what it needs from ``data.outdir`` / ``data.summary``
  and stores plain numbers in ``data.extras[key]`` (nothing stored: the section is absent);
- ``section(data: ShotData) -> list[Section]`` turns them into report sections (plotly figures,
  tables, notes).

Built in: the **blend-shape solve** (issue 11). Its contract, so the solve only has to write it:
``OUTDIR/curves.csv`` with the header ``frame,time,<shape names>`` (one row per frame, weights
in [0, 1]), and the per-frame marker residual in cm as ``summary.json`` ->
``steps.<solve|blendshapes>.residual`` (or ``residualPerFrame``: a list, one value per frame) or a ``residual``
column of ``curves.csv``. The section plots the curves (shapes that never reach 0.05 start
hidden) and the residual.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Section", "register", "run_gather_hooks", "sections_for"]


@dataclass
class Section:
    """A part of a shot's report: a title, a short explanation, figures (plotly dicts), a table."""

    key: str
    title: str
    text: str = ""
    figures: list = field(default_factory=list)
    table: list | None = None          # rows of (label, value)


_HOOKS: list = []


def register(key: str, gather, section) -> None:
    """Add a hook (replacing one of the same key)."""
    _HOOKS[:] = [h for h in _HOOKS if h[0] != key]
    _HOOKS.append((key, gather, section))


def run_gather_hooks(data) -> None:
    for key, gather, _ in _HOOKS:
        try:
            gather(data)
        except Exception as exc:  # a broken optional section must not lose the rest of the report
            data.warnings.append(f"{key}: could not be read ({type(exc).__name__}: {exc})")


def sections_for(data) -> list:
    out = []
    for key, _, section in _HOOKS:
        if key in data.extras:
            out.extend(section(data))
    return out


# -- the blend-shape solve ---------------------------------------------------------------------------

def _gather_blendshapes(data) -> None:
    path = data.outdir / "curves.csv"
    if not path.is_file():
        return
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    if len(rows) < 2 or rows[0][:2] != ["frame", "time"]:
        data.warnings.append(f"{path.name}: expected a header 'frame,time,<shapes>'")
        return
    header = rows[0]
    body = np.array([[float(v) if v not in ("", "nan", "NaN") else np.nan for v in r] for r in rows[1:] if r])
    cols = {name: body[:, k] for k, name in enumerate(header)}
    residual = cols.pop("residual", None)
    frames = cols.pop("frame")
    cols.pop("time")
    steps = data.summary.get("steps", {})
    for key in ("solve", "blendshapes"):
        step = steps.get(key) or {}
        per_frame = step.get("residualPerFrame", step.get("residual"))  # the solve's per-frame marker residual
        if isinstance(per_frame, list):
            residual = np.asarray(per_frame, dtype=np.float64)
            break
    data.extras["blendshapes"] = {"frames": frames, "curves": cols, "residual": residual,
                                  "units": "cm", "file": path.name}


def _blendshape_sections(data) -> list:
    from .plots import line_figure

    bs = data.extras["blendshapes"]
    frames = bs["frames"]
    traces = []
    for name, w in bs["curves"].items():
        traces.append((name, frames, w, bool(np.nanmax(w) >= 0.05) if w.size else False))
    figs = [line_figure("Blend-shape weight curves", traces, xtitle="frame", ytitle="weight",
                        yrange=(0, 1), key="blendshape-curves")]
    if bs["residual"] is not None and len(bs["residual"]):
        r = np.asarray(bs["residual"])
        figs.append(line_figure("Blend-shape solve: marker residual per frame", [("residual", frames[:r.size], r, True)],
                                xtitle="frame", ytitle=f"residual ({bs['units']})", key="blendshape-residual"))
    active = sum(1 for *_, shown in traces if shown)
    return [Section(key="blendshapes", title="Blend-shape solve",
                    text=f"{len(traces)} shapes from {bs['file']}, {active} reach a weight of 0.05 (the others start "
                         "hidden: click a name to show it).", figures=figs)]


register("blendshapes", _gather_blendshapes, _blendshape_sections)
