"""Kernel widths ("stiffness" in the authors' plug-in): the default rules and per-marker overrides.

Default rule of the interpolating transfer (:data:`LOCAL_WIDTH_RULE`)
-------------------------------------------------------------------
Metric-aware and per marker: marker j's width is ``LOCAL_WIDTH_FACTOR`` (0.7) times its *local
spacing*, the mean distance to its ``LOCAL_NEIGHBOURS`` (3) nearest other markers, measured in the
metric of the centre-to-centre matrix the transfer uses (Euclidean, edge-path or fast-marching
geodesic, hybrid); constraint centres get 0.7 times the median local spacing of the markers. The
width follows the marker layout: wide where markers are sparse (forehead, cheeks: 1.5-1.9x the
median), narrow where they are dense (lips, lids). Chosen on the tuning shapes of
``benchmarks/heldout_split.json`` (brow, eye, nose, cheek; ``python benchmarks/rbf_heldout.py``,
section 2): the factor minimises the tuning mesh error for every distance method (0.7 for
Euclidean, geodesic and hybrid, on edge paths and fast marching alike), and 3 neighbours beat
1, 2, 4 and 6; the figures held out (mouth, jaw) are in the README.

Why the metric: the previous rule (1.1 x the median nearest-marker distance, always measured with
Euclidean distances) was tuned on edge-path geodesics, which run 8-15% long: on accurate
(fast-marching) geodesics the same width is 8-15% wider relative to the distances, and the transfer
lost (hybrid face error 62.0% against 57.7% with edge paths). Measured in the distance's own metric,
the width scales with what the kernel sees, and fast marching transfers at least as well as edge
paths at the default width.

Kernels that grow with distance
-------------------------------
The per-marker rule is for the positive definite kernels (gaussian, inverse multiquadric). The
conditionally positive definite ones (multiquadric, thin-plate spline, cubic) get one width for every
centre (:data:`GROWING_WIDTH_RULES`): their polynomial moment conditions act on the weights, and
per-column widths rescale the weights, so per-marker widths would change the interpolant they
define (measured: the thin-plate spline's error tripled). For thin-plate spline and cubic with
their polynomial a uniform width is only a scale (1 x the median nearest-marker distance, for the
conditioning); for the multiquadric it is a shape parameter: 0.1 x the median spacing (the
multiquadric then behaves like ``|r|``) minimised its tuning error (63.8%, against 77.4% at 1 x
and 104% at 2 x).

Paper mode (:data:`PAPER_WIDTH_RULE`)
-------------------------------------
``width = 1.1 * h`` for every centre, ``h`` the median over the markers of each marker's Euclidean
distance to its nearest other marker: 2.0 cm on the sample layouts, the authors' fixed 2 cm
expressed relative to the marker spacing (pass ``widths=2.0`` (cm) to reproduce their plug-in). It
is the rule every transfer used before the local rule; ``--rbf paper`` keeps it.

History of that rule: the first rule (1.5 h, fixed before any evaluation) made the Gaussian of
geodesic or hybrid distances indefinite on the MakeHuman face (smallest kernel-matrix eigenvalue
-0.08) and the exact geodesic interpolant explode (errors up to 120 cm); at 1.1 h = 2 cm every
method's kernel matrix is positive definite. A Gaussian of width s interpolating a constant on a
regular grid of spacing h ripples by about ``2 exp(-pi**2 s**2 / h**2)`` (4e-3 at s = 0.8 h, 1e-4
at s = h), so widths near the spacing reproduce smooth motion; what wider kernels add is leakage
into the still parts of the face and, on geodesic distances, a loss of positive definiteness.

Overrides
---------
``widths`` may be:

- ``None``: the default rule for every centre;
- a positive scalar (mesh units): that width for every centre (markers and constraint centres);
- a sequence of M (markers only; constraint centres keep the default) or C (every centre) widths;
- a dict ``{marker name: width}``: those markers get the given width, every other centre the
  default. Unknown names raise :class:`~usdface.errors.OptionError` listing the markers.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ComputeError, OptionError, list_names
from .kernels import canonical_kernel_name

__all__ = [
    "DEFAULT_WIDTH_FACTOR",
    "LOCAL_WIDTH_FACTOR",
    "LOCAL_NEIGHBOURS",
    "WidthRule",
    "LOCAL_WIDTH_RULE",
    "PAPER_WIDTH_RULE",
    "GROWING_WIDTH_RULES",
    "median_marker_spacing",
    "median_marker_spacing_from_points",
    "local_marker_spacing",
    "default_width",
    "resolve_widths",
    "transfer_widths",
    "default_width_rule",
    "WIDTH_RULE_WORDS",
    "width_source",
]

#: paper-mode (and former) kernel width as a multiple of the median Euclidean nearest-marker distance
DEFAULT_WIDTH_FACTOR = 1.1
#: default kernel width of the interpolating transfer, as a multiple of each marker's local spacing
LOCAL_WIDTH_FACTOR = 0.7
#: nearest other markers whose mean distance is a marker's local spacing
LOCAL_NEIGHBOURS = 3


def median_marker_spacing(D_mm) -> float:
    """Median nearest-neighbour distance among markers.

    Parameters
    ----------
    D_mm : array_like, shape (M, M), float
        Marker-to-marker distances (mesh units), M >= 2; may be asymmetric (row j is measured from
        marker j). The diagonal is ignored.

    Returns
    -------
    float
        ``median_j min_{k != j} D_mm[j, k]`` in mesh units.

    Raises
    ------
    ComputeError
        Fewer than two markers, or the median is not a positive finite number (e.g. most markers
        coincide).
    """
    d = np.array(D_mm, dtype=np.float64)  # a copy: the diagonal is overwritten
    if d.ndim != 2 or d.shape[0] != d.shape[1]:
        raise OptionError(f"marker distances must be a square (M, M) matrix; got shape {d.shape}")
    if d.shape[0] < 2:
        raise ComputeError("marker spacing needs at least 2 markers; the default kernel width cannot be derived")
    np.fill_diagonal(d, np.inf)
    d[np.isnan(d)] = np.inf
    h = float(np.median(d.min(axis=1)))
    if not (np.isfinite(h) and h > 0):
        raise ComputeError(
            f"median nearest-marker distance is {h}; markers coincide or are unreachable: "
            "give kernel widths explicitly"
        )
    return h


def median_marker_spacing_from_points(points) -> float:
    """Median nearest-neighbour Euclidean distance among marker points.

    Parameters
    ----------
    points : array_like, shape (M, 3), float
        Marker positions (mesh units).

    Returns
    -------
    float
        See :func:`median_marker_spacing`.
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise OptionError(f"marker points must have shape (M, 3); got {p.shape}")
    diff = p[:, None, :] - p[None, :, :]
    return median_marker_spacing(np.sqrt(np.einsum("ijk,ijk->ij", diff, diff)))


