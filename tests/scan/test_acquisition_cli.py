"""The stereo, detect, landmarks train and register commands, end to end and on bad input."""
import json

import numpy as np
import pytest

from usdface import cli


def run(*args):
    return cli.main([str(a) for a in args])


@pytest.fixture(scope="module")
def scene_files(tmp_path_factory, sample_assets, shared_data):
    import cv2

    from usdface.scan.landmarks import FACE_LANDMARKS, Landmarks, write_landmarks
    from usdface.scan.synthetic import render_stereo_pair, sample_face

    d = tmp_path_factory.mktemp("acq")
    mesh, _, _, scene = sample_face(sample_assets, "stylized", photo=shared_data / "images" / "astronaut.png")
    pair = render_stereo_pair(scene, size=(400, 300))
    cv2.imwrite(str(d / "L.png"), pair["first"])
    cv2.imwrite(str(d / "R.png"), pair["second"])
    (d / "calib.json").write_text(json.dumps(pair["calibration"]))
    uv, _ = pair["camera"].project(scene.landmarks())
    write_landmarks(d / "lm.json", Landmarks.from_image_points(FACE_LANDMARKS, uv))
    assert run("import-mesh", sample_assets / "meshes" / "makehuman_hm08_face_cm.obj", "-o", d / "generic.usdc") == 0
    from usdface.scan.surface import camera_to_scan

    truth = camera_to_scan(pair["camera"].to_camera(scene.points[: mesh.n_points])) / 10.0  # cm
    return d, truth, pair


def test_stereo_then_register(scene_files, sample_assets, capsys):
    from usdface.io.images import read_float_map
    from usdface.mesh.layout import read_layout
    from usdface.scan.register import apply_similarity, similarity_fit
    from usdface.usd.mesh_layer import read_mesh_layer

    d, truth, pair = scene_files
    assert run("stereo", d / "L.png", d / "R.png", "--calib", d / "calib.json", "--method", "graphcut",
               "--max-cycles", "2", "--depth-range", 500, 700, "-o", d / "scan.usdc", "--disparity",
               d / "disp.pfm") == 0
    scan, regions = read_mesh_layer(d / "scan.usdc")
    assert scan.units == "mm" and scan.n_points > 5000 and regions == []
    disp = read_float_map(d / "disp.pfm")
    assert disp.shape == (300, 400) and np.isfinite(disp).mean() > 0.2
    lay = sample_assets / "layouts" / "makehuman_hm08_face.layout.json"
    assert run("register", "--generic", d / "generic.usdc", "--scan", d / "scan.usdc", "--landmarks", d / "lm.json",
               "--generic-landmarks", sample_assets / "landmarks" / "makehuman_hm08_face.landmarks.layout.json",
               "--layout", lay, "-o", d / "registered.usdc") == 0
    reg, reg_regions = read_mesh_layer(d / "registered.usdc")
    generic, g_regions = read_mesh_layer(d / "generic.usdc")
    assert reg.units == "cm" and np.array_equal(reg.face_vertex_indices, generic.face_vertex_indices)
    assert [r.name for r in reg_regions] == [r.name for r in g_regions]
    err = np.linalg.norm(reg.points - truth, axis=1).mean()
    s, R, t = similarity_fit(generic.points, truth)
    e_sim = np.linalg.norm(apply_similarity(generic.points, s, R, t) - truth, axis=1).mean()
    assert err < e_sim  # better than the best similarity, through a real stereo scan
    carried = read_layout(d / "registered.layout.json")
    assert carried.names == read_layout(lay).names
    # both are mesh layers: each records its own mesh, as read back (issue 20: layers know what
    # they belong to), and `check` finds them consistent
    from usdface import api
    from usdface.usd.identity import mesh_record
    from usdface.usd.layers import layer_provenance

    for name, mesh in (("scan.usdc", scan), ("registered.usdc", reg)):
        assert layer_provenance(d / name)["identity"] == {"version": 1, "mesh": mesh_record(mesh)}
        assert not [f for f in api.check(d / name).summary["findings"] if f["rule"] == "usdface:LayerIdentity"]
    # the registered mesh and its carried layout drive the whole pipeline on a real capture
    assert run("run", "--mesh", d / "registered.usdc", "--capture", sample_assets / "capture" / "JawMoCap.ma",
               "--layout", d / "registered.layout.json", "-o", d / "shot") == 0
    assert (d / "shot" / "shot.usda").is_file()


