"""Whole-take blend-shape weight solve: marker displacements -> weight curves in [0, 1].

The problem
-----------
For a take of F frames, M markers and K shapes, with ``b_mk`` the displacement of marker m's
bound point under shape k at weight 1 (:func:`usdface.blendshape.rig.marker_basis`), ``d_fm`` the
stabilised marker displacement at frame f and ``v_fm`` its validity, the weights W (F x K) minimise

    E(W) = 1/2 sum_f sum_m v_fm |sum_k w_fk b_mk - d_fm|^2                    (data, cm^2)
         + beta sum_f sum_k w_fk                                              (sparsity: L1 on w >= 0)
         + gamma/2 sum_f sum_(L,R) (n_L w_fL - n_R w_fR)^2                     (left/right prior)
         + lambda/2 sum_k n_k^2 |L w_k|^2                                       (temporal smoothness)

subject to ``0 <= w_fk <= 1``; ``n_k = |b_k|`` is how much shape k moves the markers (Frobenius
norm over markers; the prior is relative to the data's own curvature n_k^2, so gamma is
dimensionless and acts alike on strong and weak pairs), L the F x F Neumann Laplacian (second differences inside the take, first
differences at its ends), and ``lambda = (rate / (2 pi f_c))^4``: a shape fitted on its own is
low-passed at the cut-off ``f_c`` (``smoothing_hz``) whatever the capture rate, and the penalty
is on the acceleration of the *marker motion* each shape makes (n_k^2), so all terms are in cm^2.
Invalid samples simply have no data term: their frames are held by their valid markers and by
the smoothness (a frame with no valid marker is interpolated from its neighbours).

How it is solved
----------------
Scaled variables ``v_k = n_k w_k`` give the data term unit columns and turn the smoothness into
``lambda/2 |L v_k|^2`` for every shape, so the Hessian of the full-marker problem is the Kronecker
sum ``I_F (x) G + lambda L^2 (x) I_K`` with ``G = A^T A + gamma sum c c^T`` (K x K). It is
diagonalised by G's eigenvectors Q along shapes and by the orthonormal DCT-II along time (the
eigenvectors of the Neumann Laplacian, eigenvalues ``mu_j = 2 - 2 cos(pi j / F)``). ADMM (Boyd et
al. 2011, scaled form with over-relaxation) splits the box constraint off:

    W-update:  (G + rho I) W + lambda L^2 W = B + rho (Z - U) + E(W_prev)     (exact, O(F K^2 + F K log F))
    Z-update:  Z = clip(relax W + (1 - relax) Z + U, 0, n)                       (the box in scaled units)
    U-update:  U += relax W + (1 - relax) Z_old - Z

Missing samples break the Kronecker structure; they enter as the semi-proximal term
``E_f = sum_(m missing at f) A_m^T A_m`` (PSD): the W-update keeps the full-marker matrix and adds
``E_f w_prev`` to its right-hand side, which is ADMM with a positive semi-definite proximal term
and converges to the same minimiser (Fazel, Pong, Sun & Tseng 2013). rho adapts by residual
balancing (free here: it only shifts the diagonal). The returned weights are the projected
iterate Z / n, so the bounds hold exactly.

Refit (default on): the L1 term picks which shapes are active but also shrinks the active ones
toward 0 and lets small noise-driven weights through. As in the relaxed lasso (Meinshausen 2007),
a second pass minimises E with ``beta = 0`` and ``gamma = 0`` over the *support* found by the
first: the entries with ``w > support_threshold``, widened by ``support_dilation_s`` on either
side so ramps keep their feet; every other entry is held at 0 (a per-entry upper bound in the same
box projection). The sparsity and the left/right prior thus decide which shapes act together, and
the data alone decides how much. Warm started from the first pass. On the synthetic takes of
``benchmarks/blendshape_synthetic.py`` (0.5 mm noise, 5% missing) it cuts the mesh error from
about 6% to about 3.5%.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, OptionError, list_names
from . import _kernels as kn
from .parameters import (DEFAULT_MAX_ITERATIONS, DEFAULT_SMOOTHING_HZ, DEFAULT_SPARSITY,  # noqa: F401 (re-exported)
                         DEFAULT_SUPPORT_DILATION_S, DEFAULT_SUPPORT_THRESHOLD, DEFAULT_SYMMETRY, DEFAULT_TOLERANCE,
                         SolverParameters)

__all__ = ["CurveSolver", "CurveSolution", "SolverParameters", "solve_curves", "solve_reference", "objective",
           "neumann_laplacian", "DEFAULT_SMOOTHING_HZ", "DEFAULT_SPARSITY", "DEFAULT_SYMMETRY", "DEFAULT_TOLERANCE"]

#: with a refit, the sparse pass stops at this multiple of the tolerance (it only picks the support)
SUPPORT_TOLERANCE_FACTOR = 4.0
#: a shape moving no marker by more than this fraction of the largest shape's motion is unobservable
UNOBSERVABLE_FRACTION = 1e-6
#: a marker moved by no shape more than this fraction of the largest marker motion is "unmoved"
UNMOVED_FRACTION = 1e-3


@dataclass
class CurveSolution:
    """Solved weight curves and how well they fit.

    Attributes
    ----------
    weights : ndarray, shape (F, K), float64
        In [0, 1] exactly.
    names : tuple of str
        Shape names (the rig's order).
    residual : ndarray, shape (F,), float64
        Per-frame marker residual: RMS over the frame's valid markers of ``|fit - d|`` (mesh
        units); NaN for a frame without valid markers.
    still_residual : ndarray, shape (F,)
        The same for all-zero weights (a still face): RMS of ``|d|`` over the valid markers.
    marker_rms : ndarray, shape (M,)
        Per-marker residual RMS over its valid frames.
    iterations : int
    converged : bool
    primal, dual : float
        Final RMS ADMM residuals (scaled units).
    rho : float
        Final penalty parameter.
    seconds : float
        Solve time (set-up included).
    """

    weights: np.ndarray
    names: tuple
    residual: np.ndarray
    still_residual: np.ndarray
    marker_rms: np.ndarray
    iterations: int
    converged: bool
    primal: float
    dual: float
    rho: float
    seconds: float
    info: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return self.weights.shape[0]

    def summary(self) -> dict:
        fin = np.isfinite(self.residual)
        return {
            "frames": int(self.n_frames), "shapes": len(self.names), "iterations": int(self.iterations),
            "converged": bool(self.converged), "seconds": round(float(self.seconds), 4),
            "residualMean": float(np.mean(self.residual[fin])) if fin.any() else None,
            "residualMax": float(np.max(self.residual[fin])) if fin.any() else None,
            "stillResidualMean": float(np.mean(self.still_residual[fin])) if fin.any() else None,
            "activePerFrameMean": float((self.weights > 0.01).sum(axis=1).mean()),
            **self.info,
        }


def neumann_laplacian(n: int) -> np.ndarray:
    """(n, n) dense Neumann Laplacian ``D^T D`` of the first difference D (for tests and references)."""
    lap = np.zeros((n, n))
    if n > 1:
        i = np.arange(n - 1)
        lap[i, i] += 1.0
        lap[i + 1, i + 1] += 1.0
        lap[i, i + 1] -= 1.0
        lap[i + 1, i] -= 1.0
    return lap


def smoothing_weight(rate: float, smoothing_hz: float | None) -> float:
    """lambda = (rate / (2 pi f_c))^4 (0 when smoothing is off)."""
    if smoothing_hz is None or smoothing_hz == 0:
        return 0.0
    return (rate / (2.0 * math.pi * smoothing_hz)) ** 4


class CurveSolver:
    """Set up once per rig and binding (the marker basis), solve whole takes.

    Parameters
    ----------
    basis : array_like, shape (M, K, 3)
        Marker displacement per shape at weight 1 (cm; :func:`usdface.blendshape.rig.marker_basis`).
    names : sequence of str, length K, optional
    marker_names : sequence of str, length M, optional
    symmetric_pairs : sequence of (str, str) or (int, int)
        Shapes coupled by the left/right prior (:func:`usdface.blendshape.mirror.find_mirror_pairs`).
    exclude : sequence of str
        Shapes held at weight 0 (e.g. gaze and tongue shapes, which skin markers do not see).
    params : SolverParameters
        Smoothing, sparsity, symmetry, refit and the ADMM settings
        (:class:`usdface.blendshape.parameters.SolverParameters`).

    Examples
    --------
    >>> solver = CurveSolver(marker_basis(rig, binding), names=rig.names)   # doctest: +SKIP
    >>> sol = solver.solve(displacements, rate=60.0)                          # doctest: +SKIP
    """

    def __init__(self, basis, *, names=None, marker_names=None, symmetric_pairs=(), exclude=(),
                 params: SolverParameters = SolverParameters()) -> None:
        smoothing_hz, sparsity, symmetry = params.smoothing_hz, params.sparsity, params.symmetry
        rho, relaxation = params.rho, params.relaxation
        b = np.asarray(basis, dtype=np.float64)
        if b.ndim != 3 or b.shape[2] != 3 or b.shape[0] == 0 or b.shape[1] == 0:
            raise InputError(f"marker basis must have shape (M>0, K>0, 3); got {b.shape}")
        if not np.isfinite(b).all():
            raise InputError("marker basis has NaN or infinite values")
        m_n, k_n, _ = b.shape
        self.names = tuple(str(n) for n in names) if names is not None else tuple(f"shape{k}" for k in range(k_n))
        if len(self.names) != k_n:
            raise InputError(f"{len(self.names)} shape names for a basis of {k_n} shapes")
        self.marker_names = (tuple(str(n) for n in marker_names) if marker_names is not None
                             else tuple(f"marker{m}" for m in range(m_n)))
        if len(self.marker_names) != m_n:
            raise InputError(f"{len(self.marker_names)} marker names for a basis of {m_n} markers")
        for label, value, lo in (("smoothing", smoothing_hz or 0.0, 0.0), ("sparsity", sparsity, 0.0),
                                 ("symmetry", symmetry, 0.0)):
            if not (np.isfinite(value) and value >= lo):
                raise OptionError(f"--{label} {value}: expected a number >= 0")
        if not 1.0 <= relaxation < 2.0:
            raise OptionError(f"ADMM relaxation {relaxation}: expected 1 <= relaxation < 2")
        if not rho > 0:
            raise OptionError(f"ADMM rho {rho}: expected > 0")
        self.basis = b
        self.smoothing_hz = smoothing_hz if smoothing_hz else None
        self.sparsity = float(sparsity)
        self.symmetry = float(symmetry)
        self.rho0 = float(rho)
        self.refit = bool(params.refit)
        self.support_threshold = float(params.support_threshold)
        self.support_dilation_s = float(params.support_dilation_s)
        self.relaxation = float(relaxation)
        self.params = params
        norms = np.sqrt((b ** 2).sum(axis=(0, 2)))
        top = float(norms.max())
        self.norms = norms
        self.observed = norms > UNOBSERVABLE_FRACTION * top if top > 0 else np.zeros(k_n, dtype=bool)
        self.unobservable = [self.names[k] for k in np.flatnonzero(~self.observed)]
        self.excluded = [self.names[self._index(n)] for n in exclude]
        for n in self.excluded:
            self.observed[self.names.index(n)] = False
        reach = np.linalg.norm(b, axis=2).max(axis=1)  # (M,) largest motion of each marker
        self.unmoved_markers = [self.marker_names[m] for m in np.flatnonzero(reach <= UNMOVED_FRACTION * reach.max())] \
            if reach.max() > 0 else list(self.marker_names)
        obs = np.flatnonzero(self.observed)
        self._obs = obs
        n = norms[obs]
        scaled = b[:, obs, :] / n[None, :, None]  # (M, K', 3), unit columns
        self._basis32 = np.ascontiguousarray(scaled.transpose(0, 2, 1), dtype=np.float32)  # (M, 3, K')
        a = scaled.transpose(0, 2, 1).reshape(3 * m_n, obs.size)  # (3M, K'), rows m*3 + c
        self._a = a
        g_data = a.T @ a
        g = g_data.copy()
        pairs = []
        col = {int(k): i for i, k in enumerate(obs)}
        for left, right in symmetric_pairs:
            il = self._index(left)
            ir = self._index(right)
            if il in col and ir in col:
                c = np.zeros(obs.size)
                c[col[il]] += 1.0
                c[col[ir]] -= 1.0
                g += self.symmetry * np.outer(c, c)
                pairs.append((self.names[il], self.names[ir]))
        self.pairs = pairs
        # eigenbases of the sparse pass (with the prior) and of the refit (data only)
        self._eig = {"sparse": _eigenbasis(g), "refit": _eigenbasis(g_data)}
        self._n = n

    def _index(self, name_or_index) -> int:
        if isinstance(name_or_index, (int, np.integer)):
            return int(name_or_index)
        try:
            return self.names.index(name_or_index)
        except ValueError:
            raise InputError(f"symmetric pair: shape {name_or_index!r} not in {list_names(self.names)}") from None

    @property
    def n_shapes(self) -> int:
        return len(self.names)

    @property
    def n_markers(self) -> int:
        return len(self.marker_names)

    # -- the solve -------------------------------------------------------------------------------
    def solve(self, displacements, *, rate: float, valid=None, max_iterations: int | None = None,
              tolerance: float | None = None, backend: str = "auto", support=None) -> CurveSolution:
        """Solve a whole take.

        Parameters
        ----------
        displacements : array_like, shape (F, M, 3)
            Marker displacements from the neutral (cm, mesh space, stabilised); NaN where invalid.
        rate : float
            Frames per second (sets the smoothness weight).
        valid : array_like (F, M) bool, optional
            Default: where ``displacements`` is finite. Samples marked invalid are ignored.
        max_iterations : int, optional
        tolerance : float, optional
            Stop when the RMS primal and dual residuals fall below it (scaled units, cm).
            Default (None): the solver's parameters.
        backend : {"auto", "numba", "numpy"}
        support : array_like (F, K) bool, optional
            Skip the sparse pass and solve only the refit over this support (for tests and for
            re-solving a take with a support edited by hand).

        Returns
        -------
        CurveSolution
        """
        from threadpoolctl import threadpool_limits

        t0 = time.perf_counter()
        max_iterations = self.params.max_iterations if max_iterations is None else max_iterations
        tolerance = self.params.tolerance if tolerance is None else tolerance
        d = np.asarray(displacements, dtype=np.float64)
        if d.ndim != 3 or d.shape[1:] != (self.n_markers, 3):
            raise InputError(f"displacements must have shape (F, M={self.n_markers}, 3); got {d.shape}")
        if d.shape[0] == 0:
            raise InputError("displacements: zero frames")
        if not (np.isfinite(rate) and rate > 0):
            raise OptionError(f"rate {rate}: expected a positive number of frames per second")
        ok = np.isfinite(d).all(axis=2)
        if valid is not None:
            v = np.asarray(valid, dtype=bool)
            if v.shape != ok.shape:
                raise InputError(f"valid must have shape {ok.shape}; got {v.shape}")
            ok = ok & v
        if backend not in ("auto", "numba", "numpy"):
            raise OptionError(f"backend {backend!r}: expected auto, numba or numpy")
        if backend == "numba" and not kn.AVAILABLE:
            raise OptionError("backend 'numba' needs numba (pip install numba)")
        use_numba = kn.AVAILABLE and backend != "numpy"
        with threadpool_limits(limits=1, user_api="blas"):  # K x K products: threads only add overhead
            problem = self._problem(d, ok, rate=float(rate))
            hi = np.broadcast_to(self._n.astype(np.float32)[None, :], problem["b"].shape).copy()
            if support is None:
                # the sparse pass only has to find the support when a refit follows
                loose = SUPPORT_TOLERANCE_FACTOR * tolerance if self.refit else tolerance
                z, info = self._admm(problem, hi, sparsity=self.sparsity, start=None,
                                     max_iterations=int(max_iterations), tolerance=float(loose),
                                     use_numba=use_numba)
            else:
                sup = np.asarray(support, dtype=bool)
                if sup.shape != (d.shape[0], self.n_shapes):
                    raise InputError(f"support must have shape {(d.shape[0], self.n_shapes)}; got {sup.shape}")
                z = np.zeros_like(hi)
                info = {"iterations": 0, "converged": True}
            info["supportSize"] = None
            if (self.refit or support is not None) and self._obs.size:
                if support is None:
                    w1 = z / self._n.astype(np.float32)[None, :]
                    support = _dilate(w1 > self.support_threshold, int(round(self.support_dilation_s * rate)))
                else:
                    support = sup[:, self._obs]
                hi = np.where(support, hi, np.float32(0.0))
                z, info2 = self._admm(problem, hi, sparsity=0.0, start=z, max_iterations=int(max_iterations),
                                      tolerance=float(tolerance), use_numba=use_numba, basis="refit")
                info = {"iterations": info["iterations"] + info2["iterations"],
                        "converged": info["converged"] and info2["converged"], "primal": info2["primal"],
                        "dual": info2["dual"], "rho": info2["rho"],
                        "passIterations": [info["iterations"], info2["iterations"]],
                        "supportSize": float(support.sum(axis=1).mean())}
        f_n = d.shape[0]
        weights = np.zeros((f_n, self.n_shapes))
        if self._obs.size:
            weights[:, self._obs] = z / self._n.astype(np.float32)[None, :]
        np.clip(weights, 0.0, 1.0, out=weights)  # already exact; a guard against float32 rounding
        residual, still, marker_rms = self.residuals(weights, d, ok)
        info["seconds"] = time.perf_counter() - t0
        extra = {"smoothingHz": self.smoothing_hz, "sparsity": self.sparsity, "symmetry": self.symmetry,
                 "symmetricPairs": [f"{a}/{b}" for a, b in self.pairs], "unobservableShapes": list(self.unobservable),
                 "excludedShapes": list(self.excluded), "refit": self.refit,
                 "meanSupportPerFrame": info.get("supportSize"), "passIterations": info.get("passIterations"),
                 "invalidSamples": int((~ok).sum()), "backend": "numba" if use_numba else "numpy"}
        return CurveSolution(weights, self.names, residual, still, marker_rms, info["iterations"], info["converged"],
                             info["primal"], info["dual"], info["rho"], info["seconds"], extra)

    def residuals(self, weights, displacements, valid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(per-frame RMS residual, per-frame still-face RMS, per-marker RMS) over valid samples."""
        d = np.where(valid[:, :, None], displacements, 0.0)
        m_n = self.n_markers
        fit = (weights @ self.basis.transpose(1, 0, 2).reshape(self.n_shapes, 3 * m_n)).reshape(-1, m_n, 3)
        fit -= d
        r2 = np.einsum("fmd,fmd->fm", fit, fit) * valid
        s2 = np.einsum("fmd,fmd->fm", d, d)
        cnt = valid.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            per_frame = np.sqrt(r2.sum(axis=1) / cnt)
            still = np.sqrt(s2.sum(axis=1) / cnt)
            per_marker = np.sqrt(r2.sum(axis=0) / valid.sum(axis=0))
        return per_frame, still, per_marker

    def _problem(self, d, ok, *, rate) -> dict:
        """What both passes share: data term, spectrum, missing samples."""
        f_n = d.shape[0]
        m_n = self.n_markers
        # layout (F, K'): frames are rows, so a frame's shapes are contiguous (the missing-sample
        # term reads whole rows) and the DCT runs along axis 0
        data = np.where(ok[:, :, None], d, 0.0).reshape(f_n, 3 * m_n)
        b = (data @ self._a).astype(np.float32)
        lam_s = smoothing_weight(rate, self.smoothing_hz)
        mu = 2.0 - 2.0 * np.cos(np.pi * np.arange(f_n) / f_n)
        frames, markers = np.nonzero(~ok)
        return {"b": b, "spectrum": (lam_s * mu ** 2)[:, None], "frames": frames.astype(np.int64),
                "markers": markers.astype(np.int64)}

    def _admm(self, problem, hi, *, sparsity, start, max_iterations, tolerance, use_numba, basis="sparse"):
        """Scaled ADMM for one pass; ``hi`` (F, K') float32 per-entry upper bounds (scaled units)."""
        import scipy.fft as sfft

        b0 = problem["b"]
        f_n, k_n = b0.shape
        if k_n == 0:
            return np.zeros((f_n, 0), dtype=np.float32), {"iterations": 0, "converged": True, "primal": 0.0,
                                                           "dual": 0.0, "rho": self.rho0}
        b = b0 - (sparsity / self._n).astype(np.float32)[None, :] if sparsity else b0
        spectrum = problem["spectrum"]
        frames, markers = problem["frames"], problem["markers"]
        lam, q32, qt32 = self._eig[basis]
        lam = lam[None, :]
        update = kn.admm_box_update if use_numba else kn.admm_box_update_numpy
        missing = kn.add_missing_term if use_numba else kn.add_missing_term_numpy

        def inverse_diagonal(rho):
            return (1.0 / (lam + rho + spectrum)).astype(np.float32)

        def w_solve(r, inv):
            y = sfft.dct(r @ q32, type=2, norm="ortho", axis=0, overwrite_x=True, workers=1)
            y *= inv
            return sfft.idct(y, type=2, norm="ortho", axis=0, overwrite_x=True, workers=1) @ qt32

        rho = self.rho0
        inv = inverse_diagonal(rho)
        if start is None:
            w = w_solve(b.copy(), inv)
        else:
            w = np.array(start, dtype=np.float32)
        z = np.minimum(np.maximum(w, np.float32(0.0)), hi)
        u = np.zeros_like(z)
        r = b + np.float32(rho) * z
        scale = 1.0 / math.sqrt(k_n * f_n)
        primal = dual = np.inf
        converged = False
        it = 0
        relax = np.float32(self.relaxation)
        for it in range(1, max_iterations + 1):
            if frames.size:
                missing(r, w, frames, markers, self._basis32)
            w = w_solve(r, inv)
            p2, d2 = update(w, z, u, r, b, hi, np.float32(rho), relax)
            primal = math.sqrt(p2) * scale
            dual = rho * math.sqrt(d2) * scale
            if primal < tolerance and dual < tolerance:
                converged = True
                break
            if it % 10 == 0:  # residual balancing (Boyd et al. 2011, 3.4.1): only the diagonal shifts
                factor = 2.0 if primal > 10.0 * dual else (0.5 if dual > 10.0 * primal else 1.0)
                if factor != 1.0:
                    rho *= factor
                    u /= np.float32(factor)
                    inv = inverse_diagonal(rho)
                    r = b + np.float32(rho) * (z - u)
        return z, {"iterations": it, "converged": converged, "primal": primal, "dual": dual, "rho": rho}


