"""`usdface preview`: software rendering of meshes, regions, scalar maps and markers to PNG.

No GPU and no pxr: pure functions over numpy arrays returning ``(H, W, 3) uint8`` BGR images
(OpenCV order); colours given as arguments are RGB 0..255.

Main entry points
-----------------
- :class:`Camera` — ``Camera.fit(points, view="front"|"three-quarter"|"side"|"turntable"|yaw, size=(512, 512),
  projection="orthographic"|"perspective")``; fit once on all frames to share a framing.
  :func:`fit_camera` does the same and leaves room for the title and colour bar.
- :func:`render_mesh` — ``render_mesh(points, triangles, *, camera=None, view="front",
  region_colors=None, scalars=None, markers=None, extra_points=None, edges=None, title="", ...)``.
- :func:`render_face` — the same for a :class:`usdface.mesh.FaceMesh` and its regions.
- :func:`contact_sheet`, :func:`render_sequence` — grids of frames with captions, one camera.
- :func:`write_png` — atomic PNG writer.
- Lower level: :func:`rasterize`, :func:`render_buffers`, :func:`point_visibility`,
  :func:`polygon_edges`, :func:`apply_colormap`, :func:`colormap_lut`.
"""
from .camera import TURNTABLE_SWING, VIEW_CHOICES, VIEWS, Camera, view_yaw
from .colormap import COLORMAPS, apply_colormap, colormap_lut, region_palette
from .png import encode_jpeg
from .render import (Buffers, encode_png, fit_camera, point_visibility, polygon_edges, rasterize, render_buffers, render_face,
                     render_mesh, vertex_normals, write_png)
from .sheet import contact_sheet, render_sequence

__all__ = ["COLORMAPS", "TURNTABLE_SWING", "VIEW_CHOICES", "VIEWS", "Buffers", "Camera", "apply_colormap", "colormap_lut", "contact_sheet", "encode_jpeg", "encode_png", "fit_camera",
           "point_visibility", "polygon_edges", "rasterize", "region_palette", "render_buffers",
           "render_face", "render_mesh", "render_sequence", "vertex_normals", "view_yaw", "write_png"]
