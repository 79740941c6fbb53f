"""Face acquisition processors (seed 001, sections 2-4): ``stereo``, ``detect``, ``landmarks train``,
``register``.

- ``usdface stereo LEFT RIGHT --calib CALIB.json -o SCAN.usdc [--disparity DISP.exr]``: a stereo
  pair to a disparity map and a metric scan mesh layer;
- ``usdface detect IMAGE -o FEATURES.json [--aam MODEL.npz] [--preview OUT.png]``: Haar face,
  eyes and mouth, and (with a model) the facial landmarks;
- ``usdface landmarks train IMAGES... -o MODEL.npz`` (point files beside the images) or
  ``usdface landmarks train IMAGE --landmarks L.json -o MODEL.npz`` (one hand-annotated image,
  augmented): an active appearance model;
- ``usdface register --generic MESH.usd --scan SCAN.usd --landmarks L.json -o REGISTERED.usdc``:
  the generic face warped onto the scan, keeping its topology, regions and marker layout.

Each writes its outputs only when everything succeeded (atomic writes; a failure removes what
the same run wrote before it).
"""
from __future__ import annotations

import json
import logging
import math
import time
from pathlib import Path

import numpy as np

from ..fileutil import refuse_overwriting_inputs
from ..errors import ComputeError, InputError, MeshError, OptionError, list_names

log = logging.getLogger("usdface")

__all__ = ["stereo", "detect", "landmarks_train", "register", "register_cli", "scan_camera",
           "lift_image_landmarks"]


