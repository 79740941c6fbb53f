"""numba kernels of the tissue engine: the same forces as :mod:`usdface.tissue.forces`, fused.

Imported only when numba is available (:data:`AVAILABLE`); the simulator falls back to the numpy
kernels otherwise. Loops here run over springs/prisms inside compiled code (no Python per spring).
"""
from __future__ import annotations

import numpy as np

from ..numba_cache import AVAILABLE, njit  # the engine runs (slower) on numpy without it


#: energy slots of :func:`total_forces`
E_SPRING, E_VOLUME, E_SKULL, E_MUSCLE = 0, 1, 2, 3


@njit(cache=True, inline="always")
def smooth_ramp(pen, k, delta):  # pragma: no cover - compiled
    """(force, energy, stiffness) of a penalty ``k`` past 0 with a smoothed onset of width ``delta``.

    ``f = k pen^2 / (2 delta)`` up to ``delta``, then ``k (pen - delta/2)``: the stiffness rises
    continuously from 0 (kinks in the stiffness make implicit steps chatter).
    """
    if pen <= delta:
        return 0.5 * k * pen * pen / delta, k * pen * pen * pen / (6.0 * delta), k * pen / delta
    q = pen - 0.5 * delta
    return k * q, k * (delta * delta / 24.0 + 0.5 * q * q), k


@njit(cache=True, fastmath=True)
def spring_kernel(x, v, si, sj, l0, k, lc, kb, cs, F):  # pragma: no cover - compiled
    """Add spring forces into F; return the elastic energy.

    Biphasic part: :func:`smooth_ramp` of ``l - lc`` with stiffness ``kb`` and onset width
    ``(lc - l0) / 2``."""
    e = 0.0
    for s in range(si.shape[0]):
        i = si[s]
        j = sj[s]
        dx = x[j, 0] - x[i, 0]
        dy = x[j, 1] - x[i, 1]
        dz = x[j, 2] - x[i, 2]
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        inv = 1.0 / length if length > 1e-300 else 0.0
        ux = dx * inv
        uy = dy * inv
        uz = dz * inv
        ext = length - l0[s]
        f = k[s] * ext
        e += 0.5 * k[s] * ext * ext
        over = length - lc[s]
        if over > 0.0:
            fb, eb, _ = smooth_ramp(over, kb[s], 0.5 * (lc[s] - l0[s]))
            f += fb
            e += eb
        if cs[s] != 0.0:
            f += cs[s] * ((v[j, 0] - v[i, 0]) * ux + (v[j, 1] - v[i, 1]) * uy + (v[j, 2] - v[i, 2]) * uz)
        F[i, 0] += f * ux
        F[i, 1] += f * uy
        F[i, 2] += f * uz
        F[j, 0] -= f * ux
        F[j, 1] -= f * uy
        F[j, 2] -= f * uz
    return e


@njit(cache=True, fastmath=True)
def _tet_into(x, a, b, c, d, sign, g, ia, ib, ic, id_):  # pragma: no cover - compiled
    """Add sign * gradient of tet volume into g rows ia..id_; return sign * volume."""
    bax = x[b, 0] - x[a, 0]
    bay = x[b, 1] - x[a, 1]
    baz = x[b, 2] - x[a, 2]
    cax = x[c, 0] - x[a, 0]
    cay = x[c, 1] - x[a, 1]
    caz = x[c, 2] - x[a, 2]
    dax = x[d, 0] - x[a, 0]
    day = x[d, 1] - x[a, 1]
    daz = x[d, 2] - x[a, 2]
    # gd = (b-a)x(c-a)/6, gb = (c-a)x(d-a)/6, gc = (d-a)x(b-a)/6
    gdx = (bay * caz - baz * cay) / 6.0
    gdy = (baz * cax - bax * caz) / 6.0
    gdz = (bax * cay - bay * cax) / 6.0
    gbx = (cay * daz - caz * day) / 6.0
    gby = (caz * dax - cax * daz) / 6.0
    gbz = (cax * day - cay * dax) / 6.0
    gcx = (day * baz - daz * bay) / 6.0
    gcy = (daz * bax - dax * baz) / 6.0
    gcz = (dax * bay - day * bax) / 6.0
    vol = gdx * dax + gdy * day + gdz * daz
    g[ib, 0] += sign * gbx
    g[ib, 1] += sign * gby
    g[ib, 2] += sign * gbz
    g[ic, 0] += sign * gcx
    g[ic, 1] += sign * gcy
    g[ic, 2] += sign * gcz
    g[id_, 0] += sign * gdx
    g[id_, 1] += sign * gdy
    g[id_, 2] += sign * gdz
    g[ia, 0] -= sign * (gbx + gcx + gdx)
    g[ia, 1] -= sign * (gby + gcy + gdy)
    g[ia, 2] -= sign * (gbz + gcz + gdz)
    return sign * vol


