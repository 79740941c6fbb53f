"""Rigid and similarity fitting kernels (weighted Kabsch / Umeyama).

Shared by head stabilisation (:mod:`usdface.capture.stabilize`) and marker binding. All functions
are pure numpy: inputs are never modified.

Convention: a fit maps ``src`` onto ``dst`` as ``dst ~= s * R @ src + t`` (column vectors), with
``R`` a proper rotation (det +1), ``s > 0`` a uniform scale (1 when ``scale=False``) and ``t`` a
translation. The fit minimises ``sum_k w_k |s R src_k + t - dst_k|^2``.

References: W. Kabsch, Acta Cryst. A32 (1976) 922; S. Umeyama, IEEE PAMI 13(4) (1991) 376.
"""
from __future__ import annotations

import numpy as np

from ..errors import ComputeError, OptionError

__all__ = [
    "fit_rigid",
    "fit_rigid_batch",
    "apply_rigid",
    "to_matrix",
    "from_matrix",
    "invert_matrix",
    "rotation_angle",
]


def _prepare_batch(src, dst, weights):
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    if src.shape[-1] != 3 or dst.shape[-1] != 3 or src.ndim not in (2, 3) or dst.ndim not in (2, 3):
        raise OptionError(f"src and dst must have shape (K, 3) or (F, K, 3); got {src.shape} and {dst.shape}")
    if src.shape[-2] != dst.shape[-2]:
        raise OptionError(f"src and dst must have the same number of points; got {src.shape[-2]} and {dst.shape[-2]}")
    n_frames = max(src.shape[0] if src.ndim == 3 else 1, dst.shape[0] if dst.ndim == 3 else 1)
    k = src.shape[-2]
    src_b = np.broadcast_to(src, (n_frames, k, 3)) if src.ndim == 2 else src
    dst_b = np.broadcast_to(dst, (n_frames, k, 3)) if dst.ndim == 2 else dst
    if src_b.shape[0] != n_frames or dst_b.shape[0] != n_frames:
        raise OptionError(f"src and dst frame counts differ: {src.shape} and {dst.shape}")
    if weights is None:
        w = np.ones((n_frames, k))
    else:
        w = np.asarray(weights, dtype=np.float64)
        if w.shape not in ((k,), (n_frames, k)):
            raise OptionError(f"weights must have shape ({k},) or ({n_frames}, {k}); got {w.shape}")
        if np.any(~np.isfinite(w)) or np.any(w < 0):
            raise OptionError("weights must be finite and non-negative")
        w = np.broadcast_to(w, (n_frames, k)).copy()
    # non-finite points get zero weight, and are zeroed so they cannot poison the sums
    ok = np.isfinite(src_b).all(axis=2) & np.isfinite(dst_b).all(axis=2)
    w[~ok] = 0.0
    src_b = np.where(ok[..., None], src_b, 0.0)
    dst_b = np.where(ok[..., None], dst_b, 0.0)
    return src_b, dst_b, w


def fit_rigid_batch(src, dst, *, weights=None, scale=False, min_points=3):
    """Fit one rigid (or similarity) transform per frame, vectorised over frames.

    Parameters
    ----------
    src : ndarray, shape (K, 3) or (F, K, 3), float
        Source points (shared by all frames when 2-D). Non-finite points are ignored.
    dst : ndarray, shape (K, 3) or (F, K, 3), float
        Target points, same units as ``src``. Non-finite points are ignored.
    weights : ndarray, shape (K,) or (F, K), optional
        Non-negative weight per point (per frame). Default: all ones.
    scale : bool
        Also fit a uniform scale (Umeyama); otherwise ``s = 1``.
    min_points : int
        Frames with fewer points of positive weight (and finite coordinates) get NaN outputs.

    Returns
    -------
    R : ndarray, shape (F, 3, 3), float64
        Proper rotations (NaN in frames with too few points).
    s : ndarray, shape (F,), float64
        Scales (1.0 when ``scale=False``; NaN in frames with too few points).
    t : ndarray, shape (F, 3), float64
        Translations, so that ``dst ~= s R src + t``.

    Notes
    -----
    With collinear points (or two points) the rotation about their line is undetermined; the
    SVD then returns one of the minimisers.
    """
    src_b, dst_b, w = _prepare_batch(src, dst, weights)
    n_frames = src_b.shape[0]
    count = (w > 0).sum(axis=1)
    wsum = w.sum(axis=1)
    good = (count >= max(int(min_points), 1)) & (wsum > 0)
    wn = np.divide(w, wsum[:, None], out=np.zeros_like(w), where=good[:, None])
    cs = np.einsum("fk,fki->fi", wn, src_b)
    cd = np.einsum("fk,fki->fi", wn, dst_b)
    xs = src_b - cs[:, None, :]
    xd = dst_b - cd[:, None, :]
    # covariance H = sum_k w_k xs_k xd_k^T;  H = U S Vt  ->  R = V D U^T
    h = np.matmul((xs * wn[:, :, None]).transpose(0, 2, 1), xd)  # batched 3 x K @ K x 3 (BLAS, not einsum)
    u, sv, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.matmul(vt.transpose(0, 2, 1), u.transpose(0, 2, 1))))
    d[d == 0] = 1.0
    dmat = np.ones((n_frames, 3))
    dmat[:, 2] = d
    rot = np.matmul(vt.transpose(0, 2, 1) * dmat[:, None, :], u.transpose(0, 2, 1))
    if scale:
        var_src = np.einsum("fk,fki,fki->f", wn, xs, xs)
        s = np.divide((sv * dmat).sum(axis=1), var_src, out=np.full(n_frames, np.nan), where=var_src > 0)
    else:
        s = np.ones(n_frames)
    t = cd - s[:, None] * np.einsum("fij,fj->fi", rot, cs)
    rot[~good] = np.nan
    s = np.where(good, s, np.nan)
    t[~good] = np.nan
    return rot, s, t


