"""`usdface lift`: 2D marker tracks (a track layer or a 2D CSV) -> a 3D capture layer on the mesh.

See :mod:`usdface.capture.lift` for the method (weak-perspective camera fitted at the neutral
frame, in-plane motion, depth from the face surface or zero). The output is a capture layer in
mesh space and mesh units with the tracks' marker names, rate and frames; bind it with the same
layout (`usdface bind --layout`) and transfer it like any capture.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from ..errors import InputError, MarkerError, OptionError
from ..usd.layers import USD_SUFFIXES, check_output_path, provenance

log = logging.getLogger("usdface")


def read_tracks(path, *, rate=None):
    """2D tracks (Capture in pixels, z = 0) from a track layer (.usd*) or a 2D capture CSV."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"tracks {p}: no such file")
    suffix = p.suffix.lower()
    if suffix in USD_SUFFIXES:
        from ..usd.capture_layer import read_capture_layer

        try:
            from ..usd.track_layer import read_track_layer
        except ImportError:  # pragma: no cover - track layers not available in this build
            read_track_layer = None
        if read_track_layer is None:
            capture = read_capture_layer(p)
        else:
            try:
                capture, _ = read_track_layer(p)
            except InputError:
                capture = read_capture_layer(p)  # a capture layer of 2D data also holds tracks
    elif suffix == ".csv":
        from ..io.csv_format import read_csv

        try:
            capture = read_csv(p, rate=rate)
        except OptionError as exc:
            if "units" not in str(exc):
                raise
            capture = read_csv(p, units="cm", rate=rate)  # pixel tracks declare no length unit
    else:
        raise InputError(f"tracks {p}: expected a track layer ({', '.join(USD_SUFFIXES)}) or a 2D CSV")
    dims = next((int(h["dims"]) for h in capture.history if "dims" in h), None)
    z = capture.positions[..., 2]
    if dims == 3 or (dims is None and np.nanmax(np.abs(z)) > 0):
        raise InputError(f"tracks {p}: the tracks are 3D; `usdface lift` takes 2D image tracks "
                         "(import 3D capture with `usdface import-capture`)")
    return capture


def _bound_surface(mesh, binding, layout):
    """(names, triangle_vertices, barycentrics) of the markers' bound points."""
    if (binding is None) == (layout is None):
        raise OptionError("lift: give exactly one of --binding BINDING.usda or --layout LAYOUT.json")
    if binding is not None:
        from ..usd.layers import open_stage
        from ..usd.mesh_layer import read_binding

        b = read_binding(open_stage(binding, what="binding"), source=str(binding))
        return list(b.names), b.triangle_vertices, b.barycentrics, str(binding)
    from ..mesh.binding import project_to_surface
    from ..mesh.layout import read_layout

    lay = read_layout(layout)
    sp = project_to_surface(mesh, lay.positions(mesh))
    return list(lay.names), sp.triangle_vertices, sp.barycentrics, str(layout)


