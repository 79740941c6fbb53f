"""The compiled orthographic shading (attribute planes, usdface.preview._kernels) against the numpy
reference (_shade_pixels) on the real MakeHuman face, and the rasteriser's reused scratch buffers."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.io.meshes import read_mesh
from usdface.preview import Camera, RenderStyle, colormap_lut, render_buffers, render_mesh
from usdface.preview import raster as raster_module
from usdface.preview.colormap import CLAY, NAN_COLOR
from usdface.preview.shading import _background, _covered_box, _shade

pytest.importorskip("numba")
from usdface.preview import _kernels  # noqa: E402

# measured (tests below, 960x540): at most 1 level of 255 on <= 6e-5 of the covered pixels for
# colours; a scalar pixel whose index lands on the other side of a .5 takes the next colour-map
# entry (up to 3 levels). Bounds: one level / one map step, on at most 5e-4 of the pixels.
MAX_FRACTION = 5e-4


@pytest.fixture(scope="module")
def face(sample_assets):
    m = read_mesh(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj")
    pts = np.asarray(m.points, dtype=np.float64)
    rng = np.random.default_rng(7)
    n = pts.shape[0]
    colors = np.clip(np.asarray(CLAY) + 0.2 * rng.standard_normal((n, 3)), 0.0, 1.0)
    scalars = (pts[:, 1] - pts[:, 1].min()) / np.ptp(pts[:, 1])
    scalars[rng.random(n) < 0.1] = np.nan  # NaN vertices: the NaN-weight plane
    return dict(points=pts, tris=m.triangles(), colors=colors, scalars=scalars)


def _both(face, buf, tris, *, shading, scalar, monkeypatch):
    """(fast path image, reference image, fast path calls)."""
    calls = []
    real = _kernels.ortho_shade_kernel
    monkeypatch.setattr(_kernels, "ortho_shade_kernel", lambda *a: (calls.append(1), real(*a)))
    lut = colormap_lut("viridis")
    outs = []
    for compiled in (None, False):
        out = _background(buf.camera.size, None)
        _shade(buf, face["points"], tris, face["colors"], out, shading=shading, specular=0.04 if scalar else 0.10,
               scalar_t=face["scalars"] if scalar else None, lut=lut if scalar else None, compiled=compiled)
        outs.append(out.astype(np.int64))
    return outs[0], outs[1], len(calls)


CASES = [  # view (yaw), shading, scalar, reversed winding
    ("front", "smooth", False, False), ("front", "flat", False, False), ("front", "unlit", False, False),
    ("front", "smooth", True, False), ("front", "unlit", True, False),
    (35.0, "smooth", False, False), (35.0, "flat", True, False),
    (150.0, "smooth", False, False),  # from behind: the back of the open face mesh
    ("front", "smooth", False, True), ("front", "flat", False, True),  # every triangle turned away
]


@pytest.mark.parametrize("view,shading,scalar,flip", CASES)
def test_ortho_fast_path_matches_numpy_reference(face, view, shading, scalar, flip, monkeypatch):
    tris = face["tris"][:, ::-1].copy() if flip else face["tris"]
    cam = Camera.fit(face["points"], view=view, size=(960, 540))
    buf = render_buffers(face["points"], tris, cam)
    cov = buf.triangle >= 0
    assert buf.box == _covered_box(buf.triangle)
    back = ~buf.front[buf.triangle[cov]]
    if flip or view == 150.0:
        assert back.mean() > 0.9  # the case really shows back faces
    fast, ref, calls = _both(face, buf, tris, shading=shading, scalar=scalar, monkeypatch=monkeypatch)
    assert calls == 1  # the fast path ran (not the per-pixel kernel)
    bg = _background(cam.size, None).astype(np.int64)
    assert (np.abs(ref - bg).max(axis=2)[cov] > 0).mean() > 0.99  # the reference drew the face
    assert np.array_equal(fast[~cov], bg[~cov])  # background untouched
    if scalar:
        if shading == "unlit":
            nan_bgr = np.round(np.asarray(NAN_COLOR[::-1]) * 255)
            assert (np.abs(ref[cov] - nan_bgr).max(axis=1) <= 1).sum() > 1000  # NaN pixels are shown
        lut = colormap_lut("viridis") * 255
        bound = int(np.ceil(np.abs(np.diff(lut, axis=0)).max()))  # one step of the colour map
    else:
        bound = 1
    d = np.abs(fast - ref).max(axis=2)
    assert d.max() <= bound, (d.max(), bound)
    assert (d > 0).sum() <= MAX_FRACTION * cov.sum(), (d > 0).sum()


def test_ortho_fast_path_on_a_crumpled_mesh(face, monkeypatch):
    """Jittered points: slivers, folds and mixed facing; still the reference's picture."""
    rng = np.random.default_rng(3)
    pts = face["points"] + 0.3 * rng.standard_normal(face["points"].shape)
    f = dict(face, points=pts)
    cam = Camera.fit(pts, view=20.0, size=(960, 540))
    buf = render_buffers(pts, face["tris"], cam)
    cov = buf.triangle >= 0
    assert 0.02 < (~buf.front[buf.triangle[cov]]).mean() < 0.5
    for shading in ("smooth", "flat"):
        fast, ref, calls = _both(f, buf, face["tris"], shading=shading, scalar=False, monkeypatch=monkeypatch)
        d = np.abs(fast - ref).max(axis=2)
        assert d.max() <= 1 and (d > 0).sum() <= MAX_FRACTION * cov.sum()


