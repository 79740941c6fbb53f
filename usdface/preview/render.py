"""Software preview renderer: a z-buffered triangle rasteriser in numpy, Lambert shading, and
OpenCV overlays (markers, wireframe, text, colour bar), plus an atomic PNG writer.

No GPU, no pxr: every function takes numpy arrays and returns arrays; reading USD is the caller's
job (usdface/usd/). Images are ``(H, W, 3) uint8`` in OpenCV's **BGR** channel order (what
:func:`write_png` and ``cv2.imwrite`` expect); every colour given as an argument is **RGB**
(0..255 integers), as people write them.

How a frame is made
-------------------
1. :func:`~usdface.preview.raster.rasterize` (:mod:`usdface.preview.raster`): every triangle is
   scan-converted over the pixel centres of its bounding box (a numba kernel, or vectorised
   numpy); a z-buffer keeps the nearest surface per pixel, whatever the drawing order. Coverage
   rule: a pixel belongs to a triangle when its centre is inside or on an edge.
2. Shading, per pixel: barycentric (perspective-correct) interpolation of vertex normals and vertex
   colours, Lambert with a key light near the camera (a headlight), a fill light from the side, a
   little ambient and specular. Back faces (seen through the eye and mouth holes of an open face
   mesh) are lit as seen from their side but tinted and darker.
3. Optional wireframe of the original polygon edges, depth tested against the z-buffer.
4. With ``supersample=k`` steps 1–3 run at k times the resolution and are averaged down
   (anti-aliasing).
5. Overlays at the final resolution: markers as dots (filled when visible, hollow and dimmer when
   the surface hides them), a second point set as diamonds, labels, title, colour bar, legend.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from ..errors import MeshError, OptionError
from ._common import _bgr, _compiled, _cv2, _rgb  # noqa: F401  (_cv2, _compiled: for callers)
from .camera import Camera
from .colormap import CLAY, apply_colormap, colormap_lut, region_palette as _region_palette, \
    scalar_range as _scalar_range
from .overlays import (_colorbar, _draw_points, _legend, _overlay_scale, _text,  # noqa: F401  (_text: sheet, burnin)
                       MIN_LABEL_FONT, draw_point_labels, glyph_radius, label_font, place_point_labels)
from .png import encode_png, write_png  # noqa: F401  (re-exported)
from .raster import (Buffers, _check_mesh, _neighbourhood_max, point_visibility, rasterize,  # noqa: F401
                     render_buffers)  # (Buffers, point_visibility, rasterize: re-exported)
from .shading import BACKGROUND, _background, _shade, _wire_mask, vertex_normals  # noqa: F401

#: shading modes of :func:`render_mesh`
SHADINGS = ("smooth", "flat", "unlit")


# ================================================================================================
# input checks
# ================================================================================================
def _points3(a, what: str) -> np.ndarray | None:
    if a is None:
        return None
    a = np.asarray(a, dtype=np.float64)
    if a.ndim == 1 and a.size == 3:
        a = a.reshape(1, 3)
    if a.ndim != 2 or a.shape[1] != 3:
        raise OptionError(f"preview: {what} must have shape (M, 3); got {a.shape}")
    return a


def _labels(labels, n: int, what: str) -> list[str] | None:
    if labels is None:
        return None
    labels = [str(s) for s in labels]
    if len(labels) != n:
        raise OptionError(f"preview: {len(labels)} {what} labels for {n} {what}")
    return labels


def polygon_edges(face_vertex_counts: np.ndarray, face_vertex_indices: np.ndarray) -> np.ndarray:
    """Unique undirected edges of polygons (USD faceVertexCounts / faceVertexIndices layout).

    Returns
    -------
    ndarray, shape (E, 2), int64
        Sorted pairs (a < b), for the wireframe of the original polygons (quads stay quads).
    """
    counts = np.asarray(face_vertex_counts, dtype=np.int64).ravel()
    idx = np.asarray(face_vertex_indices, dtype=np.int64).ravel()
    if counts.sum() != idx.size:
        raise MeshError(f"polygon counts sum to {counts.sum()} but there are {idx.size} indices")
    starts = np.cumsum(counts) - counts
    pos = np.arange(idx.size)
    face = np.repeat(np.arange(counts.size), counts)
    nxt = np.where(pos + 1 < starts[face] + counts[face], pos + 1, starts[face])
    e = np.sort(np.stack([idx, idx[nxt]], axis=1), axis=1)
    return np.unique(e, axis=0)


def _region_items(region_colors) -> list[tuple[str, str | None, np.ndarray]]:
    """(name, role, indices) from a mapping name -> indices | Region, or a sequence of Regions."""
    items = []
    if isinstance(region_colors, Mapping):
        pairs = list(region_colors.items())
    elif isinstance(region_colors, Sequence) and not isinstance(region_colors, (str, bytes)):
        pairs = [(getattr(r, "name", None), r) for r in region_colors]
    else:
        raise OptionError("preview: region_colors must be a dict {name: vertex indices} or a list of Region")
    for name, val in pairs:
        role = getattr(val, "role", None)
        if hasattr(val, "indices"):
            name = name or val.name
            val = val.indices
        if name is None:
            raise OptionError("preview: every region needs a name")
        items.append((str(name), role, np.asarray(val).ravel()))
    return items


# ================================================================================================
# the one-call renderer
# ================================================================================================
def fit_camera(points, *, view: str | float = "front", size=(512, 512), projection: str = "orthographic",
               colorbar: bool = False, title_lines: int = 0, **fit_kwargs) -> Camera:
    """:meth:`Camera.fit` that keeps room for :func:`render_mesh`'s overlays: a band on the right
    for the colour bar when ``colorbar``, and one at the top for ``title_lines`` lines of title."""
    w, h = (int(v) for v in size)
    s = _overlay_scale(size)
    right = int(round(64 * s)) if colorbar else 0
    top = int(round((4 + 18 * title_lines) * s)) if title_lines else 0
    if right > w // 2:
        right = 0
    if top > h // 3:
        top = 0
    cam = Camera.fit(points, view=view, size=(w - right, h - top), projection=projection, **fit_kwargs)
    if right or top:  # same view, image extended to the right and upward
        cam = replace(cam, size=(w, h), principal=(cam.principal[0], cam.principal[1] + top))
    return cam


# ================================================================================================
def render_mesh(points: np.ndarray, triangles: np.ndarray, *, camera: Camera | None = None,
                view: str | float = "front", size=(512, 512), projection: str = "orthographic",
                pitch: float = 0.0, vertex_colors: np.ndarray | None = None, region_colors=None, region_palette=None,
                scalars: np.ndarray | None = None, scalar_range: tuple[float, float] | None = None,
                scalar_label: str = "", colormap: str = "viridis",
                markers: np.ndarray | None = None, marker_labels=None, marker_color=(255, 200, 40),
                marker_name: str = "markers",
                extra_points: np.ndarray | None = None, extra_labels=None, extra_color=(40, 230, 255),
                extra_name: str = "points", links: bool = False,
                edges: np.ndarray | None = None, wire_color=(18, 18, 22), wire_alpha: float = 0.5,
                title: str = "", shading: str = "smooth", background=None, supersample: int = 2,
                legend: bool = True, occlusion_tolerance: float | None = None,
                marker_radius: float | None = None, label_info: dict | None = None) -> np.ndarray:
    """Render a preview image of a triangle mesh.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
        Vertex positions (any linear unit).
    triangles : ndarray, shape (T, 3), int
        Triangles (e.g. ``FaceMesh.triangles()``); counter-clockwise = front face.
    camera : Camera, optional
        Fixed camera (e.g. shared by every frame of a sequence); its size wins over ``size``.
        Default: :func:`fit_camera` of the points, markers and extra points with ``view``
        (name or yaw in degrees), ``size`` (width, height), ``projection`` and ``pitch`` (degrees,
        positive from above), leaving room for the title and colour bar.
    vertex_colors : ndarray, shape (N, 3), optional
        RGB per vertex, floats in [0, 1] or uint8.
    region_colors : dict {name: vertex indices or Region} or list of Region, optional
        Vertices of each region get the fixed palette colour of the region (mouth red-ish, eyes
        blue-ish, outer border grey, others distinct; see :func:`usdface.preview.colormap.region_palette`);
        later regions paint over earlier ones; other vertices are clay. Loop regions (outer border,
        mouth, eyes: one vertex wide) also tint two rings of vertices around them (weights
        :data:`BAND_WEIGHTS`) so they show at any size. A legend lists them.
    region_palette : dict {name: (r, g, b)}, optional
        Overrides of region colours (0..255).
    scalars : ndarray, shape (N,), optional
        A value per vertex shown through ``colormap`` with a colour bar; NaN shows grey.
    scalar_range : (lo, hi), optional
        Values at the ends of the colour map (default: min/max; symmetric for ``coolwarm``).
    scalar_label : str
        Title of the colour bar (quantity and unit, e.g. ``"displacement (cm)"``).
    colormap : str
        ``viridis`` (default), ``magma`` or ``coolwarm`` (diverging).
    markers : ndarray, shape (M, 3), optional
        Drawn as dots: filled when visible, hollow and dimmer when behind the surface. NaN rows
        (gaps) are skipped.
    marker_labels : sequence of M str, optional
    marker_color : (r, g, b)
    marker_name : str
        Legend text of the markers.
    extra_points, extra_labels, extra_color, extra_name :
        A second point set (e.g. bound points vs capture markers), drawn as diamonds.
    links : bool
        Draw a thin line from each marker to the extra point of the same index (needs M == K).
    edges : ndarray, shape (E, 2), int, optional
        Wireframe overlay: the edges of the original polygons (see :func:`polygon_edges`),
        hidden parts removed.
    wire_color, wire_alpha :
        Wireframe colour (r, g, b) and opacity.
    title : str
        Text at the top left (may have several lines).
    shading : str
        ``"smooth"`` (Lambert per pixel with interpolated vertex normals), ``"flat"`` (one normal
        per triangle) or ``"unlit"`` (the vertex colours exactly, e.g. to read a scalar map).
    background : (r, g, b), optional
        Solid background; default a dark vertical gradient.
    supersample : int
        Render at this multiple of the size and average down (anti-aliasing); 1 = off.
    legend : bool
        Draw the region and marker legends and the colour bar.
    occlusion_tolerance : float, optional
        World units a marker may lie behind the surface and still count as visible; default 1%
        of the mesh's bounding-box diagonal.
    marker_radius : float, optional
        Dot radius in pixels; default scales with the image (4 px at 512, at least 3.5) and
        shrinks to 0.35 of the median spacing of the points on screen (at least 1.5 px), so
        glyphs never swamp a small picture.
    label_info : dict, optional
        Filled with the label layout (``boxes`` (K, 4) x0 y0 x1 y1, ``placed``, ``leader``,
        ``anchors``, ``texts``, ``reserved`` boxes of glyphs, legends, colour bar and title,
        ``radius``): labels are placed by :mod:`usdface.preview.labels` so that no two boxes
        overlap, none covers a glyph, legend, colour bar or title, and all lie inside the image;
        labels away from their point get a leader line.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
        The image, BGR channel order (ready for :func:`write_png` / ``cv2.imwrite``).
    """
    cv2 = _cv2()
    points, tris = _check_mesh(points, triangles)
    n = points.shape[0]
    markers = _points3(markers, "markers")
    extra = _points3(extra_points, "extra_points")
    marker_labels = _labels(marker_labels, 0 if markers is None else markers.shape[0], "marker")
    extra_labels = _labels(extra_labels, 0 if extra is None else extra.shape[0], "extra point")
    if shading not in SHADINGS:
        raise OptionError(f"preview: shading must be one of {', '.join(SHADINGS)}; got {shading!r}")
    ss = int(supersample)
    if ss < 1 or ss > 8:
        raise OptionError(f"preview: supersample must be 1..8; got {supersample}")
    given = [k for k, v in (("vertex_colors", vertex_colors), ("region_colors", region_colors),
                            ("scalars", scalars)) if v is not None]
    if len(given) > 1:
        raise OptionError(f"preview: give only one of vertex_colors, region_colors, scalars; got {', '.join(given)}")
    if links and (markers is None or extra is None or markers.shape[0] != extra.shape[0]):
        raise OptionError("preview: links=True needs markers and extra_points of the same length; got "
                          f"{None if markers is None else markers.shape[0]} and {None if extra is None else extra.shape[0]}")
    if edges is not None:
        e = np.asarray(edges)
        if e.ndim != 2 or e.shape[1] != 2 or (e.size and (not np.issubdtype(e.dtype, np.integer)
                                                           or e.min() < 0 or e.max() >= n)):
            raise MeshError(f"preview: edges must be integer pairs (E, 2) of vertex indices in 0..{n - 1}")
        edges = e.astype(np.int64)
    marker_rgb = _rgb(marker_color, "marker_color")
    extra_rgb = _rgb(extra_color, "extra_color")
    wire_rgb = _rgb(wire_color, "wire_color")
    if camera is None:
        camera = fit_camera([points, markers, extra], view=view, size=size, projection=projection, pitch=pitch,
                            colorbar=scalars is not None and legend, title_lines=len(str(title).splitlines()))
    elif not isinstance(camera, Camera):
        raise OptionError(f"preview: camera must be a usdface.preview.Camera; got {type(camera).__name__}")
    w, h = camera.size
    s = _overlay_scale((w, h))  # overlay scale (text, dots); not below half size to stay legible
    diag = float(np.linalg.norm([np.ptp(points[:, k]) for k in range(3)])) or 1.0  # per column: fast
    tol = 0.01 * diag if occlusion_tolerance is None else float(occlusion_tolerance)

    # --- per-vertex colours ---------------------------------------------------------------------
    legend_entries = []
    lut = lo = hi = scalar_t = None
    has_nan = False
    colors = np.broadcast_to(np.asarray(CLAY), (n, 3)).copy()
    if vertex_colors is not None:
        vc = np.asarray(vertex_colors)
        if vc.ndim != 2 or vc.shape[0] != n or vc.shape[1] not in (3, 4):
            raise OptionError(f"preview: vertex_colors must have shape ({n}, 3); got {vc.shape}")
        vc = vc[:, :3].astype(np.float64) / (255.0 if vc.dtype == np.uint8 else 1.0)
        colors = np.clip(np.nan_to_num(vc, nan=0.5), 0.0, 1.0)
    elif region_colors is not None:
        colors, legend_entries = _region_colors(points, tris, region_colors, region_palette, diag)
    elif scalars is not None:
        sc = np.asarray(scalars, dtype=np.float64).ravel()
        if sc.size != n:
            raise OptionError(f"preview: scalars must have one value per vertex ({n}); got {sc.size}")
        lo, hi = _scalar_range(sc, colormap=colormap) if scalar_range is None else map(float, scalar_range)
        colors = apply_colormap(sc, vrange=(lo, hi), colormap=colormap)  # also checks the range
        lut = colormap_lut(colormap)
        finite = np.isfinite(sc)
        has_nan = not bool(finite.all())
        with np.errstate(invalid="ignore"):
            scalar_t = np.where(finite, np.clip((sc - lo) / ((hi - lo) or 1.0), 0.0, 1.0), np.nan)

    # --- rasterise, shade, wireframe (at the supersampled resolution) ---------------------------
    cam_hi = camera.resized(ss) if ss > 1 else camera
    buf = render_buffers(points, tris, cam_hi, _reuse=True, _checked=True)
    out = _background(cam_hi.size, background)
    _shade(buf, points, tris, colors, out, shading=shading, specular=0.10 if scalars is None else 0.04,
           scalar_t=scalar_t, lut=lut)
    ref = None
    if edges is not None:
        ref = _neighbourhood_max(buf.depth, 1)
        mask = _wire_mask(buf, edges, 0.004 * diag, ref)
        a = float(np.clip(wire_alpha, 0.0, 1.0))
        out[mask] = (out[mask] * (1 - a) + np.asarray(_bgr(wire_rgb), dtype=np.float32) * a + 0.5).astype(np.uint8)
    if ss > 1:
        out = cv2.resize(out, (w, h), interpolation=cv2.INTER_AREA)
    out = np.ascontiguousarray(out)

    # --- overlays at the final resolution -------------------------------------------------------
    sets = []
    if markers is not None:
        iv, vis = point_visibility(markers, buf, tolerance=tol, _ref=ref)
        sets.append(("circle", markers, iv, vis, marker_labels, marker_rgb, marker_name))
    if extra is not None:
        iv, vis = point_visibility(extra, buf, tolerance=tol, _ref=ref)
        sets.insert(0, ("diamond", extra, iv, vis, extra_labels, extra_rgb, extra_name))
    projected = [camera.project(pts)[0] for _, pts, *_ in sets]
    if marker_radius is not None:
        radius = float(marker_radius)
    else:
        radius = glyph_radius([xy[iv] for xy, (_, _, iv, *_) in zip(projected, sets)], (w, h), scale=s)
    if links:
        a_xy, _ = camera.project(markers)
        b_xy, _ = camera.project(extra)
        f = 16
        for p, q in zip(a_xy, b_xy):
            if np.isfinite(p).all() and np.isfinite(q).all():
                a = tuple(int(round((c - 0.5) * f)) for c in p)
                b = tuple(int(round((c - 0.5) * f)) for c in q)
                cv2.line(out, a, b, (230, 230, 230), 1, cv2.LINE_AA, 4)
    point_legend, label_entries, glyph_boxes = [], [], []
    for (shape, pts, iv, vis, labels, prgb, pname), xy in zip(sets, projected):
        _draw_points(out, xy, iv, vis, prgb, radius=radius, shape=shape)
        g = radius * (1.25 if shape == "diamond" else 1.0)
        for m in np.flatnonzero(iv):
            glyph_boxes.append((xy[m, 0] - 0.5 - 0.8 * g, xy[m, 1] - 0.5 - 0.8 * g,
                                xy[m, 0] - 0.5 + 0.8 * g, xy[m, 1] - 0.5 + 0.8 * g))
            if labels is not None and labels[m]:
                label_entries.append((xy[m], labels[m], prgb, bool(vis[m])))
        nvis, nin = int(vis.sum()), int(iv.sum())
        text = f"{pname}: {nvis} visible"
        if nin - nvis:
            text += f", {nin - nvis} hidden"
        if pts.shape[0] - nin:
            text += f", {pts.shape[0] - nin} off"
        point_legend.append(("circle" if shape == "circle" else "diamond", prgb, text))
    reserved = list(glyph_boxes)
    if lut is not None and legend:
        reserved.append(_colorbar(out, lut, lo, hi, scalar_label, s, has_nan))
    if legend:
        for box in (_legend(out, legend_entries, s, corner="bottom-left"),
                    _legend(out, point_legend[::-1], s, corner="bottom-right" if legend_entries else "bottom-left")):
            if box is not None:
                reserved.append(box)
    if title:
        for k, line in enumerate(str(title).splitlines()):
            size = (0.55 if k == 0 else 0.42) * s
            org = (10 * s, (22 + 18 * k) * s)
            _text(out, line, org, size, (245, 245, 245))
            (tw, th), bl = cv2.getTextSize(line, 0, size, 3)
            reserved.append((org[0] - 2, org[1] - th - 2, org[0] + tw + 2, org[1] + bl + 2))
    if label_entries:
        font = label_font(s)
        obstacles = np.array(reserved, dtype=np.float64).reshape(-1, 4)
        while True:  # a crowded small picture: smaller text before leaving labels out
            placement, _, bases = place_point_labels((w, h), label_entries, radius=radius, font=font,
                                                     obstacles=obstacles)
            if not placement.n_dropped or font <= MIN_LABEL_FONT * 0.8:
                break
            font = max(font * 0.88, MIN_LABEL_FONT * 0.8)
        draw_point_labels(out, label_entries, placement, bases, radius=radius, font=font)
        if label_info is not None:
            label_info.update(boxes=placement.boxes, placed=placement.placed, leader=placement.leader,
                              anchors=np.array([e[0] for e in label_entries]) - 0.5, texts=[e[1] for e in label_entries],
                              reserved=np.array(reserved, dtype=np.float64).reshape(-1, 4), radius=radius)
    elif label_info is not None:
        label_info.update(boxes=np.zeros((0, 4)), placed=np.zeros(0, bool), leader=np.zeros(0, bool),
                          anchors=np.zeros((0, 2)), texts=[], reserved=np.array(reserved).reshape(-1, 4),
                          radius=radius)
    return out


#: region roles (and names, for plain dicts) that are loops of vertices, drawn with a band
LOOP_ROLES = ("outerBorder", "mouth", "eye")
LOOP_NAMES = ("outerBorder", "mouth", "leftEye", "rightEye")
#: width of the band drawn around a loop region, as a fraction of the mesh's bounding-box diagonal
BAND_WIDTH = 0.035


_BAND_CACHE: dict = {}
_REGION_COLOR_CACHE: dict = {}


def _region_colors(points, tris, region_colors, region_palette, diag) -> tuple[np.ndarray, list]:
    """(per-vertex colours (N, 3) float64 0..1, legend entries) of :func:`render_mesh`'s
    ``region_colors``: clay, a band fading out around loop regions (holes, border), the regions'
    own colours on top. Cached per mesh topology, regions and palette: every frame of a movie has
    the same colours (the bands are measured on the first pose seen, as :func:`_band_cached`)."""
    n = points.shape[0]
    items = _region_items(region_colors)
    topology = _digest(tris)
    key = (n, topology, tuple((name, role, str(idx.dtype), _digest(idx)) for name, role, idx in items),
           tuple(sorted((str(k), tuple(v) if isinstance(v, (list, tuple)) else repr(v))
                        for k, v in (region_palette or {}).items())))
    hit = _REGION_COLOR_CACHE.get(key)
    if hit is not None:
        return hit[0].copy(), list(hit[1])
    pal = _region_palette([it[0] for it in items], [it[1] for it in items])
    for name, rgb in (region_palette or {}).items():
        pal[name] = _rgb(rgb, f"region_palette[{name!r}]")
    colors = np.broadcast_to(np.asarray(CLAY), (n, 3)).copy()
    legend_entries = []
    for name, role, idx in items:
        if idx.size and (not np.issubdtype(idx.dtype, np.integer) or idx.min() < 0 or idx.max() >= n):
            raise MeshError(f"preview: region {name!r} has vertex indices outside 0..{n - 1}")
        if idx.size and (role in LOOP_ROLES or (role is None and name in LOOP_NAMES)):
            # a loop of vertices (hole or border) is one vertex wide: shade a band around it
            rgb = np.asarray(pal[name], dtype=np.float64) / 255
            near, weight = _band_cached(points, topology, idx.astype(np.int64), BAND_WIDTH * diag)
            colors[near] = colors[near] * (1 - weight[:, None]) + rgb * weight[:, None]
    for name, _role, idx in items:
        colors[idx.astype(np.int64)] = np.asarray(pal[name], dtype=np.float64) / 255
        legend_entries.append(("swatch", pal[name], f"{name} ({np.unique(idx).size})"))
    if len(_REGION_COLOR_CACHE) >= 32:
        _REGION_COLOR_CACHE.clear()
    _REGION_COLOR_CACHE[key] = (colors.copy(), list(legend_entries))
    return colors, legend_entries


def _digest(a: np.ndarray) -> str:
    import hashlib

    return hashlib.sha1(memoryview(np.ascontiguousarray(a)).cast("B")).hexdigest()


def _band_cached(points, topology: str, idx, width):
    """:func:`_band` once per topology (``topology``: the triangles' digest) and region: a movie
    renders the same face hundreds of times and the band is decoration (computed on the first
    pose seen)."""
    key = (points.shape[0], topology, _digest(idx))
    hit = _BAND_CACHE.get(key)
    if hit is None:
        if len(_BAND_CACHE) >= 32:
            _BAND_CACHE.clear()
        hit = _BAND_CACHE[key] = _band(points, idx, width)
    return hit


def _band(points: np.ndarray, idx: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices within ``width`` of the vertex set ``idx`` and their band weight (0.85 at the
    loop, fading to 0 at ``width``)."""
    from scipy.spatial import cKDTree

    d, _ = cKDTree(points[idx]).query(points, distance_upper_bound=width)
    near = np.flatnonzero(np.isfinite(d))
    return near, 0.85 * (1.0 - d[near] / width) ** 0.6


def render_face(mesh, *, regions=None, wireframe: bool = False, **kwargs) -> np.ndarray:
    """:func:`render_mesh` of a :class:`usdface.mesh.FaceMesh`: its fan triangulation, its polygon
    edges as wireframe when ``wireframe``, and ``regions`` (list of Region or dict) as region colours."""
    if wireframe and kwargs.get("edges") is None:
        kwargs["edges"] = polygon_edges(mesh.face_vertex_counts, mesh.face_vertex_indices)
    if regions is not None:
        kwargs["region_colors"] = regions
    return render_mesh(mesh.points, mesh.triangles(), **kwargs)


__all__ = ["BACKGROUND", "Buffers", "encode_png", "fit_camera", "point_visibility", "polygon_edges", "rasterize", "render_buffers",
           "render_face", "render_mesh", "vertex_normals", "write_png"]
