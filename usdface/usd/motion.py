"""Head motion on the face's root prim: one way, shared by every deliverable.

The rigid head motion removed by stabilisation is delivered as a time-sampled
``xformOp:transform`` on the face's root prim (``/Face``: an Xform in mesh and point-cache layers,
the SkelRoot in skeleton and blend-shape layers), relative to the neutral frame (identity there),
in mesh space. The mesh's own points stay head-stabilised, so every importer (usdview, Blender,
Maya, Unreal) moves the whole face the same way in every deliverable, and dropping the head motion
is dropping one op.
"""
from __future__ import annotations

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom

from ..errors import InputError

HEAD_MOTION_DOC = ("Head motion removed by stabilisation (mesh space, relative to the neutral frame): "
                   "the face's points are head-stabilised and this transform moves the whole face")


def _to_usd(m: np.ndarray) -> Gf.Matrix4d:
    """Column-vector 4x4 numpy -> USD's row-vector Matrix4d."""
    return Gf.Matrix4d(*np.asarray(m, dtype=np.float64).T.ravel().tolist())


def author_head_motion(stage: Usd.Stage, root_path: Sdf.Path | str, motion: np.ndarray, *, start: float = 0.0,
                       times=None) -> None:
    """Author ``motion`` as the time-sampled ``xformOp:transform`` of ``root_path`` (an over if the
    prim is defined elsewhere). When the composed prim already has transform ops (a mesh layer that
    places the face), the head motion is appended after them as ``xformOp:transform:headMotion``,
    so it moves the face in its own space.

    Parameters
    ----------
    motion : ndarray (F, 4, 4)
        Column-vector rigid transforms in mesh space, mesh units.
    start, times :
        Time code of each frame: ``times`` (F,) when given, else ``start + f``.
    """
    motion = np.asarray(motion, dtype=np.float64)
    if motion.ndim != 3 or motion.shape[1:] != (4, 4) or not np.isfinite(motion).all():
        raise InputError(f"head motion: expected finite (F, 4, 4) transforms; got {motion.shape}")
    codes = start + np.arange(len(motion), dtype=np.float64) if times is None else np.asarray(times, dtype=float)
    if codes.shape != (len(motion),):
        raise InputError(f"head motion: {len(motion)} transforms for {codes.size} time codes")
    prim = stage.GetPrimAtPath(root_path) or stage.OverridePrim(root_path)
    xf = UsdGeom.Xformable(prim)
    existing = xf.GetOrderedXformOps()
    op = xf.AddTransformOp(opSuffix="headMotion") if existing else xf.AddTransformOp()
    attr = op.GetAttr()
    attr.SetDocumentation(HEAD_MOTION_DOC)
    with Sdf.ChangeBlock():
        for t, m in zip(codes, motion):
            attr.Set(_to_usd(m), Usd.TimeCode(float(t)))


def read_head_motion(stage: Usd.Stage, root_path: Sdf.Path | str, times) -> np.ndarray | None:
    """The root prim's local transform at ``times`` as (F, 4, 4) column-vector matrices, or None
    when it has no transform op."""
    prim = stage.GetPrimAtPath(root_path)
    if not prim:
        return None
    xf = UsdGeom.Xformable(prim)
    if not xf.GetOrderedXformOps():
        return None
    out = np.empty((len(times), 4, 4))
    for i, t in enumerate(times):
        out[i] = np.array(xf.GetLocalTransformation(Usd.TimeCode(t)), dtype=np.float64).T
    return out