@njit(cache=True, fastmath=True)
def prism_gradient(x, pr, g):  # pragma: no cover - compiled
    """Volume of prism ``pr`` (6 node indices) and its gradient written into g (6, 3)."""
    for r in range(6):
        g[r, 0] = 0.0
        g[r, 1] = 0.0
        g[r, 2] = 0.0
    vol = _tet_into(x, pr[0], pr[1], pr[2], pr[3], -1.0, g, 0, 1, 2, 3)
    vol += _tet_into(x, pr[1], pr[2], pr[3], pr[4], -1.0, g, 1, 2, 3, 4)
    vol += _tet_into(x, pr[2], pr[3], pr[4], pr[5], -1.0, g, 2, 3, 4, 5)
    return vol


@njit(cache=True, fastmath=True)
def volume_kernel(x, v, prisms, V0, coef, beta, F, vol_out):  # pragma: no cover - compiled
    """Add volume preservation forces into F, store volumes in vol_out; return the energy.

    Prism volume = -(T(a,b,c,a') + T(b,c,a',b') + T(c,a',b',c')), T the signed tet volume
    (see :func:`usdface.tissue.prisms.prism_volumes`). Force ``-c (V - V0 + beta dV/dt) grad V``:
    the ``beta`` term damps volume changes (stiffness-proportional, like the springs' axial damping).
    """
    e = 0.0
    g = np.empty((6, 3))
    for p in range(prisms.shape[0]):
        vol = prism_gradient(x, prisms[p], g)
        vol_out[p] = vol
        dv = vol - V0[p]
        e += 0.5 * coef[p] * dv * dv
        if beta != 0.0:
            rate = 0.0
            for r in range(6):
                n = prisms[p, r]
                rate += g[r, 0] * v[n, 0] + g[r, 1] * v[n, 1] + g[r, 2] * v[n, 2]
            dv += beta * rate
        s = -coef[p] * dv
        for r in range(6):
            n = prisms[p, r]
            F[n, 0] += s * g[r, 0]
            F[n, 1] += s * g[r, 1]
            F[n, 2] += s * g[r, 2]
    return e


@njit(cache=True)
def muscle_kernel(x, nodes, muscle, coef, anchors, metric, eps, F):  # pragma: no cover - compiled
    """Add muscle pulls toward each entry's anchor; return their energy.

    Energy ``coef sqrt(d^T P d + eps^2)``, ``d = x - anchor``, ``P`` the muscle's squeeze metric
    (identity for linear muscles): a pull of constant strength that fades within ``eps`` of the
    anchor instead of flipping direction there."""
    e = 0.0
    for q in range(nodes.shape[0]):
        c = coef[q]
        if c == 0.0:
            continue
        n = nodes[q]
        m = muscle[q]
        dx = anchors[m, 0] - x[n, 0]
        dy = anchors[m, 1] - x[n, 1]
        dz = anchors[m, 2] - x[n, 2]
        px = metric[m, 0, 0] * dx + metric[m, 0, 1] * dy + metric[m, 0, 2] * dz
        py = metric[m, 1, 0] * dx + metric[m, 1, 1] * dy + metric[m, 1, 2] * dz
        pz = metric[m, 2, 0] * dx + metric[m, 2, 1] * dy + metric[m, 2, 2] * dz
        s = np.sqrt(dx * px + dy * py + dz * pz + eps * eps)
        e += c * s
        g = c / s
        F[n, 0] += g * px
        F[n, 1] += g * py
        F[n, 2] += g * pz
    return e


@njit(cache=True)
def skull_kernel(x, v, n_vert, normals, margin, k_skull, beta, F):  # pragma: no cover - compiled
    """Skull penalty on penetrating fascia nodes (damped with ``beta`` times its stiffness)."""
    e = 0.0
    for i in range(n_vert):
        f = n_vert + i
        b = 2 * n_vert + i
        s = ((x[f, 0] - x[b, 0]) * normals[i, 0] + (x[f, 1] - x[b, 1]) * normals[i, 1]
             + (x[f, 2] - x[b, 2]) * normals[i, 2])
        pen = margin[i] - s
        if pen > 0.0:
            fs, es, ks = smooth_ramp(pen, k_skull, 0.5 * margin[i])
            e += es
            if beta != 0.0:
                rate = ((v[f, 0] - v[b, 0]) * normals[i, 0] + (v[f, 1] - v[b, 1]) * normals[i, 1]
                        + (v[f, 2] - v[b, 2]) * normals[i, 2])
                fs -= beta * ks * rate
            F[f, 0] += fs * normals[i, 0]
            F[f, 1] += fs * normals[i, 1]
            F[f, 2] += fs * normals[i, 2]
    return e


