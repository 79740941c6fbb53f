"""Rigid head stabilisation: remove the head's rigid motion from a capture.

Per frame, the rigid transform (rotation + translation, no scale) that best maps a set of stable
markers' reference (neutral-frame) positions onto their positions in that frame is fitted by
weighted least squares (:func:`usdface.capture.rigid.fit_rigid_batch`). Positions are brought
back into the reference (head-local) frame with its inverse, and the transforms are kept as the
capture's ``head_motion`` so that ``Capture.world_positions()`` gives the input back.

Stable markers are chosen by name or automatically, by data: starting from every usable marker,
fit, rank markers by the RMS distance of their stabilised positions from their reference
positions over the take, keep the most rigid 80 % (never fewer than ``n_auto``) and repeat until
``n_auto`` markers remain and the set no longer changes. Which markers are rigid depends on the
take: in a jaw take the forehead and eye corners win, in a brow take the cheeks and chin do.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..errors import MarkerError, OptionError, list_names
from ..model.capture import Capture
from .rigid import fit_rigid_batch, rotation_angle, to_matrix

__all__ = [
    "stabilize",
    "StabilizeReport",
    "RigidMotion",
    "residual_rigid_motion",
    "rigid_motion",
    "rank_rigid_markers",
]

#: markers valid in fewer than this fraction of frames are never chosen automatically
MIN_VALID_FRACTION = 0.5
#: fraction of the candidate set kept per iteration of the automatic selection
KEEP_FRACTION = 0.8
MAX_ITERATIONS = 40


@dataclass(frozen=True)
class RigidMotion:
    """Rigid motion of a marker set relative to its reference positions, per frame.

    For each frame ``f``, the rigid transform ``(R_f, t_f)`` that best maps the set's reference
    positions onto its positions in frame ``f`` is fitted (least squares, valid markers only).

    Attributes
    ----------
    markers : tuple of str
        The marker set.
    angle_deg : ndarray, shape (F,), float64
        Rotation angle of ``R_f`` in degrees (NaN where fewer than 3 markers are valid).
    translation : ndarray, shape (F,), float64
        Displacement of the set's reference centroid ``c`` under the transform,
        ``|R_f c + t_f - c|``, in capture units (independent of where the origin is).
    """

    markers: tuple[str, ...]
    angle_deg: np.ndarray
    translation: np.ndarray

    @property
    def max_angle_deg(self) -> float:
        return float(np.nanmax(self.angle_deg)) if np.isfinite(self.angle_deg).any() else math.nan

    @property
    def max_translation(self) -> float:
        return float(np.nanmax(self.translation)) if np.isfinite(self.translation).any() else math.nan

    @property
    def p95_angle_deg(self) -> float:
        return float(np.nanpercentile(self.angle_deg, 95)) if np.isfinite(self.angle_deg).any() else math.nan

    @property
    def p95_translation(self) -> float:
        return float(np.nanpercentile(self.translation, 95)) if np.isfinite(self.translation).any() else math.nan

    def summary(self) -> dict:
        """JSON-serialisable maxima and 95th percentiles."""
        return {
            "markers": list(self.markers),
            "max_angle_deg": self.max_angle_deg,
            "p95_angle_deg": self.p95_angle_deg,
            "max_translation": self.max_translation,
            "p95_translation": self.p95_translation,
        }


@dataclass(frozen=True)
class StabilizeReport:
    """What :func:`stabilize` did.

    Attributes
    ----------
    markers : tuple of str
        Stable markers used in the fit.
    auto : bool
        True when they were chosen automatically.
    reference_frame : int
        Frame index whose positions the fit maps to (the head-local frame).
    scores : dict of str to float
        Per marker (all markers), RMS over valid frames of the distance between its stabilised
        position and its reference position, in capture units: a non-rigidity score (NaN for
        markers invalid at the reference frame or everywhere).
    fit_rms : ndarray, shape (F,), float64
        RMS fit residual of the stable markers per frame (NaN where interpolated).
    interpolated_frames : ndarray, shape (K,), int64
        Frames with fewer than 3 valid stable markers, whose head motion was interpolated from
        the neighbouring frames (rotation by slerp, reference centroid linearly; held at the ends).
    holdout : tuple of str
        Markers not used in the fit on which ``before``/``after`` are measured.
    before, after : RigidMotion or None
        Rigid motion of the held-out set in the input positions and in the stabilised positions.
        Good stabilisation leaves only the set's own non-rigid (expression) motion in ``after``.
    """

    markers: tuple[str, ...]
    auto: bool
    reference_frame: int
    scores: dict
    fit_rms: np.ndarray
    interpolated_frames: np.ndarray
    holdout: tuple[str, ...] = ()
    before: RigidMotion | None = None
    after: RigidMotion | None = None
    units: str | None = None

    def summary(self) -> dict:
        """JSON-serialisable digest of the report."""
        return {
            "markers": list(self.markers),
            "auto": self.auto,
            "reference_frame": self.reference_frame,
            "units": self.units,
            "interpolated_frames": [int(f) for f in self.interpolated_frames],
            "max_fit_rms": float(np.nanmax(self.fit_rms)) if np.isfinite(self.fit_rms).any() else None,
            "holdout": {
                "markers": list(self.holdout),
                "before": self.before.summary() if self.before is not None else None,
                "after": self.after.summary() if self.after is not None else None,
            },
        }


# -- kernels ------------------------------------------------------------------------------------


def _to_local(positions, rot, t):
    """Inverse rigid transform per frame: R^T (x - t); NaN stays NaN."""
    return np.einsum("fji,fmj->fmi", rot, positions - t[:, None, :])


def _scores(local, reference):
    """(M,) RMS over valid frames of |local - reference|; NaN where no valid frame."""
    d2 = ((local - reference[None]) ** 2).sum(axis=2)
    ok = np.isfinite(d2)
    n = ok.sum(axis=0)
    s = np.where(ok, d2, 0.0).sum(axis=0)
    return np.sqrt(np.divide(s, n, out=np.full(s.shape, np.nan), where=n > 0))


def rigid_motion(positions, reference, *, markers=()):
    """Per-frame rigid motion of a marker set relative to reference positions.

    Parameters
    ----------
    positions : ndarray, shape (F, K, 3), float
        The set's positions per frame (NaN = invalid).
    reference : ndarray, shape (K, 3), float
        The set's reference positions (must be finite).
    markers : sequence of str
        Names, stored in the result.

    Returns
    -------
    RigidMotion
        Rotation angle (degrees) and reference-centroid displacement (units) per frame.
    """
    reference = np.asarray(reference, dtype=np.float64)
    rot, _, t = fit_rigid_batch(reference, positions)
    c = reference.mean(axis=0)
    disp = np.einsum("fij,j->fi", rot, c) + t - c
    return RigidMotion(tuple(markers), rotation_angle(rot), np.linalg.norm(disp, axis=1))


def residual_rigid_motion(capture: Capture, markers, *, reference_frame=None) -> RigidMotion:
    """Rigid motion of a named marker set in a capture's positions (as stored).

    Parameters
    ----------
    capture : Capture
    markers : sequence of str
        At least 3 marker names, valid at the reference frame.
    reference_frame : int, optional
        Frame index of the reference positions; default the capture's neutral frame.

    Returns
    -------
    RigidMotion
    """
    idx = _indices(capture, markers, what="marker")
    ref_f = capture.neutral_frame if reference_frame is None else _frame_index(capture, reference_frame, "reference_frame")
    ref = (capture.neutral if reference_frame is None else capture.positions[ref_f])[idx]
    bad = [capture.names[i] for i, ok in zip(idx, np.isfinite(ref).all(axis=1)) if not ok]
    if bad:
        raise MarkerError(f"marker(s) {list_names(bad)} invalid at reference frame {ref_f}")
    if len(idx) < 3:
        raise OptionError(f"residual rigid motion needs at least 3 markers; got {len(idx)}")
    return rigid_motion(capture.positions[:, idx], ref, markers=[capture.names[i] for i in idx])


def _indices(capture, names, *, what):
    if isinstance(names, str):
        raise OptionError(f"{what}s must be a list of marker names, not the string {names!r}")
    names = list(names)
    idx = [capture.index(n) for n in names]
    if len(set(idx)) != len(idx):
        raise OptionError(f"{what}s list names a marker twice: {list_names(names)}")
    return idx


def _frame_index(capture, value, option):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise OptionError(f"{option} must be a frame index (int) or 'neutral'; got {value!r}")
    f = int(value)
    if not 0 <= f < capture.n_frames:
        raise OptionError(f"{option}: frame index {f} outside 0..{capture.n_frames - 1}")
    return f


def _select(positions, reference, candidates, n_auto):
    """Automatic stable-marker selection (see module docstring). Returns (keep, scores)."""
    keep = np.asarray(candidates)
    scores = None
    for _ in range(MAX_ITERATIONS):
        rot, _, t = fit_rigid_batch(reference[keep], positions[:, keep])
        local = _to_local(positions, rot, t)
        scores = _scores(local, reference)
        cand_scores = scores[candidates]
        order = np.asarray(candidates)[np.argsort(np.where(np.isfinite(cand_scores), cand_scores, np.inf), kind="stable")]
        n = max(n_auto, int(math.ceil(KEEP_FRACTION * len(keep))))
        new_keep = np.sort(order[:n])
        if len(keep) == n_auto and np.array_equal(new_keep, np.sort(keep)):
            break
        keep = new_keep
    return np.sort(keep), scores


def _candidates(capture, ref):
    """Markers valid in the reference positions ``ref`` (M, 3) and in enough frames."""
    valid = capture.valid
    ok = np.isfinite(ref).all(axis=1) & (valid.mean(axis=0) >= MIN_VALID_FRACTION)
    return np.flatnonzero(ok)


def rank_rigid_markers(capture: Capture, *, n_auto: int = 8, reference="neutral") -> list[tuple[str, float]]:
    """Rank markers from most to least rigid with the head, by the automatic selection's score.

    Parameters
    ----------
    capture : Capture
    n_auto : int
        Size of the final stable set of the selection the scores come from.
    reference : "neutral" or int
        Reference: the capture's rest pose, or a frame index.

    Returns
    -------
    list of (name, score)
        Candidate markers (valid at the reference frame and in at least half of the frames),
        sorted by score: RMS distance (capture units) from the reference position after
        stabilisation with the automatically selected set.
    """
    ref = capture.neutral if reference == "neutral" else capture.positions[_frame_index(capture, reference, "reference")]
    cands = _candidates(capture, ref)
    n_auto = _check_n_auto(n_auto, len(cands), capture)
    _, scores = _select(capture.positions, ref, cands, n_auto)
    order = sorted(cands, key=lambda i: scores[i])
    return [(capture.names[i], float(scores[i])) for i in order]


def _check_n_auto(n_auto, n_cands, capture):
    if isinstance(n_auto, (bool, np.bool_)) or not isinstance(n_auto, (int, np.integer)) or n_auto < 3:
        raise OptionError(f"n_auto must be an integer >= 3 (a rigid fit needs 3 markers); got {n_auto!r}")
    if n_cands < 3:
        raise MarkerError(
            f"capture{(' ' + capture.source) if capture.source else ''} has only {n_cands} marker(s) valid at the "
            f"reference frame and in at least {MIN_VALID_FRACTION:.0%} of frames; stabilisation needs 3"
        )
    return int(min(n_auto, n_cands))


def _interpolate_motion(rot, t, centroid, good):
    """Fill frames where ``good`` is False: slerp rotations, interpolate the centroid's path."""
    frames = np.arange(rot.shape[0])
    gf = frames[good]
    path = np.einsum("fij,j->fi", rot[good], centroid) + t[good]
    if len(gf) == 1:
        rot_all = np.repeat(rot[good], rot.shape[0], axis=0)
    else:
        slerp = Slerp(gf, Rotation.from_matrix(rot[good]))
        rot_all = slerp(np.clip(frames, gf[0], gf[-1])).as_matrix()
    path_all = np.stack([np.interp(frames, gf, path[:, k]) for k in range(3)], axis=1)
    out_r = np.where(good[:, None, None], rot, rot_all)
    out_t = np.where(good[:, None], t, path_all - np.einsum("fij,j->fi", rot_all, centroid))
    return out_r, out_t


