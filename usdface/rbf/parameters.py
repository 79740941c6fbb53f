"""What an :class:`~usdface.rbf.transfer.RBFTransfer` is asked to do, as two frozen dataclasses.

- :class:`RBFSettings`: the interpolation itself (mode, kernel, widths, polynomial term,
  regularisation, the default width factor, the policy for frames with no valid marker). Checked
  when made: every field on its own and the pairs that do not apply to paper mode.
- :class:`RBFCentres`: what the centres are (how many are markers, their names, the points of the
  polynomial term, the markers' bound triangles). Its fields are checked against the distances
  when the transfer is set up (:mod:`usdface.rbf.system`), since their expected sizes come from them.

Also the array checks every part of the transfer shares (:func:`as_float_array`, :func:`shape_error`).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError, OptionError, list_names
from .kernels import DECAYING_KERNELS, canonical_kernel_name
from .stiffness import DEFAULT_WIDTH_FACTOR

__all__ = ["RBFSettings", "RBFCentres", "MODES", "ALL_INVALID_POLICIES", "as_float_array", "shape_error"]

MODES = ("interpolate", "paper")
ALL_INVALID_POLICIES = ("error", "hold", "zero")


def shape_error(name: str, expected: str, arr) -> InputError:
    """The :class:`InputError` of an array ``name`` whose shape is not ``expected``."""
    return InputError(f"{name} must have shape {expected}; got {np.shape(arr)}")


def as_float_array(name: str, a) -> np.ndarray:
    """``a`` as a floating-point array (integers become float64; floats keep their type and are
    not copied), else an :class:`InputError` naming it."""
    try:
        arr = np.asarray(a)
    except Exception as exc:  # pragma: no cover - exotic array-likes
        raise InputError(f"{name}: cannot be read as an array ({exc})") from None
    if arr.dtype.kind not in "fiu":
        raise InputError(f"{name}: expected a numeric array; got dtype {arr.dtype}")
    if arr.dtype.kind != "f":
        arr = arr.astype(np.float64)
    return arr


@dataclass(frozen=True)
class RBFSettings:
    """How the marker displacements are interpolated (see :mod:`usdface.rbf.transfer`).

    Checked when made; ``kernel`` is stored under its canonical name, ``regularization`` as a float
    and ``polynomial`` as a bool.

    Attributes
    ----------
    mode : {"interpolate", "paper"}
        Interpolating solve, or the paper's Eqs. 1-5.
    kernel : str
        One of :data:`usdface.rbf.kernels.KERNELS` or an alias (``gaussian`` = paper Eq. 3).
    widths : None, float, sequence or dict
        Kernel width per centre (mesh units); see :func:`usdface.rbf.stiffness.resolve_widths`.
        None: ``width_factor`` x the median nearest-marker distance of ``D_cc`` (the plain rule; the
        pipeline's defaults come from :func:`usdface.rbf.stiffness.transfer_widths`, through
        :func:`usdface.rbf.build.build_transfer`).
    polynomial : bool
        Interpolate mode only: add the linear polynomial term (reproduces affine motion exactly;
        recommended with multiquadric, thin-plate spline and cubic). Needs
        :attr:`RBFCentres.centre_points` and :attr:`RBFCentres.vertex_points`.
    regularization : float
        Interpolate mode only: lambda >= 0 added to the diagonal of Phi_cc (in kernel units; phi(0)
        = 1 for gaussian and the multiquadrics). lambda > 0 smooths: the markers are no longer
        reproduced exactly.
    width_factor : float
        Multiple of the marker spacing used by the default width rule (unitless).
    all_invalid : {"error", "hold", "zero"}
        What to do with frames where every marker is invalid.

    Raises
    ------
    OptionError
        Bad mode, kernel, regularization or all_invalid, or a polynomial term, a kernel that does
        not decay or a regularisation with paper mode.
    """

    mode: str = "interpolate"
    kernel: str = "gaussian"
    widths: Any = None
    polynomial: bool = False
    regularization: float = 0.0
    width_factor: float = DEFAULT_WIDTH_FACTOR
    all_invalid: str = "error"

    def __post_init__(self) -> None:
        mode, kernel = self.mode, self.kernel
        if mode not in MODES:
            raise OptionError(f"mode: expected one of {', '.join(MODES)}; got {mode!r}")
        canonical = canonical_kernel_name(kernel)
        if self.all_invalid not in ALL_INVALID_POLICIES:
            raise OptionError(f"all_invalid: expected one of {', '.join(ALL_INVALID_POLICIES)}; "
                              f"got {self.all_invalid!r}")
        try:
            lam = float(self.regularization)
        except (TypeError, ValueError):
            raise OptionError(f"regularization: expected a number >= 0; got {self.regularization!r}") from None
        if not (math.isfinite(lam) and lam >= 0):
            raise OptionError(f"regularization: expected a finite number >= 0; got {self.regularization!r}")
        polynomial = bool(self.polynomial)
        if mode == "paper" and polynomial:
            raise OptionError("polynomial=True applies to mode='interpolate' only (Eqs. 1-5 have no polynomial term)")
        if mode == "paper" and canonical not in DECAYING_KERNELS:
            raise OptionError(f"kernel {kernel!r} does not decay with distance: paper mode (Eqs. 1-5, no solve) "
                              f"needs one of {', '.join(sorted(DECAYING_KERNELS))}; use mode='interpolate'")
        if mode == "paper" and lam > 0:
            raise OptionError("regularization applies to mode='interpolate' only (paper mode solves no system)")
        object.__setattr__(self, "kernel", canonical)
        object.__setattr__(self, "regularization", lam)
        object.__setattr__(self, "polynomial", polynomial)


@dataclass(frozen=True)
class RBFCentres:
    """What the C centres of the distance matrices are: the M markers first, then P constraint
    centres (pinned or rigid vertices, displacement always zero).

    The sizes are checked against the distances by :meth:`n_markers_of`,
    :meth:`polynomial_points` and :meth:`collocation_arrays` (the transfer's set-up calls them).

    Attributes
    ----------
    n_markers : int, optional
        M, the number of markers (the first M centres); default C (no constraint centres).
    centre_points : array_like, shape (C, 3), optional
        Centre positions (mesh units), for the polynomial term.
    vertex_points : array_like, shape (N, 3), optional
        Vertex positions (mesh units), for the polynomial term.
    marker_names : sequence of str, length M, optional
        For per-marker width dicts and messages; stored as a tuple of str.
    collocation : (tri (M, 3) int, bary (M, 3) float), optional
        Interpolate mode: impose the interpolation conditions on the field as the mesh shows it —
        marker j's row of the system is the barycentric combination (``bary[j]``) of the kernel
        rows of the vertices ``tri[j]`` of its triangle, instead of ``phi(D_cc[j])``. The vertex
        displacements then reproduce every marker exactly at its bound surface point, whatever the
        distance (hybrid distances jump where w crosses the threshold, so a marker's own distance
        row and its neighbouring vertices' rows can disagree). Constraint centres keep their rows.
    """

    n_markers: int | None = None
    centre_points: Any = None
    vertex_points: Any = None
    marker_names: Sequence[str] | None = None
    collocation: tuple | None = None

    def __post_init__(self) -> None:
        if self.marker_names is not None:
            object.__setattr__(self, "marker_names", tuple(str(n) for n in self.marker_names))

    def n_markers_of(self, n_centres: int) -> int:
        """M for C = ``n_centres`` centres, the marker names checked against it.

        Raises
        ------
        OptionError
            ``n_markers`` not an integer in 1..C; as many names as markers, none repeated.
        """
        M = n_centres if self.n_markers is None else self.n_markers
        if isinstance(M, bool) or not isinstance(M, (int, np.integer)) or not 1 <= M <= n_centres:
            raise OptionError(f"n_markers: expected an integer in 1..{n_centres} (the number of centres); "
                              f"got {self.n_markers!r}")
        names = self.marker_names
        if names is not None:
            if len(names) != M:
                raise OptionError(f"marker_names: {len(names)} names for {M} markers")
            if len(set(names)) != M:
                dup = sorted({n for n in names if names.count(n) > 1})
                raise OptionError(f"marker_names: duplicated names {list_names(dup)}")
        return int(M)

    def polynomial_points(self, n_vertices: int, n_centres: int) -> tuple[np.ndarray, np.ndarray]:
        """(centre points (C, 3), vertex points (N, 3)) as float arrays, for the polynomial term.

        Raises
        ------
        OptionError
            Either is missing.
        InputError
            Wrong shapes, NaN or infinite coordinates.
        """
        if self.centre_points is None or self.vertex_points is None:
            missing = [n for n, v in (("centre_points", self.centre_points), ("vertex_points", self.vertex_points))
                       if v is None]
            raise OptionError(f"polynomial=True needs {' and '.join(missing)} (positions in mesh units)")
        cp = as_float_array("centre_points", self.centre_points)
        vp = as_float_array("vertex_points", self.vertex_points)
        if cp.shape != (n_centres, 3):
            raise shape_error("centre_points", f"(C, 3) = ({n_centres}, 3)", cp)
        if vp.shape != (n_vertices, 3):
            raise shape_error("vertex_points", f"(N, 3) = ({n_vertices}, 3)", vp)
        for name, arr in (("centre_points", cp), ("vertex_points", vp)):
            if not np.isfinite(arr).all():
                raise InputError(f"{name}: {int((~np.isfinite(arr)).any(axis=1).sum())} point(s) are NaN or infinite")
        return cp, vp

    def collocation_arrays(self, mode: str, n_markers: int, n_vertices: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(tri (M, 3) int64, bary (M, 3) float64), or None without collocation.

        Raises
        ------
        OptionError
            Collocation with paper mode.
        InputError
            Wrong shapes, vertex indices outside 0..N-1.
        """
        if self.collocation is None:
            return None
        if mode != "interpolate":
            raise OptionError("collocation applies to mode='interpolate' only")
        tri = np.asarray(self.collocation[0], dtype=np.int64)
        bary = np.asarray(self.collocation[1], dtype=np.float64)
        M = n_markers
        if tri.shape != (M, 3) or bary.shape != (M, 3):
            raise shape_error("collocation", f"two arrays of shape (M, 3) = ({M}, 3)", tri)
        if tri.min() < 0 or tri.max() >= n_vertices:
            raise InputError(f"collocation: triangle vertex indices outside 0..{n_vertices - 1}")
        return tri, bary
