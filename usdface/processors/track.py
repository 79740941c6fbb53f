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

import logging
import time
from pathlib import Path

import numpy as np

from ..errors import OptionError
from ..fileutil import StagedOutputs, check_output_file, refuse_overwriting_inputs
from ..options import TrackOptions
from ..registry import Result
from ..usd.layers import check_output_path, describe, is_in_memory, provenance

log = logging.getLogger("usdface")

__all__ = ["track"]


def track(video, *, options: TrackOptions, output, csv=None, preview=None) -> Result:
    """Track coloured dots in a video; write a 2D track layer (and optionally CSV and a preview PNG).

    Parameters
    ----------
    video : path
        Movie (.mp4, .avi, .mov...), image sequence pattern (``name.####.png``) or folder.
    options : TrackOptions
        ``seeds`` (seed points on the first frame) or ``auto`` (number of dots to find), a
        ``layout`` (and its ``mesh``) to name automatic dots, the dot ``radius`` range (pixels),
        the ``rate`` (required for image sequences), the Mahalanobis ``threshold``, the colour
        covariance floor ``min_std`` (levels), the association ``gate`` (pixels), and the
        ``preview_frame`` (default: the middle one).
    output : path, Sdf.Layer or Usd.Stage
        Track layer.
    csv, preview : path, optional
        Also write the tracks as usdface CSV (2D, pixels) / a PNG of a tracked frame.
    """
    from ..io.images import check_image_output
    from ..io.video import open_video
    from ..tracking.detect import check_radius_range
    from ..usd.identity import capture_record, identity

    o = options
    t0 = time.perf_counter()
    if (o.seeds is None) == (o.auto is None):
        raise OptionError("track: give exactly one of --seeds SEEDS.json or --auto N")
    inputs = {"video": video, "--seeds": o.seeds, "--layout": o.layout, "--mesh": o.mesh}
    out = check_output_path(output, inputs=inputs)
    refuse_overwriting_inputs({"--csv": csv, "--preview": preview}, inputs)
    csv_path = check_output_file(csv, suffixes=(".csv",), option="--csv") if csv else None
    png_path = check_image_output(preview, suffixes=(".png",), option="--preview") if preview else None
    reader = open_video(video, rate=o.rate)
    radius = check_radius_range(o.radius, size=reader.size)
    detector, names, xy, area, init = _initialise(reader.read(0), reader.size, o, radius)
    if detector.model.regularised:
        log.info("colour model regularised to a %.0f-level floor", o.min_std)
    result, shown = _track(reader, detector, (names, xy, area), o, png_path is not None)
    elapsed = time.perf_counter() - t0
    # time code = frame index from 0 (the first frame read), whatever the sequence's numbering;
    # the first file's number is kept in the options (firstFrame) to map back to the footage
    capture = result.to_capture(source=str(video), units="px", start_frame=0)
    recorded = {"seeds": Path(o.seeds).name if o.seeds is not None else None, "auto": o.auto,
                "firstFrame": int(reader.first_frame), "radius": list(radius), "rate": reader.rate,
                "threshold": o.threshold, "minStd": o.min_std, "gate": result.stats["gate"],
                "layout": Path(o.layout).name if o.layout else None}
    prov_inputs = {"video": video if reader.kind == "movie" else None}
    if o.seeds is not None:
        prov_inputs["seeds"] = o.seeds
    if o.layout:
        prov_inputs["layout"] = o.layout
    # the layer holds a take (2D, pixels): it records its own identity, as a capture layer does
    prov = provenance("track", options=recorded, inputs=prov_inputs, identity=identity(capture=capture_record(capture)))
    picture = None
    if png_path is not None:
        from ..tracking.preview import render_track_preview

        picture = render_track_preview(shown[1], result, shown[0])
    files = _write(out, capture, result, reader, prov, (csv_path, png_path, picture))
    return _result(out, files, result, reader, detector, init, elapsed)


def _layout_front_view(layout_path, mesh_path=None):
    """Layout marker names and front-view positions (x, -y): y down like an image."""
    from ..mesh.layout import read_layout
    from ..usd.inputs import load_mesh

    layout = read_layout(layout_path)
    if mesh_path is not None:
        mesh, _ = load_mesh(mesh_path)
        pts = layout.positions(mesh)
    else:
        if any(m.vertex is not None for m in layout.markers):
            raise OptionError(f"--layout {layout_path}: has vertex entries; give the mesh with --mesh")
        pts = np.array([m.point for m in layout.markers], dtype=np.float64)
    return list(layout.names), np.stack([pts[:, 0], -pts[:, 1]], axis=1)




