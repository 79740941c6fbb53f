"""Disparity maps: the real Middlebury pair (crops) and rendered faces with exact depth."""
import numpy as np
import pytest

from usdface.errors import InputError, OptionError
from usdface.scan.calibration import calibration_from_dict
from usdface.scan.stereo import bad_pixel_rate, check_rectified, compute_disparity, disparity_range

CROP = (slice(120, 300), slice(180, 460))  # 280 x 180, disparities 7-60 inside


@pytest.fixture(scope="module")
def moto(shared_data):
    import cv2

    d = shared_data / "images" / "stereo"
    left = cv2.imread(str(d / "motorcycle_left.png"))
    right = cv2.imread(str(d / "motorcycle_right.png"))
    gt = np.load(d / "motorcycle_disp.npz")["arr_0"]
    return left, right, gt


def test_bad_pixel_rate_definition():
    gt = np.array([[10.0, 10.0, np.inf, 10.0]])
    d = np.array([[10.5, 13.0, 0.0, np.nan]])
    r = bad_pixel_rate(d, gt)
    assert r["pixels"] == 3
    assert r["bad"] == pytest.approx(2 / 3)  # one wrong, one missing
    assert r["bad_known"] == pytest.approx(1 / 2)
    assert r["density"] == pytest.approx(2 / 3)


def test_graphcut_beats_plain_sgbm_on_middlebury_crop(moto):
    left, right, gt = moto
    L, R, G = left[CROP], right[CROP], gt[CROP]
    plain = compute_disparity(L, R, method="sgbm-plain", num_disparities=64, min_texture=0)
    wls = compute_disparity(L, R, method="sgbm", num_disparities=64, min_texture=0)
    gc = compute_disparity(L, R, method="graphcut", num_disparities=64, max_cycles=1, min_texture=0)
    b_plain = bad_pixel_rate(plain.disparity, G)["bad"]
    b_wls = bad_pixel_rate(wls.disparity, G)["bad"]
    b_gc = bad_pixel_rate(gc.disparity, G)["bad"]
    assert b_gc < b_plain
    assert b_gc < 0.25 and b_wls < 0.35
    assert gc.valid.mean() > 0.7 and wls.valid.mean() > 0.6


def test_vertical_pair_is_the_transposed_horizontal_one(moto):
    left, right, _ = moto
    L, R = left[CROP], right[CROP]
    h = compute_disparity(L, R, method="sgbm", num_disparities=64)
    v = compute_disparity(np.ascontiguousarray(L.transpose(1, 0, 2)), np.ascontiguousarray(R.transpose(1, 0, 2)),
                          method="sgbm", num_disparities=64, vertical=True)
    assert np.allclose(np.nan_to_num(v.disparity.T), np.nan_to_num(h.disparity))


def test_rectification_check(moto):
    import cv2

    left, right, _ = moto
    assert check_rectified(left, right)["rectified"] is True
    M = cv2.getRotationMatrix2D((370, 250), 3.0, 1.0)
    rot = cv2.warpAffine(right, M, (right.shape[1], right.shape[0]))
    r = check_rectified(left, rot)
    assert r["rectified"] is False and r["median_offset"] > 2


def test_bad_pairs():
    a = np.zeros((100, 120), np.uint8)
    with pytest.raises(InputError, match="differ in size"):
        compute_disparity(a, np.zeros((100, 121), np.uint8))
    with pytest.raises(OptionError, match="--method"):
        compute_disparity(a, a, method="magic")
    with pytest.raises(OptionError, match="do not fit"):
        compute_disparity(a, a, num_disparities=128)


@pytest.fixture(scope="module")
def face_pair(sample_assets, shared_data):
    from usdface.scan.synthetic import render_stereo_pair, sample_face

    _, _, _, scene = sample_face(sample_assets, "stylized", photo=shared_data / "images" / "astronaut.png")
    return render_stereo_pair(scene, size=(320, 240)), render_stereo_pair(scene, size=(240, 320), vertical=True)


@pytest.mark.parametrize("method, median_mm, p95_mm", [("sgbm", 2.5, 10.0), ("graphcut", 1.5, 6.0)])
def test_rendered_face_depth_error(face_pair, method, median_mm, p95_mm):
    for pair in face_pair:
        cal = calibration_from_dict(pair["calibration"])
        lo, n = disparity_range(cal, 500, 700)
        r = compute_disparity(pair["first"], pair["second"], method=method, min_disparity=lo, num_disparities=n,
                              vertical=cal.vertical, max_cycles=2)
        z = cal.depth(np.where(r.valid, r.disparity, np.nan))
        face = np.isfinite(pair["depth"])
        ok = face & np.isfinite(z)
        assert ok.sum() > 0.8 * face.sum()
        err = np.abs(z - pair["depth"])[ok]
        assert np.median(err) < median_mm and np.percentile(err, 95) < p95_mm
        # the flat background is not matched
        assert (np.isfinite(z) & ~face).mean() < 0.05
