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
import math
import time
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError, MeshError, OptionError, list_names
from ..model.mesh import Binding, FaceMesh, Region

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
    "claim_numbers",
    "format_summary_table",
    "format_claim_table",
    "format_shape_table",
    "format_overshoot_table",
    "format_report",
]

#: shapes whose largest vertex displacement is below this (cm) are skipped
MIN_SHAPE_DISPLACEMENT_CM = 0.1
#: radius (cm) around the mouth / eye loops defining the mouth and eye error regions
REGION_RADIUS_CM = 1.5
#: vertices moving less than this (cm) in the truth count as "still" (for the leak measure)
STILL_CM = 0.05
#: the kernel width of the authors' plug-in (cm, every marker)
AUTHORS_WIDTH_CM = 2.0

METHODS = ("euclidean", "geodesic", "hybrid")
MODES = ("paper", "interpolate")
#: pinned-border variants: the whole outer border (`--pin-border all`), nothing, or only the part of
#: the outer border above the mouth corners (the jaw's border is left free)
PINS = ("border", "none", "upper")
#: regions of the summary tables
TABLE_REGIONS = ("face", "mouth", "eyes", "rest")
#: every error region, in the column order of :attr:`ConfigResult.mean_error`
REGION_NAMES = ("face", "mouth", "eyes", "rest", "upperLip", "lowerLip", "leftUpperLid", "leftLowerLid",
                "rightUpperLid", "rightLowerLid")

_GEODESIC_ROLES = ("mouth", "eye", "geodesic")


# ------------------------------------------------------------------------------------------------
# configurations
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class TransferConfig:
    """One way of transferring the marker motion.

    Attributes
    ----------
    method : {"euclidean", "geodesic", "hybrid"}
        Distance (paper Eqs. 6, 7, 8).
    mode : {"paper", "interpolate"}
        RBF mode of :class:`usdface.rbf.RBFTransfer` (paper = Eqs. 1-5, weights not solved).
    kernel : str
        RBF kernel (``gaussian`` = paper Eq. 3).
    width_cm : float or None
        Kernel width of every centre in cm; None = the pipeline's rule (1.1 x the median
        Euclidean nearest-marker distance between the bound points).
    polynomial : bool
        Linear polynomial term (interpolate mode).
    pin : {"border", "none", "upper"}
        Which outer-border vertices are zero-displacement centres (no effect in paper mode, where
        constraint centres get zero weight).
    backend : {"graph", "heat", "exact"}
        Geodesic back-end (geodesic and hybrid).
    """

    method: str
    mode: str = "interpolate"
    kernel: str = "gaussian"
    width_cm: float | None = None
    polynomial: bool = False
    pin: str = "border"
    backend: str = "graph"
    threshold: float | None = None

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise OptionError(f"method {self.method!r}: expected one of {', '.join(METHODS)}")
        if self.mode not in MODES:
            raise OptionError(f"mode {self.mode!r}: expected one of {', '.join(MODES)}")
        if self.pin not in PINS:
            raise OptionError(f"pin {self.pin!r}: expected one of {', '.join(PINS)}")
        if self.width_cm is not None and not (math.isfinite(self.width_cm) and self.width_cm > 0):
            raise OptionError(f"width_cm must be a positive number or None; got {self.width_cm!r}")
        if self.mode == "paper" and self.polynomial:
            raise OptionError("polynomial applies to interpolate mode only")
        if self.threshold is not None and (self.method != "hybrid" or not 0.0 <= self.threshold < 1.0):
            raise OptionError(f"threshold applies to the hybrid method and must be in [0, 1); got {self.threshold!r}")

    @property
    def method_label(self) -> str:
        if self.method == "euclidean":
            return self.method
        thr = "" if self.threshold is None else f" thr={self.threshold:g}"
        return f"{self.method}/{self.backend}{thr}"

    @property
    def kernel_label(self) -> str:
        k = {"gaussian": "gauss", "thin_plate_spline": "TPS", "inverse_multiquadric": "IMQ"}.get(self.kernel, self.kernel)
        w = "1.1h" if self.width_cm is None else f"{self.width_cm:g} cm"
        return f"{k} {w}" + (" +poly" if self.polynomial else "")

    @property
    def pin_label(self) -> str:
        return "-" if self.mode == "paper" else self.pin

    @property
    def label(self) -> str:
        return f"{self.method_label} {self.mode} {self.kernel_label} pin={self.pin_label}"

    def same_except_method(self, other: "TransferConfig") -> bool:
        return (self.mode, self.kernel, self.width_cm, self.polynomial, self.pin_label) == \
               (other.mode, other.kernel, other.width_cm, other.polynomial, other.pin_label)


