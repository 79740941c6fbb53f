"""Blend-shape rigs and weight curves (pure numpy; no pxr, no cv2).

- :mod:`~usdface.blendshape.rig` — :class:`BlendShapeRig` (neutral + named offsets), the NPZ and
  OBJ-folder loaders, :func:`marker_basis` (what each shape does to each bound marker);
- :mod:`~usdface.blendshape.mirror` — left/right pairs that get the symmetry prior;
- :mod:`~usdface.blendshape.solver` — :class:`CurveSolver`: the whole-take weight solve;
- :mod:`~usdface.blendshape.take` — one capture + binding + rig -> curves and deliverables;
- :mod:`~usdface.blendshape.posefit` — the solve corrects the head stabilisation and the rest pose;
- :mod:`~usdface.blendshape.curves` — resampling to film rates, key reduction;
- :mod:`~usdface.blendshape.csvio` — the curves CSV and the Live Link Face CSV;
- :mod:`~usdface.blendshape.transfer` — a generic rig carried onto a face without one;
- :mod:`~usdface.blendshape.synthetic` — takes with exact truth (tests, benchmarks).

USD input and output live in :mod:`usdface.usd.blendshape_layer`; the commands in
:mod:`usdface.processors.solve` and :mod:`usdface.processors.shapes`.
"""
from .mirror import find_mirror_pairs
from .rig import BlendShapeRig, load_mesh_folder_rig, load_npz_rig, marker_basis
from .solver import CurveSolution, CurveSolver, solve_curves
from .take import deliverable_curves, solve_take

__all__ = ["BlendShapeRig", "CurveSolution", "CurveSolver", "deliverable_curves", "find_mirror_pairs",
           "load_mesh_folder_rig", "load_npz_rig", "marker_basis", "solve_curves", "solve_take"]