def local_marker_spacing(D_mm, neighbours: int = LOCAL_NEIGHBOURS) -> np.ndarray:
    """Each marker's mean distance to its ``neighbours`` nearest other markers.

    Parameters
    ----------
    D_mm : array_like, shape (M, M), float
        Marker-to-marker distances (mesh units), M >= 2, in any metric; may be asymmetric (hybrid
        rows use the row marker's weight): a pair's distance is the smaller of its two entries, so
        it does not depend on which end measured it. The diagonal is ignored; ``inf`` (unreachable)
        entries are skipped.
    neighbours : int
        k >= 1; markers with fewer reachable neighbours average those they have.

    Returns
    -------
    ndarray, shape (M,), float64
        Local spacing per marker (mesh units).

    Raises
    ------
    ComputeError
        Fewer than two markers, or a marker with no reachable neighbour at a positive distance.
    """
    d = np.array(D_mm, dtype=np.float64)
    if d.ndim != 2 or d.shape[0] != d.shape[1]:
        raise OptionError(f"marker distances must be a square (M, M) matrix; got shape {d.shape}")
    if isinstance(neighbours, bool) or not isinstance(neighbours, (int, np.integer)) or neighbours < 1:
        raise OptionError(f"neighbours: expected an integer >= 1; got {neighbours!r}")
    M = d.shape[0]
    if M < 2:
        raise ComputeError("marker spacing needs at least 2 markers; the default kernel width cannot be derived")
    d[np.isnan(d)] = np.inf
    d = np.minimum(d, d.T)
    np.fill_diagonal(d, np.inf)
    k = min(int(neighbours), M - 1)
    near = np.sort(d, axis=1)[:, :k]
    finite = np.isfinite(near)
    count = finite.sum(axis=1)
    out = np.where(finite, near, 0.0).sum(axis=1) / np.maximum(count, 1)
    bad = (count == 0) | ~(out > 0)
    if bad.any():
        raise ComputeError(
            f"{int(bad.sum())} marker(s) (e.g. #{int(np.flatnonzero(bad)[0])}) have no other marker at a positive "
            "reachable distance; markers coincide or are unreachable: give kernel widths explicitly"
        )
    return out


