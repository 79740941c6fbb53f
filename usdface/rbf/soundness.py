"""Which kernel works with which distance: the well-posed variant of each, or a refusal.

Theory
------
The interpolation guarantees of radial kernels are statements about Euclidean distances
(Micchelli 1986; Wendland, "Scattered Data Approximation", 2005, Ch. 6 and 8):

- gaussian and inverse multiquadric are positive definite: the system of distinct centres is
  non-singular with no extra term;
- the multiquadric is conditionally positive definite of order 1, thin-plate spline and cubic of
  order 2 (:data:`usdface.rbf.kernels.CPD_ORDER`): the system is uniquely solvable once the
  polynomials of degree < order are added and their moment conditions imposed. The linear
  polynomial of :class:`usdface.rbf.RBFTransfer` covers both orders, so it is added by default
  (:func:`resolve_polynomial`).

On geodesic or hybrid distances none of this holds. The Gaussian of a geodesic distance is
positive definite for every width only on a flat space (Feragen, Lauze and Hauberg, "Geodesic
exponential kernels: when curvature and linearity conflict", CVPR 2015), and a face with open eyes
and mouth is far from one; but the decaying kernels (gaussian, inverse multiquadric) stay positive
definite when the width is small against the distance to the nearest centre, the matrix is then
dominated by its diagonal, and where they lose it the ridge term of ``regularization="auto"``
(:mod:`usdface.rbf.stability`) restores a bounded interpolant. The growing kernels
(multiquadric, thin-plate spline, cubic) have no such regime: their values are dominated by the
*far* centres, exactly where geodesic distances differ most from Euclidean ones (around the mouth
and eyes), the polynomial term is a polynomial of the Euclidean coordinates and does not restore a
conditional definiteness the metric never had, and a ridge term large enough to bound the solve
no longer interpolates. Measured on the tuning shapes of ``benchmarks/heldout_split.json``
(``python benchmarks/rbf_heldout.py``, section 1), with ``regularization="auto"`` and with or
without the polynomial: 150-3500% of the shapes' motion for every growing kernel on geodesic and
hybrid distances (amplification 17-780x, 3-65x the Gaussian's error on the same distances),
against 56-72% on Euclidean ones.

One Euclidean pair is refused although it is well posed: the cubic. With its polynomial it is
scale-free (the width changes nothing), and its interpolant amplifies marker motion 8.8x on the
tuning shapes, beyond the 6x above which every transfer measured there did worse than leaving the
face still (:data:`usdface.rbf.stability.WARN_AMPLIFICATION`); its error is 1.5x the Gaussian's
(86% against 56% tuning). With no parameter to bring it back, it has no variant the pipeline can
stand behind. The thin-plate spline (4.7x, 72.5%) and the multiquadric at its default width (2.6x,
63.8%) stay.

Policy (:data:`SOUND_KERNELS`): on Euclidean distances gaussian, inverse multiquadric, multiquadric
and thin-plate spline, the last two with their polynomial (thin-plate spline needs it; the
multiquadric's plain matrix is also non-singular, so ``--no-polynomial`` stays allowed for it); on
geodesic and hybrid distances gaussian and inverse multiquadric only; in paper mode (Eqs. 1-5, no
solve) the decaying kernels only, on any distance. The cubic thus works with no method (it stays a
``--kernel`` choice so that 0.2's command lines parse); its refusal says so instead of pointing to
another method.
"""
from __future__ import annotations

from ..errors import OptionError
from .kernels import CPD_ORDER, DECAYING_KERNELS, KERNELS, canonical_kernel_name

__all__ = ["DISTANCE_METHODS", "SOUND_KERNELS", "PAPER_KERNELS", "resolve_polynomial", "sound_kernels",
           "check_kernel_method"]

#: distance methods of the transfer (paper Eqs. 6, 7, 8)
DISTANCE_METHODS = ("euclidean", "geodesic", "hybrid")

#: interpolate mode: the kernels with a well-posed variant on each distance method
SOUND_KERNELS = {
    "euclidean": ("gaussian", "inverse_multiquadric", "multiquadric", "thin_plate_spline"),
    "geodesic": ("gaussian", "inverse_multiquadric"),
    "hybrid": ("gaussian", "inverse_multiquadric"),
}

#: paper mode (Eqs. 1-5: W_j = D_j / sum_k phi(d_jk), no solve): kernels that decay with distance
PAPER_KERNELS = tuple(k for k in KERNELS if k in DECAYING_KERNELS)


