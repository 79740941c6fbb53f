"""The implicit integrator of the Simulator (seed 001 §5.3 made unconditionally stable):
linearised backward Euler (Baraff-Witkin) with a line search on the incremental potential.

``(M (1 + h gamma) + h C + h^2 K) v_new = M v + h F_el(x)``: ``K`` the positive semi-definite part
of the tangent stiffness (springs, volume Gauss-Newton term, skull contact, muscles) assembled
each step in 3x3 blocks, the volume term applied matrix-free, solved by block-Jacobi
preconditioned conjugate gradients (numba kernels in :mod:`usdface.tissue._kernels`, or the numpy
functions here).

:class:`ImplicitEuler` is a part of :class:`usdface.tissue.integrators.Simulator` (a mixin: it
works on the Simulator's state).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from . import _kernels as kn
from .divergence import DivergenceError
from .forces import prism_volume_gradients, smooth_ramp

__all__ = ["ImplicitEuler"]


class ImplicitEuler:
    """The implicit Euler step and the tangent-stiffness assembly of a Simulator (mixin)."""

    def _implicit_setup(self) -> dict:
        if self._implicit is not None:
            return self._implicit
        nf = self.n_free
        si, sj = self.si, self.sj
        free_i, free_j = si < nf, sj < nf
        both = free_i & free_j
        rows = np.concatenate([np.arange(nf), si[both], sj[both]])
        cols = np.concatenate([np.arange(nf), sj[both], si[both]])
        key = np.unique(rows * np.int64(nf) + cols)
        brow, bcol = key // nf, key % nf
        indptr = np.searchsorted(brow, np.arange(nf + 1)).astype(np.int64)
        indices = bcol.astype(np.int64)

        def slot(r, c):
            r = np.asarray(r, dtype=np.int64)
            c = np.asarray(c, dtype=np.int64)
            ok = (r < nf) & (c < nf)
            out = np.full(r.shape, -1, dtype=np.int64)
            out[ok] = np.searchsorted(key, r[ok] * nf + c[ok])
            return out

        imp = {
            "indptr": indptr, "indices": indices, "key": key,
            "diag": slot(np.arange(nf), np.arange(nf)),
            "ii": slot(si, si), "jj": slot(sj, sj), "ij": slot(si, sj), "ji": slot(sj, si),
            "K": np.zeros((key.size, 3, 3)),
            "G": np.zeros((self.prisms.shape[0], 6, 3)), "Dv": np.zeros((nf, 3, 3)),
        }
        self._implicit = imp
        return imp

    def _assemble(self, hk: float = 1.0, hc: float = 0.0) -> None:
        """``hk K + hc C`` into imp["K"] (tangent stiffness, damping), volume gradients G and the
        volume term's diagonal blocks Dv."""
        imp = self._implicit
        if self.backend == "numba":
            kn.assemble_stiffness(self.x, self.si, self.sj, self.l0, self.k, self.lc, self.kb, self.cs, imp["ii"],
                                  imp["jj"], imp["ij"], imp["ji"], self.prisms, self.model.volume_coef,
                                  self.muscles.nodes, self.muscles.muscle, self.m_coef, self.anchors, self.muscles.metric,
                                  self.m_eps, self.n, self.skull_normals, self.skull_margin, self.k_skull, self.beta,
                                  hk, hc, imp["diag"], imp["K"], imp["G"], imp["Dv"])
        else:
            _assemble_numpy(self, hk, hc)

    def _apply(self, data, vscale, v) -> np.ndarray:
        """(data + sum_p vscale_p g_p g_p^T) @ v for the current assembly."""
        imp = self._implicit
        out = np.empty_like(v)
        if self.backend == "numba":
            kn.apply_matrix(data, imp["indices"], imp["indptr"], imp["G"], self.prisms, vscale, v, out)
        else:
            out = _apply_numpy(data, imp, self.prisms, vscale, v)
        return out

    def elastic_forces(self) -> np.ndarray:
        """Forces without the damping terms at the current positions (energies updated); cached
        between a step's line search and the next step when nothing moved in between."""
        if self._fel_valid:
            return self._fel
        v = self.v
        gamma = self.gamma
        self.v = self._vzero
        self.gamma = 0.0
        try:
            F = self.compute_forces()
        finally:
            self.v, self.gamma = v, gamma
        self._fel = F.copy()
        self._fel_energies = self.energies.copy()
        return self._fel

    def _implicit_step(self, h: float) -> None:
        """Linearised backward Euler, written for the new velocity:
        ``(M (1 + h gamma) + h C + h^2 K) v_new = M v + h F_el(x)`` (F_el: the forces without damping;
        algebraically the same as Baraff-Witkin's ``dv`` system), then a line search on the
        incremental potential."""
        imp = self._implicit_setup()
        nf = self.n_free
        F = self.elastic_forces()
        u0 = float(self._fel_energies.sum())
        self._assemble(h * h, h)
        A = imp["K"]
        diag = imp["diag"]
        m = self.mass_free * (1.0 + h * self.gamma)
        A[diag, 0, 0] += m
        A[diag, 1, 1] += m
        A[diag, 2, 2] += m
        v0 = np.ascontiguousarray(self.v[:nf])
        F_rhs = F
        if self.beta and self.v[nf:].any():
            # moving bones drag the tissue through the damping of the springs, prisms and contact
            # that reach them: those forces (free nodes at rest) go to the right-hand side
            vb = self._vzero.copy()
            vb[nf:] = self.v[nf:]
            v_saved, g_saved = self.v, self.gamma
            self.v, self.gamma = vb, 0.0
            try:
                F_rhs = self.compute_forces().copy()
            finally:
                self.v, self.gamma = v_saved, g_saved
        rhs = self.mass_free[:, None] * v0 + h * F_rhs[:nf]
        # the volume term enters the matrix-free part with its stiffness (h^2) and its damping (h beta)
        vfac = h * h + h * self.beta
        vscale = vfac * self.model.volume_coef
        if "Dv_h" not in imp:
            imp["Dv_h"] = np.empty_like(imp["Dv"])
        np.multiply(imp["Dv"], vfac, out=imp["Dv_h"])
        # solve for the velocity change (A dv = rhs - A v0) so the tolerance is relative to the change,
        # warm-started with the last step's change
        rhs = rhs - self._apply(A, vscale, v0)
        if self.backend == "numba":
            dv, it, res = kn.block_cg(A, imp["indices"], imp["indptr"], diag, imp["G"], self.prisms, vscale,
                                      imp["Dv_h"], rhs, self._dv, self.cg_tol, self._cg_atol, 2000)
        else:
            dv, it, res = _cg_numpy(A, imp, self.prisms, vscale, imp["Dv_h"], rhs, self._dv, self.cg_tol,
                                    self._cg_atol)
        self._dv = dv
        v1 = v0 + dv
        self.last_cg = (int(it), float(res))
        if not np.isfinite(res) or res > 1e-2:
            raise DivergenceError(
                f"implicit solve failed at t = {self.time:.4f} s (step {self.steps}): CG residual {res:.2g} after "
                f"{it} iterations", time=self.time, step=self.steps,
                cause="the tangent system is ill-conditioned (inverted elements or extreme parameters)")
        # the step is one Newton step on the incremental potential
        #   phi(x) = |x - x_n - h v_n|_M^2 / (2 h^2) + gamma |x - x_n|_M^2 / (2 h) + U(x)
        # from x_n; a backtracking line search on phi keeps it a descent step where the tangent
        # changes within the step (stiffening springs, contact), which would otherwise chatter
        x0 = self.x[:nf].copy()
        phi0 = 0.5 * float(np.einsum("i,ij,ij->", self.mass_free, v0, v0)) + u0
        d = h * v1
        alpha = 1.0
        for _ in range(8):
            self.x[:nf] = x0 + alpha * d
            self._fel_valid = False
            self.elastic_forces()
            step = alpha * d
            kin = step - h * v0
            phi = (0.5 / (h * h)) * float(np.einsum("i,ij,ij->", self.mass_free, kin, kin)) \
                + (0.5 * self.gamma / h) * float(np.einsum("i,ij,ij->", self.mass_free, step, step)) \
                + float(self._fel_energies.sum())
            if phi <= phi0 + 1e-9 * abs(phi0) or not np.isfinite(phi):
                break
            alpha *= 0.5
        self.last_alpha = alpha
        self.v[:nf] = (self.x[:nf] - x0) / h
        self.energies[:] = self._fel_energies
        self._fel_valid = True  # the forces at the new positions serve the next step



