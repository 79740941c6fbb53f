"""The distance methods and geodesic back-ends, named once (the options and the command line offer
these; :class:`usdface.distance.GeodesicSolver` implements the back-ends)."""

#: distance methods: Euclidean (paper Eq. 6), geodesic (Eq. 7), hybrid (Eq. 8)
METHODS = ("euclidean", "geodesic", "hybrid")
#: geodesic back-ends: shortest edge paths (the paper's), fast marching, heat method, exact MMP
BACKENDS = ("graph", "fmm", "heat", "exact")
#: the paper's edge paths (README: why not fmm)
DEFAULT_BACKEND = "graph"
#: region roles whose vertices seed the hybrid's geodesic regions (paper Fig. 5: mouth and eyes)
GEODESIC_ROLES = ("mouth", "eye", "geodesic")
