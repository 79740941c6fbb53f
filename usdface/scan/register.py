"""Registration of a generic face model onto a scan (seed 001, section 4.2).

"Radial Basis Functions are then used to interpolate the generic model to the raw data, and
finally, vertices of the generic model are moved closer towards the raw data surface by
considering their closest points." Three stages, keeping the generic topology:

1. **Similarity** (Umeyama): rotation, uniform scale and translation of the generic landmarks
   onto the scan landmarks.
2. **RBF warp**: a 3-D thin-plate spline with an affine term (:class:`usdface.scan.warp.ThinPlateSpline`,
   ``phi(r) = r``) interpolating the landmark correspondences moves every generic vertex.
3. **Closest-point projection** (iterated): each vertex is pulled toward its closest point on the
   scan (:class:`usdface.mesh.closest.SurfaceLocator`), along the scan normal (point-to-plane)
   plus a little point-to-point, keeping only pairs whose normals agree (angle below
   ``max_normal_angle``), whose distance is plausible (below ``max_distance_factor`` times the
   median) and whose closest point is not on the scan's border or a hole edge. A smoothness term
   keeps the Laplacian (the local shape) of the warped generic mesh, and the landmarks stay
   soft-pinned to the scan landmarks. The generic's eye and mouth holes (and ``hole_rings`` rings
   of vertices around them) get no data term: they follow their neighbours. The stiffness
   decreases over the iterations (coarse to fine). Each iteration is one sparse least-squares
   solve:

   ``min_X  sum_i w_i [ n_i . (x_i - c_i) ]^2 + mu w_i |x_i - c_i|^2
            + alpha |L X - L X_rbf|^2 + beta sum_l |x(l) - s_l|^2``

   with the point-to-plane term linearised as a pull toward the foot of the current position on
   the scan's tangent plane, so x, y and z share one sparse N x N factorisation per iteration.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..errors import ComputeError, InputError, MeshError, list_names
from .closest_points import NearSurface, closest_on_segments
from .mesh_operators import (boundary_edge_flags, boundary_segments, boundary_vertex_mask, farthest_points,
                             hole_vertices, uniform_laplacian, vertex_normals)
from .similarity import apply_similarity, similarity_fit

__all__ = ["similarity_fit", "apply_similarity", "GenericRegistration", "RegistrationParameters", "RegistrationResult",
           "register_generic", "hole_vertices", "boundary_vertex_mask", "HOLE_RINGS"]

#: rings of vertices around the eye and mouth holes also left without a data term
HOLE_RINGS = 1


@dataclass(frozen=True)
class RegistrationParameters:
    """How :meth:`GenericRegistration.register` registers the generic onto a scan.

    Attributes
    ----------
    iterations : int
        Closest-point iterations (0: stop after the RBF warp).
    stiffness : (start, end)
        Weight ``alpha`` of the Laplacian term, decreased geometrically over the iterations,
        relative to the data term (per vertex).
    landmark_weight : float
        ``beta`` per landmark, relative to one vertex's data term.
    point_weight : float
        ``mu``: point-to-point share added to point-to-plane.
    max_normal_angle : float
        Degrees; pairs whose normals differ more are dropped.
    max_distance_factor : float
        Pairs farther than this times the median pair distance are dropped (and never closer
        than ``min_distance``, default 1% of the scan's diagonal).
    rbf_smoothing : float
        Ridge of the thin-plate warp (0 = exact at the landmarks).
    border_weight : float
        When > 0, the generic's outer-border vertices are also pulled (point to point, this
        weight) to their closest point on the scan's boundary: for scans cropped like the
        generic (a mesh of another face, a scan trimmed to the face mask). Leave 0 for raw
        scans whose outline is hair, ears or the image border.
    coverage_weight : float
        When > 0, adds the reverse pairs: up to ``coverage_samples`` scan vertices each pull
        their closest point on the generic surface (point to point, this weight per pair,
        scaled by generic vertices / samples), so the generic covers all of the scan. Same
        caveat as ``border_weight`` (measured: no help on the sample faces).
    laplacian_reference : str
        Whose local shape the smoothness term keeps: ``"rbf"`` (the warped generic, default)
        or ``"similarity"`` (the generic only moved rigidly and scaled).
    field_iterations : int
        Iterations of the smooth-field stage between the thin-plate warp and the projection: a
        global displacement (Gaussian RBF on ``field_centres`` farthest-point centres of width
        ``field_width`` times the landmarks' diagonal, plus an affine part, ridge
        ``field_smoothing``) fitted to point-to-plane closest-point constraints, the landmarks
        and (with ``border_weight``) the border. A global smooth field turns the normal offsets
        seen on differently oriented parts of the face into the tangential motion between them.
        0 (default) skips it; it pays off with ``border_weight`` on cropped scans.
    field_centres, field_width, field_smoothing :
        See ``field_iterations``.
    """

    iterations: int = 20
    stiffness: tuple = (10.0, 0.5)
    landmark_weight: float = 1.0
    point_weight: float = 0.1
    max_normal_angle: float = 60.0
    max_distance_factor: float = 3.0
    min_distance: float | None = None
    rbf_smoothing: float = 0.0
    border_weight: float = 0.0
    coverage_weight: float = 0.0
    coverage_samples: int = 20000
    laplacian_reference: str = "rbf"
    field_iterations: int = 0
    field_centres: int = 100
    field_width: float = 0.5
    field_smoothing: float = 3e-3


@dataclass(frozen=True, eq=False)
class _Scan:
    """The scan as the registration queries it, built once per scan: points, triangles, vertex
    normals, boundary edges, the exact locator, a k-d tree of its vertices and its longest edge
    (to skip hopeless closest-point searches), and the fast approximate search on dense scans."""

    points: np.ndarray
    triangles: np.ndarray
    normals: np.ndarray
    edge_flags: np.ndarray
    locator: object
    near: tuple
    fast: object
    diagonal: float

    @classmethod
    def build(cls, points, triangles, locator, *, dense: bool) -> "_Scan":
        from scipy.spatial import cKDTree

        from ..mesh.closest import SurfaceLocator

        S = np.asarray(points, dtype=np.float64)
        F = np.asarray(triangles, dtype=np.int64)
        e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
        tree = cKDTree(S)
        return cls(points=S, triangles=F, normals=vertex_normals(S, F), edge_flags=boundary_edge_flags(F),
                   locator=locator or SurfaceLocator(S, F),
                   near=(tree, float(np.linalg.norm(S[e[:, 0]] - S[e[:, 1]], axis=1).max())),
                   fast=NearSurface(S, F, tree) if dense else None,
                   diagonal=float(np.linalg.norm(np.ptp(S, axis=0))))


@dataclass(frozen=True)
class _PairRule:
    """Which closest-point pairs are kept: normals within ``cos_max``, distance within ``factor``
    times the median (never below ``min_d``)."""

    cos_max: float
    factor: float
    min_d: float


@dataclass(frozen=True, eq=False)
class RegistrationResult:
    """Result of :meth:`GenericRegistration.register`.

    Attributes
    ----------
    points : ndarray, shape (N, 3)
        Registered generic vertices (scan space and units).
    similarity_points, rbf_points : ndarray, shape (N, 3)
        After stage 1 and after stage 2.
    similarity : (s, R, t)
    landmark_residuals : ndarray, shape (M,)
        Distance of each registered generic landmark to its scan landmark.
    surface_distance : ndarray, shape (N,)
        Final distance of each vertex to the scan surface (NaN for vertices without a data term).
    data_vertices : ndarray, shape (N,), bool
        Vertices with an accepted closest-point pair in the last iteration.
    info : dict
    """

    points: np.ndarray
    similarity_points: np.ndarray
    rbf_points: np.ndarray
    similarity: tuple
    landmark_residuals: np.ndarray
    surface_distance: np.ndarray
    data_vertices: np.ndarray
    info: dict = field(default_factory=dict)

    def warp_points(self, generic_points, points) -> np.ndarray:
        """Carry other 3-D points of the generic model (e.g. muscle origins and insertions of a
        rig) along: a thin-plate spline of the final vertex displacement, sampled on a subset of
        vertices."""
        from .warp import ThinPlateSpline

        g = np.asarray(generic_points, dtype=np.float64)
        k = max(1, g.shape[0] // 400)
        idx = np.arange(0, g.shape[0], k)
        tps = ThinPlateSpline(g[idx], self.points[idx], smoothing=1e-6)
        return tps(np.asarray(points, dtype=np.float64))


class GenericRegistration:
    """Register a generic face mesh onto scans (set up once, register many scans).

    Parameters
    ----------
    mesh : FaceMesh
        The generic face (its polygons are triangulated for the computation; vertex order kept).
    regions : list of Region
        Its regions; ``eye`` and ``mouth`` roles mark the holes excluded from the data term.
    landmarks : ndarray, shape (M, 3)
        Generic landmarks (mesh units), any points near the surface; they are attached to the
        surface (closest point) so they move with it.
    hole_rings : int
        Rings of vertices around the eye and mouth holes also excluded from the data term.

    Examples
    --------
    >>> reg = GenericRegistration(mesh, regions, landmarks)                   # doctest: +SKIP
    >>> res = reg.register(scan_points, scan_triangles, scan_landmarks)        # doctest: +SKIP
    """

    def __init__(self, mesh, regions, landmarks, *, hole_rings: int = HOLE_RINGS):
        from ..mesh.closest import SurfaceLocator

        if not regions:
            raise MeshError(f"generic mesh {mesh.source or mesh.name} has no regions: registration needs its eye and "
                            "mouth hole regions (import it with `usdface import-mesh`, which finds them)")
        roles = {r.role for r in regions}
        if not ({"eye", "mouth"} & roles):
            raise MeshError(f"generic mesh {mesh.source or mesh.name}: no eye or mouth region among "
                            f"{list_names(r.name for r in regions)}; registration excludes those holes")
        lm = np.asarray(landmarks, dtype=np.float64)
        if lm.ndim != 2 or lm.shape[1] != 3 or len(lm) < 4:
            raise InputError(f"generic landmarks must be (M >= 4, 3); got {lm.shape}")
        self.mesh = mesh
        self.regions = regions
        self.triangles = mesh.triangles()
        self.n = mesh.n_points
        loc = SurfaceLocator(mesh.points, self.triangles)
        self.lm_tri, self.lm_bary, _, self.lm_dist = loc.closest(lm)
        self.landmarks = lm
        self.excluded = hole_vertices(mesh, regions, rings=hole_rings)
        self.L = uniform_laplacian(self.n, self.triangles)
        used = np.zeros(self.n, bool)
        used[self.triangles.ravel()] = True
        self.excluded |= ~used
        # landmark rows: x(l) = sum_k bary_k x_{tri_k}
        rows = np.repeat(np.arange(len(lm)), 3)
        cols = self.triangles[self.lm_tri].ravel()
        self.B = sp.coo_matrix((self.lm_bary.ravel(), (rows, cols)), shape=(len(lm), self.n)).tocsr()

    def _pairs(self, X, scan: _Scan, rule: _PairRule, locator):
        """Accepted closest-point pairs: (vertex indices, closest points, scan normals, median distance).

        Vertices whose nearest scan vertex is farther than ``rule.factor`` times the median of those
        distances (and ``rule.min_d``) plus the scan's longest edge cannot have an accepted pair, so
        the exact (and, far from the surface, costly) closest-point search of ``locator`` skips them.
        """
        cand = np.flatnonzero(~self.excluded)
        tree, longest = scan.near
        dv, _ = tree.query(X[cand])
        cand = cand[dv <= max(rule.factor * float(np.median(dv)), rule.min_d) + longest]
        tri, bary, cp, dist = locator.closest(X[cand])
        on_edge = (scan.edge_flags[tri] & (bary < 1e-9)).any(axis=1)  # over the scan's border or a hole
        cn = np.einsum("kj,kjd->kd", bary, scan.normals[scan.triangles[tri]])
        cn /= np.maximum(np.linalg.norm(cn, axis=1, keepdims=True), 1e-300)
        gn = vertex_normals(X, self.triangles)[cand]
        ok = ~on_edge & (np.einsum("ij,ij->i", cn, gn) >= rule.cos_max)
        if ok.sum() < 10:
            raise ComputeError(f"registration: only {int(ok.sum())} generic vertices found a compatible scan "
                               "point (check the landmarks and the scan's units and orientation)")
        med = float(np.median(dist[ok]))
        ok &= dist <= max(rule.factor * med, rule.min_d)
        return cand[ok], cp[ok], cn[ok], med

    def _border(self, scan: _Scan, weight: float):
        """(generic outer-border vertices, scan boundary segment ends a, b) when ``weight`` > 0 and
        both exist, else empty."""
        none = np.zeros(0, np.int64)
        if weight <= 0:
            return none, None, None
        idx = np.unique(np.concatenate([r.indices for r in self.regions if r.role == "outerBorder"] or [none]))
        seg = boundary_segments(scan.triangles, scan.edge_flags)
        if not (idx.size and len(seg)):
            return none, None, None
        return idx, scan.points[seg[:, 0]], scan.points[seg[:, 1]]

    def _smooth_field(self, X0, sl, scan: _Scan, rule: _PairRule, params: RegistrationParameters):
        """Stage 2b: a smooth displacement field (Gaussian RBF on ``params.field_centres`` farthest
        points plus an affine part) fitted to point-to-plane closest-point constraints, the
        landmarks and (with ``border_weight``) the border, iterated ``params.field_iterations`` times.

        Unlike the per-vertex projection, a global smooth field turns the normal offsets seen on
        differently oriented parts of the face into the tangential motion between them."""
        landmark_weight = 100.0 * params.landmark_weight
        C = X0[farthest_points(X0, params.field_centres)]
        sig = params.field_width * float(np.linalg.norm(np.ptp(sl, axis=0)))
        r = np.linalg.norm(X0[:, None, :] - C[None, :, :], axis=2)
        Bv = np.hstack([np.exp(-(r / sig) ** 2), X0, np.ones((len(X0), 1))])  # (N, M + 4)
        nb = Bv.shape[1]
        m = C.shape[0]
        Blm = self.B @ Bv
        coef = np.zeros((nb, 3))
        coef[m:m + 3] = np.eye(3)
        X = X0
        border, seg_a, seg_b = self._border(scan, params.border_weight)
        for _ in range(params.field_iterations):
            idx, cp, nrm, _ = self._pairs(X, scan, rule, scan.locator)
            Bd = Bv[idx]
            A1 = np.hstack([Bd * nrm[:, 0:1], Bd * nrm[:, 1:2], Bd * nrm[:, 2:3]])  # (K, 3 nb)
            b1 = np.einsum("ij,ij->i", nrm, cp)
            H = A1.T @ A1
            g = A1.T @ b1
            if border.size:
                bp, bd = closest_on_segments(X[border], seg_a, seg_b)
                keep = bd <= max(rule.factor * float(np.median(bd)), rule.min_d)
                Kb = np.kron(np.eye(3), Bv[border[keep]])
                H += params.border_weight * Kb.T @ Kb
                g += params.border_weight * Kb.T @ bp[keep].T.ravel()
            Lk = np.kron(np.eye(3), Blm)
            H += landmark_weight * Lk.T @ Lk
            g += landmark_weight * Lk.T @ sl.T.ravel()
            reg = np.zeros(3 * nb)
            for d in range(3):
                reg[d * nb:d * nb + m] = params.field_smoothing * len(b1)
            H += np.diag(reg)
            # the ridge pulls the RBF weights to 0: keep the affine part free
            sol = np.linalg.solve(H + 1e-9 * np.eye(3 * nb), g)
            coef = sol.reshape(3, nb).T
            X = Bv @ coef
        return X

    def _coverage_term(self, X, scan: _Scan, D, rhs, params: RegistrationParameters, rule: _PairRule):
        """Scan -> generic pairs: scan vertex s pulls the generic surface point closest to it."""
        from ..mesh.closest import SurfaceLocator

        n = self.n
        S = scan.points
        k = max(1, S.shape[0] // params.coverage_samples)
        sidx = np.arange(0, S.shape[0], k)
        q = S[sidx]
        loc = SurfaceLocator(X, self.triangles)
        tri, bary, _, dist = loc.closest(q)
        tv = self.triangles[tri]
        gn = vertex_normals(X, self.triangles)
        cn = np.einsum("kj,kjd->kd", bary, gn[tv])
        cn /= np.maximum(np.linalg.norm(cn, axis=1, keepdims=True), 1e-300)
        ok = np.einsum("ij,ij->i", cn, scan.normals[sidx]) >= rule.cos_max
        ok &= ~self.excluded[tv].any(axis=1)  # not into the eye and mouth holes
        if ok.sum() < 10:
            return D, rhs
        ok &= dist <= max(rule.factor * float(np.median(dist[ok])), rule.min_d)
        tv, bary, q = tv[ok], bary[ok], q[ok]
        w = params.coverage_weight * n / max(len(q), 1)
        rows = np.repeat(np.arange(len(q)), 3)
        Bs = sp.coo_matrix((bary.ravel(), (rows, tv.ravel())), shape=(len(q), n)).tocsr()
        D = D + w * (Bs.T @ Bs).tocsr()
        rhs = rhs + w * (Bs.T @ q)
        return D, rhs

    def landmark_positions(self, points) -> np.ndarray:
        """(M, 3) the generic landmarks' surface points evaluated on ``points`` (N, 3)."""
        return self.B @ np.asarray(points)

    def register(self, scan_points, scan_triangles, scan_landmarks, params: RegistrationParameters | None = None, *,
                 locator=None, progress=None) -> RegistrationResult:
        """Register the generic mesh onto one scan.

        Parameters
        ----------
        scan_points : ndarray, shape (S, 3)
            Scan vertices, in the generic's units (convert first).
        scan_triangles : ndarray, shape (F, 3)
        scan_landmarks : ndarray, shape (M, 3)
            The scan's landmarks, in the order of the generic landmarks.
        params : RegistrationParameters, optional
            Iterations, weights and pair rules (default: :class:`RegistrationParameters`).
        locator : SurfaceLocator, optional
            Prebuilt locator of the scan.
        progress : callable(iteration, record), optional
            Called after each closest-point iteration.

        Returns
        -------
        RegistrationResult
        """
        from .warp import ThinPlateSpline

        params = RegistrationParameters() if params is None else params
        t0 = time.perf_counter()
        sl = np.asarray(scan_landmarks, dtype=np.float64)
        if sl.shape != self.landmarks.shape:
            raise InputError(f"scan landmarks have shape {sl.shape}; the generic has {self.landmarks.shape}")
        # 1. similarity
        s, R, t = similarity_fit(self.landmark_positions(self.mesh.points), sl)
        X_sim = apply_similarity(self.mesh.points, s, R, t)
        # 2. thin-plate warp of the landmark correspondences
        X_rbf = ThinPlateSpline(self.landmark_positions(X_sim), sl, smoothing=params.rbf_smoothing)(X_sim)
        info = {"similarity_scale": s, "seconds_rbf": time.perf_counter() - t0}
        F = np.asarray(scan_triangles, dtype=np.int64)
        scan = _Scan.build(scan_points, F, locator, dense=len(F) > 20 * self.n)
        rule = _PairRule(cos_max=np.cos(np.radians(params.max_normal_angle)), factor=params.max_distance_factor,
                         min_d=0.01 * scan.diagonal if params.min_distance is None else float(params.min_distance))
        X_field = X_rbf
        if params.field_iterations > 0:
            X_field = self._smooth_field(X_rbf, sl, scan, rule, params)
        info["seconds_field"] = time.perf_counter() - t0
        info["seconds_locator"] = time.perf_counter() - t0
        # 3. closest-point projection
        reference = X_sim if params.laplacian_reference == "similarity" else X_field
        X, data, history = self._project(X_field.copy(), reference, sl, scan, rule, params, progress)
        dist_final = np.full(self.n, np.nan)
        if params.iterations and data.any():
            _, _, _, d = scan.locator.closest(X[data])
            dist_final[data] = d
        res_lm = np.linalg.norm(self.landmark_positions(X) - sl, axis=1)
        info.update(iterations=history, seconds=time.perf_counter() - t0, excluded=int(self.excluded.sum()))
        return RegistrationResult(points=X, similarity_points=X_sim, rbf_points=X_rbf, similarity=(s, R, t),
                                  landmark_residuals=res_lm, surface_distance=dist_final, data_vertices=data,
                                  info=info)

    def _project(self, X, reference, sl, scan: _Scan, rule: _PairRule, params: RegistrationParameters, progress):
        """Stage 3: iterated closest-point projection from ``X``, keeping the Laplacian of
        ``reference``; returns (points, data-term vertices of the last iteration, history)."""
        from scipy.sparse.linalg import splu

        n = self.n
        delta = self.L @ reference
        LtL = (self.L.T @ self.L).tocsr()
        BtB = (self.B.T @ self.B).tocsr()
        data = np.zeros(n, bool)
        alphas = np.geomspace(params.stiffness[0], params.stiffness[1], max(params.iterations, 1))
        border_idx, seg_a, seg_b = self._border(scan, params.border_weight)
        point_weight, landmark_weight = params.point_weight, params.landmark_weight
        history = []
        for it in range(params.iterations):
            idx, c, nrm, med = self._pairs(X, scan, rule, scan.fast or scan.locator)
            data[:] = False
            data[idx] = True
            # point-to-plane as point-to-point to the foot of the current position on the scan's
            # tangent plane (Chen & Medioni), plus mu of plain point-to-point: the three coordinates
            # then share one N x N system (one sparse factorisation per iteration)
            foot = X[idx] + nrm * np.einsum("ij,ij->i", c - X[idx], nrm)[:, None]
            w = np.zeros(n)
            w[idx] = 1.0 + point_weight
            rhs = np.zeros((n, 3))
            rhs[idx] = (foot + point_weight * c) * 1.0  # = w * ((foot + mu c) / (1 + mu))
            D = sp.diags(w)
            if border_idx.size:
                bp, bd = closest_on_segments(X[border_idx], seg_a, seg_b)
                keep = bd <= max(rule.factor * float(np.median(bd)), rule.min_d)
                bi = border_idx[keep]
                wb = np.zeros(n)
                wb[bi] = params.border_weight
                D = D + sp.diags(wb)
                rhs[bi] += params.border_weight * bp[keep]
            if params.coverage_weight > 0:
                D, rhs = self._coverage_term(X, scan, D, rhs, params, rule)
            alpha = alphas[it]
            M = (D + alpha * LtL + landmark_weight * BtB).tocsc()
            rhs = rhs + alpha * (self.L.T @ delta) + landmark_weight * (self.B.T @ sl)
            X_new = splu(M, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                         options={"SymmetricMode": True}).solve(rhs)
            if not np.isfinite(X_new).all():
                raise ComputeError("registration: the closest-point solve failed (non-finite positions)")
            move = float(np.sqrt(((X_new - X) ** 2).sum(axis=1).mean()))
            X = X_new
            history.append({"iteration": it, "pairs": int(idx.size), "median_distance": med,
                            "stiffness": float(alpha), "rms_move": move})
            if progress is not None:
                progress(it, history[-1])
        return X, data, history


def register_generic(mesh, regions, generic_landmarks, scan_points, scan_triangles, scan_landmarks,
                     params: RegistrationParameters | None = None, *,
                     hole_rings: int = HOLE_RINGS) -> RegistrationResult:
    """One-call form of :class:`GenericRegistration`."""
    return GenericRegistration(mesh, regions, generic_landmarks, hole_rings=hole_rings).register(
        scan_points, scan_triangles, scan_landmarks, params)
