"""Bind capture markers to points on a face mesh surface through a marker layout.

:func:`bind_layout` takes a :class:`~usdface.mesh.layout.Layout` (a vertex or a point per marker,
made for this mesh); the points are projected onto the surface
(:func:`~usdface.mesh.surface_points.project_to_surface`), and the capture-to-mesh similarity is
fitted from the capture's neutral markers to the bound points (Umeyama). Without a layout,
:func:`usdface.mesh.auto_binding.bind_auto` aligns the marker cloud to the surface instead; both
share the checks here (retarget mode, the neutral markers, the capture-to-mesh unit scale).

Each marker is bound to a polygon, the triangle of :meth:`FaceMesh.triangles` holding the point
(its 3 vertices and barycentric weights) and the nearest vertex of that polygon (the nearest
vertex of the surface patch, never one across a hole such as the mouth slit).
"""
from __future__ import annotations

import numpy as np

from ..capture.rigid import to_matrix
from ..errors import ComputeError, MarkerError, OptionError, list_names
from ..model.capture import Capture
from ..model.mesh import Binding, FaceMesh
from ..units import scale_between
from .closest import SurfaceLocator
from .layout import Layout
from .surface_points import project_to_surface

__all__ = ["RETARGET_MODES", "alignment_residuals", "bind_layout", "check_retarget", "neutral_markers",
           "unit_scale_for"]

#: values of the ``retarget`` option (see :class:`~usdface.model.mesh.Binding`)
RETARGET_MODES = ("displacement", "similarity")


# -- checks -------------------------------------------------------------------------------------
def check_retarget(retarget: str) -> None:
    if retarget not in RETARGET_MODES:
        raise OptionError(f"retarget: {retarget!r} is not one of {', '.join(RETARGET_MODES)}")


def _capture_where(capture: Capture) -> str:
    return f" {capture.source}" if capture.source else ""


def neutral_markers(capture: Capture) -> np.ndarray:
    neutral = capture.neutral
    bad = ~np.isfinite(neutral).all(axis=1)
    if bad.any():
        names = [n for n, b in zip(capture.names, bad) if b]
        raise MarkerError(
            f"capture{_capture_where(capture)}: {capture.describe_neutral()} {'has' if capture.neutral_frames[1] - capture.neutral_frames[0] == 1 else 'have'} "
            f"no valid position for marker(s) {list_names(names)}; choose other neutral frames or fill the gaps first"
        )
    return neutral


def unit_scale_for(capture: Capture, mesh: FaceMesh, retarget: str) -> float:
    """Capture units -> mesh units (1.0 when both unknown, or unknown and not needed)."""
    if capture.units is not None and mesh.units is not None:
        return scale_between(capture.units, mesh.units)
    if retarget == "displacement" and (capture.units is None) != (mesh.units is None):
        missing = f"capture{_capture_where(capture)}" if capture.units is None else f"mesh {mesh.source or mesh.name}"
        raise MarkerError(
            f"{missing} has no units: retarget='displacement' moves the mesh by the capture's displacements "
            f"converted to mesh units, so both units are needed (capture: {capture.units}, mesh: {mesh.units}); "
            "give the units or use retarget='similarity'"
        )
    return 1.0


def _check_names(layout: Layout, capture: Capture) -> None:
    cap = set(capture.names)
    lay = set(layout.names)
    extra = [n for n in layout.names if n not in cap]
    missing = [n for n in capture.names if n not in lay]
    lw = f" {layout.source}" if layout.source else ""
    if extra:
        raise MarkerError(
            f"layout{lw} names marker(s) the capture{_capture_where(capture)} lacks: {list_names(extra)}; "
            f"capture has {capture.n_markers} markers: {list_names(capture.names)}"
        )
    if missing:
        raise MarkerError(
            f"layout{lw} has no entry for capture marker(s) {list_names(missing)}; "
            f"layout has {layout.n_markers} markers: {list_names(layout.names)}"
        )