def _eigenbasis(g: np.ndarray):
    """(eigenvalues >= 0, Q float32, Q^T float32) of a symmetric PSD matrix."""
    lam, q = np.linalg.eigh(g)
    return (np.maximum(lam, 0.0), np.ascontiguousarray(q, dtype=np.float32),
            np.ascontiguousarray(q.T, dtype=np.float32))


def _dilate(mask: np.ndarray, frames: int) -> np.ndarray:
    """(F, K) bool mask widened by ``frames`` along axis 0."""
    if frames <= 0:
        return mask
    from scipy.ndimage import maximum_filter1d

    return maximum_filter1d(mask.astype(np.uint8), size=2 * frames + 1, axis=0, mode="constant") > 0


def objective(weights, basis, displacements, valid=None, *, rate: float, smoothing_hz=DEFAULT_SMOOTHING_HZ,
              sparsity=DEFAULT_SPARSITY, symmetry=DEFAULT_SYMMETRY, pair_indices=()) -> float:
    """E(W) of the module docstring, evaluated directly (for tests and comparisons)."""
    w = np.asarray(weights, dtype=np.float64)
    b = np.asarray(basis, dtype=np.float64)
    d = np.asarray(displacements, dtype=np.float64)
    ok = np.isfinite(d).all(axis=2) if valid is None else np.asarray(valid, bool) & np.isfinite(d).all(axis=2)
    fit = np.einsum("fk,mkd->fmd", w, b)
    e = 0.5 * np.where(ok, ((fit - np.nan_to_num(d)) ** 2).sum(axis=2), 0.0).sum()
    e += sparsity * w.sum()
    n2 = (b ** 2).sum(axis=(0, 2))
    nk = np.sqrt(n2)
    for il, ir in pair_indices:
        e += 0.5 * symmetry * ((nk[il] * w[:, il] - nk[ir] * w[:, ir]) ** 2).sum()
    lam_s = smoothing_weight(rate, smoothing_hz)
    if lam_s:
        lw = _laplacian_apply(w)
        e += 0.5 * lam_s * (n2[None, :] * lw ** 2).sum()
    return float(e)