# -- public step --------------------------------------------------------------------------------


def stabilize(capture: Capture, *, markers=None, n_auto: int = 8, reference="neutral", holdout=None):
    """Remove the head's rigid motion from a capture.

    Parameters
    ----------
    capture : Capture
        Input capture (not modified). If it already carries ``head_motion`` (stabilised before),
        the new motion is composed onto it, so world positions are still reproduced.
    markers : sequence of str, optional
        Stable markers to fit (at least 3, valid at the reference frame). Default: choose
        ``n_auto`` markers automatically by lowest non-rigid motion (see module docstring).
    n_auto : int
        Number of markers chosen automatically (>= 3); ignored when ``markers`` is given.
    reference : "neutral" or int
        Frame index whose positions define the head-local frame; default "neutral": the capture's
        rest pose (:attr:`Capture.neutral`: the neutral frame, or the average over the neutral
        window when one is set).
    holdout : sequence of str, optional
        Markers (not in the fit) on which the report measures the residual rigid motion before and
        after. Default: the ``max(3, len(markers) // 2)`` non-fit markers with the lowest
        non-rigidity score after stabilisation — an optimistic, after-the-fact choice; pass
        names chosen independently for an unbiased check.

    Returns
    -------
    capture : Capture
        ``positions`` in the head-local frame (reference-frame world coordinates), shape (F, M, 3);
        ``head_motion`` (F, 4, 4) with ``world = head_motion[f] @ [local, 1]``; a history entry
        ``{"step": "stabilize", ...}``.
    report : StabilizeReport

    Raises
    ------
    MarkerError
        Unknown marker names (the message lists the capture's markers), stable markers invalid at
        the reference frame, fewer than 3 usable markers, or no frame with 3 valid stable markers.
    OptionError
        Bad ``n_auto``, ``reference`` or ``holdout``.
    """
    pos = capture.positions
    if reference == "neutral":
        # the rest pose (averaged over the neutral stretch when one is set): the head-local
        # frame is the rest pose's, and a noisy single frame does not tilt it
        ref_f = capture.neutral_frame
        ref = capture.neutral
    else:
        ref_f = _frame_index(capture, reference, "reference")
        ref = pos[ref_f]

    keep, auto = _stable_markers(capture, ref, ref_f, markers, n_auto)
    rot, _, t = fit_rigid_batch(ref[keep], pos[:, keep])
    good = np.isfinite(rot).all(axis=(1, 2))
    if not good.any():
        raise MarkerError(
            f"no frame has 3 valid stable markers ({list_names(capture.names[i] for i in keep)}); cannot stabilise"
        )
    interpolated = np.flatnonzero(~good)
    if interpolated.size:
        rot, t = _interpolate_motion(rot, t, ref[keep].mean(axis=0), good)

    local = _to_local(pos, rot, t)
    motion = to_matrix(rot, 1.0, t)
    head = motion if capture.head_motion is None else np.matmul(capture.head_motion, motion)

    res = np.linalg.norm(local[:, keep] - ref[keep][None], axis=2)
    nval = np.isfinite(res).sum(axis=1)
    fit_rms = np.sqrt(np.divide(np.nansum(res**2, axis=1), nval, out=np.full(len(res), np.nan), where=nval > 0))
    fit_rms[interpolated] = np.nan
    scores = _scores(local, ref)
    scores[~np.isfinite(ref).all(axis=1)] = np.nan

    hold = _holdout_markers(capture, ref, ref_f, holdout, keep, scores)
    before = after = None
    hold_names = tuple(capture.names[i] for i in hold)
    if len(hold) >= 3:
        before = rigid_motion(pos[:, hold], ref[hold], markers=hold_names)
        after = rigid_motion(local[:, hold], ref[hold], markers=hold_names)

    names = tuple(capture.names[i] for i in keep)
    report = StabilizeReport(
        markers=names,
        auto=auto,
        reference_frame=ref_f,
        scores={n: float(s) for n, s in zip(capture.names, scores)},
        fit_rms=fit_rms,
        interpolated_frames=interpolated.astype(np.int64),
        holdout=hold_names,
        before=before,
        after=after,
        units=capture.units,
    )
    step = {
        "step": "stabilize",
        "markers": list(names),
        "auto": auto,
        "n_auto": int(n_auto) if auto else None,
        "reference_frame": int(ref_f),
        "interpolated_frames": int(interpolated.size),
        "max_fit_rms": report.summary()["max_fit_rms"],
    }
    return capture.replace(step=step, positions=local, head_motion=head), report


