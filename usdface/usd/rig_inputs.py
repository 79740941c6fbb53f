"""Readers of blend-shape rigs as the commands take them: a USD mesh with UsdSkel blend shapes, or
a neutral mesh (OBJ, PLY, ... or a USD mesh layer) with its shapes given apart (an ``.npz``, a
folder of ``<shape>.obj`` or a USD rig); and the generic rig shipped with usdface. Shared by
`solve`, `run`'s blend-shape step and `shapes transfer`."""
from __future__ import annotations

import logging
from pathlib import Path

from ..errors import InputError, OptionError, list_names
from .layers import USD_SUFFIXES, describe, is_in_memory

log = logging.getLogger("usdface")

__all__ = ["load_rig", "default_generic"]


def load_rig(mesh, shapes=None, *, mesh_units=None):
    """The rig and the mesh's regions from ``--mesh`` (and ``--shapes``).

    ``mesh``: a USD mesh with UsdSkel blend shapes (no ``shapes``), or a neutral mesh (OBJ/PLY/...
    or a USD mesh layer) with ``shapes`` = an ``.npz``, a folder of ``<shape>.obj`` or a USD rig
    whose neutral must match the mesh. In Python, ``mesh`` may be an ``Sdf.Layer`` or a
    ``Usd.Stage`` (read as USD).

    Returns
    -------
    rig : usdface.blendshape.rig.BlendShapeRig
    regions : list of Region
        The mesh's regions (hole regions found when the mesh has none).
    """
    from ..blendshape.rig import BlendShapeRig, check_neutral, check_same_topology, load_mesh_folder_rig, load_npz_rig
    from ..mesh.topology import find_hole_regions
    from .inputs import load_mesh

    in_memory = is_in_memory(mesh)
    mp = mesh if in_memory else Path(mesh)
    if not in_memory and not mp.exists():
        raise InputError(f"--mesh {mp}: no such file")
    is_usd = in_memory or mp.suffix.lower() in USD_SUFFIXES
    if shapes is None:
        if not is_usd:
            raise OptionError(f"--mesh {mp} is a plain mesh: give its blend shapes with --shapes DIR|NPZ|RIG.usd "
                              "(or a USD mesh with UsdSkel blend shapes as --mesh)")
        usd_rig = _read_usd_rig(mp, mesh_units)
        rig = BlendShapeRig(tuple(usd_rig.names), usd_rig.deltas, usd_rig.mesh, source=describe(mp),
                            notes=tuple(usd_rig.notes))
        regions = usd_rig.regions
    else:
        sp = Path(shapes)
        if is_usd and _has_shapes(mp):
            raise OptionError(f"--mesh {describe(mp)} has blend shapes of its own; --shapes {sp} would replace them: "
                              "give one")
        neutral, regions = load_mesh(mp, units=mesh_units)
        if sp.is_dir():
            rig = load_mesh_folder_rig(sp, neutral)
        elif sp.suffix.lower() == ".npz":
            rig = load_npz_rig(sp, neutral)
        elif sp.suffix.lower() in USD_SUFFIXES:
            usd_rig = _read_usd_rig(sp, mesh_units or neutral.units)
            check_same_topology(neutral, usd_rig.mesh, what=f"rig {sp}")
            check_neutral(usd_rig.mesh.points, neutral, source=str(sp))
            rig = BlendShapeRig(tuple(usd_rig.names), usd_rig.deltas, neutral, source=str(sp),
                                notes=tuple(usd_rig.notes))
        elif not sp.exists():
            raise InputError(f"--shapes {sp}: no such file or folder")
        else:
            raise OptionError(f"--shapes {sp}: expected a folder of <shape>.obj, an .npz (names, deltas[, neutral]) or "
                              "a USD rig")
    if not regions:
        regions = find_hole_regions(rig.mesh)
    for note in rig.notes:
        log.warning("rig %s: %s", rig.source, note)
    return rig, regions


def _read_usd_rig(path, units):
    from .blendshape_layer import read_blendshape_rig

    return read_blendshape_rig(path, units=units)


def _has_shapes(path) -> bool:
    from .blendshape_layer import read_blendshape_rig

    try:
        read_blendshape_rig(path)
    except InputError:
        return False
    return True


def default_generic() -> dict:
    """Paths of the default generic rig of `shapes transfer` (MakeHuman, CC0), shipped with the
    package (``usdface/resources/generic``): ``mesh``, ``shapes`` and ``landmarks``."""
    root = Path(__file__).resolve().parents[1] / "resources" / "generic"
    paths = {"mesh": root / "makehuman_hm08_face_cm.usdc",
             "shapes": root / "makehuman_hm08_face_units_cm.npz",
             "landmarks": root / "makehuman_hm08_face.landmarks.layout.json"}
    missing = [str(p) for p in paths.values() if not p.is_file()]
    if missing:
        raise InputError(f"the default generic rig is missing from this installation ({list_names(missing)}); "
                         "reinstall usdface, or give --generic RIG (and --generic-landmarks)")
    return paths