def _initialise(first, size, o: TrackOptions, radius):
    """(detector, names, positions, areas, how) on the first frame: from the seed points, or the
    ``auto`` dots found there (named by the layout's front view when there is one)."""
    from ..io.seeds import read_seeds
    from ..tracking.detect import check_seeds
    from ..tracking.tracker import initialise_auto, initialise_from_seeds

    layout_view = _layout_front_view(o.layout, o.mesh) if o.layout is not None else None
    if o.seeds is not None:
        seed_points = check_seeds(read_seeds(o.seeds), size, source=f"--seeds {o.seeds}")
        detector, names, xy, area = initialise_from_seeds(first, seed_points, radius=radius, threshold=o.threshold,
                                                          min_std=o.min_std)
        return detector, names, xy, area, "seeds"
    detector, names, xy, area = initialise_auto(first, int(o.auto), radius=radius, threshold=o.threshold,
                                                min_std=o.min_std, layout=layout_view)
    return detector, names, xy, area, "auto" + ("+layout" if layout_view else "")


def _track(reader, detector, start, o: TrackOptions, keep_preview: bool):
    """(TrackResult, (index, frame) shown in the preview or None): every frame tracked from
    ``start`` = (names, positions, areas) on the first."""
    from ..progress import progress
    from ..tracking.tracker import track_frames

    kept = {}
    want = o.preview_frame

    def frames():
        for i, frame in reader:
            if keep_preview:
                if want is None and i == reader.n_frames // 2:
                    kept["middle"] = (i, frame)
                elif want is not None and i == want:
                    kept[want] = frame
            yield frame

    names, xy, area = start
    result = track_frames(progress(frames(), total=reader.n_frames, desc="track", unit="frame"), detector, names, xy,
                          initial_area=area, rate=reader.rate, size=reader.size, gate=o.gate)
    if not keep_preview:
        return result, None
    if want is not None:
        if want not in kept:
            raise OptionError(f"--preview-frame {want}: outside 0..{result.positions.shape[0] - 1}")
        return result, (want, kept[want])
    return result, kept["middle"]


def _write(out, capture, result, reader, prov, extras) -> dict:
    """The CSV, the preview (``extras`` = (csv path, png path, picture)) and the track layer, all
    or none (a failure or an interruption leaves the old files as they were). Returns the files written."""
    from ..io.csv_format import write_csv
    from ..preview.png import write_png
    from ..usd.track_layer import write_track_layer

    csv_path, png_path, picture = extras
    files = {}
    with StagedOutputs() as staged:
        if csv_path is not None:
            write_csv(staged.path(csv_path), capture.replace(units=None), dims=2)
            files["csv"] = csv_path
        if png_path is not None:
            write_png(staged.path(png_path), picture)
            files["preview"] = png_path
        write_track_layer(staged.path(out), capture, confidence=result.confidence, image_size=reader.size, prov=prov,
                          source_video=str(capture.source))
        staged.commit()
    return files


def _result(out, files, result, reader, detector, init, elapsed) -> Result:
    """The summary and the lines `usdface track` prints."""
    csv_path, png_path = files.get("csv"), files.get("preview")
    names = result.names
    valid = result.valid
    n_frames, n_markers = valid.shape
    where = describe(out) if is_in_memory(out) else str(out)
    summary = {
        "output": where, "csv": str(csv_path) if csv_path else None, "preview": str(png_path) if png_path else None,
        "frames": n_frames, "markers": n_markers, "names": list(names), "rate": reader.rate,
        "imageSize": list(reader.size), "init": init, "validFraction": float(valid.mean()),
        "invalidSamples": int((~valid).sum()), "colourModel": {"mean": detector.model.mean.tolist(),
                                                              "regularised": bool(detector.model.regularised)},
        "stats": result.stats, "seconds": elapsed, "fps": n_frames / max(elapsed, 1e-9),
    }
    worst = sorted(zip((~valid).sum(axis=0), names), reverse=True)[:3]
    text = [
        f"tracked {n_markers} markers over {n_frames} frames ({reader.width}x{reader.height}, {reader.rate:g} fps) "
        f"in {elapsed:.1f} s ({summary['fps']:.0f} frames/s); init: {init}",
        f"valid samples: {100 * valid.mean():.1f}%" + (
            f"; most invalid: {', '.join(f'{n} ({c})' for c, n in worst if c)}" if (~valid).any() else ""),
        f"wrote {where}" + (f", {csv_path}" if csv_path else "") + (f", {png_path}" if png_path else ""),
    ]
    return Result(layers={"output": out}, files=files, summary=summary, text=text)
