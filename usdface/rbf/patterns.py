"""Invalid samples: one small operator per validity pattern, cached (see :mod:`usdface.rbf.transfer`).

A frame whose markers are not all valid is solved with its valid markers only, by feeding the full
transfer matrix *effective* displacements: the valid markers' own, and at each dropped marker the
value the reduced interpolant takes there (block inverse of the marker block ``Z`` of A^-1; paper
mode: the renormalised Eq. 4). :func:`pattern_operator` computes that (M, |S|) operator for one
pattern; :class:`PatternCache` scans a sequence's validity, computes each new pattern once, and
turns a chunk's displacements into effective ones.
"""
from __future__ import annotations

import numpy as np

from ..errors import ComputeError, list_names
from .solver import SINGULAR_CONDITION, FittedTransfer
from .system import RBFSystem

__all__ = ["PatternCache", "pattern_operator"]


def pattern_operator(system: RBFSystem, fitted: FittedTransfer, valid: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """(M, |S|) operator E of one validity pattern: effective marker displacements = E @ valid ones.

    Parameters
    ----------
    system : RBFSystem
    fitted : FittedTransfer
        From :func:`usdface.rbf.solver.fit_system` on ``system``.
    valid : ndarray, shape (M,), bool
        The pattern (S: the valid markers, R: the others).
    frames : ndarray of int
        The frames with this pattern, for messages.

    Returns
    -------
    ndarray, shape (M, |S|), float64
        Interpolate mode: identity on S and ``-Z_RR^-1 Z_RS`` on R (``D_R = A_RS A_SS^-1 D_S``).
        Paper mode: ``r_j / r_j^S`` on the diagonal of S (Eq. 4 over the valid markers), 0 on R.

    Raises
    ------
    ComputeError
        The reduced system is singular, the valid centres leave the polynomial term undetermined,
        or (paper mode) non-positive Eq. 4 sums.
    """
    M = system.n_markers
    S = np.flatnonzero(valid)
    R = np.flatnonzero(~valid)
    E = np.zeros((M, S.size))
    where = lambda: (f"frame(s) {list_names(frames.tolist(), limit=8)} with invalid markers "
                     f"{list_names([system.marker_label(int(r)) for r in R], limit=8)}")
    if system.settings.mode == "paper":
        rS = fitted.phi_mm[np.ix_(S, S)].sum(axis=1)
        if not (np.isfinite(rS) & (rS > 0)).all():
            raise ComputeError(f"paper mode: Eq. 4 sums are not positive for {where()}")
        E[S, np.arange(S.size)] = fitted.r[S] / rS
        return E
    if system.settings.polynomial:
        P_S = np.vstack([system.P_c[S], system.P_c[M:]])
        if np.linalg.matrix_rank(P_S) < 4:
            raise ComputeError(
                f"polynomial term: the valid centres of {where()} are coplanar or fewer than 4; "
                "the linear part is undetermined (add constraint centres or use polynomial=False)"
            )
    Z = fitted.Z_mm
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


class PatternCache:
    """The operators of the validity patterns seen so far (key: the pattern's bytes), with counts.

    Starts with the all-valid pattern (the identity), which is counted neither as a miss nor as a hit.
    """

    def __init__(self, system: RBFSystem, fitted: FittedTransfer) -> None:
        self._system, self._fitted = system, fitted
        M = system.n_markers
        self._full = np.ones(M, dtype=bool).tobytes()
        self._operators: dict[bytes, np.ndarray] = {self._full: np.eye(M)}
        self.hits = 0
        self.misses = 0

    def info(self) -> dict[str, int]:
        """``{"hits", "misses", "patterns"}`` (see :meth:`usdface.rbf.transfer.RBFTransfer.cache_info`)."""
        return {"hits": self.hits, "misses": self.misses, "patterns": len(self._operators)}

    def clear(self) -> None:
        """Forget every pattern except the all-valid one; reset the counters."""
        self._operators = {k: v for k, v in self._operators.items() if k == self._full}
        self.hits = self.misses = 0

    def scan(self, disp: np.ndarray, all_invalid: str) -> tuple[np.ndarray, np.ndarray, list[bytes]]:
        """Validity of every frame; computes (and counts) every pattern before any output.

        Parameters
        ----------
        disp : ndarray, shape (F, M, 3), float
            Marker displacements (mesh units), NaN or inf for invalid samples.
        all_invalid : {"error", "hold", "zero"}
            ``"error"``: frames with no valid marker raise here.

        Returns
        -------
        valid : ndarray, shape (F, M), bool
        pid : ndarray, shape (F,), int64
            Pattern id per frame: -1 all valid, -2 none valid, else an index into ``keys``.
        keys : list of bytes
            The pattern keys by id.

        Raises
        ------
        ComputeError
            Frames with no valid marker (``all_invalid="error"``; ``.frames`` lists them), or a
            pattern whose reduced system is singular.
        """
        F, M = disp.shape[:2]
        valid = np.isfinite(disp).all(axis=2)
        n_valid = valid.sum(axis=1)
        none = np.flatnonzero(n_valid == 0)
        if none.size and all_invalid == "error":
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
                if key in self._operators:
                    self.hits += int(count)
                else:
                    self._operators[key] = pattern_operator(self._system, self._fitted, pattern, partial[inv == u])
                    self.misses += 1
                    self.hits += int(count) - 1
            pid[partial] = inv
        return valid, pid, keys

    def effective(self, disp: np.ndarray, scan: tuple, all_invalid: str, held: np.ndarray | None) -> np.ndarray:
        """(f, M, 3) float64 effective marker displacements of a chunk (no NaN).

        ``scan`` is the chunk's slice of :meth:`scan`'s (valid, pid, keys); frames with no valid
        marker repeat the previous frame (``held`` before the chunk's first) with ``"hold"``, else
        are zero.
        """
        valid, pid, keys = scan
        f, M = disp.shape[:2]
        out = np.empty((f, M, 3))
        full = pid == -1
        out[full] = disp[full]
        for u in np.unique(pid[pid >= 0]):
            idx = np.flatnonzero(pid == u)
            S = valid[idx[0]]
            E = self._operators[keys[u]]
            out[idx] = np.einsum("ms,fsc->fmc", E, disp[idx][:, S])
        for i in np.flatnonzero(pid == -2):
            if all_invalid == "hold" and (i > 0 or held is not None):
                out[i] = out[i - 1] if i > 0 else held
            else:
                out[i] = 0.0
        return out
