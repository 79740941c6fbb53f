"""Muscle-driven layered tissue simulation (seed 001 §5): a physically based face.

- :mod:`~usdface.tissue.model` — the three-layer prism model of a face mesh (epidermis, fascia, bone
  nodes; springs on prism edges and cross-diagonals; per-layer stiffness; volume per prism):
  :func:`build_tissue_model`, :class:`TissueOptions`, :class:`TissueModel`; the surface it is
  built on in :mod:`~usdface.tissue.surface` (winding, normals, areas), the prisms' geometry and
  offset field in :mod:`~usdface.tissue.prisms`.
- :mod:`~usdface.tissue.forces` — the forces as numpy kernels (springs, biphasic, damping, volume
  preservation, skull contact, muscles); :mod:`~usdface.tissue._kernels` the same in numba.
- :mod:`~usdface.tissue.muscles` — linear (Waters) and sphincter muscles, the jaw:
  :class:`Muscle`, :class:`Jaw`, :func:`compile_muscles`.
- :mod:`~usdface.tissue.integrators` — :class:`Simulator` with explicit (the paper's), symplectic
  and implicit Euler (:mod:`~usdface.tissue.implicit`); :class:`DivergenceError`
  (:mod:`~usdface.tissue.divergence`).
- :mod:`~usdface.tissue.rig` — landmarks and the default rig of named muscles:
  :func:`default_rig`, :func:`face_landmarks`, :func:`warp_rig`, :class:`MuscleRig`.
- :mod:`~usdface.tissue.expressions` — presets and contraction timelines (JSON).
- :mod:`~usdface.tissue.animation` — driving a simulator through a timeline; :class:`ControlSamples`.
- :mod:`~usdface.tissue.simulation` — a face ready to simulate (:func:`build_simulator`) and what a
  simulation reports (:func:`volume_stats`).
- :mod:`~usdface.tissue.fit` — contractions fitted to marker motion (:class:`FitParameters`).
- :mod:`~usdface.tissue.pictures` — every preset's pose on faces, in one picture.

No pxr here: rig and animation layers are written by :mod:`usdface.usd.muscle_layer`, the
commands live in :mod:`usdface.processors.muscles`, :mod:`~usdface.processors.simulate` and
:mod:`~usdface.processors.fit_muscles`.
"""
from ..lazy import lazy_exports

#: time integrators of the simulator (:class:`Simulator`), named once: the options offer these
INTEGRATORS = ("explicit", "symplectic", "implicit")

#: public name -> submodule; loaded on first use, so that the command line (which only needs the
#: preset names) does not pay for the simulator and its numba kernels at start-up
_EXPORTS = {
    "PRESET_NAMES": "expressions", "PRESETS": "expressions", "Timeline": "expressions",
    "expression_timeline": "expressions", "preset_contractions": "expressions", "read_timeline": "expressions",
    "FitParameters": "fit", "FitResult": "fit", "LinearResponse": "fit", "capture_displacements": "fit",
    "fit_frames": "fit", "fit_sequence": "fit", "linear_response": "fit",
    "ControlSamples": "animation", "animate": "animation", "build_simulator": "simulation", "tissue_options": "simulation",
    "volume_stats": "simulation", "preset_contact_sheet": "pictures", "preset_poses": "pictures",
    "DivergenceError": "divergence", "EquilibriumReport": "integrators",
    "Simulator": "integrators",
    "TissueModel": "model", "TissueOptions": "model", "build_tissue_model": "model",
    "Jaw": "muscles", "Muscle": "muscles", "MuscleSet": "muscles", "compile_muscles": "muscles",
    "MuscleRig": "rig", "default_rig": "rig", "face_landmarks": "rig", "jaw_weights": "rig", "warp_rig": "rig",
}


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())


__all__ = [
    "INTEGRATORS", "PRESETS", "PRESET_NAMES", "ControlSamples", "DivergenceError", "EquilibriumReport",
    "FitParameters", "FitResult", "Jaw", "LinearResponse", "Muscle", "MuscleRig", "MuscleSet", "Simulator", "Timeline",
    "TissueModel", "TissueOptions", "animate", "build_simulator", "build_tissue_model", "capture_displacements",
    "compile_muscles", "default_rig", "expression_timeline", "face_landmarks", "fit_frames", "fit_sequence",
    "jaw_weights", "linear_response", "preset_contact_sheet", "preset_contractions", "preset_poses", "read_timeline",
    "tissue_options", "volume_stats", "warp_rig",
]