@njit(cache=True)
def total_forces(x, v, si, sj, l0, k, lc, kb, cs, prisms, V0, vcoef, m_nodes, m_muscle, m_coef, anchors, metric, m_eps,
                 n_vert, skull_normals, skull_margin, k_skull, gamma, beta, mass, n_free, F, vol_out,
                 energy):  # pragma: no cover
    """All forces of the model on the free nodes: F (n, 3) is overwritten; energy (4,) too."""
    F[:, :] = 0.0
    energy[E_SPRING] = spring_kernel(x, v, si, sj, l0, k, lc, kb, cs, F)
    energy[E_VOLUME] = volume_kernel(x, v, prisms, V0, vcoef, beta, F, vol_out)
    energy[E_MUSCLE] = muscle_kernel(x, m_nodes, m_muscle, m_coef, anchors, metric, m_eps, F)
    if k_skull > 0.0:
        energy[E_SKULL] = skull_kernel(x, v, n_vert, skull_normals, skull_margin, k_skull, beta, F)
    else:
        energy[E_SKULL] = 0.0
    if gamma != 0.0:
        for i in range(n_free):
            s = gamma * mass[i]
            F[i, 0] -= s * v[i, 0]
            F[i, 1] -= s * v[i, 1]
            F[i, 2] -= s * v[i, 2]


@njit(cache=True)
def explicit_update(x, v, F, inv_mass, h, n_free, symplectic):  # pragma: no cover - compiled
    """Forward Euler (x += h v_old; v += h a) or symplectic Euler (v += h a; x += h v_new)."""
    for i in range(n_free):
        w = h * inv_mass[i]
        for c in range(3):
            if symplectic:
                v[i, c] += w * F[i, c]
                x[i, c] += h * v[i, c]
            else:
                x[i, c] += h * v[i, c]
                v[i, c] += w * F[i, c]


# -- implicit Euler: block matrix assembly ---------------------------------------------------------

@njit(cache=True)
def _add_block(data, slot, s, ux, uy, uz, a, b):  # pragma: no cover - compiled
    """data[slot] += s * (a u u^T + b I) when slot >= 0."""
    if slot < 0:
        return
    u0 = ux
    u1 = uy
    u2 = uz
    data[slot, 0, 0] += s * (a * u0 * u0 + b)
    data[slot, 0, 1] += s * (a * u0 * u1)
    data[slot, 0, 2] += s * (a * u0 * u2)
    data[slot, 1, 0] += s * (a * u1 * u0)
    data[slot, 1, 1] += s * (a * u1 * u1 + b)
    data[slot, 1, 2] += s * (a * u1 * u2)
    data[slot, 2, 0] += s * (a * u2 * u0)
    data[slot, 2, 1] += s * (a * u2 * u1)
    data[slot, 2, 2] += s * (a * u2 * u2 + b)


