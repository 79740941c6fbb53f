"""render_mesh: colours, shading, markers and occlusion, wireframe, overlays, errors."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.errors import MeshError, OptionError
from usdface.mesh import FaceMesh, Region
from usdface.preview import (Camera, PointSet, RegionColors, RenderStyle, ScalarColors, VertexColors, colormap_lut,
                             point_visibility, polygon_edges, render_buffers, render_face, render_mesh)
from usdface.preview.colormap import CLAY

BG = (255, 0, 255)  # a background colour no shading produces
BG_BGR = np.array(BG[::-1])


def grid(nx=4, ny=4, z=0.0, x0=-1.0, x1=1.0, y0=-1.0, y1=1.0):
    """A flat quad grid facing +Z: points (nx*ny, 3), quads (Q, 4), triangles (2Q, 3)."""
    gx, gy = np.meshgrid(np.linspace(x0, x1, nx), np.linspace(y0, y1, ny))
    pts = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, z)], axis=1)
    k = np.arange(nx * ny).reshape(ny, nx)
    quads = np.stack([k[:-1, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, 1:].ravel(), k[1:, :-1].ravel()], axis=1)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return pts, quads, tris


def front_cam(pts, size=(64, 64)):
    return Camera.fit(pts, size=size, margin=0.1)


def px(cam, p):
    xy, _ = cam.project(np.asarray(p, dtype=float))
    return int(xy[1]), int(xy[0])  # row, column


def test_unlit_render_shows_vertex_colours_and_background():
    pts, _, tris = grid()
    cam = front_cam(pts)
    img = render_mesh(pts, tris, camera=cam, style=RenderStyle(shading="unlit", background=BG, supersample=1))
    assert img.shape == (64, 64, 3) and img.dtype == np.uint8
    clay_bgr = np.round(np.array(CLAY[::-1]) * 255)
    np.testing.assert_array_equal(img[32, 32], clay_bgr)
    np.testing.assert_array_equal(img[1, 1], BG_BGR)


def test_lit_render_is_shaded_and_back_faces_are_darker():
    pts, _, tris = grid()
    cam = front_cam(pts)
    style = RenderStyle(background=BG, supersample=1)
    front = render_mesh(pts, tris, camera=cam, style=style)
    back = render_mesh(pts, tris[:, ::-1], camera=cam, style=style)
    buf_f = render_buffers(pts, tris, cam)
    buf_b = render_buffers(pts, tris[:, ::-1], cam)
    assert buf_f.front.all() and not buf_b.front.any()
    cov = buf_f.covered
    lum_f = front[cov].astype(float).mean()
    lum_b = back[cov].astype(float).mean()
    assert lum_b < 0.8 * lum_f
    # back faces get a purple-grey tint: blue above green
    b, g, r = back[cov].astype(float).mean(axis=0)
    assert b > g
    # lit front: bright but not saturated, roughly clay coloured (red >= green >= blue)
    b, g, r = front[32, 32].astype(int)
    assert 150 < r < 255 and r >= g >= b


def test_supersampling_anti_aliases_edges():
    pts = np.array([[0, 0, 0], [1, 0.13, 0], [0.21, 1, 0]], dtype=float)
    tris = np.array([[0, 1, 2]])
    cam = front_cam(pts)
    kw = dict(camera=cam, colors=VertexColors(np.ones((3, 3))))
    hard = render_mesh(pts, tris, style=RenderStyle(shading="unlit", background=(0, 0, 0), supersample=1), **kw)[..., 0]
    soft = render_mesh(pts, tris, style=RenderStyle(shading="unlit", background=(0, 0, 0), supersample=3), **kw)[..., 0]
    assert set(np.unique(hard)) <= {0, 255}
    partial = (soft > 10) & (soft < 245)
    assert partial.sum() > 40  # the slanted edges have intermediate values
    assert abs(int(soft.astype(int).sum()) - int(hard.astype(int).sum())) < 0.03 * hard.astype(int).sum()


def test_scalars_map_min_and_max_to_colormap_ends_with_colour_bar():
    # left strip all min, right strip all max, unlit: pixels show the LUT ends exactly
    pts, _, tris = grid(nx=4, ny=2)
    s = np.where(pts[:, 0] < 0, -2.5, 4.0)
    cam = front_cam(pts, size=(200, 100))
    img = render_mesh(pts, tris, camera=cam, colors=ScalarColors(s, label="dist (cm)"),
                      style=RenderStyle(shading="unlit", background=BG, supersample=1))
    lut = np.round(colormap_lut("viridis") * 255).astype(int)
    np.testing.assert_array_equal(img[px(cam, [-0.85, 0, 0])], lut[0][::-1])
    np.testing.assert_array_equal(img[px(cam, [0.85, 0, 0])], lut[-1][::-1])
    # colour bar at the right edge: high end at the top, low end at the bottom
    h, w = img.shape[:2]
    found = False
    for col in range(w - 30, w):  # a column of the bar, somewhere at the right edge
        bar = img[:, col].astype(int)
        rows_hi = np.flatnonzero(np.all(np.abs(bar - lut[-1][::-1]) <= 1, axis=1))
        rows_lo = np.flatnonzero(np.all(np.abs(bar - lut[0][::-1]) <= 1, axis=1))
        if rows_hi.size and rows_lo.size and rows_hi.max() < rows_lo.min():
            found = True
            assert np.ptp(rows_hi) < 5 and np.ptp(rows_lo) < 5  # each end is a short run
    assert found


def test_scalars_are_interpolated_before_the_colour_lookup():
    # between a low and a high vertex every pixel shows a colour of the map (RGB blending of purple
    # and yellow would give browns that are not on viridis)
    pts, _, tris = grid(nx=2, ny=2)
    s = np.where(pts[:, 0] < 0, 0.0, 1.0)
    cam = front_cam(pts, size=(100, 100))
    flat = RenderStyle(shading="unlit", supersample=1, background=BG, legend=False)
    img = render_mesh(pts, tris, camera=cam, colors=ScalarColors(s), style=flat)
    lut = np.round(colormap_lut("viridis") * 255).astype(int)[:, ::-1]
    row = img[50, 15:85].astype(int)
    dist = np.abs(row[:, None, :] - lut[None]).max(axis=2).min(axis=1)
    assert dist.max() <= 1
    # NaN scalars: grey where the NaN vertices dominate, and an n/a swatch
    s2 = s.copy()
    s2[pts[:, 0] > 0] = np.nan
    img2 = render_mesh(pts, tris, camera=cam, colors=ScalarColors(s2), style=flat)
    np.testing.assert_array_equal(img2[50, 80], [140, 140, 140])


def test_scalar_range_clips():
    pts, _, tris = grid(nx=4, ny=2)
    s = pts[:, 0] * 10
    cam = front_cam(pts, size=(200, 100))
    img = render_mesh(pts, tris, camera=cam, colors=ScalarColors(s, range=(-100, -50), colormap="magma"),
                      style=RenderStyle(shading="unlit", supersample=1))
    lut = np.round(colormap_lut("magma") * 255).astype(int)
    np.testing.assert_array_equal(img[px(cam, [0.5, 0, 0])], lut[-1][::-1])


def test_region_colours_dict_and_regions():
    pts, quads, tris = grid(nx=5, ny=5)
    mouth = np.flatnonzero(pts[:, 1] < -0.4)
    eye = np.flatnonzero(pts[:, 1] > 0.4)
    cam = front_cam(pts, size=(128, 128))
    flat = RenderStyle(shading="unlit", supersample=1, legend=False)
    img = render_mesh(pts, tris, camera=cam, colors=RegionColors({"mouth": mouth, "leftEye": eye}), style=flat)
    b, g, r = img[px(cam, [0, -0.9, 0])].astype(int)
    assert r > 180 and r > 2 * g  # mouth red-ish
    b, g, r = img[px(cam, [0, 0.9, 0])].astype(int)
    assert b > 200 and b > r + 80  # eye blue-ish
    mesh = FaceMesh(pts, np.full(len(quads), 4), quads.ravel())
    regs = [Region("lowerLip", "mouth", mouth), Region("rightEye", "eye", eye)]
    img2 = render_face(mesh, regions=regs, camera=cam, style=flat)
    np.testing.assert_array_equal(img2[px(cam, [0, -0.9, 0])], img[px(cam, [0, -0.9, 0])])
    # overrides and the legend
    green_mouth = RegionColors({"mouth": mouth}, palette={"mouth": (0, 255, 0)})
    img3 = render_mesh(pts, tris, camera=cam, colors=green_mouth, style=RenderStyle(shading="unlit", supersample=1))
    np.testing.assert_array_equal(img3[px(cam, [0, -0.9, 0])], [0, 255, 0])
    assert not np.array_equal(img3[100:, :60], render_mesh(pts, tris, camera=cam, colors=green_mouth,
                                                           style=flat)[100:, :60])


def test_hidden_marker_is_drawn_differently_from_a_visible_one():
    pts, _, tris = grid()
    visible = [-0.5, 0.0, 0.05]  # just in front of the surface
    hidden = [0.5, 0.0, -3.0]  # behind it
    markers = np.array([visible, hidden])
    cam = front_cam(pts, size=(128, 128))
    buf = render_buffers(pts, tris, cam)
    in_view, vis = point_visibility(markers, buf, tolerance=0.02)
    assert in_view.all() and vis.tolist() == [True, False]
    color = (255, 200, 40)
    img = render_mesh(pts, tris, camera=cam, markers=PointSet(markers, color=color),
                      style=RenderStyle(shading="unlit", supersample=1, legend=False))
    plain = render_mesh(pts, tris, camera=cam, style=RenderStyle(shading="unlit", supersample=1))
    # visible: a filled dot of the marker colour
    np.testing.assert_array_equal(img[px(cam, visible)], color[::-1])
    # hidden: hollow (surface shows in the middle), outline dimmer than the marker colour
    r, c = px(cam, hidden)
    np.testing.assert_array_equal(img[r, c], plain[r, c])
    patch = img[r - 7:r + 8, c - 7:c + 8].astype(int)
    changed = np.any(patch != plain[r - 7:r + 8, c - 7:c + 8], axis=-1)
    assert changed.sum() > 10  # a ring was drawn
    assert not np.any(np.all(np.abs(patch - np.array(color[::-1])) <= 10, axis=-1))  # never full colour


def test_marker_on_the_surface_at_grazing_angle_counts_as_visible():
    pts, _, tris = grid(nx=20, ny=20)
    on_surface = pts[[45, 150, 233]]
    cam = Camera.fit(pts, view=70.0, size=(256, 256))  # surface seen at 70 degrees
    buf = render_buffers(pts, tris, cam.resized(2))
    _, vis = point_visibility(on_surface, buf, tolerance=0.01 * 2.83)
    assert vis.all()


def test_nan_markers_are_skipped_and_counted_in_the_legend():
    pts, _, tris = grid()
    markers = np.array([[0, 0, 0.1], [np.nan, np.nan, np.nan]])
    img = render_mesh(pts, tris, markers=PointSet(markers, labels=["A", "gap"]))
    assert img.shape == (512, 512, 3)


def test_extra_points_and_links_and_labels_draw_something():
    pts, _, tris = grid()
    cam = front_cam(pts, size=(128, 128))
    m = np.array([[-0.5, 0.5, 0.1], [0.5, -0.5, 0.1]])
    e = m + np.array([0.3, 0.0, 0.0])
    base = render_mesh(pts, tris, camera=cam, markers=m, style=RenderStyle(legend=False))
    more = render_mesh(pts, tris, camera=cam, markers=PointSet(m, labels=["a", "b"]),
                       extra=PointSet(e, labels=["a'", "b'"], color=(0, 255, 0)),
                       style=RenderStyle(links=True, legend=False))
    assert np.abs(more[px(cam, e[0])].astype(int) - [0, 255, 0]).max() <= 8
    assert np.any(more != base)


def test_wireframe_draws_polygon_edges_not_triangle_diagonals_and_hides_occluded_edges():
    pts, quads, tris = grid(nx=3, ny=3)
    edges = polygon_edges(np.full(len(quads), 4), quads.ravel())
    assert len(edges) == 12  # 3x3 grid of quads: 12 edges, no diagonals
    cam = front_cam(pts, size=(128, 128))
    kw = dict(camera=cam, style=RenderStyle(shading="unlit", supersample=1, background=BG, wire_color=(0, 0, 0),
                                            wire_alpha=1.0))
    img = render_mesh(pts, tris, edges=edges, **kw)
    dark = np.all(img == 0, axis=-1)
    assert dark[px(cam, [0.0, 0.5, 0])]  # middle vertical polygon edge
    assert dark[px(cam, [0.5, 0.0, 0])]  # middle horizontal edge
    assert not dark[px(cam, [0.5, 0.5, 0])]  # quad diagonal (triangulation only)
    # a second, larger grid behind: its edges are hidden where the front grid covers them
    back_pts, back_quads, back_tris = grid(nx=9, ny=9, z=-1.0, x0=-2, x1=2, y0=-2, y1=2)  # lines every 0.5
    allp = np.vstack([pts, back_pts])
    allt = np.vstack([tris, back_tris + len(pts)])
    alle = np.vstack([edges, polygon_edges(np.full(len(back_quads), 4), back_quads.ravel()) + len(pts)])
    cam2 = front_cam(allp, size=(128, 128))
    kw["camera"] = cam2
    img2 = render_mesh(allp, allt, edges=alle, **kw)
    dark2 = np.all(img2 == 0, axis=-1)
    assert dark2[px(cam2, [-1.5, 1.25, -1])] and dark2[px(cam2, [1.25, -1.5, -1])]  # back edges in the open
    assert not dark2[px(cam2, [-0.5, 0.25, 0])]  # back edges x = -0.5, y = 0.5: behind the front grid
    assert not dark2[px(cam2, [0.25, 0.5, 0])]
    assert dark2[px(cam2, [0.0, 0.25, 0])]  # front edge x = 0


def test_title_changes_only_the_top_left():
    pts, _, tris = grid()
    cam = Camera.fit(pts)
    a = render_mesh(pts, tris, camera=cam)
    b = render_mesh(pts, tris, camera=cam, title="Jaw take, frame 120\nhybrid RBF")
    diff = np.any(a != b, axis=-1)
    rows, cols = np.nonzero(diff)
    assert diff.sum() > 200 and rows.max() < 60 and cols.min() < 20


def test_auto_framing_leaves_room_for_title_and_colour_bar():
    pts, _, tris = grid()
    plain = render_buffers(pts, tris, Camera.fit(pts)).covered
    from usdface.preview import fit_camera
    cam = fit_camera(pts, colorbar=True, title_lines=2)
    assert cam.size == (512, 512)
    cov = render_buffers(pts, tris, cam).covered
    rows, cols = np.nonzero(cov)
    prow, pcol = np.nonzero(plain)
    assert cols.max() < pcol.max() - 40  # clear of the colour bar on the right
    assert rows.min() > prow.min() + 20  # clear of the title at the top


def test_perspective_render_differs_from_orthographic():
    pts, _, tris = grid()
    box = np.vstack([pts, pts + [0, 0, -2]])
    t = np.vstack([tris, tris[:, ::-1] + len(pts)])
    o = render_mesh(box, t, style=RenderStyle(view="left", projection="orthographic", size=(96, 96)))
    p = render_mesh(box, t, style=RenderStyle(view="left", projection="perspective", size=(96, 96)))
    assert o.shape == p.shape and np.any(o != p)


def test_inputs_are_not_modified():
    pts, _, tris = grid()
    markers = np.array([[0.0, 0.0, 0.1]])
    copies = [a.copy() for a in (pts, tris, markers)]
    render_mesh(pts, tris, markers=markers, colors=ScalarColors(pts[:, 0]), edges=np.array([[0, 1]]))
    for a, b in zip((pts, tris, markers), copies):
        np.testing.assert_array_equal(a, b)


def test_errors_name_the_problem():
    pts, _, tris = grid()
    with pytest.raises(OptionError, match="colors must be a RegionColors, ScalarColors or VertexColors"):
        render_mesh(pts, tris, colors={"a": [0]})
    with pytest.raises(MeshError, match="triangle vertex indices"):
        render_mesh(pts, tris + 100)
    with pytest.raises(MeshError, match=r"shape \(N>0, 3\)"):
        render_mesh(pts[:, :2], tris)
    with pytest.raises(MeshError, match="NaN"):
        render_mesh(np.full_like(pts, np.nan), tris)
    with pytest.raises(OptionError, match="2 marker labels for 1 marker"):
        render_mesh(pts, tris, markers=PointSet([[0, 0, 0]], labels=["a", "b"]))
    with pytest.raises(MeshError, match="region 'mouth'"):
        render_mesh(pts, tris, colors=RegionColors({"mouth": [0, 999]}))
    with pytest.raises(MeshError, match="edges"):
        render_mesh(pts, tris, edges=np.array([[0, 99]]))
    with pytest.raises(OptionError, match="scalars"):
        render_mesh(pts, tris, colors=ScalarColors(np.zeros(3)))
    with pytest.raises(OptionError, match="shading"):
        RenderStyle(shading="toon")
    with pytest.raises(OptionError, match="marker_color"):
        render_mesh(pts, tris, markers=PointSet([[0, 0, 0]], color=(300, 0, 0)))
    with pytest.raises(OptionError, match="links"):
        render_mesh(pts, tris, markers=[[0, 0, 0]], extra=[[0, 0, 0], [1, 1, 1]], style=RenderStyle(links=True))
    with pytest.raises(OptionError, match="supersample"):
        RenderStyle(supersample=0)
    with pytest.raises(OptionError, match="wire_color"):
        RenderStyle(wire_color=(0, 0))
    with pytest.raises(OptionError, match="camera must be a usdface.preview.Camera"):
        render_mesh(pts, tris, camera="front")