# ================================================================================================
# stereo
# ================================================================================================
def stereo(left, right, output=None, *, calib=None, method: str = "sgbm", disparity=None, min_disparity=None,
           num_disparities=None, depth_range=None, vertical=None, surface: str = "grid", step: int = 2,
           max_cycles: int = 3, time_limit=None, block_size: int = 5, max_stretch: float = 4.0,
           fill: str = "background", ground_truth=None, bad_threshold: float = 2.0) -> dict:
    """Stereo pair -> disparity map (optional file) and scan mesh layer (metric, needs ``calib``).

    Parameters
    ----------
    left, right : path
        The pair: left and right images, or top and bottom for a vertical rig.
    output : path, optional
        Scan mesh layer (.usdc/.usda); needs ``calib``.
    calib : path, optional
        Calibration JSON (:mod:`usdface.scan.calibration`).
    method : str
        ``sgbm`` (default), ``sgbm-wls`` (SGBM + WLS filter) or ``graphcut``
        (:mod:`usdface.scan.stereo`).
    disparity : path, optional
        Disparity map to write (.exr, .tif, .pfm or .npy).
    fill : {"background", "none"}
        The disparity map (written and scored) is dense by default: pixels the method's checks
        reject get the background disparity of their row (:func:`usdface.scan.stereo.fill_background`);
        ``"none"`` leaves them NaN. The scan mesh uses the accepted pixels only, either way.
    ground_truth : path, optional
        Ground-truth disparity (.npz, .pfm, .exr, .npy, .tif; +inf or NaN where unknown) of the
        first image: the summary gets the bad-pixel rate of the map (|d - gt| > ``bad_threshold``
        px over the pixels with finite ground truth, missing disparities counted bad).
    min_disparity, num_disparities : int, optional
        Disparity range (default: from ``depth_range`` with a calibration, else 0 and 64).
    depth_range : (near, far), optional
        Depths in calibration units, to set the disparity range.
    vertical : bool, optional
        Vertical rig without calibration (with one, the calibration says).
    surface : str
        ``grid``, ``poisson`` or ``ball-pivoting``.
    step : int
        Pixel subsampling of the scan mesh.
    """
    from ..io.images import FLOAT_MAP_SUFFIXES, check_image_output, read_image, write_float_map
    from ..mesh.model import FaceMesh
    from ..scan.calibration import read_calibration, rectify_pair
    from ..scan.stereo import METHODS, bad_pixel_rate, check_rectified, compute_disparity, disparity_range, fill_background
    from ..scan.surface import reconstruct_surface
    from ..usd.layers import check_output_path, provenance

    t0 = time.perf_counter()
    inputs = {"left": left, "right": right, "--calib": calib, "--ground-truth": ground_truth}
    out = check_output_path(output, inputs=inputs) if output is not None else None
    refuse_overwriting_inputs({"--disparity": disparity}, inputs)
    disp_path = check_image_output(disparity, suffixes=FLOAT_MAP_SUFFIXES, option="--disparity") if disparity else None
    if method not in METHODS:
        raise OptionError(f"--method must be one of {', '.join(METHODS)}; got {method!r}")
    if fill not in ("background", "none"):
        raise OptionError(f"--fill must be background or none; got {fill!r}")
    if out is None and disparity is None and ground_truth is None:
        raise OptionError("stereo: nothing to do: give -o SCAN.usdc, --disparity DISP.exr and/or --ground-truth GT")
    gt = None
    if ground_truth is not None:
        from ..io.images import read_float_map

        gt = read_float_map(ground_truth)
    if out is not None and calib is None:
        raise OptionError("stereo: a metric scan (-o) needs the camera calibration: --calib CALIB.json "
                          '({"f", "cx", "cy", "baseline", "doffs", "vertical"} for a rectified pair, '
                          "or K1, D1, K2, D2, R, T)")
    a = read_image(left)
    b = read_image(right)
    if a.shape[:2] != b.shape[:2]:
        raise InputError(f"stereo: {left} is {a.shape[1]}x{a.shape[0]} but {right} is {b.shape[1]}x{b.shape[0]}; "
                         "the two images of a pair must have the same size")
    cal = read_calibration(calib) if calib is not None else None
    rect = None
    if cal is not None and not cal.rectified:
        rect = rectify_pair(a, b, cal)
        a, b, rcal = rect.first, rect.second, rect.calibration
    else:
        rcal = cal
    is_vertical = bool(rcal.vertical) if rcal is not None else bool(vertical)
    if rcal is not None and vertical is not None and bool(vertical) != rcal.vertical:
        raise OptionError(f"--vertical contradicts the calibration {calib} (vertical: {str(rcal.vertical).lower()})")
    check = check_rectified(a, b, vertical=is_vertical)
    if check["rectified"] is False:
        along = "column" if is_vertical else "row"
        if cal is None:
            raise InputError(f"stereo: {left} and {right} are not a rectified pair (matched features differ by a "
                             f"median of {check['median_offset']:.1f} px across the baseline, {along}s should agree); "
                             "give --calib with K1, D1, K2, D2, R, T to rectify them")
        raise InputError(f"stereo: after {'rectification' if rect else 'reading'}, matched features still differ by "
                         f"a median of {check['median_offset']:.1f} px across the baseline: the calibration "
                         f"{calib} does not fit these images (or the pair is {'horizontal' if is_vertical else 'vertical'})")
    if min_disparity is None and num_disparities is None and depth_range is not None:
        if rcal is None:
            raise OptionError("--depth-range needs --calib (depths become disparities through f and baseline)")
        min_disparity, num_disparities = disparity_range(rcal, *depth_range)
    min_disparity = 0 if min_disparity is None else int(min_disparity)
    num_disparities = 64 if num_disparities is None else int(num_disparities)
    from ..scan.graphcut import GraphCutParameters
    from ..scan.stereo import MatchingParameters

    res = compute_disparity(a, b, MatchingParameters(method=method, min_disparity=min_disparity,
                                                     num_disparities=num_disparities, vertical=is_vertical,
                                                     block_size=block_size,
                                                     graphcut=GraphCutParameters(max_cycles=max_cycles,
                                                                                 time_limit=time_limit)))
    d = np.where(res.valid, res.disparity, np.nan).astype(np.float32)  # accepted pixels: the scan's
    dmap = fill_background(res.disparity, res.valid, vertical=is_vertical) if fill == "background" else d
    summary = {"left": str(left), "right": str(right), "method": method, "size": [a.shape[1], a.shape[0]],
               "vertical": is_vertical, "minDisparity": res.min_disparity, "numDisparities": res.num_disparities,
               "validFraction": float(np.isfinite(d).mean()), "rectifiedCheck": check, "fill": fill,
               "disparitySeconds": round(float(res.info.get("seconds", math.nan)), 3)}
    text = [f"{method}: disparities {res.min_disparity}..{res.min_disparity + res.num_disparities - 1} px on "
            f"{a.shape[1]}x{a.shape[0]}{' (vertical pair)' if is_vertical else ''}, "
            f"{100 * summary['validFraction']:.1f}% of pixels valid, {summary['disparitySeconds']:.2f} s"]
    if gt is not None:
        if rect is not None:
            raise OptionError("--ground-truth: the pair was rectified here, so the map is not in the ground truth's "
                              "pixels; give a rectified pair with its rectified calibration")
        if gt.shape != dmap.shape:
            raise InputError(f"--ground-truth {ground_truth}: {gt.shape[1]}x{gt.shape[0]} but the images are "
                             f"{dmap.shape[1]}x{dmap.shape[0]}")
        score = bad_pixel_rate(dmap, gt, threshold=bad_threshold)
        summary["groundTruth"] = {"file": str(ground_truth), "threshold": bad_threshold, **score}
        text.append(f"bad pixels (|d - gt| > {bad_threshold:g} px over the {score['pixels']} pixels with ground "
                    f"truth, missing counted bad): {100 * score['bad']:.1f}%  (over the {100 * score['density']:.1f}% "
                    f"given: {100 * score['bad_known']:.1f}%; map fill: {fill})")
    mesh = prov = None
    if out is not None:
        depth = rcal.depth(d)
        pts = rcal.points(depth)
        surf = reconstruct_surface(pts, np.isfinite(depth), method=surface, step=step, max_stretch=max_stretch)
        mesh = FaceMesh(points=surf.points, face_vertex_counts=np.full(len(surf.triangles), 3),
                        face_vertex_indices=surf.triangles.ravel(), units=rcal.units, name="Scan", source=str(left))
        camera = scan_camera_dict(rcal, (a.shape[1], a.shape[0]), rect=rect, original=cal)
        prov = provenance("stereo", options={"method": method, "minDisparity": res.min_disparity,
                                             "numDisparities": res.num_disparities, "surface": surface, "step": step,
                                             "vertical": is_vertical},
                          inputs={"left": left, "right": right, "calibration": calib})
        prov["scanCamera"] = json.dumps(camera, sort_keys=True)
        zs = -surf.points[:, 2]
        summary.update({"output": str(out), "points": int(surf.n_points), "triangles": int(len(surf.triangles)),
                        "units": rcal.units, "depthRange": [float(zs.min()), float(zs.max())]})
        text.append(f"wrote {out}: scan of {surf.n_points} points, {len(surf.triangles)} triangles ({surface}), "
                    f"depth {zs.min():.1f}..{zs.max():.1f} {rcal.units}")
    # writes last, so a failure above leaves nothing behind
    written = []
    try:
        if disp_path is not None:
            write_float_map(disp_path, dmap)
            written.append(disp_path)
            summary["disparity"] = str(disp_path)
            text.append(f"wrote {disp_path}: disparity map (float32, "
                        + ("rejected pixels filled with the background disparity)" if fill == "background"
                           else "NaN where rejected)"))
        if out is not None:
            from ..usd.mesh_layer import write_mesh_layer

            write_mesh_layer(out, mesh, [], prov=prov)
    except BaseException:
        for p in written:
            Path(p).unlink(missing_ok=True)
        raise
    summary["seconds"] = round(time.perf_counter() - t0, 3)
    summary["_text"] = text
    return summary