def test_detect_and_train(tmp_path, shared_data, sample_assets, capsys):
    photo = shared_data / "images" / "astronaut.png"
    assert run("landmarks", "train", photo, "--landmarks", sample_assets / "landmarks" / "astronaut.landmarks.json",
               "--augment", 12, "-o", tmp_path / "a.npz") == 0
    assert run("detect", photo, "--aam", tmp_path / "a.npz", "-o", tmp_path / "f.json", "--preview",
               tmp_path / "p.png", "--json") == 0
    capsys.readouterr()
    f = json.loads((tmp_path / "f.json").read_text())
    assert len(f["faces"]) == 1 and len(f["landmarks"]) == 20
    from usdface.scan.landmarks import read_landmarks

    hand = read_landmarks(sample_assets / "landmarks" / "astronaut.landmarks.json")
    fitted = read_landmarks(tmp_path / "f.json")
    err = np.mean([np.hypot(*(np.subtract(fitted.image[n], hand.image[n]))) for n in hand.image])
    assert err < 4.0  # px, the photo's inter-ocular distance is ~45 px
    assert (tmp_path / "p.png").is_file()


def _files(d):
    return sorted(p.name for p in d.iterdir())


def test_bad_inputs(tmp_path, scene_files, shared_data, sample_assets, capsys):
    import cv2

    d, _, pair = scene_files
    before = _files(tmp_path)
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), pair["second"][:200])
    assert run("stereo", d / "L.png", small, "--calib", d / "calib.json", "-o", tmp_path / "s.usdc") == 2
    assert "same size" in capsys.readouterr().err
    # unrectified pair without calibration
    M = cv2.getRotationMatrix2D((200, 150), 4.0, 1.0)
    rot = tmp_path / "rot.png"
    cv2.imwrite(str(rot), cv2.warpAffine(pair["second"], M, (400, 300)))
    assert run("stereo", d / "L.png", rot, "--disparity", tmp_path / "d.npy") == 2
    assert "not a rectified pair" in capsys.readouterr().err
    assert run("stereo", d / "L.png", d / "R.png", "-o", tmp_path / "s.usdc") == 2
    assert "needs the camera calibration" in capsys.readouterr().err
    # no face
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((200, 200, 3), 90, np.uint8))
    assert run("detect", blank, "-o", tmp_path / "f.json", "--preview", tmp_path / "p.png") == 2
    assert "no face found" in capsys.readouterr().err
    assert _files(tmp_path) == sorted(before + ["small.png", "rot.png", "blank.png"])  # nothing partial left