def _bsr(data, imp) -> sp.bsr_matrix:
    nb = imp["indptr"].size - 1
    return sp.bsr_matrix((data, imp["indices"], imp["indptr"]), shape=(3 * nb, 3 * nb))


def _apply_numpy(data, imp, prisms, vscale, v) -> np.ndarray:
    nf = v.shape[0]
    out = _bsr(data, imp).dot(v.ravel()).reshape(nf, 3)
    G = imp["G"]
    free = prisms < nf
    vv = np.where(free[:, :, None], v[np.minimum(prisms, nf - 1)], 0.0)
    d = vscale * np.einsum("prk,prk->p", G, vv)
    contrib = d[:, None, None] * G
    for k in range(3):
        out[:, k] += np.bincount(prisms[free], weights=contrib[:, :, k][free], minlength=nf)[:nf]
    return out


def _cg_numpy(A, imp, prisms, vscale, pdiag, rhs, x0, tol, atol):
    from scipy.sparse.linalg import LinearOperator, cg

    nb = rhs.shape[0]
    op = LinearOperator((3 * nb, 3 * nb), matvec=lambda y: _apply_numpy(A, imp, prisms, vscale,
                                                                        y.reshape(nb, 3)).ravel())
    pinv = np.linalg.inv(A[imp["diag"]] + pdiag)
    prec = LinearOperator(op.shape, matvec=lambda r: np.einsum("nij,nj->ni", pinv, r.reshape(nb, 3)).ravel())
    it = [0]

    def count(_):
        it[0] += 1

    sol, _ = cg(op, rhs.ravel(), x0=x0.ravel(), rtol=tol, atol=atol, maxiter=2000, M=prec, callback=count)
    res = float(np.linalg.norm(rhs.ravel() - op.matvec(sol)) / max(np.linalg.norm(rhs), atol / tol, 1e-300))
    return sol.reshape(nb, 3), it[0], res


