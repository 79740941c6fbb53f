"""`usdface bind`: markers bound to points on the mesh surface -> binding layer (.usda)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..options import BindOptions
from ..registry import Result
from ..usd.layers import check_output_path, provenance


def bind(mesh_path, capture_path, *, options: BindOptions, output) -> Result:
    """Bind the capture's markers to the mesh from a layout or automatically; write the binding layer.

    The binding is judged before it is written (:mod:`usdface.mesh.judgement`): the mesh's size in
    its units (``face-size``), layout points off the surface (``layout-distance``), markers far from
    their layout point or surface after the fit (``fit-residual``) and a fitted capture-to-mesh
    scale contradicting the units (``unit-scale``) stop the command with PlausibilityError unless
    ``allow`` names them. Findings are in the summary's ``plausibility``.
    """
    from ..capture.plausibility import parse_allow
    from ..errors import OptionError
    from ..mesh.judged_binding import bind_and_judge
    from ..usd.capture_layer import read_capture_layer
    from ..usd.identity import identity, markers_record, mesh_record
    from ..usd.mesh_layer import read_mesh_layer, write_binding_layer

    layout, auto, retarget, allow = options.layout, options.auto, options.retarget, options.allow
    out = check_output_path(output, inputs={"--mesh": mesh_path, "--capture": capture_path, "--layout": layout})
    if (layout is None) == (not auto):
        raise OptionError("bind: give exactly one of --layout LAYOUT.json or --auto")
    mesh, _ = read_mesh_layer(mesh_path)
    capture = read_capture_layer(capture_path)
    binding, res, checked = bind_and_judge(mesh, capture, layout=layout, retarget=retarget, allow=allow,
                                           mesh_name=_described(mesh_path, "mesh"),
                                           capture_name=_described(capture_path, "capture"))
    allow = parse_allow(allow)
    recorded = {"layout": layout is not None, "auto": auto, "retarget": retarget}
    if allow:
        recorded["allow"] = sorted(allow)
    # the mesh and the bound points it was made for; no take: a binding serves every take of the character
    prov = provenance("bind", options=recorded, inputs={"mesh": mesh_path, "capture": capture_path, "layout": layout},
                      identity=identity(mesh=mesh_record(mesh), markers=markers_record(binding)))
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
    text = [
        f"wrote {out}: {binding.n_markers} markers bound ({binding.method}, retarget {binding.retarget})",
        f"  {'fit residual (neutral markers vs layout points)' if binding.method == 'layout' else 'residual'} "
        f"median {np.median(res):.3f} {u}, max {res.max():.3f} {u}, capture-to-mesh scale "
        f"{scale:.3f}; largest: "
        f"({', '.join(f'{binding.names[i]} {res[i]:.2f}' for i in order[:5])})",
    ]
    if checked:
        text.append("  plausibility: " + ", ".join(
            f"{f['code']} ({'accepted ' if f['allowed'] else ''}{f['severity']})" for f in checked))
    return Result(layers={"output": out}, summary=summary, text=text)


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


