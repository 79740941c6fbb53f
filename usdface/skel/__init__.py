"""Skeletal animation from the RBF transfer: joints per marker, skin weights from the transfer matrix.

:mod:`usdface.skel.joints` names the joints (valid USD identifiers, with a mapping back to the
marker names) and computes their animation; :mod:`usdface.skel.weights` turns the N x M transfer
matrix into linear-blend-skinning weights (head remainder, pruning to K influences, the
negative-weight policy). No pxr here: :mod:`usdface.usd.skel_layer` authors the UsdSkel prims.
"""
from .joints import HEAD_JOINT, SkeletonRig, build_rig, head_motion_in_mesh_space, joint_names
from .weights import NEGATIVE_POLICIES, SkinWeights, full_weights, prune_weights, skinning_error

__all__ = ["HEAD_JOINT", "SkeletonRig", "build_rig", "head_motion_in_mesh_space", "joint_names",
           "NEGATIVE_POLICIES", "SkinWeights", "full_weights", "prune_weights", "skinning_error"]
