"""The checked RBF problem and its system matrix (seed 000, Eqs. 1-2).

:class:`RBFSystem` takes the distances, :class:`~usdface.rbf.parameters.RBFSettings` and
:class:`~usdface.rbf.parameters.RBFCentres`, checks them against each other once, resolves the
kernel widths and the polynomial basis, and gives the kernel rows (``Phi_vc``) and the full
interpolation matrix ``A`` that :mod:`usdface.rbf.solver` factorises. The conventions (per-centre
widths, asymmetric ``D_cc`` used row by row, collocation rows) are those of :mod:`usdface.rbf.transfer`.
"""
from __future__ import annotations

import numpy as np

from ..errors import ComputeError, InputError
from .kernels import DECAYING_KERNELS, KERNELS
from .parameters import RBFCentres, RBFSettings, as_float_array, shape_error
from .stiffness import resolve_widths

__all__ = ["RBFSystem"]


def _check_distances(name: str, arr: np.ndarray, kernel: str) -> None:
    """No NaN, no negative distance, and infinite ones only with a kernel that decays to zero."""
    nan = np.isnan(arr)
    if nan.any():
        raise InputError(f"{name}: {int(nan.sum())} distance(s) are NaN (e.g. at {tuple(int(i) for i in np.argwhere(nan)[0])})")
    neg = arr < 0
    if neg.any():
        raise InputError(f"{name}: {int(neg.sum())} distance(s) are negative (e.g. at {tuple(int(i) for i in np.argwhere(neg)[0])})")
    if kernel not in DECAYING_KERNELS and np.isinf(arr).any():
        raise ComputeError(
            f"{name}: {int(np.isinf(arr).sum())} infinite distance(s) (unreachable pairs) but kernel "
            f"{kernel!r} does not decay to zero; use gaussian or inverse_multiquadric, or finite distances"
        )


class RBFSystem:
    """The checked inputs of a transfer: distances, widths, polynomial basis, collocation rows.

    Parameters
    ----------
    D_vc : array_like, shape (N, C), float
        Vertex-to-centre distances (mesh units), >= 0; ``+inf`` allowed with decaying kernels.
        Not copied.
    D_cc : array_like, shape (C, C), float
        Centre-to-centre distances (mesh units), row j measured from centre j, markers first.
    settings : RBFSettings
    centres : RBFCentres

    Attributes
    ----------
    settings : RBFSettings
    n_vertices, n_centres, n_markers : int
        N, C and M.
    marker_names : tuple of str or None
    widths : ndarray, shape (C,), float64, read-only
        Kernel width per centre (mesh units).
    D_vc, D_cc : ndarray
        The distances as float arrays.
    P_c : ndarray, shape (C, 4), or None
        Polynomial basis ``[1, (x - origin) / scale]`` at the centres (``settings.polynomial`` only).
    vertex_points : ndarray, shape (N, 3), or None
        Vertex positions (mesh units), for the polynomial basis at the vertices.
    poly_origin : ndarray, shape (3,); poly_scale : float
        Centring and scale of the polynomial basis (mesh units).
    collocation : (ndarray (M, 3) int64, ndarray (M, 3) float64) or None

    Raises
    ------
    InputError
        Wrong shapes, NaN or negative distances, NaN/inf centre or vertex points.
    OptionError
        Bad n_markers, marker_names or widths; polynomial points missing; collocation in paper mode.
    ComputeError
        Infinite distances with a kernel that does not decay to zero; coincident centre points.
    """

    def __init__(self, D_vc, D_cc, settings: RBFSettings, centres: RBFCentres) -> None:
        self.settings = settings
        self.phi = KERNELS[settings.kernel]
        D_vc = as_float_array("D_vc", D_vc)
        D_cc = as_float_array("D_cc", D_cc)
        if D_vc.ndim != 2 or D_vc.shape[0] == 0 or D_vc.shape[1] == 0:
            raise shape_error("D_vc (vertex-to-centre distances)", "(N, C) with N, C >= 1", D_vc)
        N, C = D_vc.shape
        if D_cc.shape != (C, C):
            raise shape_error("D_cc (centre-to-centre distances)", f"(C, C) = ({C}, {C}) to match D_vc", D_cc)
        M = centres.n_markers_of(C)
        self.n_vertices, self.n_centres, self.n_markers = int(N), int(C), M
        self.marker_names = centres.marker_names
        for name, arr in (("D_vc", D_vc), ("D_cc", D_cc)):
            _check_distances(name, arr, settings.kernel)
        self.D_vc, self.D_cc = D_vc, D_cc

        self.P_c = self.vertex_points = self.poly_origin = self.poly_scale = None
        if settings.polynomial:
            cp, vp = centres.polynomial_points(N, C)
            # P = [1, (x - c) / L]: the same polynomial space, better conditioned than raw coordinates
            origin = cp.mean(axis=0)
            scale = float(np.sqrt(((cp - origin) ** 2).sum(axis=1).mean()))
            if not scale > 0:
                raise ComputeError("polynomial term: all centre points coincide")
            self.poly_origin, self.poly_scale = origin, scale
            self.P_c = np.hstack([np.ones((C, 1)), (cp - origin) / scale])
            self.vertex_points = vp

        self.widths = resolve_widths(settings.widths, D_cc, M, marker_names=self.marker_names,
                                     factor=settings.width_factor)
        self.widths.setflags(write=False)
        self.collocation = centres.collocation_arrays(settings.mode, M, N)

    def marker_label(self, j: int) -> str:
        """Centre ``j`` for messages: the marker's name (quoted), ``marker #j`` or ``constraint centre #p``."""
        if j < self.n_markers:
            return repr(self.marker_names[j]) if self.marker_names is not None else f"marker #{j}"
        return f"constraint centre #{j - self.n_markers}"

    def kernel_rows(self, rows: slice, cols: slice | None = None) -> np.ndarray:
        """``Phi_vc[rows, cols]`` (float64) from ``D_vc``, each column with its centre's width."""
        cols = slice(None) if cols is None else cols
        return self.phi(self.D_vc[rows, cols], self.widths[cols])

    def matrix(self) -> np.ndarray:
        """The full (all markers valid) system matrix A, (C, C) or with the polynomial (C + 4, C + 4).

        ``Phi_cc`` (column k with centre k's width; marker rows replaced by their collocation rows
        when given), ``regularization`` on its diagonal, bordered by ``P`` and ``P^T`` with the
        polynomial term (seed 000, Eq. 2; the polynomial block is the usual RBF augmentation).
        """
        phi_cc = self.phi(self.D_cc, self.widths)  # column k uses the width of centre k
        C = self.n_centres
        lam = self.settings.regularization
        if self.collocation is not None:
            tri, bary = self.collocation
            rows = self.phi(self.D_vc[tri.ravel()], self.widths).reshape(tri.shape[0], 3, C)
            phi_cc[: tri.shape[0]] = np.einsum("mt,mtc->mc", bary, rows)
        if not self.settings.polynomial:
            A = phi_cc
            A[np.diag_indices(C)] += lam
            return A
        A = np.zeros((C + 4, C + 4))
        A[:C, :C] = phi_cc
        A[np.arange(C), np.arange(C)] += lam
        A[:C, C:] = self.P_c
        A[C:, :C] = self.P_c.T
        return A