def scan_camera_dict(rcal, size, *, rect=None, original=None) -> dict:
    """What ``register`` needs to lift image landmarks onto a scan: the first rectified camera."""
    cam = {"f": rcal.f, "cx": rcal.cx, "cy": rcal.cy, "width": int(size[0]), "height": int(size[1]),
           "baseline": rcal.baseline, "doffs": rcal.doffs, "vertical": bool(rcal.vertical), "units": rcal.units,
           "frame": "scan = (x, -y, -z) of the first rectified camera (x right, y down, z forward)"}
    if rect is not None and rect.R1 is not None:
        cam["rectification"] = {"K1": original.K1.tolist(), "D1": original.D1.ravel().tolist(),
                                "R1": rect.R1.tolist(), "P1": rect.P1.tolist()}
    return cam


def scan_camera(scan_path) -> dict | None:
    """The ``scanCamera`` a ``stereo`` scan layer records (None for other meshes)."""
    from ..usd.layers import get_provenance, open_stage

    prov = get_provenance(open_stage(scan_path, what="scan"))
    raw = prov.get("scanCamera")
    return json.loads(raw) if raw else None


# ================================================================================================
# detect
# ================================================================================================
def detect(image, output, *, preview=None, aam=None, min_size=None, min_neighbors: int = 5) -> dict:
    """Haar face/eye/mouth detection (and AAM landmarks with ``aam``) -> features JSON."""
    from ..io.images import check_image_output, read_image, write_image
    from ..scan.detect import detect_faces, draw_detections, features_dict
    from ..scan.landmarks import _atomic_text

    refuse_overwriting_inputs({"-o": output, "--preview": preview}, {"image": image, "--aam": aam})
    out = Path(output)
    if out.suffix.lower() != ".json":
        raise OptionError(f"-o {out}: expected a .json features file")
    if not (out.parent if str(out.parent) else Path(".")).is_dir():
        raise OptionError(f"-o {out}: folder {out.parent} does not exist")
    prev = check_image_output(preview, option="--preview") if preview else None
    model = None
    if aam is not None:
        from ..scan.aam import load_aam

        model = load_aam(aam)
    img = read_image(image)
    faces = detect_faces(img, min_size=min_size, min_neighbors=min_neighbors)
    h, w = img.shape[:2]
    if not faces:
        raise ComputeError(f"detect: no face found in {image} ({w}x{h}; Haar frontal-face cascade, faces of at least "
                           f"{min_size or max(24, min(h, w) // 12)} px). Nothing written. A face must be frontal and "
                           "upright; try --min-size for small faces")
    landmarks = None
    fit = None
    if model is not None:
        fit = model.fit(img, faces[0].box)
        landmarks = {n: tuple(p) for n, p in zip(model.names, fit.points)}
    data = features_dict(Path(image).name, (w, h), faces, landmarks)
    text = [f"{len(faces)} face(s) in {image}: " + "; ".join(
        f"box {list(f.box)}, {len(f.eyes)} eye(s), mouth {'found' if f.mouth else 'not found'}" for f in faces)]
    if fit is not None:
        text.append(f"  {len(model.names)} landmarks fitted on the largest face (AAM residual {fit.residual:.3f}, "
                    f"{fit.iterations} iterations)")
    pic = draw_detections(img, faces, fit.points if fit is not None else None) if prev else None
    _atomic_text(out, json.dumps(data, indent=1) + "\n")
    try:
        if prev is not None:
            write_image(prev, pic)
            text.append(f"wrote {prev}: preview")
    except BaseException:
        out.unlink(missing_ok=True)
        raise
    text.insert(0, f"wrote {out}")
    return dict(data, output=str(out), _text=text)


