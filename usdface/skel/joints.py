"""Joints of the marker skeleton: names, rest/bind transforms and per-frame animation.

The skeleton is one static root joint and one translation-only joint per marker, children of
the root::

    Head                     root: the head's rigid part; never moves in mesh space (the head
                             motion is the /Face prim's transform, see the skeleton layer)
    Head/<marker joint>      at the marker's bound surface point; animated by a translation

Joints and their bind/rest transforms are in mesh space (the Skeleton prim has no transform and
the mesh's geomBindTransform is the identity). Matrices here are column-vector 4x4 numpy arrays
(``p' = M @ [p, 1]``); the USD layer code converts them. With linear blend skinning the skinning
transform of joint j is ``M_j = world_j(t) @ inverse(bind_j)``: the identity for the root and a
translation by ``tau_j(t)`` for marker joint j, so a vertex with weights summing to one skins to
``p + sum_j w_j tau_j(t)``. Which translations the marker joints get depends on the weights: the
marker displacements themselves for the exact signed weights, a fitted blend of them for the
DCC-safe weights (:mod:`usdface.skel.dcc`).
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..errors import MarkerError, list_names

HEAD_JOINT = "Head"
_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def sanitize_identifier(name: str) -> str:
    """A valid USD identifier (``[A-Za-z_][A-Za-z0-9_]*``) close to ``name``.

    Every character outside ``[A-Za-z0-9_]`` becomes ``_``; a leading digit (or an empty name)
    gets an ``_`` prefix. ``"Lip.Upper-1"`` -> ``"Lip_Upper_1"``, ``"3D"`` -> ``"_3D"``.
    """
    s = re.sub(r"[^A-Za-z0-9_]", "_", str(name))
    if not s or s[0].isdigit():
        s = "_" + s
    return s


def joint_names(marker_names, *, head: str = HEAD_JOINT) -> tuple[list[str], dict[str, str]]:
    """Joint names for the markers: valid identifiers, unique, never the head joint's name.

    Returns
    -------
    names : list of str, length M
        Joint name per marker (sanitised; collisions get ``_2``, ``_3``... suffixes).
    mapping : dict joint name -> marker name
        Only the joints whose name differs from their marker's.
    """
    used = {head}
    names, mapping = [], {}
    for marker in marker_names:
        base = sanitize_identifier(marker)
        name, k = base, 2
        while name in used:
            name, k = f"{base}_{k}", k + 1
        used.add(name)
        names.append(name)
        if name != marker:
            mapping[name] = str(marker)
    return names, mapping


def head_motion_in_mesh_space(head_motion: np.ndarray, capture_to_mesh: np.ndarray) -> np.ndarray:
    """The capture's head motion (capture space, column vectors) as rigid motions in mesh space.

    ``H_mesh(t) = C @ H(t) @ C^-1`` with C the binding's capture-to-mesh similarity: the actor's
    head rotation about the actor's (mapped) head, and the translation scaled like the face. The
    similarity's scale cancels in the rotation, so H_mesh is rigid.

    Parameters
    ----------
    head_motion : ndarray, shape (F, 4, 4)
    capture_to_mesh : ndarray, shape (4, 4)

    Returns
    -------
    ndarray, shape (F, 4, 4), float64
    """
    c = np.asarray(capture_to_mesh, dtype=np.float64)
    return np.einsum("ij,fjk,kl->fil", c, np.asarray(head_motion, dtype=np.float64), np.linalg.inv(c))


def capture_head_motion(capture, capture_to_mesh: np.ndarray) -> np.ndarray | None:
    """The head motion a stabilised capture removed, in mesh space and relative to its neutral
    frame: ``H_mesh(f) = C H(n)^-1 H(f) C^-1`` (decision D1; identity on the neutral frame n, whose
    head pose the conditioning stabilises on; see :func:`usdface.capture.retarget.mesh_head_motion`),
    as the skeleton and the blend-shape curves carry it on /Face.

    Parameters
    ----------
    capture : usdface.model.capture.Capture
        Its ``head_motion`` (F, 4, 4) (capture space, column vectors) or None, and ``neutral_frame``.
    capture_to_mesh : ndarray, shape (4, 4)
        The binding's capture-to-mesh similarity C.

    Returns
    -------
    ndarray (F, 4, 4) float64, or None when the capture was not stabilised.
    """
    if capture.head_motion is None:
        return None
    n = capture.neutral_frame
    rel = np.einsum("ij,fjk->fik", np.linalg.inv(capture.head_motion[n]), capture.head_motion)
    return head_motion_in_mesh_space(rel, capture_to_mesh)


@dataclass(frozen=True)
class SkeletonRig:
    """The marker skeleton and its animation (mesh space, mesh units).

    Attributes
    ----------
    marker_names : tuple of str, length M
    joint_names : tuple of str, length M
        Marker joint names (valid identifiers), in marker order.
    joint_paths : tuple of str, length M + 1
        UsdSkel joint paths: ``"Head"`` then ``"Head/<joint>"`` per marker.
    name_mapping : dict joint -> marker
        Joints renamed from their marker name.
    head_pivot : ndarray (3,)
        Rest position of the root joint.
    bound_points : ndarray (M, 3)
        Rest (bind) position of each marker joint: its bound surface point.
    joint_translations : ndarray (F, M, 3)
        Marker joint translation per frame (mesh units); no NaN.
    """

    marker_names: tuple
    joint_names: tuple
    joint_paths: tuple
    name_mapping: dict
    head_pivot: np.ndarray
    bound_points: np.ndarray
    joint_translations: np.ndarray

    @property
    def n_joints(self) -> int:
        return len(self.joint_paths)

    @property
    def n_frames(self) -> int:
        return self.joint_translations.shape[0]

    def bind_transforms(self) -> np.ndarray:
        """(J, 4, 4) mesh-space bind transforms: the root at its pivot, markers at bound points."""
        out = np.tile(np.eye(4), (self.n_joints, 1, 1))
        out[0, :3, 3] = self.head_pivot
        out[1:, :3, 3] = self.bound_points
        return out

    def rest_transforms(self) -> np.ndarray:
        """(J, 4, 4) joint-local rest transforms (markers relative to the root)."""
        out = self.bind_transforms()
        out[1:, :3, 3] -= self.head_pivot
        return out

    def local_animation(self) -> np.ndarray:
        """(F, J, 3) joint-local translations per frame for the SkelAnimation (rotations are all
        the identity and scales all one): the root stays at its pivot."""
        trans = np.empty((self.n_frames, self.n_joints, 3))
        trans[:, 0] = self.head_pivot
        trans[:, 1:] = self.bound_points[None] - self.head_pivot + self.joint_translations
        return trans

    def skinning_transforms(self) -> np.ndarray:
        """(F, J, 4, 4) skinning transforms ``world_j(t) @ inverse(bind_j)`` (numpy reference)."""
        out = np.tile(np.eye(4), (self.n_frames, self.n_joints, 1, 1))
        out[:, 1:, :3, 3] = self.joint_translations
        return out


def build_rig(marker_names, bound_points, joint_translations, *, head_pivot=None) -> SkeletonRig:
    """Assemble the :class:`SkeletonRig`.

    Parameters
    ----------
    marker_names : sequence of str, length M
    bound_points : array (M, 3)
        Bound surface points (mesh space, mesh units).
    joint_translations : array (F, M, 3)
        Per-frame marker joint translations (mesh space, mesh units); must be finite (the
        caller resolves missing samples).
    head_pivot : array (3,), optional
        Rest position of the root joint (default: centroid of the bound points).
    """
    names = tuple(str(n) for n in marker_names)
    pts = np.asarray(bound_points, dtype=np.float64)
    tr = np.asarray(joint_translations, dtype=np.float64)
    if pts.shape != (len(names), 3) or tr.ndim != 3 or tr.shape[1:] != (len(names), 3):
        raise MarkerError(f"skeleton: {len(names)} markers but bound points {pts.shape} and translations {tr.shape}")
    bad = ~np.isfinite(tr).all(axis=(0, 2))
    if bad.any():
        raise MarkerError(f"skeleton: marker joint translations are not finite for {list_names(np.array(names)[bad])}")
    joints, mapping = joint_names(names)
    pivot = pts.mean(axis=0) if head_pivot is None else np.asarray(head_pivot, dtype=np.float64)
    return SkeletonRig(marker_names=names, joint_names=tuple(joints),
                       joint_paths=(HEAD_JOINT,) + tuple(f"{HEAD_JOINT}/{j}" for j in joints),
                       name_mapping=mapping, head_pivot=pivot, bound_points=pts, joint_translations=tr)
