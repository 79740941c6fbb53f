"""Geodesic distance matrices from surface-point sources: edge graph, heat method, exact.

Back-ends of :class:`GeodesicSolver`:

``"graph"`` (default)
    The paper's mesh-based geodesic distance (Eq. 7): the shortest path along mesh edges. A
    surface-point source starts from the three vertices of its triangle at their Euclidean distance
    from the point (a virtual node). One search per source over the whole mesh (multi-source,
    never per pair), exactly equal to :func:`scipy.sparse.csgraph.dijkstra` on the same graph.
    Edge paths overestimate surface distances by 5-9 % on average whatever the resolution (the
    path zig-zags along edge directions), as in the paper.
``"fmm"``
    Fast marching with exact point-source triangle updates, split obtuse corners and late-update
    reopening (:mod:`usdface.distance.marching`): surface geodesics within 0.03-0.4 % of exact
    (MMP) on face meshes (0.34 % on the 2020-vertex sample face, 0.03 % at 560k vertices), at
    about 2.6x the CPU time of an edge-graph search and 0.94x the wall time of scipy's multi-source
    Dijkstra at 560k vertices (``benchmarks/bench_distances.py --n 17``; one search per source,
    sources in parallel). Close to, not exactly, symmetric. Not
    the default: at the pipeline's kernel width rule (1.1 x marker spacing) the transfer of the
    sample expression shapes is better on the edge-graph distances (face error 57.7 % vs 62.0 %,
    benchmarks/quality_expressions.py); with a 0.75 x width, fmm hybrid gives 48.6 %, the best of
    all (the width sweep of benchmarks/quality_expressions.py).
``"heat"``
    The heat method (Crane et al. 2013) of potpourri3d (``MeshHeatMethodDistanceSolver``,
    intrinsic-Delaunay "robust" Laplacian by default). potpourri3d takes vertex sources only, so
    each surface-point source is inserted into a copy of its triangle (1-to-3 split in the plane of
    the triangle: the surface is unchanged) and the solver is factored on that mesh; vertex
    sources reuse one factorization. One solve per source. Heat-method distances are not
    symmetric: ``at_sources()[i, j]`` is the field of source j evaluated at source i.
    ``t_coef="auto"`` (default) uses ``t = t_coef * h^2`` with
    ``t_coef = max(1, (L / (250 h))^2)``, L the bounding-box diagonal of the component and h its
    mean edge length: potpourri3d's default ``t_coef = 1`` works up to ~30k vertices on a face
    but at 300k the heat, a single backward-Euler step, falls below rounding a few hundred edge
    rings from the source and distances behind the mouth and eyes collapse (measured on the
    MakeHuman face refined to 328k: max error 10.6 cm of a 24 cm diameter with t_coef = 1; 0.36 cm
    with the auto value ~8; see benchmarks/bench_distances.py).
``"exact"``
    Exact polyhedral geodesics (MMP, pygeodesic), for validation and small meshes (minutes at
    30k vertices, hours at 300k). Surface points are inserted as for ``"heat"`` (exact: the
    surface does not change). pygeodesic sometimes leaves +inf at reachable vertices; those
    entries are filled with the ``"graph"`` distance, counted in the report and warned about.

Meshes with several connected components: distances between a vertex (or source) and a source on
another component are +inf in the raw matrices. ``components="error"`` (default) raises
ComputeError naming the markers bound on different components; ``"euclidean"`` puts the
Euclidean distance in every unreachable entry and reports how many; ``"inf"`` keeps +inf and
reports. Vertices on a component that holds no source are unreachable from every source (a warning
counts them unless the policy fills them). :meth:`GeodesicSolver.source_components` tells which
source lies on which component.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import ComputeError, InputError, OptionError, list_names
from .methods import BACKENDS, DEFAULT_BACKEND
from . import graph as _graph
from .components import triangle_components
from .fields import auto_t_coef, solve_fields
from .euclidean import (_check_dtype, check_matrix_memory, pairwise_euclidean, source_points,
                        validate_sources, warn)

__all__ = ["BACKENDS", "DEFAULT_BACKEND", "DistanceReport", "GeodesicResult", "GeodesicSolver", "auto_t_coef",
           "geodesic_distances"]

log = logging.getLogger("usdface")

COMPONENT_POLICIES = ("error", "euclidean", "inf")

@dataclass
class DistanceReport:
    """What a distance computation did, for logs and provenance.

    Attributes
    ----------
    backend : str
    n_vertices, n_sources : int
    n_components : int
        Connected components of the mesh.
    source_components : ndarray, shape (S,), int64
        Component of each source (0 = the largest component).
    unreachable_pairs : int
        (vertex, source) pairs on different components (+inf in the raw matrix).
    unreachable_vertices : int
        Vertices on components that hold no source.
    components_policy : str
    euclidean_fallback_pairs : int
        Entries (vertex and source-source) set to the Euclidean distance by
        ``components="euclidean"``.
    exact_inf_entries : int
        ``"exact"``: entries pygeodesic left at +inf that were filled from the graph distance.
    t_coef : dict
        ``"heat"``: t_coef used per component.
    max_source_shift : float
        Largest distance a source point was moved when inserted as a vertex (mesh units).
    settled_fraction : float or None
        ``"graph"``, ``"fmm"``: vertices settled by all the searches / (N * S) (1.0 for full
        searches).
    needed_vertices : int or None
        Vertices whose distances were asked for (bounded search), None for all.
    max_distance : float or None
        The bound of the searches (entries beyond are +inf), None when unbounded (also when the
        bound asked for covered the whole mesh: see ``notes``).
    memory_estimate : int
        Bytes the computation was estimated to need (checked against the memory available).
    seconds : float
        The whole :meth:`GeodesicSolver.solve` call.
    setup_seconds : float
        Building the search structures before the first search: the solver's connected
        components and, for ``"graph"`` the edge graph, for ``"fmm"`` the update tables; 0 when a
        previous solve of the same solver built them.
    search_seconds : float
        ``"graph"``, ``"fmm"``: the searches themselves (all sources, wall time, ``threads`` in
        parallel); the other back-ends: their solves.
    threads : int
        Threads the searches ran on (numba's, at most one per source).
    notes : list of str
    """

    backend: str
    n_vertices: int
    n_sources: int
    n_components: int
    source_components: np.ndarray
    unreachable_pairs: int = 0
    unreachable_vertices: int = 0
    components_policy: str = "error"
    euclidean_fallback_pairs: int = 0
    exact_inf_entries: int = 0
    t_coef: dict = field(default_factory=dict)
    max_source_shift: float = 0.0
    settled_fraction: float | None = None
    needed_vertices: int | None = None
    max_distance: float | None = None
    memory_estimate: int = 0
    seconds: float = 0.0
    setup_seconds: float = 0.0
    search_seconds: float = 0.0
    threads: int = 1
    notes: list = field(default_factory=list)


@dataclass
class GeodesicResult:
    """Vertex-to-source and source-to-source distances and the report.

    Attributes
    ----------
    vertex : ndarray, shape (N, S)
        Mesh units. With a ``needed`` mask, entries of vertices not needed may be +inf.
    sources : ndarray, shape (S, S), float64
        ``sources[i, j]``: distance from source j's field evaluated at source i (the row is the
        evaluation point, like a row of ``vertex``); symmetric for ``"graph"`` and ``"exact"``.
    report : DistanceReport
    """

    vertex: np.ndarray
    sources: np.ndarray
    report: DistanceReport


class GeodesicSolver:
    """Geodesic distances on one triangle mesh: set up once, query many source sets.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Vertex positions, mesh units.
    triangles : array_like, shape (T, 3), int
        Triangles (e.g. :meth:`usdface.mesh.FaceMesh.triangles`).
    backend : {"fmm", "graph", "heat", "exact"}
        See the module docstring (default :data:`DEFAULT_BACKEND`).
    edges : array_like, shape (E, 2), int, optional
        ``"graph"`` only: the edges to search along (default: the triangles' edges; pass
        :func:`usdface.distance.graph.polygon_edges` to leave out quad diagonals).
    t_coef : float or "auto"
        ``"heat"`` only: time step factor, ``t = t_coef * (mean edge length)^2``.
    use_robust : bool
        ``"heat"`` only: potpourri3d's intrinsic Delaunay Laplacian (recommended).
    components : {"error", "euclidean", "inf"}
        What to do with sources and vertices on different connected components.
    dtype : {numpy.float64, numpy.float32}
        Type of the (N, S) matrix (the (S, S) one is float64).
    memory_limit : int, optional
        Bytes allowed for the computation (matrices, search tables and scratch); default: the
        memory available when computing. Checked before any work (:meth:`memory_estimate`).
    engine : {"auto", "numba", "scipy"}
        ``"graph"`` search engine (numba: parallel bucket-queue Dijkstra, bounded searches;
        scipy: csgraph.dijkstra on the augmented graph).

    Examples
    --------
    >>> solver = GeodesicSolver(mesh.points, mesh.triangles())          # doctest: +SKIP
    >>> d = solver.distances(binding.triangle_vertices, binding.barycentrics)   # (N, S)
    >>> dss = solver.at_sources(binding.triangle_vertices, binding.barycentrics)  # (S, S)
    """

    def __init__(self, points, triangles, *, backend: str = DEFAULT_BACKEND, edges=None, t_coef="auto",
                 use_robust: bool = True, components: str = "error", dtype=np.float64,
                 memory_limit: int | None = None, engine: str = "auto") -> None:
        started = time.perf_counter()
        if backend not in BACKENDS:
            raise OptionError(f"backend must be one of {', '.join(BACKENDS)}; got {backend!r}")
        if components not in COMPONENT_POLICIES:
            raise OptionError(f"components must be one of {', '.join(COMPONENT_POLICIES)}; got {components!r}")
        if not (t_coef == "auto" or (isinstance(t_coef, (int, float)) and t_coef > 0)):
            raise OptionError(f"t_coef must be 'auto' or a positive number; got {t_coef!r}")
        if engine not in ("auto", "numba", "scipy"):
            raise OptionError(f"engine must be 'auto', 'numba' or 'scipy'; got {engine!r}")
        if edges is not None and backend != "graph":
            raise OptionError(f"edges= applies to backend='graph' only (backend {backend!r} follows the triangles)")
        pts = np.asarray(points, dtype=np.float64)
        tris = np.asarray(triangles)
        if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] == 0:
            raise InputError(f"points must have shape (N>0, 3); got {pts.shape}")
        if tris.ndim != 2 or tris.shape[1] != 3 or tris.shape[0] == 0:
            raise InputError(f"triangles must have shape (T>0, 3); got {tris.shape}")
        tris = tris.astype(np.int64)
        if tris.min() < 0 or tris.max() >= pts.shape[0]:
            raise InputError(f"triangle vertex indices outside 0..{pts.shape[0] - 1}")
        if not np.isfinite(pts).all():
            raise InputError(f"{int((~np.isfinite(pts)).any(axis=1).sum())} vertices are NaN or infinite")
        self.points = pts
        self.triangles = tris
        self.backend = backend
        self.t_coef = t_coef
        self.use_robust = bool(use_robust)
        self.components = components
        self.dtype = _check_dtype(dtype)
        self.memory_limit = memory_limit
        self.engine = engine
        self._edges = None if edges is None else np.asarray(edges, dtype=np.int64).reshape(-1, 2)
        # from the triangles directly: the edge list (a sort of 3T keys) is built only for "graph"
        self.n_components, self.component_labels = triangle_components(pts.shape[0], tris)
        self._graph = None
        self._marching = None
        self._field_cache: dict = {}
        self._last: tuple | None = None
        self._setup_unreported = time.perf_counter() - started   # goes into the next report
        self.report: DistanceReport | None = None

    # -------------------------------------------------------------------------------------------
    @classmethod
    def from_mesh(cls, mesh, **options) -> "GeodesicSolver":
        """Solver on a :class:`usdface.mesh.FaceMesh` (its fan triangulation)."""
        return cls(mesh.points, mesh.triangles(), **options)

    @property
    def n_points(self) -> int:
        return self.points.shape[0]

    @property
    def edges(self) -> np.ndarray:
        """(E, 2) int64 edges the ``"graph"`` back-end searches along (the triangles' edges unless
        given), built on first use."""
        if self._edges is None:
            self._edges = _graph.mesh_edges(self.triangles)
        return self._edges

    @property
    def graph(self):
        """The (N, N) edge graph (scipy CSR), built on first use."""
        if self._graph is None:
            self._graph = _graph.edge_graph(self.points, self.edges)
        return self._graph

    @property
    def marching(self):
        """The fast-marching update tables (:class:`usdface.distance.marching.MarchingMesh`), built
        on first use."""
        if self._marching is None:
            from .marching import MarchingMesh
            self._marching = MarchingMesh(self.points, self.triangles)
        return self._marching

    def memory_estimate(self, n_sources: int) -> tuple[int, str]:
        """Bytes a :meth:`solve` with ``n_sources`` sources needs at its peak, and what they are.

        Counts the (N, S) result (and the copies the back-end makes), the search structures not
        built yet (edge graph, fast-marching tables) and the scratch of the searches running in
        parallel (one per numba thread). Heat and exact add their solver's own memory, roughly.
        """
        from .euclidean import fmt_bytes
        from .marching import marching_mesh_bytes, search_bytes

        n, s, t = self.n_points, int(n_sources), self.triangles.shape[0]
        item = np.dtype(self.dtype).itemsize
        matrix = n * s * item
        threads = _graph._nb.get_num_threads() if _graph.HAVE_NUMBA else 1
        threads = max(1, min(threads, s))
        parts = {"matrix": matrix}
        if self.backend == "graph":
            if self._graph is None:
                parts["edge graph"] = 2 * self.edges.shape[0] * 12 + 8 * (n + 1)
            parts["search scratch"] = threads * n * 9
        elif self.backend == "fmm":
            parts["source rows"] = matrix               # a row per source, then the vertex-major matrix
            if self._marching is None:
                parts["marching tables"] = marching_mesh_bytes(n, t)
            parts["search scratch"] = threads * search_bytes(n)
        else:
            parts["matrix"] = 2 * matrix + n * s * 8        # float64 fields, then the transposed copy
            # potpourri3d's factorisation / pygeodesic's windows, roughly, per vertex
            parts["solver"] = n * (400 if self.backend == "heat" else 2000)
        total = int(sum(parts.values()))
        return total, " + ".join(f"{k} {fmt_bytes(v)}" for k, v in parts.items())

    def source_components(self, source_tri_vertices, source_barycentrics=None) -> np.ndarray:
        """(S,) connected component of each source (0 = largest component)."""
        tri = np.asarray(source_tri_vertices, dtype=np.int64).reshape(-1, 3)
        return self.component_labels[tri[:, 0]]

    # -------------------------------------------------------------------------------------------
    def distances(self, source_tri_vertices, source_barycentrics, *, names=None) -> np.ndarray:
        """(N, S) distance from every vertex to every source point (mesh units)."""
        return self.solve(source_tri_vertices, source_barycentrics, names=names).vertex

    def at_sources(self, source_tri_vertices, source_barycentrics, *, names=None) -> np.ndarray:
        """(S, S) distances between the source points themselves, float64.

        Computed exactly at the points, not interpolated: ``"graph"`` reaches each point through
        its sink node (exact graph distance); ``"heat"`` and ``"exact"`` read their fields at the
        vertex inserted for the point. Row i, column j = source j's distance evaluated at source i.
        """
        return self.solve(source_tri_vertices, source_barycentrics, names=names).sources

    def solve(self, source_tri_vertices, source_barycentrics, *, names=None, needed=None,
              max_distance: float | None = None) -> GeodesicResult:
        """Both matrices in one pass (``distances`` and ``at_sources`` share it; the last result is cached).

        Parameters
        ----------
        source_tri_vertices : array_like, shape (S, 3), int
        source_barycentrics : array_like, shape (S, 3), float
        names : sequence of str, optional
            Marker names for messages.
        needed : array_like of bool, shape (N,), optional
            Only these vertices' distances are needed (the hybrid's geodesic region): ``"graph"``
            stops each search once they are all settled, ``"exact"`` stops its propagation at
            them; ``"heat"`` computes everything anyway. Other entries may be +inf.
        max_distance : float, optional
            Bound the searches: entries farther than this (mesh units) are +inf. ``"graph"`` and
            ``"fmm"`` stop each search there (a Gaussian kernel of width s needs distances up to a
            few s only); ``"heat"`` and ``"exact"`` compute everything and clear the far entries.
            A bound at least the bounding-box diagonal of the mesh would visit (nearly) every
            vertex anyway: the searches then run unbounded, and the report says so.

        Returns
        -------
        GeodesicResult
        """
        t0 = time.perf_counter()
        tri, bary, names = validate_sources(self.n_points, source_tri_vertices, source_barycentrics, names=names)
        need = None
        if needed is not None:
            need = np.asarray(needed, dtype=bool).reshape(-1)
            if need.size != self.n_points:
                raise InputError(f"needed mask has {need.size} entries for {self.n_points} vertices")
        bound = None
        fallback_note = None
        if max_distance is not None:
            try:
                bound = float(max_distance)
            except (TypeError, ValueError):
                raise OptionError(f"max_distance must be a positive number (mesh units); got {max_distance!r}") from None
            if not bound > 0:
                raise OptionError(f"max_distance must be a positive number (mesh units); got {max_distance!r}")
            diag = float(np.linalg.norm(np.ptp(self.points, axis=0)))
            if bound >= diag:
                fallback_note = (f"max_distance {bound:.4g} is at least the mesh's bounding-box diagonal "
                                 f"({diag:.4g}): a bounded search would visit (nearly) every vertex, so the "
                                 f"searches ran unbounded")
                bound = None
        key = (tri.tobytes(), bary.tobytes(), None if need is None else np.packbits(need).tobytes(), bound)
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        s = tri.shape[0]
        n = self.n_points
        src_comp = self.component_labels[tri[:, 0]]
        bad = np.flatnonzero((self.component_labels[tri] != src_comp[:, None]).any(axis=1))
        if bad.size:
            raise InputError(f"sources {list_names([names[i] for i in bad])}: triangle vertices lie on "
                             f"different connected components (not a triangle of the mesh)")
        comps = np.unique(src_comp)
        if self.components == "error" and comps.size > 1:
            parts = []
            for c in comps:
                members = [names[i] for i in np.flatnonzero(src_comp == c)]
                size = int((self.component_labels == c).sum())
                parts.append(f"component {c} ({size} vertices): {list_names(members)}")
            raise ComputeError(
                f"markers are bound on {comps.size} different connected components of the mesh, so "
                f"geodesic distances between them are infinite: {'; '.join(parts)}. Bind all markers "
                f"on one component, or use components='euclidean' to fall back to Euclidean "
                f"distance across components")
        estimate, detail = self.memory_estimate(s)
        check_matrix_memory(n, s, self.dtype, what=f"{self.backend} geodesic distances", copies=0.0,
                            extra_bytes=estimate, detail=detail, memory_limit=self.memory_limit)
        report = DistanceReport(backend=self.backend, n_vertices=n, n_sources=s,
                                n_components=self.n_components, source_components=src_comp,
                                components_policy=self.components,
                                needed_vertices=None if need is None else int(need.sum()),
                                max_distance=bound, memory_estimate=estimate)
        if fallback_note:
            report.notes.append(fallback_note)
            warn(fallback_note)
        report.setup_seconds, self._setup_unreported = self._setup_unreported, 0.0
        if self.backend == "graph":
            vertex, sources = self._solve_graph(tri, bary, need, report, bound)
        elif self.backend == "fmm":
            vertex, sources = self._solve_fmm(tri, bary, need, report, bound)
        else:
            searched = time.perf_counter()
            vertex, sources = solve_fields(self, tri, bary, need, names, report)
            report.search_seconds = time.perf_counter() - searched
            if bound is not None:
                vertex[vertex > bound] = np.inf
                sources[sources > bound] = np.inf
        vertex, sources = self._apply_component_policy(vertex, sources, tri, bary, src_comp, report)
        report.seconds = time.perf_counter() - t0
        log.info("geodesic %s: %d vertices x %d sources in %.3f s: set-up %.3f s, searches %.3f s "
                 "(%.4f s a source on %d threads)", self.backend, n, s, report.seconds, report.setup_seconds,
                 report.search_seconds, report.search_seconds / max(s, 1), report.threads)
        self.report = report
        result = GeodesicResult(vertex, sources, report)
        self._last = (key, result)
        return result

    # -------------------------------------------------------------------------------------------
    def _solve_graph(self, tri, bary, need, report, bound=None):
        if self._graph is None:
            started = time.perf_counter()
            self._graph = _graph.edge_graph(self.points, self.edges)
            report.setup_seconds += time.perf_counter() - started
        searched = time.perf_counter()
        vertex, sources, settled = _graph.multi_source_shortest_paths(
            self._graph, self.points, tri, bary, needed=need, dtype=self.dtype, engine=self.engine,
            limit=np.inf if bound is None else bound)
        report.search_seconds = time.perf_counter() - searched
        if self.engine != "scipy" and _graph.HAVE_NUMBA:
            report.threads = max(1, min(_graph._nb.get_num_threads(), tri.shape[0]))
        report.settled_fraction = float(settled.sum()) / float(self.n_points * tri.shape[0])
        if need is not None and (self.engine == "scipy" or not _graph.HAVE_NUMBA):
            report.notes.append("scipy engine: full searches (no bounded search without numba)")
        # rows = evaluation point, columns = source (see GeodesicResult.sources)
        return vertex, np.ascontiguousarray(sources.T)

    def _solve_fmm(self, tri, bary, need, report, bound=None):
        from .marching import MarchingMesh, march

        if self._marching is None:
            started = time.perf_counter()
            self._marching = MarchingMesh(self.points, self.triangles)
            report.setup_seconds += time.perf_counter() - started
        searched = time.perf_counter()
        vertex, sources, settled = march(self._marching, self.points, tri, bary, needed=need, dtype=self.dtype,
                                         limit=np.inf if bound is None else bound)
        report.search_seconds = time.perf_counter() - searched
        report.threads = max(1, min(_graph._nb.get_num_threads(), tri.shape[0]))
        report.settled_fraction = float(settled.sum()) / float(self.n_points * tri.shape[0])
        # rows = evaluation point, columns = source (see GeodesicResult.sources)
        return vertex, np.ascontiguousarray(sources.T)

    def _cached(self, kind, c, pts, tris, build):
        key = (kind, int(c), pts.shape[0], tris.shape[0], hash(pts.tobytes()), hash(tris.tobytes()))
        hit = self._field_cache.get((kind, int(c)))
        if hit is not None and hit[0] == key:
            return hit[1]
        obj = build()
        self._field_cache[(kind, int(c))] = (key, obj)  # one per component: a new set replaces it
        return obj

    def _heat_solver(self, c, pts, tris):
        try:
            import potpourri3d as pp3d
        except ImportError as exc:  # pragma: no cover
            raise ComputeError("backend='heat' needs potpourri3d (pip install potpourri3d)") from exc
        tc = auto_t_coef(pts, tris) if self.t_coef == "auto" else float(self.t_coef)

        def build():
            return pp3d.MeshHeatMethodDistanceSolver(pts, tris, t_coef=tc, use_robust=self.use_robust)
        return self._cached("heat", c, pts, tris, build), tc

    def _exact_solver(self, c, pts, tris):
        try:
            from pygeodesic.geodesic import PyGeodesicAlgorithmExact
        except ImportError as exc:  # pragma: no cover
            raise ComputeError("backend='exact' needs pygeodesic (pip install pygeodesic)") from exc

        def build():
            return PyGeodesicAlgorithmExact(pts, tris.astype(np.int32))
        return self._cached("exact", c, pts, tris, build)

    # -------------------------------------------------------------------------------------------
    def _apply_component_policy(self, vertex, sources, tri, bary, src_comp, report):
        labels = self.component_labels
        if self.n_components == 1:
            return vertex, sources
        cross_v = labels[:, None] != src_comp[None, :]
        cross_s = src_comp[:, None] != src_comp[None, :]
        report.unreachable_pairs = int(cross_v.sum())
        report.unreachable_vertices = int((~np.isin(labels, src_comp)).sum())
        if self.components == "euclidean" and (cross_v.any() or cross_s.any()):
            q = source_points(self.points, tri, bary)
            rows = np.flatnonzero(cross_v.any(axis=1))
            e = pairwise_euclidean(self.points[rows], q)
            sub = np.asarray(vertex[rows])
            sub[cross_v[rows]] = e[cross_v[rows]]
            vertex[rows] = sub
            es = pairwise_euclidean(q, q)
            sources[cross_s] = es[cross_s]
            report.euclidean_fallback_pairs = int(cross_v.sum() + cross_s.sum())
            msg = (f"{report.euclidean_fallback_pairs} distances between points on different connected "
                   f"components use the Euclidean distance (components='euclidean'); "
                   f"{report.unreachable_vertices} vertices lie on components without markers")
            report.notes.append(msg)
            warn(msg)
        elif report.unreachable_vertices or cross_s.any():
            msg = (f"{report.unreachable_vertices} vertices lie on connected components holding no source: "
                   f"their distances are +inf (components={self.components!r}; use 'euclidean' to fill them)")
            report.notes.append(msg)
            warn(msg)
        return vertex, sources


def geodesic_distances(points, triangles, source_tri_vertices, source_barycentrics, *,
                       backend: str = DEFAULT_BACKEND, names=None, max_distance: float | None = None,
                       **options) -> tuple[np.ndarray, np.ndarray]:
    """One-call form of :class:`GeodesicSolver`: ``(N, S)`` and ``(S, S)`` geodesic matrices.

    Parameters
    ----------
    points : array_like, shape (N, 3)
    triangles : array_like, shape (T, 3), int
    source_tri_vertices, source_barycentrics : array_like, shape (S, 3)
    backend : {"fmm", "graph", "heat", "exact"}
    names : sequence of str, optional
    max_distance : float, optional
        Bound the searches (mesh units; see :meth:`GeodesicSolver.solve`).
    **options
        Passed to :class:`GeodesicSolver`.

    Returns
    -------
    vertex : ndarray, shape (N, S)
    sources : ndarray, shape (S, S)
    """
    r = GeodesicSolver(points, triangles, backend=backend, **options).solve(
        source_tri_vertices, source_barycentrics, names=names, max_distance=max_distance)
    return r.vertex, r.sources
