"""`usdface preview`: software rendering of meshes, regions, scalar maps and markers to PNG.

No GPU and no pxr: pure functions over numpy arrays returning ``(H, W, 3) uint8`` BGR images
(OpenCV order); colours given as arguments are RGB 0..255.

Main entry points
-----------------
- :class:`Camera` — ``Camera.fit(points, view="front"|"three-quarter"|"side"|"turntable"|yaw, size=(512, 512),
  projection="orthographic"|"perspective")``; fit once on all frames to share a framing.
  :func:`fit_camera` does the same and leaves room for the title and colour bar.
- :func:`render_mesh` — ``render_mesh(points, triangles, *, camera=None, style=RenderStyle(...),
  colors=RegionColors(regions) | ScalarColors(values, range, label) | VertexColors(rgb),
  markers=PointSet(points, labels, color, name), extra=PointSet(...), edges=None, title="")``:
  :class:`RenderStyle` (frozen) is how the picture looks, the other arguments what it shows.
- :func:`render_face` — the same for a :class:`usdface.mesh.FaceMesh` and its regions.
- :func:`contact_sheet`, :func:`render_sequence` — grids of frames with captions, one camera
  (:class:`SheetLayout`).
- :func:`write_png` — atomic PNG writer.
- Lower level: :func:`rasterize`, :func:`render_buffers`, :func:`point_visibility`,
  :func:`polygon_edges`, :func:`apply_colormap`, :func:`colormap_lut`.
"""
from ..lazy import lazy_exports

#: public name -> submodule, loaded on first use
_EXPORTS = {
    "Camera": "camera", "TURNTABLE_SWING": "camera", "VIEWS": "camera", "VIEW_CHOICES": "camera",
    "view_yaw": "camera", "COLORMAPS": "colormap", "apply_colormap": "colormap", "colormap_lut": "colormap",
    "region_palette": "colormap", "encode_jpeg": "png", "Buffers": "render", "encode_png": "render",
    "fit_camera": "render", "point_visibility": "render", "polygon_edges": "render", "rasterize": "render",
    "render_buffers": "render", "render_face": "render", "render_mesh": "render", "vertex_normals": "render",
    "write_png": "render", "contact_sheet": "sheet", "render_sequence": "sheet", "SheetLayout": "sheet",
    "RenderStyle": "style", "RegionColors": "style", "ScalarColors": "style", "VertexColors": "style",
    "PointSet": "style", "SHADINGS": "style",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())

__all__ = ["COLORMAPS", "SHADINGS", "TURNTABLE_SWING", "VIEW_CHOICES", "VIEWS", "Buffers", "Camera", "PointSet",
           "RegionColors", "RenderStyle", "ScalarColors", "SheetLayout", "VertexColors", "apply_colormap",
           "colormap_lut", "contact_sheet", "encode_jpeg", "encode_png", "fit_camera", "point_visibility",
           "polygon_edges", "rasterize", "region_palette", "render_buffers", "render_face", "render_mesh",
           "render_sequence", "vertex_normals", "view_yaw", "write_png"]
