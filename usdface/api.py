"""usdface's Python API: the stage processors for pipeline scripts and a DCC's Python.

Every processor of the command line is here, taking the same options objects
(:mod:`usdface.options`) and working on in-memory stages and layers as well as on files:

- inputs may be a file path, an ``Sdf.Layer`` or a ``Usd.Stage`` (a DCC's open scene, or a stage
  composing the mesh, the capture and what earlier steps authored);
- the output is authored into ``into``: an ``Sdf.Layer``, or a ``Usd.Stage`` (its edit target's
  layer). By default a new anonymous layer is made. Nothing touches the disk unless you pass a
  file path as ``into``;
- the processor's opinions are merged into ``into`` only when it succeeds: an error raises a
  :class:`~usdface.UsdFaceError` (naming the prim, marker or option at fault) and leaves ``into``
  exactly as it was.

Each call returns a :class:`Result`: the layer written (``.layer``) and the processor's summary
(``.summary``, the same dict ``usdface COMMAND --json`` prints).

Example — the main job in memory, then on files::

    import usdface
    from pxr import Usd
    from usdface import api
    from usdface.options import CaptureOptions, DistanceOptions, TransferOptions, RunOptions

    mesh = api.import_mesh("sample_assets/meshes/makehuman_hm08_face_cm.obj").layer
    capture = api.import_capture("sample_assets/capture/JawMoCap.ma", CaptureOptions(stabilize="auto",
                                                                                    trim=(0, 300))).layer
    stage = api.new_stage(mesh)          # in memory; the mesh's units, up axis and default prim
    api.bind(stage, capture, layout="sample_assets/layouts/makehuman_hm08_face.layout.json", into=stage)
    api.distances(stage, DistanceOptions(method="hybrid"), into=stage)
    anim = api.transfer(stage, TransferOptions(), into=stage).summary   # points authored into the stage

    api.run("face.obj", "take.ma", "out/jaw", RunOptions(layout="face.layout.json"))   # files, as `usdface run`

Inside a DCC: usdface needs usd-core's ``pxr`` or a DCC's own USD build of a compatible version,
with usdface's schemas registered before the first stage is opened (``PXR_PLUGINPATH_NAME`` set
to ``usdface plugin-path``; see the README's DCC section for what works in Blender's Python).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .errors import OptionError, UsdFaceError
from .options import (BindOptions, CaptureOptions, DistanceOptions, PlayblastOptions, RunOptions, SkelOptions,
                      SolveOptions, TransferOptions)

__all__ = ["Result", "new_stage", "import_mesh", "import_capture", "bind", "distances", "transfer", "skel",
           "solve", "run", "evaluator", "playblast", "report", "check", "UsdFaceError", "CaptureOptions",
           "BindOptions", "DistanceOptions", "TransferOptions", "SkelOptions", "SolveOptions", "RunOptions",
           "PlayblastOptions"]


@dataclass
class Result:
    """What a processor wrote: the layer (or file path) and its summary dict."""

    layer: object
    summary: dict = field(repr=False)


def _into(into, name: str):
    """The target: a new anonymous layer by default; a path, layer or stage as given."""
    if into is None:
        from pxr import Sdf

        return Sdf.Layer.CreateAnonymous(f"{name}.usda")
    return into


def _result(target, summary: dict) -> Result:
    from .usd.layers import is_in_memory, target_layer

    layer = target_layer(target) if is_in_memory(target) else target
    return Result(layer, {k: v for k, v in summary.items() if not k.startswith("_")})


def _options(options, cls):
    if options is None:
        return cls()
    if isinstance(options, cls):
        return options
    if isinstance(options, RunOptions):
        return options.group(cls)
    if isinstance(options, dict):
        return cls.from_mapping(options, what=cls.__name__)
    raise OptionError(f"options: expected a {cls.__name__} (usdface.options); got {type(options).__name__}")


def new_stage(*layers):
    """An in-memory stage composing ``layers`` (strongest first, as sublayers) that carries the
    metadata usdface needs and a bare stage lacks (root-layer metadata is not inherited from
    sublayers): the first layer's units, up axis and default prim, and the rate and time range of
    the first layer that has them."""
    from .usd.layers import new_stage as make

    return make(layers)


def import_mesh(source, *, units: str | None = None, up_axis: str = "Y", into=None) -> Result:
    """A mesh (OBJ/PLY/STL/OFF file, USD file, layer or stage) as a mesh layer: ``/Face/Geom`` with
    its hole regions (outer border, mouth, eyes)."""
    from .processors.import_mesh import import_mesh as run_import

    target = _into(into, "mesh")
    return _result(target, run_import(source, target, units=units, up_axis=up_axis))


def import_capture(source, options: CaptureOptions | None = None, *, into=None) -> Result:
    """A capture (Maya ASCII, C3D, TRC, CSV file, or a capture layer / stage) as a capture layer
    (``/Capture/Markers``), conditioned as ``options`` say (stabilise, fill gaps, trim...)."""
    from .processors.import_capture import import_capture as run_import

    target = _into(into, "capture")
    return _result(target, run_import(source, target, **_options(options, CaptureOptions).to_dict()))


def bind(stage, capture=None, *, layout=None, auto: bool = False, options: BindOptions | None = None,
         into=None) -> Result:
    """Bind the capture's markers to the face in ``stage`` (from a marker layout JSON, or
    ``auto``); ``capture`` defaults to ``stage`` itself (a scene holding both)."""
    from .processors.bind import bind as run_bind

    target = _into(into, "binding")
    return _result(target, run_bind(stage, stage if capture is None else capture, target, layout=layout,
                                    auto=auto, **_options(options, BindOptions).to_dict()))


def distances(stage, options: DistanceOptions | None = None, *, binding=None, into=None) -> Result:
    """Distance matrices (Euclidean / geodesic / hybrid) of the face in ``stage`` to its bound
    markers; ``binding`` defaults to ``stage`` (where `bind` authored)."""
    from .processors.distances import distances as run_distances

    o = _options(options, DistanceOptions)
    target = _into(into, "analysis")
    return _result(target, run_distances(stage, stage if binding is None else binding, target, method=o.method,
                                         backend=o.backend, region_radius_cm=o.region_radius, sigma_cm=o.sigma,
                                         threshold=o.threshold, pin_border=o.pin_border, components=o.components))


def transfer(stage, options: TransferOptions | None = None, *, capture=None, binding=None, analysis=None,
             method: str | None = None, head_motion: bool = True, into=None) -> Result:
    """RBF transfer of the capture's marker motion to every vertex: time-sampled points (and the
    head motion on the face's root prim). ``capture``, ``binding`` and ``analysis`` default to
    ``stage``; ``method`` picks a distance matrix when the analysis holds several."""
    from .processors.transfer import transfer as run_transfer

    target = _into(into, "anim")
    return _result(target, run_transfer(stage, stage if capture is None else capture,
                                        stage if binding is None else binding,
                                        stage if analysis is None else analysis, target, method=method,
                                        head_motion=head_motion, **_options(options, TransferOptions).to_dict()))


def skel(stage, options: SkelOptions | None = None, *, transfer_options: TransferOptions | None = None,
         capture=None, binding=None, analysis=None, method: str | None = None, head_motion: bool = True,
         into=None) -> Result:
    """UsdSkel keyframes reproducing the transfer: a skeleton with a joint per marker, DCC-safe skin
    weights (``options``: :class:`usdface.options.SkelOptions`), corrective shapes and the head
    motion on the SkelRoot. ``capture``, ``binding`` and ``analysis`` default to ``stage``. The
    UsdSkel check of the written layer (`usdface skel`'s) needs the mesh composed with it, so it
    runs here only when ``into`` is a file path."""
    from .processors.skel import skel as run_skel
    from .usd.layers import is_in_memory

    target = _into(into, "skel")
    o = _options(options, SkelOptions)
    return _result(target, run_skel(stage, stage if capture is None else capture, stage if binding is None else binding,
                                    stage if analysis is None else analysis, target, method=method,
                                    head_motion=head_motion, verify=not is_in_memory(target), **o.to_dict(),
                                    **_options(transfer_options, TransferOptions).to_dict()))


def solve(mesh, capture, output, options: RunOptions | dict | None = None, *, csv=None, livelink=None,
          corrective=None) -> dict:
    """Blend-shape weight curves on a rig, on files, exactly as `usdface solve` (``options``: the
    capture, binding and solve fields of :class:`usdface.options.RunOptions`; ``mesh`` a USD mesh
    with blend shapes, or a neutral with ``options.shapes``). Returns the summary."""
    from .processors.solve import solve as run_solve

    o = options if isinstance(options, RunOptions) else RunOptions() if options is None else \
        RunOptions.from_mapping(options, what="solve options")
    summary = run_solve(mesh, capture, output, shapes=o.shapes, layout=o.layout, auto=bool(o.auto), csv=csv,
                        livelink=livelink, livelink_fill_zeros=o.livelink_fill_zeros, corrective=corrective,
                        fps=o.fps, key_tolerance=o.key_tolerance, head_motion=o.head_motion, retarget=o.retarget,
                        mesh_units=o.mesh_units, **o.group(CaptureOptions).to_dict(), **o.solver_kwargs())
    return {k: v for k, v in summary.items() if not k.startswith("_")}


def run(mesh, capture, out_dir, options: RunOptions | dict | None = None, *, cache=None) -> dict:
    """The main job on files, exactly as `usdface run` (returns its summary)."""
    from .processors.run import run as run_job

    summary = run_job(mesh, capture, out_dir, options, cache=cache)
    return {k: v for k, v in summary.items() if not k.startswith("_")}


def evaluator(source, *, mesh: str | None = None):
    """The animated face of any deliverable (file path, layer or stage): a
    :class:`usdface.usd.evaluate.FaceEvaluator` giving world- or mesh-space points at any time
    code, whatever moves the face (point caches, UsdSkel skinning and blend shapes, the head
    motion on /Face)::

        ev = api.evaluator("out/jaw/shot_skel.usda")
        points = ev.points(441)                   # (N, 3), world space, the stage's units
    """
    from .usd.evaluate import FaceEvaluator
    from .usd.layers import describe, open_stage

    return FaceEvaluator(open_stage(source, what="file"), mesh=mesh, source=describe(source))


def playblast(shot, output, options=None) -> dict:
    """Render a shot (file) frame by frame into an H.264 movie, exactly as `usdface playblast`;
    ``options`` is a :class:`usdface.options.PlayblastOptions` (or a dict of its fields).
    Needs the ``media`` extra."""
    from .processors.playblast import playblast as render

    return {k: v for k, v in render(shot, output, options).items() if not k.startswith("_")}


def report(outdir, output, *, playblast: bool | str = True) -> dict:
    """The offline HTML QC report of a run's folder, exactly as `usdface report` (``playblast``:
    render one, link an existing movie by path, or False for none)."""
    from .processors.report import report as build

    return {k: v for k, v in build(outdir, output, playblast=playblast).items() if not k.startswith("_")}


def check(target) -> list:
    """USD's validators and usdface's schema rules on a file, layer or stage; the findings
    (``severity``, ``code``, ``message``...) — errors have ``severity == "error"``."""
    from .usd.validation import check_layer

    return check_layer(target)