# -- layout binding -------------------------------------------------------------------------------
def bind_layout(
    mesh: FaceMesh,
    layout: Layout,
    capture: Capture,
    *,
    retarget: str = "displacement",
    locator: SurfaceLocator | None = None,
) -> Binding:
    """Bind a capture's markers to a mesh through a marker layout.

    Parameters
    ----------
    mesh : FaceMesh
    layout : Layout
        One entry per capture marker (same names; order may differ).
    capture : Capture
        Its neutral frame gives the capture side of the capture-to-mesh similarity.
    retarget : {"displacement", "similarity"}
        Recorded on the binding (how capture displacements become mesh displacements).
    locator : SurfaceLocator, optional
        Reuse a locator built on this mesh.

    Returns
    -------
    Binding
        In the capture's marker order, ``method="layout"``. ``residuals`` = distance (mesh units)
        from each layout position to its bound surface point (0 for vertices and points on the
        surface). ``capture_to_mesh`` = similarity (Umeyama) fitted from the neutral markers (capture
        units) to the bound points, setting aside markers more than 25% of the face's extent off
        (:func:`usdface.mesh.judgement.robust_similarity`); :func:`alignment_residuals` gives how
        well it fits.

    Raises
    ------
    MarkerError
        Layout and capture marker sets differ; a marker has no valid neutral position; units
        missing where needed.
    MeshError
        A vertex entry is out of range.
    OptionError
        Unknown ``retarget``.
    """
    check_retarget(retarget)
    _check_names(layout, capture)
    neutral = neutral_markers(capture)
    unit_scale = unit_scale_for(capture, mesh, retarget)
    target = layout.positions(mesh, capture.names)
    sp = project_to_surface(mesh, target, locator=locator)
    # robust: a marker far from its layout point (judged by usdface.mesh.judgement) is set aside so
    # that it does not drag the placement of the others
    from .judgement import FIT_MARKER_FRACTION, extent, robust_similarity

    try:
        rot, s, t, _, _ = robust_similarity(neutral * unit_scale, sp.points,
                                            limit=FIT_MARKER_FRACTION * extent(sp.points))
    except ComputeError as e:
        raise ComputeError(f"layout binding: {e}") from None
    return bound_at(capture, sp, retarget=retarget, capture_to_mesh=to_matrix(rot, s * unit_scale, t),
                    unit_scale=unit_scale, method="layout")


def bound_at(capture: Capture, sp, *, retarget: str, capture_to_mesh, unit_scale: float, method: str) -> Binding:
    """The Binding of ``capture``'s markers to the surface points ``sp`` they project to (a
    :class:`~usdface.mesh.surface_points.SurfacePoints`, one per marker), however they were aligned."""
    return Binding(
        names=capture.names,
        face_indices=sp.face_indices,
        triangle_vertices=sp.triangle_vertices,
        barycentrics=sp.barycentrics,
        nearest_vertices=sp.nearest_vertices,
        residuals=sp.distances,
        retarget=retarget,
        capture_to_mesh=capture_to_mesh,
        unit_scale=unit_scale,
        method=method,
    )


def alignment_residuals(binding: Binding, capture: Capture, mesh: FaceMesh) -> np.ndarray:
    """Distance from each neutral marker mapped by ``binding.capture_to_mesh`` to its bound point.

    Parameters
    ----------
    binding : Binding
    capture : Capture
        With the binding's markers (any order).
    mesh : FaceMesh
        The bound mesh (its current points are used).

    Returns
    -------
    ndarray, shape (M,), float64
        Mesh units, in the binding's marker order.
    """
    idx = [capture.index(n) for n in binding.names]
    src = capture.neutral[idx]
    m = binding.capture_to_mesh
    mapped = src @ m[:3, :3].T + m[:3, 3]
    return np.linalg.norm(mapped - binding.surface_points(mesh.points), axis=1)