def default_configs(*, methods=METHODS, modes=MODES, pins=PINS, authors_width: bool = True,
                    heat: bool = False, thin_plate: bool = False) -> list[TransferConfig]:
    """The evaluation grid.

    For every method: paper mode with the default width rule (and with the authors' 2 cm when
    ``authors_width``), and interpolate mode (Gaussian, default width rule) with every ``pins``
    variant. ``heat`` adds geodesic/heat interpolate (pin border); ``thin_plate`` adds thin-plate
    spline + linear polynomial interpolate (pin border) for every method.
    """
    out = []
    for method in methods:
        if "paper" in modes:
            out.append(TransferConfig(method, "paper", pin="none"))
            if authors_width:
                out.append(TransferConfig(method, "paper", width_cm=AUTHORS_WIDTH_CM, pin="none"))
        if "interpolate" in modes:
            for pin in pins:
                out.append(TransferConfig(method, "interpolate", pin=pin))
    if heat and "interpolate" in modes and "geodesic" in methods:
        out.append(TransferConfig("geodesic", "interpolate", pin="border", backend="heat"))
    if thin_plate and "interpolate" in modes:
        for method in methods:
            out.append(TransferConfig(method, "interpolate", kernel="thin_plate_spline", polynomial=True,
                                      pin="border"))
    return out


def parse_configs(methods=None, modes=None, pins=None, widths=None, *, backend: str = "graph",
                  heat: bool = False, thin_plate: bool = False) -> list[TransferConfig]:
    """Configurations from CLI-style lists.

    Parameters
    ----------
    methods, modes, pins : sequence of str, optional
        Default: all of :data:`METHODS`, :data:`MODES`, :data:`PINS`.
    widths : sequence of (str or float), optional
        ``"default"`` (the pipeline's rule: 1.1 x the Euclidean median nearest-marker distance h)
        and/or widths in cm; default ``["default"]``.
        Paper mode is run with every width; interpolate mode too.
    backend : str
        Geodesic back-end for geodesic and hybrid.
    heat, thin_plate : bool
        Extra rows, see :func:`default_configs`.
    """
    methods = list(methods or METHODS)
    modes = list(modes or MODES)
    pins = list(pins or PINS)
    ws = []
    for w in (widths or ["default"]):
        if w is None or (isinstance(w, str) and w.lower() in ("default", "rule", "1.1h")):
            ws.append(None)
        else:
            try:
                ws.append(float(w))
            except (TypeError, ValueError):
                raise OptionError(f"width {w!r}: expected 'default' or a width in cm") from None
    out = []
    for method in methods:
        for mode in modes:
            for w in ws:
                if mode == "paper":
                    out.append(TransferConfig(method, mode, width_cm=w, pin="none", backend=backend))
                else:
                    for pin in pins:
                        out.append(TransferConfig(method, mode, width_cm=w, pin=pin, backend=backend))
    if heat and "interpolate" in modes:
        out.append(TransferConfig("geodesic", "interpolate", pin=pins[0], backend="heat"))
    if thin_plate and "interpolate" in modes:
        for method in methods:
            out.append(TransferConfig(method, "interpolate", kernel="thin_plate_spline", polynomial=True,
                                      pin=pins[0], backend=backend))
    return out


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
# regions
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class EvaluationRegions:
    """Vertex masks of the error regions (see the module docstring).

    Attributes
    ----------
    masks : dict str -> ndarray (N,) bool
        One per name of :data:`REGION_NAMES` (absent holes give empty masks).
    radius : float
        Region radius (mesh units).
    corner_y : float or None
        y of the higher mouth corner (mesh units): the "upper" pin keeps border vertices above it.
    """

    masks: dict
    radius: float
    corner_y: float | None = None

    def __getitem__(self, name: str) -> np.ndarray:
        return self.masks[name]

    def counts(self) -> dict[str, int]:
        return {k: int(v.sum()) for k, v in self.masks.items()}


