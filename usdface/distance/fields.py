"""The field back-ends of :class:`usdface.distance.geodesic.GeodesicSolver`: ``"heat"``
(potpourri3d's heat method) and ``"exact"`` (pygeodesic's MMP).

Both take vertex sources only, so each surface-point source is inserted into its triangle as a
new vertex (1-to-3 split in the triangle's plane: the surface is unchanged), one connected
component at a time; ``"exact"`` fills the entries pygeodesic leaves at +inf with the edge-graph
distance and says how many.
"""
from __future__ import annotations

import numpy as np

from ..errors import ComputeError, list_names
from . import graph as _graph
from .euclidean import warn

__all__ = ["AUTO_T_RINGS", "auto_t_coef", "solve_fields"]

#: t_coef = max(1, (L / (AUTO_T_RINGS h))^2): sqrt(t) never smaller than the bounding-box
#: diagonal over this many mean edge lengths (calibrated on the MakeHuman face, 2k-328k vertices)
AUTO_T_RINGS = 250.0


def auto_t_coef(points, triangles) -> float:
    """Heat-method time factor that stays accurate at high resolution.

    Parameters
    ----------
    points : array_like, shape (N, 3)
    triangles : array_like, shape (T, 3), int
        One connected component.

    Returns
    -------
    float
        ``max(1, (L / (250 h))^2)``; L = bounding-box diagonal, h = mean edge length (the h of
        potpourri3d's ``t = t_coef * h^2``).
    """
    p = np.asarray(points, dtype=np.float64)
    e = _graph.mesh_edges(triangles)
    if e.size == 0:
        return 1.0
    h = float(np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1).mean())
    used = np.bincount(np.asarray(triangles).ravel(), minlength=p.shape[0]) > 0
    diag = float(np.linalg.norm(np.ptp(p[used], axis=0)))
    if h <= 0:
        return 1.0
    return max(1.0, (diag / (AUTO_T_RINGS * h)) ** 2)


def solve_fields(solver, tri, bary, need, names, report):
    """``"heat"`` or ``"exact"`` distances of a solver, component by component.

    Parameters
    ----------
    solver : GeodesicSolver
        Its points, triangles, components, back-end and cached field solvers.
    tri, bary : ndarray, shape (S, 3)
        Validated sources (triangle vertices, barycentrics).
    need : ndarray of bool, shape (N,), or None
        ``"exact"`` stops its propagation at these vertices (and the sources).
    names : list of str
    report : DistanceReport
        Receives max_source_shift, t_coef, exact_inf_entries and notes.

    Returns
    -------
    vertex : ndarray, shape (N, S)
    sources : ndarray, shape (S, S), float64
        Row i = source i, column j = source j's field there.
    """
    n, s = solver.n_points, tri.shape[0]
    out = np.empty((s, n), dtype=solver.dtype)
    out.fill(np.inf)
    sources = np.full((s, s), np.inf)
    src_comp = report.source_components
    max_shift = 0.0
    for c in np.unique(src_comp):
        members = np.flatnonzero(src_comp == c)
        if solver.n_components == 1:
            verts, local, ctris = np.arange(n), np.arange(n), solver.triangles
        else:
            verts = np.flatnonzero(solver.component_labels == c)
            local = np.full(n, -1, dtype=np.int64)
            local[verts] = np.arange(verts.size)
            ctris = local[solver.triangles[solver.component_labels[solver.triangles[:, 0]] == c]]
        sp_, st_, sv, moved = _graph.insert_surface_points(
            solver.points[verts], ctris, local[tri[members]], bary[members],
            names=[names[i] for i in members])
        max_shift = max(max_shift, float(moved.max()))
        targets = None
        if need is not None:
            targets = np.concatenate([np.flatnonzero(need[verts]), sv])
        fields = _component_fields(solver, c, sp_, st_, sv, targets, report)  # (m, n_sub)
        if verts.size == n:
            out[members] = fields[:, :n]
        else:
            out[np.ix_(members, verts)] = fields[:, :verts.size]
        sources[np.ix_(members, members)] = fields[:, sv]
    report.max_source_shift = max_shift
    # rows = evaluation point, columns = source (see GeodesicResult.sources)
    sources = sources.T.copy()
    np.fill_diagonal(sources, 0.0)
    if solver.backend == "exact":
        bad = ~np.isfinite(out)
        same = solver.component_labels[None, :] == src_comp[:, None]
        if need is not None:
            bad &= need[None, :]
        bad &= same
        bad_s = ~np.isfinite(sources) & (src_comp[:, None] == src_comp[None, :])
        n_bad = int(bad.sum()) + int(bad_s.sum())
        if n_bad:
            rows = np.flatnonzero(bad.any(axis=1) | bad_s.any(axis=0))
            gv, gs, _ = _graph.multi_source_shortest_paths(
                solver.graph, solver.points, tri[rows], bary[rows], engine=solver.engine)
            sub = out[rows]
            sub[bad[rows]] = gv.T[bad[rows]]
            out[rows] = sub
            cols = sources[:, rows]
            cols[bad_s[:, rows]] = gs.T[bad_s[:, rows]]
            sources[:, rows] = cols
            report.exact_inf_entries = n_bad
            msg = (f"exact geodesics: pygeodesic left {n_bad} reachable entries at +inf "
                   f"(sources {list_names([names[i] for i in rows])}); filled with the graph "
                   f"(shortest edge path) distance")
            report.notes.append(msg)
            warn(msg)
    return out.T, sources

def _component_fields(solver, c, pts, tris, src_vertices, targets, report) -> np.ndarray:
    """(len(src_vertices), n_sub) distance fields on one component's mesh (sources inserted)."""
    uniq, inv = np.unique(src_vertices, return_inverse=True)
    if solver.backend == "heat":
        solver, tc = solver._heat_solver(c, pts, tris)
        report.t_coef[int(c)] = tc
        rows = [np.asarray(solver.compute_distance(int(v)), dtype=np.float64) for v in uniq]
    else:
        alg = solver._exact_solver(c, pts, tris)
        rows = []
        for v in uniq:
            if targets is None:
                d, _ = alg.geodesicDistances(np.array([v], dtype=np.int32), None)
                if d is None:
                    raise ComputeError(f"pygeodesic failed on component {c} (see its printed message)")
                rows.append(d)
            else:
                tg = np.unique(targets).astype(np.int32)
                d, _ = alg.geodesicDistances(np.array([v], dtype=np.int32), tg)
                if d is None:
                    raise ComputeError(f"pygeodesic failed on component {c} (see its printed message)")
                full = np.full(pts.shape[0], np.inf)
                full[tg] = d
                rows.append(full)
    fields = np.stack(rows)[inv]
    return fields