def _assemble_numpy(sim, hk: float = 1.0, hc: float = 0.0) -> None:
    """numpy version of :func:`usdface.tissue._kernels.assemble_stiffness` (``hk K + hc C``)."""
    imp = sim._implicit
    K = imp["K"]
    K[:] = 0.0
    x = sim.x
    nf = sim.n_free
    d = x[sim.sj] - x[sim.si]
    length = np.linalg.norm(d, axis=1)
    u = d / np.maximum(length, 1e-300)[:, None]
    f = sim.k * (length - sim.l0)
    fb, _, kbs = smooth_ramp(length - sim.lc, sim.kb, 0.5 * np.where(np.isfinite(sim.lc), sim.lc - sim.l0, 1.0))
    f = f + fb
    kk = sim.k + kbs
    t = np.where(f > 0, f / np.maximum(length, 1e-300), 0.0)
    uu = u[:, :, None] * u[:, None, :]
    blk = (hk * (kk - t) + hc * sim.cs)[:, None, None] * uu + (hk * t)[:, None, None] * np.eye(3)
    for key, sign in (("ii", 1.0), ("jj", 1.0), ("ij", -1.0), ("ji", -1.0)):
        s = imp[key]
        ok = s >= 0
        np.add.at(K, s[ok], sign * blk[ok])
    _, g = prism_volume_gradients(x, sim.prisms)
    imp["G"][:] = g
    Dv = imp["Dv"]
    Dv[:] = 0.0
    free = sim.prisms < nf
    outer = sim.model.volume_coef[:, None, None, None] * g[:, :, :, None] * g[:, :, None, :]
    np.add.at(Dv, sim.prisms[free], outer[free])
    n = sim.n
    if sim.k_skull > 0:
        s = np.einsum("ij,ij->i", x[n:2 * n] - x[2 * n:], sim.skull_normals)
        pen = np.flatnonzero(s < sim.skull_margin)
        _, _, ks = smooth_ramp(sim.skull_margin[pen] - s[pen], sim.k_skull, 0.5 * sim.skull_margin[pen])
        nn = sim.skull_normals[pen]
        np.add.at(K, imp["diag"][n + pen], ((hk + hc * sim.beta) * ks)[:, None, None] * nn[:, :, None] * nn[:, None, :])
    ms = sim.muscles
    if ms.nodes.size:
        dm = sim.anchors[ms.muscle] - x[ms.nodes]
        P = ms.metric[ms.muscle]
        pd = np.einsum("kij,kj->ki", P, dm)
        s2 = np.einsum("ij,ij->i", dm, pd) + sim.m_eps ** 2
        ok = sim.m_coef != 0
        g = hk * sim.m_coef[ok] / np.sqrt(s2[ok])
        blk = g[:, None, None] * (P[ok] - pd[ok, :, None] * pd[ok, None, :] / s2[ok, None, None])
        np.add.at(K, imp["diag"][ms.nodes[ok]], blk)
