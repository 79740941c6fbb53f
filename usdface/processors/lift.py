"""`usdface lift`: 2D marker tracks (a track layer or a 2D CSV) -> a 3D capture layer on the mesh.

See :mod:`usdface.capture.lift` for the method (weak-perspective camera fitted at the neutral
frame, in-plane motion, depth from the face surface or zero). The output is a capture layer in
mesh space and mesh units with the tracks' marker names, rate and frames; bind it with the same
layout (`usdface bind --layout`) and transfer it like any capture.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError, MarkerError, OptionError
from ..options import LiftOptions
from ..registry import Result
from ..usd.layers import check_output_path, describe, is_in_memory, provenance

__all__ = ["lift"]


def lift(tracks, mesh, *, options: LiftOptions, output) -> Result:
    """Lift 2D tracks to a 3D capture layer on the mesh.

    ``tracks``: a track layer, a capture layer of 2D data or a 2D CSV (pixels). ``mesh``: a mesh
    layer or any mesh file `usdface run` accepts (OBJ, PLY, ...; ``options.mesh_units`` for files
    without units, default cm). The markers' bound points come from ``options.binding`` or
    ``options.layout``. The neutral tracks' fit to the bound points is judged like a 3D layout fit
    (:func:`usdface.mesh.judgement.fit_residual_findings`, code ``fit-residual``): a marker more
    than 25% of the face's image size off, or an rms beyond 15%, stops the lift unless
    ``options.allow`` names the check.
    """
    from ..capture.lift import DEFAULT_MIN_COS, check_marker_sets, lift_displacements, surface_normals
    from ..model.capture import Capture
    from ..capture.plausibility import report
    from ..usd.capture_layer import write_capture_layer
    from ..usd.identity import capture_record, identity
    from ..usd.inputs import load_mesh
    from ..usd.track_inputs import read_tracks

    o = options
    out = check_output_path(output, inputs={"tracks": tracks, "--mesh": mesh, "--binding": o.binding,
                                            "--layout": o.layout})
    min_cos = DEFAULT_MIN_COS
    capture_2d = read_tracks(tracks, rate=o.rate)
    if not is_in_memory(mesh) and not Path(mesh).is_file():
        raise InputError(f"--mesh {mesh}: no such file")
    face, _ = load_mesh(mesh, units=o.mesh_units)
    names, tri, bary, place_src = _bound_surface(face, mesh, o.binding, o.layout)
    check_marker_sets(capture_2d.names, names, tracks=f"tracks {describe(tracks)}", layout=place_src)
    order = [names.index(n) for n in capture_2d.names]  # layout rows in the tracks' order
    tri, bary = np.asarray(tri)[order], np.asarray(bary)[order]
    bound = np.einsum("mk,mkd->md", bary, face.points[tri])
    n_frame = capture_2d.neutral_frame if o.neutral is None else int(o.neutral)
    if not 0 <= n_frame < capture_2d.n_frames:
        raise OptionError(f"--neutral {o.neutral}: outside 0..{capture_2d.n_frames - 1}")
    uv = capture_2d.positions[..., :2]
    ok = np.isfinite(uv[n_frame]).all(axis=1)
    if not ok.all():
        raise MarkerError(f"tracks {describe(tracks)}: marker(s) {', '.join(np.array(capture_2d.names)[~ok])} invalid "
                          f"at the neutral frame {n_frame}; choose another neutral frame (--neutral)")
    cam, findings = _fit_camera(uv[n_frame], bound, capture_2d.names,
                                what=f"tracks {describe(tracks)} on {place_src}")
    checked = report(findings, allow=o.allow)
    normals = surface_normals(face.points, face.triangles(), tri, bary)
    disp = lift_displacements(uv, n_frame, cam, normals=normals, depth=o.depth, min_cos=min_cos)
    step = {"step": "lift", "dims": 3, "tracks": _name(tracks), "depth": o.depth, "minCos": min_cos,
            "cameraScale": cam.scale, "cameraRows": cam.rows.tolist(), "cameraOffset": cam.offset.tolist(),
            "residualRms": cam.residual_rms, "residualMax": cam.residual_max, "neutralFrame": n_frame,
            "trackHistory": list(capture_2d.history)}
    capture = Capture(names=capture_2d.names, positions=bound[None] + disp, rate=capture_2d.rate, units=face.units,
                      start_frame=capture_2d.start_frame, neutral_frame=n_frame, source=describe(tracks),
                      history=(step,))
    grazing = int((np.abs(normals @ cam.view_direction) < min_cos).sum())
    recorded = {"depth": o.depth, "neutral": n_frame, "min_cos": min_cos}
    if o.allow:
        from ..capture.plausibility import parse_allow

        recorded["allow"] = sorted(parse_allow(o.allow))
    # the lifted layer is a take: it records its own identity, as `import-capture` does (no mesh: a
    # capture may be bound on another face, by the same layout or retargeted)
    prov = provenance("lift", options=recorded,
                      inputs={"tracks": tracks, "mesh": mesh, "binding": o.binding, "layout": o.layout},
                      identity=identity(capture=capture_record(capture)))
    write_capture_layer(out, capture, prov=prov)
    moved = np.linalg.norm(disp, axis=2)
    where = describe(out) if is_in_memory(out) else str(out)
    summary = {
        "output": where, "frames": capture_2d.n_frames, "markers": capture_2d.n_markers, "rate": capture_2d.rate,
        "units": face.units, "depth": o.depth, "neutralFrame": n_frame,
        "cameraScale": cam.scale, "viewDirection": cam.view_direction.tolist(),
        "residualRms": cam.residual_rms, "residualMax": cam.residual_max,
        "grazingMarkers": grazing, "invalidSamples": int((~np.isfinite(uv).all(axis=2)).sum()),
        "maxDisplacement": float(np.nanmax(moved)) if np.isfinite(moved).any() else 0.0,
        "plausibility": checked,
    }
    text = [
        f"wrote {where}: {capture_2d.n_markers} markers x {capture_2d.n_frames} frames lifted to {face.units} on the "
        f"mesh (depth: {o.depth})",
        f"  camera: {cam.scale:.4g} px per {face.units}, view direction "
        f"({', '.join(f'{v:.3f}' for v in cam.view_direction)}), neutral fit rms {cam.residual_rms:.3g} px "
        f"(max {cam.residual_max:.3g} px)",
    ] + ([f"  {grazing} markers seen at a grazing angle: their depth step is bounded"] if grazing else [])
    return Result(layers={"output": out}, summary=summary, text=text)


def _name(source) -> str:
    """A file's name, or an in-memory layer as described in messages."""
    return describe(source) if is_in_memory(source) else Path(source).name


