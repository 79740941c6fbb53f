"""Colour maps and the region palette."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.errors import OptionError
from usdface.preview import apply_colormap, colormap_lut, region_palette
from usdface.preview.colormap import NAN_COLOR, SEQUENTIAL, lab_to_srgb, srgb_to_lab


@pytest.mark.parametrize("name", SEQUENTIAL)
def test_sequential_maps_are_strictly_monotonic_in_lightness(name):
    lut = colormap_lut(name, 512)
    lightness = srgb_to_lab(lut)[:, 0]
    assert np.all(np.diff(lightness) > 0)
    assert lightness[-1] - lightness[0] > 70  # a wide lightness range


def test_viridis_and_magma_ends_match_the_reference_palettes():
    np.testing.assert_allclose(colormap_lut("viridis")[0] * 255, [68, 1, 84], atol=1.0)
    np.testing.assert_allclose(colormap_lut("viridis")[-1] * 255, [253, 231, 37], atol=1.0)
    np.testing.assert_allclose(colormap_lut("magma")[-1] * 255, [252, 253, 191], atol=1.0)


def test_scalars_map_min_and_max_to_the_ends():
    s = np.array([3.0, -1.0, 7.0, 2.0])
    out = apply_colormap(s)
    lut = colormap_lut("viridis")
    np.testing.assert_array_equal(out[1], lut[0])
    np.testing.assert_array_equal(out[2], lut[-1])
    # explicit range: values beyond it are clipped to the ends
    out = apply_colormap(s, vrange=(0.0, 2.0))
    np.testing.assert_array_equal(out[1], lut[0])
    np.testing.assert_array_equal(out[0], lut[-1])
    np.testing.assert_array_equal(out[3], lut[-1])


def test_nan_scalars_are_grey_and_constant_scalars_do_not_divide_by_zero():
    out = apply_colormap(np.array([1.0, np.nan, 2.0]))
    np.testing.assert_array_equal(out[1], NAN_COLOR)
    out = apply_colormap(np.full(4, 5.0))
    assert np.isfinite(out).all()


def test_diverging_map_is_symmetric_about_zero():
    out = apply_colormap(np.array([-2.0, 0.0, 1.0]), colormap="coolwarm")
    lut = colormap_lut("coolwarm")
    np.testing.assert_array_equal(out[0], lut[0])  # default range is (-2, 2)
    np.testing.assert_allclose(out[1], lut[128], atol=0.02)
    assert out[1].min() > 0.8  # near white in the middle


def test_lab_round_trip():
    rgb = np.random.default_rng(0).uniform(0, 1, (100, 3))
    np.testing.assert_allclose(lab_to_srgb(srgb_to_lab(rgb)), rgb, atol=1e-9)
    np.testing.assert_allclose(srgb_to_lab(np.ones(3)), [100, 0, 0], atol=1e-4)


def test_errors():
    with pytest.raises(OptionError, match="unknown colormap"):
        colormap_lut("jet")
    with pytest.raises(OptionError, match="range"):
        apply_colormap(np.zeros(3), vrange=(1.0, 0.0))


def test_region_palette_roles():
    pal = region_palette(["outerBorder", "mouth", "leftEye", "rightEye", "nose", "cheeks", "lips_inner"])
    r, g, b = pal["mouth"]
    assert r > 180 and r > 2 * g and r > 2 * b  # red-ish
    for eye in ("leftEye", "rightEye"):
        r, g, b = pal[eye]
        assert b > 200 and b > r + 80  # blue-ish
    assert pal["leftEye"] != pal["rightEye"]
    r, g, b = pal["outerBorder"]
    assert r == g == b  # grey
    assert pal["nose"] != pal["cheeks"] and len(set(pal.values())) == len(pal)
    assert region_palette(["x"], ["mouth"])["x"] == region_palette(["mouth"])["mouth"]  # role wins
    assert region_palette(["nose"]) == region_palette(["nose"])  # deterministic