def loop_rims(points, loop) -> tuple[np.ndarray, np.ndarray]:
    """Split a closed hole loop into its upper and lower rim at its extreme-x vertices.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
    loop : ndarray, shape (L,), int
        Ordered closed loop (first vertex not repeated).

    Returns
    -------
    upper, lower : ndarray of int
        Vertex indices of each rim, both including the two corners; ``upper`` is the rim with the
        larger mean y.
    """
    loop = np.asarray(loop, dtype=np.int64)
    x = points[loop, 0]
    a, b = int(np.argmin(x)), int(np.argmax(x))
    rolled = np.roll(loop, -a)
    kb = (b - a) % loop.size
    r1 = rolled[: kb + 1]
    r2 = np.concatenate([rolled[kb:], rolled[:1]])
    if points[r1, 1].mean() >= points[r2, 1].mean():
        return r1, r2
    return r2, r1


def _rim_y(points, rim, x) -> np.ndarray:
    px, py = points[rim, 0], points[rim, 1]
    order = np.argsort(px, kind="stable")
    return np.interp(x, px[order], py[order])


def _split_by_centre_line(points, loop, mask) -> tuple[np.ndarray, np.ndarray]:
    """(above, below): vertices of ``mask`` between the loop's corners, above / below its centre line."""
    upper, lower = loop_rims(points, loop)
    x, y = points[:, 0], points[:, 1]
    xa, xb = points[loop, 0].min(), points[loop, 0].max()
    centre = 0.5 * (_rim_y(points, upper, x) + _rim_y(points, lower, x))
    inside = mask & (x > xa) & (x < xb)
    return inside & (y > centre), inside & (y < centre)


def evaluation_regions(mesh: FaceMesh, regions: list[Region], *, radius: float) -> EvaluationRegions:
    """Error-region masks of a face mesh (see the module docstring).

    Parameters
    ----------
    mesh : FaceMesh
    regions : list of Region
        Hole regions (``mouth`` role ``mouth``, eyes role ``eye`` named ``leftEye``/``rightEye``
        or any name, sorted to left/right by mean x).
    radius : float
        Region radius (mesh units), e.g. 1.5 cm.

    Returns
    -------
    EvaluationRegions
    """
    p = mesh.points
    n = p.shape[0]
    empty = np.zeros(n, dtype=bool)

    def near(loop):
        d, _ = cKDTree(p[np.asarray(loop)]).query(p, k=1)
        return d <= radius

    mouth_r = [r for r in regions if r.role == "mouth"]
    eye_r = [r for r in regions if r.role == "eye"]
    masks = {"face": np.ones(n, dtype=bool)}
    mouth = near(_loop_of(mouth_r[0])) if mouth_r else empty.copy()
    masks["mouth"] = mouth
    eye_masks = {}
    for r in eye_r:
        eye_masks[r.name] = near(_loop_of(r)) & ~mouth
    eyes = np.zeros(n, dtype=bool)
    for m in eye_masks.values():
        eyes |= m
    masks["eyes"] = eyes
    masks["rest"] = ~(mouth | eyes)
    corner_y = None
    if mouth_r:
        loop = _loop_of(mouth_r[0])
        masks["upperLip"], masks["lowerLip"] = _split_by_centre_line(p, loop, mouth)
        x = p[loop, 0]
        corner_y = float(max(p[loop[np.argmin(x)], 1], p[loop[np.argmax(x)], 1]))
    else:
        masks["upperLip"], masks["lowerLip"] = empty.copy(), empty.copy()
    mid_x = 0.5 * (p[:, 0].min() + p[:, 0].max())
    for side in ("left", "right"):
        cands = [r for r in eye_r if (p[_loop_of(r), 0].mean() > mid_x) == (side == "left")]
        if cands:
            r = max(cands, key=lambda r: _loop_of(r).size)
            masks[f"{side}UpperLid"], masks[f"{side}LowerLid"] = _split_by_centre_line(p, _loop_of(r), eye_masks[r.name])
        else:
            masks[f"{side}UpperLid"], masks[f"{side}LowerLid"] = empty.copy(), empty.copy()
    return EvaluationRegions({k: masks[k] for k in REGION_NAMES}, float(radius), corner_y)


def _loop_of(region: Region) -> np.ndarray:
    return region.loop if region.loop is not None else region.indices


# ------------------------------------------------------------------------------------------------
# pinned centres
# ------------------------------------------------------------------------------------------------

