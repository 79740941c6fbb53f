"""Haar face detection on the real photo; the AAM trained and tested on rendered faces."""
import numpy as np
import pytest

from usdface.errors import FormatError, InputError
from usdface.scan.aam import load_aam, procrustes_align, similarity_transform_2d, train_aam
from usdface.scan.detect import detect_faces, draw_detections, largest_face_box
from usdface.scan.landmarks import FACE_LANDMARKS, interocular_distance


def _iou(a, b):
    ax, ay, aw, ah = a
    bx, by, bw, bh = b
    ix = max(0, min(ax + aw, bx + bw) - max(ax, bx))
    iy = max(0, min(ay + ah, by + bh) - max(ay, by))
    return ix * iy / (aw * ah + bw * bh - ix * iy)


def test_haar_finds_the_one_face_of_the_photo(shared_data):
    import cv2

    img = cv2.imread(str(shared_data / "images" / "astronaut.png"))
    faces = detect_faces(img)
    assert len(faces) == 1
    assert _iou(faces[0].box, (177, 66, 95, 95)) > 0.85
    assert len(faces[0].eyes) == 2 and faces[0].eyes[0][0] < faces[0].eyes[1][0]
    assert faces[0].mouth is not None  # the smile cascade (no mouth cascade ships with OpenCV)
    pic = draw_detections(img, faces)
    assert pic.shape[0] >= 768


def test_no_face_in_a_blank_image():
    assert detect_faces(np.full((200, 200, 3), 128, np.uint8)) == []


def test_similarity_and_procrustes():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(10, 2))
    th = 0.3
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    b = 2.5 * a @ R.T + [3, -1]
    A, t = similarity_transform_2d(a, b)
    assert np.allclose(a @ A.T + t, b)
    aligned, mean = procrustes_align(np.stack([a, b, 0.5 * a + 1]))
    assert np.allclose(aligned[0], aligned[1], atol=1e-6) and np.allclose(aligned[0], aligned[2], atol=1e-6)


@pytest.fixture(scope="module")
def renders(sample_assets, shared_data):
    from usdface.scan.synthetic import render_annotated_faces, sample_face

    photo = shared_data / "images" / "astronaut.png"
    units = np.load(sample_assets / "meshes" / "makehuman_hm08_face_units_cm.npz")
    keep = [i for i, n in enumerate(units["names"]) if not str(n).startswith("eyeLook") and str(n) != "tongueOut"]
    deltas = units["deltas"][keep]
    _, _, _, neutral = sample_face(sample_assets, "neutral", photo=photo)
    _, _, _, stylized = sample_face(sample_assets, "stylized", photo=photo)
    train = render_annotated_faces(neutral, 40, size=(160, 160), seed=1, deltas=deltas)
    test_same = render_annotated_faces(neutral, 6, size=(160, 160), seed=77, deltas=deltas)
    test_other = render_annotated_faces(stylized, 6, size=(160, 160), seed=78, deltas=deltas)
    return train, test_same, test_other


def _errors(model, images, marks):
    out = []
    for img, lm in zip(images, marks):
        box = largest_face_box(img)
        if box is None:
            continue
        fit = model.fit(img, box)
        iod = interocular_distance(lm)
        out.append((np.linalg.norm(fit.initial - lm, axis=1).mean() / iod, np.linalg.norm(fit.points - lm, axis=1).mean() / iod))
    return np.array(out)


def test_aam_on_held_out_renders(renders, tmp_path):
    (imgs, marks), (ti, tm), (oi, om) = renders
    model = train_aam(imgs, marks, names=FACE_LANDMARKS, detector=largest_face_box)
    assert model.n_points == 20 and model.n_shape_modes >= 3
    p = model.save(tmp_path / "face.aam.npz")
    model = load_aam(p)
    same = _errors(model, ti, tm)
    other = _errors(model, oi, om)
    assert len(same) >= 5 and len(other) >= 5  # Haar finds the rendered faces
    # fitting improves on the Haar-box start and ends within a few % of the inter-ocular distance
    assert np.median(same[:, 1]) < 0.03 and np.median(same[:, 1]) < np.median(same[:, 0])
    assert np.median(other[:, 1]) < 0.06 and np.median(other[:, 1]) < np.median(other[:, 0])


def test_aam_bad_inputs(tmp_path):
    img = np.zeros((50, 50), np.uint8)
    with pytest.raises(InputError, match="at least 2"):
        train_aam([img], np.zeros((1, 5, 2)), names="abcde")
    with pytest.raises(InputError, match="2 images but 3"):
        train_aam([img, img], np.zeros((3, 5, 2)), names="abcde")
    (tmp_path / "m.npz").write_bytes(b"junk")
    with pytest.raises(FormatError):
        load_aam(tmp_path / "m.npz")
    with pytest.raises(InputError, match="no such file"):
        load_aam(tmp_path / "none.npz")
