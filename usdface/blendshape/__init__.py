"""Blend-shape rigs and weight curves (pure numpy; no pxr, no cv2).

- :mod:`~usdface.blendshape.rig` — :class:`BlendShapeRig` (neutral + named offsets), the NPZ and
  OBJ-folder loaders, :func:`marker_basis` (what each shape does to each bound marker);
- :mod:`~usdface.blendshape.mirror` — left/right pairs that get the symmetry prior;
- :mod:`~usdface.blendshape.parameters` — the solve's settings and defaults (what the options offer);
- :mod:`~usdface.blendshape.solver` — :class:`CurveSolver`: the whole-take weight solve;
- :mod:`~usdface.blendshape.take` — one capture + binding + rig -> curves and deliverables;
- :mod:`~usdface.blendshape.report` — the summary and printed lines of a solved take;
- :mod:`~usdface.blendshape.corrective` — the rig's pose plus the RBF transfer of its residual;
- :mod:`~usdface.blendshape.posefit` — the solve corrects the head stabilisation and the rest pose;
- :mod:`~usdface.blendshape.curves` — resampling to film rates, key reduction;
- :mod:`~usdface.blendshape.csvio` — the curves CSV and the Live Link Face CSV;
- :mod:`~usdface.blendshape.rig_transfer` — a generic rig carried onto a face without one;
- :mod:`~usdface.blendshape.synthetic` — takes with exact truth (tests, benchmarks).

USD input and output live in :mod:`usdface.usd.blendshape_layer`, :mod:`usdface.usd.rig_inputs`
and :mod:`usdface.usd.curves_files`; the commands in :mod:`usdface.pipeline.solve`,
:mod:`usdface.processors.blendshapes` and :mod:`usdface.processors.shapes_transfer`. Names load on
first use (the command line reads only :mod:`~usdface.blendshape.parameters` at start-up).
"""
from ..lazy import lazy_exports

#: public name -> submodule, loaded on first use
_EXPORTS = {
    "find_mirror_pairs": "mirror", "BlendShapeRig": "rig", "load_mesh_folder_rig": "rig", "load_npz_rig": "rig",
    "marker_basis": "rig", "CurveSolution": "solver", "CurveSolver": "solver", "solve_curves": "solver",
    "SolverParameters": "parameters", "TakeParameters": "parameters", "DeliveryParameters": "parameters",
    "deliverable_curves": "take", "solve_take": "take",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())

__all__ = sorted(_EXPORTS)
