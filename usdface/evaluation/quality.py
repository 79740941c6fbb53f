"""Quality of the RBF transfer against ground-truth expression shapes (pure numpy, no pxr).

The test
--------
Given a face mesh, its hole regions (:func:`usdface.mesh.topology.find_hole_regions`), a marker
binding and a set of ground-truth expression shapes (per-vertex displacements, e.g. the 52
artist-made ARKit shapes of the MakeHuman sample face), each shape is treated as one capture frame:

1. marker displacements = the shape's displacement at the bound marker points (barycentric
   interpolation of the vertex displacements, :meth:`Binding.surface_points`);
2. those are transferred to every vertex with one :class:`TransferConfig` (distance method,
   RBF mode, kernel, kernel width, pinned border), exactly as the pipeline does it: centres =
   markers + pinned constraint vertices (:func:`usdface.mesh.regions.constraint_vertices`, thinned
   to the median nearest-marker spacing, kept 0.5 spacing away from the markers), hybrid seeds =
   the mouth and eye loops;
3. the per-vertex error ``|predicted - true|`` is summarised per shape over the whole face and per
   error region (below), in cm and as % of the shape's mean displacement (mean over all vertices
   of ``|true displacement|``).

Shapes whose largest vertex displacement is under :data:`MIN_SHAPE_DISPLACEMENT_CM` (1 mm) are
skipped (their % errors are meaningless).

Error regions (fixed here, not tuned on results)
-------------------------------------------------
``R`` = :data:`REGION_RADIUS_CM` (1.5 cm). Distances are Euclidean, to the nearest *vertex* of a
hole loop.

``face``
    every vertex.
``mouth``
    vertices within R of the mouth loop.
``eyes``
    vertices within R of either eye loop (not in ``mouth``).
``rest``
    every other vertex.

Each hole loop (mouth, each eye) is split at its two extreme-x vertices (the corners) into an upper
and a lower rim (the rim with the larger mean y is the upper one). Its *centre line* is
``c(x) = (y_upper(x) + y_lower(x)) / 2``, each rim's y linearly interpolated in x. With ``x_a <
x_b`` the corners' x:

``upperLip`` / ``lowerLip``
    ``mouth`` vertices with ``x_a < x < x_b`` and ``y > c(x)`` / ``y < c(x)``.
``leftUpperLid`` / ``leftLowerLid`` (and ``right...``)
    vertices within R of that eye's loop with ``x_a < x < x_b`` and ``y > c(x)`` / ``y < c(x)``.

+Y is up and the performer's left is +X (the convention of :func:`find_hole_regions`).

The paper's claim, made measurable
----------------------------------
Seed 000 says Euclidean distances make artifacts around the holes that geodesic / hybrid distances
fix. :func:`claim_numbers` gives, per configuration, on ``jawOpen`` the ``upperLip`` error (the
lower-lip markers are Euclidean-close to the upper lip, which should stay) and on ``eyeBlinkLeft``
/ ``eyeBlinkRight`` the lower-lid error of the blinking eye (the upper-lid marker is close to the
lower lid, which should stay), with the mean vertical (y) displacement predicted vs true in that
region (a negative predicted dy on the upper lip in jawOpen is the lip being dragged down).

Other measures
--------------
``still motion``
    mean ``|predicted displacement|`` over the vertices the shape does not move
    (``|true| < STILL_CM`` = 0.5 mm): motion leaking away from the markers.
``overshoot``
    largest predicted vertex displacement over the largest marker displacement, and over the
    largest true vertex displacement.
"""
from __future__ import annotations

import fnmatch
import time

import numpy as np

from ..errors import InputError, OptionError, list_names
from ..model.mesh import Binding, FaceMesh, Region
# the evaluation's parts, one module each; their names stay importable from here
from .configs import (AUTHORS_WIDTH_CM, METHODS, MIN_SHAPE_DISPLACEMENT_CM, MODES, PINS, REGION_NAMES,
                      REGION_RADIUS_CM, STILL_CM, TABLE_REGIONS, TransferConfig, default_configs, parse_configs)
from .regions import EvaluationRegions, evaluation_regions, loop_rims, pinned_vertices
from .results import ConfigResult, QualityReport, shape_errors
from .setup import TransferSetup
from .tables import (claim_numbers, format_claim_table, format_overshoot_table, format_report, format_shape_table,
                     format_summary_table, report_summary, summary_rows)