def test_register_bad_inputs(tmp_path, scene_files, sample_assets, capsys):
    from usdface.usd.layers import provenance
    from usdface.usd.mesh_layer import read_mesh_layer, write_mesh_layer

    d, _, pair = scene_files
    if not (d / "scan.usdc").exists():
        assert run("stereo", d / "L.png", d / "R.png", "--calib", d / "calib.json", "--depth-range", 500, 700,
                   "-o", d / "scan.usdc") == 0
    glm = sample_assets / "landmarks" / "makehuman_hm08_face.landmarks.layout.json"
    base = ["register", "--generic", d / "generic.usdc", "--scan", d / "scan.usdc", "--generic-landmarks", glm]
    lm = json.loads((d / "lm.json").read_text())
    # a landmark outside the image
    bad = dict(lm, Chin={"image": [900.0, 20.0]})
    (tmp_path / "out.json").write_text(json.dumps(bad))
    assert run(*base, "--landmarks", tmp_path / "out.json", "-o", tmp_path / "r.usdc") == 2
    assert "outside the 400x300 image" in capsys.readouterr().err
    # a landmark on a hole of the scan (the background)
    bad = dict(lm, Chin={"image": [5.0, 5.0]})
    (tmp_path / "hole.json").write_text(json.dumps(bad))
    assert run(*base, "--landmarks", tmp_path / "hole.json", "-o", tmp_path / "r.usdc") == 2
    assert "fall on holes" in capsys.readouterr().err
    # a generic mesh without regions
    g, _ = read_mesh_layer(d / "generic.usdc")
    write_mesh_layer(tmp_path / "noreg.usdc", g, [], prov=provenance("test", options={}, inputs={}))
    assert run("register", "--generic", tmp_path / "noreg.usdc", "--scan", d / "scan.usdc", "--generic-landmarks",
               glm, "--landmarks", d / "lm.json", "-o", tmp_path / "r.usdc") == 2
    assert "has no regions" in capsys.readouterr().err
    assert not (tmp_path / "r.usdc").exists()


def test_register_onto_a_mesh_scan_with_scan_landmarks(tmp_path, sample_assets, capsys):
    """The stylized face's geometry as the scan (no camera: 3-D scan landmarks), cropped like the
    generic, so --border and the smooth-field stage apply."""
    from usdface.io.meshes import read_mesh
    from usdface.mesh.layout import read_layout
    from usdface.scan.landmarks import FACE_LANDMARKS, Landmarks, write_landmarks
    from usdface.scan.register import GenericRegistration, apply_similarity, similarity_fit
    from usdface.mesh.topology import find_hole_regions
    from usdface.usd.mesh_layer import read_mesh_layer

    meshes = sample_assets / "meshes"
    glm_path = sample_assets / "landmarks" / "makehuman_hm08_face.landmarks.layout.json"
    assert run("import-mesh", meshes / "makehuman_hm08_face_cm.obj", "-o", tmp_path / "g.usdc") == 0
    assert run("import-mesh", meshes / "makehuman_hm08_face_stylized_cm.obj", "-o", tmp_path / "s.usdc") == 0
    g = read_mesh(meshes / "makehuman_hm08_face_cm.obj")
    st = read_mesh(meshes / "makehuman_hm08_face_stylized_cm.obj")
    reg = GenericRegistration(g, find_hole_regions(g), read_layout(glm_path).positions(g, FACE_LANDMARKS))
    slm = reg.landmark_positions(st.points)
    write_landmarks(tmp_path / "l.json", Landmarks(image={}, scan=dict(zip(FACE_LANDMARKS, map(tuple, slm)))))
    assert run("register", "--generic", tmp_path / "g.usdc", "--scan", tmp_path / "s.usdc", "--landmarks",
               tmp_path / "l.json", "--generic-landmarks", glm_path, "--border", "--field", 8, "-o",
               tmp_path / "r.usdc") == 0
    r, _ = read_mesh_layer(tmp_path / "r.usdc")
    s, R, t = similarity_fit(g.points, st.points)
    e_sim = np.linalg.norm(apply_similarity(g.points, s, R, t) - st.points, axis=1).mean()
    assert np.linalg.norm(r.points - st.points, axis=1).mean() <= 0.30 * e_sim
    # a scan landmark off the surface (on a hole, or wrong units) is refused
    bad = dict(zip(FACE_LANDMARKS, map(tuple, slm)))
    bad["Chin"] = (0.0, 60.0, 30.0)
    write_landmarks(tmp_path / "bad.json", Landmarks(image={}, scan=bad))
    assert run("register", "--generic", tmp_path / "g.usdc", "--scan", tmp_path / "s.usdc", "--landmarks",
               tmp_path / "bad.json", "--generic-landmarks", glm_path, "-o", tmp_path / "r2.usdc") == 2
    assert "away from the scan surface" in capsys.readouterr().err
    assert not (tmp_path / "r2.usdc").exists()
    # image landmarks need a scan made by `usdface stereo` (its camera)
    write_landmarks(tmp_path / "img.json", Landmarks.from_image_points(FACE_LANDMARKS, np.zeros((20, 2)) + 5))
    assert run("register", "--generic", tmp_path / "g.usdc", "--scan", tmp_path / "s.usdc", "--landmarks",
               tmp_path / "img.json", "--generic-landmarks", glm_path, "-o", tmp_path / "r2.usdc") == 2
    assert "records no camera" in capsys.readouterr().err


