"""Forces of the layered tissue model (seed 001 §5.2), as pure numpy kernels.

Every force here is the negative gradient of an energy (damping aside), so the total energy of a
damped simulation with fixed contractions can only fall: the stability tests rely on that.

- springs (optionally biphasic, Lee-Terzopoulos-Waters 1995): ``f = k (l - l0) + k_b r(l - l_c)``
  along the spring, ``l_c = l0 (1 + strain_c)``, ``k_b = k (factor - 1)``, ``r`` the ramp
  ``(l - l_c)_+`` with its corner rounded over ``(l_c - l0) / 2`` (:func:`smooth_ramp`);
- damping: node damping ``-gamma m v`` and axial spring damping ``-c ((v_i - v_j) . u) u``;
- volume preservation per prism, proportional to its volume change: ``f = -c_p (V - V0) dV/dx``
  (energy ``c_p (V - V0)^2 / 2``);
- skull non-penetration: a fascia node closer than ``margin`` to its bone node's tangent plane
  is pushed out along the skull normal ``n`` by a smoothed penalty of the penetration
  ``margin - s``, ``s = (x_f - x_b) . n`` (:func:`smooth_ramp`);
- muscles on fascia nodes: ``f = a F w u``, ``u`` the unit vector toward the muscle's anchor
  (origin of a linear muscle, centre of a sphincter), ``d = x - anchor``; energy
  ``a F w sqrt(d^T P d + eps^2)`` with ``P`` the identity for linear muscles and the squeeze
  metric of a sphincter (its pull acts in its plane, mostly along its long axis)
  (:mod:`usdface.tissue.muscles` computes the weights ``w``).

These are the reference implementation (vectorised, sparse incidence gather/scatter); the
simulator uses the equivalent numba kernels of :mod:`usdface.tissue._kernels` when numba is
installed. Shapes: ``n`` nodes, ``S`` springs, ``P`` prisms, ``K`` muscle entries, ``M``
muscles. Lengths in mesh units, forces in model force units.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def incidence(springs: np.ndarray, n_nodes: int) -> sp.csr_matrix:
    """(S, n) signed incidence: row s has -1 at spring s's first node and +1 at its second.

    ``D @ x`` gives the spring vectors ``x_j - x_i``; ``D.T @ f`` scatters per-spring forces
    ``f`` (acting on the second node) back onto the nodes.
    """
    s = np.asarray(springs)
    rows = np.repeat(np.arange(s.shape[0]), 2)
    cols = s.ravel()
    vals = np.tile([-1.0, 1.0], s.shape[0])
    return sp.csr_matrix((vals, (rows, cols)), shape=(s.shape[0], n_nodes))


def spring_forces(x, v, springs, rest_length, stiffness, *, biphasic_strain=None, biphasic_factor=1.0,
                  damping=0.0, D=None):
    """Spring forces on all nodes.

    Parameters
    ----------
    x, v : ndarray (n, 3)
        Node positions (mesh units) and velocities (mesh units / s).
    springs : ndarray (S, 2) int
    rest_length : ndarray (S,)
    stiffness : ndarray (S,)
        Force per mesh unit of extension.
    biphasic_strain : float or None
        Tension strain past which the spring stiffens to ``biphasic_factor * stiffness``.
    damping : float
        Axial damping as a fraction of stiffness (s).
    D : scipy.sparse matrix (S, n), optional
        :func:`incidence` of ``springs`` (built when not given).

    Returns
    -------
    F : ndarray (n, 3)
    energy : float
        Elastic energy (force units x mesh units).
    """
    if D is None:
        D = incidence(springs, x.shape[0])
    d = D @ x
    length = np.sqrt(np.einsum("ij,ij->i", d, d))
    u = d / np.maximum(length, 1e-300)[:, None]
    ext = length - rest_length
    f = stiffness * ext
    energy = 0.5 * np.dot(stiffness, ext * ext)
    if biphasic_strain is not None and biphasic_factor != 1.0:
        over = length - rest_length * (1.0 + biphasic_strain)
        kb = stiffness * (biphasic_factor - 1.0)
        fb, eb, _ = smooth_ramp(over, kb, 0.5 * biphasic_strain * rest_length)
        f = f + fb
        energy += float(eb.sum())
    if damping:
        dv = D @ v
        f = f + damping * stiffness * np.einsum("ij,ij->i", dv, u)
    # f > 0 pulls the ends together: +f u on the first node, -f u on the second
    return -(D.T @ (f[:, None] * u)), float(energy)


def _tet_grads(a, b, c, d):
    """Volume (1/6) (b-a)x(c-a).(d-a) and its gradients w.r.t. a, b, c, d."""
    gd = np.cross(b - a, c - a) / 6.0
    gb = np.cross(c - a, d - a) / 6.0
    gc = np.cross(d - a, b - a) / 6.0
    ga = -(gb + gc + gd)
    vol = np.einsum("ij,ij->i", gd, d - a)
    return vol, ga, gb, gc, gd


def prism_volume_gradients(x, prisms):
    """Prism volumes and their gradients (three-tetrahedron split, see :func:`~usdface.tissue.prisms.prism_volumes`).

    Parameters
    ----------
    x : ndarray (n, 3)
    prisms : ndarray (P, 6) int

    Returns
    -------
    volume : ndarray (P,)
    grad : ndarray (P, 6, 3)
        dV/dx of each of the prism's six nodes.
    """
    p = [x[prisms[:, k]] for k in range(6)]
    grad = np.zeros((prisms.shape[0], 6, 3))
    vol = np.zeros(prisms.shape[0])
    for nodes in ((0, 1, 2, 3), (1, 2, 3, 4), (2, 3, 4, 5)):
        v, *g = _tet_grads(*(p[k] for k in nodes))
        vol -= v
        for k, gk in zip(nodes, g):
            grad[:, k] -= gk
    return vol, grad


def volume_forces(x, prisms, rest_volume, coef, *, v=None, damping=0.0):
    """Volume preservation forces ``-c_p (V - V0) dV/dx`` per prism (seed 001 §5.2).

    Parameters
    ----------
    x : ndarray (n, 3)
    prisms : ndarray (P, 6) int
    rest_volume, coef : ndarray (P,)
    v : ndarray (n, 3), optional
        Velocities, for the damping term.
    damping : float
        ``beta`` (s): the force becomes ``-c_p (V - V0 + beta dV/dt) dV/dx`` (volume changes are
        damped in proportion to their stiffness, like the springs' axial damping).

    Returns
    -------
    F : ndarray (n, 3)
    energy : float
        ``sum c_p (V - V0)^2 / 2``.
    volume : ndarray (P,)
        Current volumes.
    """
    vol, grad = prism_volume_gradients(x, prisms)
    dv = vol - rest_volume
    e = float(0.5 * np.dot(coef, dv * dv))
    if damping and v is not None:
        dv = dv + damping * np.einsum("prk,prk->p", grad, v[prisms])
    contrib = -(coef * dv)[:, None, None] * grad
    F = np.zeros_like(x)
    for k in range(3):
        F[:, k] = np.bincount(prisms.ravel(), weights=contrib[:, :, k].ravel(), minlength=x.shape[0])
    return F, e, vol


def muscle_forces(x, nodes, muscle, coef, anchors, metric=None, eps=0.0):
    """Muscle forces on fascia nodes: ``coef`` times the unit vector toward the muscle's anchor.

    Parameters
    ----------
    x : ndarray (n, 3)
    nodes : ndarray (K,) int
        Node of each muscle entry.
    muscle : ndarray (K,) int
        Muscle of each entry.
    coef : ndarray (K,)
        Contraction x force x weight of each entry (force units).
    anchors : ndarray (M, 3)
        Current anchor point of each muscle (linear: origin; sphincter: centre).
    metric : ndarray (M, 3, 3), optional
        Squeeze metric ``P`` of each muscle (symmetric positive semi-definite; identity for
        linear muscles, the default): the energy is ``coef sqrt(d^T P d + eps^2)`` with
        ``d = x - anchor``, the force ``-coef P d / sqrt(d^T P d + eps^2)``.
    eps : float
        Softening length: the pull fades within about ``eps`` of the anchor instead of flipping
        direction there.

    Returns
    -------
    F : ndarray (n, 3)
    energy : float
        ``sum coef |x - anchor|`` (the forces are its negative gradient).
    """
    d = anchors[muscle] - x[nodes]
    pd = d if metric is None else np.einsum("kij,kj->ki", metric[muscle], d)
    dist = np.sqrt(np.einsum("ij,ij->i", d, pd) + eps * eps)
    F = np.zeros_like(x)
    for k in range(3):
        F[:, k] = np.bincount(nodes, weights=coef * pd[:, k] / dist, minlength=x.shape[0])
    return F, float(np.dot(coef, dist))


def smooth_ramp(pen, k, delta):
    """A penalty of stiffness ``k`` past 0 with a smoothed onset: force ``k pen^2 / (2 delta)`` up to
    ``delta``, then ``k (pen - delta / 2)``; (force, energy, stiffness) element-wise, zero for
    ``pen <= 0``. The stiffness rises continuously (a kink would make implicit steps chatter)."""
    pen = np.asarray(pen, dtype=np.float64)
    delta = np.broadcast_to(np.asarray(delta, dtype=np.float64), pen.shape)
    small = pen <= delta
    q = pen - 0.5 * delta
    f = np.where(small, 0.5 * k * pen ** 2 / delta, k * q)
    e = np.where(small, k * pen ** 3 / (6.0 * delta), k * (delta ** 2 / 24.0 + 0.5 * q * q))
    kk = np.where(small, k * pen / delta, k)
    zero = pen <= 0
    return np.where(zero, 0.0, f), np.where(zero, 0.0, e), np.where(zero, 0.0, kk)


def skull_forces(x_fascia, x_bone, normals, margin, k_skull, *, v_fascia=None, v_bone=None, damping=0.0):
    """Skull non-penetration penalty on fascia nodes.

    A fascia node closer than ``margin`` to its bone node's tangent plane (``s < margin``,
    ``s = (x_f - x_b) . n``) is pushed out along ``n`` with :func:`smooth_ramp` of the
    penetration ``margin - s`` (smoothing length ``margin / 2``).

    Parameters
    ----------
    x_fascia, x_bone : ndarray (N, 3)
        Fascia nodes and the bone nodes below them.
    normals : ndarray (N, 3)
        Outward skull normal at each bone node (unit).
    margin : ndarray (N,)
        Distance the fascia node must keep above the bone node's tangent plane.
    k_skull : float
        Penalty stiffness (force per mesh unit).
    v_fascia, v_bone : ndarray (N, 3), optional
        Velocities, for the damping term ``-damping * stiffness * (n . (v_f - v_b))`` in contact.

    Returns
    -------
    F : ndarray (N, 3)
        Forces on the fascia nodes.
    energy : float
    """
    s = np.einsum("ij,ij->i", x_fascia - x_bone, normals)
    f, e, ks = smooth_ramp(np.maximum(margin - s, 0.0), k_skull, 0.5 * margin)
    if damping and v_fascia is not None:
        f = f - damping * ks * np.einsum("ij,ij->i", v_fascia - v_bone, normals)
    return f[:, None] * normals, float(e.sum())
