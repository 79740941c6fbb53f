"""The files of the blend-shape deliverable: the curves layer (CURVES.usdc), the curves CSV and the
Live Link Face CSV, all holding the same curves, written together (`solve`, `solve --apply`,
`run`'s blend-shape step); and curves read back from either (`solve --apply`)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from .layers import USD_SUFFIXES, describe, is_in_memory

__all__ = ["CurveFiles", "write_curve_files", "AppliedCurves", "read_curve_file"]


@dataclass(frozen=True)
class CurveFiles:
    """Where the curves go: ``output`` the curves layer (a path, or in Python an ``Sdf.Layer`` /
    ``Usd.Stage`` to author into); ``csv`` and ``livelink`` CSV paths, or None (not written)."""

    output: object
    csv: object = None
    livelink: object = None


def write_curve_files(curves, rig, regions, files: CurveFiles, *, staged, prov: dict, report: dict,
                      start_frame: int = 0, fill_zeros: bool = False) -> dict:
    """Write the deliverable's files for ``curves`` into ``staged`` temporaries (the caller commits
    them: :class:`usdface.fileutil.StagedOutputs`); an in-memory ``files.output`` is authored
    directly, after the temporaries are written.

    Parameters
    ----------
    curves : usdface.blendshape.take.DeliverableCurves
    rig : usdface.blendshape.rig.BlendShapeRig
    regions : list of Region
        The rig mesh's regions (authored on the layer's mesh).
    files : CurveFiles
    staged : usdface.fileutil.StagedOutputs
    prov, report : dict
        The layer's provenance and the JSON-able report stored beside it.
    start_frame : int
        Time code of the first delivered frame (decision D2).
    fill_zeros : bool
        Live Link CSV: zeros for the ARKit shapes the rig lacks (otherwise an error naming them).

    Returns
    -------
    dict
        ``{"files": {"curves", "csv", "livelink": final paths written}}``, plus ``"livelink"`` (the
        Live Link CSV's report) when it was written.
    """
    from ..blendshape.csvio import curves_csv_text, live_link_face_text
    from .blendshape_layer import CurveSamples, write_curves_layer

    n = curves.values.shape[0]
    frames = start_frame + np.arange(n)
    written = {"curves": describe(files.output) if is_in_memory(files.output) else str(files.output)}
    extra = {}
    if files.livelink is not None:  # before any file: a rig without ARKit names fails first
        text, ll_report = live_link_face_text(rig.names, curves.values, rate=curves.rate,
                                              head_motion=curves.head_motion, fill_missing=fill_zeros,
                                              source=f"the rig {rig.source}")
        extra["livelink"] = ll_report
    samples = CurveSamples(times=start_frame + curves.sample_frames, weights=curves.sample_values, rate=curves.rate,
                           start=float(frames[0]), end=float(frames[-1]), head_motion=curves.head_motion,
                           head_times=frames if curves.head_motion is not None else None)
    if not is_in_memory(files.output):
        write_curves_layer(staged.path(files.output), rig, regions, samples, prov=prov, report=report)
    if files.csv is not None:
        staged.path(files.csv).write_text(curves_csv_text(rig.names, curves.values, rate=curves.rate,
                                                          start_frame=start_frame))
        written["csv"] = str(files.csv)
    if files.livelink is not None:
        staged.path(files.livelink).write_text(text)
        written["livelink"] = str(files.livelink)
    if is_in_memory(files.output):  # all or nothing in memory too: the files are written, not committed
        write_curves_layer(files.output, rig, regions, samples, prov=prov, report=report)
    return {"files": written, **extra}


@dataclass(frozen=True)
class AppliedCurves:
    """Curves read back (:func:`read_curve_file`): ``names`` (K), ``values`` (F, K) at every frame,
    ``rate``, ``start`` (the first frame's time code) and ``head_motion`` (F, 4, 4) or None."""

    names: list
    values: np.ndarray
    rate: float
    start: int
    head_motion: np.ndarray | None = None


def read_curve_file(path, *, option: str = "--apply") -> AppliedCurves:
    """Weight curves from a curves CSV (``frame,time,<names>``) or a curves layer (any SkelAnimation
    with blend-shape weights; reduced keys are interpolated linearly to every frame, as USD does,
    and the head motion on /Face comes along, interpolated rigidly)."""
    from ..blendshape.csvio import read_curves_csv
    from .blendshape_layer import head_motion_of_layer, read_curves_layer

    cp = Path(path)
    if cp.suffix.lower() not in USD_SUFFIXES:
        names, frames, values, rate = read_curves_csv(cp)
        return AppliedCurves(names, values, rate, int(frames[0]))
    data = read_curves_layer(cp)
    names, times, values, rate = data["names"], data["times"], data["weights"], data["rate"]
    if times.size == 0:
        raise InputError(f"{option} {cp}: the curves have no time samples")
    frames = np.arange(int(round(times[0])), int(round(times[-1])) + 1)
    values = np.stack([np.interp(frames, times, values[:, k]) for k in range(len(names))], axis=1)
    head = None
    hm = head_motion_of_layer(cp)
    if hm is not None:
        from ..blendshape.curves import interpolate_rigid

        head = interpolate_rigid(hm[0], hm[1], frames)
    return AppliedCurves(names, values, rate, int(frames[0]), head)