def test_unrectified_calibrated_pair(tmp_path, sample_assets, shared_data):
    """A pair whose second camera is turned by 2 degrees: rectified from K1, D1, K2, D2, R, T."""
    import cv2

    from usdface.mesh.closest import SurfaceLocator
    from usdface.scan.image_landmarks import lift_image_landmarks
    from usdface.scan.render import PinholeCamera, render_view
    from usdface.scan.surface import camera_to_scan
    from usdface.scan.synthetic import render_stereo_pair, rotation_matrix, sample_face
    from usdface.usd.mesh_layer import read_mesh_layer
    from usdface.usd.scan_inputs import scan_camera

    _, _, _, scene = sample_face(sample_assets, "stylized", photo=shared_data / "images" / "astronaut.png")
    pair = render_stereo_pair(scene, size=(400, 300))
    cam1 = pair["camera"]
    B = 60.0
    Rrel = rotation_matrix(2.0, 1.0, 0.5)
    cam2 = PinholeCamera(K=cam1.K, R=Rrel @ cam1.R, t=Rrel @ (cam1.t - [B, 0, 0]), size=cam1.size)
    second = render_view(scene.points, scene.triangles, cam2, texture=scene.texture).image
    cv2.imwrite(str(tmp_path / "L.png"), pair["first"])
    cv2.imwrite(str(tmp_path / "R.png"), second)
    calib = {"K1": cam1.K.tolist(), "D1": [0, 0, 0, 0, 0], "K2": cam1.K.tolist(), "D2": [0, 0, 0, 0, 0],
             "R": Rrel.tolist(), "T": (-Rrel @ [B, 0, 0]).tolist()}
    (tmp_path / "c.json").write_text(json.dumps(calib))
    # without the calibration the pair is refused as unrectified
    assert run("stereo", tmp_path / "L.png", tmp_path / "R.png", "--disparity", tmp_path / "d.npy") == 2
    assert run("stereo", tmp_path / "L.png", tmp_path / "R.png", "--calib", tmp_path / "c.json", "--depth-range",
               450, 750, "-o", tmp_path / "scan.usdc") == 0
    scan, _ = read_mesh_layer(tmp_path / "scan.usdc")
    # the scan is in the rectified first camera's frame: compare with the truth seen from there
    cam = scan_camera(tmp_path / "scan.usdc")
    R1 = np.array(cam["rectification"]["R1"])
    truth = camera_to_scan(cam1.to_camera(scene.points) @ R1.T)
    _, _, _, d = SurfaceLocator(truth, scene.triangles).closest(scan.points)
    assert np.median(d) < 1.5  # mm
    # image landmarks clicked on the original (unrectified) first image land on the surface
    uv, _ = cam1.project(scene.landmarks())
    from usdface.scan.landmarks import FACE_LANDMARKS

    lifted = lift_image_landmarks(dict(zip(FACE_LANDMARKS, uv)), scan.points, scan.triangles(), cam)
    true_lm = camera_to_scan(cam1.to_camera(scene.landmarks()) @ R1.T)
    err = np.linalg.norm(np.array([lifted[n] for n in FACE_LANDMARKS]) - true_lm, axis=1)
    assert np.median(err) < 3.0  # mm


