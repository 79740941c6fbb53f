"""Options of the RBF transfer (`transfer`, `skel`, `run`)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

from ..distance.methods import METHODS
from ..errors import OptionError
from ..rbf.kernel_names import KERNEL_NAMES
from .fields import Options, option
from .values import boolean, nonnegative_float, positive_float, shown


def regularization_value(value, flag):
    if value == "auto":
        return "auto"
    return nonnegative_float(value, flag)


def stiffness_value(value, flag):
    """A width in mesh units, a {marker: width} dict, or the path of a JSON file holding one."""
    if isinstance(value, Mapping):
        widths = {}
        for k, v in value.items():
            widths[str(k)] = positive_float(v, f"{flag} {k}")
        return widths
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return positive_float(value, flag)
    if isinstance(value, (str, Path)):
        try:
            float(value)
        except ValueError:
            return str(value)  # a JSON file of widths
        return positive_float(value, flag)  # "-1" is a width, not a file name
    raise OptionError(f"{flag} {shown(value)}: expected a width in mesh units or a JSON file {{marker: width}}")


def polynomial_value(value, flag):
    """--polynomial / --no-polynomial: True, False, or "auto" (the kernels that need it)."""
    if value == "auto":
        return "auto"
    return boolean(value, flag)


@dataclass(frozen=True)
class TransferOptions(Options):
    """The RBF transfer (`transfer`, `skel`, `run`)."""

    rbf: str = option("interpolate", flag="--rbf", choices=("paper", "interpolate"), group="transfer",
                      help="paper: Eqs. 1-5 as published; interpolate: exact RBF solve")
    kernel: str = option("gaussian", flag="--kernel", choices=KERNEL_NAMES, group="transfer",
                         help="radial basis function (interpolate mode: gaussian and inverse_multiquadric with every "
                              "--method, multiquadric and thin_plate_spline with euclidean; cubic is refused with "
                              "every --method; paper mode: gaussian and inverse_multiquadric)")
    stiffness: Any = option(None, flag="--stiffness", coerce=stiffness_value, metavar="WIDTH|JSON", group="transfer",
                            help="kernel width in mesh units for every marker, or a JSON file {marker: width} "
                                 "(default: per marker, 0.7 x its mean distance to its 3 nearest markers in the "
                                 "transfer's distances, 1.2-3 cm on a face; --rbf paper: 1.1 x the median "
                                 "nearest-marker distance, about 2 cm)")
    regularization: Any = option("auto", flag="--regularization", coerce=regularization_value, metavar="LAMBDA|auto",
                                 group="transfer",
                                 help="ridge term added to the kernel matrix (interpolate mode). auto: exact "
                                      "interpolation unless it amplifies marker motion more than 25x (geodesic "
                                      "kernels can), then the lambda with the least amplification")
    polynomial: Any = option("auto", flag="--polynomial", coerce=polynomial_value, action="store_const", const=True,
                             negate=("--no-polynomial", False), group="transfer",
                             negate_help="do not add the polynomial term, not even to the kernels that need it "
                                         "(thin_plate_spline is then refused)",
                             help="add a linear polynomial term (interpolate mode); by default exactly the kernels "
                                  "that need it get it (multiquadric, thin-plate spline), --no-polynomial turns "
                                  "it off")
    method: str | None = option(None, flag="--method", choices=METHODS, group="transfer",
                                help="which distance matrix of the analysis layer (default: its only one)")
    head_motion: bool = option(True, flag="--no-head-motion", coerce=boolean, group="deliverables",
                               help="drop the head motion removed by stabilisation (by default every deliverable "
                                    "carries it as a time-sampled transform on the face's root prim /Face)")

    def parameters(self):
        """The compute parameters (:class:`usdface.rbf.fitting.TransferParameters`)."""
        from ..rbf.fitting import TransferParameters

        return TransferParameters(rbf=self.rbf, kernel=self.kernel, stiffness=self.stiffness,
                                  regularization=self.regularization, polynomial=self.polynomial)

    def validate(self) -> None:
        super().validate()
        if self.rbf == "paper" and (self.polynomial is True or self.regularization not in ("auto", 0.0)):
            raise OptionError("--polynomial and --regularization apply to --rbf interpolate only "
                              "(paper mode solves nothing)")
        if self.method is not None:  # else the analysis layer's method, checked by the transfer
            from ..rbf.soundness import check_kernel_method, resolve_polynomial

            polynomial = self.rbf == "interpolate" and resolve_polynomial(self.kernel, self.polynomial)
            check_kernel_method(self.kernel, self.method, polynomial=polynomial, mode=self.rbf)