# ================================================================================================
# landmarks train
# ================================================================================================
def _annotation_for(image: Path, points_dir: Path | None):
    from ..scan.landmarks import read_landmarks, read_pts

    folder = points_dir or image.parent
    for cand in (folder / f"{image.stem}.pts", folder / f"{image.stem}.landmarks.json", folder / f"{image.stem}.json"):
        if cand.is_file():
            if cand.suffix == ".pts":
                return None, read_pts(cand)
            lm = read_landmarks(cand)
            return list(lm.image), lm.image_array()
    raise InputError(f"landmarks train: no point file for {image} (looked for {image.stem}.pts, "
                     f"{image.stem}.landmarks.json, {image.stem}.json in {folder})")


def landmarks_train(images, output, *, landmarks=None, points_dir=None, augment=None, model_size: float = 60.0,
                    seed: int = 0) -> dict:
    """Train an AAM from annotated images (point files beside them) or one image + a landmarks file."""
    from ..io.images import read_image
    from ..scan.aam import augment_sample, train_aam
    from ..scan.detect import largest_face_box
    from ..scan.landmarks import FACE_LANDMARKS, read_landmarks

    refuse_overwriting_inputs({"-o": output}, {"images": [str(p) for p in images], "--landmarks": landmarks})
    out = Path(output)
    if out.suffix != ".npz":
        raise OptionError(f"-o {out}: an AAM model is written as .npz")
    if not (out.parent if str(out.parent) else Path(".")).is_dir():
        raise OptionError(f"-o {out}: folder {out.parent} does not exist")
    images = [Path(p) for p in images]
    if not images:
        raise OptionError("landmarks train: give at least one image")
    imgs, shapes, names = [], [], None
    if landmarks is not None:
        if len(images) != 1:
            raise OptionError("landmarks train --landmarks L.json takes exactly one image (the one the file annotates)")
        lm = read_landmarks(landmarks)
        if not lm.image:
            raise InputError(f"landmarks {landmarks}: no image points")
        img = read_image(images[0])
        lm.check_inside((img.shape[1], img.shape[0]), what=f"image {images[0]}")
        names = [n for n in FACE_LANDMARKS if n in lm.image] + [n for n in lm.image if n not in FACE_LANDMARKS]
        pts = lm.image_array(names)
        n_aug = 40 if augment is None else int(augment)
        ai, ap = augment_sample(img, pts, n_aug, seed=seed)
        imgs, shapes = [img] + ai, np.concatenate([pts[None], ap])
    else:
        for p in images:
            img = read_image(p)
            nm, pts = _annotation_for(p, Path(points_dir) if points_dir else None)
            if nm is not None:
                if names is None:
                    names = nm
                elif nm != names:
                    raise InputError(f"landmarks train: {p}'s points are {list_names(nm)}, expected "
                                     f"{list_names(names)} (every image needs the same landmarks in the same order)")
                pts = np.array([pts[nm.index(n)] for n in names])
            if names is None:
                names = [f"p{k}" for k in range(len(pts))]
            if len(pts) != len(names):
                raise InputError(f"landmarks train: {p} has {len(pts)} points, the others {len(names)}")
            bad = (pts[:, 0] < -0.5) | (pts[:, 0] > img.shape[1] - 0.5) | (pts[:, 1] < -0.5) | (pts[:, 1] > img.shape[0] - 0.5)
            if bad.any():
                raise InputError(f"landmarks train: {int(bad.sum())} point(s) of {p} lie outside the "
                                 f"{img.shape[1]}x{img.shape[0]} image: {list_names(np.array(names)[bad])}")
            imgs.append(img)
            shapes.append(pts)
        shapes = np.asarray(shapes)
        if augment:
            extra_i, extra_p = [], []
            for k, (im, pt) in enumerate(zip(list(imgs), shapes)):
                ai, ap = augment_sample(im, pt, int(augment), seed=seed + k)
                extra_i += ai
                extra_p.append(ap)
            imgs += extra_i
            shapes = np.concatenate([shapes] + extra_p)
    from ..scan.aam import AAMTrainingParameters

    model = train_aam(imgs, shapes, names=names, params=AAMTrainingParameters(model_size=model_size),
                      detector=largest_face_box)
    model.save(out)
    m = model.meta
    return {"output": str(out), "images": len(imgs), "points": len(names), "names": list(names),
            "shapeModes": m["shape_modes"], "appearanceModes": m["appearance_modes"], "seconds": m["seconds"],
            "_text": [f"wrote {out}: AAM of {len(names)} landmarks from {len(imgs)} image(s) "
                      f"({m['shape_modes']} shape modes, appearance modes {m['appearance_modes']}, "
                      f"{m['template_pixels']} template pixels, {m['seconds']:.1f} s)"]}


