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

from ..errors import ComputeError, InputError, MeshError, OptionError, list_names

__all__ = ["similarity_fit", "apply_similarity", "GenericRegistration", "RegistrationResult", "register_generic",
           "hole_vertices", "boundary_vertex_mask"]


def similarity_fit(src, dst, *, scale: bool = True):
    """Least-squares similarity ``dst ~ s R src + t`` (Umeyama 1991).

    Parameters
    ----------
    src, dst : ndarray, shape (M, 3)

    Returns
    -------
    s : float
    R : ndarray, shape (3, 3)
    t : ndarray, shape (3,)
    """
    a = np.asarray(src, dtype=np.float64)
    b = np.asarray(dst, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 2 or a.shape[1] != 3:
        raise OptionError(f"similarity fit: point sets must both be (M, 3); got {a.shape} and {b.shape}")
    if len(a) < 3:
        raise ComputeError(f"similarity fit: {len(a)} correspondences; at least 3 are needed")
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    A, B = a - ma, b - mb
    cov = B.T @ A / len(a)
    u, sig, vt = np.linalg.svd(cov)
    d = np.sign(np.linalg.det(u @ vt)) or 1.0
    D = np.diag([1.0, 1.0, d])
    R = u @ D @ vt
    var = (A ** 2).sum() / len(a)
    if var <= 0:
        raise ComputeError("similarity fit: all source points coincide")
    s = float(np.trace(np.diag(sig) @ D) / var) if scale else 1.0
    return s, R, mb - s * R @ ma


def apply_similarity(points, s, R, t) -> np.ndarray:
    return s * np.asarray(points, dtype=np.float64) @ R.T + t


def _edges(triangles):
    t = np.asarray(triangles, dtype=np.int64)
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    return e


def boundary_vertex_mask(n_points, triangles) -> np.ndarray:
    """(N,) True for vertices on a boundary edge (an edge used by one triangle)."""
    e = np.sort(_edges(triangles), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    mask = np.zeros(n_points, bool)
    mask[uniq[counts == 1].ravel()] = True
    return mask


def _boundary_edge_flags(triangles) -> np.ndarray:
    """(T, 3) True where the triangle's edge opposite vertex k is a boundary edge."""
    t = np.asarray(triangles, dtype=np.int64)
    opp = np.concatenate([t[:, [1, 2]], t[:, [2, 0]], t[:, [0, 1]]])
    lo, hi = opp.min(axis=1), opp.max(axis=1)
    key = lo * (int(t.max()) + 1) + hi  # one int64 per undirected edge
    order = np.argsort(key, kind="stable")
    ks = key[order]
    start = np.r_[True, ks[1:] != ks[:-1]]
    run = np.cumsum(start) - 1
    counts = np.bincount(run)
    flags = np.empty(key.size, bool)
    flags[order] = counts[run] == 1
    return flags.reshape(3, -1).T


def _boundary_segments(triangles, edge_flags) -> np.ndarray:
    """(E, 2) vertex pairs of the boundary edges (``edge_flags`` from :func:`_boundary_edge_flags`)."""
    t = np.asarray(triangles, dtype=np.int64)
    opp = np.stack([t[:, [1, 2]], t[:, [2, 0]], t[:, [0, 1]]], axis=1)  # (T, 3, 2)
    return opp[edge_flags]


def _closest_on_segments(q, a, b, k: int = 8):
    """Closest point of each query on a set of segments (exact among the k nearest midpoints)."""
    from scipy.spatial import cKDTree

    mid = 0.5 * (a + b)
    kk = min(k, len(mid))
    _, idx = cKDTree(mid).query(q, k=kk)
    idx = idx.reshape(len(q), -1)
    A, B = a[idx], b[idx]
    e = B - A
    ee = np.maximum(np.einsum("qkd,qkd->qk", e, e), 1e-300)
    tt = np.clip(np.einsum("qkd,qkd->qk", q[:, None, :] - A, e) / ee, 0.0, 1.0)
    P = A + tt[..., None] * e
    d = np.linalg.norm(P - q[:, None, :], axis=2)
    j = d.argmin(axis=1)
    r = np.arange(len(q))
    return P[r, j], d[r, j]


def _adjacency(n, triangles) -> sp.csr_matrix:
    e = _edges(triangles)
    A = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    A = ((A + A.T) > 0).astype(np.float64)
    return A.tocsr()


def hole_vertices(mesh, regions, *, roles=("eye", "mouth"), rings: int = 1) -> np.ndarray:
    """(N,) bool: vertices of the ``roles`` hole regions and ``rings`` rings of neighbours."""
    mask = np.zeros(mesh.n_points, bool)
    for r in regions:
        if r.role in roles:
            mask[r.indices] = True
    if rings > 0 and mask.any():
        A = _adjacency(mesh.n_points, mesh.triangles())
        for _ in range(rings):
            mask = mask | (A @ mask.astype(np.float64) > 0)
    return mask


def _uniform_laplacian(n, triangles) -> sp.csr_matrix:
    A = _adjacency(n, triangles)
    deg = np.asarray(A.sum(axis=1)).ravel()
    return (sp.diags(np.ones(n)) - sp.diags(1.0 / np.maximum(deg, 1)) @ A).tocsr()


def _vertex_normals(points, triangles) -> np.ndarray:
    p = np.asarray(points)
    t = np.asarray(triangles)
    fn = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    flat = t.ravel()
    n = np.stack([np.bincount(flat, weights=np.repeat(fn[:, d], 3), minlength=len(p)) for d in range(3)], axis=1)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)


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

    def __init__(self, mesh, regions, landmarks, *, hole_rings: int = 1):
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
        self.L = _uniform_laplacian(self.n, self.triangles)
        used = np.zeros(self.n, bool)
        used[self.triangles.ravel()] = True
        self.excluded |= ~used
        # landmark rows: x(l) = sum_k bary_k x_{tri_k}
        rows = np.repeat(np.arange(len(lm)), 3)
        cols = self.triangles[self.lm_tri].ravel()
        self.B = sp.coo_matrix((self.lm_bary.ravel(), (rows, cols)), shape=(len(lm), self.n)).tocsr()

    def _pairs(self, X, loc, S, F, scan_n, edge_flags, cos_max, factor, min_d, near=None):
        """Accepted closest-point pairs: (vertex indices, closest points, scan normals, median distance).

        ``near`` = (k-d tree of the scan vertices, longest scan edge): vertices whose nearest scan
        vertex is farther than ``factor`` times the median of those distances (and ``min_d``) plus
        the longest edge cannot have an accepted pair, so the exact (and, far from the surface,
        costly) closest-point search skips them.
        """
        cand = np.flatnonzero(~self.excluded)
        if near is not None:
            tree, longest = near
            dv, _ = tree.query(X[cand])
            cand = cand[dv <= max(factor * float(np.median(dv)), min_d) + longest]
        tri, bary, cp, dist = loc.closest(X[cand])
        on_edge = (edge_flags[tri] & (bary < 1e-9)).any(axis=1)  # over the scan's border or a hole
        cn = np.einsum("kj,kjd->kd", bary, scan_n[F[tri]])
        cn /= np.maximum(np.linalg.norm(cn, axis=1, keepdims=True), 1e-300)
        gn = _vertex_normals(X, self.triangles)[cand]
        ok = ~on_edge & (np.einsum("ij,ij->i", cn, gn) >= cos_max)
        if ok.sum() < 10:
            raise ComputeError(f"registration: only {int(ok.sum())} generic vertices found a compatible scan "
                               "point (check the landmarks and the scan's units and orientation)")
        med = float(np.median(dist[ok]))
        ok &= dist <= max(factor * med, min_d)
        return cand[ok], cp[ok], cn[ok], med

    def _smooth_field(self, X0, sl, loc, S, F, scan_n, edge_flags, *, iterations, centres, width, smoothing, cos_max,
                      factor, min_d, landmark_weight, border_weight=0.0, near=None):
        """Stage 2b: a smooth displacement field (Gaussian RBF on ``centres`` farthest points plus an
        affine part) fitted to point-to-plane closest-point constraints and the landmarks, iterated.

        Unlike the per-vertex projection, a global smooth field turns the normal offsets seen on
        differently oriented parts of the face into the tangential motion between them."""
        C = X0[_farthest_points(X0, centres)]
        sig = width * float(np.linalg.norm(np.ptp(sl, axis=0)))
        r = np.linalg.norm(X0[:, None, :] - C[None, :, :], axis=2)
        Bv = np.hstack([np.exp(-(r / sig) ** 2), X0, np.ones((len(X0), 1))])  # (N, M + 4)
        nb = Bv.shape[1]
        m = C.shape[0]
        Blm = self.B @ Bv
        coef = np.zeros((nb, 3))
        coef[m:m + 3] = np.eye(3)
        X = X0
        border = np.zeros(0, np.int64)
        if border_weight > 0:
            border = np.unique(np.concatenate([r.indices for r in self.regions if r.role == "outerBorder"]
                                              or [np.zeros(0, np.int64)]))
            seg = _boundary_segments(F, edge_flags)
            if not len(seg):
                border = np.zeros(0, np.int64)
        for _ in range(iterations):
            idx, cp, nrm, _ = self._pairs(X, loc, S, F, scan_n, edge_flags, cos_max, factor, min_d, near=near)
            Bd = Bv[idx]
            A1 = np.hstack([Bd * nrm[:, 0:1], Bd * nrm[:, 1:2], Bd * nrm[:, 2:3]])  # (K, 3 nb)
            b1 = np.einsum("ij,ij->i", nrm, cp)
            H = A1.T @ A1
            g = A1.T @ b1
            if border.size:
                bp, bd = _closest_on_segments(X[border], S[seg[:, 0]], S[seg[:, 1]])
                keep = bd <= max(factor * float(np.median(bd)), min_d)
                Kb = np.kron(np.eye(3), Bv[border[keep]])
                H += border_weight * Kb.T @ Kb
                g += border_weight * Kb.T @ bp[keep].T.ravel()
            Lk = np.kron(np.eye(3), Blm)
            H += landmark_weight * Lk.T @ Lk
            g += landmark_weight * Lk.T @ sl.T.ravel()
            reg = np.zeros(3 * nb)
            for d in range(3):
                reg[d * nb:d * nb + m] = smoothing * len(b1)
            H += np.diag(reg)
            # the ridge pulls the RBF weights to 0: keep the affine part free
            sol = np.linalg.solve(H + 1e-9 * np.eye(3 * nb), g)
            coef = sol.reshape(3, nb).T
            X = Bv @ coef
        return X

    def _coverage_term(self, X, S, F, scan_n, D, rhs, weight, samples, cos_max, factor, min_d):
        """Scan -> generic pairs: scan vertex s pulls the generic surface point closest to it."""
        from ..mesh.closest import SurfaceLocator

        n = self.n
        k = max(1, S.shape[0] // samples)
        sidx = np.arange(0, S.shape[0], k)
        q = S[sidx]
        loc = SurfaceLocator(X, self.triangles)
        tri, bary, _, dist = loc.closest(q)
        tv = self.triangles[tri]
        gn = _vertex_normals(X, self.triangles)
        cn = np.einsum("kj,kjd->kd", bary, gn[tv])
        cn /= np.maximum(np.linalg.norm(cn, axis=1, keepdims=True), 1e-300)
        ok = np.einsum("ij,ij->i", cn, scan_n[sidx]) >= cos_max
        ok &= ~self.excluded[tv].any(axis=1)  # not into the eye and mouth holes
        if ok.sum() < 10:
            return D, rhs
        ok &= dist <= max(factor * float(np.median(dist[ok])), min_d)
        tv, bary, q = tv[ok], bary[ok], q[ok]
        w = weight * n / max(len(q), 1)
        rows = np.repeat(np.arange(len(q)), 3)
        Bs = sp.coo_matrix((bary.ravel(), (rows, tv.ravel())), shape=(len(q), n)).tocsr()
        D = D + w * (Bs.T @ Bs).tocsr()
        rhs = rhs + w * (Bs.T @ q)
        return D, rhs

    def landmark_positions(self, points) -> np.ndarray:
        return self.B @ np.asarray(points)

    def register(self, scan_points, scan_triangles, scan_landmarks, *, iterations: int = 20,
                 stiffness=(10.0, 0.5), landmark_weight: float = 1.0, point_weight: float = 0.1,
                 max_normal_angle: float = 60.0, max_distance_factor: float = 3.0, min_distance=None,
                 rbf_smoothing: float = 0.0, border_weight: float = 0.0, coverage_weight: float = 0.0,
                 coverage_samples: int = 20000, laplacian_reference: str = "rbf",
                 field_iterations: int = 0, field_centres: int = 100, field_width: float = 0.5,
                 field_smoothing: float = 3e-3, locator=None, progress=None) -> RegistrationResult:
        """Register the generic mesh onto one scan.

        Parameters
        ----------
        scan_points : ndarray, shape (S, 3)
            Scan vertices, in the generic's units (convert first).
        scan_triangles : ndarray, shape (F, 3)
        scan_landmarks : ndarray, shape (M, 3)
            The scan's landmarks, in the order of the generic landmarks.
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
        locator : SurfaceLocator, optional
            Prebuilt locator of the scan.

        Returns
        -------
        RegistrationResult
        """
        from ..mesh.closest import SurfaceLocator
        from .warp import ThinPlateSpline

        t0 = time.perf_counter()
        S = np.asarray(scan_points, dtype=np.float64)
        F = np.asarray(scan_triangles, dtype=np.int64)
        sl = np.asarray(scan_landmarks, dtype=np.float64)
        if sl.shape != self.landmarks.shape:
            raise InputError(f"scan landmarks have shape {sl.shape}; the generic has {self.landmarks.shape}")
        # 1. similarity
        g_lm = self.landmark_positions(self.mesh.points)
        s, R, t = similarity_fit(g_lm, sl)
        X_sim = apply_similarity(self.mesh.points, s, R, t)
        # 2. thin-plate warp of the landmark correspondences
        src = self.landmark_positions(X_sim)
        tps = ThinPlateSpline(src, sl, smoothing=rbf_smoothing)
        X_rbf = tps(X_sim)
        info = {"similarity_scale": s, "seconds_rbf": time.perf_counter() - t0}
        loc = locator or SurfaceLocator(S, F)
        scan_n = _vertex_normals(S, F)
        edge_flags = _boundary_edge_flags(F)
        diag = float(np.linalg.norm(np.ptp(S, axis=0)))
        min_d = 0.01 * diag if min_distance is None else float(min_distance)
        cos_max = np.cos(np.radians(max_normal_angle))
        from scipy.spatial import cKDTree

        e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
        tree = cKDTree(S)
        near = (tree, float(np.linalg.norm(S[e[:, 0]] - S[e[:, 1]], axis=1).max()))
        fast = _NearSurface(S, F, tree) if len(F) > 20 * self.n else None
        X_field = X_rbf
        if field_iterations > 0:
            X_field = self._smooth_field(X_rbf, sl, loc, S, F, scan_n, edge_flags, iterations=field_iterations,
                                         centres=field_centres, width=field_width, smoothing=field_smoothing,
                                         cos_max=cos_max, factor=max_distance_factor, min_d=min_d,
                                         landmark_weight=100.0 * landmark_weight, border_weight=border_weight,
                                         near=near)
        info["seconds_field"] = time.perf_counter() - t0
        X = X_field.copy()
        info["seconds_locator"] = time.perf_counter() - t0
        n = self.n
        delta = self.L @ (X_sim if laplacian_reference == "similarity" else X_field)
        LtL = (self.L.T @ self.L).tocsr()
        BtB = (self.B.T @ self.B).tocsr()
        data = np.zeros(n, bool)
        dist_final = np.full(n, np.nan)
        alphas = np.geomspace(stiffness[0], stiffness[1], max(iterations, 1))
        border_idx = np.zeros(0, np.int64)
        if border_weight > 0:
            roles = ("outerBorder",)
            border_idx = np.unique(np.concatenate([r.indices for r in self.regions if r.role in roles]
                                                  or [np.zeros(0, np.int64)]))
            seg = _boundary_segments(F, edge_flags)
            if border_idx.size and len(seg):
                seg_a, seg_b = S[seg[:, 0]], S[seg[:, 1]]
            else:
                border_idx = np.zeros(0, np.int64)
        history = []
        for it in range(iterations):
            idx, c, nrm, med = self._pairs(X, fast or loc, S, F, scan_n, edge_flags, cos_max, max_distance_factor,
                                           min_d, near=near)
            data[:] = False
            data[idx] = True
            # point-to-plane as point-to-point to the foot of the current position on the scan's
            # tangent plane (Chen & Medioni), plus mu of plain point-to-point: the three coordinates
            # then share one N x N system (one sparse factorisation per iteration)
            k = idx.size
            foot = X[idx] + nrm * np.einsum("ij,ij->i", c - X[idx], nrm)[:, None]
            w = np.zeros(n)
            w[idx] = 1.0 + point_weight
            target = np.zeros((n, 3))
            target[idx] = (foot + point_weight * c) * 1.0
            rhs = target.copy()  # = w * ((foot + mu c) / (1 + mu))
            D = sp.diags(w)
            if border_idx.size:
                bp, bd = _closest_on_segments(X[border_idx], seg_a, seg_b)
                keep = bd <= max(max_distance_factor * float(np.median(bd)), min_d)
                bi = border_idx[keep]
                wb = np.zeros(n)
                wb[bi] = border_weight
                D = D + sp.diags(wb)
                rhs[bi] += border_weight * bp[keep]
            if coverage_weight > 0:
                D, rhs = self._coverage_term(X, S, F, scan_n, D, rhs, coverage_weight, coverage_samples, cos_max,
                                             max_distance_factor, min_d)
            alpha = alphas[it]
            M = (D + alpha * LtL + landmark_weight * BtB).tocsc()
            rhs = rhs + alpha * (self.L.T @ delta) + landmark_weight * (self.B.T @ sl)
            from scipy.sparse.linalg import splu

            X_new = splu(M, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                         options={"SymmetricMode": True}).solve(rhs)
            if not np.isfinite(X_new).all():
                raise ComputeError("registration: the closest-point solve failed (non-finite positions)")
            move = float(np.sqrt(((X_new - X) ** 2).sum(axis=1).mean()))
            X = X_new
            history.append({"iteration": it, "pairs": int(k), "median_distance": med, "stiffness": float(alpha),
                            "rms_move": move})
            if progress is not None:
                progress(it, history[-1])
        if iterations and data.any():
            _, _, _, d = loc.closest(X[data])
            dist_final[data] = d
        res_lm = np.linalg.norm(self.landmark_positions(X) - sl, axis=1)
        info.update(iterations=history, seconds=time.perf_counter() - t0, excluded=int(self.excluded.sum()))
        return RegistrationResult(points=X, similarity_points=X_sim, rbf_points=X_rbf, similarity=(s, R, t),
                                  landmark_residuals=res_lm, surface_distance=dist_final, data_vertices=data.copy(),
                                  info=info)


class _NearSurface:
    """Closest points on a dense scan mesh for the projection iterations: the exact closest point
    among the triangles around the ``k`` nearest scan vertices of each query (one k-d tree query,
    fixed-size candidate sets). On a scan whose triangles are small compared with the distances
    involved it almost always finds the exact closest point (:class:`usdface.mesh.closest.SurfaceLocator`
    gives the final distances); it is several times faster than the exact search when many queries
    hang off the scan's border."""

    def __init__(self, points, triangles, tree, *, k: int = 2, max_per_vertex: int = 8):
        self.P = np.asarray(points, dtype=np.float64)
        self.F = np.asarray(triangles, dtype=np.int64)
        self.tree = tree
        self.k = k
        nv = self.P.shape[0]
        v = self.F.ravel()
        t = np.repeat(np.arange(len(self.F)), 3)
        order = np.argsort(v, kind="stable")
        v, t = v[order], t[order]
        starts = np.searchsorted(v, np.arange(nv))
        rank = np.arange(v.size) - starts[v]
        keep = rank < max_per_vertex
        self.vt = np.full((nv, max_per_vertex), -1, dtype=np.int64)
        self.vt[v[keep], rank[keep]] = t[keep]

    def closest(self, q):
        from ..mesh.closest import closest_point_on_triangles

        q = np.asarray(q, dtype=np.float64)
        _, nv = self.tree.query(q, k=self.k)
        cand = self.vt[nv.reshape(len(q), -1)].reshape(len(q), -1)  # (Q, k * max_per_vertex)
        valid = cand >= 0
        cand = np.where(valid, cand, self.vt[nv.reshape(len(q), -1)[:, :1], 0])  # pad with a real triangle
        qi = np.repeat(np.arange(len(q)), cand.shape[1])
        tri = cand.ravel()
        f = self.F[tri]
        pt, bc, d = closest_point_on_triangles(q[qi], self.P[f[:, 0]], self.P[f[:, 1]], self.P[f[:, 2]])
        d = d.reshape(len(q), -1)
        j = d.argmin(axis=1)
        r = np.arange(len(q))
        sel = r * cand.shape[1] + j
        return tri[sel], bc[sel], pt[sel], d[r, j]


def _farthest_points(P, m: int) -> np.ndarray:
    """Indices of ``m`` points of ``P`` spread out by farthest-point sampling (deterministic)."""
    m = min(m, len(P))
    idx = [int(np.argmin(P[:, 1]))]
    d = np.linalg.norm(P - P[idx[0]], axis=1)
    for _ in range(m - 1):
        i = int(d.argmax())
        idx.append(i)
        d = np.minimum(d, np.linalg.norm(P - P[i], axis=1))
    return np.array(idx)


def register_generic(mesh, regions, generic_landmarks, scan_points, scan_triangles, scan_landmarks,
                     **options) -> RegistrationResult:
    """One-call form of :class:`GenericRegistration` (``hole_rings`` and ``register`` options)."""
    rings = options.pop("hole_rings", 1)
    return GenericRegistration(mesh, regions, generic_landmarks, hole_rings=rings).register(
        scan_points, scan_triangles, scan_landmarks, **options)
