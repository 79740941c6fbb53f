"""Binding markers to a face and judging the result in one step (`bind`, `solve`): the root cause
(a mesh in metres) is reported alone, before the layout distances and fit residuals it causes."""
from __future__ import annotations

__all__ = ["bind_and_judge"]


def bind_and_judge(mesh, capture, *, layout=None, retarget="displacement", allow=(), mesh_name="mesh",
                   capture_name="capture"):
    """Bind ``capture`` to ``mesh`` (from the layout file, else automatically) and judge the result
    (:mod:`usdface.mesh.judgement`; `bind`'s docstring). Returns ``(binding, residuals, findings)``:
    residuals are the layout-fit residuals of the neutral markers for a layout binding, the surface
    residuals for an automatic one. Raises PlausibilityError unless ``allow`` names the finding."""
    from ..capture.plausibility import parse_allow, report
    from .auto_binding import bind_auto
    from .binding import alignment_residuals, bind_layout
    from .layout import read_layout

    allow = parse_allow(allow)
    # judged in stages, so that a root cause (a mesh in metres) is reported alone rather than with
    # the layout distances and fit residuals it causes
    checked = report(mesh_findings(mesh, mesh_name), allow=allow)
    if layout is not None:
        binding = bind_layout(mesh, read_layout(layout), capture, retarget=retarget)
        checked += report(layout_findings(binding, mesh, mesh_name=mesh_name, layout=layout), allow=allow)
    else:
        binding = bind_auto(mesh, capture, retarget=retarget)
    # for a layout binding the bound points are the layout's (residual ~0): what tells the user how
    # well capture and layout agree is the similarity fit of the neutral markers to those points
    res = binding.residuals if binding.method == "auto" else alignment_residuals(binding, capture, mesh)
    checked += report(binding_findings(binding, capture, mesh, res, mesh_name=mesh_name, capture_name=capture_name,
                                        layout=layout), allow=allow)
    return binding, res, checked


def mesh_findings(mesh, mesh_name: str) -> list:
    from .judgement import mesh_size_finding

    f = mesh_size_finding(mesh.points, mesh.units, what=mesh_name,
                          fix="import-mesh --units {unit}, or run --mesh-units {unit}")
    return [f] if f is not None else []


def layout_findings(binding, mesh, *, mesh_name: str, layout) -> list:
    from .judgement import extent, layout_distance_finding

    f = layout_distance_finding(list(binding.names), binding.residuals, extent(binding.surface_points(mesh.points)),
                                units=mesh.units, what=f"layout {layout} on {mesh_name}",
                                mesh_extent=extent(mesh.points))
    return [f] if f is not None else []


def binding_findings(binding, capture, mesh, res, *, mesh_name: str, capture_name: str, layout) -> list:
    from .judgement import FIT_MARKER_FRACTION, extent, fit_residual_findings, unit_scale_finding

    bound = binding.surface_points(mesh.points)
    face = extent(bound)
    findings = []
    names = list(binding.names)
    if binding.method == "layout":
        what = f"{capture_name} on layout {layout}"
        kept = res <= FIT_MARKER_FRACTION * face
        findings += fit_residual_findings(names, res, kept, face, units=mesh.units, what=what)
    else:
        what = f"{capture_name} aligned to {mesh_name}"
        kept = res <= FIT_MARKER_FRACTION * face
        findings += fit_residual_findings(names, res, kept, face, units=mesh.units, what=what, kind="surface")
    scale = binding.capture_rotation_scale[1] / binding.unit_scale
    f = unit_scale_finding(scale, capture_units=capture.units, mesh_units=mesh.units, what=f"{capture_name} on {mesh_name}")
    if f is not None:
        findings.append(f)
    return findings