# ================================================================================================
# register
# ================================================================================================
def lift_image_landmarks(image_points: dict, scan_points, scan_triangles, camera: dict, *, radius: int = 2,
                         scan_source: str = "scan") -> dict:
    """Image landmarks -> 3-D scan points through the scan's depth seen by its camera.

    The scan mesh is rendered (z-buffer, exact ray intersection) from the first rectified camera it
    was made from; each landmark takes the depth interpolated at its sub-pixel position, or, next
    to a hole (eye corners and lip lines often are), the depth of the nearest surface pixel within
    ``radius`` pixels.

    Raises
    ------
    InputError
        A landmark is outside the image or has no scan surface around it (a hole).
    """
    from ..scan.render import PinholeCamera, _raycast
    from ..scan.surface import scan_to_camera

    w, h = int(camera["width"]), int(camera["height"])
    names = list(image_points)
    uv = np.array([image_points[n] for n in names], dtype=np.float64).reshape(-1, 2)
    rc = camera.get("rectification")
    if rc:
        from ..scan.calibration import rectify_image_points

        uv = rectify_image_points(uv, rc["K1"], rc["D1"], rc["R1"], rc["P1"])
    outside = [f"{n} ({u:.1f}, {v:.1f})" for n, (u, v) in zip(names, uv)
               if not (-0.5 <= u <= w - 0.5 and -0.5 <= v <= h - 0.5)]
    if outside:
        raise InputError(f"landmarks outside the {w}x{h} image of {scan_source}: {list_names(outside)}")
    K = np.array([[camera["f"], 0, camera["cx"]], [0, camera["f"], camera["cy"]], [0, 0, 1.0]])
    cam = PinholeCamera(K=K, R=np.diag([1.0, -1.0, -1.0]), t=np.zeros(3), size=(w, h))
    _, _, depth = _raycast(np.asarray(scan_points, dtype=np.float64), np.asarray(scan_triangles, dtype=np.int64), cam)
    out, holes = {}, []
    for n, (u, v) in zip(names, uv):
        zc = _depth_at(depth, u, v, radius)
        if zc is None:
            holes.append(f"{n} ({u:.1f}, {v:.1f})")
            continue
        pc = np.array([(u - camera["cx"]) * zc / camera["f"], (v - camera["cy"]) * zc / camera["f"], zc])
        out[n] = scan_to_camera(pc[None])[0]
    if holes:
        raise InputError(f"{len(holes)} landmark(s) fall on holes of {scan_source} (no surface within {radius} px): "
                         f"{list_names(holes)}; move them onto the surface or give them as scan points")
    return out


def _depth_at(depth, u, v, radius):
    """Depth at a sub-pixel position: bilinear between the 4 pixel centres around it when all are
    on the surface, else the valid pixel nearest to it within ``radius`` (None: a hole)."""
    h, w = depth.shape
    j0, i0 = int(np.floor(u)), int(np.floor(v))
    if 0 <= i0 < h - 1 and 0 <= j0 < w - 1:
        q = depth[i0:i0 + 2, j0:j0 + 2]
        if np.isfinite(q).all():
            a, b = u - j0, v - i0
            return float(q[0, 0] * (1 - a) * (1 - b) + q[0, 1] * a * (1 - b) + q[1, 0] * (1 - a) * b + q[1, 1] * a * b)
    best = None
    for i in range(max(0, int(round(v)) - radius), min(h, int(round(v)) + radius + 1)):
        for j in range(max(0, int(round(u)) - radius), min(w, int(round(u)) + radius + 1)):
            if np.isfinite(depth[i, j]):
                d2 = (i - v) ** 2 + (j - u) ** 2
                if best is None or d2 < best[0]:
                    best = (d2, float(depth[i, j]))
    return None if best is None else best[1]


def _layout_sidecar(path: Path) -> Path:
    return path.with_name(path.name.split(".")[0] + ".layout.json")


