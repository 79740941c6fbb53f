"""DCC-safe skinning of the RBF transfer: non-negative weights summing to one, K per vertex.

What is fitted
--------------
The transfer moves vertex i by ``v_i(f) = sum_m B_im t_m(f)`` (B the N x M transfer matrix, t_m(f)
marker m's displacement at frame f). Blender, Maya's skinCluster and game engines take skin
weights that are non-negative, sum to one and number at most K per vertex, and B is none of those
(the interpolant has negative lobes). The deliverable here is a rig those tools play:

- joints: a static root (the head's rigid part; it takes each vertex's remaining weight) and one
  translation-only joint per marker, at the marker's bound point;
- weights W (N x (1 + M)): W >= 0, rows summing to one, at most K non-zero per row (root
  included), every non-zero weight >= :data:`MIN_WEIGHT` (Blender drops smaller ones);
- joint animation: joint j translates by ``tau_j(f) = sum_m P_jm t_m(f)``; P = W_m^+ B is the
  least-squares best for every frame at once (W_m: W without the root column), so a joint follows
  a blend of nearby markers (amplified: its weight is shared with its neighbours and the root);
- S corrective blend shapes (time-invariant offsets; at most 16) with per-frame weights in [0, 1]
  that add the least-squares projection of what the skinning misses at that frame on S - 1
  correction directions (below).

Linear blend skinning of translation joints with rows summing to one moves vertex i by
``sum_j W_ij tau_j(f)``; blend shapes add before skinning and pass through unchanged. The skinned
face is therefore ``p_i + (W_m P t(f))_i + (shapes)``, and its error against the point cache is
``(B - W_m P) t(f)`` minus its projection on the shapes.

This is smooth skinning decomposition (SSDR, Le & Deng 2012) restricted to translation joints,
with the example poses replaced by a distribution over marker motions:

- initialisation: Gaussian kernels of the vertex-to-marker distances (the transfer's own distances
  and width), divided by their largest row sum: non-negative, local, rows summing to at most one
  (the root takes the rest). With every centre's kernel kept their span contains B exactly
  (B = Phi A^-1 for the Gaussian interpolant), so P can undo the kernels' smoothing;
- alternation: P-step ``P = W_m^+ B``; W-step per vertex, the simplex-constrained least squares
  ``min (w P - b_i) Sigma (w P - b_i)^T`` on the vertex's K candidate joints
  (:func:`usdface.skel.simplex_lsq.simplex_lsq`), Sigma the covariance of the fitting range. The
  K candidates start as the K largest initial weights; each W-step also solves on the 2K largest
  and keeps the K strongest of that solution where they fit the vertex better (sparse selection
  that never increases the objective);
- shapes: the leading left singular vectors u_c of ``(B - W_m P) Sigma^{1/2}``, one direction per
  axis (u_c along x, y or z): C = S - 1 orthonormal correction directions s_c whose per-frame
  coefficients ``alpha_c(f) = <s_c, residual(f)>`` are signed. DCC importers clamp shape weights
  to [0, 1] (Blender's shape-key sliders), so the S shapes are the vertices of a regular simplex in
  the span of the C directions, ``S_k = sigma sum_c V_ck s_c`` (V a C x S matrix with orthonormal
  rows and ``V 1 = 0``): any alpha is ``sum_k beta_k S_k`` with
  ``beta = V^T alpha / sigma + t 1``, and the smallest t making beta >= 0 gives weights that are
  zero at rest. sigma makes the largest offset of any shape :data:`SHAPE_OFFSET_FACTOR` marker
  spacings, far more than the skinning misses, so the weights stay below one (they are clipped to
  [0, 1], and the error reported includes any clipping).

The range of motion (Sigma)
---------------------------
Weights belong to the character, not to a take. The default range is synthetic: every marker
moved by random smooth displacement fields over the face, i.e. a Gaussian process on the bound
points with covariance ``exp(-(d_jk / s)^2) + jitter * I`` (d the transfer's marker-to-marker
distances, hybrid or geodesic ones keep the lips apart; s = :data:`ROM_WIDTH_FACTOR` x the median
marker spacing; the jitter lets every marker also move alone). The fit is quadratic in the motion,
so the expected error over that infinite random range is exactly ``tr(E Sigma E^T)``: no sampling.
A take can be the range instead (Sigma = its marker-motion Gram matrix).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from threadpoolctl import threadpool_limits

from ..errors import ComputeError, OptionError
from .modes import DEFAULT_SHAPES, MAX_SHAPES
from .simplex_lsq import simplex_lsq
from .weights import SkinWeights, error_summary

#: smallest authored weight (Blender's USD importer drops smaller ones and renormalises)
MIN_WEIGHT = 1e-5
#: synthetic range of motion: correlation width as a multiple of the median marker spacing
ROM_WIDTH_FACTOR = 1.0
#: synthetic range of motion: independent motion of each marker, relative to the shared part
ROM_JITTER = 0.1
#: largest offset of a corrective shape, in median marker spacings (weights then stay well below one)
SHAPE_OFFSET_FACTOR = 2.0
#: alternations of the weight and joint-motion steps; stop early below this relative gain
DEFAULT_ITERATIONS = 12
CONVERGED = 1e-3


@dataclass(frozen=True)
class DccSkin:
    """A fitted DCC-safe skin (module docstring). Joint 0 is the static root, joint 1 + m marker m.

    Attributes
    ----------
    weights : SkinWeights
        K influences per vertex: non-negative, rows summing to one, each weight 0 or >= MIN_WEIGHT.
    joint_map : ndarray (M, M) float64
        P: marker joint j translates by ``joint_map[j] @ t(f)`` (t(f) the (M, 3) marker displacements).
    shapes : ndarray (S, N, 3) float64
        Corrective blend-shape offsets (mesh units at weight one); they sum to zero.
    shape_map : ndarray (S, M, 3) float64
        Shape weights before the shift: ``lin_s(f) = sum(shape_map[s] * t(f))``; the weights are
        ``clip(lin - min(0, min_s lin_s), 0, 1)`` (:meth:`shape_weights`).
    objective : list of float
        ``tr(E Sigma E^T)`` (E = B - W_m P) at the start, after each alternation and after
        dropping the weights below MIN_WEIGHT.
    """

    weights: SkinWeights
    joint_map: np.ndarray
    shapes: np.ndarray
    shape_map: np.ndarray
    objective: list

    @property
    def n_shapes(self) -> int:
        return self.shapes.shape[0]

    def joint_translations(self, displacements: np.ndarray) -> np.ndarray:
        """(F, M, 3) marker-joint translations for marker displacements (F, M, 3)."""
        return np.matmul(self.joint_map, np.asarray(displacements, dtype=np.float64))

    def shape_weights(self, displacements: np.ndarray) -> np.ndarray:
        """(F, S) blend-shape weights in [0, 1] for marker displacements (F, M, 3)."""
        d = np.asarray(displacements, dtype=np.float64)
        lin = d.reshape(d.shape[0], -1) @ self.shape_map.reshape(self.n_shapes, d.shape[1] * 3).T
        if self.n_shapes == 0:
            return lin
        return np.clip(lin - np.minimum(lin.min(axis=1, keepdims=True), 0.0), 0.0, 1.0)

    def displacements(self, displacements: np.ndarray) -> np.ndarray:
        """(F, N, 3) vertex displacements the rig gives (numpy linear blend skinning + shapes)."""
        d = np.asarray(displacements, dtype=np.float64)
        f, m, _ = d.shape
        n = self.shapes.shape[1]
        dense = self.weights.dense(m + 1)[:, 1:]
        tau = self.joint_translations(d).transpose(1, 0, 2).reshape(m, -1)  # (M, F*3)
        out = (dense @ tau).reshape(n, f, 3).transpose(1, 0, 2)
        if self.n_shapes:
            out = out + (self.shape_weights(d) @ self.shapes.reshape(self.n_shapes, -1)).reshape(f, n, 3)
        return out


def rom_covariance(marker_distances: np.ndarray, *, width: float | None = None,
                   jitter: float = ROM_JITTER) -> np.ndarray:
    """Covariance of the synthetic range of motion: smooth random marker displacement fields.

    Parameters
    ----------
    marker_distances : ndarray (M, M)
        Marker-to-marker distances (mesh units; the transfer's, possibly asymmetric: symmetrised).
    width : float, optional
        Correlation width s (mesh units); default ROM_WIDTH_FACTOR x the median nearest-marker distance.
    jitter : float
        Weight of independent per-marker motion (>= 0).

    Returns
    -------
    ndarray (M, M) float64, symmetric positive definite: ``exp(-(d/s)^2) + jitter I``
    (for jitter = 0 it can be singular; a tiny ridge is added).
    """
    from ..rbf.stiffness import median_marker_spacing

    d = np.asarray(marker_distances, dtype=np.float64)
    d = 0.5 * (d + d.T)
    d[~np.isfinite(d)] = np.inf
    s = ROM_WIDTH_FACTOR * median_marker_spacing(d) if width is None else float(width)
    if not s > 0:
        raise OptionError(f"range-of-motion width must be > 0; got {width!r}")
    cov = np.exp(-(d / s) ** 2)
    np.fill_diagonal(cov, 1.0)
    # a Gaussian of non-Euclidean distances need not be positive definite: clip its spectrum
    ev, vec = np.linalg.eigh(cov)
    cov = (vec * np.maximum(ev, 0.0)) @ vec.T
    cov += (max(float(jitter), 0.0) + 1e-9) * np.eye(d.shape[0])
    return 0.5 * (cov + cov.T)


def take_covariance(displacements: np.ndarray) -> np.ndarray:
    """(M, M) Gram matrix of a take's marker displacements (F, M, 3), summed over axes, per frame."""
    d = np.asarray(displacements, dtype=np.float64)
    flat = d.transpose(1, 0, 2).reshape(d.shape[1], -1)
    g = flat @ flat.T / max(d.shape[0], 1)
    return g + 1e-9 * max(float(np.trace(g)) / g.shape[0], 1e-30) * np.eye(g.shape[0])


def initial_weights(vertex_marker_distances: np.ndarray, widths) -> np.ndarray:
    """(N, 1 + M) starting weights: Gaussian kernels of the distances over their largest row sum.

    Column 0 (the root) takes each row's remainder, so rows sum to one and every weight is >= 0.
    """
    from ..rbf.kernels import gaussian

    phi = gaussian(np.asarray(vertex_marker_distances, dtype=np.float64), np.asarray(widths, dtype=np.float64))
    phi[~np.isfinite(phi)] = 0.0
    top = float(phi.sum(axis=1).max())
    if not top > 0:
        raise ComputeError("skin weights: no vertex is within reach of any marker (all kernel values are zero)")
    phi /= top
    return np.concatenate([np.clip(1.0 - phi.sum(axis=1, keepdims=True), 0.0, 1.0), phi], axis=1)


def _joint_map(w_markers: np.ndarray, b: np.ndarray) -> np.ndarray:
    """P = W_m^+ B by the normal equations (a joint without vertices gets a zero row)."""
    a = w_markers.T @ w_markers
    ridge = 1e-12 * max(float(np.trace(a)) / a.shape[0], 1e-30)
    return np.linalg.solve(a + ridge * np.eye(a.shape[0]), w_markers.T @ b)


def _support(weights: np.ndarray, k: int) -> np.ndarray:
    """The K largest entries of each row (ties by joint index), sorted by joint index."""
    order = np.argsort(-weights, axis=1, kind="stable")[:, :k]
    return np.sort(order, axis=1)


def solve_weights(transfer_matrix: np.ndarray, joint_map: np.ndarray, covariance: np.ndarray, support: np.ndarray, *,
                  allowed: np.ndarray | None = None, start: np.ndarray | None = None) -> np.ndarray:
    """The W-step: each vertex's best weights on its support for a given joint motion.

    Per vertex i, ``min (w P_1 - b_i) Sigma (w P_1 - b_i)^T`` over w >= 0 summing to one on the
    support, P_1 = P with a zero row prepended (the root never moves).

    Parameters
    ----------
    transfer_matrix : ndarray (N, M)
    joint_map : ndarray (M, M)
        P (:attr:`DccSkin.joint_map`).
    covariance : ndarray (M, M)
    support : ndarray (N, S) int
        Candidate joints per vertex (0 = root, 1 + m = marker m).
    allowed, start : see :func:`usdface.skel.simplex_lsq.simplex_lsq` (``start`` as (N, 1 + M)).

    Returns
    -------
    ndarray (N, 1 + M): dense weights.
    """
    b = np.asarray(transfer_matrix, dtype=np.float64)
    p = np.asarray(joint_map, dtype=np.float64)
    n, m = b.shape
    a = np.vstack([np.zeros((1, m)), p])  # the root never moves
    cov = np.asarray(covariance, dtype=np.float64)
    gram = a @ cov @ a.T
    linear = b @ cov @ a.T
    w = simplex_lsq(gram, linear, support, allowed=allowed,
                    start=None if start is None else np.take_along_axis(start, support, axis=1))
    out = np.zeros((n, p.shape[0] + 1))
    np.put_along_axis(out, support, w, axis=1)
    return out


def _vertex_objective(b, w, p, cov) -> np.ndarray:
    e = b - w[:, 1:] @ p
    return ((e @ cov) * e).sum(axis=1)


def _objective(b, w, p, cov) -> float:
    e = b - w[:, 1:] @ p
    return float(((e @ cov) * e).sum())


def fit_dcc_skin(transfer_matrix: np.ndarray, initial: np.ndarray, k: int | None, covariance: np.ndarray, *,
                 n_shapes: int = DEFAULT_SHAPES, shape_offset: float = 1.0,
                 iterations: int = DEFAULT_ITERATIONS) -> DccSkin:
    """Fit DCC-safe weights, joint motion and corrective shapes to the transfer (module docstring).

    Parameters
    ----------
    transfer_matrix : ndarray (N, M)
        B: vertex displacement = B @ marker displacements.
    initial : ndarray (N, 1 + M)
        Starting weights (:func:`initial_weights`); their K largest per row are each vertex's
        candidate joints.
    k : int or None
        Influences per vertex, root included (>= 1); None: every joint may take weight.
    covariance : ndarray (M, M)
        Sigma of the fitting range (:func:`rom_covariance` or :func:`take_covariance`).
    n_shapes : int
        Corrective blend shapes: 0, or 2..MAX_SHAPES (S shapes correct S - 1 directions).
    shape_offset : float
        Largest offset of any corrective shape (mesh units); a shape's weight is the fraction of
        it applied (the processor uses the median marker spacing).
    iterations : int
        Weight / joint-motion alternations (>= 1).

    Returns
    -------
    DccSkin
    """
    b = np.asarray(transfer_matrix, dtype=np.float64)
    n, m = b.shape
    w0 = np.asarray(initial, dtype=np.float64)
    cov = np.asarray(covariance, dtype=np.float64)
    if w0.shape != (n, m + 1):
        raise ComputeError(f"skin fit: initial weights {w0.shape}, expected {(n, m + 1)}")
    if cov.shape != (m, m):
        raise ComputeError(f"skin fit: covariance {cov.shape}, expected {(m, m)}")
    if k is not None and (isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1):
        raise OptionError(f"--max-influences: expected an integer >= 1; got {k!r}")
    check_shape_count(n_shapes)
    if not shape_offset > 0:
        raise OptionError(f"corrective shape offset must be > 0; got {shape_offset!r}")
    with threadpool_limits(limits=1, user_api="blas"):
        return _fit(b, w0, cov, m + 1 if k is None else min(int(k), m + 1), int(n_shapes), float(shape_offset),
                    int(iterations))


def check_shape_count(n_shapes) -> int:
    """--corrective-shapes: 0 or 2..MAX_SHAPES (one shape alone cannot correct anything)."""
    if (isinstance(n_shapes, bool) or not isinstance(n_shapes, (int, np.integer))
            or not (n_shapes == 0 or 2 <= n_shapes <= MAX_SHAPES)):
        raise OptionError(f"--corrective-shapes: expected 0 or an integer from 2 to {MAX_SHAPES}; got {n_shapes!r}")
    return int(n_shapes)


def _fit(b, w0, cov, kk, n_shapes, shape_offset, iterations) -> DccSkin:
    # small dense products: one BLAS thread is faster, and far faster on a loaded machine
    m1 = w0.shape[1]
    support = _support(w0, kk)
    pool = _support(w0, min(2 * kk, m1)) if kk < m1 else None
    w = np.zeros_like(w0)
    np.put_along_axis(w, support, np.take_along_axis(w0, support, axis=1), axis=1)
    w /= w.sum(axis=1, keepdims=True)
    p = _joint_map(w[:, 1:], b)
    history = [_objective(b, w, p, cov)]
    for _ in range(max(1, int(iterations))):
        w = solve_weights(b, p, cov, support, start=w)
        if pool is not None:
            # another support per vertex: the K strongest of the weights on twice as many candidates;
            # a vertex takes it only if it fits better (so the objective never increases)
            on_pool = solve_weights(b, p, cov, pool, start=w)  # w lives on a subset of the pool
            other = _support(on_pool, kk)
            kept = np.zeros_like(on_pool)
            np.put_along_axis(kept, other, np.take_along_axis(on_pool, other, axis=1), axis=1)
            w_other = solve_weights(b, p, cov, other, start=kept / kept.sum(axis=1, keepdims=True))
            better = _vertex_objective(b, w_other, p, cov) < _vertex_objective(b, w, p, cov)
            w[better] = w_other[better]
            support[better] = other[better]
        p = _joint_map(w[:, 1:], b)
        history.append(_objective(b, w, p, cov))
        if history[-2] - history[-1] <= CONVERGED * history[-2]:
            break
    w = _drop_small(b, w, cov, support)
    p = _joint_map(w[:, 1:], b)
    history.append(_objective(b, w, p, cov))
    shapes, shape_map = _corrective_shapes(b - w[:, 1:] @ p, cov, n_shapes, shape_offset)
    # strongest first, as SkinWeights keeps them
    order = np.argsort(-np.take_along_axis(w, support, axis=1), axis=1, kind="stable")
    idx = np.take_along_axis(support, order, axis=1)
    vals = np.take_along_axis(w, idx, axis=1)
    return DccSkin(SkinWeights(idx.astype(np.int32), vals, "dcc", "dcc"), p, shapes, shape_map, history)


def _drop_small(b, w, cov, support, *, rounds: int = 3) -> np.ndarray:
    """Zero the weights below MIN_WEIGHT and refit the rest, until none is left (then rescale)."""
    allowed = np.ones(support.shape, dtype=bool)
    for _ in range(rounds):
        vals = np.take_along_axis(w, support, axis=1)
        small = (vals > 0) & (vals < MIN_WEIGHT)
        if not small.any():
            return w
        allowed &= ~small
        rows = np.flatnonzero(small.any(axis=1))
        p = _joint_map(w[:, 1:], b)
        w[rows] = solve_weights(b[rows], p, cov, support[rows], allowed=allowed[rows])
    vals = np.take_along_axis(w, support, axis=1)
    vals[vals < MIN_WEIGHT] = 0.0
    vals /= vals.sum(axis=1, keepdims=True)
    out = np.zeros_like(w)
    np.put_along_axis(out, support, vals, axis=1)
    return out


def simplex_frame(c: int) -> np.ndarray:
    """(C, C + 1) vertices of a regular simplex centred at the origin: orthonormal rows, ``V 1 = 0``.

    Any vector a of R^C is ``V beta`` with ``beta = V^T a + t 1`` for every t (columns sum to
    zero), so a large enough t makes every coefficient non-negative.
    """
    # orthonormal basis of the complement of 1 in R^(C+1) (Helmert's, deterministic)
    h = np.zeros((c, c + 1))
    for i in range(c):
        h[i, :i + 1] = 1.0
        h[i, i + 1] = -(i + 1.0)
        h[i] /= np.linalg.norm(h[i])
    return h


def _corrective_shapes(residual_map: np.ndarray, cov: np.ndarray, n_shapes: int,
                       shape_offset: float) -> tuple[np.ndarray, np.ndarray]:
    """Corrective shapes on the simplex of the leading per-axis residual directions (module docstring).

    Direction (c, a) moves the vertices along axis a by the c-th left singular vector u_c of
    ``E Sigma^{1/2}``; its coefficient at a frame is ``u_c^T E t_a(f)``, the least-squares projection
    of the skinning error (the directions are orthonormal).
    """
    n, m = residual_map.shape
    if n_shapes == 0:
        return np.zeros((0, n, 3)), np.zeros((0, m, 3))
    ev, vec = np.linalg.eigh(cov)
    half = (vec * np.sqrt(np.maximum(ev, 0.0))) @ vec.T
    u, _, _ = np.linalg.svd(residual_map @ half, full_matrices=False)
    n_dirs = n_shapes - 1
    dirs = np.zeros((n_dirs, n, 3))
    dir_maps = np.zeros((n_dirs, m, 3))
    for d in range(n_dirs):
        c, axis = divmod(d, 3)
        uc = u[:, c]
        uc = uc if uc[np.argmax(np.abs(uc))] > 0 else -uc  # deterministic sign
        dirs[d, :, axis] = uc
        dir_maps[d, :, axis] = uc @ residual_map
    v = simplex_frame(n_dirs)
    shapes = np.einsum("ck,cnx->knx", v, dirs)
    sigma = shape_offset / float(np.linalg.norm(shapes, axis=2).max())
    return sigma * shapes, np.einsum("ck,cmx->kmx", v, dir_maps) / sigma


def dcc_skinning_error(skin: DccSkin, transfer_matrix: np.ndarray, displacements: np.ndarray, *,
                       chunk_frames: int = 128) -> dict:
    """How far the fitted rig is from the point cache (numpy linear blend skinning, float64).

    Parameters
    ----------
    skin : DccSkin
    transfer_matrix : ndarray (N, M)
    displacements : ndarray (F, M, 3)
        Marker displacements (finite; effective ones on frames with missing markers).

    Returns
    -------
    dict with ``max`` and ``rms`` (mesh units) over every vertex and frame, ``maxFrame``
    (index into ``displacements``) and ``frames``.
    """
    b = np.asarray(transfer_matrix, dtype=np.float64)
    d = np.asarray(displacements, dtype=np.float64)

    def chunks():
        for a in range(0, d.shape[0], chunk_frames):
            part = d[a:a + chunk_frames]
            flat = part.transpose(1, 0, 2).reshape(part.shape[1], -1)
            err = skin.displacements(part) - (b @ flat).reshape(b.shape[0], part.shape[0], 3).transpose(1, 0, 2)
            yield a, np.sqrt((err * err).sum(axis=2))  # (f, N)

    return error_summary(chunks())
