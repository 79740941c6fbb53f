"""`usdface muscles`: the default rig of named anatomical muscles placed on a face -> rig layer (.usda).

Placed from the face's hole loops and surface, or from marker positions of a layout or binding, or
warped from another face's rig (seed 001 §5.2).
"""
from __future__ import annotations

import time

from ..errors import InputError, list_names
from ..options import MusclesOptions
from ..registry import Result
from ..usd.layers import check_output_path, provenance


def muscles(mesh_path, *, options: MusclesOptions, output) -> Result:
    """Place the default muscle rig on a face (or warp ``options.from_rig`` onto it); write the rig layer.

    ``options.layout`` / ``options.binding``: marker positions on this mesh to place the brows, nose
    tip, chin and forehead from (otherwise from the surface); ``options.from_rig``: a rig layer built
    on another face, warped onto this one through both faces' landmarks (keeps hand edits);
    ``options.force``: maximum forces by base muscle name; ``options.tissue``: tissue settings
    recorded with the rig. The rig is compiled on the mesh before it is written, so a rig that
    cannot act on this face (a muscle far from it, an empty zone) is refused, named.
    """
    from ..tissue.rig import default_rig, face_landmarks, landmark_correspondence, warp_rig
    from ..tissue.simulation import build_simulator
    from ..usd.identity import claims_of, identity, mesh_record, verify
    from ..usd.layers import describe
    from ..usd.muscle_layer import read_rig_layer, write_rig_layer
    from ..usd.tissue_inputs import load_tissue_mesh, marker_positions

    layout, binding, from_rig = options.layout, options.binding, options.from_rig
    forces, tissue = options.max_forces(), options.tissue_settings()
    out = check_output_path(output, inputs={"--mesh": mesh_path, "--layout": layout, "--binding": binding,
                                            "--from-rig": from_rig})
    t0 = time.perf_counter()
    mesh, regions = load_tissue_mesh(mesh_path)
    on_mesh = mesh_record(mesh)
    if binding is not None and layout is None:  # the binding's bound points index this mesh's vertices
        verify(claims_of(binding, "binding"), mesh=(f"mesh {describe(mesh_path)}", on_mesh),
               remedy="bind the capture on this mesh (`usdface bind`), or place the muscles with --layout")
    markers = marker_positions(mesh, layout=layout, binding=binding)
    if from_rig is not None:
        src = read_rig_layer(from_rig, units=mesh.units)
        if not src.landmarks:
            raise InputError(f"rig {from_rig}: records no landmarks; cannot warp it to another face")
        _, lm = face_landmarks(mesh, regions, markers=markers)
        a, b = landmark_correspondence(src, lm)
        rig = warp_rig(src, a, b, target_mesh=mesh)
        rig = rig.replace(landmarks=lm, tissue={**src.tissue, **tissue})
    else:
        rig = default_rig(mesh, regions, markers=markers, forces=forces, tissue=tissue)
    # the rig must act on this mesh: compile it once (names far muscles, empty zones)
    build_simulator(mesh, regions, rig)
    prov = provenance("muscles", options={"layout": layout is not None, "binding": binding is not None,
                                          "fromRig": from_rig is not None, "forces": forces, "tissue": tissue},
                      inputs={"mesh": mesh_path, "layout": layout, "binding": binding, "fromRig": from_rig},
                      identity=identity(mesh=on_mesh))  # a rig is made for one face; no markers, no take
    write_rig_layer(out, rig, mesh_path=mesh_path, prov=prov)
    lin = [m.name for m in rig.muscles if m.type == "linear"]
    sph = [m.name for m in rig.muscles if m.type == "sphincter"]
    summary = {"output": str(out), "muscles": list(rig.names), "linear": len(lin), "sphincter": len(sph),
               "placement": rig.placement, "jawPivot": [float(c) for c in rig.jaw_pivot],
               "jawMaxAngle": rig.jaw_max_angle, "units": mesh.units, "seconds": time.perf_counter() - t0}
    text = [
        f"wrote {out}: {len(rig.muscles)} muscles ({len(lin)} linear, {len(sph)} sphincter), placed from "
        f"{rig.placement}" + (" (warped from " + str(from_rig) + ")" if from_rig else ""),
        f"  {list_names(rig.names, 30)}",
    ]
    return Result(layers={"output": out}, summary=summary, text=text)
