"""What a QC report shows, gathered from a run's output folder alone.

``OUTDIR`` (written by ``usdface run``) holds everything: ``summary.json`` (inputs, options,
per-step reports: stabilisation, gaps filled, binding residuals, transfer amplification and
regularisation, timing), ``capture.usdc`` (stabilised markers, validity, the head motion removed),
and the shot stage (the animated face). :func:`gather_shot` turns them into plain numbers
(:class:`ShotData`); plots and HTML are built from that. No USD here: the report pipeline
(:mod:`usdface.pipeline.report`) reads the shot stage and the capture layer and hands over the
shot's reader (an object with ``face_points``, ``rest_points``...) and the capture (a
:class:`usdface.capture.Capture`).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["ShotData", "gather_shot", "find_shot", "load_run_summary", "SHOT_FILES", "CAPTURE_FILE"]

#: the shot stages a report looks for, in order
SHOT_FILES = ("shot.usda", "shot_skel.usda", "shot_blendshapes.usda")
#: the run's conditioned capture (the marker plots)
CAPTURE_FILE = "capture.usdc"


@dataclass
class ShotData:
    """Numbers and metadata of one shot for its report (see :func:`gather_shot`).

    Arrays are indexed by frame (F) and marker (M); ``frames`` are the shot's time codes.
    """

    outdir: Path
    name: str
    shot: Path
    summary: dict
    options: dict
    inputs: dict
    rate: float
    frames: np.ndarray                      # (F,) time codes
    units: str
    marker_names: list = field(default_factory=list)
    markers: np.ndarray | None = None        # (F, M, 3) stabilised marker positions (capture units), NaN invalid
    valid: np.ndarray | None = None          # (F, M) bool
    neutral: int = 0                         # index of the neutral frame
    neutral_frames: tuple = (0, 1)           # frames start <= f < end the rest pose is averaged over
    rest: np.ndarray | None = None           # (M, 3) the rest pose (capture units): displacements are from it
    filled: list = field(default_factory=list)   # [(marker, first index, stop index, method)] in shot frames
    stabilize: dict = field(default_factory=dict)  # the run's stabilisation report
    stab_rms: dict = field(default_factory=dict)   # {"markers"|"holdout": (before (F,), after (F,))}
    head_motion: bool = False
    residuals: dict = field(default_factory=dict)  # binding residual per marker
    residual_kind: str = ""
    displacement: np.ndarray | None = None   # (F, 4) per frame: min, median, 95th percentile, max (mesh units)
    vertex_max: np.ndarray | None = None     # (N,) largest displacement of each vertex over the shot
    transfer: dict = field(default_factory=dict)   # summary's transfer step + the layer's FaceTransferAPI
    extras: dict = field(default_factory=dict)     # sections added by hooks (blend-shape solve...)
    warnings: list = field(default_factory=list)
    mixed_layers: list = field(default_factory=list)  # layers made for another mesh, bound points or take

    @property
    def n_frames(self) -> int:
        return int(self.frames.size)


def _json_field(value):
    if isinstance(value, str) and value[:1] in "[{":
        try:
            return json.loads(value)
        except ValueError:
            return value
    return value


def find_shot(outdir: Path) -> Path:
    """The shot stage of a run's folder (shot.usda, else shot_skel.usda, ...)."""
    for name in SHOT_FILES:
        if (outdir / name).is_file():
            return outdir / name
    raise InputError(f"report {outdir}: no shot stage ({', '.join(SHOT_FILES)}); give the output folder of "
                     "`usdface run`")


def load_run_summary(outdir) -> dict:
    """The ``summary.json`` of a run's output folder.

    Raises
    ------
    InputError
        The folder or its summary.json is missing or unreadable.
    """
    outdir = Path(outdir)
    if not outdir.is_dir():
        raise InputError(f"report {outdir}: no such folder (expected the output folder of `usdface run`)")
    summary_path = outdir / "summary.json"
    if not summary_path.exists():
        raise InputError(f"report {outdir}: no summary.json (expected the output folder of `usdface run`)")
    from ..inputfiles import read_json

    data = read_json(summary_path, label=f"report {summary_path}")  # a regular file, bounded, UTF-8
    if not isinstance(data, dict):
        raise InputError(f"report {summary_path}: expected the JSON object `usdface run` writes")
    return data


