"""Whole-take figures of a quality report, and the hold-out split they are reported on.

Definitions (issue 19, a shape playing the part of a frame):

``mesh error``
    Over the shapes whose mean true vertex displacement (over every face vertex) exceeds
    ``min_mean_cm`` (0.05 cm = 0.5 mm by default: the face moves), the sum of the shapes' mean
    vertex errors over the sum of their mean true displacements, in %. Unlike the README's
    "mean of per-shape %", big motions weigh more than small ones, as in a take.
``jaw-drop mouth error``
    The mean vertex error (cm) over the vertices within 1.5 cm of the mouth's hole loop (the
    ``mouth`` region of :mod:`usdface.evaluation.regions`) on the ``jawOpen`` shape.

A hold-out split (:class:`HeldOutSplit`, read from a JSON file such as
``benchmarks/heldout_split.json``) names the shapes defaults are tuned on and the shapes they are
reported on.
"""
from __future__ import annotations

import fnmatch
import json
from dataclasses import dataclass
from typing import TYPE_CHECKING
from pathlib import Path

import numpy as np

from ..errors import InputError, OptionError, list_names
from .configs import REGION_NAMES

if TYPE_CHECKING:  # annotations only: results' summaries use these figures
    from .results import ConfigResult, QualityReport

__all__ = ["MESH_ERROR_MIN_MEAN_CM", "JAW_DROP_SHAPE", "HeldOutSplit", "read_split", "mesh_error",
           "jaw_drop_mouth_error"]

#: a shape counts in the mesh error when its mean true vertex displacement exceeds this (cm)
MESH_ERROR_MIN_MEAN_CM = 0.05
#: the shape of the jaw-drop mouth error
JAW_DROP_SHAPE = "jawOpen"


@dataclass(frozen=True)
class HeldOutSplit:
    """Shape names to tune on and to report on.

    Attributes
    ----------
    tuning, heldout : tuple of str
        Disjoint.
    exclude : tuple of str
        Glob patterns of shapes in neither set.
    source : str
        Where the split was read from.
    """

    tuning: tuple
    heldout: tuple
    exclude: tuple = ()
    source: str = ""

    def __post_init__(self) -> None:
        both = sorted(set(self.tuning) & set(self.heldout))
        if both:
            raise InputError(f"split {self.source}: shapes both tuned on and held out: {list_names(both)}")

    def reverse(self) -> "HeldOutSplit":
        """The same split with the roles swapped (the check)."""
        return HeldOutSplit(self.heldout, self.tuning, self.exclude, f"{self.source} (reversed)")

    def check(self, names) -> None:
        """Every named shape exists in ``names`` (the shapes file); excluded names are in neither set."""
        have = set(names)
        missing = [n for n in self.tuning + self.heldout if n not in have]
        if missing:
            raise InputError(f"split {self.source}: shapes {list_names(missing)} are not in the shapes file")
        bad = [n for n in self.tuning + self.heldout if any(fnmatch.fnmatchcase(n, p) for p in self.exclude)]
        if bad:
            raise InputError(f"split {self.source}: excluded shapes {list_names(bad)} are in a set")


def read_split(path) -> HeldOutSplit:
    """Read a split JSON: ``{"tuning": [...], "heldout": [...], "exclude_patterns": [...]}``."""
    p = Path(path)
    try:
        data = json.loads(p.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"split {p}: cannot read it as JSON ({exc})") from None
    try:
        return HeldOutSplit(tuple(data["tuning"]), tuple(data["heldout"]), tuple(data.get("exclude_patterns", ())),
                            str(p))
    except (KeyError, TypeError):
        raise InputError(f"split {p}: expected lists 'tuning' and 'heldout'") from None


def _indices(report: QualityReport, shapes) -> np.ndarray:
    if shapes is None:
        return np.arange(len(report.shape_names))
    missing = [s for s in shapes if s not in report.shape_names]
    if missing:
        raise OptionError(f"shapes {list_names(missing)} were not evaluated")
    return np.array([report.shape(s) for s in shapes], dtype=np.int64)


def mesh_error(report: QualityReport, result: ConfigResult, *, shapes=None, region: str = "face",
               min_mean_cm: float = MESH_ERROR_MIN_MEAN_CM) -> float:
    """Issue 19's mesh error, in % (see the module docstring).

    Parameters
    ----------
    report : QualityReport
    result : ConfigResult
        One of ``report.results``.
    shapes : sequence of str, optional
        Restrict to these shapes (default every evaluated shape).
    region : str
        Region whose mean vertex error is summed (default the whole face); the denominator is always
        the face's mean true displacement.
    min_mean_cm : float
        Shapes whose mean true displacement is at most this (cm) are left out; 0 keeps all.

    Returns
    -------
    float
        ``100 * sum(mean error) / sum(mean true displacement)``; NaN when no shape qualifies.
    """
    idx = _indices(report, shapes)
    keep = idx[report.truth_mean[idx] > min_mean_cm]
    if keep.size == 0:
        return float("nan")
    err = result.mean_error[keep, REGION_NAMES.index(region)]
    return float(100.0 * err.sum() / report.truth_mean[keep].sum())


def jaw_drop_mouth_error(report: QualityReport, result: ConfigResult, *, shape: str = JAW_DROP_SHAPE) -> float:
    """Mean vertex error (cm) within 1.5 cm of the mouth's hole loop on ``shape`` (NaN if not evaluated)."""
    if shape not in report.shape_names:
        return float("nan")
    return float(result.mean_error[report.shape(shape), REGION_NAMES.index("mouth")])
