"""`usdface track`: a video of a face wearing coloured dots -> 2D marker tracks (seed 002).

``usdface track VIDEO [--seeds SEEDS.json | --auto N] [--layout L.json [--mesh M]] [--radius R1 R2]
[--rate HZ] -o TRACKS.usdc [--csv TRACKS.csv] [--preview OUT.png]``

The dots' colour is learned on the first frame at the seed points (``{"Chin": [x, y], ...}``,
pixels, OpenCV convention: integer = pixel centre, y down), or found by a circular Hough
transform (``--auto N``; names from a marker layout's front view when ``--layout`` is given, else
m00, m01, ...). Every frame is segmented by the Mahalanobis distance in YCbCr, cleaned by
morphology, split in connected components, refined to sub-pixel centroids; the tracker keeps
identities (constant-velocity prediction, global-motion correction, gated Hungarian assignment,
merged-blob splitting) and marks hidden or doubtful dots invalid.

Outputs (all checked before any work, written only when everything succeeded): a 2D track layer
(:mod:`usdface.usd.track_layer`), optionally the usdface CSV (2D wide form, pixels) and a preview PNG.
"""
from __future__ import annotations

import json
import logging
import os
import secrets
import time
from pathlib import Path

import numpy as np

from ..fileutil import refuse_overwriting_inputs
from ..errors import InputError, OptionError, UsdFaceError

log = logging.getLogger("usdface")

__all__ = ["track", "read_seeds", "register_cli"]