def gather_shot(outdir, summary: dict, face, *, shot, capture=None) -> ShotData:
    """A run's output folder as :class:`ShotData`.

    Parameters
    ----------
    outdir : path
        The run's output folder.
    summary : dict
        Its summary.json (:func:`load_run_summary`).
    face : shot reader
        The shot stage read (:class:`usdface.usd.playback.ShotReader`): ``name``, ``rate``,
        ``start``, ``end``, ``units``, ``rest_points`` (N, 3), ``face_points(times,
        stabilized=True)`` (F, N, 3) and ``transfer_settings()``.
    shot : path
        The shot stage (:func:`find_shot`).
    capture : usdface.capture.Capture, optional
        The run's conditioned capture (``capture.usdc``); without it the marker plots are left out.
    """
    outdir = Path(outdir)
    prov = summary.get("provenance", {})
    data = ShotData(outdir=outdir, name=face.name, shot=Path(shot), summary=summary,
                    options=_json_field(prov.get("options", {})) or {},
                    inputs=_json_field(prov.get("inputs", {})) or {}, rate=face.rate,
                    frames=np.arange(face.start, face.end + 1), units=face.units or "units")
    steps = summary.get("steps", {})
    _capture(data, capture, steps.get("import-capture", {}))
    bind = steps.get("bind", {})
    data.residuals = dict(bind.get("residuals", {}))
    data.residual_kind = bind.get("residualKind", "")
    _displacement(data, face)
    tr = dict(steps.get("transfer") or steps.get("skel") or {})
    tr.update({f"layer:{k}": v for k, v in face.transfer_settings().items()})
    data.transfer = tr
    from .sections import run_gather_hooks

    run_gather_hooks(data)
    return data


def _capture(data: ShotData, cap, cap_step: dict) -> None:
    if cap is None:
        data.warnings.append(f"{CAPTURE_FILE} is missing: no marker plots")
        return
    data.marker_names = list(cap.names)
    pos = np.asarray(cap.positions, dtype=np.float64)
    data.markers = pos
    data.valid = np.isfinite(pos).all(axis=2)
    data.neutral = int(np.clip(cap.neutral_frame, 0, pos.shape[0] - 1))
    data.neutral_frames = cap.neutral_frames
    data.rest = np.asarray(cap.neutral, dtype=np.float64)
    reports = cap_step.get("reports", {})
    data.stabilize = dict(reports.get("stabilize") or {})
    timing = reports.get("timing") or {}
    scale = 1.0
    if timing.get("sourceRate") and timing.get("rate"):
        scale = float(timing["rate"]) / float(timing["sourceRate"])
    for marker, a, b, method in (reports.get("gaps") or {}).get("filled", []):
        # gaps are found before resampling, in the trimmed take's frames
        data.filled.append((marker, int(round(a * scale)), max(int(round(b * scale)), int(round(a * scale)) + 1),
                            method))
    if cap.head_motion is not None:
        data.head_motion = True
        head = np.asarray(cap.head_motion, dtype=np.float64)
        raw = np.einsum("fmj,fjk->fmk", pos, head[:, :3, :3]) + head[:, None, 3, :3]
        for key, names in (("markers", data.stabilize.get("markers", [])),
                           ("holdout", (data.stabilize.get("holdout") or {}).get("markers", []))):
            idx = [data.marker_names.index(n) for n in names if n in data.marker_names]
            if idx:
                data.stab_rms[key] = (_rms_from_neutral(raw[:, idx], data.neutral_frames),
                                      _rms_from_neutral(pos[:, idx], data.neutral_frames))


def _rms_from_neutral(p: np.ndarray, frames) -> np.ndarray:
    """(F,) root mean square over markers of the distance to their rest position (the robust
    average over the neutral frames ``start <= f < end``, as the capture's rest pose)."""
    from ..capture.rest import robust_rest_pose

    a, b = frames
    rest = p[a] if b - a == 1 else robust_rest_pose(p[a:b])[0]
    d = np.linalg.norm(p - rest[None], axis=2)
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.nanmean(d * d, axis=1))


def _displacement(data: ShotData, reader, chunk: int = 128) -> None:
    """Per-frame displacement range of the face from its rest pose, and each vertex's largest."""
    rest = reader.rest_points
    stats = np.empty((data.n_frames, 4))
    vmax = np.zeros(rest.shape[0])
    for i in range(0, data.n_frames, chunk):
        t = data.frames[i:i + chunk]
        d = np.linalg.norm(reader.face_points(t, stabilized=True) - rest, axis=2)  # the transfer, not the head
        stats[i:i + len(t)] = np.stack([d.min(axis=1), np.median(d, axis=1), np.percentile(d, 95, axis=1),
                                        d.max(axis=1)], axis=1)
        vmax = np.maximum(vmax, d.max(axis=0))
    data.displacement = stats
    data.vertex_max = vmax
