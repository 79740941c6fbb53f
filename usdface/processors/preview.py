"""`usdface preview`: a software-rendered PNG of a layer at a frame, or a contact sheet."""
from __future__ import annotations

import numpy as np

from ..fileutil import refuse_overwriting_inputs
from ..errors import OptionError
from ..options import PreviewOptions
from ..registry import Result


def _scalars(scene, color, reference_points):
    if color == "displacement":
        return np.linalg.norm(scene.mesh.points - scene.rest_points, axis=1)
    if color == "error":
        return np.linalg.norm(scene.mesh.points - reference_points, axis=1)
    return None


def _render_one(scene, *, camera, color, reference_points, labels, title, scalar_range=None):
    from ..preview import PointSet, RegionColors, ScalarColors, render_mesh

    units = scene.mesh.units or "units"
    colors = None
    if color == "regions":
        colors = RegionColors(scene.regions) if scene.regions else None
    elif color == "displacement":
        colors = ScalarColors(_scalars(scene, color, None), range=scalar_range, label=f"displacement ({units})")
    elif color == "error":
        colors = ScalarColors(_scalars(scene, color, reference_points), range=scalar_range,
                              label=f"error vs reference ({units})")
    elif color == "hybrid-weight":
        if scene.hybrid_weight is None:
            raise OptionError("--color hybrid-weight: the file has no primvars:usdface:hybridWeight "
                              "(compute hybrid distances with `usdface distances --method hybrid`)")
        colors = ScalarColors(scene.hybrid_weight, range=(0.0, 1.0), label="hybrid weight w")
    markers = None
    if scene.markers is not None:
        markers = PointSet(scene.markers, labels=scene.marker_names if labels else None)
    bound = PointSet(scene.bound_points, name="bound points") if scene.bound_points is not None else None
    return render_mesh(scene.mesh.points, scene.mesh.triangles(), camera=camera, colors=colors, markers=markers,
                       extra=bound, title=title)


def preview(file, *, options: PreviewOptions, output) -> Result:
    """Render ``file`` at ``options.frame`` (or a contact sheet of ``options.frames``) to the PNG ``output``."""
    from ..preview import contact_sheet, fit_camera, write_png
    from ..usd.face_evaluator import FaceEvaluator
    from ..usd.layers import is_in_memory, open_stage
    from ..usd.scene import read_scene_frame

    path = file
    frame, frames, view, size, color = options.frame, options.frames, options.view, options.size, options.color
    reference, labels = options.reference, options.labels
    files = {"file": path, "--reference": reference}
    refuse_overwriting_inputs({"-o": output}, {k: v for k, v in files.items() if not is_in_memory(v)})
    if not str(output).lower().endswith(".png"):
        raise OptionError(f"-o {output}: expected a .png file")
    if color == "error" and reference is None:
        raise OptionError("--color error needs --reference LAYER (the points to compare against)")
    if size < 64 or size > 8192:
        raise OptionError(f"--size {size}: expected 64..8192 pixels")
    stage = open_stage(path, what="file")
    times = list(frames) if frames else [frame]
    if stage.HasAuthoredTimeCodeRange():
        lo, hi = stage.GetStartTimeCode(), stage.GetEndTimeCode()
        outside = [t for t in times if t is not None and not lo <= t <= hi]
        if outside:
            raise OptionError(f"--frame {outside[0]:g}: outside the layer's time range {lo:g}..{hi:g}")
    evaluator = FaceEvaluator(stage, source=str(path))  # skinning and blend shapes as UsdSkel evaluates them
    scenes = [read_scene_frame(path, time=t, evaluator=evaluator) for t in times]
    cell = size if len(scenes) == 1 else max(256, size // min(len(scenes), 4))
    everything = [s.mesh.points for s in scenes] + [scenes[0].rest_points]
    camera = fit_camera(everything, view=view, size=(cell, cell), colorbar=color not in ("regions", "none"),
                        title_lines=2)
    images, captions = [], []
    name = str(path).rsplit("/", 1)[-1]
    refs = [None] * len(scenes)
    if reference is not None:
        ref = FaceEvaluator.open(reference, what="--reference")
        if ref.n_points != evaluator.n_points:
            raise OptionError(f"--reference {reference}: its face mesh has {ref.n_points} points, {name} has "
                              f"{evaluator.n_points}")
        refs = [ref.points(s.time) for s in scenes]
    shared = None
    if color in ("displacement", "error"):  # one colour scale for every frame of a sheet
        top = max(float(_scalars(s, color, r).max()) for s, r in zip(scenes, refs))
        shared = (0.0, top if top > 0 else 1.0)
    for s, ref in zip(scenes, refs):
        title = f"{name}  t={s.time:g}" if len(scenes) == 1 else ""
        images.append(_render_one(s, camera=camera, color=color, reference_points=ref, labels=labels, title=title,
                                  scalar_range=shared))
        captions.append(f"t = {s.time:g}")
    image = images[0] if len(images) == 1 else contact_sheet(images, captions, title=f"{name}  ({color})")
    write_png(output, image)
    summary = {"output": str(output), "frames": [s.time for s in scenes], "view": view, "color": color}
    return Result(files={"output": str(output)}, summary=summary,
                  text=[f"wrote {output} ({image.shape[1]}x{image.shape[0]}, {len(scenes)} frame(s), {color})"])