@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_reused_buffers_equal_fresh_ones_after_a_larger_frame(face, projection):
    pts = face["points"]
    centre = pts.mean(axis=0)
    cam = Camera.fit(pts, size=(320, 240), projection=projection)
    small = centre + 0.5 * (pts - centre) + np.array([3.0, -2.0, 0.0])
    render_buffers(pts, face["tris"], cam, _reuse=True)  # the scratch buffers now hold the large face
    reused = render_buffers(small, face["tris"], cam, _reuse=True)
    fresh = render_buffers(small, face["tris"], cam)
    assert np.array_equal(reused.triangle, fresh.triangle)
    assert np.array_equal(reused.depth, fresh.depth)
    assert np.isinf(reused.depth[reused.triangle < 0]).all()
    assert np.isfinite(fresh.depth[fresh.triangle >= 0]).all()
    # and whole frames: the small face after the large one is the small face alone (no legend: text
    # drawn the first time is rasterised, later pasted from a sprite, a level or so apart)
    kw = dict(camera=cam, style=RenderStyle(legend=False), markers=small[::50])
    render_mesh(pts, face["tris"], **kw)
    after = render_mesh(small, face["tris"], **kw)
    raster_module._SCRATCH.buffers = {}
    alone = render_mesh(small, face["tris"], **kw)
    assert np.array_equal(after, alone)


def test_region_colours_cache_serves_the_same_colours_and_tells_regions_apart(face):
    from usdface.preview.render import _BAND_CACHE, _REGION_COLOR_CACHE, _region_colors

    pts, tris = face["points"], face["tris"]
    diag = float(np.linalg.norm(np.ptp(pts, axis=0)))
    low = np.flatnonzero(pts[:, 1] < np.percentile(pts[:, 1], 8))
    regions = {"mouth": low[:40], "leftEye": low[40:60], "forehead": np.flatnonzero(pts[:, 1] > np.percentile(pts[:, 1], 90))}
    _REGION_COLOR_CACHE.clear()
    _BAND_CACHE.clear()
    first, legend = _region_colors(pts, tris, regions, None, diag)
    assert len(_REGION_COLOR_CACHE) == 1
    first[:] = 0.0  # the caller's copy: the cache keeps its own
    again, legend_again = _region_colors(pts, tris, regions, None, diag)
    _REGION_COLOR_CACHE.clear()
    _BAND_CACHE.clear()
    fresh, legend_fresh = _region_colors(pts, tris, regions, None, diag)
    assert np.array_equal(again, fresh) and legend_again == legend_fresh == legend
    assert np.abs(fresh - np.asarray(CLAY)).max(axis=1).astype(bool).sum() > 60  # regions and bands coloured
    fewer = dict(regions, mouth=low[:30])
    other, _ = _region_colors(pts, tris, fewer, None, diag)
    assert not np.array_equal(other, fresh)
    repainted, legend_repainted = _region_colors(pts, tris, regions, {"forehead": (255, 0, 0)}, diag)
    assert np.allclose(repainted[regions["forehead"]], (1.0, 0.0, 0.0)) and legend_repainted != legend


def test_compiled_text_paste_is_the_numpy_blend_bit_for_bit(monkeypatch):
    from usdface.preview import overlays
    from usdface.preview.overlays import _paste, _text_sprite

    rng = np.random.default_rng(5)
    base, gain, _ = _text_sprite("frame 0123  00:00:02:03", 0.8, (245, 245, 245), 1, True)
    assert base.size and (gain < 0.999).any() and (gain > 0.001).any()  # glyphs with soft edges
    img = rng.integers(0, 256, (60, 200, 3), dtype=np.uint8)
    for x, y in ((3, 5), (-20, -4), (150, 40), (500, 5)):  # inside, clipped top-left, bottom-right, outside
        fast, slow = img.copy(), img.copy()
        _paste(fast, base, gain, x, y)
        with monkeypatch.context() as m:
            m.setattr(overlays, "_compiled", lambda: None)
            _paste(slow, base, gain, x, y)
        assert np.array_equal(fast, slow)
        if x < 200:
            assert not np.array_equal(fast, img)