@njit(cache=True)
def assemble_stiffness(x, si, sj, l0, k, lc, kb, cs, slot_ii, slot_jj, slot_ij, slot_ji, prisms, vcoef,
                       m_nodes, m_muscle, m_coef, anchors, metric, m_eps, n_vert, skull_normals, skull_margin,
                       k_skull, beta, hk, hc, diag_slot, K, G, Dv):  # pragma: no cover - compiled
    """``hk K + hc C`` as 3x3 blocks into K (zeroed here): the positive semi-definite tangent stiffness K
    and the damping C (``hk = 1, hc = 0`` gives K alone; the implicit step uses ``h^2, h``).

    Springs: ``k_eff u u^T + max(0, f / l) (I - u u^T)`` (the compressive transverse term is
    dropped so the matrix stays positive semi-definite); skull: ``k_s n n^T`` on penetrating
    nodes; muscles: ``coef / d (I - u u^T)``. Volume: the Gauss-Newton term
    ``c_p grad V grad V^T`` is not stored; its gradients go to G (P, 6, 3) for
    :func:`apply_matrix` and its diagonal blocks to Dv (n_free, 3, 3) (for the preconditioner).
    """
    K[:, :, :] = 0.0
    for s in range(si.shape[0]):
        i = si[s]
        j = sj[s]
        dx = x[j, 0] - x[i, 0]
        dy = x[j, 1] - x[i, 1]
        dz = x[j, 2] - x[i, 2]
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        inv = 1.0 / length if length > 1e-300 else 0.0
        ux = dx * inv
        uy = dy * inv
        uz = dz * inv
        f = k[s] * (length - l0[s])
        kk = k[s]
        over = length - lc[s]
        if over > 0.0:
            fb, eb, kbs = smooth_ramp(over, kb[s], 0.5 * (lc[s] - l0[s]))
            f += fb
            kk += kbs
        t = f * inv if f > 0.0 else 0.0
        a = hk * (kk - t) + hc * cs[s]
        t *= hk
        _add_block(K, slot_ii[s], 1.0, ux, uy, uz, a, t)
        _add_block(K, slot_jj[s], 1.0, ux, uy, uz, a, t)
        _add_block(K, slot_ij[s], -1.0, ux, uy, uz, a, t)
        _add_block(K, slot_ji[s], -1.0, ux, uy, uz, a, t)
    # volume: the rank-one Gauss-Newton term c_p g g^T is applied matrix-free (apply_matrix);
    # keep the gradients, and put its diagonal blocks in D for the preconditioner
    Dv[:, :, :] = 0.0
    for p in range(prisms.shape[0]):
        g = G[p]
        prism_gradient(x, prisms[p], g)
        c = vcoef[p]
        for r in range(6):
            n = prisms[p, r]
            if n >= diag_slot.shape[0]:
                continue
            for a0 in range(3):
                for b0 in range(3):
                    Dv[n, a0, b0] += c * g[r, a0] * g[r, b0]
    if k_skull > 0.0:
        for i in range(n_vert):
            f = n_vert + i
            b = 2 * n_vert + i
            s = ((x[f, 0] - x[b, 0]) * skull_normals[i, 0] + (x[f, 1] - x[b, 1]) * skull_normals[i, 1]
                 + (x[f, 2] - x[b, 2]) * skull_normals[i, 2])
            pen = skull_margin[i] - s
            if pen > 0.0:
                fs, es, ks = smooth_ramp(pen, k_skull, 0.5 * skull_margin[i])
                _add_block(K, diag_slot[f], (hk + hc * beta) * ks, skull_normals[i, 0], skull_normals[i, 1],
                           skull_normals[i, 2], 1.0, 0.0)
    for q in range(m_nodes.shape[0]):
        c = m_coef[q]
        if c == 0.0:
            continue
        n = m_nodes[q]
        m = m_muscle[q]
        dx = anchors[m, 0] - x[n, 0]
        dy = anchors[m, 1] - x[n, 1]
        dz = anchors[m, 2] - x[n, 2]
        # Hessian of c sqrt(d^T P d + eps^2): c / s (P - (P d)(P d)^T / s^2)
        px = metric[m, 0, 0] * dx + metric[m, 0, 1] * dy + metric[m, 0, 2] * dz
        py = metric[m, 1, 0] * dx + metric[m, 1, 1] * dy + metric[m, 1, 2] * dz
        pz = metric[m, 2, 0] * dx + metric[m, 2, 1] * dy + metric[m, 2, 2] * dz
        slot = diag_slot[n]
        s2 = dx * px + dy * py + dz * pz + m_eps * m_eps
        g = hk * c / np.sqrt(s2)
        pv = (px, py, pz)
        for a0 in range(3):
            for b0 in range(3):
                K[slot, a0, b0] += g * (metric[m, a0, b0] - pv[a0] * pv[b0] / s2)


@njit(cache=True)
def bsr_matvec(data, indices, indptr, xin, out):  # pragma: no cover - compiled
    """out = A @ xin for a block-CSR matrix of 3x3 blocks; xin, out (nb, 3)."""
    for r in range(indptr.shape[0] - 1):
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        for q in range(indptr[r], indptr[r + 1]):
            c = indices[q]
            b = data[q]
            x0 = xin[c, 0]
            x1 = xin[c, 1]
            x2 = xin[c, 2]
            s0 += b[0, 0] * x0 + b[0, 1] * x1 + b[0, 2] * x2
            s1 += b[1, 0] * x0 + b[1, 1] * x1 + b[1, 2] * x2
            s2 += b[2, 0] * x0 + b[2, 1] * x1 + b[2, 2] * x2
        out[r, 0] = s0
        out[r, 1] = s1
        out[r, 2] = s2


