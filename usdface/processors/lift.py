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
         rate=None, min_cos=None) -> dict:
    """Lift 2D tracks to a 3D capture layer on the mesh; returns the summary."""
    from ..capture.lift import (DEFAULT_MIN_COS, check_marker_sets, fit_weak_perspective, lift_displacements,
                                surface_normals)
    from ..capture.model import Capture
    from ..usd.capture_layer import write_capture_layer
    from ..usd.mesh_layer import read_mesh_layer

    out = check_output_path(output, inputs={"tracks": tracks_path, "--mesh": mesh_path, "--binding": binding,
                                            "--layout": layout})
    if depth not in ("tangent", "zero"):
        raise OptionError(f"--depth: expected tangent or zero; got {depth!r}")
    min_cos = DEFAULT_MIN_COS if min_cos is None else float(min_cos)
    tracks = read_tracks(tracks_path, rate=rate)
    mesh, _ = read_mesh_layer(mesh_path)
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
    cam = fit_weak_perspective(uv[n_frame], bound)
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
    face_px = cam.scale * float(np.ptp(bound, axis=0).max())
    if cam.residual_rms > 0.05 * face_px:  # more than 5% of the face's size in the image
        log.warning("the neutral tracks fit the layout poorly (rms %.2f px on a face %.0f px wide): check the "
                    "neutral frame, the layout and the track names", cam.residual_rms, face_px)
    prov = provenance("lift", options={"depth": depth, "neutral": n_frame, "min_cos": min_cos},
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
    }
    summary["_text"] = [
        f"wrote {out}: {tracks.n_markers} markers x {tracks.n_frames} frames lifted to {mesh.units} on the mesh "
        f"(depth: {depth})",
        f"  camera: {cam.scale:.4g} px per {mesh.units}, view direction "
        f"({', '.join(f'{v:.3f}' for v in cam.view_direction)}), neutral fit rms {cam.residual_rms:.3g} px "
        f"(max {cam.residual_max:.3g} px)",
    ] + ([f"  {grazing} markers seen at a grazing angle: their depth step is bounded"] if grazing else [])
    return summary


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
    p.add_argument("--mesh", required=True, help="mesh layer")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--binding", help="binding layer giving the markers' bound points")
    src.add_argument("--layout", help="marker layout JSON (usdface-layout/1) on the mesh")
    p.add_argument("--depth", choices=["zero", "tangent"], default="zero",
                   help="depth change: none (default), or slide on the tangent plane at the bound point")
    p.add_argument("--neutral", type=int, metavar="FRAME", help="neutral frame index (default: the tracks')")
    p.add_argument("--rate", type=float, metavar="HZ", help="track rate when a CSV does not declare it")
    p.add_argument("-o", "--output", required=True, help="capture layer to write (.usdc)")
    add_common_options(p)
    p.set_defaults(func=lambda args: lift(args.tracks, args.mesh, args.output, binding=args.binding,
                                          layout=args.layout, depth=args.depth, neutral=args.neutral,
                                          rate=args.rate))
