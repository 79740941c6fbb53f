"""Detection kernels: colour model, coverage centroids (compiled vs numpy reference), Hough."""
from __future__ import annotations


import numpy as np
import pytest

from usdface.errors import InputError, OptionError
from usdface.tracking.detect import (ColourModel, MarkerDetector, check_radius_range, check_seeds, find_circles,
                                     learn_colour_model)
from usdface.tracking.synthetic import _disc_coverage

SKIN = np.array([120, 150, 200], np.float32)
BLUE = np.array([215, 70, 20], np.float32)


def dots_image(centres, radius=6.0, size=(200, 160), noise=2.0, seed=0):
    w, h = size
    img = np.tile(SKIN, (h, w, 1))
    for cx, cy in centres:
        cov = _disc_coverage(np.array([[cx, cy]]), radius, 0, 0, w, h, ss=8)[..., None].astype(np.float32)
        img = img * (1 - cov) + BLUE * cov
    img += np.random.default_rng(seed).normal(0, noise, img.shape)
    return np.clip(img + 0.5, 0, 255).astype(np.uint8)


def test_degenerate_colour_model_is_regularised():
    img = dots_image([(50.0, 50.0)], noise=0)
    # all seeds on one pixel, a flat colour: zero covariance
    model = learn_colour_model(img, [(50, 50)] * 5, radius=0.5, min_std=6.0)
    assert model.regularised
    assert np.all(np.linalg.eigvalsh(model.cov) >= 36.0 - 1e-9)
    assert np.isfinite(np.linalg.inv(model.cov)).all()
    d2 = model.table()
    assert d2.shape == (65536,) and np.isfinite(d2).all()


def test_mahalanobis_table_matches_formula():
    rng = np.random.default_rng(1)
    px = rng.normal([100, 150, 200], [5, 3, 9], size=(500, 3))
    m = ColourModel.from_pixels(px, min_std=1.0)
    cb, cr = 210, 140
    diff = np.array([cb, cr]) - m.mean
    assert m.table()[cr * 256 + cb] == pytest.approx(diff @ np.linalg.inv(m.cov) @ diff, rel=1e-5)


def test_radius_and_seed_checks():
    with pytest.raises(OptionError, match="impossible radius range"):
        check_radius_range((9, 4))
    with pytest.raises(OptionError, match="impossible radius range"):
        check_radius_range((0, 4))
    with pytest.raises(OptionError, match="impossible radius range"):
        check_radius_range((10, 200), size=(320, 240))
    assert check_radius_range((4, 9), size=(320, 240)) == (4.0, 9.0)
    with pytest.raises(InputError, match="outside.*Chin"):
        check_seeds({"Nose": [10, 10], "Chin": [400, 10]}, (320, 240))
    with pytest.raises(InputError, match="Nose"):
        check_seeds({"Nose": "here"}, (320, 240))


@pytest.mark.parametrize("seed", range(4))
def test_subpixel_centroids_and_fast_path_match_reference(seed):
    rng = np.random.default_rng(seed)
    centres = np.array([[40, 40], [120, 50], [60, 110], [150, 120]], float) + rng.uniform(-0.5, 0.5, (4, 2))
    img = dots_image(centres, seed=seed)
    model = learn_colour_model(img, centres, radius=4)
    fast = MarkerDetector(model, (4, 9))
    ref = MarkerDetector(model, (4, 9))
    ref.fast = False
    a, b = fast.detect(img), ref.detect(img)
    assert len(a) == len(b) == 4
    oa, ob = np.lexsort(a.xy.T[::-1]), np.lexsort(b.xy.T[::-1])
    assert np.abs(a.xy[oa] - b.xy[ob]).max() < 0.02          # compiled kernel == numpy reference
    assert np.abs(a.area[oa] - b.area[ob]).max() < 0.02 * a.area.max()
    oc = np.lexsort(centres.T[::-1])
    assert np.abs(a.xy[oa] - centres[oc]).max() < 0.08        # sub-pixel accurate (noise 2 levels)
    assert np.allclose(a.radius, 6.0, atol=0.2)               # sum of coverage = pi r^2
    assert (a.confidence > 0.9).all()


def test_blob_filter_rejects_wrong_size_and_shape():
    img = dots_image([(40.3, 40.7)], noise=1)
    import cv2

    cv2.circle(img, (140, 100), 30, tuple(int(c) for c in BLUE), -1, cv2.LINE_AA)      # too big
    cv2.line(img, (20, 140), (90, 150), tuple(int(c) for c in BLUE), 4, cv2.LINE_AA)   # a stroke
    model = learn_colour_model(img, [(40.3, 40.7)], radius=4)
    det = MarkerDetector(model, (4, 9)).detect(img, hough=True)
    good = det.xy[det.confidence > 0.5]
    assert good.shape[0] == 1 and np.abs(good[0] - [40.3, 40.7]).max() < 0.1


def test_hough_finds_disc():
    cov = _disc_coverage(np.array([[20.2, 18.6]]), 6.0, 0, 0, 40, 40, ss=4)
    c = find_circles(cov, (4, 9))
    assert c.shape[0] >= 1 and np.hypot(c[0, 0] - 20.2, c[0, 1] - 18.6) < 1.0 and 4 <= c[0, 2] <= 9
