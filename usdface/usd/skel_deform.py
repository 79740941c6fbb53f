"""How UsdSkel deforms one mesh: blend shapes, then linear / dual-quaternion or rigid skinning.

The deformation half of the face reader (:class:`usdface.usd.face_evaluator.FaceEvaluator`), through
UsdSkel itself (``UsdSkel.Cache``, ``SkeletonQuery.ComputeSkinningTransforms``,
``BlendShapeQuery``, ``UsdSkel.SkinPoints``): a mesh is skinned only under a ``SkelRoot`` with a
bound Skeleton that has a bind pose, blend shapes apply only when the Skeleton's animation has
``blendShapes`` weights, joint and blend-shape orders are remapped from the animation to the mesh,
rigid (constant-interpolation) influences move the whole mesh.
"""
from __future__ import annotations

import logging

import numpy as np
from pxr import Gf, Usd, UsdSkel, Vt

from ..errors import InputError

__all__ = ["SkelDeformation"]

log = logging.getLogger("usdface")


class SkelDeformation:
    """What UsdSkel does to the points of mesh ``prim`` (nothing when it is not skinned).

    Parameters
    ----------
    prim : Usd.Prim
        The mesh.
    n_points : int
        Its point count (checked against the joint influences).
    source : str
        Name used in error messages.

    Attributes
    ----------
    skinning_method : str or None (``"classicLinear"``, ``"dualQuaternion"``)
    joints : list of str, the skeleton's joint order ([] without skinning)
    blend_shapes : list of str, the mesh's ``skel:blendShapes`` order ([] without blend shapes)
    skel_prim : Usd.Prim or None, the bound Skeleton
    steps : tuple of str, ``"blendShapes"``, ``"skinning"`` or ``"rigidSkinning"`` in order of
        application
    """

    def __init__(self, prim: Usd.Prim, *, n_points: int, source: str):
        self.prim, self.n_points, self.source = prim, n_points, source
        self.mesh_path = str(prim.GetPath())
        self.skinning_method = None
        self.joints: list[str] = []
        self.blend_shapes: list[str] = []
        self.lbs = self.rigid = self.blend = False
        self.skel_prim = None
        found = self._queries()
        if found is not None:
            skin, skel_query, binding = found
            self._skin, self._skel_query = skin, skel_query
            self._anim_query = skel_query.GetAnimQuery()
            self.skel_prim = skel_query.GetPrim()
            self._setup_skinning()
            self._setup_blend_shapes(binding)

    # -- set-up ----------------------------------------------------------------------------------

    def _queries(self):
        """(SkinningQuery, SkeletonQuery, BindingAPI) of the mesh, or None when UsdSkel does not
        deform it (with a warning when it carries skinning data anyway)."""
        prim = self.prim
        binding = UsdSkel.BindingAPI(prim)
        has_influences = prim.HasAPI(UsdSkel.BindingAPI) and (
            binding.GetJointIndicesPrimvar().HasAuthoredValue() or binding.GetBlendShapesAttr().HasAuthoredValue())
        root = UsdSkel.Root.Find(prim)
        if not root:
            if has_influences:
                log.warning("%s: %s has skin weights or blend shapes but no SkelRoot ancestor; UsdSkel does not "
                            "deform it (evaluating its authored points)", self.source, self.mesh_path)
            return None
        cache = UsdSkel.Cache()
        cache.Populate(root, Usd.TraverseInstanceProxies())
        skin = cache.GetSkinningQuery(prim)
        skeleton = binding.GetInheritedSkeleton()
        skel_query = cache.GetSkelQuery(skeleton) if skeleton else None
        if not skin or not skel_query:
            if has_influences:
                log.warning("%s: %s is under the SkelRoot %s but bound to no valid Skeleton; UsdSkel does not "
                            "deform it", self.source, self.mesh_path, root.GetPath())
            return None
        return skin, skel_query, binding

    def _setup_skinning(self) -> None:
        skin, skel_query = self._skin, self._skel_query
        if not (skin.HasJointInfluences() and skel_query.HasBindPose()):
            return
        self.rigid = skin.IsRigidlyDeformed()
        self.lbs = not self.rigid
        self.skinning_method = str(skin.GetSkinningMethod())
        self.joints = [str(j) for j in skel_query.GetJointOrder()]
        self._joint_mapper = skin.GetJointMapper()
        if self._joint_mapper is not None and self._joint_mapper.IsIdentity():
            self._joint_mapper = None
        self._influences_vary = (skin.GetJointIndicesPrimvar().ValueMightBeTimeVarying()
                                 or skin.GetJointWeightsPrimvar().ValueMightBeTimeVarying())
        self._influences = skin.ComputeJointInfluences(Usd.TimeCode.Default())
        if self._influences is None:
            raise InputError(f"{self.source}: the joint influences of {self.mesh_path} are invalid "
                             "(primvars:skel:jointIndices / jointWeights)")
        self._n_influences = skin.GetNumInfluencesPerComponent()
        if not self.rigid and len(self._influences[0]) != self.n_points * self._n_influences:
            raise InputError(f"{self.source}: {self.mesh_path} has {len(self._influences[0])} joint indices "
                             f"for {self.n_points} points x {self._n_influences} influences")

    def _setup_blend_shapes(self, binding) -> None:
        skin = self._skin
        if not (skin.HasBlendShapes() and self._anim_query and len(self._anim_query.GetBlendShapeOrder())):
            return
        query = UsdSkel.BlendShapeQuery(binding)
        offsets = query.ComputeSubShapePointOffsets()
        if query.GetNumBlendShapes() and any(len(o) for o in offsets):
            self.blend = True
            self._bs_query = query
            self._bs_offsets = offsets
            self._bs_indices = query.ComputeBlendShapePointIndices()
            self._bs_mapper = skin.GetBlendShapeMapper()
            self.blend_shapes = [str(b) for b in (skin.GetBlendShapeOrder() or [])]

    # -- what it is ------------------------------------------------------------------------------

    @property
    def skinned(self) -> bool:
        return self.lbs or self.rigid

    @property
    def steps(self) -> tuple:
        return tuple(name for name, on in (("blendShapes", self.blend), ("skinning", self.lbs),
                                           ("rigidSkinning", self.rigid)) if on)

    def time_samples(self) -> set[float]:
        """Time codes at which the deformation may change (joint animation, blend-shape weights,
        influences, geomBindTransform); the skeleton's ancestors' transforms are the caller's."""
        times: set[float] = set()
        if self.skinned:
            if self._anim_query:
                times.update(self._anim_query.GetJointTransformTimeSamples())
            # (SkinningQuery.GetTimeSamples throws when geomBindTransform is not authored)
            for attr in (self._skin.GetJointIndicesPrimvar().GetAttr(), self._skin.GetJointWeightsPrimvar().GetAttr(),
                         self._skin.GetGeomBindTransformAttr()):
                if attr:
                    times.update(attr.GetTimeSamples())
        if self.blend:
            times.update(self._anim_query.GetBlendShapeWeightTimeSamples())
        return times

    # -- queries ---------------------------------------------------------------------------------

    def geom_bind_transform(self, tc: Usd.TimeCode) -> Gf.Matrix4d:
        return self._skin.GetGeomBindTransform(tc)

    def blend_shape_weights(self, tc: Usd.TimeCode) -> np.ndarray:
        """(B,) float32 weights in the mesh's ``blend_shapes`` order."""
        if not self.blend:
            return np.zeros(0, dtype=np.float32)
        return np.asarray(self._remapped_weights(self._anim_query.ComputeBlendShapeWeights(tc)), dtype=np.float32)

    def _remapped_weights(self, weights):
        if self._bs_mapper is not None and not self._bs_mapper.IsIdentity():
            weights = self._bs_mapper.Remap(weights)
        return weights

    def skinning_transforms(self, tc: Usd.TimeCode):
        """The skinning transforms (inverse bind times joint, skeleton space, Gf row-vector) in
        the mesh's joint order."""
        xforms = self._skel_query.ComputeSkinningTransforms(tc)
        if xforms is None:
            raise InputError(f"{self.source}: UsdSkel cannot compute the skinning transforms of "
                             f"{self.skel_prim.GetPath()} at time {tc.GetValue():g}")
        if self._joint_mapper is not None:
            xforms = self._joint_mapper.RemapTransforms(xforms, Vt.Matrix4dArray())
        return xforms

    def _apply_blend_shapes(self, pts: Vt.Vec3fArray, tc: Usd.TimeCode) -> None:
        weights = self._anim_query.ComputeBlendShapeWeights(tc)
        if weights is None:
            return
        weights = self._remapped_weights(weights)
        sub_weights, shape_idx, sub_idx = self._bs_query.ComputeSubShapeWeights(Vt.FloatArray(weights))
        if not self._bs_query.ComputeDeformedPoints(sub_weights, shape_idx, sub_idx, self._bs_indices,
                                                    self._bs_offsets, pts):
            raise InputError(f"{self.source}: UsdSkel could not apply the blend shapes of {self.mesh_path} at "
                             f"time {tc.GetValue():g} (point indices or offsets out of range?)")

    def deform(self, pts: Vt.Vec3fArray, tc: Usd.TimeCode) -> Gf.Matrix4d | None:
        """Deform ``pts`` (mesh space) in place: into skeleton space when skinned. Returns, for
        rigid skinning, the row-vector transform UsdSkel gives the whole mesh (else None)."""
        if self.blend:
            self._apply_blend_shapes(pts, tc)
        if self.lbs:
            indices, weights = self._influences
            if self._influences_vary:
                indices, weights = self._skin.ComputeJointInfluences(tc)
            gbind = self._skin.GetGeomBindTransform(tc)
            if not UsdSkel.SkinPoints(self._skin.GetSkinningMethod(), gbind, self.skinning_transforms(tc), indices,
                                      weights, self._n_influences, pts, False):
                raise InputError(f"{self.source}: UsdSkel could not skin {self.mesh_path} at time "
                                 f"{tc.GetValue():g} (joint indices out of range?)")
            return None
        if self.rigid:
            # the query remaps the skeleton's joint order to the mesh's itself
            return self._skin.ComputeSkinnedTransform(self._skel_query.ComputeSkinningTransforms(tc), tc)
        return None
