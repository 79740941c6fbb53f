"""`usdface bind`: markers bound to points on the mesh surface -> binding layer (.usda)."""
from __future__ import annotations

import numpy as np

from ..usd.layers import check_output_path, provenance


def bind(mesh_path, capture_path, output, *, layout=None, auto=False, retarget="displacement") -> dict:
    """Bind the capture's markers to the mesh from a layout or automatically; write the binding layer."""
    from ..errors import OptionError
    from ..mesh.binding import alignment_residuals, bind_auto, bind_layout
    from ..mesh.layout import read_layout
    from ..usd.capture_layer import read_capture_layer
    from ..usd.mesh_layer import read_mesh_layer, write_binding_layer

    out = check_output_path(output, inputs={"--mesh": mesh_path, "--capture": capture_path, "--layout": layout})
    if (layout is None) == (not auto):
        raise OptionError("bind: give exactly one of --layout LAYOUT.json or --auto")
    mesh, _ = read_mesh_layer(mesh_path)
    capture = read_capture_layer(capture_path)
    if layout is not None:
        binding = bind_layout(mesh, read_layout(layout), capture, retarget=retarget)
    else:
        binding = bind_auto(mesh, capture, retarget=retarget)
    prov = provenance("bind", options={"layout": layout is not None, "auto": auto, "retarget": retarget},
                      inputs={"mesh": mesh_path, "capture": capture_path, "layout": layout})
    write_binding_layer(out, binding, mesh_path=mesh_path, capture_path=capture_path, mesh_units=mesh.units,
                        prov=prov)
    # for a layout binding the bound points are the layout's (residual ~0): what tells the user how
    # well capture and layout agree is the similarity fit of the neutral markers to those points
    res = binding.residuals if binding.method == "auto" else alignment_residuals(binding, capture, mesh)
    order = np.argsort(res)[::-1]
    summary = {
        "output": str(out), "markers": binding.n_markers, "method": binding.method, "retarget": binding.retarget,
        "residuals": {n: float(r) for n, r in zip(binding.names, res)},
        "residualKind": "surface" if binding.method == "auto" else "layout-fit",
        "residualMedian": float(np.median(res)), "residualMax": float(res.max()),
        "units": mesh.units,
    }
    u = mesh.units or "units"
    summary["_text"] = [
        f"wrote {out}: {binding.n_markers} markers bound ({binding.method}, retarget {binding.retarget})",
        f"  {'fit residual (neutral markers vs layout points)' if binding.method == 'layout' else 'residual'} "
        f"median {np.median(res):.3f} {u}, max {res.max():.3f} {u}, capture-to-mesh scale "
        f"{binding.capture_rotation_scale[1] / binding.unit_scale:.3f}; largest: "
        f"({', '.join(f'{binding.names[i]} {res[i]:.2f}' for i in order[:5])})",
    ]
    return summary
