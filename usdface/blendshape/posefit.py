"""Pose refit: the solve corrects the head stabilisation and the rest pose with what the rig explains.

Two errors reach every frame of a solved take before the solver sees it, and the rig can tell
them apart from expression once a first solve is known:

- Stabilisation fits each frame's rigid head motion to a few "stable" markers before anything is
  known about the expression; on a face every marker moves with some expression (the forehead
  with the brows, the eye corners with blinks and squints), so the fit takes part of the
  expression for head motion. On the tuning rig's take (``benchmarks/make_heldout_rig.py
  --tuning``: layered curves, 0.3 mm noise, no head motion at all) the head turns up to 1.6
  degrees that never turned, and the mesh error goes from 2.4% (no stabilisation) to 7.0%.
- The rest pose is averaged over the still stretch at the neutral frame
  (:mod:`usdface.capture.rest`); its last frames may already hold the start of an expression too
  slow to tell from the noise, which biases the rest pose along that expression's shapes (on the
  tuning take, averaging frames 0-9 instead of the 5 still ones costs 3.4 points of mesh error).

The refit alternates exact minimisations of the misfit
``sum_f sum_m v_fm |R_f (q_m + o_m + B_m w_f) + t_f - x_fm|^2`` (``x`` the stabilised markers in
mesh space, ``q`` their bound points, ``o`` the rest-pose correction, ``B`` the marker basis):
the weights for fixed pose (the curve solver, all its priors); per frame the rigid correction
(R_f, t_f) for fixed weights (stabilised captures only; weighted Kabsch over every valid marker,
Huber weights so that a marker the rig cannot follow does not turn the head); and ``o`` as the
robust average of ``R_f^T (x_f - t_f) - q`` over the quiet frames of the neutral stretch: those
whose solved weights all stay at or below the solver's support threshold (frames the rig calls
neutral). ``o`` is never fitted to frames with expression, nor with the rig's pose subtracted
(which lets ``o`` and the weights trade: on the tuning rig that drifts, round after round), so
the refit stays put. It stops when the corrected displacements move less than the tolerance
(RMS) or after ``rounds`` rounds.

Chosen on the tuning rig (four takes, seeds 15-18 of ``make_heldout_rig.py --tuning``,
stabilised): mesh error 3.46% mean with the head refit alone, 3.28% with the rest refit over the
quiet frames; "quiet" as "the pose moves the markers less than the noise" 3.78%, and with the
pose subtracted 3.04% but drifting to twice the error in 16 rounds on a short take.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..capture.rest import HUBER_K, robust_rest_pose
from ..capture.rigid import fit_rigid_batch, rotation_angle, to_matrix
from .parameters import DEFAULT_POSE_REFIT_ROUNDS, DEFAULT_SUPPORT_THRESHOLD

__all__ = ["PoseRefit", "refit_pose", "rigid_corrections", "DEFAULT_POSE_REFIT_ROUNDS"]

#: reweighting passes of the Huber-weighted rigid fit per round
_KABSCH_PASSES = 3
#: median |n| of a 3D standard normal vector
_MEDIAN_CHI3 = 1.5382


@dataclass
class PoseRefit:
    """What :func:`refit_pose` did.

    Attributes
    ----------
    corrections : ndarray, shape (F, 4, 4) or None
        Per frame, the rigid motion (mesh space, column vectors, cm) of the stabilised markers about
        the rig's pose: ``x ~ corrections[f] @ (q + o + B w_f)``; None when the head was not refitted.
    rest_offset : ndarray, shape (M, 3)
        The rest-pose correction ``o`` (cm; zeros when not refitted).
    rest_frames : list of int
        The neutral-stretch frames ``o`` was averaged over (empty: not refitted).
    rounds : int
        Refit rounds run (0: the first solve only).
    change : float
        RMS change of the corrected displacements in the last round (cm).
    """

    corrections: np.ndarray | None
    rest_offset: np.ndarray
    rest_frames: list
    rounds: int
    change: float

    def summary(self) -> dict:
        out = {"rounds": int(self.rounds), "lastChangeCm": round(float(self.change), 6),
               "restFrames": [int(f) for f in self.rest_frames],
               "restOffsetRmsCm": round(float(np.sqrt((self.rest_offset ** 2).sum(axis=1).mean())), 6)}
        if self.corrections is not None:
            ang = rotation_angle(self.corrections[:, :3, :3])
            out.update(headAngleDegMedian=round(float(np.median(ang)), 4), headAngleDegMax=round(float(ang.max()), 4))
        return out


def rigid_corrections(model, observed, valid) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame rigid ``(R, t)`` with ``observed ~ R model + t``, Huber-weighted over valid markers.

    Parameters
    ----------
    model, observed : ndarray, shape (F, M, 3), float64
        The rig's marker positions and the measured ones (same units); ``observed`` may hold
        anything where ``valid`` is False.
    valid : ndarray, shape (F, M), bool

    Returns
    -------
    R : ndarray (F, 3, 3); t : ndarray (F, 3)
        Identity where a frame has fewer than 3 valid markers.
    """
    import warnings

    x = np.where(valid[:, :, None], observed, 0.0)
    w = valid.astype(np.float64)
    rot = t = None
    for _ in range(_KABSCH_PASSES):
        rot, _, t = fit_rigid_batch(model, x, weights=w)
        bad = ~np.isfinite(rot).all(axis=(1, 2))
        rot[bad] = np.eye(3)
        t[bad] = 0.0
        r = np.linalg.norm(np.matmul(model, rot.transpose(0, 2, 1)) + t[:, None] - x, axis=2)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a frame without valid markers
            scale = np.nanmedian(np.where(valid, r, np.nan), axis=1) / _MEDIAN_CHI3  # per-coordinate sigma
        limit = np.nan_to_num(HUBER_K * scale, nan=np.inf)[:, None]
        w = np.where(r > limit, limit / np.maximum(r, 1e-300), 1.0) * valid
    return rot, t