def pinned_vertices(points, regions: list[Region], marker_points, *, spacing: float, corner_y: float | None
                    ) -> dict[str, np.ndarray]:
    """Constraint vertices of each pin variant, as the pipeline picks them.

    ``border``: :func:`usdface.mesh.regions.constraint_vertices` with ``pin_border="all"`` (the
    outer border thinned to ``spacing``, kept ``0.5 spacing`` from the markers) plus any
    pinned/rigid region; ``upper``: ``pin_border="upper"`` (outer-border picks above the mouth
    corners only: the pipeline's default); ``none``: the pinned/rigid regions only.

    Returns
    -------
    dict pin -> ndarray of int (sorted)
    """
    from ..mesh.regions import constraint_vertices

    pts = np.asarray(points, dtype=np.float64)
    kw = dict(spacing=spacing, exclude_near=marker_points, clearance=0.5 * spacing)
    out = {}
    for pin, policy in (("border", "all"), ("none", "none"), ("upper", "upper")):
        out[pin] = np.sort(constraint_vertices(pts, regions, pin_border=policy, **kw)[0]).astype(np.int64)
    return out


# ------------------------------------------------------------------------------------------------
# errors
# ------------------------------------------------------------------------------------------------

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

    def to_dict(self) -> dict:
        """JSON-ready summary (per config: per-shape numbers and aggregates)."""
        out = {"settings": self.settings, "shapes": list(self.shape_names), "skipped": dict(self.skipped),
               "regionVertices": self.regions.counts(),
               "truthMeanCm": _r(self.truth_mean), "truthMaxCm": _r(self.truth_max), "markerMaxCm": _r(self.marker_max),
               "summary": summary_rows(self), "claim": claim_numbers(self), "configs": []}
        for res in self.results:
            c = res.config
            out["configs"].append({
                "label": c.label, "method": c.method, "backend": c.backend if c.method != "euclidean" else None,
                "mode": c.mode, "kernel": c.kernel, "widthCm": res.width_cm, "widthRule": c.width_cm is None,
                "polynomial": c.polynomial, "pin": c.pin_label, "constraints": res.n_constraints,
                "conditionNumber": res.condition_number, "minEigenvalue": res.min_eigenvalue,
                "meanErrorCm": {rn: _r(res.mean_error[:, i]) for i, rn in enumerate(REGION_NAMES)},
                "maxErrorCm": {rn: _r(res.max_error[:, i]) for i, rn in enumerate(REGION_NAMES)},
                "predictedMaxCm": _r(res.predicted_max), "stillMotionCm": _r(res.still_motion),
            })
        return out


def _r(a, nd=5):
    return [None if not np.isfinite(v) else round(float(v), nd) for v in np.asarray(a).ravel()]


# ------------------------------------------------------------------------------------------------
# the evaluation
# ------------------------------------------------------------------------------------------------

