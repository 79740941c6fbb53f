"""Muscle-driven layered tissue simulation (seed 001 §5): a physically based face.

- :mod:`~usdface.tissue.model` — the three-layer prism model of a face mesh (epidermis, fascia, bone
  nodes; springs on prism edges and cross-diagonals; per-layer stiffness; volume per prism):
  :func:`build_tissue_model`, :class:`TissueOptions`, :class:`TissueModel`.
- :mod:`~usdface.tissue.forces` — the forces as numpy kernels (springs, biphasic, damping, volume
  preservation, skull contact, muscles); :mod:`~usdface.tissue._kernels` the same in numba.
- :mod:`~usdface.tissue.muscles` — linear (Waters) and sphincter muscles, the jaw:
  :class:`Muscle`, :class:`Jaw`, :func:`compile_muscles`.
- :mod:`~usdface.tissue.integrators` — :class:`Simulator` with explicit (the paper's), symplectic
  and implicit Euler; :class:`DivergenceError`.
- :mod:`~usdface.tissue.rig` — landmarks and the default rig of named muscles:
  :func:`default_rig`, :func:`face_landmarks`, :func:`warp_rig`, :class:`MuscleRig`.
- :mod:`~usdface.tissue.expressions` — presets and contraction timelines (JSON).
- :mod:`~usdface.tissue.animate` — driving a simulator through a timeline.
- :mod:`~usdface.tissue.fit` — contractions fitted to marker motion.

No pxr here: rig and animation layers are written by :mod:`usdface.usd.muscle_layer`, the
commands live in :mod:`usdface.processors.tissue`.
"""
from .animate import animate
from .expressions import PRESET_NAMES, PRESETS, Timeline, expression_timeline, preset_contractions, read_timeline
from .fit import FitResult, LinearResponse, fit_frames, fit_sequence, linear_response
from .integrators import INTEGRATORS, DivergenceError, EquilibriumReport, Simulator
from .model import TissueModel, TissueOptions, build_tissue_model
from .muscles import Jaw, Muscle, MuscleSet, compile_muscles
from .rig import MuscleRig, default_rig, face_landmarks, jaw_weights, warp_rig

__all__ = [
    "INTEGRATORS", "PRESETS", "PRESET_NAMES", "DivergenceError", "EquilibriumReport", "FitResult", "Jaw",
    "LinearResponse", "Muscle", "MuscleRig", "MuscleSet", "Simulator", "Timeline", "TissueModel", "TissueOptions",
    "animate", "build_tissue_model", "compile_muscles", "default_rig", "expression_timeline", "face_landmarks",
    "fit_frames", "fit_sequence", "jaw_weights", "linear_response", "preset_contractions", "read_timeline",
    "warp_rig",
]
