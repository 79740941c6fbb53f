"""Skeletal animation from the RBF transfer: joints per marker and their skin weights.

:mod:`usdface.skel.joints` names the joints (valid USD identifiers, with a mapping back to the
marker names) and lays out their rest pose and animation; :mod:`usdface.skel.weights` turns the
N x M transfer matrix into exact, signed weights (for UsdSkel consumers);
:mod:`usdface.skel.dcc` fits the default DCC-safe rig (non-negative weights summing to one, K per
vertex, fitted joint motion and corrective blend shapes) with the batched simplex least squares
of :mod:`usdface.skel.simplex_lsq`. No pxr here: :mod:`usdface.usd.skel_layer` authors the
UsdSkel prims.
"""
from .dcc import DccSkin, fit_dcc_skin, initial_weights, rom_covariance, take_covariance
from .joints import HEAD_JOINT, SkeletonRig, build_rig, head_motion_in_mesh_space, joint_names
from .weights import SkinWeights, full_weights, prune_weights, skinning_error

__all__ = ["DccSkin", "fit_dcc_skin", "initial_weights", "rom_covariance", "take_covariance",
           "HEAD_JOINT", "SkeletonRig", "build_rig", "head_motion_in_mesh_space", "joint_names",
           "SkinWeights", "full_weights", "prune_weights", "skinning_error"]