def _stable_markers(capture: Capture, ref: np.ndarray, ref_f: int, markers, n_auto: int) -> tuple[np.ndarray, bool]:
    """(indices of the markers the rigid fit uses, whether they were chosen automatically)."""
    if markers is None:
        cands = _candidates(capture, ref)
        n = _check_n_auto(n_auto, len(cands), capture)
        keep, _ = _select(capture.positions, ref, cands, n)
        return keep, True
    keep = np.asarray(_indices(capture, markers, what="stable marker"), dtype=np.int64)
    if len(keep) < 3:
        raise OptionError(f"markers: a rigid fit needs at least 3 stable markers; got {list_names(markers)}")
    bad = [capture.names[i] for i in keep if not np.isfinite(ref[i]).all()]
    if bad:
        raise MarkerError(
            f"stable marker(s) {list_names(bad)} invalid at reference frame {ref_f}; "
            f"choose other markers or another reference frame"
        )
    return keep, False


def _holdout_markers(capture: Capture, ref: np.ndarray, ref_f: int, holdout, keep: np.ndarray,
                     scores: np.ndarray) -> list:
    """Indices of the markers the report measures the residual rigid motion on: ``holdout``
    (checked), else the ``max(3, len(keep) // 2)`` most rigid markers outside the fit."""
    keep_set = set(int(i) for i in keep)
    if holdout is None:
        others = [i for i in np.argsort(np.where(np.isfinite(scores), scores, np.inf), kind="stable")
                  if i not in keep_set and np.isfinite(scores[i])]
        return others[: max(3, len(keep) // 2)]
    hold = _indices(capture, holdout, what="holdout marker")
    overlap = [capture.names[i] for i in hold if i in keep_set]
    if overlap:
        raise OptionError(f"holdout markers {list_names(overlap)} are also stable (fit) markers")
    bad = [capture.names[i] for i in hold if not np.isfinite(ref[i]).all()]
    if bad:
        raise MarkerError(f"holdout marker(s) {list_names(bad)} invalid at reference frame {ref_f}")
    return hold
