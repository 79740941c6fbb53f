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
from dataclasses import dataclass, replace

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
from .style import (EXTRA_COLOR, MARKER_COLOR, SHADINGS, PointSet, RegionColors, RenderStyle,  # noqa: F401
                    ScalarColors, VertexColors)  # (SHADINGS: re-exported)


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
                style: RenderStyle | None = None, colors=None, markers=None, extra=None,
                edges: np.ndarray | None = None, title: str = "", label_info: dict | None = None) -> np.ndarray:
    """Render a preview image of a triangle mesh.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
        Vertex positions (any linear unit).
    triangles : ndarray, shape (T, 3), int
        Triangles (e.g. ``FaceMesh.triangles()``); counter-clockwise = front face.
    camera : Camera, optional
        Fixed camera (e.g. shared by every frame of a sequence); its size wins over the style's.
        Default: :func:`fit_camera` of the points, markers and extra points with the style's
        ``view``, ``size``, ``projection`` and ``pitch``, leaving room for the title and colour bar.
    style : RenderStyle, optional
        How the picture looks (:class:`usdface.preview.RenderStyle`: shading, background,
        supersampling, legend, wireframe colour, glyph size, links...).
    colors : RegionColors, ScalarColors or VertexColors, optional
        What colours the surface (default: clay): regions in their palette colours with a legend,
        a value per vertex through a colour map with a colour bar, or given RGB per vertex.
    markers : PointSet or ndarray (M, 3), optional
        Drawn as dots (:class:`usdface.preview.PointSet`: points, labels, colour, legend name).
    extra : PointSet or ndarray (K, 3), optional
        A second point set (e.g. bound points vs capture markers), drawn as diamonds.
    edges : ndarray, shape (E, 2), int, optional
        Wireframe overlay: the edges of the original polygons (see :func:`polygon_edges`),
        hidden parts removed.
    title : str
        Text at the top left (may have several lines).
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
    style = RenderStyle() if style is None else style
    points, tris = _check_mesh(points, triangles)
    n = points.shape[0]
    sets = _point_sets(markers, extra, style)
    edges = _checked_edges(edges, n)
    if camera is None:
        by_shape = {ps.shape: ps.points for ps in sets}  # framed in the order: mesh, markers, extra
        camera = fit_camera([points, by_shape.get("circle"), by_shape.get("diamond")], view=style.view, size=style.size,
                            projection=style.projection, pitch=style.pitch,
                            colorbar=isinstance(colors, ScalarColors) and style.legend,
                            title_lines=len(str(title).splitlines()))
    elif not isinstance(camera, Camera):
        raise OptionError(f"preview: camera must be a usdface.preview.Camera; got {type(camera).__name__}")
    diag = float(np.linalg.norm([np.ptp(points[:, k]) for k in range(3)])) or 1.0  # per column: fast
    surface = _surface_colors(points, tris, colors, diag)
    out, buf, ref = _draw_surface(points, tris, camera, style, surface, edges, diag)
    tol = 0.01 * diag if style.occlusion_tolerance is None else float(style.occlusion_tolerance)
    w, h = camera.size
    s = _overlay_scale((w, h))  # overlay scale (text, dots); not below half size to stay legible
    drawn = _draw_point_sets(out, camera, buf, ref, sets, style, tolerance=tol, scale=s)
    reserved = list(drawn.glyph_boxes) + _draw_legends(out, surface, drawn.legend, style, title, s)
    _draw_labels(out, drawn, reserved, s, label_info)
    return out


# -- the parts of a picture -----------------------------------------------------------------------

@dataclass
class _SetToDraw:
    """A point set ready to draw: checked points (M, 3) and labels, colour, legend name, glyph."""

    points: np.ndarray
    labels: list | None
    rgb: tuple
    name: str
    shape: str


def _point_sets(markers, extra, style: RenderStyle) -> list:
    """The point sets to draw, diamonds (``extra``) under dots (``markers``), checked."""
    markers, extra = PointSet.of(markers), PointSet.of(extra)
    mk = None if markers is None else _points3(markers.points, "markers")
    ex = None if extra is None else _points3(extra.points, "extra_points")
    mk_labels = _labels(markers.labels if markers is not None else None, 0 if mk is None else mk.shape[0], "marker")
    ex_labels = _labels(extra.labels if extra is not None else None, 0 if ex is None else ex.shape[0], "extra point")
    if style.links and (mk is None or ex is None or mk.shape[0] != ex.shape[0]):
        raise OptionError("preview: links=True needs markers and extra_points of the same length; got "
                          f"{None if mk is None else mk.shape[0]} and {None if ex is None else ex.shape[0]}")
    sets = []
    if ex is not None:
        sets.append(_SetToDraw(ex, ex_labels, _rgb(extra.color or EXTRA_COLOR, "extra_color"),
                               extra.name or "points", "diamond"))
    if mk is not None:
        sets.append(_SetToDraw(mk, mk_labels, _rgb(markers.color or MARKER_COLOR, "marker_color"),
                               markers.name or "markers", "circle"))
    return sets


def _checked_edges(edges, n: int) -> np.ndarray | None:
    if edges is None:
        return None
    e = np.asarray(edges)
    if e.ndim != 2 or e.shape[1] != 2 or (e.size and (not np.issubdtype(e.dtype, np.integer)
                                                       or e.min() < 0 or e.max() >= n)):
        raise MeshError(f"preview: edges must be integer pairs (E, 2) of vertex indices in 0..{n - 1}")
    return e.astype(np.int64)


@dataclass
class _Surface:
    """Per-vertex colours (N, 3) float64 0..1, and what the legends need: region entries, or the
    colour map (``lut``), its range and the normalised scalars (``t``, NaN where missing)."""

    colors: np.ndarray
    legend: list
    lut: np.ndarray | None = None
    lo: float | None = None
    hi: float | None = None
    t: np.ndarray | None = None
    has_nan: bool = False
    label: str = ""


def _surface_colors(points, tris, colors, diag: float) -> _Surface:
    """The surface's colours from :func:`render_mesh`'s ``colors`` (clay without)."""
    n = points.shape[0]
    clay = np.broadcast_to(np.asarray(CLAY), (n, 3)).copy()
    if colors is None:
        return _Surface(clay, [])
    if isinstance(colors, VertexColors):
        vc = np.asarray(colors.rgb)
        if vc.ndim != 2 or vc.shape[0] != n or vc.shape[1] not in (3, 4):
            raise OptionError(f"preview: vertex_colors must have shape ({n}, 3); got {vc.shape}")
        vc = vc[:, :3].astype(np.float64) / (255.0 if vc.dtype == np.uint8 else 1.0)
        return _Surface(np.clip(np.nan_to_num(vc, nan=0.5), 0.0, 1.0), [])
    if isinstance(colors, RegionColors):
        return _Surface(*_region_colors(points, tris, colors.regions, colors.palette, diag))
    if isinstance(colors, ScalarColors):
        sc = np.asarray(colors.values, dtype=np.float64).ravel()
        if sc.size != n:
            raise OptionError(f"preview: scalars must have one value per vertex ({n}); got {sc.size}")
        cmap = colors.colormap
        lo, hi = _scalar_range(sc, colormap=cmap) if colors.range is None else map(float, colors.range)
        rgb = apply_colormap(sc, vrange=(lo, hi), colormap=cmap)  # also checks the range
        finite = np.isfinite(sc)
        with np.errstate(invalid="ignore"):
            t = np.where(finite, np.clip((sc - lo) / ((hi - lo) or 1.0), 0.0, 1.0), np.nan)
        return _Surface(rgb, [], lut=colormap_lut(cmap), lo=lo, hi=hi, t=t, has_nan=not bool(finite.all()),
                        label=colors.label)
    raise OptionError("preview: colors must be a RegionColors, ScalarColors or VertexColors (usdface.preview); got "
                      f"{type(colors).__name__}")


def _draw_surface(points, tris, camera: Camera, style: RenderStyle, surface: _Surface, edges, diag: float):
    """Rasterise, shade and draw the wireframe at the supersampled resolution, then average down.
    Returns (image, buffers, the depth reference of the wireframe or None)."""
    cv2 = _cv2()
    ss = style.supersample
    cam_hi = camera.resized(ss) if ss > 1 else camera
    buf = render_buffers(points, tris, cam_hi, _reuse=True, _checked=True)
    out = _background(cam_hi.size, style.background)
    _shade(buf, points, tris, surface.colors, out, shading=style.shading,
           specular=0.10 if surface.lut is None else 0.04, scalar_t=surface.t, lut=surface.lut)
    ref = None
    if edges is not None:
        ref = _neighbourhood_max(buf.depth, 1)
        mask = _wire_mask(buf, edges, 0.004 * diag, ref)
        a = float(np.clip(style.wire_alpha, 0.0, 1.0))
        out[mask] = (out[mask] * (1 - a) + np.asarray(_bgr(style.wire_color), dtype=np.float32) * a + 0.5
                     ).astype(np.uint8)
    if ss > 1:
        w, h = camera.size
        out = cv2.resize(out, (w, h), interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(out), buf, ref


@dataclass
class _DrawnPoints:
    glyph_boxes: list
    labels: list            # (xy, text, rgb, visible) of every labelled point in view
    legend: list            # point legend entries
    radius: float


def _draw_point_sets(out, camera: Camera, buf, ref, sets: list, style: RenderStyle, *, tolerance: float,
                     scale: float) -> _DrawnPoints:
    """Dots and diamonds (filled when visible, hollow when hidden), the links between them; the
    glyphs' boxes, the labels to place and the legend entries."""
    cv2 = _cv2()
    seen = [point_visibility(ps.points, buf, tolerance=tolerance, _ref=ref) for ps in sets]
    projected = [camera.project(ps.points)[0] for ps in sets]
    if style.marker_radius is not None:
        radius = float(style.marker_radius)
    else:
        w, h = camera.size
        radius = glyph_radius([xy[iv] for xy, (iv, _) in zip(projected, seen)], (w, h), scale=scale)
    if style.links:
        by_shape = {ps.shape: ps.points for ps in sets}
        a_xy, _ = camera.project(by_shape["circle"])
        b_xy, _ = camera.project(by_shape["diamond"])
        f = 16
        for p, q in zip(a_xy, b_xy):
            if np.isfinite(p).all() and np.isfinite(q).all():
                a = tuple(int(round((c - 0.5) * f)) for c in p)
                b = tuple(int(round((c - 0.5) * f)) for c in q)
                cv2.line(out, a, b, (230, 230, 230), 1, cv2.LINE_AA, 4)
    drawn = _DrawnPoints([], [], [], radius)
    for ps, (iv, vis), xy in zip(sets, seen, projected):
        _draw_points(out, xy, iv, vis, ps.rgb, radius=radius, shape=ps.shape)
        g = radius * (1.25 if ps.shape == "diamond" else 1.0)
        for m in np.flatnonzero(iv):
            drawn.glyph_boxes.append((xy[m, 0] - 0.5 - 0.8 * g, xy[m, 1] - 0.5 - 0.8 * g,
                                      xy[m, 0] - 0.5 + 0.8 * g, xy[m, 1] - 0.5 + 0.8 * g))
            if ps.labels is not None and ps.labels[m]:
                drawn.labels.append((xy[m], ps.labels[m], ps.rgb, bool(vis[m])))
        nvis, nin = int(vis.sum()), int(iv.sum())
        text = f"{ps.name}: {nvis} visible"
        if nin - nvis:
            text += f", {nin - nvis} hidden"
        if ps.points.shape[0] - nin:
            text += f", {ps.points.shape[0] - nin} off"
        drawn.legend.append((ps.shape, ps.rgb, text))
    return drawn