def lift(tracks_path, mesh_path, output, *, binding=None, layout=None, depth="zero", neutral=None,
         rate=None, min_cos=None, mesh_units=None, allow=()) -> dict:
    """Lift 2D tracks to a 3D capture layer on the mesh; returns the summary.

    ``mesh_path``: a mesh layer or any mesh file `usdface run` accepts (OBJ, PLY, ...; ``mesh_units``
    for files without units, default cm). The neutral tracks' fit to the markers' bound points is
    judged like a 3D layout fit (:func:`usdface.mesh.judgement.fit_residual_findings`, code
    ``fit-residual``): a marker more than 25% of the face's image size off, or an rms beyond 15%,
    stops the lift unless ``allow`` names the check.
    """
    from ..capture.lift import DEFAULT_MIN_COS, check_marker_sets, lift_displacements, surface_normals
    from ..model.capture import Capture
    from ..capture.plausibility import report
    from ..usd.capture_layer import write_capture_layer
    from .import_mesh import load_mesh

    out = check_output_path(output, inputs={"tracks": tracks_path, "--mesh": mesh_path, "--binding": binding,
                                            "--layout": layout})
    if depth not in ("tangent", "zero"):
        raise OptionError(f"--depth: expected tangent or zero; got {depth!r}")
    min_cos = DEFAULT_MIN_COS if min_cos is None else float(min_cos)
    tracks = read_tracks(tracks_path, rate=rate)
    from ..usd.layers import is_in_memory

    if not is_in_memory(mesh_path) and not Path(mesh_path).is_file():
        raise InputError(f"--mesh {mesh_path}: no such file")
    mesh, _ = load_mesh(mesh_path, units=mesh_units)
    names, tri, bary, place_src = _bound_surface(mesh, binding, layout)
    check_marker_sets(tracks.names, names, tracks=f"tracks {tracks_path}", layout=place_src)
    order = [names.index(n) for n in tracks.names]  # layout rows in the tracks' order
    tri, bary = np.asarray(tri)[order], np.asarray(bary)[order]
    bound = np.einsum("mk,mkd->md", bary, mesh.points[tri])
    n_frame = tracks.neutral_frame if neutral is None else int(neutral)
    if not 0 <= n_frame < tracks.n_frames:
        raise OptionError(f"--neutral {neutral}: outside 0..{tracks.n_frames - 1}")
    uv = tracks.positions[..., :2]
    ok = np.isfinite(uv[n_frame]).all(axis=1)
    if not ok.all():
        raise MarkerError(f"tracks {tracks_path}: marker(s) {', '.join(np.array(tracks.names)[~ok])} invalid at the "
                          f"neutral frame {n_frame}; choose another neutral frame (--neutral)")
    cam, findings = _fit_camera(uv[n_frame], bound, tracks.names, what=f"tracks {tracks_path} on {place_src}")
    checked = report(findings, allow=allow)
    normals = surface_normals(mesh.points, mesh.triangles(), tri, bary)
    disp = lift_displacements(uv, n_frame, cam, normals=normals, depth=depth, min_cos=min_cos)
    positions = bound[None] + disp
    step = {"step": "lift", "dims": 3, "tracks": Path(tracks_path).name, "depth": depth, "minCos": min_cos,
            "cameraScale": cam.scale, "cameraRows": cam.rows.tolist(), "cameraOffset": cam.offset.tolist(),
            "residualRms": cam.residual_rms, "residualMax": cam.residual_max, "neutralFrame": n_frame,
            "trackHistory": list(tracks.history)}
    capture = Capture(names=tracks.names, positions=positions, rate=tracks.rate, units=mesh.units,
                      start_frame=tracks.start_frame, neutral_frame=n_frame, source=str(tracks_path),
                      history=(step,))
    grazing = int((np.abs(normals @ cam.view_direction) < min_cos).sum())
    lift_options = {"depth": depth, "neutral": n_frame, "min_cos": min_cos}
    if allow:
        from ..capture.plausibility import parse_allow

        lift_options["allow"] = sorted(parse_allow(allow))
    prov = provenance("lift", options=lift_options,
                      inputs={"tracks": tracks_path, "mesh": mesh_path, "binding": binding, "layout": layout})
    write_capture_layer(out, capture, prov=prov)
    moved = np.linalg.norm(disp, axis=2)
    summary = {
        "output": str(out), "frames": tracks.n_frames, "markers": tracks.n_markers, "rate": tracks.rate,
        "units": mesh.units, "depth": depth, "neutralFrame": n_frame,
        "cameraScale": cam.scale, "viewDirection": cam.view_direction.tolist(),
        "residualRms": cam.residual_rms, "residualMax": cam.residual_max,
        "grazingMarkers": grazing, "invalidSamples": int((~np.isfinite(uv).all(axis=2)).sum()),
        "maxDisplacement": float(np.nanmax(moved)) if np.isfinite(moved).any() else 0.0,
        "plausibility": checked,
    }
    summary["_text"] = [
        f"wrote {out}: {tracks.n_markers} markers x {tracks.n_frames} frames lifted to {mesh.units} on the mesh "
        f"(depth: {depth})",
        f"  camera: {cam.scale:.4g} px per {mesh.units}, view direction "
        f"({', '.join(f'{v:.3f}' for v in cam.view_direction)}), neutral fit rms {cam.residual_rms:.3g} px "
        f"(max {cam.residual_max:.3g} px)",
    ] + ([f"  {grazing} markers seen at a grazing angle: their depth step is bounded"] if grazing else [])
    return summary


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


def register_cli(sub) -> None:
    """Add `usdface lift` to the CLI."""
    from ..cliargs import add_common_options

    p = sub.add_parser("lift", help="lift 2D marker tracks (video) to a 3D capture layer on the mesh",
                       description="Map 2D image tracks of face markers to 3D motion on a character mesh: fit a "
                                   "weak-perspective camera to the neutral frame against the markers' bound "
                                   "points, map image displacements into the image plane in mesh units, and take "
                                   "the depth change from the face surface (tangent plane) or zero. Writes a "
                                   "capture layer (mesh units, same marker names) for bind/transfer/skel.")
    p.add_argument("tracks", help="2D track layer (.usd*) or 2D capture CSV (pixels)")
    p.add_argument("--mesh", required=True, help="mesh layer, or a mesh file (OBJ, PLY, STL, OFF... as `run` takes)")
    p.add_argument("--mesh-units", choices=["mm", "cm", "dm", "m", "in", "ft"],
                   help="units of a mesh file that does not say (OBJ: default cm)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--binding", help="binding layer giving the markers' bound points")
    src.add_argument("--layout", help="marker layout JSON (usdface-layout/1) on the mesh")
    p.add_argument("--depth", choices=["zero", "tangent"], default="zero",
                   help="depth change: none (default), or slide on the tangent plane at the bound point")
    p.add_argument("--neutral", type=int, metavar="FRAME", help="neutral frame index (default: the tracks')")
    p.add_argument("--rate", type=float, metavar="HZ", help="track rate when a CSV does not declare it")
    p.add_argument("-o", "--output", required=True, help="capture layer to write (.usdc)")
    from ..cliargs import add_options, options_from_args
    from ..options import PlausibilityOptions

    add_options(p, PlausibilityOptions)
    add_common_options(p)
    p.set_defaults(func=lambda args: lift(args.tracks, args.mesh, args.output, binding=args.binding,
                                          layout=args.layout, depth=args.depth, neutral=args.neutral,
                                          rate=args.rate, mesh_units=args.mesh_units,
                                          allow=options_from_args(PlausibilityOptions, args).allow))
