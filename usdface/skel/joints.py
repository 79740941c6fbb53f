"""Joints of the marker skeleton: names, rest/bind transforms and per-frame animation.

The skeleton is one head joint (the root) and one translation-only joint per marker, children of
the head joint::

    Head                     root; its animation is the head motion (identity when none)
    Head/<marker joint>      at the marker's bound surface point; animated by the marker's
                             (head-local) mesh-space displacement

Matrices here are column-vector 4x4 numpy arrays (``p' = M @ [p, 1]``); the USD layer code
converts them. With linear blend skinning the skinning transform of joint j is
``M_j = world_j(t) @ inverse(bind_j)``: for a marker joint ``H(t) @ T(t_j(t))`` and for the head
``H(t)``, so a vertex with weights summing to one skins to ``H(t) (p + sum_j w_j t_j(t))``: the
stabilised transfer moved by the head.
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
        Rest position of the head joint.
    bound_points : ndarray (M, 3)
        Rest (bind) position of each marker joint: its bound surface point.
    marker_translations : ndarray (F, M, 3)
        Marker joint displacement per frame (head-local, mesh units); no NaN.
    head_motion : ndarray (F, 4, 4) or None
        Head joint motion per frame in mesh space (None: identity).
    """

    marker_names: tuple
    joint_names: tuple
    joint_paths: tuple
    name_mapping: dict
    head_pivot: np.ndarray
    bound_points: np.ndarray
    marker_translations: np.ndarray
    head_motion: np.ndarray | None = None

    @property
    def n_joints(self) -> int:
        return len(self.joint_paths)

    @property
    def n_frames(self) -> int:
        return self.marker_translations.shape[0]

    def bind_transforms(self) -> np.ndarray:
        """(J, 4, 4) world-space bind transforms: the head at its pivot, markers at bound points."""
        out = np.tile(np.eye(4), (self.n_joints, 1, 1))
        out[0, :3, 3] = self.head_pivot
        out[1:, :3, 3] = self.bound_points
        return out

    def rest_transforms(self) -> np.ndarray:
        """(J, 4, 4) joint-local rest transforms (markers relative to the head)."""
        out = self.bind_transforms()
        out[1:, :3, 3] -= self.head_pivot
        return out

    def local_animation(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-frame joint-local translations (F, J, 3) and rotations as quaternions (F, J, 4)
        in (w, x, y, z) order, for the SkelAnimation (scales are all one)."""
        F, J = self.n_frames, self.n_joints
        trans = np.empty((F, J, 3))
        rot = np.zeros((F, J, 4))
        rot[:, :, 0] = 1.0
        trans[:, 1:] = self.bound_points[None] - self.head_pivot + self.marker_translations
        if self.head_motion is None:
            trans[:, 0] = self.head_pivot
        else:
            # head world = H(t) @ T(pivot): rotation of H, translation H applied to the pivot
            hm = self.head_motion
            trans[:, 0] = np.einsum("fij,j->fi", hm[:, :3, :3], self.head_pivot) + hm[:, :3, 3]
            rot[:, 0] = rotation_to_quaternion(hm[:, :3, :3])
        return trans, rot

    def skinning_transforms(self) -> np.ndarray:
        """(F, J, 4, 4) skinning transforms ``world_j(t) @ inverse(bind_j)`` (numpy reference)."""
        F, J = self.n_frames, self.n_joints
        h = np.tile(np.eye(4), (F, 1, 1)) if self.head_motion is None else self.head_motion
        out = np.repeat(h[:, None], J, axis=1).copy()
        out[:, 1:, :3, 3] += np.einsum("fij,fmj->fmi", h[:, :3, :3], self.marker_translations)
        return out


def rotation_to_quaternion(r: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) unit quaternions (w, x, y, z), w >= 0."""
    r = np.asarray(r, dtype=np.float64)
    m = r.reshape(-1, 3, 3)
    q = np.empty((m.shape[0], 4))
    tr = np.trace(m, axis1=1, axis2=2)
    for i, a in enumerate(m):
        if tr[i] > 0:
            s = 2.0 * np.sqrt(tr[i] + 1.0)
            q[i] = (0.25 * s, (a[2, 1] - a[1, 2]) / s, (a[0, 2] - a[2, 0]) / s, (a[1, 0] - a[0, 1]) / s)
        elif a[0, 0] > a[1, 1] and a[0, 0] > a[2, 2]:
            s = 2.0 * np.sqrt(1.0 + a[0, 0] - a[1, 1] - a[2, 2])
            q[i] = ((a[2, 1] - a[1, 2]) / s, 0.25 * s, (a[0, 1] + a[1, 0]) / s, (a[0, 2] + a[2, 0]) / s)
        elif a[1, 1] > a[2, 2]:
            s = 2.0 * np.sqrt(1.0 + a[1, 1] - a[0, 0] - a[2, 2])
            q[i] = ((a[0, 2] - a[2, 0]) / s, (a[0, 1] + a[1, 0]) / s, 0.25 * s, (a[1, 2] + a[2, 1]) / s)
        else:
            s = 2.0 * np.sqrt(1.0 + a[2, 2] - a[0, 0] - a[1, 1])
            q[i] = ((a[1, 0] - a[0, 1]) / s, (a[0, 2] + a[2, 0]) / s, (a[1, 2] + a[2, 1]) / s, 0.25 * s)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0] *= -1
    return q.reshape(r.shape[:-2] + (4,))


def build_rig(marker_names, bound_points, marker_translations, *, head_motion=None, head_pivot=None) -> SkeletonRig:
    """Assemble the :class:`SkeletonRig`.

    Parameters
    ----------
    marker_names : sequence of str, length M
    bound_points : array (M, 3)
        Bound surface points (mesh space, mesh units).
    marker_translations : array (F, M, 3)
        Per-frame marker displacements (head-local mesh space, mesh units); must be finite (the
        caller resolves missing samples).
    head_motion : array (F, 4, 4), optional
        Head motion in mesh space (:func:`head_motion_in_mesh_space`).
    head_pivot : array (3,), optional
        Rest position of the head joint (default: centroid of the bound points).
    """
    names = tuple(str(n) for n in marker_names)
    pts = np.asarray(bound_points, dtype=np.float64)
    tr = np.asarray(marker_translations, dtype=np.float64)
    if pts.shape != (len(names), 3) or tr.ndim != 3 or tr.shape[1:] != (len(names), 3):
        raise MarkerError(f"skeleton: {len(names)} markers but bound points {pts.shape} and translations {tr.shape}")
    bad = ~np.isfinite(tr).all(axis=(0, 2))
    if bad.any():
        raise MarkerError(f"skeleton: marker joint translations are not finite for {list_names(np.array(names)[bad])}")
    joints, mapping = joint_names(names)
    pivot = pts.mean(axis=0) if head_pivot is None else np.asarray(head_pivot, dtype=np.float64)
    if head_motion is not None:
        head_motion = np.asarray(head_motion, dtype=np.float64)
        if head_motion.shape != (tr.shape[0], 4, 4):
            raise MarkerError(f"skeleton: head motion {head_motion.shape} for {tr.shape[0]} frames")
    return SkeletonRig(marker_names=names, joint_names=tuple(joints),
                       joint_paths=(HEAD_JOINT,) + tuple(f"{HEAD_JOINT}/{j}" for j in joints),
                       name_mapping=mapping, head_pivot=pivot, bound_points=pts, marker_translations=tr,
                       head_motion=head_motion)