def _draw_legends(out, surface: _Surface, point_legend: list, style: RenderStyle, title: str, s: float) -> list:
    """Colour bar, region and point legends, title; returns the boxes they cover."""
    cv2 = _cv2()
    reserved = []
    if surface.lut is not None and style.legend:
        reserved.append(_colorbar(out, surface.lut, surface.lo, surface.hi, surface.label, s, surface.has_nan))
    if style.legend:
        for box in (_legend(out, surface.legend, s, corner="bottom-left"),
                    _legend(out, point_legend[::-1], s, corner="bottom-right" if surface.legend else "bottom-left")):
            if box is not None:
                reserved.append(box)
    if title:
        for k, line in enumerate(str(title).splitlines()):
            size = (0.55 if k == 0 else 0.42) * s
            org = (10 * s, (22 + 18 * k) * s)
            _text(out, line, org, size, (245, 245, 245))
            (tw, th), bl = cv2.getTextSize(line, 0, size, 3)
            reserved.append((org[0] - 2, org[1] - th - 2, org[0] + tw + 2, org[1] + bl + 2))
    return reserved


def _draw_labels(out, drawn: _DrawnPoints, reserved: list, s: float, label_info: dict | None) -> None:
    """Point labels placed around everything else (smaller text before leaving any out)."""
    entries, radius = drawn.labels, drawn.radius
    h, w = out.shape[:2]
    if entries:
        font = label_font(s)
        obstacles = np.array(reserved, dtype=np.float64).reshape(-1, 4)
        while True:  # a crowded small picture: smaller text before leaving labels out
            placement, _, bases = place_point_labels((w, h), entries, radius=radius, font=font, obstacles=obstacles)
            if not placement.n_dropped or font <= MIN_LABEL_FONT * 0.8:
                break
            font = max(font * 0.88, MIN_LABEL_FONT * 0.8)
        draw_point_labels(out, entries, placement, bases, radius=radius, font=font)
        if label_info is not None:
            label_info.update(boxes=placement.boxes, placed=placement.placed, leader=placement.leader,
                              anchors=np.array([e[0] for e in entries]) - 0.5, texts=[e[1] for e in entries],
                              reserved=np.array(reserved, dtype=np.float64).reshape(-1, 4), radius=radius)
    elif label_info is not None:
        label_info.update(boxes=np.zeros((0, 4)), placed=np.zeros(0, bool), leader=np.zeros(0, bool),
                          anchors=np.zeros((0, 2)), texts=[], reserved=np.array(reserved).reshape(-1, 4),
                          radius=radius)


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


def render_face(mesh, *, regions=None, wireframe: bool = False, camera: Camera | None = None,
                style: RenderStyle | None = None, colors=None, markers=None, extra=None, title: str = "") -> np.ndarray:
    """:func:`render_mesh` of a :class:`usdface.mesh.FaceMesh`: its fan triangulation, its polygon
    edges as wireframe when ``wireframe``, and ``regions`` (list of Region or dict) as region colours
    (else ``colors``)."""
    edges = polygon_edges(mesh.face_vertex_counts, mesh.face_vertex_indices) if wireframe else None
    colors = RegionColors(regions) if regions is not None else colors
    return render_mesh(mesh.points, mesh.triangles(), camera=camera, style=style, colors=colors, markers=markers,
                       extra=extra, edges=edges, title=title)


__all__ = ["BACKGROUND", "Buffers", "PointSet", "RegionColors", "RenderStyle", "ScalarColors", "VertexColors",
           "encode_png", "fit_camera", "point_visibility", "polygon_edges", "rasterize", "render_buffers",
           "render_face", "render_mesh", "vertex_normals", "write_png"]
