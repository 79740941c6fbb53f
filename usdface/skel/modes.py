"""The skeletal deliverable's modes and defaults, named once (the options offer these; the fitting
in :mod:`usdface.skel.fitting`, :mod:`usdface.skel.dcc` and :mod:`usdface.skel.weights` implements
them). Plain constants: the command line reads them at start-up."""

#: skin weights: "dcc" non-negative, summing to one, K per vertex, with corrective shapes (what
#: Blender, Maya and game engines take as they are); "exact" the signed transfer matrix (UsdSkel only)
SKIN_WEIGHTS = ("dcc", "exact")
DEFAULT_SKIN_WEIGHTS = "dcc"
#: the deprecated --negative-weights values and the --skin-weights they mean
NEGATIVE_WEIGHTS_ALIAS = {"keep": "exact", "clamp": "dcc"}
#: joints per vertex, root included (Unreal takes 8; many game pipelines 4)
DEFAULT_MAX_INFLUENCES = 8
#: other numbers of influences whose point-cache error the summary reports
REPORT_INFLUENCES = (4, 8)
#: what the DCC-safe weights are fitted on: the synthetic range of motion (the character's
#: weights, the same for every take) or the take's own marker motion
SKIN_FITS = ("rom", "take")
DEFAULT_SKIN_FIT = "rom"
#: exact weights pruned to K: refitted by least squares over the take, or rescaled to sum to one
FIT_METHODS = ("lsq", "renormalize")
DEFAULT_FIT_METHOD = "lsq"
#: corrective blend shapes by default (the simplex of 15 directions, five per axis); at most MAX_SHAPES
DEFAULT_SHAPES = 16
MAX_SHAPES = 16