def test_landmarks_train_augment_zero_or_negative_is_one_clear_line(tmp_path, shared_data, sample_assets, capsys):
    """--augment 0 or -1 with one annotated image used to end in a numpy traceback (exit 1)."""
    photo = shared_data / "images" / "astronaut.png"
    hand = sample_assets / "landmarks" / "astronaut.landmarks.json"
    assert run("landmarks", "train", photo, "--landmarks", hand, "--augment", -1, "-o", tmp_path / "a.npz") == 2
    assert capsys.readouterr().err.strip().endswith("--augment -1: expected a whole number >= 0")
    assert run("landmarks", "train", photo, "--landmarks", hand, "--augment", 0, "-o", tmp_path / "a.npz") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].endswith("AAM training needs at least 2 annotated images (augment a single one)")
    assert not (tmp_path / "a.npz").exists()


def test_stereo_and_register_in_memory(scene_files, sample_assets, tmp_path, monkeypatch):
    """The Python API: the scan authored into a layer, the generic registered onto it from an
    in-memory generic, nothing written; the same points as through files."""
    from pxr import Sdf

    from usdface import api
    from usdface.errors import OptionError
    from usdface.options import RegisterOptions, StereoOptions
    from usdface.usd.mesh_layer import read_mesh_layer

    d, _, _ = scene_files
    glm = sample_assets / "landmarks" / "makehuman_hm08_face.landmarks.layout.json"
    stereo_options = StereoOptions(calib=str(d / "calib.json"), depth_range=(500, 700))
    register_options = RegisterOptions(landmarks=str(d / "lm.json"), generic_landmarks=str(glm), iterations=4)
    files = tmp_path / "files"
    files.mkdir()
    assert run("stereo", d / "L.png", d / "R.png", "--calib", d / "calib.json", "--depth-range", 500, 700,
               "-o", files / "scan.usdc", "-q") == 0
    assert run("register", "--generic", d / "generic.usdc", "--scan", files / "scan.usdc", "--landmarks",
               d / "lm.json", "--generic-landmarks", glm, "--iterations", 4, "-o", files / "reg.usdc", "-q") == 0
    readonly = tmp_path / "readonly"
    readonly.mkdir()
    readonly.chmod(0o555)
    monkeypatch.chdir(readonly)
    try:
        scan = Sdf.Layer.CreateAnonymous("scan.usda")
        result = api.stereo(d / "L.png", d / "R.png", stereo_options, into=scan)
        assert result.layer is scan and result.summary["points"] == read_mesh_layer(files / "scan.usdc")[0].n_points
        generic = api.import_mesh(d / "generic.usdc").layer
        registered = api.register(generic, scan, register_options)
        assert isinstance(registered.layer, Sdf.Layer) and registered.files == {}
        in_memory, regions = read_mesh_layer(registered.layer)
        on_disk, _ = read_mesh_layer(files / "reg.usdc")
        assert np.allclose(in_memory.points, on_disk.points, atol=1e-5)
        assert [r.name for r in regions] == ["outerBorder", "mouth", "leftEye", "rightEye"]
        # an in-memory generic has no landmarks file beside it; an in-memory output no layout beside it
        with pytest.raises(OptionError, match="the generic is in-memory layer"):
            api.register(generic, scan, RegisterOptions(landmarks=str(d / "lm.json")))
        with pytest.raises(OptionError, match=r"say where the carried layout goes \(layout_output=\)"):
            api.register(generic, scan, RegisterOptions(
                landmarks=str(d / "lm.json"), generic_landmarks=str(glm),
                layout=str(sample_assets / "layouts" / "makehuman_hm08_face.layout.json")))
        assert list(readonly.iterdir()) == []
    finally:
        readonly.chmod(0o755)