class TransferSetup:
    """Everything a transfer needs on one mesh + binding, built once and shared by many configs.

    Sources are the M bound markers followed by every candidate constraint vertex (the union of
    the pin variants' vertices); each distance kind (euclidean, geodesic per back-end, hybrid per
    back-end and threshold) is computed once over all of them, and a config takes the columns of
    its own pin variant. Column j of every distance kind depends only on source j (a hybrid column
    blends with the *vertex's* weight), so this gives exactly the matrices the pipeline would
    compute for that pin variant.

    Parameters
    ----------
    mesh : FaceMesh
        ``units`` None counts as cm.
    regions : list of Region
    binding : Binding
    region_radius_cm, hybrid_radius_cm, hybrid_sigma_cm, hybrid_threshold : float
        See :func:`evaluate`.

    Attributes
    ----------
    cm : float
        One cm in mesh units.
    regions : EvaluationRegions
    marker_points : ndarray (M, 3)
    spacing : float
        Median nearest-marker Euclidean distance (mesh units): constraint thinning, as the pipeline.
    pins : dict pin -> ndarray of int
        Constraint vertices of each pin variant.
    seconds : dict
        Time spent on each distance kind.
    """

    def __init__(self, mesh: FaceMesh, regions: list[Region], binding: Binding, *,
                 region_radius_cm: float = REGION_RADIUS_CM, hybrid_radius_cm: float = 1.0,
                 hybrid_sigma_cm: float = 2.0, hybrid_threshold: float = 0.6) -> None:
        from ..rbf.stiffness import median_marker_spacing_from_points
        from ..units import scale_between

        if binding.triangle_vertices.max() >= mesh.n_points:
            raise MeshError(f"binding refers to vertex {int(binding.triangle_vertices.max())} but mesh "
                            f"{mesh.source or mesh.name} has {mesh.n_points} vertices")
        self.mesh = mesh
        self.region_list = list(regions)
        self.binding = binding
        self.units = mesh.units or "cm"
        self.cm = scale_between("cm", self.units)
        self.hybrid_radius_cm = float(hybrid_radius_cm)
        self.hybrid_sigma_cm = float(hybrid_sigma_cm)
        self.hybrid_threshold = float(hybrid_threshold)
        self.region_radius_cm = float(region_radius_cm)
        self.regions = evaluation_regions(mesh, regions, radius=region_radius_cm * self.cm)
        pts = mesh.points
        M = binding.n_markers
        self.n_markers = M
        self.marker_points = binding.surface_points(pts)
        self.spacing = median_marker_spacing_from_points(self.marker_points)
        self.pins = pinned_vertices(pts, regions, self.marker_points, spacing=self.spacing,
                                    corner_y=self.regions.corner_y)
        cand = np.unique(np.concatenate([self.pins[p] for p in PINS]))
        self._col_of = {int(v): M + i for i, v in enumerate(cand)}
        self._src_tri = np.concatenate([binding.triangle_vertices, np.repeat(cand[:, None], 3, axis=1)])
        self._src_bary = np.concatenate([binding.barycentrics, np.tile([1.0, 0.0, 0.0], (cand.size, 1))])
        self._seeds = [_loop_of(r) for r in regions if r.role in _GEODESIC_ROLES]
        self._cache: dict = {}
        self._solvers: dict = {}
        self.seconds: dict = {}

    def distance_key(self, cfg: TransferConfig) -> tuple:
        if cfg.method == "euclidean":
            return ("euclidean",)
        if cfg.method == "geodesic":
            return ("geodesic", cfg.backend)
        return ("hybrid", cfg.backend, self.hybrid_threshold if cfg.threshold is None else float(cfg.threshold))

    def matrices(self, cfg: TransferConfig) -> tuple[np.ndarray, np.ndarray]:
        """(D_vc (N, M + P_all), D_cc) of ``cfg``'s distance over every candidate source (mesh units)."""
        from ..distance import GeodesicSolver, euclidean_at_sources, euclidean_distances, hybrid_distances

        key = self.distance_key(cfg)
        if key in self._cache:
            return self._cache[key]
        t0 = time.perf_counter()
        pts, tri, bary = self.mesh.points, self._src_tri, self._src_bary
        if cfg.method == "euclidean":
            dv = euclidean_distances(pts, tri, bary)
            dc = euclidean_at_sources(pts, tri, bary)
        else:
            if cfg.backend not in self._solvers:
                self._solvers[cfg.backend] = GeodesicSolver.from_mesh(self.mesh, backend=cfg.backend)
            solver = self._solvers[cfg.backend]
            if cfg.method == "geodesic":
                res = solver.solve(tri, bary)
                dv, dc = res.vertex, res.sources
            else:
                if not self._seeds:
                    raise MeshError("hybrid distances need mouth/eye (or geodesic) regions; none found on mesh "
                                    f"{self.mesh.source or self.mesh.name}")
                hyb = hybrid_distances(solver, tri, bary, self._seeds, radius=self.hybrid_radius_cm * self.cm,
                                       sigma=self.hybrid_sigma_cm * self.cm, threshold=key[2])
                dv, dc = hyb.vertex, hyb.sources
        dv = np.asarray(dv, dtype=np.float64)
        dc = np.asarray(dc, dtype=np.float64)
        if not np.isfinite(dv).all():
            raise MeshError(f"{cfg.method_label} distances: some vertices are unreachable from some markers")
        self._cache[key] = (dv, dc)
        self.seconds["/".join(str(k) for k in key)] = round(time.perf_counter() - t0, 4)
        return dv, dc

    def constraints(self, cfg: TransferConfig) -> np.ndarray:
        """Constraint vertices ``cfg`` uses (none beyond pinned/rigid regions in paper mode)."""
        return self.pins["none"] if cfg.mode == "paper" else self.pins[cfg.pin]

    def _columns(self, cfg: TransferConfig) -> np.ndarray:
        cons = self.constraints(cfg)
        return np.concatenate([np.arange(self.n_markers), [self._col_of[int(v)] for v in cons]]).astype(np.int64)

    def min_eigenvalue(self, cfg: TransferConfig, widths) -> float | None:
        """Smallest eigenvalue of the symmetric part of ``cfg``'s kernel matrix Phi_cc.

        Only for the positive-definite-for-Euclidean kernels (gaussian, inverse multiquadric): a
        negative value means the kernel is not positive definite on these distances (geodesic
        distances are not Euclidean), so the interpolating solve can ring or blow up. None for
        other kernels.
        """
        from ..rbf.kernels import get_kernel

        if cfg.kernel not in ("gaussian", "inverse_multiquadric"):
            return None
        _, dc = self.matrices(cfg)
        cols = self._columns(cfg)
        if cfg.mode == "paper":
            cols = cols[: self.n_markers]
        phi = get_kernel(cfg.kernel)(dc[np.ix_(cols, cols)], np.asarray(widths)[: cols.size])
        return float(np.linalg.eigvalsh(0.5 * (phi + phi.T)).min())

    def transfer(self, cfg: TransferConfig):
        """The fitted :class:`usdface.rbf.RBFTransfer` of ``cfg`` (runtime warnings silenced)."""
        from ..rbf.stiffness import DEFAULT_WIDTH_FACTOR
        from ..rbf.transfer import RBFTransfer

        dv, dc = self.matrices(cfg)
        M = self.n_markers
        cons = self.constraints(cfg)
        cols = self._columns(cfg)
        centre_points = np.concatenate([self.marker_points, self.mesh.points[cons]])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return RBFTransfer(dv[:, cols], dc[np.ix_(cols, cols)], mode=cfg.mode, kernel=cfg.kernel,
                               widths=(DEFAULT_WIDTH_FACTOR * self.spacing if cfg.width_cm is None
                                       else cfg.width_cm * self.cm),
                               polynomial=cfg.polynomial, n_markers=M, centre_points=centre_points,
                               vertex_points=self.mesh.points, marker_names=self.binding.names,
                               # as the pipeline: exact at the bound points on the mesh
                               collocation=(self.binding.triangle_vertices, self.binding.barycentrics)
                               if cfg.mode == "interpolate" else None).fit()

    def predict(self, cfg: TransferConfig, displacements, *, dtype=np.float64) -> np.ndarray:
        """Vertex displacements (F, N, 3) (mesh units) for marker displacements (F, M, 3)."""
        return self.transfer(cfg).apply(displacements, dtype=dtype)


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


