"""`usdface bind`: markers bound to points on the mesh surface -> binding layer (.usda)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..usd.layers import check_output_path, provenance


def bind(mesh_path, capture_path, output, *, layout=None, auto=False, retarget="displacement", allow=()) -> dict:
    """Bind the capture's markers to the mesh from a layout or automatically; write the binding layer.

    The binding is judged before it is written (:mod:`usdface.mesh.judgement`): the mesh's size in
    its units (``face-size``), layout points off the surface (``layout-distance``), markers far from
    their layout point or surface after the fit (``fit-residual``) and a fitted capture-to-mesh
    scale contradicting the units (``unit-scale``) stop the command with PlausibilityError unless
    ``allow`` names them. Findings are in the summary's ``plausibility``.
    """
    from ..capture.plausibility import parse_allow
    from ..errors import OptionError
    from ..usd.capture_layer import read_capture_layer
    from ..usd.mesh_layer import read_mesh_layer, write_binding_layer

    out = check_output_path(output, inputs={"--mesh": mesh_path, "--capture": capture_path, "--layout": layout})
    if (layout is None) == (not auto):
        raise OptionError("bind: give exactly one of --layout LAYOUT.json or --auto")
    mesh, _ = read_mesh_layer(mesh_path)
    capture = read_capture_layer(capture_path)
    binding, res, checked = bind_and_judge(mesh, capture, layout=layout, retarget=retarget, allow=allow,
                                           mesh_name=_described(mesh_path, "mesh"),
                                           capture_name=_described(capture_path, "capture"))
    allow = parse_allow(allow)
    options = {"layout": layout is not None, "auto": auto, "retarget": retarget}
    if allow:
        options["allow"] = sorted(allow)
    prov = provenance("bind", options=options, inputs={"mesh": mesh_path, "capture": capture_path, "layout": layout})
    write_binding_layer(out, binding, mesh_path=mesh_path, capture_path=capture_path, mesh_units=mesh.units,
                        prov=prov)
    order = np.argsort(res)[::-1]
    scale = binding.capture_rotation_scale[1] / binding.unit_scale
    summary = {
        "output": str(out), "markers": binding.n_markers, "method": binding.method, "retarget": binding.retarget,
        "residuals": {n: float(r) for n, r in zip(binding.names, res)},
        "residualKind": "surface" if binding.method == "auto" else "layout-fit",
        "residualMedian": float(np.median(res)), "residualMax": float(res.max()),
        "captureToMeshScale": float(scale),
        "units": mesh.units, "plausibility": checked,
    }
    u = mesh.units or "units"
    summary["_text"] = [
        f"wrote {out}: {binding.n_markers} markers bound ({binding.method}, retarget {binding.retarget})",
        f"  {'fit residual (neutral markers vs layout points)' if binding.method == 'layout' else 'residual'} "
        f"median {np.median(res):.3f} {u}, max {res.max():.3f} {u}, capture-to-mesh scale "
        f"{scale:.3f}; largest: "
        f"({', '.join(f'{binding.names[i]} {res[i]:.2f}' for i in order[:5])})",
    ]
    if checked:
        summary["_text"].append("  plausibility: " + ", ".join(
            f"{f['code']} ({'accepted ' if f['allowed'] else ''}{f['severity']})" for f in checked))
    return summary


def bind_and_judge(mesh, capture, *, layout=None, retarget="displacement", allow=(), mesh_name="mesh",
                   capture_name="capture"):
    """Bind ``capture`` to ``mesh`` (from the layout file, else automatically) and judge the result
    (:mod:`usdface.mesh.judgement`; `bind`'s docstring). Returns ``(binding, residuals, findings)``:
    residuals are the layout-fit residuals of the neutral markers for a layout binding, the surface
    residuals for an automatic one. Raises PlausibilityError unless ``allow`` names the finding."""
    from ..capture.plausibility import parse_allow, report
    from ..mesh.binding import alignment_residuals, bind_auto, bind_layout
    from ..mesh.layout import read_layout

    allow = parse_allow(allow)
    # judged in stages, so that a root cause (a mesh in metres) is reported alone rather than with
    # the layout distances and fit residuals it causes
    checked = report(_mesh_findings(mesh, mesh_name), allow=allow)
    if layout is not None:
        binding = bind_layout(mesh, read_layout(layout), capture, retarget=retarget)
        checked += report(_layout_findings(binding, mesh, mesh_name=mesh_name, layout=layout), allow=allow)
    else:
        binding = bind_auto(mesh, capture, retarget=retarget)
    # for a layout binding the bound points are the layout's (residual ~0): what tells the user how
    # well capture and layout agree is the similarity fit of the neutral markers to those points
    res = binding.residuals if binding.method == "auto" else alignment_residuals(binding, capture, mesh)
    checked += report(_binding_findings(binding, capture, mesh, res, mesh_name=mesh_name, capture_name=capture_name,
                                        layout=layout), allow=allow)
    return binding, res, checked


def _described(path, what: str) -> str:
    """'mesh PATH' plus the file it was imported from, when the layer's provenance says."""
    from ..usd.layers import describe, get_provenance, is_in_memory, open_stage

    if is_in_memory(path):
        return f"{what} {describe(path)}"
    try:
        inputs = json.loads(get_provenance(open_stage(path, what=what)).get("inputs", "{}"))
        source = (inputs.get(what) or {}).get("file")
    except Exception:  # noqa: BLE001 - provenance is informative only
        source = None
    # a layer imported from a file is named by its file name and that file (inside `run` the
    # layer sits in a private folder whose path would mean nothing to the user)
    return f"{what} {Path(path).name} (imported from {source})" if source else f"{what} {path}"


def _mesh_findings(mesh, mesh_name: str) -> list:
    from ..mesh.judgement import mesh_size_finding

    f = mesh_size_finding(mesh.points, mesh.units, what=mesh_name,
                          fix="import-mesh --units {unit}, or run --mesh-units {unit}")
    return [f] if f is not None else []


def _layout_findings(binding, mesh, *, mesh_name: str, layout) -> list:
    from ..mesh.judgement import extent, layout_distance_finding

    f = layout_distance_finding(list(binding.names), binding.residuals, extent(binding.surface_points(mesh.points)),
                                units=mesh.units, what=f"layout {layout} on {mesh_name}",
                                mesh_extent=extent(mesh.points))
    return [f] if f is not None else []


def _binding_findings(binding, capture, mesh, res, *, mesh_name: str, capture_name: str, layout) -> list:
    from ..mesh.judgement import FIT_MARKER_FRACTION, extent, fit_residual_findings, unit_scale_finding

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
