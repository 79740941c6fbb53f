"""The real MakeHuman hm08 face (CC0, ../shared/data/meshes): holes seen through, regions, expressions."""
from __future__ import annotations

import time
from collections import defaultdict

import cv2
import numpy as np
import pytest

from usdface.preview import (Camera, PointSet, RegionColors, RenderStyle, ScalarColors, SheetLayout, polygon_edges,
                             render_buffers, render_mesh, render_sequence, write_png)

BG = (255, 0, 255)


def _load_obj(path):
    """Tiny OBJ reader (v and f lines) used when usdface.io.meshes is not available."""
    verts, counts, idx = [], [], []
    for line in open(path):
        s = line.split()
        if not s:
            continue
        if s[0] == "v":
            verts.append([float(v) for v in s[1:4]])
        elif s[0] == "f":
            f = [int(v.split("/")[0]) - 1 for v in s[1:]]
            counts.append(len(f))
            idx.extend(f)
    return np.array(verts), np.array(counts), np.array(idx)


@pytest.fixture(scope="module")
def face(shared_data):
    path = shared_data / "meshes" / "makehuman_hm08_face_cm.obj"
    if not path.exists():
        pytest.skip(f"{path} not present")
    try:
        from usdface.io.meshes import read_mesh
        m = read_mesh(path)
        points, counts, idx = m.points, m.face_vertex_counts, m.face_vertex_indices
    except ImportError:
        points, counts, idx = _load_obj(path)
    # fan triangulation (v0, vk, vk+1), the same as FaceMesh.triangles()
    starts = np.cumsum(counts) - counts
    tris = np.array([[idx[s], idx[s + k], idx[s + k + 1]] for s, c in zip(starts, counts) for k in range(1, c - 1)])
    edges = polygon_edges(counts, idx)
    loops = _boundary_loops(edges, counts, idx)
    assert [len(lp) for lp in loops] == [28, 28, 38, 82]  # eyes, mouth, outer border (data README)
    eyes = sorted(loops[:2], key=lambda lp: points[lp, 0].mean())  # right eye (-X) first
    return dict(points=points, tris=tris, edges=edges, right_eye=eyes[0], left_eye=eyes[1], mouth=loops[2],
                border=loops[3], path=path)


def _boundary_loops(edges, counts, idx):
    starts = np.cumsum(counts) - counts
    all_e = np.sort(np.array([(idx[s + k], idx[s + (k + 1) % c])
                              for s, c in zip(starts, counts) for k in range(c)]), 1)
    u, n = np.unique(all_e, axis=0, return_counts=True)
    adj = defaultdict(list)
    for a, b in u[n == 1]:
        adj[a].append(b)
        adj[b].append(a)
    seen, loops = set(), []
    for s in adj:
        if s in seen:
            continue
        loop, prev, cur = [s], None, s
        seen.add(s)
        while True:
            nxt = [v for v in adj[cur] if v != prev and v not in seen]
            if not nxt:
                break
            prev, cur = cur, nxt[0]
            seen.add(cur)
            loop.append(cur)
        loops.append(np.array(loop))
    return sorted(loops, key=len)