def _bound_surface(mesh, mesh_source, binding, layout):
    """(names, triangle_vertices, barycentrics, source) of the markers' bound points; a binding made
    for another mesh than ``mesh`` (read from ``mesh_source``) is refused (MixedLayersError)."""
    if (binding is None) == (layout is None):
        raise OptionError("lift: give exactly one of --binding BINDING.usda or --layout LAYOUT.json")
    if binding is not None:
        from ..usd.identity import claims_of, mesh_record, verify
        from ..usd.layers import open_stage
        from ..usd.mesh_layer import read_binding

        b = read_binding(open_stage(binding, what="binding"), source=str(binding))
        verify(claims_of(binding, "binding"), mesh=(f"mesh {describe(mesh_source)}", mesh_record(mesh)),
               remedy="bind on this mesh (`usdface bind`), or lift with --layout")
        return list(b.names), b.triangle_vertices, b.barycentrics, str(binding)
    from ..mesh.surface_points import project_to_surface
    from ..mesh.layout import read_layout

    lay = read_layout(layout)
    sp = project_to_surface(mesh, lay.positions(mesh))
    return list(lay.names), sp.triangle_vertices, sp.barycentrics, str(layout)


def _fit_camera(image_points, model_points, names, *, what: str):
    """Weak-perspective camera fitted robustly, and the judgement of its residuals.

    The residual of a correct fit is the difference between the performer's marker placement and
    the layout's (about 5% of the face on the sample clip; a 3D layout fit of the same take leaves
    6%), so it is judged by the same rule as a 3D layout fit. A marker far off (a wrong seed, a
    mislabelled track) is set aside and the camera refitted without it, as the 3D fit does.
    Returns (camera, findings).
    """
    from ..capture.lift import fit_weak_perspective
    from ..mesh.judgement import FIT_MARKER_FRACTION, MAX_EXCLUDED_FRACTION, extent, fit_residual_findings

    uv = np.asarray(image_points, dtype=np.float64)
    x = np.asarray(model_points, dtype=np.float64)
    kept = np.ones(len(uv), dtype=bool)
    while True:
        cam = fit_weak_perspective(uv[kept], x[kept])
        res = np.linalg.norm(cam.project(x) - uv, axis=1)
        face_px = cam.scale * extent(x)  # the face's size in the image, as a 3D fit measures it
        limit = FIT_MARKER_FRACTION * face_px
        worst = int(np.argmax(np.where(kept, res, -np.inf)))
        if res[worst] <= limit or (~kept).sum() >= int(MAX_EXCLUDED_FRACTION * len(uv)) or kept.sum() <= 4:
            break
        kept[worst] = False
    findings = fit_residual_findings(list(names), res, res <= limit, face_px, units="px", what=what)
    return cam, findings