def refit_pose(solver, displacements, bound_points, *, rate: float, rounds: int = DEFAULT_POSE_REFIT_ROUNDS,
               tolerance: float, solve_options: dict, head: bool = True, rest_frames=None,
               quiet: float = DEFAULT_SUPPORT_THRESHOLD):
    """Solve, correct the head and the rest pose with the rig's pose, solve again (module docstring).

    Parameters
    ----------
    solver : usdface.blendshape.solver.CurveSolver
        Built on the marker basis in cm.
    displacements : ndarray, shape (F, M, 3), float64
        Stabilised marker displacements in mesh space (cm), NaN where invalid.
    bound_points : ndarray, shape (M, 3)
        The markers' bound points on the mesh (cm): where the displacements start.
    rate : float
    rounds : int
        Refit rounds after the first solve (0: the first solve alone).
    tolerance : float
        Stop when the corrected displacements change by less than this (RMS, cm).
    solve_options : dict
        Passed to :meth:`CurveSolver.solve` (max_iterations, tolerance...).
    head : bool
        Refit the head (a stabilised capture); False keeps it.
    rest_frames : (int, int), optional
        The neutral stretch ``start <= f < end``; the rest pose is refitted over its quiet frames
        when it has at least 2 frames (and 2 are quiet). None: the rest pose is kept.
    quiet : float
        A frame is quiet when every solved weight is at most this.

    Returns
    -------
    solution : CurveSolution
        Of the last solve.
    corrected : ndarray (F, M, 3)
        The displacements it solved (cm), NaN where invalid.
    refit : PoseRefit
    """
    d = np.asarray(displacements, dtype=np.float64)
    valid = np.isfinite(d).all(axis=2)
    q = np.asarray(bound_points, dtype=np.float64)
    observed = q[None] + np.where(valid[:, :, None], d, 0.0)
    f_n = d.shape[0]
    rot, t = np.tile(np.eye(3), (f_n, 1, 1)), np.zeros((f_n, 3))
    offset = np.zeros_like(q)
    used: list = []
    stretch = None if rest_frames is None or rest_frames[1] - rest_frames[0] < 2 else tuple(rest_frames)
    current = d
    sol = solver.solve(current, rate=rate, **solve_options)
    change, done = 0.0, 0
    flat_basis = solver.basis.transpose(1, 0, 2).reshape(solver.n_shapes, -1)  # (K, 3M)
    for done in range(1, int(rounds) + 1 if (head or stretch) else 1):
        model_disp = (sol.weights @ flat_basis).reshape(f_n, -1, 3)
        if head:
            rot, t = rigid_corrections(q[None] + offset[None] + model_disp, observed, valid)
        local = np.matmul(observed - t[:, None], rot) - q[None]  # R^T (x - t) - q, row vectors
        if stretch is not None:
            a, b = stretch
            still = a + np.flatnonzero(sol.weights[a:b].max(axis=1) <= quiet)
            if still.size >= 2:
                offset = np.nan_to_num(robust_rest_pose(np.where(valid[still, :, None], local[still], np.nan))[0])
                used = still.tolist()
        corrected = np.where(valid[:, :, None], local - offset[None], np.nan)
        diff = (corrected - current)[valid]
        change = float(np.sqrt((diff ** 2).sum(axis=1).mean())) if diff.size else 0.0
        current = corrected
        sol = solver.solve(current, rate=rate, **solve_options)
        if change < tolerance:
            break
    return sol, current, PoseRefit(to_matrix(rot, 1.0, t) if head else None, offset, used, done, change)
