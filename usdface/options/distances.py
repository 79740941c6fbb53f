"""Options of the distance matrices (`distances`, `run`)."""
from __future__ import annotations

from dataclasses import dataclass

from ..distance.methods import BACKENDS, DEFAULT_BACKEND, METHODS
from .fields import Options, option
from .values import nonnegative_float, positive_float, unit_interval


@dataclass(frozen=True)
class DistanceOptions(Options):
    """Distance matrices (`distances`, `run`)."""

    method: str = option("hybrid", flag="--method", choices=METHODS, group="distances",
                         help="Euclidean (Eq. 6), geodesic (Eq. 7) or hybrid (Eq. 8)")
    backend: str = option(DEFAULT_BACKEND, flag="--backend", choices=BACKENDS, group="distances",
                          help="geodesic back-end: fmm (fast marching: accurate, the default), graph (shortest edge "
                               "paths, the paper's: 8-15% long), heat method, exact polyhedral (small meshes)")
    region_radius: float = option(1.0, flag="--region-radius", coerce=nonnegative_float, metavar="CM",
                                  group="distances",
                                  help="hybrid: geodesic regions = vertices within this distance of the mouth/eye "
                                       "loops (cm)")
    sigma: float = option(2.0, flag="--sigma", coerce=positive_float, metavar="CM", group="distances",
                          help="hybrid: weight width (cm)")
    threshold: float = option(0.6, flag="--threshold", coerce=unit_interval, group="distances",
                              help="hybrid: geodesic term skipped where w <= this")
    pin_border: str = option("upper", flag="--pin-border", choices=("upper", "all", "none"), group="distances",
                             help="outer border as zero-displacement centres: above the mouth corners (the jaw's "
                                  "border moves with the jaw), all of it, or none")
    components: str = option("error", flag="--components", choices=("error", "euclidean"), group="distances",
                             help="markers on different mesh components: error, or Euclidean distance across them")

    def parameters(self):
        """The compute parameters (:class:`usdface.distance.matrices.DistanceParameters`)."""
        from ..distance.matrices import DistanceParameters

        return DistanceParameters(method=self.method, backend=self.backend, components=self.components,
                                  pin_border=self.pin_border, region_radius_cm=self.region_radius,
                                  sigma_cm=self.sigma, threshold=self.threshold)
