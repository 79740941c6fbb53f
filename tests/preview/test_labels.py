"""Previews that read well: labels never overlap and stay inside the image, glyphs scale to the
picture, loop regions show."""
from __future__ import annotations

import numpy as np
import pytest

from usdface.preview import Camera, PointSet, RegionColors, RenderStyle, render_mesh
from usdface.preview.labels import boxes_overlap, place_labels


def _pairwise_overlaps(boxes):
    b = boxes[np.isfinite(boxes).all(axis=1)]
    o = boxes_overlap(b, b)
    np.fill_diagonal(o, False)
    return int(o.sum() // 2)


def test_dense_random_labels_never_overlap_and_stay_inside():
    rng = np.random.default_rng(11)
    anchors = rng.normal([200, 150], [30, 25], size=(60, 2))  # a crowd in the middle
    anchors[:5] = [[1, 1], [399, 1], [1, 299], [399, 299], [200, 0]]  # at the very edges
    sizes = rng.uniform([30, 8], [90, 12], size=(60, 2))
    obstacles = np.array([[0, 260, 120, 300], [330, 0, 400, 200]])  # a legend, a colour bar
    p = place_labels(anchors, sizes, image_size=(400, 300), gap=4, obstacles=obstacles)
    assert p.placed.sum() >= 55
    b = p.boxes[p.placed]
    assert (b[:, 0] >= 0).all() and (b[:, 1] >= 0).all() and (b[:, 2] <= 400).all() and (b[:, 3] <= 300).all()
    assert _pairwise_overlaps(p.boxes) == 0
    assert not boxes_overlap(b, obstacles).any()
    np.testing.assert_allclose(b[:, 2] - b[:, 0], sizes[p.placed, 0])  # boxes keep their size


def test_an_isolated_label_sits_next_to_its_point_upper_right():
    p = place_labels([[100, 100]], [[40, 10]], image_size=(300, 300), gap=5)
    x0, y0, x1, y1 = p.boxes[0]
    assert (x0, y1) == pytest.approx((100 + 5 * np.cos(np.pi / 4), 100 - 5 * np.sin(np.pi / 4)))
    assert not p.leader[0]


def test_labels_that_cannot_fit_are_left_out_not_overlapped():
    anchors = np.full((30, 2), 20.0)
    p = place_labels(anchors, np.full((30, 2), [30, 10]), image_size=(40, 40), gap=2)
    assert 0 < p.placed.sum() < 30 and p.n_dropped == 30 - p.placed.sum()
    assert _pairwise_overlaps(p.boxes) == 0


@pytest.fixture(scope="module")
def jaw_frame(sample_assets, tmp_path_factory):
    """The MakeHuman face with its 41 layout markers (and the bound points a little off them)."""
    from usdface.io.meshes import read_mesh
    from usdface.mesh.layout import read_layout

    mesh = read_mesh(sample_assets / "meshes" / "makehuman_hm08_face_cm.obj")
    layout = read_layout(sample_assets / "layouts" / "makehuman_hm08_face.layout.json")
    names = [m.name for m in layout.markers]
    markers = np.array([m.point if m.point is not None else mesh.points[m.vertex] for m in layout.markers],
                       dtype=np.float64)
    return mesh, names, markers


@pytest.mark.parametrize("size", [256, 384, 512, 1024, 2048])
def test_preview_labels_at_every_size(jaw_frame, size):
    mesh, names, markers = jaw_frame
    bound = markers + np.array([0.4, -0.3, 0.2])
    info = {}
    img = render_mesh(mesh.points, mesh.triangles(), style=RenderStyle(size=(size, size), supersample=1),
                      markers=PointSet(markers, labels=names), extra=bound, title="jaw  t=441", label_info=info)
    boxes, placed = info["boxes"], info["placed"]
    assert img.shape == (size, size, 3)
    inside = boxes[placed]
    assert (inside[:, :2] >= 0).all() and (inside[:, 2] <= size).all() and (inside[:, 3] <= size).all()
    assert _pairwise_overlaps(boxes) == 0
    assert not boxes_overlap(inside, info["reserved"]).any()  # no label over a dot, legend or title
    # every label shows from 300 px up; at 256 px a few may be left out rather than overlap
    assert placed.all() if size >= 300 else placed.sum() >= 0.75 * len(names)
    # a label placed away from its point has a leader line; the others touch their point
    for box, anchor, lead in zip(boxes[placed], info["anchors"][placed], info["leader"][placed]):
        qx, qy = np.clip(anchor[0], box[0], box[2]), np.clip(anchor[1], box[1], box[3])
        gap = np.hypot(qx - anchor[0], qy - anchor[1])
        assert lead or gap <= 2.5 * info["radius"] + 6


@pytest.mark.parametrize("size", [96, 160, 256, 512, 2048])
def test_marker_glyphs_scale_to_the_picture(jaw_frame, size):
    mesh, names, markers = jaw_frame
    info = {}
    render_mesh(mesh.points, mesh.triangles(), style=RenderStyle(size=(size, size), supersample=1, legend=False),
                markers=markers, label_info=info)
    cam = Camera.fit([mesh.points, markers], size=(size, size), margin=0.06)
    xy, _ = cam.project(markers)
    d = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    spacing = np.median(d.min(axis=1))
    r = info["radius"]
    assert r <= max(4.0 * size / 512, 3.5) + 1e-9          # never bigger than the image's default
    assert r <= max(0.36 * spacing, 1.5)                     # dots of neighbouring markers stay apart
    assert r >= 1.5
    if size >= 512:
        assert r == pytest.approx(max(4.0 * size / 512, 3.5), rel=0.01) or r == pytest.approx(0.35 * spacing, rel=0.05)


def test_loop_regions_are_visible_on_the_face(jaw_frame):
    """The eye and mouth loops are one vertex wide and lie where the surface turns away from the
    camera: drawn as bands, their colour covers pixels of the shaded face (without the band, no
    pixel of the mouth's or eyes' colour showed)."""
    from usdface.mesh.topology import find_hole_regions
    from usdface.preview.colormap import CLAY, region_palette

    mesh, _, _ = jaw_frame
    regions = find_hole_regions(mesh)
    img = render_mesh(mesh.points, mesh.triangles(), colors=RegionColors(regions),
                      style=RenderStyle(size=(512, 512), legend=False, supersample=1)).astype(np.float64)
    pal = region_palette([r.name for r in regions], [r.role for r in regions])
    clay = np.array(CLAY[::-1]) * 255
    for name in ("mouth", "leftEye", "rightEye"):
        target = np.array(pal[name][::-1], dtype=np.float64)
        tinted = np.linalg.norm(img - target, axis=2) < 0.5 * np.linalg.norm(target - clay)
        assert tinted.sum() > 400, (name, int(tinted.sum()))