@dataclass(frozen=True)
class WidthRule:
    """A default kernel-width rule: ``factor`` x a marker spacing in the transfer's metric.

    Attributes
    ----------
    factor : float
        Multiple of the spacing (> 0).
    neighbours : int
        Per-marker rule: the local spacing is the mean distance to this many nearest markers.
    per_marker : bool
        True: marker j gets ``factor * local_spacing[j]`` and constraint centres ``factor *
        median(local_spacing)``; False: every centre gets ``factor * median nearest-marker
        distance`` (:func:`median_marker_spacing`, row minima as given).
    name : str
        For reports and provenance.
    """

    factor: float
    neighbours: int = 1
    per_marker: bool = False
    name: str = "median"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.factor) and self.factor > 0):
            raise OptionError(f"width factor must be a positive number; got {self.factor!r}")

    def widths(self, D_cc, n_markers: int) -> np.ndarray:
        """Width of every centre (mesh units), shape (C,), from the centre-to-centre distances.

        Parameters
        ----------
        D_cc : array_like, shape (C, C), float
            Centre-to-centre distances (mesh units), markers first; only the marker block is read.
        n_markers : int
            Number of markers M (<= C).
        """
        d = np.asarray(D_cc)
        C = int(d.shape[0])
        block = d[:n_markers, :n_markers]
        if not self.per_marker:
            return np.full(C, float(self.factor) * median_marker_spacing(block))
        local = local_marker_spacing(block, self.neighbours)
        out = np.full(C, float(self.factor) * float(np.median(local)))
        out[:n_markers] = float(self.factor) * local
        return out

    def describe(self) -> str:
        if self.per_marker:
            return (f"{self.factor:g} x each marker's mean distance to its {self.neighbours} nearest markers, "
                    "in the transfer's metric")
        return f"{self.factor:g} x the median nearest-marker distance"


#: default of the interpolating transfer (see the module docstring)
LOCAL_WIDTH_RULE = WidthRule(LOCAL_WIDTH_FACTOR, LOCAL_NEIGHBOURS, per_marker=True, name="local")
#: paper mode: 1.1 x the median nearest-marker distance (Euclidean, see :func:`transfer_widths`)
PAPER_WIDTH_RULE = WidthRule(DEFAULT_WIDTH_FACTOR, 1, per_marker=False, name="paper")
#: interpolate mode, kernels growing with distance: one width, a multiple of the median spacing in
#: the transfer's metric (see the module docstring)
GROWING_WIDTH_RULES = {
    "multiquadric": WidthRule(0.1, 1, per_marker=False, name="uniform"),
    "thin_plate_spline": WidthRule(1.0, 1, per_marker=False, name="uniform"),
    "cubic": WidthRule(1.0, 1, per_marker=False, name="uniform"),
}


#: how a printed line names where the width it shows comes from, per rule name
WIDTH_RULE_WORDS = {"local": "median of the per-marker widths", "paper": "1.1 x the median marker spacing",
                    "uniform": "one width for every centre"}


def width_source(stiffness, rule: str) -> str:
    """Where a printed (median) width comes from: ``--stiffness``, or the default rule's words.

    Parameters
    ----------
    stiffness : None, float or dict
        The transfer's ``stiffness`` option (:func:`parse_stiffness`): None for the default rule, one
        width for every marker, or {marker: width} for some (the rule gives the others).
    rule : str
        The rule's name (:attr:`WidthRule.name`).
    """
    if stiffness is not None and not isinstance(stiffness, dict):
        return "--stiffness"
    return WIDTH_RULE_WORDS.get(rule, rule) + (" and --stiffness" if stiffness is not None else "")


