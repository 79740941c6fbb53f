"""Skeletal animation from the RBF transfer: joints per marker and their skin weights.

:mod:`usdface.skel.joints` names the joints (valid USD identifiers, with a mapping back to the
marker names) and lays out their rest pose and animation; :mod:`usdface.skel.weights` turns the
N x M transfer matrix into exact, signed weights (for UsdSkel consumers);
:mod:`usdface.skel.dcc` fits the default DCC-safe rig (non-negative weights summing to one, K per
vertex, fitted joint motion and corrective blend shapes) with the batched simplex least squares
of :mod:`usdface.skel.simplex_lsq`; :mod:`usdface.skel.fitting` takes a fitted transfer to the
skin `usdface skel` writes; :mod:`usdface.skel.modes` names the modes and defaults the options
offer. No pxr here: :mod:`usdface.usd.skel_layer` authors the UsdSkel prims. Names load on first
use (the command line reads only :mod:`usdface.skel.modes` at start-up).
"""
from ..lazy import lazy_exports

#: public name -> submodule, loaded on first use
_EXPORTS = {
    "DccSkin": "dcc", "fit_dcc_skin": "dcc", "initial_weights": "dcc", "rom_covariance": "dcc",
    "take_covariance": "dcc", "HEAD_JOINT": "joints", "SkeletonRig": "joints", "build_rig": "joints",
    "head_motion_in_mesh_space": "joints", "capture_head_motion": "joints", "joint_names": "joints",
    "SkinWeights": "weights",
    "full_weights": "weights", "prune_weights": "weights", "skinning_error": "weights",
    "SkelInputs": "fitting", "SkinFit": "fitting", "SkinParameters": "fitting", "apply_matrix": "fitting",
    "effective_displacements": "fitting", "fit_dcc": "fitting", "fit_skin": "fitting", "skel_inputs": "fitting",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())

__all__ = sorted(_EXPORTS)