# ------------------------------------------------------------------------------------------------
# summaries
# ------------------------------------------------------------------------------------------------

def _baseline(report: QualityReport, res: ConfigResult) -> ConfigResult | None:
    """The Euclidean result with the same mode/kernel/width/pin as ``res`` (None if absent)."""
    for other in report.results:
        if other.config.method == "euclidean" and other.config.same_except_method(res.config):
            return other
    return None


def summary_rows(report: QualityReport) -> list[dict]:
    """One row per configuration: errors averaged over the shapes.

    Per region of :data:`TABLE_REGIONS`: ``meanCm`` (mean over shapes of the per-shape mean
    error), ``meanPct`` (mean over shapes of the per-shape mean error as % of the shape's mean
    displacement), ``maxCm`` (largest vertex error over all shapes), ``maxPct`` (mean over shapes
    of the per-shape max error as % of the shape's mean displacement). ``winsMouth`` / ``winsEyes``:
    shapes where this config's mean mouth / eye error is lower than the Euclidean config with the
    same mode, kernel, width and pin (None for Euclidean rows). ``stillMotionCm``: mean over shapes
    of the mean predicted displacement of still vertices. ``overshoot``: mean over shapes of
    predicted max / marker max.
    """
    rows = []
    F = len(report.shape_names)
    for res in report.results:
        c = res.config
        row = {"label": c.label, "method": c.method_label, "mode": c.mode, "kernel": c.kernel_label,
               "pin": c.pin_label, "widthCm": round(res.width_cm, 4), "constraints": res.n_constraints,
               "conditionNumber": res.condition_number, "minEigenvalue": res.min_eigenvalue}
        for rn in TABLE_REGIONS:
            i = REGION_NAMES.index(rn)
            row[rn] = {"meanCm": float(np.nanmean(res.mean_error[:, i])),
                       "meanPct": float(np.nanmean(report.percent(res, rn))),
                       "maxCm": float(np.nanmax(res.max_error[:, i])),
                       "maxPct": float(np.nanmean(report.percent(res, rn, "max")))}
        base = _baseline(report, res)
        for key, rn in (("winsMouth", "mouth"), ("winsEyes", "eyes"), ("winsFace", "face")):
            if base is None or c.method == "euclidean":
                row[key] = None
            else:
                i = REGION_NAMES.index(rn)
                row[key] = int((res.mean_error[:, i] < base.mean_error[:, i]).sum())
        row["shapes"] = F
        row["stillMotionCm"] = float(np.nanmean(res.still_motion))
        row["overshoot"] = float(np.mean(res.predicted_max / np.maximum(report.marker_max, 1e-12)))
        rows.append(row)
    return rows