def register(generic, scan, output, *, landmarks=None, generic_landmarks=None, layout=None, layout_output=None,
             image=None, aam=None, iterations: int = 20, border: bool = False, field: int = 0,
             hole_rings: int = 1) -> dict:
    """Warp the generic face onto a scan (similarity, thin-plate RBF, closest-point projection).

    Parameters
    ----------
    generic : path
        Generic mesh layer with regions (from ``import-mesh``).
    scan : path
        Scan mesh layer (from ``stereo``, or any mesh layer).
    output : path
        Registered mesh layer to write: the generic's topology, UVs and regions, the scan's space,
        the generic's units.
    landmarks : path, optional
        Scan landmarks: ``{"name": {"image": [u, v]}}`` (on the first image of the stereo pair,
        lifted through the scan) or ``{"name": {"scan": [x, y, z]}}``, or a ``detect`` features file.
    generic_landmarks : path, optional
        The generic's landmarks, a marker layout (default: ``<generic stem>.landmarks.layout.json``
        beside the generic).
    layout : path, optional
        The generic's marker layout, carried over to ``layout_output`` (default
        ``<output stem>.layout.json``).
    image, aam : path, optional
        Without ``landmarks``: detect the face in ``image`` and fit the AAM ``aam``.
    border : bool
        Also match the generic's outer border to the scan's border (scans cropped like the generic).
    field : int
        Iterations of the smooth-field stage (a global RBF displacement fitted to the closest-point
        constraints) between the thin-plate warp and the projection; 0 skips it.
    """
    from ..mesh.layout import Layout, LayoutMarker, read_layout, write_layout
    from ..scan.landmarks import read_landmarks
    from ..scan.register import GenericRegistration
    from ..units import scale_between
    from ..usd.layers import check_output_path, provenance
    from ..usd.mesh_layer import read_mesh_layer, write_mesh_layer

    t0 = time.perf_counter()
    inputs = {"--generic": generic, "--scan": scan, "--landmarks": landmarks,
              "--generic-landmarks": generic_landmarks, "--layout": layout, "--image": image, "--aam": aam}
    out = check_output_path(output, inputs=inputs)
    refuse_overwriting_inputs({"--layout-output": layout_output}, inputs)
    gpath = Path(generic)
    mesh, regions = read_mesh_layer(generic)
    if not regions:
        raise MeshError(f"register: generic mesh {generic} has no regions; registration needs its eye and mouth hole "
                        "regions and carries its regions over (make the layer with `usdface import-mesh`)")
    if generic_landmarks is None:
        cand = gpath.with_name(gpath.name.split(".")[0] + ".landmarks.layout.json")
        if not cand.is_file():
            raise OptionError(f"register: give the generic's landmarks with --generic-landmarks G.layout.json "
                              f"(no {cand.name} beside {generic})")
        generic_landmarks = cand
    glay = read_layout(generic_landmarks)
    lay_in = read_layout(layout) if layout is not None else None
    lay_out = Path(layout_output) if layout_output else (_layout_sidecar(out) if lay_in is not None else None)
    if lay_out is not None and lay_in is None:
        raise OptionError("--layout-output needs --layout (the generic's marker layout)")
    smesh, _ = read_mesh_layer(scan)
    cam = scan_camera(scan)
    if landmarks is not None:
        lm = read_landmarks(landmarks)
    elif image is not None and aam is not None:
        from ..io.images import read_image
        from ..scan.aam import load_aam
        from ..scan.detect import detect_faces
        from ..scan.landmarks import Landmarks

        model = load_aam(aam)
        img = read_image(image)
        faces = detect_faces(img, features=False)
        if not faces:
            raise ComputeError(f"register: no face found in {image}; give --landmarks")
        fit = model.fit(img, faces[0].box)
        lm = Landmarks.from_image_points(model.names, fit.points, source=f"AAM fit on {image}")
    else:
        raise OptionError("register: give the scan's landmarks with --landmarks L.json (image points on the first "
                          "stereo image, e.g. from `usdface detect IMAGE --aam MODEL`, or scan points), or --image "
                          "and --aam to detect them")
    scan_tris = smesh.triangles()
    scan_pts = smesh.points
    points3 = {n: np.asarray(p, dtype=np.float64) for n, p in lm.scan.items()}
    img_only = {n: p for n, p in lm.image.items() if n not in points3 and n in glay.names}
    if img_only:
        if cam is None:
            raise InputError(f"register: landmarks {landmarks} has image points but {scan} records no camera (it was "
                             "not made by `usdface stereo`); give scan points {\"name\": {\"scan\": [x, y, z]}}")
        points3.update(lift_image_landmarks(img_only, scan_pts, scan_tris, cam, scan_source=str(scan)))
    names = [n for n in glay.names if n in points3]
    unknown = [n for n in list(lm.image) + list(lm.scan) if n not in glay.names]
    if len(names) < 4:
        raise InputError(f"register: only {len(names)} landmark(s) shared by the scan landmarks and the generic's "
                         f"({list_names(glay.names)}); at least 4 are needed (20 recommended)")
    if unknown:
        log.warning("register: landmarks not on the generic, ignored: %s", list_names(sorted(set(unknown))))
    # scan -> generic units
    factor = 1.0
    if smesh.units and mesh.units and smesh.units != mesh.units:
        factor = scale_between(smesh.units, mesh.units)
    S = scan_pts * factor
    SL = np.array([points3[n] for n in names]) * factor
    # scan landmarks must sit on the scan (3-D ones may be typed in or come from elsewhere)
    from ..mesh.closest import SurfaceLocator

    loc = SurfaceLocator(S, scan_tris)
    _, _, _, dl = loc.closest(SL)
    diag = float(np.linalg.norm(np.ptp(S, axis=0)))
    far = [f"{n} ({d / factor:.2f} {smesh.units or 'units'})" for n, d in zip(names, dl) if d > 0.03 * diag]
    if far:
        raise InputError(f"register: scan landmark(s) away from the scan surface (a hole, or the wrong units?): "
                         f"{list_names(far)}")
    GL = glay.positions(mesh, names)
    reg = GenericRegistration(mesh, regions, GL, hole_rings=hole_rings)
    from ..scan.register import RegistrationParameters

    res = reg.register(S, scan_tris, SL, RegistrationParameters(iterations=iterations,
                                                                border_weight=1.0 if border else 0.0,
                                                                field_iterations=field), locator=loc)
    registered = mesh.with_points(res.points)
    prov = provenance("register", options={"iterations": iterations, "border": border, "field": field,
                                           "holeRings": hole_rings,
                                           "landmarks": names},
                      inputs={"generic": generic, "scan": scan, "landmarks": landmarks,
                              "genericLandmarks": generic_landmarks, "layout": layout})
    new_layout = None
    if lay_in is not None:
        from ..scan.synthetic import evaluate_locations, surface_locations

        entries = []
        pnames = [m.name for m in lay_in.markers if m.point is not None]
        if pnames:
            pos = lay_in.positions(mesh, pnames)
            tri, bary = surface_locations(mesh.points, mesh.triangles(), pos)
            moved = evaluate_locations(res.points, mesh.triangles(), tri, bary)
            moved_by = dict(zip(pnames, moved))
        for m in lay_in.markers:
            if m.vertex is not None:
                entries.append(LayoutMarker(m.name, vertex=m.vertex))
            else:
                entries.append(LayoutMarker(m.name, point=tuple(float(x) for x in moved_by[m.name])))
        new_layout = Layout(tuple(entries), units=mesh.units)
    write_mesh_layer(out, registered, regions, prov=prov)
    if new_layout is not None:
        try:
            write_layout(lay_out, new_layout, decimals=5)
        except BaseException:
            out.unlink(missing_ok=True)
            raise
    sd = res.surface_distance[np.isfinite(res.surface_distance)]
    u = mesh.units or "units"
    summary = {"output": str(out), "generic": str(generic), "scan": str(scan), "landmarks": names,
               "points": mesh.n_points, "units": mesh.units, "scale": float(res.similarity[0]),
               "landmarkResidualMean": float(res.landmark_residuals.mean()),
               "landmarkResidualMax": float(res.landmark_residuals.max()),
               "surfaceDistanceMedian": float(np.median(sd)) if sd.size else None,
               "surfaceDistanceP95": float(np.percentile(sd, 95)) if sd.size else None,
               "dataVertices": int(res.data_vertices.sum()), "regions": [r.name for r in regions],
               "layout": str(lay_out) if new_layout is not None else None,
               "seconds": round(time.perf_counter() - t0, 3)}
    summary["_text"] = [
        f"wrote {out}: {mesh.n_points} generic vertices registered onto {scan} from {len(names)} landmarks "
        f"(scale {res.similarity[0]:.3f}, {iterations} closest-point iterations), regions "
        f"{', '.join(r.name for r in regions)} carried over",
        f"  landmark residual mean {summary['landmarkResidualMean']:.3f} {u}, max {summary['landmarkResidualMax']:.3f} {u}; "
        + (f"distance to the scan median {summary['surfaceDistanceMedian']:.3f} {u}, 95% {summary['surfaceDistanceP95']:.3f} {u}"
           if sd.size else "no closest-point pairs"),
    ]
    if new_layout is not None:
        summary["_text"].append(f"wrote {lay_out}: marker layout ({new_layout.n_markers} markers) on the registered mesh")
    return summary