def default_width_rule(kernel: str = "gaussian", mode: str = "interpolate") -> WidthRule:
    """The default width rule of ``kernel`` in ``mode`` (see the module docstring)."""
    if mode == "paper":
        return PAPER_WIDTH_RULE
    if mode != "interpolate":
        raise OptionError(f"mode: expected interpolate or paper; got {mode!r}")
    return GROWING_WIDTH_RULES.get(canonical_kernel_name(kernel), LOCAL_WIDTH_RULE)


def default_width(D_cc, n_markers: int, *, factor: float = DEFAULT_WIDTH_FACTOR) -> float:
    """Default kernel width: ``factor`` times the median nearest-marker distance.

    Parameters
    ----------
    D_cc : array_like, shape (C, C), float
        Centre-to-centre distances (mesh units); the first ``n_markers`` centres are the markers.
    n_markers : int
        Number of markers M (<= C).
    factor : float
        Multiple of the marker spacing, > 0 (default :data:`DEFAULT_WIDTH_FACTOR`).

    Returns
    -------
    float
        Width in mesh units.
    """
    if not (np.isfinite(factor) and factor > 0):
        raise OptionError(f"width factor must be a positive number; got {factor!r}")
    d = np.asarray(D_cc)
    return float(factor) * median_marker_spacing(d[:n_markers, :n_markers])


def _check_positive(values: np.ndarray, labels: Sequence[str]) -> None:
    bad = ~(np.isfinite(values) & (values > 0))
    if bad.any():
        shown = [f"{labels[i]}={float(values[i])!r}" for i in np.flatnonzero(bad)]
        raise OptionError(
            f"widths: kernel widths must be positive finite numbers (mesh units); bad: {list_names(shown)}"
        )


def resolve_widths(
    widths,
    D_cc,
    n_markers: int,
    *,
    marker_names: Sequence[str] | None = None,
    factor: float = DEFAULT_WIDTH_FACTOR,
    rule: WidthRule | None = None,
) -> np.ndarray:
    """Per-centre kernel widths from a user specification.

    Parameters
    ----------
    widths : None, float, sequence of float (length M or C), or dict {str: float}
        See the module docstring. Widths are in mesh units.
    D_cc : array_like, shape (C, C), float
        Centre-to-centre distances (mesh units); markers first. Only used for the default rule
        (the median marker spacing is not computed when every width is given).
    n_markers : int
        Number of markers M (the first M centres).
    marker_names : sequence of str, length M, optional
        Marker names; required for a dict and used in messages.
    factor : float
        Factor of the median rule (see :func:`default_width`) when no ``rule`` is given.
    rule : WidthRule, optional
        The default rule for the centres ``widths`` leaves open (e.g. :data:`LOCAL_WIDTH_RULE`);
        None: ``factor`` x the median nearest-marker distance of ``D_cc``.

    Returns
    -------
    ndarray, shape (C,), float64
        Width of every centre (markers first, then constraint centres).

    Raises
    ------
    OptionError
        NaN, infinite, zero or negative widths; a sequence of the wrong length; a dict without
        marker names or naming unknown markers.
    """
    C = int(np.shape(D_cc)[0])
    M = int(n_markers)
    if marker_names is not None and len(marker_names) != M:
        raise OptionError(f"marker_names has {len(marker_names)} names but there are {M} markers")
    names = list(marker_names) if marker_names is not None else [f"marker #{j}" for j in range(M)]
    labels = names + [f"constraint centre #{p}" for p in range(C - M)]

    def default() -> np.ndarray:
        if rule is not None:
            return rule.widths(D_cc, M)
        return np.full(C, default_width(D_cc, M, factor=factor))

    if widths is None:
        return default()
    if isinstance(widths, Mapping):
        if marker_names is None:
            raise OptionError("widths: a {marker: width} dict needs marker_names")
        index = {n: j for j, n in enumerate(names)}
        unknown = [k for k in widths if k not in index]
        if unknown:
            raise OptionError(
                f"widths: unknown marker(s) {list_names(unknown)}; the {M} markers are: {list_names(names, limit=100)}"
            )
        out = default() if len(widths) < C else np.empty(C)
        for k, v in widths.items():
            try:
                out[index[k]] = float(v)
            except (TypeError, ValueError):
                raise OptionError(f"widths: width of marker {k!r} must be a number; got {v!r}") from None
        _check_positive(out, labels)
        return out
    if np.isscalar(widths) or np.ndim(widths) == 0:
        try:
            w = float(widths)
        except (TypeError, ValueError):
            raise OptionError(f"widths: expected a number, a sequence or a dict; got {widths!r}") from None
        out = np.full(C, w)
        _check_positive(out[:1], ["all centres"])
        return out
    try:
        arr = np.asarray(widths, dtype=np.float64)
    except (TypeError, ValueError):
        raise OptionError(f"widths: expected a number, a sequence or a dict; got {widths!r}") from None
    if arr.ndim != 1 or arr.size not in (M, C):
        raise OptionError(
            f"widths: a sequence must have {M} (markers) or {C} (all centres) widths; got shape {arr.shape}"
        )
    if arr.size == C:
        out = arr.copy()
    else:
        out = np.empty(C)
        out[:M] = arr
        if C > M:
            out[M:] = default()[M:]
    _check_positive(out, labels)
    return out


