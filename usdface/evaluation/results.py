"""What the quality evaluation measured: per-shape errors (:func:`shape_errors`), one configuration's
results (:class:`ConfigResult`) and the whole report (:class:`QualityReport`)."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .configs import REGION_NAMES, TransferConfig
from .regions import EvaluationRegions

__all__ = ["shape_errors", "ConfigResult", "QualityReport"]


def shape_errors(predicted, truth, masks) -> tuple[np.ndarray, np.ndarray]:
    """Mean and max vertex error per shape and region.

    Parameters
    ----------
    predicted, truth : array_like, shape (F, N, 3)
        Vertex displacements.
    masks : sequence of ndarray (N,) bool, length R

    Returns
    -------
    mean, max : ndarray, shape (F, R)
        Of ``|predicted - truth|`` over each region's vertices (NaN for an empty region).
    """
    err = np.linalg.norm(np.asarray(predicted, dtype=np.float64) - np.asarray(truth, dtype=np.float64), axis=2)
    F = err.shape[0]
    mean = np.full((F, len(masks)), np.nan)
    mx = np.full((F, len(masks)), np.nan)
    for r, m in enumerate(masks):
        if m.any():
            mean[:, r] = err[:, m].mean(axis=1)
            mx[:, r] = err[:, m].max(axis=1)
    return mean, mx


@dataclass
class ConfigResult:
    """Errors of one :class:`TransferConfig` on every shape (lengths in cm).

    Attributes
    ----------
    config : TransferConfig
    width_cm : float
        Kernel width of the markers (median), cm.
    condition_number : float or None
        Of the interpolation system (None in paper mode).
    n_constraints : int
        Pinned constraint centres used.
    mean_error, max_error : ndarray, shape (F, R)
        Mean / max vertex error per shape and region (:data:`REGION_NAMES` order), cm.
    mean_dy : ndarray, shape (F, R)
        Mean predicted y displacement per region, cm.
    predicted_max : ndarray, shape (F,)
        Largest predicted vertex displacement, cm.
    still_motion : ndarray, shape (F,)
        Mean predicted displacement over the still vertices (NaN when none), cm.
    seconds : float
        Transfer time (fit + apply), excluding the distance matrices.
    min_eigenvalue : float or None
        Smallest eigenvalue of the symmetric part of the kernel matrix (gaussian/IMQ only; < 0:
        not positive definite on these distances), see :meth:`TransferSetup.min_eigenvalue`.
    predictions : ndarray, shape (F, N, 3), optional
        Predicted displacements (mesh units) when ``keep_predictions``.
    """

    config: TransferConfig
    width_cm: float
    condition_number: float | None
    n_constraints: int
    mean_error: np.ndarray
    max_error: np.ndarray
    mean_dy: np.ndarray
    predicted_max: np.ndarray
    still_motion: np.ndarray
    seconds: float = 0.0
    predictions: np.ndarray | None = None
    min_eigenvalue: float | None = None

    def region(self, name: str) -> int:
        return REGION_NAMES.index(name)


@dataclass
class QualityReport:
    """Everything :func:`evaluate` measured.

    Attributes
    ----------
    shape_names : list of str, length F
    skipped : dict name -> reason
    regions : EvaluationRegions
    truth_mean : ndarray (F,)
        Mean true vertex displacement (over the whole face), cm: the denominator of the % errors.
    truth_max, marker_max : ndarray (F,)
        Largest true vertex / marker displacement, cm.
    truth_dy : ndarray (F, R)
        Mean true y displacement per region, cm.
    results : list of ConfigResult
    settings : dict
        Radii, hybrid parameters, marker spacing, units, timings.
    """

    shape_names: list
    skipped: dict
    regions: EvaluationRegions
    truth_mean: np.ndarray
    truth_max: np.ndarray
    marker_max: np.ndarray
    truth_dy: np.ndarray
    results: list
    settings: dict = field(default_factory=dict)

    def result(self, config: TransferConfig) -> ConfigResult:
        for r in self.results:
            if r.config == config:
                return r
        raise KeyError(config.label)

    def shape(self, name: str) -> int:
        return self.shape_names.index(name)

    def subset(self, shape_names) -> "QualityReport":
        """The same report restricted to ``shape_names`` (in that order)."""
        idx = np.array([self.shape(n) for n in shape_names], dtype=np.int64)
        results = [replace(r, mean_error=r.mean_error[idx], max_error=r.max_error[idx], mean_dy=r.mean_dy[idx],
                           predicted_max=r.predicted_max[idx], still_motion=r.still_motion[idx],
                           predictions=None if r.predictions is None else r.predictions[idx])
                   for r in self.results]
        return replace(self, shape_names=[self.shape_names[i] for i in idx], truth_mean=self.truth_mean[idx],
                       truth_max=self.truth_max[idx], marker_max=self.marker_max[idx], truth_dy=self.truth_dy[idx],
                       results=results, settings={**self.settings, "shapes": int(idx.size)})

    def percent(self, res: ConfigResult, region: str = "face", which: str = "mean") -> np.ndarray:
        """(F,) error in region as % of each shape's mean displacement."""
        arr = res.mean_error if which == "mean" else res.max_error
        return 100.0 * arr[:, REGION_NAMES.index(region)] / self.truth_mean


