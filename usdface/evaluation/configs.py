"""Transfer configurations of the quality evaluation: which distance, RBF mode, kernel, width and
pinned border a row of the tables uses (:class:`TransferConfig`), and the grids of them."""
from __future__ import annotations

import math
from dataclasses import dataclass

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