def parse_stiffness(value):
    """--stiffness: None, a number (mesh units, every marker), or a JSON file {marker: width}."""
    if value is None or isinstance(value, (int, float, dict)):
        return value
    try:
        return float(value)
    except ValueError:
        pass
    from pathlib import Path

    from ..inputfiles import read_json

    path = Path(value)
    if not path.exists():
        raise OptionError(f"--stiffness {value}: expected a width in mesh units or a JSON file {{marker: width}}")
    data = read_json(path, label=f"--stiffness {value}")  # a regular file, bounded size and nesting, UTF-8
    if not isinstance(data, dict):
        raise OptionError(f"--stiffness {value}: expected a JSON object {{marker: width}}")
    return data


def transfer_widths(widths, D_cc, n_markers: int, *, mode: str = "interpolate", kernel: str = "gaussian",
                    marker_names: Sequence[str] | None = None, marker_points=None) -> np.ndarray:
    """The kernel width of every centre as the transfer uses it (``--stiffness`` and the default rules).

    Parameters
    ----------
    widths : None, float, sequence or dict
        ``--stiffness`` (see :func:`resolve_widths`); None: the default rule for every centre, or
        for the centres a dict or an M-sequence leaves open.
    D_cc : array_like, shape (C, C), float
        The transfer's centre-to-centre distances (mesh units), markers first: the metric of the
        interpolate rules.
    n_markers : int
        Number of markers M.
    mode : {"interpolate", "paper"}
        ``interpolate``: :func:`default_width_rule` of ``kernel`` on ``D_cc`` (per marker for
        gaussian and inverse multiquadric). ``paper``: :data:`PAPER_WIDTH_RULE`, its spacing
        measured with Euclidean distances between ``marker_points`` (as the paper's fixed width; on
        ``D_cc`` when no points are given).
    kernel : str
        ``--kernel``.
    marker_names : sequence of str, optional
        For a ``{marker: width}`` dict and messages.
    marker_points : array_like, shape (M, 3), optional
        Bound marker points (mesh units), for the paper rule.

    Returns
    -------
    ndarray, shape (C,), float64
        Widths (mesh units).
    """
    rule = default_width_rule(kernel, mode)
    if mode == "paper" and marker_points is not None:
        h = median_marker_spacing_from_points(marker_points)
        C = int(np.shape(D_cc)[0])
        # the Euclidean spacing as a stand-in matrix: the median rule then gives factor x h
        return resolve_widths(widths, np.full((C, C), h), int(n_markers), marker_names=marker_names,
                              factor=rule.factor)
    return resolve_widths(widths, D_cc, n_markers, marker_names=marker_names, rule=rule)
