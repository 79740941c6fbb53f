"""Transfer configurations of the quality evaluation: which distance, RBF mode, kernel, width and
pinned border a row of the tables uses (:class:`TransferConfig`), and the grids of them."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..errors import OptionError

__all__ = ["MIN_SHAPE_DISPLACEMENT_CM", "REGION_RADIUS_CM", "STILL_CM", "AUTHORS_WIDTH_CM", "METHODS", "MODES",
           "PINS", "TABLE_REGIONS", "REGION_NAMES", "TransferConfig", "default_configs", "parse_configs"]

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
        Kernel width of every centre in cm; None = the width rule.
    polynomial : "auto", True or False
        Linear polynomial term (interpolate mode); "auto" = the pipeline's default (exactly the
        kernels that need it, :func:`usdface.rbf.soundness.resolve_polynomial`).
    pin : {"border", "none", "upper"}
        Which outer-border vertices are zero-displacement centres (no effect in paper mode, where
        constraint centres get zero weight).
    backend : {"graph", "fmm", "heat", "exact"} or None
        Geodesic back-end (geodesic and hybrid); None: the pipeline's for the mode
        (:func:`usdface.distance.methods.default_backend`: fast marching, edge paths in paper mode).
    threshold : float, optional
        Hybrid threshold (default the setup's).
    width_rule : None, "legacy" or WidthRule
        When ``width_cm`` is None: None = the pipeline's rule for the mode
        (:func:`usdface.rbf.stiffness.transfer_widths`); "legacy" = 1.1 x the median Euclidean
        nearest-marker distance for every centre (the rule of every mode before the per-marker
        rule); a :class:`usdface.rbf.stiffness.WidthRule` = that rule on the config's distances.
    regularization : "auto" or float
        As ``--regularization`` (default "auto", the pipeline's).
    check : bool
        Refuse kernel and method pairs with no well-posed variant, as the pipeline does (False: to
        measure them).
    """

    method: str
    mode: str = "interpolate"
    kernel: str = "gaussian"
    width_cm: float | None = None
    polynomial: Any = "auto"
    pin: str = "border"
    backend: str | None = None
    threshold: float | None = None
    width_rule: Any = None
    regularization: Any = "auto"
    check: bool = True

    def __post_init__(self) -> None:
        if self.backend is None:
            from ..distance.methods import default_backend

            object.__setattr__(self, "backend", default_backend(self.mode))
        if self.method not in METHODS:
            raise OptionError(f"method {self.method!r}: expected one of {', '.join(METHODS)}")
        if self.mode not in MODES:
            raise OptionError(f"mode {self.mode!r}: expected one of {', '.join(MODES)}")
        if self.pin not in PINS:
            raise OptionError(f"pin {self.pin!r}: expected one of {', '.join(PINS)}")
        if self.width_cm is not None and not (math.isfinite(self.width_cm) and self.width_cm > 0):
            raise OptionError(f"width_cm must be a positive number or None; got {self.width_cm!r}")
        if self.mode == "paper" and self.polynomial is True:
            raise OptionError("polynomial applies to interpolate mode only")
        if self.polynomial not in ("auto", True, False):
            raise OptionError(f"polynomial: expected 'auto', True or False; got {self.polynomial!r}")
        if self.width_rule is not None and self.width_rule != "legacy" and not hasattr(self.width_rule, "widths"):
            raise OptionError(f"width_rule: expected None, 'legacy' or a WidthRule; got {self.width_rule!r}")
        if self.threshold is not None and (self.method != "hybrid" or not 0.0 <= self.threshold < 1.0):
            raise OptionError(f"threshold applies to the hybrid method and must be in [0, 1); got {self.threshold!r}")

    @property
    def method_label(self) -> str:
        if self.method == "euclidean":
            return self.method
        thr = "" if self.threshold is None else f" thr={self.threshold:g}"
        return f"{self.method}/{self.backend}{thr}"

    @property
    def uses_polynomial(self) -> bool:
        """The polynomial term, resolved (False in paper mode)."""
        from ..rbf.soundness import resolve_polynomial

        return self.mode == "interpolate" and resolve_polynomial(self.kernel, self.polynomial)

    @property
    def width_label(self) -> str:
        if self.width_cm is not None:
            return f"{self.width_cm:g} cm"
        rule = self.width_rule
        if rule == "legacy" or (rule is None and self.mode == "paper"):
            return "1.1h"
        if rule is None:
            from ..rbf.stiffness import default_width_rule

            rule = default_width_rule(self.kernel, self.mode)
        return f"{rule.factor:g}l{rule.neighbours}" if rule.per_marker else f"{rule.factor:g}h~"

    @property
    def kernel_label(self) -> str:
        k = {"gaussian": "gauss", "thin_plate_spline": "TPS", "inverse_multiquadric": "IMQ"}.get(self.kernel, self.kernel)
        reg = "" if self.regularization == "auto" else f" lambda={self.regularization:g}"
        return f"{k} {self.width_label}" + (" +poly" if self.uses_polynomial else "") + reg

    @property
    def pin_label(self) -> str:
        return "-" if self.mode == "paper" else self.pin

    @property
    def label(self) -> str:
        return f"{self.method_label} {self.mode} {self.kernel_label} pin={self.pin_label}"

    def same_except_method(self, other: "TransferConfig") -> bool:
        return (self.mode, self.kernel, self.width_cm, self.width_rule, self.uses_polynomial, self.pin_label,
                self.regularization) == (other.mode, other.kernel, other.width_cm, other.width_rule,
                                         other.uses_polynomial, other.pin_label, other.regularization)


