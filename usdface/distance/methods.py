"""The distance methods and geodesic back-ends, named once (the options and the command line offer
these; :class:`usdface.distance.GeodesicSolver` implements the back-ends)."""

#: distance methods: Euclidean (paper Eq. 6), geodesic (Eq. 7), hybrid (Eq. 8)
METHODS = ("euclidean", "geodesic", "hybrid")
#: geodesic back-ends: shortest edge paths (the paper's), fast marching, heat method, exact MMP
BACKENDS = ("graph", "fmm", "heat", "exact")
#: fast marching: within 0.03% of exact geodesics (edge paths run 8-15% long), and at the default
#: width rule it transfers at least as well as edge paths on the held-out shapes (mouth, jaw: hybrid
#: 31.7% against 33.3% mesh error; README "Transfer quality")
DEFAULT_BACKEND = "fmm"
#: the paper's edge paths (Eq. 7): `run --rbf paper` keeps them unless --backend says otherwise
PAPER_BACKEND = "graph"


def default_backend(rbf: str = "interpolate") -> str:
    """The geodesic back-end of an RBF mode when none is named: :data:`PAPER_BACKEND` for the
    paper's Eqs. 1-5, :data:`DEFAULT_BACKEND` otherwise."""
    return PAPER_BACKEND if rbf == "paper" else DEFAULT_BACKEND
#: region roles whose vertices seed the hybrid's geodesic regions (paper Fig. 5: mouth and eyes)
GEODESIC_ROLES = ("mouth", "eye", "geodesic")
