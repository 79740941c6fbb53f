"""A marker layout bound to a mesh surface without a capture: the bound points are where the
layout's markers project onto the surface (the evaluation against ground-truth shapes and the
blend-shape experiments bind markers this way)."""
from __future__ import annotations

from .surface_points import project_to_surface
from .layout import Layout
from ..model.mesh import Binding, FaceMesh

__all__ = ["binding_from_layout"]


def binding_from_layout(mesh: FaceMesh, layout: Layout) -> Binding:
    """Bind a layout's markers to the mesh surface (closest-point projection; no capture needed).

    Parameters
    ----------
    mesh : FaceMesh
    layout : Layout
        Marker positions on ``mesh`` (:func:`usdface.mesh.layout.read_layout`).

    Returns
    -------
    Binding
        ``method="layout"``, identity capture transform (only the bound points matter here);
        ``residuals`` are the layout points' distances to the surface (mesh units).
    """
    sp = project_to_surface(mesh, layout.positions(mesh))
    return Binding(names=layout.names, face_indices=sp.face_indices, triangle_vertices=sp.triangle_vertices,
                   barycentrics=sp.barycentrics, nearest_vertices=sp.nearest_vertices, residuals=sp.distances,
                   method="layout")
