"""RBF transfer of marker displacements onto mesh vertices (seed 000, Eqs. 1-5).

Inputs are precomputed distances (Euclidean, geodesic or hybrid; :mod:`usdface.distance` makes
them): ``D_vc`` (N, C) vertex-to-centre and ``D_cc`` (C, C) centre-to-centre, where the C centres
are the M markers followed by P constraint centres (pinned or rigid vertices, displacement always
zero), and per-frame marker displacements (F, M, 3) with NaN for invalid samples.

Kernel widths and asymmetric distances
--------------------------------------
Each centre k has its own kernel ``phi_k(d) = phi(d / s_k)`` (the authors' per-marker
"stiffness"). A point's basis row is ``phi_k(distance from the point to centre k)`` for every k:
the evaluation matrix is ``Phi_vc[i, k] = phi_k(D_vc[i, k])`` and the interpolation matrix is
built the same way, ``Phi_cc[j, k] = phi_k(D_cc[j, k])`` -- row j is "centre j seen as a point".
``D_cc`` need not be symmetric (the hybrid distance uses the row centre's weight); it is used as
given, row j measured from centre j, and never symmetrised. With that convention a vertex whose
distance row equals centre j's row gets exactly centre j's value, so the interpolation is exact at
the centres whatever the asymmetry.

Modes
-----
``mode="interpolate"`` (default)
    Solve ``Phi_cc W = D`` (C x C; with ``polynomial=True`` the augmented system
    ``[[Phi_cc, P], [P^T, 0]] [W; c] = [D; 0]`` with ``P = [1, x, y, z]`` of the centre points),
    ``regularization`` (lambda >= 0) added to the diagonal of ``Phi_cc``. Exact at the centres when
    lambda = 0; constraint centres are held at zero. The solve is factorised once (LU with partial
    pivoting) and folded into the transfer matrix ``B = [Phi_vc, P_v] A^-1`` restricted to the M
    marker columns (constraint centres have zero displacement, so their columns never matter): a
    frame is ``Dv = B @ D_markers``, and a whole sequence is one float32 matrix product
    (B (N, M) @ D (M, 3F)), computed in chunks of frames.
``mode="paper"``
    Eqs. 1-5 exactly, weights not solved: ``W_j = D_j / sum_k phi_k(d_jk)`` (Eq. 4, k over the
    markers) and ``Dv_i = sum_j W_j phi_j(d_ij)`` (Eq. 5); Gaussian kernel (Eq. 3, gamma = 2) with a
    width per marker as in the authors' plug-in (other kernels are accepted). It does not reproduce
    the markers exactly. Constraint centres have D = 0, hence W = 0, and are not part of the marker
    sums of Eq. 4: in paper mode they do nothing at all. With per-marker widths the paper is
    ambiguous about which width enters Eq. 4; usdface uses ``phi_k`` (the ``Phi_cc`` convention
    above, which is Eq. 2 with all weights equal); the authors' plug-in uses the width of marker
    ``min(j, k)`` (it fills a symmetric matrix from its upper triangle). All agree for one width for
    every marker, the plug-in's default (2 cm).

Invalid samples
---------------
A marker whose displacement has a NaN (or infinite) component in a frame is invalid in that frame.
Each frame is solved with its valid markers only: the invalid centres are dropped from the system
(interpolate) or from the sums of Eqs. 4-5 (paper); NaN never enters a solve. One operator is
computed and cached per validity pattern (key: the pattern's bytes), see :meth:`RBFTransfer.cache_info`.

For the interpolating solve the reduced system is never refactorised from scratch: by the block
inverse identity ``(A_SS)^-1 = Z_SS - Z_SR Z_RR^-1 Z_RS`` (Z = A^-1, S kept, R dropped), the
reduced interpolant equals the full interpolant fed with *effective* displacements: the valid
markers' own displacements, and at each dropped marker r the value the reduced interpolant takes
there, ``D_R = A_RS A_SS^-1 D_S = -Z_RR^-1 Z_RS D_S``. Only the M x M marker block of A^-1 is
needed, so a new pattern costs O(M^3) instead of O(C^3 + N C M), and every frame, whatever its
pattern, goes through the same N x M matrix B in the same matrix product. Paper mode does the same
with the renormalised Eq. 4 (``D_eff_j = D_j * r_j / r_j^S`` with r the Eq. 4 sums).

Frames with no valid marker follow ``all_invalid``: ``"error"`` (ComputeError naming the frames,
raised before any output), ``"hold"`` (repeat the previous frame's result; frames before the first
valid frame get zero displacement) or ``"zero"`` (zero displacement: the rest pose).

Speed, memory and threads
-------------------------
Set-up (:meth:`RBFTransfer.fit`) is one SVD (condition number) and one LU solve of the (C [+ 4])
system and N x C kernel evaluations in blocks of vertices. Evaluation is a float32 GEMM in chunks
of frames into a fresh (f, N, 3) array per chunk (or one reused buffer), so
:meth:`RBFTransfer.iter_chunks` holds one or two chunks (~64 MiB each by default) at a time: a
1000-frame x 100k-vertex sequence (1.2 GB of float32) streams with bounded memory. Everything,
set-up included, uses numpy's linear algebra only: numpy and scipy each ship an OpenBLAS whose
thread pools fight when calls alternate (scipy.linalg.lu_solve + numpy matmul in a per-frame loop
ran 10-20x slower). ``blas_threads`` limits numpy's pool through threadpoolctl (e.g. inside a DCC).
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Iterator, Sequence

import numpy as np

from ..errors import ComputeError, InputError, OptionError, list_names
from .kernels import DECAYING_KERNELS, KERNELS, canonical_kernel_name
from .stiffness import DEFAULT_WIDTH_FACTOR, resolve_widths

__all__ = ["RBFTransfer", "transfer_motion", "ADVICE_CONDITION", "MODES", "ALL_INVALID_POLICIES"]

#: condition number above which :attr:`RBFTransfer.advice` speaks up (and fit() warns)
ADVICE_CONDITION = 1e10
#: condition number (or an exactly singular LU) at which fit() refuses: the result is meaningless
SINGULAR_CONDITION = 1e15
#: centres closer than this fraction of their (smaller) kernel width count as nearly coincident
COINCIDENT_RTOL = 1e-2
MODES = ("interpolate", "paper")
ALL_INVALID_POLICIES = ("error", "hold", "zero")

_SETUP_BLOCK_BYTES = 32 << 20  # kernel evaluation block during fit()
_CHUNK_BYTES = 64 << 20  # default output chunk size of iter_chunks()
_GEMM_TEMP_BYTES = 32 << 20  # GEMM temporary (a block of frames) in iter_chunks()


def check_chunk_frames(value) -> int:
    """``value`` as frames per chunk: an integer >= 1, else an :class:`OptionError` naming it."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise OptionError(f"chunk_frames: expected an integer >= 1; got {value!r}")
    return int(value)


