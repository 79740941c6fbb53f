"""Readers of what the processors take: a mesh or a capture from any file usdface understands or
from a USD layer (a path, or in memory an ``Sdf.Layer`` / ``Usd.Stage``), and the cross-checked
inputs of a transfer. Shared by every processor that reads them."""
from __future__ import annotations

import dataclasses
from pathlib import Path

from ..model.capture import Capture
from ..errors import MarkerError, MeshError, OptionError, list_names
from ..model.mesh import FaceMesh
from ..units import scale_between
from .layers import USD_SUFFIXES, describe, is_in_memory, open_stage

__all__ = ["load_mesh", "load_capture", "load_transfer_inputs", "check_capture_units"]


def load_mesh(path, *, units=None) -> tuple[FaceMesh, list]:
    """Read a mesh file, a USD mesh layer or (Python API) an in-memory stage or layer; returns
    (mesh, regions already on it)."""
    if is_in_memory(path) or Path(path).suffix.lower() in USD_SUFFIXES:
        from .mesh_layer import read_mesh_layer

        mesh, regions = read_mesh_layer(path)
        if units is not None and mesh.units is not None and units != mesh.units:
            raise OptionError(f"--units {units} conflicts with {path}'s metersPerUnit ({mesh.units})")
        if mesh.units is None:
            if units is None:
                raise MeshError(f"mesh {path}: the layer has no metersPerUnit; say its units with --units "
                                "(usdface never guesses units for USD input)")
            mesh = dataclasses.replace(mesh, units=units)
        return mesh, regions
    from ..io.meshes import read_mesh

    return read_mesh(path, units=units, other_suffixes=USD_SUFFIXES), []


def load_capture(path, *, units=None, rate=None, up_axis=None, keep_zeros=False, allow=()) -> Capture:
    """Read any capture usdface understands: a capture file (.ma .c3d .trc .csv), a capture layer,
    or (Python API) an in-memory stage or layer holding a marker set.

    ``keep_zeros``: C3D samples at exactly (0, 0, 0) stay positions instead of gaps; ``allow``:
    plausibility checks accepted (a reader's ``rate`` and ``frame-count`` limits among them)."""
    if is_in_memory(path) or Path(path).suffix.lower() in USD_SUFFIXES:
        from .capture_layer import read_capture_layer

        capture = read_capture_layer(path)
        if units is not None and capture.units is not None and units != capture.units:
            raise OptionError(f"--units {units} conflicts with capture layer {path} (in {capture.units}); "
                              "layers are never rescaled on import")
        if rate is not None and abs(rate - capture.rate) > 1e-9 * capture.rate:
            raise OptionError(f"--rate {rate:g} conflicts with capture layer {path} ({capture.rate:g} Hz); "
                              "use --resample to change the rate")
        return capture
    from ..io.captures import read_capture

    return read_capture(path, units=units, rate=rate, up_axis=up_axis, keep_zeros=keep_zeros,
                        allow=frozenset(allow))


def load_transfer_inputs(mesh_path, capture_path, binding_path, analysis_path, *, method=None):
    """Read and cross-check the inputs of a transfer: (mesh, capture, binding, distance matrix).

    Raises MixedLayersError when the binding or the analysis was made for another mesh, or the
    analysis for other bound points (:mod:`usdface.usd.identity`; layers of usdface 0.2 are
    accepted with a warning), and MarkerError / OptionError / InputError naming the file at fault
    when the analysis was computed for other markers or another mesh size.
    """
    from .analysis_layer import read_distance_matrix
    from .capture_layer import read_capture_layer
    from .identity import claims_of, markers_record, mesh_record, verify
    from .mesh_layer import read_binding, read_mesh_layer

    mesh, _ = read_mesh_layer(mesh_path)
    capture = read_capture_layer(capture_path)
    binding = read_binding(open_stage(binding_path, what="binding"), source=str(binding_path))
    dm = read_distance_matrix(analysis_path, method=method)
    on_mesh = (f"mesh {describe(mesh_path)}", mesh_record(mesh))
    verify(claims_of(binding_path, "binding"), mesh=on_mesh, remedy="bind the capture on this mesh (`usdface bind`)")
    if tuple(dm.marker_names) != tuple(binding.names):
        raise MarkerError(f"analysis {analysis_path} was computed for markers {list_names(dm.marker_names)}, "
                          f"binding {binding_path} binds {list_names(binding.names)}; recompute the distances")
    verify(claims_of(analysis_path, "analysis"), mesh=on_mesh,
           markers=(f"binding {describe(binding_path)}", markers_record(binding)),
           remedy="compute the distances again (`usdface distances`)")
    if dm.vertex_to_centre.shape[0] != mesh.n_points:
        raise OptionError(f"analysis {analysis_path} has {dm.vertex_to_centre.shape[0]} vertices, mesh {mesh_path} "
                          f"has {mesh.n_points}: they belong to different meshes")
    check_capture_units(capture, binding, mesh, capture_path=capture_path, binding_path=binding_path)
    return mesh, capture, binding, dm


def check_capture_units(capture, binding, mesh, *, capture_path, binding_path) -> None:
    """The binding converts capture displacements with the unit scale of the capture it was made
    with; a capture in other units would be scaled wrongly (10x for mm against cm)."""
    if capture.units is None or mesh.units is None:
        return
    expected = scale_between(capture.units, mesh.units)
    if abs(expected - binding.unit_scale) > 1e-9 * max(expected, 1.0):
        raise MarkerError(
            f"capture {capture_path} is in {capture.units} ({expected:g} {mesh.units} per {capture.units}) but binding "
            f"{binding_path} was made for a capture converting at {binding.unit_scale:g}; bind this capture again "
            "(`usdface bind`) or import it in the units of the bound one")