def _thin_plate_methods(methods) -> list[str]:
    """The methods the pipeline runs a thin-plate spline with (it refuses the others)."""
    from ..rbf.soundness import SOUND_KERNELS

    return [m for m in methods if "thin_plate_spline" in SOUND_KERNELS[m]]


def default_configs(*, methods=METHODS, modes=MODES, pins=PINS, authors_width: bool = True,
                    heat: bool = False, thin_plate: bool = False) -> list[TransferConfig]:
    """The evaluation grid.

    For every method: paper mode with the default width rule (and with the authors' 2 cm when
    ``authors_width``), and interpolate mode (Gaussian, default width rule) with every ``pins``
    variant. ``heat`` adds geodesic/heat interpolate (pin border); ``thin_plate`` adds thin-plate
    spline + linear polynomial interpolate (pin border) for every method the pipeline runs it with
    (Euclidean: :data:`usdface.rbf.soundness.SOUND_KERNELS`).
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
        for method in _thin_plate_methods(methods):
            out.append(TransferConfig(method, "interpolate", kernel="thin_plate_spline", polynomial=True,
                                      pin="border"))
    return out


def parse_configs(methods=None, modes=None, pins=None, widths=None, *, backend: str | None = None,
                  heat: bool = False, thin_plate: bool = False) -> list[TransferConfig]:
    """Configurations from CLI-style lists.

    Parameters
    ----------
    methods, modes, pins : sequence of str, optional
        Default: all of :data:`METHODS`, :data:`MODES`, :data:`PINS`.
    widths : sequence of (str or float), optional
        ``"default"`` (the pipeline's rule of each mode: per marker, 0.7 x the mean distance to the
        3 nearest markers in the distance's metric for interpolate; 1.1 x the Euclidean median
        nearest-marker distance h for paper), ``"1.1h"`` (that paper rule for every mode: the
        former default) and/or widths in cm; default ``["default"]``.
        Paper mode is run with every width; interpolate mode too.
    backend : str, optional
        Geodesic back-end for geodesic and hybrid; None: the pipeline's for each mode.
    heat, thin_plate : bool
        Extra rows, see :func:`default_configs` (thin-plate rows only where the pipeline accepts them).
    """
    methods = list(methods or METHODS)
    modes = list(modes or MODES)
    pins = list(pins or PINS)
    ws = []  # (width_cm, width_rule)
    for w in (widths or ["default"]):
        if w is None or (isinstance(w, str) and w.lower() in ("default", "rule")):
            ws.append((None, None))
        elif isinstance(w, str) and w.lower() in ("1.1h", "legacy"):
            ws.append((None, "legacy"))
        else:
            try:
                ws.append((float(w), None))
            except (TypeError, ValueError):
                raise OptionError(f"width {w!r}: expected 'default', '1.1h' or a width in cm") from None
    out = []
    for method in methods:
        for mode in modes:
            for w, rule in ws:
                if mode == "paper":
                    out.append(TransferConfig(method, mode, width_cm=w, width_rule=rule, pin="none", backend=backend))
                else:
                    for pin in pins:
                        out.append(TransferConfig(method, mode, width_cm=w, width_rule=rule, pin=pin, backend=backend))
    if heat and "interpolate" in modes:
        out.append(TransferConfig("geodesic", "interpolate", pin=pins[0], backend="heat"))
    if thin_plate and "interpolate" in modes:
        for method in _thin_plate_methods(methods):
            out.append(TransferConfig(method, "interpolate", kernel="thin_plate_spline", polynomial=True,
                                      pin=pins[0], backend=backend))
    return out
