"""The report's pictures: a contact sheet of the take, the binding on the face, maps of the largest
displacement and of the hybrid weight, rendered by the preview renderer (JPEG bytes)."""
from __future__ import annotations

import numpy as np

from ..preview import (PointSet, RegionColors, RenderStyle, ScalarColors, contact_sheet, encode_jpeg, fit_camera,
                       render_mesh)

__all__ = ["binding_picture", "contact_frames", "contact_sheet_picture", "map_picture", "shot_pictures", "thumbnail"]


def contact_frames(d, count: int = 8) -> list[int]:
    """Indices of ``count`` frames spread over the take, the frame of largest displacement among them."""
    n = d.n_frames
    pick = set(np.linspace(0, n - 1, min(count, n)).round().astype(int).tolist())
    if d.displacement is not None and len(pick) > 1:
        peak = int(np.argmax(d.displacement[:, 3]))
        if peak not in pick:
            nearest = min(pick - {0, n - 1} or pick, key=lambda i: abs(i - peak))
            pick.discard(nearest)
            pick.add(peak)
    return sorted(pick)


def contact_sheet_picture(d, reader, *, cell: int = 300, count: int = 8) -> tuple[bytes, list[int]]:
    """PNG of ``count`` frames coloured by displacement on one scale, and the time codes shown."""
    idx = contact_frames(d, count)
    times = d.frames[idx]
    pts = reader.face_points(times, stabilized=True)  # the transfer's deformation, head motion removed
    rest = reader.rest_points
    disp = np.linalg.norm(pts - rest, axis=2)
    top = float(disp.max()) or 1.0
    cam = fit_camera([pts, rest], size=(cell, cell), colorbar=True)
    cells = [render_mesh(pts[k], reader.triangles, camera=cam, style=RenderStyle(supersample=2),
                         colors=ScalarColors(disp[k], range=(0.0, top), label=f"displacement ({d.units})"))
             for k in range(len(idx))]
    peak = int(np.argmax(d.displacement[:, 3])) if d.displacement is not None else -1
    caps = [f"frame {int(t)}" + ("  (largest)" if i == peak else "") for i, t in zip(idx, times)]
    sheet = contact_sheet(cells, caps, columns=4,
                          title=f"{d.name}: displacement from rest (head motion removed), one colour scale")
    return encode_jpeg(sheet), [int(t) for t in times]


def binding_picture(d, reader, *, size: int = 900) -> bytes | None:
    """The rest face with its regions, the markers' bound points and their names (label layout)."""
    bound = reader.bound_points(reader.rest_points[None])
    if bound is None:
        return None
    img = render_mesh(reader.rest_points, reader.triangles, style=RenderStyle(size=(size, size), supersample=2),
                      colors=RegionColors(reader.regions) if reader.regions else None,
                      extra=PointSet(bound[0], labels=list(reader.marker_names) or None, name="bound points"),
                      title=f"{d.name}: binding")
    return encode_jpeg(img)


def map_picture(reader, values, *, label: str, title: str, size: int = 520, vrange=None) -> bytes:
    """The rest face coloured by a per-vertex value (largest displacement, hybrid weight...)."""
    img = render_mesh(reader.rest_points, reader.triangles, style=RenderStyle(size=(size, size), supersample=2),
                      colors=ScalarColors(values, range=vrange, label=label), title=title)
    return encode_jpeg(img)


def thumbnail(d, reader, *, size: int = 200) -> bytes:
    """A small picture of the frame of largest displacement (batch tables)."""
    k = int(np.argmax(d.displacement[:, 3])) if d.displacement is not None else 0
    pts = reader.face_points([d.frames[k]], stabilized=True)[0]
    disp = np.linalg.norm(pts - reader.rest_points, axis=1)
    img = render_mesh(pts, reader.triangles, style=RenderStyle(size=(size, size), supersample=2, legend=False),
                      colors=ScalarColors(disp))
    return encode_jpeg(img)


def shot_pictures(d, reader) -> dict:
    """The pictures of a shot's section (JPEG bytes): ``contact`` (picture, time codes),
    ``binding``, ``vertexMax`` (largest displacement of each vertex) and ``hybrid`` (the hybrid
    weight), each None or absent when the shot lacks what it shows."""
    pics = {"contact": contact_sheet_picture(d, reader), "binding": binding_picture(d, reader)}
    if d.vertex_max is not None:
        pics["vertexMax"] = map_picture(reader, d.vertex_max, label=f"largest displacement ({d.units})",
                                        title=f"{d.name}: largest displacement")
    if reader.hybrid_weight is not None:
        pics["hybrid"] = map_picture(reader, np.asarray(reader.hybrid_weight), label="hybrid weight w",
                                     title=f"{d.name}: hybrid weight", vrange=(0.0, 1.0))
    return pics