def fit_rigid(src, dst, *, weights=None, scale=False):
    """Fit the rigid (or similarity) transform that best maps ``src`` onto ``dst``.

    Parameters
    ----------
    src, dst : ndarray, shape (K, 3), float
        Corresponding points (same units). Points with a non-finite coordinate are ignored.
    weights : ndarray, shape (K,), optional
        Non-negative weight per point; default all ones.
    scale : bool
        Also fit a uniform scale ``s`` (Umeyama); otherwise ``s = 1.0``.

    Returns
    -------
    R : ndarray, shape (3, 3), float64
        Proper rotation.
    s : float
        Scale.
    t : ndarray, shape (3,), float64
        Translation: ``dst ~= s * R @ src + t``.

    Raises
    ------
    ComputeError
        Fewer than 3 usable points (2 points do not fix a rotation).
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    if src.ndim != 2 or dst.ndim != 2:
        raise OptionError(f"fit_rigid takes (K, 3) arrays; got {src.shape} and {dst.shape} (use fit_rigid_batch)")
    rot, s, t = fit_rigid_batch(src, dst, weights=weights, scale=scale)
    if not np.isfinite(s[0]):
        raise ComputeError(
            f"rigid fit needs at least 3 points with finite coordinates and positive weight "
            f"(and a non-degenerate source when scale=True); got {src.shape[0]} points"
        )
    return rot[0], float(s[0]), t[0]


def apply_rigid(points, R, s=1.0, t=None):
    """Apply ``s R p + t`` to points.

    Parameters
    ----------
    points : ndarray, shape (..., K, 3)
    R : ndarray, shape (3, 3) or (..., 3, 3)
    s : float or ndarray, shape (...)
    t : ndarray, shape (3,) or (..., 3), optional

    Returns
    -------
    ndarray, shape (..., K, 3), float64
    """
    p = np.asarray(points, dtype=np.float64)
    R = np.asarray(R, dtype=np.float64)
    out = np.einsum("...ij,...kj->...ki", R, p) * np.asarray(s, dtype=np.float64)[..., None, None]
    if t is not None:
        out = out + np.asarray(t, dtype=np.float64)[..., None, :]
    return out


def to_matrix(R, s=1.0, t=None):
    """Pack rotation, scale and translation into 4x4 matrices (column-vector convention).

    Parameters
    ----------
    R : ndarray, shape (..., 3, 3)
    s : float or ndarray, shape (...)
    t : ndarray, shape (..., 3), optional (zero)

    Returns
    -------
    ndarray, shape (..., 4, 4), float64
        ``M[:3, :3] = s R``, ``M[:3, 3] = t``, last row ``(0, 0, 0, 1)``.
    """
    R = np.asarray(R, dtype=np.float64)
    lead = R.shape[:-2]
    m = np.zeros(lead + (4, 4))
    m[..., :3, :3] = R * np.asarray(s, dtype=np.float64)[..., None, None]
    if t is not None:
        m[..., :3, 3] = t
    m[..., 3, 3] = 1.0
    return m


def from_matrix(m):
    """Split 4x4 similarity matrices into ``(R, s, t)`` (inverse of :func:`to_matrix`).

    Parameters
    ----------
    m : ndarray, shape (..., 4, 4)

    Returns
    -------
    R : ndarray, shape (..., 3, 3)
    s : ndarray, shape (...)
    t : ndarray, shape (..., 3)
    """
    m = np.asarray(m, dtype=np.float64)
    a = m[..., :3, :3]
    s = np.cbrt(np.linalg.det(a))
    return a / s[..., None, None], s, m[..., :3, 3].copy()


def invert_matrix(m):
    """Invert 4x4 rigid/similarity matrices without a general inverse.

    Parameters
    ----------
    m : ndarray, shape (..., 4, 4)
        Matrices built by :func:`to_matrix`.

    Returns
    -------
    ndarray, shape (..., 4, 4)
    """
    R, s, t = from_matrix(m)
    rinv = np.swapaxes(R, -1, -2) / s[..., None, None]
    return to_matrix(rinv, 1.0, -np.einsum("...ij,...j->...i", rinv, t))


def rotation_angle(R):
    """Rotation angle of rotation matrices, in degrees.

    Parameters
    ----------
    R : ndarray, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (...), float64, in [0, 180]. NaN where R is NaN.
    """
    R = np.asarray(R, dtype=np.float64)
    c = (np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0
    # arccos is ill-conditioned near 0: use atan2 with the axial vector norm
    ax = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    sn = np.linalg.norm(ax, axis=-1) / 2.0
    return np.degrees(np.arctan2(sn, c))
