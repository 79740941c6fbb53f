"""Readers of what the tissue commands (`muscles`, `simulate`, `fit-muscles`) take: the face with
its hole regions, and marker positions on it from a layout or a binding layer."""
from __future__ import annotations

import dataclasses
from pathlib import Path

from ..errors import InputError
from .inputs import load_mesh
from .layers import describe, is_in_memory, open_stage

__all__ = ["load_tissue_mesh", "marker_positions", "check_rig_mesh"]


def load_tissue_mesh(source):
    """``(mesh, regions)`` from a mesh layer, a mesh file or (Python API) an in-memory stage or
    layer. A mesh without units counts as centimetres; the hole regions (mouth, eyes) are found
    when the layer stores no mouth region.

    Raises
    ------
    InputError
        ``source`` is a path to no file.
    """
    from ..mesh.topology import find_hole_regions

    if not is_in_memory(source) and not Path(source).exists():
        raise InputError(f"mesh {source}: no such file")
    mesh, regions = load_mesh(source)
    if mesh.units is None:
        mesh = dataclasses.replace(mesh, units="cm")
    if not any(r.role == "mouth" for r in regions):
        regions = find_hole_regions(mesh)
    return mesh, regions


def marker_positions(mesh, *, layout=None, binding=None) -> dict | None:
    """``{marker name: (3,) position on mesh}`` from a marker layout JSON or a binding layer (a
    path, or in memory a stage or layer); None when neither is given (the layout wins when both
    are)."""
    if layout is not None:
        from ..mesh.layout import read_layout

        lay = read_layout(layout)
        return dict(zip(lay.names, lay.positions(mesh)))
    if binding is not None:
        from .mesh_layer import read_binding

        b = read_binding(open_stage(binding, what="binding"), source=describe(binding))
        return dict(zip(b.names, b.surface_points(mesh.points)))
    return None


def check_rig_mesh(rig, mesh_source, mesh) -> dict:
    """The mesh identity record of ``mesh`` (read from ``mesh_source``), after checking that the rig
    layer ``rig`` was placed on it: a rig of another face is refused (MixedLayersError naming both
    files), a rig of usdface 0.2 accepted with a warning (:func:`usdface.usd.identity.verify`)."""
    from .identity import claims_of, mesh_record, verify

    record = mesh_record(mesh)
    verify(claims_of(rig, "rig"), mesh=(f"mesh {describe(mesh_source)}", record),
           remedy="place the muscles on this mesh (`usdface muscles`; --from-rig warps this rig onto it)")
    return record