#: the claim's measurements: (shape, region) pairs
CLAIM_CASES = (("jawOpen", "upperLip"), ("eyeBlinkLeft", "leftLowerLid"), ("eyeBlinkRight", "rightLowerLid"))


def claim_numbers(report: QualityReport) -> list[dict]:
    """The paper's claim, per configuration: upper lip on jawOpen, lower lid on eyeBlink.

    Returns
    -------
    list of dict
        One per configuration: ``label``, and per case ``"<shape>/<region>"`` a dict with
        ``meanCm``, ``maxCm`` (vertex error over the region), ``predDyCm``, ``trueDyCm`` (mean y
        displacement over the region, predicted and true) and ``vsEuclidean`` (mean error / the
        matching Euclidean config's, None for Euclidean rows). Cases whose shape was not evaluated
        are left out.
    """
    out = []
    for res in report.results:
        row = {"label": res.config.label, "method": res.config.method_label, "mode": res.config.mode,
               "kernel": res.config.kernel_label, "pin": res.config.pin_label}
        base = _baseline(report, res)
        for shape, region in CLAIM_CASES:
            if shape not in report.shape_names:
                continue
            f = report.shape(shape)
            i = REGION_NAMES.index(region)
            e = float(res.mean_error[f, i])
            row[f"{shape}/{region}"] = {
                "meanCm": e, "maxCm": float(res.max_error[f, i]),
                "predDyCm": float(res.mean_dy[f, i]), "trueDyCm": float(report.truth_dy[f, i]),
                "vsEuclidean": None if (base is None or res.config.method == "euclidean")
                else e / float(base.mean_error[f, i]),
            }
        out.append(row)
    return out


def _f(v, nd=3) -> str:
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "-"
    return f"{v:.{nd}f}"