__all__ = [
    "MIN_SHAPE_DISPLACEMENT_CM",
    "REGION_RADIUS_CM",
    "STILL_CM",
    "AUTHORS_WIDTH_CM",
    "METHODS",
    "MODES",
    "PINS",
    "REGION_NAMES",
    "TABLE_REGIONS",
    "TransferConfig",
    "EvaluationRegions",
    "ConfigResult",
    "QualityReport",
    "TransferSetup",
    "default_configs",
    "parse_configs",
    "select_shapes",
    "evaluation_regions",
    "loop_rims",
    "marker_displacements",
    "pinned_vertices",
    "shape_errors",
    "evaluate",
    "summary_rows",
    "report_summary",
    "claim_numbers",
    "format_summary_table",
    "format_claim_table",
    "format_shape_table",
    "format_overshoot_table",
    "format_report",
]


# ------------------------------------------------------------------------------------------------
# shapes
# ------------------------------------------------------------------------------------------------

def select_shapes(names, deltas, *, min_displacement: float = MIN_SHAPE_DISPLACEMENT_CM, only=None,
                  skip=None) -> tuple[list[str], np.ndarray, dict[str, str]]:
    """Keep the shapes worth evaluating.

    Parameters
    ----------
    names : sequence of str, length F
    deltas : array_like, shape (F, N, 3)
        Per-vertex displacements (same units as ``min_displacement``).
    min_displacement : float
        Skip a shape whose largest vertex displacement is below this (default 0.1 = 1 mm in cm).
    only : sequence of str, optional
        Keep only shapes matching one of these names or glob patterns (``"eyeBlink*"``).
    skip : sequence of str, optional
        Skip shapes matching one of these names or glob patterns.

    Returns
    -------
    names : list of str
    deltas : ndarray, shape (F', N, 3), float64
    skipped : dict name -> reason
    """
    names = [str(n) for n in names]
    d = np.asarray(deltas, dtype=np.float64)
    if d.ndim != 3 or d.shape[0] != len(names) or d.shape[2] != 3:
        raise InputError(f"shapes: deltas must have shape (F={len(names)}, N, 3); got {d.shape}")
    mx = np.linalg.norm(d, axis=2).max(axis=1) if d.shape[1] else np.zeros(len(names))
    keep, skipped = [], {}
    if only:
        unmatched = [p for p in only if not any(fnmatch.fnmatchcase(n, p) for n in names)]
        if unmatched:
            raise OptionError(f"shapes {list_names(unmatched)} not found; the shapes are {list_names(names, limit=60)}")
    for i, n in enumerate(names):
        if only and not any(fnmatch.fnmatchcase(n, p) for p in only):
            continue
        if skip and any(fnmatch.fnmatchcase(n, p) for p in skip):
            skipped[n] = "skipped by name"
        elif not mx[i] >= min_displacement:
            skipped[n] = f"largest displacement {mx[i]:.3g} < {min_displacement:g}"
        else:
            keep.append(i)
    return [names[i] for i in keep], d[keep], skipped


def marker_displacements(binding: Binding, deltas) -> np.ndarray:
    """The shapes' displacements at the bound marker points.

    Parameters
    ----------
    binding : Binding
    deltas : array_like, shape (F, N, 3)

    Returns
    -------
    ndarray, shape (F, M, 3), float64
        ``sum_k b_mk * deltas[f, tri_mk]``: what a perfect capture of the shape would give.
    """
    d = np.asarray(deltas, dtype=np.float64)
    return np.einsum("mk,fmkd->fmd", binding.barycentrics, d[:, binding.triangle_vertices])


# ------------------------------------------------------------------------------------------------
# the evaluation
# ------------------------------------------------------------------------------------------------