def resolve_polynomial(kernel: str, polynomial="auto") -> bool:
    """Whether the interpolating solve gets the linear polynomial term.

    Parameters
    ----------
    kernel : str
        Kernel name (or alias).
    polynomial : {"auto", True, False}
        ``"auto"`` (default): True exactly for the conditionally positive definite kernels
        (multiquadric, thin-plate spline, cubic: :data:`~usdface.rbf.kernels.CPD_ORDER` > 0), which
        need it; False for gaussian and inverse multiquadric, where it only adds a global affine part
        (measured: it does not help them on the tuning shapes). True / False force it (``--polynomial``
        / ``--no-polynomial``).

    Returns
    -------
    bool
    """
    if isinstance(polynomial, str):
        if polynomial != "auto":
            raise OptionError(f"polynomial: expected 'auto', True or False; got {polynomial!r}")
        return CPD_ORDER[canonical_kernel_name(kernel)] > 0
    if not isinstance(polynomial, bool):
        raise OptionError(f"polynomial: expected 'auto', True or False; got {polynomial!r}")
    return polynomial


def sound_kernels(method: str, *, mode: str = "interpolate", polynomial: bool = True) -> tuple[str, ...]:
    """The kernels accepted with ``method`` (see the module docstring).

    Parameters
    ----------
    method : {"euclidean", "geodesic", "hybrid"}
    mode : {"interpolate", "paper"}
    polynomial : bool
        Interpolate mode: whether the linear polynomial term is used; without it the kernels that
        need it (order 2: thin-plate spline, cubic) are left out.

    Returns
    -------
    tuple of str
        Canonical kernel names, in the order of :data:`usdface.rbf.kernels.KERNELS`.
    """
    if method not in DISTANCE_METHODS:
        raise OptionError(f"--method {method!r}: expected one of {', '.join(DISTANCE_METHODS)}")
    if mode == "paper":
        return PAPER_KERNELS
    if mode != "interpolate":
        raise OptionError(f"--rbf {mode!r}: expected paper or interpolate")
    return tuple(k for k in SOUND_KERNELS[method] if polynomial or CPD_ORDER[k] < 2)


def check_kernel_method(kernel: str, method: str, *, polynomial: bool, mode: str = "interpolate",
                        method_source: str | None = None) -> str:
    """Refuse a kernel that has no well-posed variant with the distance ``method``.

    Parameters
    ----------
    kernel : str
        ``--kernel`` (a name of :data:`usdface.rbf.kernels.KERNELS` or an alias).
    method : {"euclidean", "geodesic", "hybrid"}
        ``--method``: the distance method (for a transfer, the analysis layer's).
    polynomial : bool
        Whether the linear polynomial term is used (after :func:`resolve_polynomial`).
    mode : {"interpolate", "paper"}
        ``--rbf``.
    method_source : str, optional
        Where the method comes from when the user did not give it (e.g. the analysis layer's
        path); named in the message.

    Returns
    -------
    str
        The canonical kernel name.

    Raises
    ------
    OptionError
        (exit 2) One line naming ``--kernel`` and ``--method`` and listing the kernels that work
        with that method.
    """
    name = canonical_kernel_name(kernel)
    ok = sound_kernels(method, mode=mode, polynomial=polynomial)
    if name in ok:
        return name
    where = f" (the distances of {method_source})" if method_source else ""
    works = f"kernels that work with --method {method}{where}"
    if mode == "paper":
        raise OptionError(f"--kernel {name} with --rbf paper (--method {method}{where}): Eqs. 1-5 solve nothing and "
                          f"need a kernel that decays with distance; {works} in paper mode: {', '.join(ok)}")
    if name in SOUND_KERNELS[method]:  # refused only because the polynomial it needs is off
        raise OptionError(f"--kernel {name} with --method {method}{where} and --no-polynomial: {name} is "
                          f"conditionally positive definite of order {CPD_ORDER[name]} and needs its linear polynomial "
                          f"term (drop --no-polynomial); {works} without it: {', '.join(ok)}")
    if not any(name in kernels for kernels in SOUND_KERNELS.values()):  # the cubic: see the module docstring
        why = ("scale-free with its polynomial, it amplifies marker motion about 9x at any width, 1.5x the error of "
               "a Gaussian" if method == "euclidean" else
               f"on {method} distances it amplifies marker motion 17x or more, 3-65x the error of a Gaussian; on "
               "Euclidean ones, scale-free with its polynomial, about 9x at any width")
        raise OptionError(f"--kernel {name} with --method {method}{where}: no usable variant with any --method ({why}); "
                          f"{works}: {', '.join(ok)}")
    raise OptionError(f"--kernel {name} with --method {method}{where}: no well-posed variant (its guarantees hold for "
                      f"Euclidean distances only; on {method} distances it amplifies marker motion 17x or more, 3-65x the "
                      f"error of a Gaussian); {works}: {', '.join(ok)}")
