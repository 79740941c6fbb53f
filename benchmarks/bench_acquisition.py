"""Face acquisition benchmark (seed 001, sections 2-4): stereo, detection, AAM, registration.

Run by hand (not in CI):

    python benchmarks/bench_acquisition.py [--quick] [--json OUT.json]

Everything is measured in one run so the ratios compare like with like:

1. Middlebury motorcycle (741x500, ground truth +inf where unknown): bad-pixel rate
   (|d - gt| > 2 px over the finite ground truth; pixels a method leaves empty count as bad)
   of OpenCV's StereoSGBM (16 and 64 disparities, block 5, its other defaults: the baseline) and
   of `usdface stereo` as the command runs it (its Python API function, ``--ground-truth``): its
   default, ``--fill none``, ``--method sgbm-wls`` and ``--method graphcut`` (3 cycles); graph-cut
   time against the 60 s target.
2. Rendered face stereo (the stylized MakeHuman face with the photo and skin texture, exact
   depth): depth error median and 95th percentile in mm, and SGBM + WLS time on a 1280x960 pair
   against plain SGBM on the same pair and range (target <= 1 s).
3. Haar detection on the face photo; the AAM trained on rendered faces, fitted on held-out renders
   (same face, unseen pose/light/expression; and the stylized face: unseen geometry) and on the
   photo itself (against the hand-placed landmarks); errors as a fraction of the inter-ocular
   distance.
4. Registration: the MakeHuman face onto the stylized face moved by a random similarity, from 20
   landmarks, against the best similarity alignment (all vertices, known correspondence); onto a
   rendered-stereo scan of the stylized face (image landmarks lifted through the scan).
5. Registration speed: a ~10k-vertex generic (the MakeHuman face subdivided) onto a ~200k-point
   stereo scan (target <= 10 s), against a baseline in the same run (similarity + thin-plate warp
   + nearest-scan-vertex snapping with a k-d tree: no surface, no normals, no smoothness).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
SHARED = ROOT.parent / "shared" / "data"
ASSETS = ROOT / "sample_assets"


def _t(fn, *a, repeat=1, **k):
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn(*a, **k)
        best = min(best, time.perf_counter() - t0)
    return out, best


def middlebury(results, quick):
    import cv2

    from usdface import api
    from usdface.options import StereoOptions
    from usdface.scan.stereo import bad_pixel_rate

    d = SHARED / "images" / "stereo"
    L = cv2.imread(str(d / "motorcycle_left.png"))
    R = cv2.imread(str(d / "motorcycle_right.png"))
    gt_path = d / "motorcycle_disp.npz"
    gt = np.load(gt_path)["arr_0"]
    rows = []

    def opencv_default(nd):
        m = cv2.StereoSGBM_create(minDisparity=0, numDisparities=nd, blockSize=5)
        raw = m.compute(L, R)
        out = raw.astype(np.float32) / 16
        out[raw < 0] = np.nan
        return out

    for nd in (16, 64):
        disp, t = _t(opencv_default, nd, repeat=3)
        rows.append((f"cv2.StereoSGBM, {nd} disparities, block 5", bad_pixel_rate(disp, gt), t))
    # the CLI itself: `usdface stereo LEFT RIGHT --ground-truth GT [--method M] [--fill F]`
    runs = [("usdface stereo (default: sgbm, fill background)", {}),
            ("usdface stereo --fill none", {"fill": "none"}),
            ("usdface stereo --method sgbm-wls", {"method": "sgbm-wls"}),
            ("usdface stereo --method graphcut", {"method": "graphcut", "max_cycles": 1 if quick else 3,
                                                  "time_limit": 55.0})]
    for label, kw in runs:
        options = StereoOptions(ground_truth=str(gt_path), **kw)
        s, t = _t(api.stereo, d / "motorcycle_left.png", d / "motorcycle_right.png", options)
        g = s.summary["groundTruth"]
        kept = {k: g[k] for k in ("bad", "bad_known", "density", "pixels")}
        rows.append((label, kept, s.summary["disparitySeconds"]))
    print("\n== Middlebury motorcycle 741x500: bad-pixel rate (|d - gt| > 2 px, missing counted bad) ==")
    print(f"{'method':52s} {'bad (all gt px)':>15s} {'bad (given px)':>15s} {'density':>8s} {'time s':>8s}")
    for label, r, t in rows:
        print(f"{label:52s} {100 * r['bad']:14.1f}% {100 * r['bad_known']:14.1f}% {100 * r['density']:7.1f}% {t:8.2f}")
    plain = rows[1][1]["bad"]
    print(f"usdface stereo default / plain cv2.StereoSGBM (64, block 5) bad-pixel ratio: {rows[2][1]['bad'] / plain:.2f}; "
          f"graph cut: {rows[5][1]['bad'] / plain:.2f} in {rows[5][2]:.1f} s (target <= 60 s)")
    results["middlebury"] = [{"method": l, **r, "seconds": t} for l, r, t in rows]


def face_stereo(results, quick):
    import cv2

    from usdface.scan.calibration import calibration_from_dict
    from usdface.scan.graphcut import GraphCutParameters
    from usdface.scan.stereo import MatchingParameters, compute_disparity, disparity_range
    from usdface.scan.synthetic import render_stereo_pair, sample_face

    _, _, _, scene = sample_face(ASSETS, "stylized", photo=SHARED / "images" / "astronaut.png")
    print("\n== Rendered face stereo (stylized MakeHuman face, photo + skin texture, exact depth) ==")
    out = {}
    for size, methods in (((640, 480), ("sgbm", "sgbm-wls", "graphcut")), ((1280, 960), ("sgbm", "sgbm-wls"))):
        for vertical in (False, True):
            sz = size if not vertical else (size[1], size[0])
            pair = render_stereo_pair(scene, size=sz, vertical=vertical)
            cal = calibration_from_dict(pair["calibration"])
            lo, n = disparity_range(cal, 500, 700)
            face = np.isfinite(pair["depth"])
            for m in methods:
                if quick and m == "graphcut":
                    continue
                params = MatchingParameters(method=m, min_disparity=lo, num_disparities=n, vertical=vertical,
                                            graphcut=GraphCutParameters(max_cycles=3))
                res, t = _t(compute_disparity, pair["first"], pair["second"], params,
                            repeat=1 if m == "graphcut" else 3)
                z = cal.depth(np.where(res.valid, res.disparity, np.nan))
                ok = face & np.isfinite(z)
                err = np.abs(z - pair["depth"])[ok]
                key = f"{m} {sz[0]}x{sz[1]}{' vertical' if vertical else ''}"
                out[key] = {"median_mm": float(np.median(err)), "p95_mm": float(np.percentile(err, 95)),
                            "coverage": float(ok.sum() / face.sum()), "seconds": t, "disparities": [lo, lo + n - 1]}
                print(f"{key:28s} depth error median {np.median(err):.2f} mm, 95% {np.percentile(err, 95):.2f} mm, "
                      f"face pixels with depth {100 * ok.sum() / face.sum():.1f}%, {t:.2f} s "
                      f"(disparities {lo}..{lo + n - 1})")
            if sz == (1280, 960):
                a, b = pair["first"], pair["second"]

                def plain():
                    bs = 5
                    mm = cv2.StereoSGBM_create(minDisparity=lo, numDisparities=n, blockSize=bs, P1=8 * 3 * bs * bs,
                                               P2=32 * 3 * bs * bs, mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
                    return mm.compute(a, b)

                _, tp = _t(plain, repeat=3)
                tw = out["sgbm 1280x960"]["seconds"]
                print(f"usdface sgbm 1280x960 (3-way mode, {n} disparities {lo}..{lo + n - 1}, with its checks): "
                      f"{tw:.3f} s vs plain SGBM {tp:.3f} s (ratio {tw / tp:.1f}); target <= 1 s")
                out["sgbm_1280_vs_plain"] = {"sgbm_s": tw, "plain_s": tp}
    results["face_stereo"] = out


def detection_and_aam(results, quick):
    import cv2

    from usdface.scan.aam import train_aam
    from usdface.scan.detect import detect_faces, largest_face_box
    from usdface.scan.landmarks import FACE_LANDMARKS, interocular_distance, read_landmarks
    from usdface.scan.synthetic import render_annotated_faces, sample_face

    photo_path = SHARED / "images" / "astronaut.png"
    photo = cv2.imread(str(photo_path))
    faces, t = _t(detect_faces, photo, repeat=3)
    print("\n== Haar detection on the photo ==")
    for f in faces:
        print(f"face box {list(f.box)} (expected about [177, 66, 95, 95]); eyes {f.eyes}; mouth (smile cascade) "
              f"{f.mouth}; {t * 1000:.0f} ms")
    results["haar"] = {"faces": [list(f.box) for f in faces], "eyes": [f.eyes for f in faces],
                       "mouth": [f.mouth for f in faces], "seconds": t}
    units = np.load(ASSETS / "meshes" / "makehuman_hm08_face_units_cm.npz")
    keep = [i for i, n in enumerate(units["names"]) if not str(n).startswith("eyeLook") and str(n) != "tongueOut"]
    deltas = units["deltas"][keep]
    _, _, _, neutral = sample_face(ASSETS, "neutral", photo=photo_path)
    _, _, _, styl = sample_face(ASSETS, "stylized", photo=photo_path)
    n_train = 40 if quick else 120
    imgs, marks = render_annotated_faces(neutral, n_train, size=(200, 200), seed=1, deltas=deltas)
    model, t_train = _t(train_aam, imgs, marks, names=FACE_LANDMARKS, detector=largest_face_box)
    print(f"\n== AAM: trained on {n_train} rendered faces in {t_train:.1f} s ({model.n_shape_modes} shape modes, "
          f"appearance modes {model.meta['appearance_modes']}) ==")
    out = {}
    for label, scene, seed in (("held-out renders, same face", neutral, 501), ("renders of the stylized face", styl, 502)):
        ti, tm = render_annotated_faces(scene, 15 if quick else 40, size=(200, 200), seed=seed, deltas=deltas)
        e0, e1, missed, times = [], [], 0, []
        for img, lm in zip(ti, tm):
            box = largest_face_box(img)
            if box is None:
                missed += 1
                continue
            fit, tf = _t(model.fit, img, box)
            times.append(tf)
            iod = interocular_distance(lm)
            e0.append(np.linalg.norm(fit.initial - lm, axis=1).mean() / iod)
            e1.append(np.linalg.norm(fit.points - lm, axis=1).mean() / iod)
        e0, e1 = np.array(e0), np.array(e1)
        print(f"{label:32s}: mean point error / IOD  start (Haar box) median {100 * np.median(e0):.1f}%, "
              f"fitted median {100 * np.median(e1):.1f}%, 90th pct {100 * np.percentile(e1, 90):.1f}%, "
              f"faces missed by Haar {missed}/{len(ti)}, {1000 * np.mean(times):.0f} ms per fit")
        out[label] = {"start_median": float(np.median(e0)), "fit_median": float(np.median(e1)),
                      "fit_p90": float(np.percentile(e1, 90)), "missed": missed, "n": len(ti)}
    hand = read_landmarks(ASSETS / "landmarks" / "astronaut.landmarks.json").image_array(FACE_LANDMARKS)
    fit = model.fit(photo, faces[0].box)
    iod = interocular_distance(hand)
    e_photo = np.linalg.norm(fit.points - hand, axis=1).mean() / iod
    e_start = np.linalg.norm(fit.initial - hand, axis=1).mean() / iod
    print(f"{'the real photo (hand landmarks)':32s}: start {100 * e_start:.1f}%, fitted {100 * e_photo:.1f}% of the IOD "
          f"({iod:.1f} px)")
    out["photo"] = {"start": float(e_start), "fit": float(e_photo)}
    results["aam"] = out
    from usdface.scan.detect import draw_detections

    prev = draw_detections(photo, faces, fit.points)
    cv2.imwrite(str(Path(os.environ.get("TMPDIR", "/tmp")) / "bench_acquisition_photo.png"), prev)


def _subdivide(mesh, n: int = 2):
    """Split every quad into n x n quads (bilinear; the surface outline and holes are kept)."""
    from usdface.model.mesh import FaceMesh

    assert (mesh.face_vertex_counts == 4).all()
    q = mesh.face_vertex_indices.reshape(-1, 4)
    P = mesh.points[q]  # (F, 4, 3): a, b, c, d counter-clockwise
    t = np.linspace(0.0, 1.0, n + 1)
    u, v = np.meshgrid(t, t, indexing="xy")  # u along a->b, v along a->d
    w = np.stack([(1 - u) * (1 - v), u * (1 - v), u * v, (1 - u) * v], axis=-1)  # (n+1, n+1, 4)
    grid = np.einsum("ijk,fkd->fijd", w, P)  # (F, n+1, n+1, 3)
    # corner and edge points are shared by neighbours: merge equal positions
    flat = grid.reshape(-1, 3)
    key = np.round(flat / (np.abs(flat).max() * 1e-9)).astype(np.int64)
    uniq, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    # keep the original vertices first, in their order
    ids = inv.reshape(len(q), n + 1, n + 1)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    ids = rank[ids]
    pts = flat[first[order]]
    a = ids[:, :-1, :-1]
    b = ids[:, :-1, 1:]
    c = ids[:, 1:, 1:]
    d = ids[:, 1:, :-1]
    quads = np.stack([a, b, c, d], axis=-1).reshape(-1, 4)
    return FaceMesh(points=pts, face_vertex_counts=np.full(len(quads), 4), face_vertex_indices=quads.ravel(),
                    units=mesh.units, name=mesh.name)


def registration(results, quick):
    from usdface.io.meshes import read_mesh
    from usdface.mesh.layout import read_layout
    from usdface.mesh.topology import find_hole_regions
    from usdface.scan.calibration import calibration_from_dict
    from usdface.scan.landmarks import FACE_LANDMARKS
    from usdface.scan.graphcut import GraphCutParameters
    from usdface.scan.image_landmarks import lift_image_landmarks
    from usdface.scan.register import GenericRegistration, RegistrationParameters, apply_similarity, similarity_fit
    from usdface.scan.stereo import MatchingParameters, compute_disparity, disparity_range
    from usdface.scan.surface import camera_to_scan, reconstruct_surface
    from usdface.scan.synthetic import render_stereo_pair, rotation_matrix, sample_face

    g = read_mesh(ASSETS / "meshes" / "makehuman_hm08_face_cm.obj")
    regions = find_hole_regions(g)
    glm = read_layout(ASSETS / "landmarks" / "makehuman_hm08_face.landmarks.layout.json").positions(g, FACE_LANDMARKS)
    st = read_mesh(ASSETS / "meshes" / "makehuman_hm08_face_stylized_cm.obj")
    reg = GenericRegistration(g, regions, glm)
    print("\n== Registration: MakeHuman face -> stylized face moved by a random similarity, 20 landmarks ==")
    rows = {}
    seeds = range(3) if quick else range(5)
    variants = {"default (similarity + TPS + projection)": {},
                "+ border matching (cropped scans)": {"border_weight": 1.0},
                "+ border + smooth field stage": {"border_weight": 1.0, "field_iterations": 8}}
    for seed in seeds:
        rng = np.random.default_rng(seed)
        s, R, t = rng.uniform(0.5, 2.0), rotation_matrix(*rng.uniform(-30, 30, 3)), rng.uniform(-40, 40, 3)
        truth = apply_similarity(st.points, s, R, t)
        slm = reg.landmark_positions(truth)
        s2, R2, t2 = similarity_fit(g.points, truth)
        e_best = np.linalg.norm(apply_similarity(g.points, s2, R2, t2) - truth, axis=1).mean()
        height = np.ptp(st.points[:, 1]) * s
        for name, kw in variants.items():
            res, tt = _t(reg.register, truth, st.triangles(), slm, RegistrationParameters(**kw))
            e = np.linalg.norm(res.points - truth, axis=1).mean()
            e_lm = np.linalg.norm(res.similarity_points - truth, axis=1).mean()
            e_rbf = np.linalg.norm(res.rbf_points - truth, axis=1).mean()
            rows.setdefault(name, []).append((e / e_best, e_lm / e_best, e_rbf / e_best, e / height, tt))
    print(f"{'variant':44s} {'final/best-sim':>14s} {'lm-sim/best':>12s} {'TPS/best':>9s} {'% height':>9s} {'s':>6s}")
    for name, r in rows.items():
        r = np.array(r)
        print(f"{name:44s} {r[:, 0].mean():14.3f} {r[:, 1].mean():12.3f} {r[:, 2].mean():9.3f} "
              f"{100 * r[:, 3].mean():8.2f}% {r[:, 4].mean():6.2f}")
    results["registration_mesh"] = {k: np.array(v).mean(axis=0).tolist() for k, v in rows.items()}

    # onto a rendered-stereo scan
    mesh, _, lm, scene = sample_face(ASSETS, "stylized", photo=SHARED / "images" / "astronaut.png")
    out = {}
    for method in ("sgbm", "graphcut"):
        pair = render_stereo_pair(scene, size=(640, 480))
        cal = calibration_from_dict(pair["calibration"])
        lo, n = disparity_range(cal, 500, 700)
        res = compute_disparity(pair["first"], pair["second"],
                                MatchingParameters(method=method, min_disparity=lo, num_disparities=n,
                                                   graphcut=GraphCutParameters(max_cycles=2)))
        z = cal.depth(np.where(res.valid, res.disparity, np.nan))
        surf = reconstruct_surface(cal.points(z), np.isfinite(z), step=2)
        cam = pair["camera"]
        uv, _ = cam.project(scene.landmarks())
        camd = {"f": cal.f, "cx": cal.cx, "cy": cal.cy, "width": 640, "height": 480}
        lifted = lift_image_landmarks(dict(zip(FACE_LANDMARKS, uv)), surf.points, surf.triangles, camd)
        SL = np.array([lifted[k] for k in FACE_LANDMARKS]) / 10.0
        truth = camera_to_scan(cam.to_camera(scene.points[: mesh.n_points])) / 10.0
        s2, R2, t2 = similarity_fit(g.points, truth)
        e_best = np.linalg.norm(apply_similarity(g.points, s2, R2, t2) - truth, axis=1).mean()
        r = reg.register(surf.points / 10.0, surf.triangles, SL)
        e = np.linalg.norm(r.points - truth, axis=1).mean()
        e_rbf = np.linalg.norm(r.rbf_points - truth, axis=1).mean()
        out[method] = {"final_cm": float(e), "best_similarity_cm": float(e_best), "rbf_cm": float(e_rbf),
                       "scan_points": int(surf.n_points)}
        print(f"stereo scan ({method}, 640x480, {surf.n_points} points), image landmarks lifted through the scan: "
              f"mean vertex error {10 * e:.2f} mm (TPS stage {10 * e_rbf:.2f} mm; best similarity {10 * e_best:.2f} mm; "
              f"ratio {e / e_best:.2f})")
    results["registration_stereo"] = out

    # speed: ~10k generic onto a ~200k-point scan
    size = (1100, 825)
    pair = render_stereo_pair(scene, size=size)
    cal = calibration_from_dict(pair["calibration"])
    lo, n = disparity_range(cal, 500, 700)
    res = compute_disparity(pair["first"], pair["second"], MatchingParameters(min_disparity=lo, num_disparities=n))
    z = cal.depth(np.where(res.valid, res.disparity, np.nan))
    surf = reconstruct_surface(cal.points(z), np.isfinite(z), step=1)
    S, F = surf.points / 10.0, surf.triangles
    truth_lm = camera_to_scan(cam_to(pair["camera"], scene.landmarks())) / 10.0
    speed = []
    for split in (2, 3):
        g10 = _subdivide(g, split)
        r10 = find_hole_regions(g10)
        t0 = time.perf_counter()
        reg10 = GenericRegistration(g10, r10, glm)
        res10 = reg10.register(S, F, truth_lm)
        t_reg = time.perf_counter() - t0

        def baseline():
            from scipy.spatial import cKDTree

            b = GenericRegistration(g10, r10, glm)
            r0 = b.register(S, F, truth_lm, RegistrationParameters(iterations=0))
            _, idx = cKDTree(S).query(r0.rbf_points)
            return S[idx]

        _, t_base = _t(baseline)
        print(f"\n== Registration speed: {g10.n_points}-vertex generic onto a {len(S)}-point scan "
              f"({len(F)} triangles) ==\nusdface register: {t_reg:.2f} s (target <= 10 s for 10k vertices; set-up + "
              f"similarity + TPS + {len(res10.info['iterations'])} projection iterations); baseline (TPS + nearest "
              f"scan vertex, k-d tree): {t_base:.2f} s; ratio {t_reg / t_base:.1f}")
        speed.append({"generic_vertices": g10.n_points, "scan_points": len(S), "seconds": t_reg,
                      "baseline_seconds": t_base})
    results["registration_speed"] = speed


def cam_to(cam, pts):
    return cam.to_camera(pts)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer cycles, samples and renders")
    ap.add_argument("--json", help="write the numbers as JSON")
    ap.add_argument("--only", choices=["middlebury", "face", "aam", "register"], nargs="*")
    args = ap.parse_args(argv)
    import cv2

    print(f"usdface acquisition benchmark - {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"OpenCV {cv2.__version__}, numpy {np.__version__}")
    results = {}
    parts = {"middlebury": middlebury, "face": face_stereo, "aam": detection_and_aam, "register": registration}
    for name, fn in parts.items():
        if args.only and name not in args.only:
            continue
        fn(results, args.quick)
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1, default=str))


if __name__ == "__main__":
    main()