@njit(cache=True, inline="always")
def _inv3(a, out):  # pragma: no cover - compiled
    """Inverse of a 3x3 matrix by cofactors (the diagonal blocks are symmetric positive definite)."""
    c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    c01 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    c02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
    inv = 1.0 / det
    out[0, 0] = c00 * inv
    out[1, 0] = c01 * inv
    out[2, 0] = c02 * inv
    out[0, 1] = (a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]) * inv
    out[1, 1] = (a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]) * inv
    out[2, 1] = (a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]) * inv
    out[0, 2] = (a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]) * inv
    out[1, 2] = (a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]) * inv
    out[2, 2] = (a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]) * inv


@njit(cache=True)
def apply_matrix(data, indices, indptr, G, prisms, vscale, xin, out):  # pragma: no cover - compiled
    """out = (A + sum_p vscale_p g_p g_p^T) xin: block-CSR part plus the matrix-free volume term."""
    bsr_matvec(data, indices, indptr, xin, out)
    nf = xin.shape[0]
    for p in range(prisms.shape[0]):
        c = vscale[p]
        if c == 0.0:
            continue
        d = 0.0
        for r in range(6):
            n = prisms[p, r]
            if n < nf:
                d += G[p, r, 0] * xin[n, 0] + G[p, r, 1] * xin[n, 1] + G[p, r, 2] * xin[n, 2]
        d *= c
        for r in range(6):
            n = prisms[p, r]
            if n < nf:
                out[n, 0] += d * G[p, r, 0]
                out[n, 1] += d * G[p, r, 1]
                out[n, 2] += d * G[p, r, 2]


@njit(cache=True, inline="always")
def _dot(a, b):  # pragma: no cover - compiled
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i, 0] * b[i, 0] + a[i, 1] * b[i, 1] + a[i, 2] * b[i, 2]
    return s


@njit(cache=True, inline="always")
def _precond(pinv, r_, z):  # pragma: no cover - compiled
    for i in range(r_.shape[0]):
        for a in range(3):
            z[i, a] = pinv[i, a, 0] * r_[i, 0] + pinv[i, a, 1] * r_[i, 1] + pinv[i, a, 2] * r_[i, 2]


@njit(cache=True)
def block_cg(data, indices, indptr, diag_slot, G, prisms, vscale, pdiag, rhs, x0, rtol, atol, max_iter):  # pragma: no cover
    """Conjugate gradients on ``A + sum_p vscale_p g_p g_p^T`` (symmetric positive definite),
    block-Jacobi preconditioned with ``A``'s diagonal blocks plus ``pdiag``.

    Stops when the residual is below ``rtol |rhs|`` or ``atol``. Returns (solution, iterations,
    residual relative to ``max(|rhs|, atol / rtol)``).
    """
    nb = rhs.shape[0]
    pinv = np.empty((nb, 3, 3))
    blk = np.empty((3, 3))
    for r in range(nb):
        for a in range(3):
            for b in range(3):
                blk[a, b] = data[diag_slot[r], a, b] + pdiag[r, a, b]
        _inv3(blk, pinv[r])
    x = x0.copy()
    ax = np.empty_like(rhs)
    apply_matrix(data, indices, indptr, G, prisms, vscale, x, ax)
    r_ = rhs - ax
    z = np.empty_like(rhs)
    _precond(pinv, r_, z)
    p = z.copy()
    rz = _dot(r_, z)
    bnorm = max(np.sqrt(_dot(rhs, rhs)), atol / rtol)
    if bnorm == 0.0:
        return x, 0, 0.0
    it = 0
    res = np.sqrt(_dot(r_, r_)) / bnorm
    ap = np.empty_like(rhs)
    while res > rtol and it < max_iter:
        apply_matrix(data, indices, indptr, G, prisms, vscale, p, ap)
        pap = _dot(p, ap)
        if pap <= 0.0:
            break
        alpha = rz / pap
        rr = 0.0
        for i in range(nb):
            for a in range(3):
                x[i, a] += alpha * p[i, a]
                r_[i, a] -= alpha * ap[i, a]
                rr += r_[i, a] * r_[i, a]
        _precond(pinv, r_, z)
        rz_new = _dot(r_, z)
        beta = rz_new / rz
        for i in range(nb):
            for a in range(3):
                p[i, a] = z[i, a] + beta * p[i, a]
        rz = rz_new
        it += 1
        res = np.sqrt(rr) / bnorm
    return x, it, res
