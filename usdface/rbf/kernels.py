"""Radial basis kernels phi(d; s) on distance arrays.

Every kernel is a pure function of a distance array ``d`` (mesh units, any shape, >= 0, ``+inf``
allowed) and a kernel width ``s`` (mesh units, a scalar or an array broadcastable against ``d``:
with ``d`` of shape (N, C) and ``s`` of shape (C,), column k uses the width of centre k). The
kernel is evaluated on the scaled radius ``r = d / s``. Inputs are never modified; the result is a
new float64 array of the broadcast shape.

Paper reference (seed 000, Ramos Carretero et al.): Eq. 3 is ``phi(d) = exp(-d**gamma)`` with
``gamma = 2``; the authors' plug-in scales it by a per-marker "stiffness" s_j, i.e.
``exp(-d**2 / s_j**2)``, which is :func:`gaussian` here.

========================  =====================  =========  ===========================
name                      phi(r), r = d / s      phi(0)     phi(+inf)
========================  =====================  =========  ===========================
``gaussian``              exp(-r**2)             1          0
``multiquadric``          sqrt(1 + r**2)         1          inf
``inverse_multiquadric``  1 / sqrt(1 + r**2)     1          0
``thin_plate_spline``     r**2 log r             0          inf
``cubic``                 r**3                   0          inf
========================  =====================  =========  ===========================

Gaussian and inverse multiquadric are positive definite (the interpolation matrix of distinct
centres is non-singular for Euclidean distances); multiquadric is conditionally positive definite
of order 1, thin-plate spline and cubic of order 2 (:data:`CPD_ORDER`): they need the linear
polynomial term of :class:`usdface.rbf.RBFTransfer` (``polynomial=True``), which the pipeline adds
by itself (:func:`usdface.rbf.soundness.resolve_polynomial`). Every one of these guarantees is a
statement about Euclidean distances; for geodesic or hybrid distances none holds, and
:func:`usdface.rbf.soundness.check_kernel_method` says which kernel and distance pairs are sound.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..errors import OptionError
from .kernel_names import KERNEL_NAMES

__all__ = [
    "gaussian",
    "multiquadric",
    "inverse_multiquadric",
    "thin_plate_spline",
    "cubic",
    "KERNELS",
    "DECAYING_KERNELS",
    "CPD_ORDER",
    "get_kernel",
    "canonical_kernel_name",
]


def _scaled(d, width) -> np.ndarray:
    d = np.asarray(d, dtype=np.float64)
    s = np.asarray(width, dtype=np.float64)
    return d / s


def gaussian(d, width=1.0) -> np.ndarray:
    """Gaussian kernel ``exp(-(d / s)**2)``.

    Paper Eq. 3 with gamma = 2, scaled by the per-marker stiffness ``s`` as in the authors' code.

    Parameters
    ----------
    d : array_like, any shape, float
        Distances (mesh units), >= 0; ``+inf`` gives 0.
    width : float or array_like
        Kernel width s (mesh units, > 0), broadcastable against ``d`` (e.g. shape (C,) for
        ``d`` of shape (N, C): one width per centre/column).

    Returns
    -------
    ndarray, float64, broadcast shape of ``d`` and ``width``
        Values in (0, 1]; 1 at d = 0, exp(-1) at d = s.
    """
    r = _scaled(d, width)
    return np.exp(-(r * r))


def multiquadric(d, width=1.0) -> np.ndarray:
    """Hardy's multiquadric ``sqrt(1 + (d / s)**2)``.

    Parameters
    ----------
    d : array_like, any shape, float
        Distances (mesh units), >= 0.
    width : float or array_like
        Kernel width s (mesh units, > 0), broadcastable against ``d``.

    Returns
    -------
    ndarray, float64
        Values >= 1, growing linearly in d for d >> s.
    """
    r = _scaled(d, width)
    return np.sqrt(1.0 + r * r)


def inverse_multiquadric(d, width=1.0) -> np.ndarray:
    """Inverse multiquadric ``1 / sqrt(1 + (d / s)**2)``.

    Parameters
    ----------
    d : array_like, any shape, float
        Distances (mesh units), >= 0; ``+inf`` gives 0.
    width : float or array_like
        Kernel width s (mesh units, > 0), broadcastable against ``d``.

    Returns
    -------
    ndarray, float64
        Values in (0, 1]; 1 at d = 0.
    """
    r = _scaled(d, width)
    return 1.0 / np.sqrt(1.0 + r * r)


def thin_plate_spline(d, width=1.0) -> np.ndarray:
    """Thin-plate spline (polyharmonic, k = 2) ``r**2 log r`` with ``r = d / s``; 0 at r = 0.

    The width only rescales the kernel and adds a multiple of ``r**2``; it matters little, but it
    keeps the values in a sensible range for mesh units.

    Parameters
    ----------
    d : array_like, any shape, float
        Distances (mesh units), >= 0.
    width : float or array_like
        Kernel width s (mesh units, > 0), broadcastable against ``d``.

    Returns
    -------
    ndarray, float64
        Negative for 0 < r < 1, 0 at r = 0 and r = 1, positive beyond.
    """
    r = _scaled(d, width)
    out = np.zeros_like(r)
    pos = r > 0
    rp = r[pos]
    out[pos] = rp * rp * np.log(rp)
    return out


def cubic(d, width=1.0) -> np.ndarray:
    """Cubic polyharmonic kernel ``(d / s)**3``.

    Parameters
    ----------
    d : array_like, any shape, float
        Distances (mesh units), >= 0.
    width : float or array_like
        Kernel width s (mesh units, > 0), broadcastable against ``d``.

    Returns
    -------
    ndarray, float64
        Values >= 0; 0 at d = 0.
    """
    r = _scaled(d, width)
    return r * r * r


#: kernel name -> function; names follow scipy.interpolate.RBFInterpolator where they exist
KERNELS: dict[str, Callable[..., np.ndarray]] = dict(zip(
    KERNEL_NAMES, (gaussian, multiquadric, inverse_multiquadric, thin_plate_spline, cubic), strict=True))

#: kernels that tend to 0 at infinite distance (so ``+inf`` distances, e.g. from a bounded
#: geodesic search, mean "no influence")
DECAYING_KERNELS = frozenset({"gaussian", "inverse_multiquadric"})

#: order of conditional positive definiteness on Euclidean distances (0: positive definite): the
#: interpolation problem is uniquely solvable once the polynomials of degree < order are added
#: (Micchelli 1986; Wendland, "Scattered Data Approximation", 2005, Ch. 8). The multiquadric is
#: order 1 (a constant suffices; its plain matrix is also non-singular), thin-plate spline and cubic
#: order 2 (the linear polynomial is needed).
CPD_ORDER = {
    "gaussian": 0,
    "inverse_multiquadric": 0,
    "multiquadric": 1,
    "thin_plate_spline": 2,
    "cubic": 2,
}

_ALIASES = {
    "thin_plate": "thin_plate_spline",
    "tps": "thin_plate_spline",
    "imq": "inverse_multiquadric",
    "mq": "multiquadric",
}


def canonical_kernel_name(name: str) -> str:
    """Return the canonical kernel name for ``name`` (or an alias); raise OptionError if unknown."""
    key = str(name).lower().replace("-", "_")
    key = _ALIASES.get(key, key)
    if key not in KERNELS:
        raise OptionError(
            f"kernel: unknown kernel {name!r}; expected one of {', '.join(KERNELS)} "
            f"(aliases: {', '.join(_ALIASES)})"
        )
    return key


def get_kernel(name: str) -> Callable[..., np.ndarray]:
    """Return the kernel function called ``name`` (see :data:`KERNELS`); OptionError if unknown."""
    return KERNELS[canonical_kernel_name(name)]