def _laplacian_apply(w: np.ndarray) -> np.ndarray:
    """L @ w along axis 0 (Neumann Laplacian), for (F, K) arrays."""
    out = np.zeros_like(w)
    if w.shape[0] > 1:
        diff = np.diff(w, axis=0)  # w[i+1] - w[i]
        out[:-1] -= diff
        out[1:] += diff
    return out


def solve_reference(basis, displacements, *, rate: float, valid=None, smoothing_hz=DEFAULT_SMOOTHING_HZ,
                    sparsity=DEFAULT_SPARSITY, symmetry=DEFAULT_SYMMETRY, pair_indices=(), upper=None,
                    method: str = "trf") -> np.ndarray:
    """The minimiser of E as one dense bounded least-squares problem (a slow test reference).

    Every term of E is a sum of squares of linear functions of the F x K weights (data rows of
    the valid samples, ``sqrt(lambda) n_k L`` rows, ``sqrt(gamma) (n_L e_L - n_R e_R)`` rows);
    the linear sparsity term is folded in by completing the square with the normal matrix.
    Solved by scipy's bounded least squares (``lsq_linear``, trust-region reflective by default),
    ``0 <= w <= upper`` (default 1; 0 holds an entry at 0). One pass: no refit. Shapes that move
    no marker are held at 0 (their only term is the sparsity, minimal at 0).

    Returns
    -------
    ndarray, shape (F, K)
    """
    from scipy.optimize import lsq_linear

    b = np.asarray(basis, dtype=np.float64)
    d = np.asarray(displacements, dtype=np.float64)
    ok = np.isfinite(d).all(axis=2) if valid is None else np.asarray(valid, bool) & np.isfinite(d).all(axis=2)
    f_n, (m_n, k_n, _) = d.shape[0], b.shape
    nk = np.sqrt((b ** 2).sum(axis=(0, 2)))
    live = np.flatnonzero(nk > 0)
    kk = live.size
    col = {int(k): i for i, k in enumerate(live)}
    a = b[:, live, :].transpose(0, 2, 1).reshape(3 * m_n, kk)  # (3M, K')
    rows, rhs = [], []
    for f in range(f_n):  # data rows of frame f
        sel = np.repeat(ok[f], 3)
        blk = np.zeros((int(sel.sum()), f_n * kk))
        blk[:, f * kk:(f + 1) * kk] = a[sel]
        rows.append(blk)
        rhs.append(d[f].reshape(-1)[sel])
    lam_s = smoothing_weight(rate, smoothing_hz)
    if lam_s and f_n > 1:
        lap = neumann_laplacian(f_n)
        rows.append(np.sqrt(lam_s) * np.kron(lap, np.diag(nk[live])))
        rhs.append(np.zeros(f_n * kk))
    for il, ir in pair_indices:
        if il in col and ir in col and symmetry:
            c = np.zeros(kk)
            c[col[il]] = nk[il]
            c[col[ir]] = -nk[ir]
            rows.append(np.sqrt(symmetry) * np.kron(np.eye(f_n), c[None, :]))
            rhs.append(np.zeros(f_n))
    top = (np.ones((f_n, k_n)) if upper is None else np.asarray(upper, dtype=np.float64))[:, live].ravel()
    free = top > 0  # entries held at 0 leave the problem
    mat = np.vstack(rows)[:, free]
    y = np.concatenate(rhs)
    if sparsity:
        # 1/2 |M w - y|^2 + beta 1.w = 1/2 |M w - (y - M (M^T M)^-1 beta 1)|^2 + const
        y = y - mat @ np.linalg.solve(mat.T @ mat, np.full(int(free.sum()), float(sparsity)))
    res = lsq_linear(mat, y, bounds=(np.zeros(int(free.sum())), top[free]), method=method, tol=1e-13,
                     lsq_solver="exact", max_iter=5000)
    x = np.zeros(f_n * kk)
    x[free] = res.x
    out = np.zeros((f_n, k_n))
    out[:, live] = x.reshape(f_n, kk)
    return out


def solve_curves(basis, displacements, *, rate: float, names=None, marker_names=None, symmetric_pairs=(),
                 valid=None, exclude=(), params: SolverParameters = SolverParameters(),
                 backend: str = "auto") -> CurveSolution:
    """One call: :class:`CurveSolver` built and solved."""
    return CurveSolver(basis, names=names, marker_names=marker_names, symmetric_pairs=symmetric_pairs,
                       exclude=exclude, params=params).solve(displacements, rate=rate, valid=valid, backend=backend)
