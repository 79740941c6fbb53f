"""Distance matrices and fitted transfers of the quality evaluation, built once per mesh and binding."""
from __future__ import annotations

import time
import warnings

import numpy as np

from ..errors import MeshError
from ..model.mesh import Binding, FaceMesh, Region
from .configs import PINS, REGION_RADIUS_CM, TransferConfig
from .regions import evaluation_regions, loop_of, pinned_vertices

__all__ = ["TransferSetup"]

_GEODESIC_ROLES = ("mouth", "eye", "geodesic")


class TransferSetup:
    """Everything a transfer needs on one mesh + binding, built once and shared by many configs.

    Sources are the M bound markers followed by every candidate constraint vertex (the union of
    the pin variants' vertices); each distance kind (euclidean, geodesic per back-end, hybrid per
    back-end and threshold) is computed once over all of them, and a config takes the columns of
    its own pin variant. Column j of every distance kind depends only on source j (a hybrid column
    blends with the *vertex's* weight), so this gives exactly the matrices the pipeline would
    compute for that pin variant.

    Parameters
    ----------
    mesh : FaceMesh
        ``units`` None counts as cm.
    regions : list of Region
    binding : Binding
    region_radius_cm, hybrid_radius_cm, hybrid_sigma_cm, hybrid_threshold : float
        See :func:`evaluate`.

    Attributes
    ----------
    cm : float
        One cm in mesh units.
    regions : EvaluationRegions
    marker_points : ndarray (M, 3)
    spacing : float
        Median nearest-marker Euclidean distance (mesh units): constraint thinning, as the pipeline.
    pins : dict pin -> ndarray of int
        Constraint vertices of each pin variant.
    seconds : dict
        Time spent on each distance kind.
    info : dict TransferConfig -> dict
        What :func:`usdface.rbf.build.build_transfer` reported (amplification, regularisation,
        warnings) for each config transferred.
    """

    def __init__(self, mesh: FaceMesh, regions: list[Region], binding: Binding, *,
                 region_radius_cm: float = REGION_RADIUS_CM, hybrid_radius_cm: float = 1.0,
                 hybrid_sigma_cm: float = 2.0, hybrid_threshold: float = 0.6) -> None:
        from ..rbf.stiffness import median_marker_spacing_from_points
        from ..units import scale_between

        if binding.triangle_vertices.max() >= mesh.n_points:
            raise MeshError(f"binding refers to vertex {int(binding.triangle_vertices.max())} but mesh "
                            f"{mesh.source or mesh.name} has {mesh.n_points} vertices")
        self.mesh = mesh
        self.region_list = list(regions)
        self.binding = binding
        self.units = mesh.units or "cm"
        self.cm = scale_between("cm", self.units)
        self.hybrid_radius_cm = float(hybrid_radius_cm)
        self.hybrid_sigma_cm = float(hybrid_sigma_cm)
        self.hybrid_threshold = float(hybrid_threshold)
        self.region_radius_cm = float(region_radius_cm)
        self.regions = evaluation_regions(mesh, regions, radius=region_radius_cm * self.cm)
        pts = mesh.points
        M = binding.n_markers
        self.n_markers = M
        self.marker_points = binding.surface_points(pts)
        self.spacing = median_marker_spacing_from_points(self.marker_points)
        self.pins = pinned_vertices(pts, regions, self.marker_points, spacing=self.spacing,
                                    corner_y=self.regions.corner_y)
        cand = np.unique(np.concatenate([self.pins[p] for p in PINS]))
        self._col_of = {int(v): M + i for i, v in enumerate(cand)}
        self._src_tri = np.concatenate([binding.triangle_vertices, np.repeat(cand[:, None], 3, axis=1)])
        self._src_bary = np.concatenate([binding.barycentrics, np.tile([1.0, 0.0, 0.0], (cand.size, 1))])
        self._seeds = [loop_of(r) for r in regions if r.role in _GEODESIC_ROLES]
        self._cache: dict = {}
        self._solvers: dict = {}
        self.seconds: dict = {}
        #: what :func:`usdface.rbf.build.build_transfer` reported for each config transferred
        self.info: dict = {}

    def distance_key(self, cfg: TransferConfig) -> tuple:
        if cfg.method == "euclidean":
            return ("euclidean",)
        if cfg.method == "geodesic":
            return ("geodesic", cfg.backend)
        return ("hybrid", cfg.backend, self.hybrid_threshold if cfg.threshold is None else float(cfg.threshold))

    def matrices(self, cfg: TransferConfig) -> tuple[np.ndarray, np.ndarray]:
        """(D_vc (N, M + P_all), D_cc) of ``cfg``'s distance over every candidate source (mesh units)."""
        from ..distance import GeodesicSolver, euclidean_at_sources, euclidean_distances, hybrid_distances

        key = self.distance_key(cfg)
        if key in self._cache:
            return self._cache[key]
        t0 = time.perf_counter()
        pts, tri, bary = self.mesh.points, self._src_tri, self._src_bary
        if cfg.method == "euclidean":
            dv = euclidean_distances(pts, tri, bary)
            dc = euclidean_at_sources(pts, tri, bary)
        else:
            if cfg.backend not in self._solvers:
                self._solvers[cfg.backend] = GeodesicSolver.from_mesh(self.mesh, backend=cfg.backend)
            solver = self._solvers[cfg.backend]
            if cfg.method == "geodesic":
                res = solver.solve(tri, bary)
                dv, dc = res.vertex, res.sources
            else:
                if not self._seeds:
                    raise MeshError("hybrid distances need mouth/eye (or geodesic) regions; none found on mesh "
                                    f"{self.mesh.source or self.mesh.name}")
                hyb = hybrid_distances(solver, tri, bary, self._seeds, radius=self.hybrid_radius_cm * self.cm,
                                       sigma=self.hybrid_sigma_cm * self.cm, threshold=key[2])
                dv, dc = hyb.vertex, hyb.sources
        dv = np.asarray(dv, dtype=np.float64)
        dc = np.asarray(dc, dtype=np.float64)
        if not np.isfinite(dv).all():
            raise MeshError(f"{cfg.method_label} distances: some vertices are unreachable from some markers")
        self._cache[key] = (dv, dc)
        self.seconds["/".join(str(k) for k in key)] = round(time.perf_counter() - t0, 4)
        return dv, dc

    def constraints(self, cfg: TransferConfig) -> np.ndarray:
        """Constraint vertices ``cfg`` uses (none beyond pinned/rigid regions in paper mode)."""
        return self.pins["none"] if cfg.mode == "paper" else self.pins[cfg.pin]

    def _columns(self, cfg: TransferConfig) -> np.ndarray:
        cons = self.constraints(cfg)
        return np.concatenate([np.arange(self.n_markers), [self._col_of[int(v)] for v in cons]]).astype(np.int64)

    def min_eigenvalue(self, cfg: TransferConfig, widths) -> float | None:
        """Smallest eigenvalue of the symmetric part of ``cfg``'s kernel matrix Phi_cc.

        Only for the positive-definite-for-Euclidean kernels (gaussian, inverse multiquadric): a
        negative value means the kernel is not positive definite on these distances (geodesic
        distances are not Euclidean), so the interpolating solve can ring or blow up. None for
        other kernels.
        """
        from ..rbf.kernels import get_kernel

        if cfg.kernel not in ("gaussian", "inverse_multiquadric"):
            return None
        _, dc = self.matrices(cfg)
        cols = self._columns(cfg)
        if cfg.mode == "paper":
            cols = cols[: self.n_markers]
        phi = get_kernel(cfg.kernel)(dc[np.ix_(cols, cols)], np.asarray(widths)[: cols.size])
        return float(np.linalg.eigvalsh(0.5 * (phi + phi.T)).min())

    def transfer(self, cfg: TransferConfig):
        """The fitted :class:`usdface.rbf.RBFTransfer` of ``cfg``, built as the pipeline builds it
        (:func:`usdface.rbf.build.build_transfer`: kernel check, polynomial, width rule, automatic
        regularisation); runtime warnings silenced, what they said is in :attr:`info` ``[cfg]``.

        Raises
        ------
        OptionError
            ``cfg.check`` and a kernel with no well-posed variant on ``cfg.method``.
        """
        from ..rbf.build import TransferGeometry, TransferSettings, build_transfer
        from ..rbf.stiffness import DEFAULT_WIDTH_FACTOR

        dv, dc = self.matrices(cfg)
        cons = self.constraints(cfg)
        cols = self._columns(cfg)
        if cfg.width_cm is not None:
            stiffness, rule = cfg.width_cm * self.cm, None
        elif cfg.width_rule == "legacy":
            stiffness, rule = DEFAULT_WIDTH_FACTOR * self.spacing, None
        else:
            stiffness, rule = None, cfg.width_rule
        settings = TransferSettings(mode=cfg.mode, kernel=cfg.kernel, stiffness=stiffness, width_rule=rule,
                                    regularization=cfg.regularization, polynomial=cfg.polynomial, check=cfg.check)
        geometry = TransferGeometry(
            marker_points=self.marker_points, centre_points=np.concatenate([self.marker_points, self.mesh.points[cons]]),
            vertex_points=self.mesh.points, marker_names=tuple(self.binding.names),
            # as the pipeline: exact at the bound points on the mesh
            collocation=(self.binding.triangle_vertices, self.binding.barycentrics))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            solver, info = build_transfer(dv[:, cols], dc[np.ix_(cols, cols)], cfg.method, settings=settings,
                                          geometry=geometry)
        self.info[cfg] = info
        return solver

    def predict(self, cfg: TransferConfig, displacements, *, dtype=np.float64) -> np.ndarray:
        """Vertex displacements (F, N, 3) (mesh units) for marker displacements (F, M, 3)."""
        return self.transfer(cfg).apply(displacements, dtype=dtype)
