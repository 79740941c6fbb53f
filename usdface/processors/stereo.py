"""`usdface stereo`: a stereo pair -> a disparity map and a metric scan mesh layer (seed 001,
section 2).

``usdface stereo LEFT RIGHT --calib CALIB.json -o SCAN.usdc [--disparity DISP.exr]``. Outputs are
written only when everything succeeded (atomic writes; a failure removes what the same run wrote).
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from ..errors import InputError, OptionError
from ..fileutil import StagedOutputs, refuse_overwriting_inputs
from ..options import StereoOptions
from ..registry import Result
from ..usd.layers import check_output_path, is_in_memory, provenance

__all__ = ["stereo"]


def stereo(left, right, *, options: StereoOptions, output=None, disparity=None) -> Result:
    """Stereo pair -> disparity map (optional file) and scan mesh layer (metric, needs ``options.calib``).

    Parameters
    ----------
    left, right : path
        The pair: left and right images, or top and bottom for a vertical rig.
    options : StereoOptions
        Calibration, method, fill, ground truth, disparity range, surface.
    output : path, Sdf.Layer or Usd.Stage, optional
        Scan mesh layer; needs the calibration. The mesh is in the scan frame (x right, y up,
        toward the camera) and the calibration's units, and its provenance records the camera
        (``scanCamera``) that `register` lifts image landmarks through.
    disparity : path, optional
        Disparity map to write (.exr, .tif, .pfm or .npy). Dense by default: pixels the method's
        checks reject get the background disparity of their row (``options.fill``); the scan
        mesh uses the accepted pixels only, either way.

    With ``options.ground_truth`` the summary gets the bad-pixel rate of the map (|d - gt| >
    ``options.bad_threshold`` px over the pixels with finite ground truth, missing disparities
    counted bad).
    """
    from ..io.images import FLOAT_MAP_SUFFIXES, check_image_output, read_float_map, read_image
    from ..scan.stereo import compute_disparity, fill_background

    o = options
    t0 = time.perf_counter()
    inputs = {"left": left, "right": right, "--calib": o.calib, "--ground-truth": o.ground_truth}
    out = check_output_path(output, inputs=inputs) if output is not None else None
    refuse_overwriting_inputs({"--disparity": disparity}, inputs)
    disp_path = check_image_output(disparity, suffixes=FLOAT_MAP_SUFFIXES, option="--disparity") if disparity else None
    if out is None and disparity is None and o.ground_truth is None:
        raise OptionError("stereo: nothing to do: give -o SCAN.usdc, --disparity DISP.exr and/or --ground-truth GT")
    gt = read_float_map(o.ground_truth) if o.ground_truth is not None else None
    if out is not None and o.calib is None:
        raise OptionError("stereo: a metric scan (-o) needs the camera calibration: --calib CALIB.json "
                          '({"f", "cx", "cy", "baseline", "doffs", "vertical"} for a rectified pair, '
                          "or K1, D1, K2, D2, R, T)")
    pair = _Pair.read(left, right, read_image)
    pair.rectify(o.calib, o.vertical)
    min_disparity, num_disparities = _disparity_range(o, pair.rcal)
    res = compute_disparity(pair.first, pair.second, o.matching(min_disparity=min_disparity,
                                                               num_disparities=num_disparities,
                                                               vertical=pair.vertical))
    d = np.where(res.valid, res.disparity, np.nan).astype(np.float32)  # accepted pixels: the scan's
    dmap = fill_background(res.disparity, res.valid, vertical=pair.vertical) if o.fill == "background" else d
    h, w = pair.first.shape[:2]
    summary = {"left": str(left), "right": str(right), "method": o.method, "size": [w, h],
               "vertical": pair.vertical, "minDisparity": res.min_disparity, "numDisparities": res.num_disparities,
               "validFraction": float(np.isfinite(d).mean()), "rectifiedCheck": pair.check, "fill": o.fill,
               "disparitySeconds": round(float(res.info.get("seconds", math.nan)), 3)}
    text = [f"{o.method}: disparities {res.min_disparity}..{res.min_disparity + res.num_disparities - 1} px on "
            f"{w}x{h}{' (vertical pair)' if pair.vertical else ''}, "
            f"{100 * summary['validFraction']:.1f}% of pixels valid, {summary['disparitySeconds']:.2f} s"]
    if gt is not None:
        _score(dmap, gt, o, pair, summary, text)
    scan = _scan_mesh(d, res, o, pair, inputs, summary, text, out) if out is not None else None
    files = _write(out, disp_path, dmap, scan, o.fill, summary, text)
    summary["seconds"] = round(time.perf_counter() - t0, 3)
    return Result(layers={"output": out} if out is not None else {}, files=files, summary=summary, text=text)


class _Pair:
    """The two images, rectified here when the calibration is not, with the calibration of the
    rectified pair (``rcal``) and the measured row (column) agreement of matched features."""

    def __init__(self, left, right, first, second):
        self.left, self.right = left, right
        self.first, self.second = first, second
        self.cal = self.rcal = self.rect = None
        self.vertical = False
        self.check = None

    @classmethod
    def read(cls, left, right, read_image) -> "_Pair":
        a, b = read_image(left), read_image(right)
        if a.shape[:2] != b.shape[:2]:
            raise InputError(f"stereo: {left} is {a.shape[1]}x{a.shape[0]} but {right} is {b.shape[1]}x{b.shape[0]}; "
                             "the two images of a pair must have the same size")
        return cls(left, right, a, b)

    def rectify(self, calib, vertical) -> None:
        """Read the calibration, rectify when it says the pair is not, and refuse a pair whose
        matched features disagree across the baseline."""
        from ..scan.calibration import read_calibration, rectify_pair
        from ..scan.stereo import check_rectified

        self.cal = read_calibration(calib) if calib is not None else None
        self.rcal = self.cal
        if self.cal is not None and not self.cal.rectified:
            self.rect = rectify_pair(self.first, self.second, self.cal)
            self.first, self.second, self.rcal = self.rect.first, self.rect.second, self.rect.calibration
        self.vertical = bool(self.rcal.vertical) if self.rcal is not None else bool(vertical)
        if self.rcal is not None and vertical is not None and bool(vertical) != self.rcal.vertical:
            raise OptionError(f"--vertical contradicts the calibration {calib} "
                              f"(vertical: {str(self.rcal.vertical).lower()})")
        self.check = check_rectified(self.first, self.second, vertical=self.vertical)
        if self.check["rectified"] is False:
            off = self.check["median_offset"]
            if self.cal is None:
                along = "column" if self.vertical else "row"
                raise InputError(f"stereo: {self.left} and {self.right} are not a rectified pair (matched features "
                                 f"differ by a median of {off:.1f} px across the baseline, {along}s should agree); "
                                 "give --calib with K1, D1, K2, D2, R, T to rectify them")
            raise InputError(f"stereo: after {'rectification' if self.rect else 'reading'}, matched features still "
                             f"differ by a median of {off:.1f} px across the baseline: the calibration {calib} does "
                             f"not fit these images (or the pair is {'horizontal' if self.vertical else 'vertical'})")


def _disparity_range(o: StereoOptions, rcal) -> tuple[int, int]:
    """(min_disparity, num_disparities): as given, else from the depth range through the
    calibration, else 0 and :data:`usdface.scan.stereo.DEFAULT_NUM_DISPARITIES`."""
    from ..scan.stereo import DEFAULT_NUM_DISPARITIES, disparity_range

    min_disparity, num_disparities = o.min_disparity, o.num_disparities
    if min_disparity is None and num_disparities is None and o.depth_range is not None:
        if rcal is None:
            raise OptionError("--depth-range needs --calib (depths become disparities through f and baseline)")
        min_disparity, num_disparities = disparity_range(rcal, *o.depth_range)
    min_disparity = 0 if min_disparity is None else int(min_disparity)
    num_disparities = DEFAULT_NUM_DISPARITIES if num_disparities is None else int(num_disparities)
    return min_disparity, num_disparities


def _score(dmap, gt, o: StereoOptions, pair: _Pair, summary: dict, text: list) -> None:
    """The bad-pixel rate of the map against the ground truth, into the summary and the text."""
    from ..scan.stereo import bad_pixel_rate

    if pair.rect is not None:
        raise OptionError("--ground-truth: the pair was rectified here, so the map is not in the ground truth's "
                          "pixels; give a rectified pair with its rectified calibration")
    if gt.shape != dmap.shape:
        raise InputError(f"--ground-truth {o.ground_truth}: {gt.shape[1]}x{gt.shape[0]} but the images are "
                         f"{dmap.shape[1]}x{dmap.shape[0]}")
    score = bad_pixel_rate(dmap, gt, threshold=o.bad_threshold)
    summary["groundTruth"] = {"file": str(o.ground_truth), "threshold": o.bad_threshold, **score}
    text.append(f"bad pixels (|d - gt| > {o.bad_threshold:g} px over the {score['pixels']} pixels with ground "
                f"truth, missing counted bad): {100 * score['bad']:.1f}%  (over the {100 * score['density']:.1f}% "
                f"given: {100 * score['bad_known']:.1f}%; map fill: {o.fill})")


def _scan_mesh(d, res, o: StereoOptions, pair: _Pair, inputs: dict, summary: dict, text: list, out):
    """(mesh, provenance) of the scan: the accepted pixels' depths as a surface, in the scan frame."""
    from ..model.mesh import FaceMesh
    from ..scan.calibration import scan_camera_dict
    from ..scan.surface import reconstruct_surface
    from ..usd.identity import identity, mesh_record

    rcal = pair.rcal
    depth = rcal.depth(d)
    surf = reconstruct_surface(rcal.points(depth), np.isfinite(depth), method=o.surface, step=o.step)
    mesh = FaceMesh(points=surf.points, face_vertex_counts=np.full(len(surf.triangles), 3),
                    face_vertex_indices=surf.triangles.ravel(), units=rcal.units, name="Scan", source=str(pair.left))
    h, w = pair.first.shape[:2]
    camera = scan_camera_dict(rcal, (w, h), rect=pair.rect, original=pair.cal)
    prov = provenance("stereo", options={"method": o.method, "minDisparity": res.min_disparity,
                                         "numDisparities": res.num_disparities, "surface": o.surface, "step": o.step,
                                         "vertical": pair.vertical},
                      inputs={"left": inputs["left"], "right": inputs["right"], "calibration": o.calib},
                      identity=identity(mesh=mesh_record(mesh)))  # a mesh layer: its own mesh
    prov["scanCamera"] = json.dumps(camera, sort_keys=True)
    zs = -surf.points[:, 2]
    where = _named(out)
    summary.update({"output": where, "points": int(surf.n_points), "triangles": int(len(surf.triangles)),
                    "units": rcal.units, "depthRange": [float(zs.min()), float(zs.max())]})
    text.append(f"wrote {where}: scan of {surf.n_points} points, {len(surf.triangles)} triangles ({o.surface}), "
                f"depth {zs.min():.1f}..{zs.max():.1f} {rcal.units}")
    return mesh, prov


def _write(out, disp_path, dmap, scan, fill: str, summary: dict, text: list) -> dict:
    """Write the disparity map and the scan layer, both or neither (a failure or an interruption
    leaves the old files as they were)."""
    from ..io.images import write_float_map
    from ..usd.mesh_layer import write_mesh_layer

    files = {}
    with StagedOutputs() as staged:
        if disp_path is not None:
            write_float_map(staged.path(disp_path), dmap)
            files["disparity"] = disp_path
            summary["disparity"] = str(disp_path)
            text.append(f"wrote {disp_path}: disparity map (float32, "
                        + ("rejected pixels filled with the background disparity)" if fill == "background"
                           else "NaN where rejected)"))
        if scan is not None:
            write_mesh_layer(staged.path(out), scan[0], [], prov=scan[1])
        staged.commit()
    return files


def _named(out) -> str:
    """How the summary names an output: its path, or an in-memory layer by name."""
    from ..usd.layers import describe

    return describe(out) if is_in_memory(out) else str(out)