def read_seeds(path) -> dict:
    """Read seed points ``{"Name": [x, y]}`` (or ``{"Name": {"image": [x, y]}}``) from JSON."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"--seeds {p}: no such file")
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"--seeds {p}: not valid JSON ({exc})") from None
    if isinstance(data, dict) and "markers" in data and isinstance(data["markers"], dict):
        data = data["markers"]
    if not isinstance(data, dict):
        raise InputError(f"--seeds {p}: expected a JSON object {{\"MarkerName\": [x, y], ...}}")
    out = {}
    for k, v in data.items():
        if isinstance(v, dict):
            v = v.get("image", v.get("xy"))
        out[str(k)] = v
    return out


def _layout_front_view(layout_path, mesh_path=None):
    """Layout marker names and front-view positions (x, -y): y down like an image."""
    from ..mesh.layout import read_layout

    layout = read_layout(layout_path)
    if mesh_path is not None:
        from .import_mesh import load_mesh

        mesh, _ = load_mesh(mesh_path)
        pts = layout.positions(mesh)
    else:
        if any(m.vertex is not None for m in layout.markers):
            raise OptionError(f"--layout {layout_path}: has vertex entries; give the mesh with --mesh")
        pts = np.array([m.point for m in layout.markers], dtype=np.float64)
    return list(layout.names), np.stack([pts[:, 0], -pts[:, 1]], axis=1)


def _check_csv_output(path) -> Path:
    p = Path(path)
    if p.suffix.lower() != ".csv":
        raise OptionError(f"--csv {p}: expected a file ending in .csv")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise OptionError(f"--csv {p}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise OptionError(f"--csv {p}: folder {folder} is not writable")
    return p


def render_track_preview(frame: np.ndarray, result, index: int, *, trail: int = 12) -> np.ndarray:
    """The frame with tracked dots: green circle = valid, red cross = invalid (last position), trails."""
    import cv2

    img = frame.copy()
    pos = result.positions
    lo = max(0, index - trail)
    for j, name in enumerate(result.names):
        pts = pos[lo:index + 1, j]
        ok = np.isfinite(pts).all(axis=1)
        for a, b in zip(pts[:-1][ok[:-1] & ok[1:]], pts[1:][ok[:-1] & ok[1:]]):
            cv2.line(img, (int(round(a[0] * 4)), int(round(a[1] * 4))), (int(round(b[0] * 4)), int(round(b[1] * 4))),
                     (0, 255, 255), 1, cv2.LINE_AA, shift=2)
        p = pos[index, j]
        if np.isfinite(p).all():
            cv2.circle(img, (int(round(p[0] * 16)), int(round(p[1] * 16))), 9 * 16, (40, 220, 40), 1, cv2.LINE_AA,
                       shift=4)
            label_at = p
        else:
            valid_before = np.flatnonzero(np.isfinite(pos[:index + 1, j]).all(axis=1))
            if valid_before.size == 0:
                continue
            q = pos[valid_before[-1], j]
            c = (int(round(q[0])), int(round(q[1])))
            cv2.drawMarker(img, c, (30, 30, 230), cv2.MARKER_TILTED_CROSS, 14, 2, cv2.LINE_AA)
            label_at = q
        cv2.putText(img, name, (int(label_at[0]) + 8, int(label_at[1]) - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.33,
                    (255, 255, 255), 1, cv2.LINE_AA)
    n_valid = int(np.isfinite(pos[index]).all(axis=1).sum())
    cv2.putText(img, f"frame {index}: {n_valid}/{len(result.names)} valid", (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55,
                (255, 255, 255), 2, cv2.LINE_AA)
    cv2.putText(img, f"frame {index}: {n_valid}/{len(result.names)} valid", (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55,
                (0, 0, 0), 1, cv2.LINE_AA)
    return img


def track(video, output, *, seeds=None, auto: int | None = None, layout=None, mesh=None, radius=(3.0, 10.0),
          rate: float | None = None, csv=None, preview=None, preview_frame: int | None = None,
          threshold: float = 4.0, min_std: float = 8.0, gate: float | None = None) -> dict:
    """Track coloured dots in a video; write a 2D track layer (and optionally CSV and a preview PNG).

    Parameters
    ----------
    video : path
        Movie (.mp4, .avi, .mov...) or image sequence pattern (``name.####.png``) or folder.
    output : path
        Track layer (.usdc/.usda).
    seeds : path or dict, optional
        Seed points on the first frame ``{name: [x, y]}`` (pixels); or
    auto : int, optional
        Number of dots to find automatically on the first frame.
    layout, mesh : path, optional
        Marker layout JSON (and the mesh for vertex entries) to name ``auto`` dots.
    radius : (r_min, r_max)
        Dot radius range in pixels.
    rate : float, optional
        Frames per second (overrides the container; required for image sequences).
    csv, preview : path, optional
        Also write the tracks as usdface CSV (2D, pixels) / a PNG of a tracked frame.
    preview_frame : int, optional
        Frame shown in the preview (default: the one with the most invalid markers, else the middle).
    threshold, min_std, gate : float
        Mahalanobis threshold; colour covariance floor (levels); association gate (pixels).

    Returns
    -------
    dict
        Summary (``_text`` lines for the CLI).
    """
    from ..io.csv_format import write_csv
    from ..io.images import check_image_output
    from ..io.video import open_video
    from ..progress import progress
    from ..tracking.detect import check_radius_range, check_seeds
    from ..tracking.tracker import initialise_auto, initialise_from_seeds, track_frames
    from ..usd.layers import check_output_path, provenance
    from ..usd.track_layer import write_track_layer

    t0 = time.perf_counter()
    if (seeds is None) == (auto is None):
        raise OptionError("track: give exactly one of --seeds SEEDS.json or --auto N")
    inputs = {"video": video, "--seeds": seeds if not isinstance(seeds, dict) else None, "--layout": layout,
              "--mesh": mesh}
    out = check_output_path(output, inputs=inputs)
    refuse_overwriting_inputs({"--csv": csv, "--preview": preview}, inputs)
    csv_path = _check_csv_output(csv) if csv else None
    png_path = check_image_output(preview, suffixes=(".png",), option="--preview") if preview else None
    r = check_radius_range(radius)
    reader = open_video(video, rate=rate)
    r = check_radius_range(r, size=reader.size)
    first = reader.read(0)
    layout_view = _layout_front_view(layout, mesh) if layout is not None else None
    if seeds is not None:
        seed_points = read_seeds(seeds) if not isinstance(seeds, dict) else dict(seeds)
        seed_points = check_seeds(seed_points, reader.size, source=f"--seeds {seeds if not isinstance(seeds, dict) else ''}".strip())
        detector, names, xy, area = initialise_from_seeds(first, seed_points, radius=r, threshold=threshold,
                                                          min_std=min_std)
        init = "seeds"
    else:
        detector, names, xy, area = initialise_auto(first, int(auto), radius=r, threshold=threshold, min_std=min_std,
                                                    layout=layout_view)
        init = "auto" + ("+layout" if layout_view else "")
    if detector.model.regularised:
        log.info("colour model regularised to a %.0f-level floor", min_std)

    kept = {}
    want = preview_frame

    def frames():
        for i, frame in reader:
            if png_path is not None:
                if want is None and i == reader.n_frames // 2:
                    kept["middle"] = (i, frame)
                elif want is not None and i == want:
                    kept[want] = frame
            yield frame

    result = track_frames(progress(frames(), total=reader.n_frames, desc="track", unit="frame"), detector, names, xy,
                          initial_area=area, rate=reader.rate, size=reader.size, gate=gate)
    elapsed = time.perf_counter() - t0
    # time code = frame index from 0 (the first frame read), whatever the sequence's numbering;
    # the first file's number is kept in the options (firstFrame) to map back to the footage
    capture = result.to_capture(source=str(video), units="px", start_frame=0)
    options = {"seeds": None if seeds is None or isinstance(seeds, dict) else Path(seeds).name, "auto": auto,
               "firstFrame": int(reader.first_frame),
               "radius": list(r), "rate": reader.rate, "threshold": threshold, "minStd": min_std, "gate": result.stats["gate"],
               "layout": Path(layout).name if layout else None}
    inputs = {"video": video if reader.kind == "movie" else None}
    if seeds is not None and not isinstance(seeds, dict):
        inputs["seeds"] = seeds
    if layout:
        inputs["layout"] = layout
    prov = provenance("track", options=options, inputs=inputs)
    written = []
    try:
        write_track_layer(out, capture, confidence=result.confidence, image_size=reader.size, prov=prov,
                          source_video=str(video))
        written.append(out)
        if csv_path is not None:
            tmp = csv_path.with_name(f".{csv_path.stem}.tmp-{os.getpid()}-{secrets.token_hex(4)}.csv")
            try:
                write_csv(tmp, capture.replace(units=None), dims=2)
                os.replace(tmp, csv_path)
            finally:
                if tmp.exists():
                    tmp.unlink()
            written.append(csv_path)
        if png_path is not None:
            from ..preview.render import write_png

            if want is not None:
                if want not in kept:
                    raise OptionError(f"--preview-frame {want}: outside 0..{result.positions.shape[0] - 1}")
                idx, frame = want, kept[want]
            else:
                idx, frame = kept["middle"]
            write_png(png_path, render_track_preview(frame, result, idx))
            written.append(png_path)
    except BaseException:
        for p in written:
            try:
                Path(p).unlink()
            except OSError:
                pass
        raise
    valid = result.valid
    n_frames, n_markers = valid.shape
    summary = {
        "output": str(out), "csv": str(csv_path) if csv_path else None, "preview": str(png_path) if png_path else None,
        "frames": n_frames, "markers": n_markers, "names": list(names), "rate": reader.rate,
        "imageSize": list(reader.size), "init": init, "validFraction": float(valid.mean()),
        "invalidSamples": int((~valid).sum()), "colourModel": {"mean": detector.model.mean.tolist(),
                                                              "regularised": bool(detector.model.regularised)},
        "stats": result.stats, "seconds": elapsed, "fps": n_frames / max(elapsed, 1e-9),
    }
    worst = sorted(zip((~valid).sum(axis=0), names), reverse=True)[:3]
    summary["_text"] = [
        f"tracked {n_markers} markers over {n_frames} frames ({reader.width}x{reader.height}, {reader.rate:g} fps) "
        f"in {elapsed:.1f} s ({summary['fps']:.0f} frames/s); init: {init}",
        f"valid samples: {100 * valid.mean():.1f}%" + (
            f"; most invalid: {', '.join(f'{n} ({c})' for c, n in worst if c)}" if (~valid).any() else ""),
        f"wrote {out}" + (f", {csv_path}" if csv_path else "") + (f", {png_path}" if png_path else ""),
    ]
    return summary


def register_cli(subparsers) -> None:
    """Add ``usdface track`` to the CLI's subparsers."""
    from ..cliargs import add_common_options

    p = subparsers.add_parser(
        "track", help="track coloured face markers in a video -> 2D track layer (+ CSV, preview)",
        description="Track coloured dots on a face in a video (seed 002: YCbCr Mahalanobis colour segmentation, "
                    "morphology, connected components, sub-pixel centroids, circular Hough transform) and keep their "
                    "identities frame to frame; write a 2D track layer (pixels, y down), optionally CSV and a preview.")
    p.add_argument("video", help="movie (.mp4, .avi, .mov) or image sequence (name.####.png|jpg|tif|exr|dpx)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--seeds", metavar="SEEDS.json",
                     help='seed points on the first frame: {"Chin": [x, y], ...} (pixels; integer = pixel centre, y down)')
    src.add_argument("--auto", type=int, metavar="N", help="find N dots automatically on the first frame")
    p.add_argument("--layout", metavar="L.json", help="marker layout to name --auto dots (front view)")
    p.add_argument("--mesh", metavar="M", help="mesh for the layout's vertex entries")
    p.add_argument("--radius", nargs=2, type=float, default=[3.0, 10.0], metavar=("R1", "R2"),
                   help="dot radius range in pixels (default 3 10)")
    p.add_argument("--rate", type=float, metavar="HZ", help="frames per second (default: the container's)")
    p.add_argument("--threshold", type=float, default=4.0, help="Mahalanobis distance threshold (default 4)")
    p.add_argument("--min-std", type=float, default=8.0, metavar="LEVELS",
                   help="colour covariance floor in 8-bit levels (regularises degenerate models; default 8)")
    p.add_argument("--gate", type=float, metavar="PX", help="association gate (default: half the smallest spacing)")
    p.add_argument("-o", "--output", required=True, metavar="TRACKS.usdc", help="track layer to write")
    p.add_argument("--csv", metavar="TRACKS.csv", help="also write the tracks as usdface CSV (2D, pixels)")
    p.add_argument("--preview", metavar="OUT.png", help="also write a PNG of a tracked frame")
    p.add_argument("--preview-frame", type=int, metavar="F", help="frame for --preview (default: the middle)")
    add_common_options(p)
    p.set_defaults(func=_cmd_track)


def _cmd_track(args) -> dict:
    return track(args.video, args.output, seeds=args.seeds, auto=args.auto, layout=args.layout, mesh=args.mesh,
                 radius=tuple(args.radius), rate=args.rate, csv=args.csv, preview=args.preview,
                 preview_frame=args.preview_frame, threshold=args.threshold, min_std=args.min_std, gate=args.gate)
