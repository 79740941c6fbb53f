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
The options are two frozen dataclasses (:mod:`usdface.rbf.parameters`): :class:`RBFSettings`
(mode, kernel, widths, polynomial term, regularisation, all-invalid policy) and :class:`RBFCentres`
(how many centres are markers, their names and points, the collocation triangles).

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

Where the parts live
--------------------
:mod:`usdface.rbf.parameters` (the options), :mod:`usdface.rbf.system` (the checked problem and
its system matrix), :mod:`usdface.rbf.solver` (the fit, condition number and advice),
:mod:`usdface.rbf.patterns` (validity patterns) and :mod:`usdface.rbf.streaming` (the chunked GEMM);
this module puts them behind :class:`RBFTransfer`.
"""
from __future__ import annotations

import warnings
from collections.abc import Iterator

import numpy as np

from ..errors import ComputeError, OptionError
from .parameters import ALL_INVALID_POLICIES, MODES, RBFCentres, RBFSettings, as_float_array, shape_error
from .patterns import PatternCache
from .solver import (ADVICE_CONDITION, COINCIDENT_RTOL, SINGULAR_CONDITION, FittedTransfer, conditioning_advice,
                     fit_system, nearly_coincident)
from .streaming import ChunkPlan, check_chunk_frames, generate_chunks, offset_rhs, plan_chunks
from .system import RBFSystem

__all__ = ["RBFTransfer", "transfer_motion", "RBFSettings", "RBFCentres", "ADVICE_CONDITION", "MODES",
           "ALL_INVALID_POLICIES", "SINGULAR_CONDITION", "COINCIDENT_RTOL", "check_chunk_frames"]


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
    settings : RBFSettings
        Mode, kernel, widths, polynomial term, regularisation, width factor, all-invalid policy
        (checked when the settings are made).
    centres : RBFCentres
        Number of markers, marker names, centre and vertex points (polynomial term), collocation;
        checked here against the distances.

    Attributes
    ----------
    settings : RBFSettings
    centres : RBFCentres
    mode, kernel, all_invalid : str
        From ``settings`` (``kernel`` canonical).
    regularization : float
    polynomial : bool
    n_vertices, n_centres, n_markers : int
        N, C, M.
    marker_names : tuple of str or None
    widths : ndarray, shape (C,), float64, read-only
        Kernel width per centre (mesh units).

    Raises
    ------
    InputError
        Wrong shapes, NaN or negative distances, NaN/inf centre or vertex points.
    OptionError
        Bad widths, n_markers or marker names, or options that do not apply to the mode (bad
        mode, kernel, regularization or all_invalid are refused by :class:`RBFSettings`).
    ComputeError
        Infinite distances with a kernel that does not decay to zero.

    Examples
    --------
    >>> rbf = RBFTransfer(D_vc, D_cc, centres=RBFCentres(n_markers=41)).fit()   # doctest: +SKIP
    >>> for frames, points in rbf.iter_chunks(displacements):                 # doctest: +SKIP
    ...     write(frames, rest_points + points)
    """

    def __init__(self, D_vc, D_cc, *, settings: RBFSettings = RBFSettings(),
                 centres: RBFCentres = RBFCentres()) -> None:
        if not isinstance(settings, RBFSettings):
            raise OptionError(f"settings: expected RBFSettings; got {type(settings).__name__}")
        if not isinstance(centres, RBFCentres):
            raise OptionError(f"centres: expected RBFCentres; got {type(centres).__name__}")
        self._system = RBFSystem(D_vc, D_cc, settings, centres)
        self.settings, self.centres = settings, centres
        self.mode, self.kernel, self.all_invalid = settings.mode, settings.kernel, settings.all_invalid
        self.regularization, self.polynomial = settings.regularization, settings.polynomial
        system = self._system
        self.n_vertices, self.n_centres, self.n_markers = system.n_vertices, system.n_centres, system.n_markers
        self.marker_names = system.marker_names
        self.widths = system.widths
        self._fitted: FittedTransfer | None = None
        self._patterns: PatternCache | None = None
        self._refused_condition: float | None = None  # measured by a fit that refused the system

    # ------------------------------------------------------------------ set-up
    def fit(self) -> "RBFTransfer":
        """Factorise the system once and build the transfer matrix B (N x M).

        Interpolate mode: the 2-norm condition number of the (C [+ 4]) system (one SVD), one LU
        solve (partial pivoting) for ``Z = A^-1[:, :M]`` and ``B = [Phi_vc, P_v] @ Z`` (kernel evaluated in
        blocks of vertices). Paper mode: ``B[:, j] = Phi_vc[:, j] / sum_k Phi_cc[j, k]`` (Eqs. 4-5,
        k over the markers). Also caches the all-valid pattern (see :func:`usdface.rbf.solver.fit_system`).

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
        try:
            fitted = fit_system(self._system)
        except ComputeError as err:
            self._refused_condition = getattr(err, "condition", self._refused_condition)
            raise
        self._fitted = fitted
        self._patterns = PatternCache(self._system, fitted)
        if fitted.condition is not None and fitted.condition > ADVICE_CONDITION:
            warnings.warn(conditioning_advice(self._system, fitted.condition), RuntimeWarning, stacklevel=2)
        return self

    def _ensure_fitted(self) -> FittedTransfer:
        if self._fitted is None:
            self.fit()
        return self._fitted

    # ------------------------------------------------------------------ diagnostics
    @property
    def transfer_matrix(self) -> np.ndarray:
        """B, shape (N, M), float64, read-only: marker displacements to vertex displacements.

        For the all-valid pattern, a frame's vertex displacements are ``Dv = B @ D`` with D the
        (M, 3) marker displacements (mesh units), so B can serve as skin weights (one column per
        marker). Interpolate mode: ``B = [Phi_vc, P_v] A^-1`` restricted to the marker columns;
        paper mode: ``B[i, j] = phi_j(d_ij) / sum_k phi_k(d_jk)`` (Eqs. 4-5).
        """
        return self._ensure_fitted().B64

    @property
    def condition_number(self) -> float | None:
        """2-norm condition number of the full (all markers valid) interpolation system.

        Includes the regularisation and the polynomial block; ``inf`` when singular. None in paper
        mode (no system is solved). Computed by :meth:`fit` with one SVD (O(C^3): milliseconds for
        tens or hundreds of centres, seconds for a few thousand).
        """
        if self._fitted is None:
            try:
                self.fit()
            except ComputeError:
                return self._refused_condition
        return self._fitted.condition

    def nearly_coincident(self, rtol: float = COINCIDENT_RTOL) -> list[tuple[str, str, float]]:
        """Pairs of centres closer than ``rtol`` times the smaller of their kernel widths.

        Returns
        -------
        list of (str, str, float)
            (label of centre j, label of centre k, distance in mesh units), closest first; labels are
            marker names (quoted) or ``constraint centre #p``. Distance is ``min(D_cc[j, k], D_cc[k, j])``.
        """
        return nearly_coincident(self._system, rtol)

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
        return conditioning_advice(self._system, cond)

    def cache_info(self) -> dict[str, int]:
        """Validity-pattern cache statistics.

        Every frame looks up its pattern: ``misses`` counts patterns computed (one small operator
        each), ``hits`` frames served by a cached one; ``patterns`` is the cache size. The all-valid
        pattern is computed by :meth:`fit` and counted neither as a miss nor, for all-valid frames,
        as a hit. Frames with no valid marker are not looked up.
        """
        if self._patterns is None:
            return {"hits": 0, "misses": 0, "patterns": 0}
        return self._patterns.info()

    def clear_cache(self) -> None:
        """Forget every validity pattern except the all-valid one; reset the counters."""
        if self._patterns is not None:
            self._patterns.clear()

    # ------------------------------------------------------------------ evaluation
    def _check_displacements(self, displacements) -> np.ndarray:
        d = as_float_array("displacements", displacements)
        if d.ndim == 2:
            d = d[None]
        if d.ndim != 3 or d.shape[1:] != (self.n_markers, 3):
            raise shape_error("displacements", f"(F, M, 3) = (F, {self.n_markers}, 3) (or (M, 3) for one frame)",
                              displacements)
        return d

    def _prepare(self, displacements, chunk_frames, dtype, blas_threads):
        """Check the arguments, fit if needed and scan validity (raising before any output)."""
        disp = self._check_displacements(displacements)
        plan = plan_chunks(self.n_vertices, chunk_frames, dtype, blas_threads)
        fitted = self._ensure_fitted()
        return disp, self._patterns.scan(disp, self.all_invalid), plan, fitted

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
        disp, scan, plan, fitted = self._prepare(displacements, chunk_frames, dtype, blas_threads)
        rhs = None if offset is None else offset_rhs(fitted, offset, plan.dtype)
        if buffers is not None and (isinstance(buffers, bool) or not isinstance(buffers, (int, np.integer))
                                    or buffers < 1):
            raise OptionError(f"buffers: expected an integer >= 1 or None; got {buffers!r}")
        n_buffers = 1 if reuse_buffer else (int(buffers) if buffers is not None else 0)
        plan = ChunkPlan(chunk_frames=plan.chunk_frames, dtype=plan.dtype, blas_threads=plan.blas_threads,
                         n_buffers=n_buffers, rhs=rhs, extents=bool(extents))
        return generate_chunks(fitted, self._patterns, self.all_invalid, disp, scan, plan)

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
        disp, scan, plan, fitted = self._prepare(displacements, chunk_frames, dtype, blas_threads)
        out = np.empty((disp.shape[0], self.n_vertices, 3), dtype=plan.dtype)
        for _ in generate_chunks(fitted, self._patterns, self.all_invalid, disp, scan, plan, out=out):
            pass  # each chunk is evaluated in place into its frame slice of out
        return out[0] if single else out


def transfer_motion(D_vc, D_cc, displacements, *, settings: RBFSettings = RBFSettings(),
                    centres: RBFCentres = RBFCentres(), dtype=np.float32) -> np.ndarray:
    """One call: ``RBFTransfer(D_vc, D_cc, settings=settings, centres=centres).fit().apply(displacements)``.

    Parameters
    ----------
    D_vc : array_like, shape (N, C)
        Vertex-to-centre distances (mesh units).
    D_cc : array_like, shape (C, C)
        Centre-to-centre distances (mesh units).
    displacements : array_like, shape (F, M, 3)
        Marker displacements (mesh units), NaN for invalid samples.
    settings : RBFSettings
    centres : RBFCentres
        As for :class:`RBFTransfer`.
    dtype : {numpy.float32, numpy.float64}
        Output type.

    Returns
    -------
    ndarray, shape (F, N, 3), ``dtype``
        Vertex displacements (mesh units).
    """
    return RBFTransfer(D_vc, D_cc, settings=settings, centres=centres).fit().apply(displacements, dtype=dtype)