def _hole_mask(cam, points, loop, shape):
    xy, _ = cam.project(points[loop])
    mask = np.zeros(shape, np.uint8)
    cv2.fillPoly(mask, [np.round((xy - 0.5) * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    return mask.astype(bool)


@pytest.mark.parametrize("view", ["front", "left", "right"])
def test_eye_holes_show_background_at_their_projected_positions(face, view):
    p = face["points"]
    cam = Camera.fit(p, view=view, size=(512, 512))
    buf = render_buffers(p, face["tris"], cam)
    facing = buf.facing()
    for eye in (face["left_eye"], face["right_eye"]):
        inside = _hole_mask(cam, p, eye, facing.shape)
        assert inside.sum() > 300
        assert (facing[inside] != 1).mean() > 0.75  # through the hole: background or the inner lids
        c, _ = cam.project(p[eye].mean(axis=0))
        assert facing[int(c[1]), int(c[0])] == 0  # the eye centre is empty
    # and the face itself is there around them
    assert buf.covered.mean() > 0.3


def test_closed_mouth_is_a_slit_and_open_mouth_a_hole(face, shared_data):
    p = face["points"]
    mouth = face["mouth"]
    cam = Camera.fit(p, size=(512, 512))
    facing = render_buffers(p, face["tris"], cam).facing()
    xy, _ = cam.project(p[mouth])
    rows = slice(int(xy[:, 1].min()) - 2, int(xy[:, 1].max()) + 3)
    x0, x1 = np.percentile(xy[:, 0], [10, 90]).astype(int)
    gaps = np.array([(facing[rows, col] != 1).sum() for col in range(x0, x1)])
    assert (gaps >= 1).mean() > 0.7  # the lips nearly touch: a thin slit between them ...
    assert gaps.max() <= 4  # ... 1-2 px high at 512 px
    assert np.all(facing[rows.start - 20:rows.start, (x0 + x1) // 2] == 1)  # upper lip above it

    units = np.load(shared_data / "meshes" / "makehuman_hm08_face_units_cm.npz")
    names = [str(n) for n in units["names"]]
    opened = p + units["deltas"][names.index("jawOpen")].astype(np.float64)
    facing_o = render_buffers(opened, face["tris"], cam).facing()  # same camera: same framing
    inside = _hole_mask(cam, opened, mouth, facing_o.shape)
    assert inside.sum() > 2000
    assert (facing_o[inside] != 1).mean() > 0.6
    c, _ = cam.project(opened[mouth].mean(axis=0))
    assert facing_o[int(c[1]), int(c[0])] != 1


def test_region_render_of_the_real_face(face, tmp_path):
    p, tris = face["points"], face["tris"]

    def grow(loop, rings=3):  # the hole's rim vertices and their neighbours (the lips curl inward)
        for _ in range(rings):
            loop = np.unique(tris[np.isin(tris, loop).any(axis=1)])
        return loop

    regions = {"outerBorder": face["border"], "mouth": grow(face["mouth"]), "leftEye": grow(face["left_eye"]),
               "rightEye": grow(face["right_eye"])}
    cam = Camera.fit(p, size=(512, 512))
    t0 = time.perf_counter()
    img = render_mesh(p, tris, camera=cam, colors=RegionColors(regions), style=RenderStyle(background=BG),
                      title="hm08 face", markers=PointSet(p[face["mouth"][:3]] + [0, 0, 0.1], labels=["a", "b", "c"]))
    elapsed = time.perf_counter() - t0
    print(f"hm08 face, {len(tris)} triangles, 512x512 supersample 2: {elapsed:.3f} s")
    # through each eye hole: the background colour
    for eye in (face["left_eye"], face["right_eye"]):
        c, _ = cam.project(p[eye].mean(axis=0))
        np.testing.assert_array_equal(img[int(c[1]), int(c[0])], BG[::-1])
    # eye rims are blue-ish, mouth rim red-ish: the pixels of visible front triangles whose three
    # corners are in the region
    buf = render_buffers(p, tris, cam)
    for name, check in (("leftEye", lambda b, g, r: b > r + 40), ("mouth", lambda b, g, r: r > b + 40)):
        member = np.zeros(len(p), bool)
        member[regions[name]] = True
        in_region = member[tris].all(axis=1)
        pix = buf.covered & in_region[np.maximum(buf.triangle, 0)] & (buf.facing() == 1)
        assert pix.sum() > 10, name
        b, g, r = img[pix].astype(float).mean(axis=0)
        assert check(b, g, r), (name, b, g, r)
    write_png(tmp_path / "face.png", img)
    assert (tmp_path / "face.png").stat().st_size > 10_000


def test_sequence_of_real_expressions_shares_one_camera(face, shared_data, tmp_path):
    units = np.load(shared_data / "meshes" / "makehuman_hm08_face_units_cm.npz")
    names = [str(n) for n in units["names"]]
    p = face["points"]
    shapes = ("jawOpen", "mouthSmileLeft", "browInnerUp")
    frames = np.stack([p] + [p + units["deltas"][names.index(n)] for n in shapes])
    disp = np.linalg.norm(frames - p, axis=2)
    sheet = render_sequence(frames, face["tris"], frame_numbers=[0, 10, 20, 30],
                            colors=ScalarColors(disp, label="displacement (cm)"), style=RenderStyle(size=(200, 200)),
                            layout=SheetLayout(columns=2, title="hm08 units"))
    assert sheet.ndim == 3 and sheet.shape[0] > 400 and sheet.shape[1] > 400
    write_png(tmp_path / "sheet.png", sheet)