def evaluate(mesh: FaceMesh, regions: list[Region], binding: Binding, shape_names, deltas, *,
             configs=None, still_cm: float = STILL_CM, keep_predictions: bool = False, skipped: dict | None = None,
             setup: TransferSetup | None = None) -> QualityReport:
    """Transfer every shape's marker displacements with every configuration; measure the errors.

    Parameters
    ----------
    mesh : FaceMesh
        The neutral face; ``units`` None counts as cm.
    regions : list of Region
        Its hole regions (outerBorder, mouth, eyes; plus pinned/rigid regions if any).
    binding : Binding
        Markers bound on ``mesh``.
    shape_names : sequence of str, length F
    deltas : array_like, shape (F, N, 3)
        True vertex displacements (mesh units); see :func:`select_shapes` to drop tiny shapes.
    configs : sequence of TransferConfig, optional
        Default :func:`default_configs`.
    still_cm : float
        "Still" vertex threshold for the leak measure (cm).
    keep_predictions : bool
        Keep every config's (F, N, 3) predictions (mesh units) in the result.
    skipped : dict, optional
        Shapes dropped beforehand (name -> reason), carried into the report.
    setup : TransferSetup, optional
        The distance matrices for this mesh and binding (reused across calls) and the radii they
        are made with: ``region_radius_cm``, the error-region radius around the mouth/eye loops
        (cm); ``hybrid_radius_cm``, ``hybrid_sigma_cm``, ``hybrid_threshold``, the hybrid distance
        parameters (a config's ``threshold`` overrides the last). Default: a TransferSetup with
        the pipeline's (:data:`REGION_RADIUS_CM`, 1 cm, 2 cm, 0.6).

    Returns
    -------
    QualityReport
        Errors in cm.
    """
    t_start = time.perf_counter()
    configs = list(default_configs() if configs is None else configs)
    if not configs:
        raise OptionError("evaluate: no configurations given")
    names = [str(n) for n in shape_names]
    truth = np.asarray(deltas, dtype=np.float64)
    N = mesh.n_points
    if truth.ndim != 3 or truth.shape != (len(names), N, 3):
        raise InputError(f"shapes: deltas must have shape (F={len(names)}, N={N}, 3) for mesh "
                         f"{mesh.source or mesh.name}; got {truth.shape}")
    if len(names) == 0:
        raise InputError("evaluate: no shapes to evaluate")
    if setup is None:
        setup = TransferSetup(mesh, regions, binding)
    cm = setup.cm
    to_cm = 1.0 / cm
    M = binding.n_markers
    ev = setup.regions
    masks = [ev[r] for r in REGION_NAMES]
    disp = marker_displacements(binding, truth)

    truth_norm = np.linalg.norm(truth, axis=2)
    truth_mean = truth_norm.mean(axis=1) * to_cm
    truth_max = truth_norm.max(axis=1) * to_cm
    marker_max = np.linalg.norm(disp, axis=2).max(axis=1) * to_cm
    still = truth_norm < still_cm * cm
    truth_dy = _region_means(truth[:, :, 1], masks) * to_cm

    results = []
    for cfg in configs:
        setup.matrices(cfg)
        t0 = time.perf_counter()
        rbf = setup.transfer(cfg)
        pred = rbf.apply(disp, dtype=np.float64)
        mean_e, max_e = shape_errors(pred, truth, masks)
        pred_norm = np.linalg.norm(pred, axis=2)
        still_motion = np.array([pred_norm[f, still[f]].mean() if still[f].any() else np.nan
                                 for f in range(len(names))])
        results.append(ConfigResult(
            config=cfg, width_cm=float(np.median(rbf.widths[:M])) * to_cm, condition_number=rbf.condition_number,
            n_constraints=int(setup.constraints(cfg).size), mean_error=mean_e * to_cm, max_error=max_e * to_cm,
            mean_dy=_region_means(pred[:, :, 1], masks) * to_cm, predicted_max=pred_norm.max(axis=1) * to_cm,
            still_motion=still_motion * to_cm, seconds=time.perf_counter() - t0,
            predictions=pred if keep_predictions else None,
            min_eigenvalue=setup.min_eigenvalue(cfg, rbf.widths)))
    settings = {
        "units": setup.units, "vertices": int(N), "markers": int(M), "shapes": len(names),
        "regionRadiusCm": setup.region_radius_cm, "hybridRadiusCm": setup.hybrid_radius_cm,
        "hybridSigmaCm": setup.hybrid_sigma_cm, "hybridThreshold": setup.hybrid_threshold, "stillCm": still_cm,
        "markerSpacingCm": setup.spacing * to_cm,
        "pinnedCentres": {p: int(v.size) for p, v in setup.pins.items()},
        "mouthCornerY": ev.corner_y, "distanceSeconds": dict(setup.seconds),
        "seconds": round(time.perf_counter() - t_start, 3),
    }
    return QualityReport(names, dict(skipped or {}), ev, truth_mean, truth_max, marker_max, truth_dy, results,
                         settings)


def _region_means(values: np.ndarray, masks) -> np.ndarray:
    """(F, R) mean of ``values`` (F, N) over each mask (NaN for an empty one)."""
    F = values.shape[0]
    return np.stack([values[:, m].mean(axis=1) if m.any() else np.full(F, np.nan) for m in masks], axis=1)