def format_summary_table(report: QualityReport) -> list[str]:
    """Markdown: one row per configuration, errors averaged over the shapes."""
    F = len(report.shape_names)
    head = ("| distance | mode | kernel, width | pinned | face mean cm (%) | face max | mouth mean cm (%) | mouth max "
            "| eyes mean cm (%) | eyes max | rest mean cm (%) | rest max | still motion cm | mouth/eyes better than Eucl. |")
    lines = [head, "|" + "|".join(["---"] * (head.count("|") - 1)) + "|"]
    for row in summary_rows(report):
        cells = [row["method"], row["mode"], row["kernel"], row["pin"]]
        for rn in TABLE_REGIONS:
            r = row[rn]
            cells.append(f"{_f(r['meanCm'])} ({r['meanPct']:.1f}%)")
            cells.append(_f(r["maxCm"], 2))
        cells.append(_f(row["stillMotionCm"]))
        cells.append("-" if row["winsMouth"] is None else f"{row['winsMouth']}/{F}, {row['winsEyes']}/{F}")
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def format_claim_table(report: QualityReport) -> list[str]:
    """Markdown: the paper's claim numbers per configuration."""
    cases = [(s, r) for s, r in CLAIM_CASES if s in report.shape_names]
    head = ["distance", "mode", "kernel, width", "pinned"]
    for s, r in cases:
        head += [f"{s} {r} mean (max) cm", "pred dy (true)", "vs Eucl."]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join(["---"] * len(head)) + "|"]
    for row in claim_numbers(report):
        cells = [row["method"], row["mode"], row["kernel"], row["pin"]]
        for s, r in cases:
            c = row[f"{s}/{r}"]
            cells += [f"{_f(c['meanCm'])} ({_f(c['maxCm'], 2)})", f"{c['predDyCm']:+.3f} ({c['trueDyCm']:+.3f})",
                      "-" if c["vsEuclidean"] is None else f"{c['vsEuclidean']:.2f}x"]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def format_shape_table(report: QualityReport, configs=None, region: str = "face") -> list[str]:
    """Markdown: per shape, the mean error in ``region`` (cm and %) of each of ``configs``."""
    results = report.results if configs is None else [report.result(c) for c in configs]
    i = REGION_NAMES.index(region)
    head = ["shape", "mean / max true disp. cm"] + [f"{r.config.method_label} {r.config.mode} pin={r.config.pin_label}"
                                                     for r in results]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join(["---"] * len(head)) + "|"]
    best_of = np.nanargmin(np.stack([r.mean_error[:, i] for r in results], axis=1), axis=1)
    for f, name in enumerate(report.shape_names):
        cells = [name, f"{report.truth_mean[f]:.3f} / {report.truth_max[f]:.2f}"]
        for k, r in enumerate(results):
            e = r.mean_error[f, i]
            txt = f"{_f(e)} ({100 * e / report.truth_mean[f]:.0f}%)"
            cells.append(f"**{txt}**" if k == best_of[f] else txt)
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def format_overshoot_table(report: QualityReport, shape: str = "jawOpen") -> list[str]:
    """Markdown: kernel width and matrix diagnostics, and the largest predicted displacement vs the
    markers' and the truth's, per configuration."""
    if shape not in report.shape_names:
        return []
    f = report.shape(shape)
    head = ["distance", "mode", "kernel, width", "pinned", "width cm", "cond.", "min eig. Phi", f"{shape} pred max cm",
            "/ marker max", "all shapes: mean pred max / marker max", "worst (shape)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join(["---"] * len(head)) + "|",
             f"| truth | | | | | | | {report.truth_max[f]:.2f} (markers {report.marker_max[f]:.2f}) | | | |"]
    for res in report.results:
        c = res.config
        ratio = res.predicted_max / np.maximum(report.marker_max, 1e-12)
        w = int(np.argmax(ratio))
        cond = "-" if res.condition_number is None else f"{res.condition_number:.2g}"
        eig = "-" if res.min_eigenvalue is None else f"{res.min_eigenvalue:+.3f}"
        lines.append("| " + " | ".join([
            c.method_label, c.mode, c.kernel_label, c.pin_label, f"{res.width_cm:.2f}", cond, eig,
            f"{res.predicted_max[f]:.2f}", f"{res.predicted_max[f] / report.marker_max[f]:.2f}",
            f"{ratio.mean():.2f}", f"{ratio[w]:.2f} ({report.shape_names[w]})"]) + " |")
    return lines


def format_report(report: QualityReport, *, shape_configs=None) -> list[str]:
    """The full markdown report: settings, summary table, claim table, overshoot, per-shape table."""
    s = report.settings
    F = len(report.shape_names)
    lines = [
        f"Ground truth: {F} expression shapes on a {s['vertices']}-vertex face, {s['markers']} markers "
        f"(median spacing h = {s['markerSpacingCm']:.2f} cm). Skipped: "
        + (", ".join(f"{k} ({v})" for k, v in report.skipped.items()) or "none") + ".",
        f"Error regions: mouth / eyes = vertices within {s['regionRadiusCm']:g} cm of the mouth / eye loops "
        f"({report.regions.counts()['mouth']} / {report.regions.counts()['eyes']} vertices), rest = the other "
        f"{report.regions.counts()['rest']}. % = of the shape's mean vertex displacement. Means are over the shapes; "
        "max = largest vertex error over all shapes.",
        f"Hybrid: radius {s['hybridRadiusCm']:g} cm, sigma {s['hybridSigmaCm']:g} cm, threshold {s['hybridThreshold']:g}. "
        f"Kernel width 1.1h = 1.1 x median nearest-marker distance h (Euclidean, between bound points). "
        f"Pinned centres: border {s['pinnedCentres']['border']}, upper (above the mouth corners) "
        f"{s['pinnedCentres']['upper']}, none {s['pinnedCentres']['none']}; paper mode ignores them (zero weight).",
        "",
        "### Errors against the ground truth (mean over shapes)",
        "",
        *format_summary_table(report),
        "",
        "### The paper's claim: jawOpen upper lip, eyeBlink lower lid",
        "",
        *format_claim_table(report),
    ]
    ov = format_overshoot_table(report)
    if ov:
        lines += ["", "### Kernel matrix and overshoot", "", *ov]
    if shape_configs is not None:
        lines += ["", "### Per shape (face mean error)", "", *format_shape_table(report, shape_configs)]
    return lines