def _shape_error(name: str, expected: str, arr) -> InputError:
    return InputError(f"{name} must have shape {expected}; got {np.shape(arr)}")


def _as_float_array(name: str, a) -> np.ndarray:
    try:
        arr = np.asarray(a)
    except Exception as exc:  # pragma: no cover - exotic array-likes
        raise InputError(f"{name}: cannot be read as an array ({exc})") from None
    if arr.dtype.kind not in "fiu":
        raise InputError(f"{name}: expected a numeric array; got dtype {arr.dtype}")
    if arr.dtype.kind != "f":
        arr = arr.astype(np.float64)
    return arr


class RBFTransfer:
    """Transfer marker displacements onto mesh vertices with radial basis functions.

    Build once (:meth:`fit` factorises; it runs on first use if not called), then evaluate many
    sequences with :meth:`apply` or :meth:`iter_chunks`.

    Parameters
    ----------
    D_vc : array_like, shape (N, C), float
        Vertex-to-centre distances (mesh units), >= 0; ``+inf`` allowed with decaying kernels
        (gaussian, inverse_multiquadric) and means "no influence". Not copied: do not modify it
        before :meth:`fit`.
    D_cc : array_like, shape (C, C), float
        Centre-to-centre distances (mesh units), row j measured from centre j, not necessarily
        symmetric (see the module docstring), centres ordered markers first.
    mode : {"interpolate", "paper"}
        Interpolating solve, or the paper's Eqs. 1-5 (see the module docstring).
    kernel : str
        One of :data:`usdface.rbf.kernels.KERNELS` (``gaussian`` = paper Eq. 3).
    widths : None, float, sequence or dict
        Kernel width per centre (mesh units); see :func:`usdface.rbf.stiffness.resolve_widths`.
        None: ``width_factor`` x the median nearest-marker distance of ``D_cc`` (the plain rule; the
        pipeline's defaults come from :func:`usdface.rbf.stiffness.transfer_widths`, through
        :func:`usdface.rbf.build.build_transfer`).
    polynomial : bool
        Interpolate mode only: add the linear polynomial term (reproduces affine motion exactly;
        recommended with multiquadric, thin-plate spline and cubic). Needs ``centre_points`` and
        ``vertex_points``.
    regularization : float
        Interpolate mode only: lambda >= 0 added to the diagonal of Phi_cc (in kernel units; phi(0)
        = 1 for gaussian and the multiquadrics). lambda > 0 smooths: the markers are no longer
        reproduced exactly.
    n_markers : int, optional
        M, the number of markers (the first M centres); default C (no constraint centres).
    centre_points : array_like, shape (C, 3), optional
        Centre positions (mesh units), for the polynomial term.
    vertex_points : array_like, shape (N, 3), optional
        Vertex positions (mesh units), for the polynomial term.
    marker_names : sequence of str, length M, optional
        For per-marker width dicts and messages.
    width_factor : float
        Multiple of the marker spacing used by the default width rule.
    all_invalid : {"error", "hold", "zero"}
        What to do with frames where every marker is invalid.
    collocation : (tri (M, 3) int, bary (M, 3) float), optional
        Interpolate mode: impose the interpolation conditions on the field as the mesh shows it —
        marker j's row of the system is the barycentric combination (``bary[j]``) of the kernel
        rows of the vertices ``tri[j]`` of its triangle, instead of ``phi(D_cc[j])``. The vertex
        displacements then reproduce every marker exactly at its bound surface point, whatever the
        distance (hybrid distances jump where w crosses the threshold, so a marker's own distance
        row and its neighbouring vertices' rows can disagree). Constraint centres keep their rows.

    Raises
    ------
    InputError
        Wrong shapes, NaN or negative distances, NaN/inf centre or vertex points.
    OptionError
        Bad mode, kernel, widths, regularization, n_markers, all_invalid, or options that do not
        apply to the mode.
    ComputeError
        Infinite distances with a kernel that does not decay to zero.

    Examples
    --------
    >>> rbf = RBFTransfer(D_vc, D_cc, n_markers=41).fit()            # doctest: +SKIP
    >>> for frames, points in rbf.iter_chunks(displacements):         # doctest: +SKIP
    ...     write(frames, rest_points + points)
    """

    def __init__(
        self,
        D_vc,
        D_cc,
        *,
        mode: str = "interpolate",
        kernel: str = "gaussian",
        widths=None,
        polynomial: bool = False,
        regularization: float = 0.0,
        n_markers: int | None = None,
        centre_points=None,
        vertex_points=None,
        marker_names: Sequence[str] | None = None,
        width_factor: float = DEFAULT_WIDTH_FACTOR,
        all_invalid: str = "error",
        collocation=None,
    ) -> None:
        if mode not in MODES:
            raise OptionError(f"mode: expected one of {', '.join(MODES)}; got {mode!r}")
        self.mode = mode
        self.kernel = canonical_kernel_name(kernel)
        self._phi = KERNELS[self.kernel]
        if all_invalid not in ALL_INVALID_POLICIES:
            raise OptionError(f"all_invalid: expected one of {', '.join(ALL_INVALID_POLICIES)}; got {all_invalid!r}")
        self.all_invalid = all_invalid
        try:
            lam = float(regularization)
        except (TypeError, ValueError):
            raise OptionError(f"regularization: expected a number >= 0; got {regularization!r}") from None
        if not (math.isfinite(lam) and lam >= 0):
            raise OptionError(f"regularization: expected a finite number >= 0; got {regularization!r}")
        self.regularization = lam
        self.polynomial = bool(polynomial)
        if mode == "paper" and self.polynomial:
            raise OptionError("polynomial=True applies to mode='interpolate' only (Eqs. 1-5 have no polynomial term)")
        if mode == "paper" and canonical_kernel_name(kernel) not in DECAYING_KERNELS:
            raise OptionError(f"kernel {kernel!r} does not decay with distance: paper mode (Eqs. 1-5, no solve) "
                              f"needs one of {', '.join(sorted(DECAYING_KERNELS))}; use mode='interpolate'")
        if mode == "paper" and lam > 0:
            raise OptionError("regularization applies to mode='interpolate' only (paper mode solves no system)")

        D_vc = _as_float_array("D_vc", D_vc)
        D_cc = _as_float_array("D_cc", D_cc)
        if D_vc.ndim != 2 or D_vc.shape[0] == 0 or D_vc.shape[1] == 0:
            raise _shape_error("D_vc (vertex-to-centre distances)", "(N, C) with N, C >= 1", D_vc)
        N, C = D_vc.shape
        if D_cc.shape != (C, C):
            raise _shape_error("D_cc (centre-to-centre distances)", f"(C, C) = ({C}, {C}) to match D_vc", D_cc)
        M = C if n_markers is None else n_markers
        if isinstance(M, bool) or not isinstance(M, (int, np.integer)) or not 1 <= M <= C:
            raise OptionError(f"n_markers: expected an integer in 1..{C} (the number of centres); got {n_markers!r}")
        self.n_vertices, self.n_centres, self.n_markers = int(N), int(C), int(M)
        if marker_names is not None:
            marker_names = tuple(str(n) for n in marker_names)
            if len(marker_names) != M:
                raise OptionError(f"marker_names: {len(marker_names)} names for {M} markers")
            if len(set(marker_names)) != M:
                dup = sorted({n for n in marker_names if marker_names.count(n) > 1})
                raise OptionError(f"marker_names: duplicated names {list_names(dup)}")
        self.marker_names = marker_names

        for name, arr in (("D_vc", D_vc), ("D_cc", D_cc)):
            nan = np.isnan(arr)
            if nan.any():
                raise InputError(f"{name}: {int(nan.sum())} distance(s) are NaN (e.g. at {tuple(int(i) for i in np.argwhere(nan)[0])})")
            neg = arr < 0
            if neg.any():
                raise InputError(f"{name}: {int(neg.sum())} distance(s) are negative (e.g. at {tuple(int(i) for i in np.argwhere(neg)[0])})")
            if self.kernel not in DECAYING_KERNELS and np.isinf(arr).any():
                raise ComputeError(
                    f"{name}: {int(np.isinf(arr).sum())} infinite distance(s) (unreachable pairs) but kernel "
                    f"{self.kernel!r} does not decay to zero; use gaussian or inverse_multiquadric, or finite distances"
                )
        self._D_vc, self._D_cc = D_vc, D_cc

        self._P_c = None
        if self.polynomial:
            if centre_points is None or vertex_points is None:
                missing = [n for n, v in (("centre_points", centre_points), ("vertex_points", vertex_points)) if v is None]
                raise OptionError(f"polynomial=True needs {' and '.join(missing)} (positions in mesh units)")
            cp = _as_float_array("centre_points", centre_points)
            vp = _as_float_array("vertex_points", vertex_points)
            if cp.shape != (C, 3):
                raise _shape_error("centre_points", f"(C, 3) = ({C}, 3)", cp)
            if vp.shape != (N, 3):
                raise _shape_error("vertex_points", f"(N, 3) = ({N}, 3)", vp)
            for name, arr in (("centre_points", cp), ("vertex_points", vp)):
                if not np.isfinite(arr).all():
                    raise InputError(f"{name}: {int((~np.isfinite(arr)).any(axis=1).sum())} point(s) are NaN or infinite")
            # P = [1, (x - c) / L]: the same polynomial space, better conditioned than raw coordinates
            origin = cp.mean(axis=0)
            scale = float(np.sqrt(((cp - origin) ** 2).sum(axis=1).mean()))
            if not scale > 0:
                raise ComputeError("polynomial term: all centre points coincide")
            self._poly_origin, self._poly_scale = origin, scale
            self._P_c = np.hstack([np.ones((C, 1)), (cp - origin) / scale])
            self._vertex_points = vp

        self.widths = resolve_widths(widths, D_cc, M, marker_names=marker_names, factor=width_factor)
        self.widths.setflags(write=False)

        self._colloc = None
        if collocation is not None:
            if mode != "interpolate":
                raise OptionError("collocation applies to mode='interpolate' only")
            tri = np.asarray(collocation[0], dtype=np.int64)
            bary = np.asarray(collocation[1], dtype=np.float64)
            if tri.shape != (M, 3) or bary.shape != (M, 3):
                raise _shape_error("collocation", f"two arrays of shape (M, 3) = ({M}, 3)", tri)
            if tri.min() < 0 or tri.max() >= N:
                raise InputError(f"collocation: triangle vertex indices outside 0..{N - 1}")
            self._colloc = (tri, bary)

        self._fitted = False
        self._B64 = self._B32 = None
        self._cond: float | None = None
        self._cache: dict[bytes, np.ndarray] = {}
        self._hits = 0
        self._misses = 0

    # ------------------------------------------------------------------ set-up
    def _marker_label(self, j: int) -> str:
        if j < self.n_markers:
            return repr(self.marker_names[j]) if self.marker_names is not None else f"marker #{j}"
        return f"constraint centre #{j - self.n_markers}"

    def _kernel_rows(self, rows: slice, cols: slice | None = None) -> np.ndarray:
        """Phi_vc[rows, cols] (float64) from D_vc, width of each column's centre."""
        cols = slice(None) if cols is None else cols
        return self._phi(self._D_vc[rows, cols], self.widths[cols])

    def _system_matrix(self) -> np.ndarray:
        """The full (all markers valid) system matrix A (C or C + 4 square)."""
        phi_cc = self._phi(self._D_cc, self.widths)  # column k uses the width of centre k
        C = self.n_centres
        if self._colloc is not None:
            tri, bary = self._colloc
            rows = self._phi(self._D_vc[tri.ravel()], self.widths).reshape(tri.shape[0], 3, C)
            phi_cc[: tri.shape[0]] = np.einsum("mt,mtc->mc", bary, rows)
        if not self.polynomial:
            A = phi_cc
            A[np.diag_indices(C)] += self.regularization
            return A
        A = np.zeros((C + 4, C + 4))
        A[:C, :C] = phi_cc
        A[np.arange(C), np.arange(C)] += self.regularization
        A[:C, C:] = self._P_c
        A[C:, :C] = self._P_c.T
        return A

    def fit(self) -> "RBFTransfer":
        """Factorise the system once and build the transfer matrix B (N x M).

        Interpolate mode: the 2-norm condition number of the (C [+ 4]) system (one SVD), one LU
        solve (partial pivoting) for ``Z = A^-1[:, :M]`` and ``B = [Phi_vc, P_v] @ Z`` (kernel evaluated in
        blocks of vertices). Paper mode: ``B[:, j] = Phi_vc[:, j] / sum_k Phi_cc[j, k]`` (Eqs. 4-5,
        k over the markers). Also caches the all-valid pattern.

        Returns
        -------
        RBFTransfer
            ``self``.

        Raises
        ------
        ComputeError
            Singular or numerically singular system (the message carries :attr:`advice`), or
            non-positive Eq. 4 sums in paper mode.

        Warns
        -----
        RuntimeWarning
            Condition number above :data:`ADVICE_CONDITION` (the warning text is :attr:`advice`).
        """
        N, C, M = self.n_vertices, self.n_centres, self.n_markers
        if self.mode == "interpolate":
            A = self._system_matrix()
            try:
                self._cond = float(np.linalg.cond(A))  # 2-norm, SVD: O(C^3), once
            except np.linalg.LinAlgError:  # pragma: no cover - SVD did not converge
                self._cond = float("inf")
            if not self._cond < SINGULAR_CONDITION:
                raise ComputeError(f"RBF system is singular; cannot transfer. {self._build_advice()}")
            E = np.zeros((A.shape[0], M))
            E[np.arange(M), np.arange(M)] = 1.0
            try:
                Z = np.linalg.solve(A, E)  # LU with partial pivoting (LAPACK gesv); Z = A^-1[:, :M]
            except np.linalg.LinAlgError:  # pragma: no cover - guarded by the condition check
                raise ComputeError(f"RBF system is singular; cannot transfer. {self._build_advice()}") from None
            self._Z_mm = np.ascontiguousarray(Z[:M, :M])
            Zc = np.ascontiguousarray(Z[:C])
            Zp = Z[C:] if self.polynomial else None
            B = np.empty((N, M))
            step = max(1, _SETUP_BLOCK_BYTES // (8 * C))
            for a in range(0, N, step):
                b = min(N, a + step)
                np.matmul(self._kernel_rows(slice(a, b)), Zc, out=B[a:b])
                if Zp is not None:
                    pv = (self._vertex_points[a:b] - self._poly_origin) / self._poly_scale
                    B[a:b] += Zp[0] + pv @ Zp[1:]
        else:
            phi_mm = self._phi(self._D_cc[:M, :M], self.widths[:M])
            r = phi_mm.sum(axis=1)
            bad = ~(np.isfinite(r) & (r > 0))
            if bad.any():
                labels = [self._marker_label(j) for j in np.flatnonzero(bad)]
                raise ComputeError(
                    f"paper mode: Eq. 4 sums sum_k phi(d_jk) are not positive for {list_names(labels)}; "
                    f"kernel {self.kernel!r} cannot be used in paper mode here (use gaussian)"
                )
            self._phi_mm = phi_mm
            self._r = r
            B = np.empty((N, M))
            step = max(1, _SETUP_BLOCK_BYTES // (8 * M))
            for a in range(0, N, step):
                b = min(N, a + step)
                np.divide(self._kernel_rows(slice(a, b), slice(0, M)), r, out=B[a:b])
            self._cond = None
        if not np.isfinite(B).all():
            raise ComputeError(f"RBF transfer matrix has non-finite entries. {self._build_advice()}")
        B.setflags(write=False)
        self._B64 = B
        self._B32 = B.astype(np.float32)
        self._B32.setflags(write=False)
        self._cache = {np.ones(M, dtype=bool).tobytes(): np.eye(M)}
        self._hits = self._misses = 0
        self._fitted = True
        if self._cond is not None and self._cond > ADVICE_CONDITION:
            warnings.warn(self._build_advice(), RuntimeWarning, stacklevel=2)
        return self

    def _ensure_fitted(self) -> None:
        if not self._fitted:
            self.fit()

    # ------------------------------------------------------------------ diagnostics
    @property
    def transfer_matrix(self) -> np.ndarray:
        """B, shape (N, M), float64, read-only: marker displacements to vertex displacements.

        For the all-valid pattern, a frame's vertex displacements are ``Dv = B @ D`` with D the
        (M, 3) marker displacements (mesh units), so B can serve as skin weights (one column per
        marker). Interpolate mode: ``B = [Phi_vc, P_v] A^-1`` restricted to the marker columns;
        paper mode: ``B[i, j] = phi_j(d_ij) / sum_k phi_k(d_jk)`` (Eqs. 4-5).
        """
        self._ensure_fitted()
        return self._B64

    @property
    def condition_number(self) -> float | None:
        """2-norm condition number of the full (all markers valid) interpolation system.

        Includes the regularisation and the polynomial block; ``inf`` when singular. None in paper
        mode (no system is solved). Computed by :meth:`fit` with one SVD (O(C^3): milliseconds for
        tens or hundreds of centres, seconds for a few thousand).
        """
        if not self._fitted:
            try:
                self.fit()
            except ComputeError:
                pass
        return self._cond

    def nearly_coincident(self, rtol: float = COINCIDENT_RTOL) -> list[tuple[str, str, float]]:
        """Pairs of centres closer than ``rtol`` times the smaller of their kernel widths.

        Returns
        -------
        list of (str, str, float)
            (label of centre j, label of centre k, distance in mesh units), closest first; labels are
            marker names (quoted) or ``constraint centre #p``. Distance is ``min(D_cc[j, k], D_cc[k, j])``.
        """
        d = np.minimum(self._D_cc, self._D_cc.T)
        w = self.widths
        tol = rtol * np.minimum(w[:, None], w[None, :])
        j, k = np.nonzero(np.triu(d < tol, k=1))
        order = np.argsort(d[j, k], kind="stable")
        return [(self._marker_label(int(j[o])), self._marker_label(int(k[o])), float(d[j[o], k[o]])) for o in order]

    def _build_advice(self) -> str:
        cond = self._cond
        parts = []
        if cond is None or not np.isfinite(cond):
            parts.append("the interpolation matrix is singular")
        else:
            parts.append(f"the interpolation matrix has condition number {cond:.3g} (> {ADVICE_CONDITION:.0e}): "
                         "the solve amplifies noise and round-off")
        pairs = self.nearly_coincident()
        if pairs:
            shown = [f"{a} and {b} ({d:.3g} apart)" for a, b, d in pairs]
            parts.append(f"nearly coincident centres (closer than {COINCIDENT_RTOL:g} x kernel width): {list_names(shown, limit=8)}; "
                         "remove or merge duplicates (check the marker binding)")
        w = self.widths
        d = np.minimum(self._D_cc, self._D_cc.T).astype(np.float64)
        np.fill_diagonal(d, np.inf)
        nearest = d.min(axis=1)
        ratio = nearest / w
        parts.append(
            f"kernel widths {w.min():.3g}..{w.max():.3g} mesh units vs nearest-centre distances down to "
            f"{nearest.min():.3g}: try a smaller width, regularization > 0 (e.g. 1e-8..1e-3)"
            + (", or a polynomial term with a polyharmonic kernel" if not self.polynomial else "")
        )
        if self.n_centres > self.n_markers and np.median(ratio[self.n_markers:]) < 0.5 * np.median(ratio[: self.n_markers]):
            parts.append("constraint centres are much denser than the markers: subsample them to about the marker spacing")
        return "; ".join(parts) + "."

    @property
    def advice(self) -> str | None:
        """What to do about a badly conditioned system, or None when the system is fine.

        Speaks up when :attr:`condition_number` exceeds :data:`ADVICE_CONDITION` (1e10): suggests a
        smaller kernel width, regularisation, a polynomial term, and names nearly coincident
        centres (marker names when given) when there are any.
        """
        cond = self.condition_number
        if cond is None or cond <= ADVICE_CONDITION:
            return None
        return self._build_advice()

    def cache_info(self) -> dict[str, int]:
        """Validity-pattern cache statistics.

        Every frame looks up its pattern: ``misses`` counts patterns computed (one small operator
        each), ``hits`` frames served by a cached one; ``patterns`` is the cache size. The all-valid
        pattern is computed by :meth:`fit` and counted neither as a miss nor, for all-valid frames,
        as a hit. Frames with no valid marker are not looked up.
        """
        return {"hits": self._hits, "misses": self._misses, "patterns": len(self._cache)}

    def clear_cache(self) -> None:
        """Forget every validity pattern except the all-valid one; reset the counters."""
        full = np.ones(self.n_markers, dtype=bool).tobytes()
        self._cache = {k: v for k, v in self._cache.items() if k == full}
        self._hits = self._misses = 0

    # ------------------------------------------------------------------ validity patterns
    def _pattern_operator(self, valid: np.ndarray, frames: np.ndarray) -> np.ndarray:
        """(M, |S|) operator E: effective marker displacements = E @ valid displacements."""
        M = self.n_markers
        S = np.flatnonzero(valid)
        R = np.flatnonzero(~valid)
        E = np.zeros((M, S.size))
        where = lambda: (f"frame(s) {list_names(frames.tolist(), limit=8)} with invalid markers "
                         f"{list_names([self._marker_label(int(r)) for r in R], limit=8)}")
        if self.mode == "paper":
            rS = self._phi_mm[np.ix_(S, S)].sum(axis=1)
            if not (np.isfinite(rS) & (rS > 0)).all():
                raise ComputeError(f"paper mode: Eq. 4 sums are not positive for {where()}")
            E[S, np.arange(S.size)] = self._r[S] / rS
            return E
        if self.polynomial:
            P_S = np.vstack([self._P_c[S], self._P_c[M:]])
            if np.linalg.matrix_rank(P_S) < 4:
                raise ComputeError(
                    f"polynomial term: the valid centres of {where()} are coplanar or fewer than 4; "
                    "the linear part is undetermined (add constraint centres or use polynomial=False)"
                )
        Z = self._Z_mm
        Z_RR = Z[np.ix_(R, R)]
        try:
            K = np.linalg.solve(Z_RR, Z[np.ix_(R, S)])
        except np.linalg.LinAlgError:
            K = None
        if K is None or not np.isfinite(K).all() or np.linalg.cond(Z_RR) > SINGULAR_CONDITION:
            raise ComputeError(f"RBF system without the invalid markers is singular for {where()}")
        E[S, np.arange(S.size)] = 1.0
        E[R] = -K
        return E

    def _scan(self, disp: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[bytes]]:
        """Validity of every frame; computes (and counts) every pattern before any output.

        Returns (valid (F, M) bool, pattern id per frame (-1 for all-valid, -2 for none valid),
        list of pattern keys by id).
        """
        F, M = disp.shape[:2]
        valid = np.isfinite(disp).all(axis=2)
        n_valid = valid.sum(axis=1)
        none = np.flatnonzero(n_valid == 0)
        if none.size and self.all_invalid == "error":
            err = ComputeError(
                f"{none.size} frame(s) have no valid marker: frame index(es) {list_names(none.tolist())} of {F}; "
                "fill the gaps or use all_invalid='hold' or 'zero'"
            )
            err.frames = none.tolist()
            raise err
        pid = np.full(F, -1, dtype=np.int64)
        pid[none] = -2
        partial = np.flatnonzero((n_valid > 0) & (n_valid < M))
        keys: list[bytes] = []
        if partial.size:
            uniq, inv, counts = np.unique(valid[partial], axis=0, return_inverse=True, return_counts=True)
            inv = inv.ravel()
            for u, (pattern, count) in enumerate(zip(uniq, counts)):
                key = np.ascontiguousarray(pattern).tobytes()
                keys.append(key)
                if key in self._cache:
                    self._hits += int(count)
                else:
                    self._cache[key] = self._pattern_operator(pattern, partial[inv == u])
                    self._misses += 1
                    self._hits += int(count) - 1
            pid[partial] = inv
        return valid, pid, keys

    def _effective(self, disp: np.ndarray, valid: np.ndarray, pid: np.ndarray, keys: list[bytes],
                   held: np.ndarray | None) -> np.ndarray:
        """(f, M, 3) float64 effective marker displacements of a chunk (no NaN)."""
        f, M = disp.shape[:2]
        out = np.empty((f, M, 3))
        full = pid == -1
        out[full] = disp[full]
        for u in np.unique(pid[pid >= 0]):
            idx = np.flatnonzero(pid == u)
            S = valid[idx[0]]
            E = self._cache[keys[u]]
            out[idx] = np.einsum("ms,fsc->fmc", E, disp[idx][:, S])
        for i in np.flatnonzero(pid == -2):
            if self.all_invalid == "hold" and (i > 0 or held is not None):
                out[i] = out[i - 1] if i > 0 else held
            else:
                out[i] = 0.0
        return out

    # ------------------------------------------------------------------ evaluation
    def _check_displacements(self, displacements) -> tuple[np.ndarray, bool]:
        d = _as_float_array("displacements", displacements)
        single = d.ndim == 2
        if single:
            d = d[None]
        if d.ndim != 3 or d.shape[1:] != (self.n_markers, 3):
            raise _shape_error("displacements", f"(F, M, 3) = (F, {self.n_markers}, 3) (or (M, 3) for one frame)", displacements)
        return d, single

    def _gemm_buffer(self, frames: int, dtype) -> np.ndarray:
        """GEMM temporary for blocks of up to ``frames`` frames, reused across chunks."""
        sub = int(min(frames, max(1, _GEMM_TEMP_BYTES // (3 * self.n_vertices * np.dtype(dtype).itemsize))))
        return np.empty((3 * sub, self.n_vertices), dtype=dtype)

    def _evaluate(self, eff: np.ndarray, out: np.ndarray, tmp: np.ndarray | None = None, *,
                  rhs: np.ndarray | None = None, extents: np.ndarray | None = None) -> None:
        """out[k] = B @ eff[k] for every frame k of a chunk (out: (f, N, 3), C-contiguous).

        One GEMM per block of frames, ``(3 f', M) @ B^T (M, N) -> (3 f', N)`` (rows ordered frame,
        component), then three strided copies interleave x, y, z into the (f', N, 3) output. This
        orientation keeps the GEMM efficient (B is streamed once per block of frames) and the
        interleaving copy cheap; a per-frame product would re-read B every frame.

        ``rhs`` (M + 3, N), from :meth:`_offset_rhs`, adds a per-vertex offset inside the same GEMM
        (the extra rows of the left factor are the unit vectors of x, y, z); ``extents`` (f, 2, 3)
        receives each frame's bounding box, reduced over the contiguous rows of the GEMM result
        (much cheaper than over the interleaved output).
        """
        f, M = eff.shape[:2]
        N = self.n_vertices
        if rhs is None:
            B = self._B32 if out.dtype == np.float32 else self._B64
            rhs = B.T
            lhs = np.ascontiguousarray(eff.transpose(0, 2, 1).reshape(3 * f, M), dtype=out.dtype)
        else:
            lhs = np.zeros((f, 3, M + 3), dtype=out.dtype)
            lhs[:, :, :M] = eff.transpose(0, 2, 1)
            lhs[:, np.arange(3), M + np.arange(3)] = 1.0
            lhs = lhs.reshape(3 * f, M + 3)
        if tmp is None:
            tmp = self._gemm_buffer(f, out.dtype)
        sub = tmp.shape[0] // 3
        for a in range(0, f, sub):
            b = min(f, a + sub)
            t = np.matmul(lhs[3 * a : 3 * b], rhs, out=tmp[: 3 * (b - a)]).reshape(b - a, 3, N)
            if extents is not None:
                t.min(axis=2, out=extents[a:b, 0])
                t.max(axis=2, out=extents[a:b, 1])
            dst = out[a:b]
            for c in range(3):
                dst[:, :, c] = t[:, c, :]

    def _offset_rhs(self, offset, dtype) -> np.ndarray:
        """(M + 3, N) right factor ``[B^T; offset^T]`` of the GEMM that adds ``offset`` (N, 3)."""
        off = _as_float_array("offset", offset)
        if off.shape != (self.n_vertices, 3):
            raise _shape_error("offset", f"(N, 3) = ({self.n_vertices}, 3)", offset)
        if not np.isfinite(off).all():
            raise InputError(f"offset: {int((~np.isfinite(off)).any(axis=1).sum())} point(s) are NaN or infinite")
        B = self._B32 if np.dtype(dtype) == np.float32 else self._B64
        rhs = np.empty((self.n_markers + 3, self.n_vertices), dtype=dtype)
        rhs[: self.n_markers] = B.T
        rhs[self.n_markers :] = off.T
        return rhs

    def iter_chunks(
        self,
        displacements,
        *,
        chunk_frames: int | None = None,
        dtype=np.float32,
        blas_threads: int | None = None,
        reuse_buffer: bool = False,
        offset=None,
        extents: bool = False,
        buffers: int | None = None,
    ) -> Iterator[tuple]:
        """Stream vertex displacements in chunks of frames.

        Validity is scanned and every validity pattern is computed before the first chunk, so bad
        frames raise before any output (at this call, not at the first ``next``). Each chunk is a
        fresh array (unless ``reuse_buffer``): memory stays bounded by about two chunks (the one the
        consumer still holds while the next is computed), a GEMM temporary (<= 32 MiB) and B,
        however long the sequence is.

        Parameters
        ----------
        displacements : array_like, shape (F, M, 3) (or (M, 3)), float
            Marker displacements per frame (mesh units), NaN (or inf) for invalid samples. Not modified.
        chunk_frames : int, optional
            Frames per chunk (>= 1); default: as many as fit in ~64 MiB of output.
        dtype : {numpy.float32, numpy.float64}
            Output type; float64 uses the float64 transfer matrix (for accuracy checks; ~2x slower).
        blas_threads : int, optional
            Limit numpy's BLAS threads during evaluation (threadpoolctl); None leaves them alone.
        reuse_buffer : bool
            Yield views of one buffer, overwritten by the next chunk: saves the page faults of a
            fresh chunk (~10% of the time) and holds one chunk instead of up to two, but the
            consumer must be done with a chunk (e.g. copied it into a Vec3fArray) before asking for
            the next one.
        offset : array_like, shape (N, 3), optional
            Added to every frame inside the same matrix product (e.g. the rest points, so the chunks
            are vertex positions): no extra pass over the output.
        extents : bool
            Also yield each frame's bounding box (min and max over the vertices of the yielded
            points), reduced from the matrix product's contiguous rows.
        buffers : int, optional
            Cycle through this many output buffers instead of a fresh array per chunk (no page
            faults after the first round): a chunk stays valid until ``buffers - 1`` more chunks
            have been produced (3 for a consumer one chunk behind a producer one chunk ahead, as
            :func:`usdface.usd.analysis_layer.write_animation_layer`'s prefetch). ``reuse_buffer``
            is ``buffers=1``.

        Yields
        ------
        frames : slice
            The frames of this chunk (indices into ``displacements``).
        points : ndarray, shape (f, N, 3), ``dtype``
            Vertex displacements (mesh units; plus ``offset`` when given), C-contiguous (each
            ``points[k]`` is ready for a Vec3fArray).
        boxes : ndarray, shape (f, 2, 3), ``dtype``
            With ``extents=True`` only: per frame, the min and max of ``points`` over the vertices.

        Raises
        ------
        InputError
            Wrong displacement shape.
        ComputeError
            Frames with no valid marker (``all_invalid="error"``), or a validity pattern whose
            reduced system is singular; raised before the first chunk.
        """
        disp, scan, chunk_frames, dtype = self._prepare(displacements, chunk_frames, dtype, blas_threads)
        rhs = None if offset is None else self._offset_rhs(offset, dtype)
        if buffers is not None and (isinstance(buffers, bool) or not isinstance(buffers, (int, np.integer))
                                    or buffers < 1):
            raise OptionError(f"buffers: expected an integer >= 1 or None; got {buffers!r}")
        n_buffers = 1 if reuse_buffer else (int(buffers) if buffers is not None else 0)
        return self._generate(disp, scan, chunk_frames, dtype, blas_threads, n_buffers=n_buffers,
                              rhs=rhs, extents=bool(extents))

    def _prepare(self, displacements, chunk_frames, dtype, blas_threads):
        """Check the arguments, fit if needed and scan validity (raising before any output)."""
        disp, _ = self._check_displacements(displacements)
        dtype = np.dtype(dtype)
        if dtype not in (np.float32, np.float64):
            raise OptionError(f"dtype: expected float32 or float64; got {dtype}")
        if chunk_frames is None:
            chunk_frames = max(1, _CHUNK_BYTES // (self.n_vertices * 3 * dtype.itemsize))
        else:
            chunk_frames = check_chunk_frames(chunk_frames)
        if blas_threads is not None and (
            isinstance(blas_threads, bool) or not isinstance(blas_threads, (int, np.integer)) or blas_threads < 1
        ):
            raise OptionError(f"blas_threads: expected an integer >= 1 or None; got {blas_threads!r}")
        self._ensure_fitted()
        return disp, self._scan(disp), chunk_frames, dtype

    def _generate(self, disp, scan, chunk_frames, dtype, blas_threads, out=None, n_buffers=0,
                  rhs=None, extents=False):
        valid, pid, keys = scan
        F = disp.shape[0]
        if F == 0:
            return
        tmp = self._gemm_buffer(min(F, chunk_frames), dtype)
        ring = []
        if n_buffers and out is None:
            ring = [np.empty((min(F, chunk_frames), self.n_vertices, 3), dtype=dtype)
                    for _ in range(min(n_buffers, -(-F // chunk_frames)))]
        limiter = None
        if blas_threads is not None:
            from threadpoolctl import ThreadpoolController

            limiter = ThreadpoolController()
        held = None
        for i, a in enumerate(range(0, F, chunk_frames)):
            b = min(F, a + chunk_frames)
            eff = self._effective(disp[a:b], valid[a:b], pid[a:b], keys, held)
            held = eff[-1].copy()
            if out is not None:
                chunk = out[a:b]
            elif ring:
                chunk = ring[i % len(ring)][: b - a]
            else:
                chunk = np.empty((b - a, self.n_vertices, 3), dtype=dtype)
            boxes = np.empty((b - a, 2, 3), dtype=dtype) if extents else None
            if limiter is None:
                self._evaluate(eff, chunk, tmp, rhs=rhs, extents=boxes)
            else:
                with limiter.limit(limits=int(blas_threads), user_api="blas"):
                    self._evaluate(eff, chunk, tmp, rhs=rhs, extents=boxes)
            yield (slice(a, b), chunk, boxes) if extents else (slice(a, b), chunk)

    def apply(self, displacements, *, dtype=np.float32, chunk_frames: int | None = None,
              blas_threads: int | None = None) -> np.ndarray:
        """Vertex displacements for every frame at once.

        Parameters
        ----------
        displacements : array_like, shape (F, M, 3) or (M, 3), float
            Marker displacements (mesh units), NaN for invalid samples. Not modified.
        dtype : {numpy.float32, numpy.float64}
            Output type (float64: the accuracy path).
        chunk_frames, blas_threads
            As for :meth:`iter_chunks`.

        Returns
        -------
        ndarray, shape (F, N, 3) (or (N, 3) for one frame), ``dtype``
            Vertex displacements (mesh units). For long sequences on big meshes prefer
            :meth:`iter_chunks` (F x N x 12 bytes in float32).
        """
        single = np.ndim(displacements) == 2
        disp, scan, chunk_frames, dtype = self._prepare(displacements, chunk_frames, dtype, blas_threads)
        out = np.empty((disp.shape[0], self.n_vertices, 3), dtype=dtype)
        for _ in self._generate(disp, scan, chunk_frames, dtype, blas_threads, out=out):
            pass  # each chunk is evaluated in place into its frame slice of out
        return out[0] if single else out


def transfer_motion(D_vc, D_cc, displacements, *, dtype=np.float32, **options) -> np.ndarray:
    """One call: ``RBFTransfer(D_vc, D_cc, **options).fit().apply(displacements)``.

    Parameters
    ----------
    D_vc : array_like, shape (N, C)
        Vertex-to-centre distances (mesh units).
    D_cc : array_like, shape (C, C)
        Centre-to-centre distances (mesh units).
    displacements : array_like, shape (F, M, 3)
        Marker displacements (mesh units), NaN for invalid samples.
    dtype : {numpy.float32, numpy.float64}
        Output type.
    **options
        Keyword options of :class:`RBFTransfer`.

    Returns
    -------
    ndarray, shape (F, N, 3), ``dtype``
        Vertex displacements (mesh units).
    """
    return RBFTransfer(D_vc, D_cc, **options).fit().apply(displacements, dtype=dtype)