# ================================================================================================
# CLI
# ================================================================================================
def register_cli(subparsers) -> None:
    """Add ``stereo``, ``detect``, ``landmarks train`` and ``register`` to the ``usdface`` command."""
    from ..cliargs import add_common_options

    p = subparsers.add_parser(
        "stereo", help="stereo pair -> disparity map and metric scan mesh layer",
        description="Match a stereo pair (rectified, or calibrated and rectified here) into a disparity map and, with "
                    "--calib, a metric scan mesh layer. Calibration JSON: {\"f\", \"cx\", \"cy\", \"baseline\", "
                    "\"doffs\", \"vertical\", \"units\"} for a rectified pair or K1, D1, K2, D2, R, T.")
    p.add_argument("left", help="left (or top) image")
    p.add_argument("right", help="right (or bottom) image")
    p.add_argument("--calib", help="calibration JSON (needed for -o)")
    p.add_argument("--method", choices=["sgbm", "sgbm-wls", "graphcut"], default="sgbm",
                   help="sgbm: semi-global matching with consistency checks (fast, default); sgbm-wls: with the WLS "
                        "edge-aware filter; graphcut: KZ1-style alpha-expansion (best, about 100x slower)")
    p.add_argument("-o", "--output", help="scan mesh layer to write (.usdc)")
    p.add_argument("--disparity", help="disparity map to write (.exr, .tif, .pfm, .npy)")
    p.add_argument("--fill", choices=["background", "none"], default="background",
                   help="pixels of the disparity map that the checks reject: the background disparity of their row "
                        "(default) or NaN; the scan uses accepted pixels only")
    p.add_argument("--ground-truth", metavar="GT", help="ground-truth disparity (.npz .pfm .exr .npy .tif; inf/NaN where "
                   "unknown): print the bad-pixel rate of the map (missing pixels count as bad)")
    p.add_argument("--bad-threshold", type=float, default=2.0, metavar="PX",
                   help="--ground-truth: a pixel is bad when |d - gt| exceeds this (default 2 px)")
    p.add_argument("--min-disparity", type=int, help="smallest disparity searched (px)")
    p.add_argument("--num-disparities", type=int, help="number of disparities searched (default 64)")
    p.add_argument("--depth-range", type=float, nargs=2, metavar=("NEAR", "FAR"),
                   help="depth range in calibration units; sets the disparity range")
    p.add_argument("--vertical", action="store_true", default=None,
                   help="vertical rig (second camera below the first) when there is no calibration")
    p.add_argument("--surface", choices=["grid", "poisson", "ball-pivoting"], default="grid")
    p.add_argument("--step", type=int, default=2, help="pixel subsampling of the scan mesh (default 2)")
    p.add_argument("--max-cycles", type=int, default=3, help="graph cut: expansion cycles (default 3)")
    p.add_argument("--time-limit", type=float, help="graph cut: seconds after which no new expansion starts")
    add_common_options(p)
    p.set_defaults(func=lambda a: stereo(a.left, a.right, a.output, calib=a.calib, method=a.method,
                                         disparity=a.disparity, min_disparity=a.min_disparity,
                                         num_disparities=a.num_disparities, depth_range=a.depth_range,
                                         vertical=a.vertical, surface=a.surface, step=a.step,
                                         max_cycles=a.max_cycles, time_limit=a.time_limit, fill=a.fill,
                                         ground_truth=a.ground_truth, bad_threshold=a.bad_threshold))

    p = subparsers.add_parser(
        "detect", help="Haar face/eye/mouth detection and AAM landmarks -> features JSON",
        description="Find faces (OpenCV Haar cascades: frontal face, eyes; the smile cascade for the mouth, since "
                    "OpenCV ships no mouth cascade) and, with --aam, fit the facial landmarks of the largest face.")
    p.add_argument("image")
    p.add_argument("-o", "--output", required=True, help="features JSON to write")
    p.add_argument("--aam", help="AAM model (.npz, from `usdface landmarks train`)")
    p.add_argument("--preview", help="PNG with the detections drawn")
    p.add_argument("--min-size", type=int, help="smallest face side in pixels")
    add_common_options(p)
    p.set_defaults(func=lambda a: detect(a.image, a.output, preview=a.preview, aam=a.aam, min_size=a.min_size))

    p = subparsers.add_parser("landmarks", help="facial landmark models (train an active appearance model)",
                              description="Facial landmark tools.")
    lsub = p.add_subparsers(dest="landmarks_command", metavar="ACTION", required=True)
    t = lsub.add_parser(
        "train", help="train an AAM from annotated images",
        description="Train an active appearance model. Each IMAGE needs a point file beside it (STEM.pts, "
                    "STEM.landmarks.json or STEM.json), or give one IMAGE with --landmarks L.json (about 20 "
                    "hand-placed points; the image is augmented).")
    t.add_argument("images", nargs="+", metavar="IMAGE")
    t.add_argument("-o", "--output", required=True, help="model to write (.npz)")
    t.add_argument("--landmarks", help="landmarks JSON of a single IMAGE")
    t.add_argument("--points-dir", help="folder of the point files (default: beside each image)")
    t.add_argument("--augment", type=int, help="jittered copies per image (default 40 with --landmarks, else 0)")
    add_common_options(t)
    t.set_defaults(func=lambda a: landmarks_train(a.images, a.output, landmarks=a.landmarks, points_dir=a.points_dir,
                                                  augment=a.augment))

    p = subparsers.add_parser(
        "register", help="warp the generic face onto a scan (RBF + closest points), keeping its topology",
        description="Register a generic face mesh layer onto a scan: similarity and thin-plate RBF warp from "
                    "landmark correspondences, then iterated closest-point projection with normal compatibility "
                    "and a smoothness term, eye and mouth holes excluded. Regions and the marker layout carry over.")
    p.add_argument("--generic", required=True, help="generic mesh layer with regions")
    p.add_argument("--scan", required=True, help="scan mesh layer (from `usdface stereo`)")
    p.add_argument("--landmarks", help="scan landmarks JSON (image or scan points) or a detect features file")
    p.add_argument("--generic-landmarks", help="the generic's landmarks (marker layout; default "
                                               "GENERIC_STEM.landmarks.layout.json beside the generic)")
    p.add_argument("--layout", help="the generic's marker layout, carried over")
    p.add_argument("--layout-output", help="where the carried layout goes (default OUTPUT_STEM.layout.json)")
    p.add_argument("--image", help="without --landmarks: the first stereo image to detect the landmarks on")
    p.add_argument("--aam", help="without --landmarks: AAM model for --image")
    p.add_argument("--iterations", type=int, default=20, help="closest-point iterations (default 20)")
    p.add_argument("--border", action="store_true", help="also match the generic's outer border to the scan's "
                                                         "(for scans cropped like the generic)")
    p.add_argument("--field", type=int, default=0, metavar="N",
                   help="iterations of the smooth-field stage before the projection (default 0; 8 with --border "
                        "for scans cropped like the generic)")
    p.add_argument("-o", "--output", required=True, help="registered mesh layer to write (.usdc)")
    add_common_options(p)
    p.set_defaults(func=lambda a: register(a.generic, a.scan, a.output, landmarks=a.landmarks,
                                           generic_landmarks=a.generic_landmarks, layout=a.layout,
                                           layout_output=a.layout_output, image=a.image, aam=a.aam,
                                           iterations=a.iterations, border=a.border, field=a.field))
