"""A face ready to simulate, and what a simulation reports.

- :func:`build_simulator`: the tissue model of a mesh, the rig's compiled muscles and jaw, and the
  :class:`~usdface.tissue.integrators.Simulator` driving them (`muscles` builds one to check that
  a rig acts on its face, `simulate` and `fit-muscles` to run it);
- :func:`tissue_options`: the model's options from a rig's recorded settings and overrides;
- :func:`volume_stats`, :func:`landmark_vertices`: the volume change and the landmark
  displacements `simulate` reports.
"""
from __future__ import annotations

import numpy as np

__all__ = ["REPORT_LANDMARKS", "tissue_options", "build_simulator", "volume_stats", "landmark_vertices"]

#: landmark displacements reported by ``simulate``
REPORT_LANDMARKS = ("mouthCorner_L", "mouthCorner_R", "upperLip", "lowerLip", "browInner_L", "browInner_R",
                    "browOuter_L", "browOuter_R", "eyeTop_L", "eyeTop_R", "chin", "noseTip")


def tissue_options(rig_tissue: dict | None = None, overrides: dict | None = None):
    """:class:`~usdface.tissue.model.TissueOptions` from a rig's recorded settings, then overrides.

    Parameters
    ----------
    rig_tissue : dict, optional
        ``{option name: value}`` recorded with the rig (:attr:`MuscleRig.tissue`).
    overrides : dict, optional
        ``{option name: value}`` that win over the rig's.

    Raises
    ------
    OptionError
        An unknown option name or a value out of range (named).
    """
    from .model import TissueOptions

    return TissueOptions().replace(**(rig_tissue or {})).replace(**(overrides or {}))


def build_simulator(mesh, regions, rig, *, integrator="implicit", dt=None, tissue=None, backend="auto"):
    """The Simulator of ``rig`` acting on ``mesh``: its tissue model, jaw and compiled muscles.

    Parameters
    ----------
    mesh : FaceMesh
        The face (units set).
    regions : list of Region
        Its hole regions (mouth, eyes: they loosen the lips and eyelids).
    rig : MuscleRig
        Muscles, jaw and recorded tissue settings, in the mesh's units.
    integrator : {"explicit", "symplectic", "implicit"}
    dt : float, optional
        Integration step (s); default: the integrator's (:meth:`Simulator.default_step`).
    tissue : dict, optional
        Tissue option overrides (:func:`tissue_options`).
    backend : {"auto", "numba", "numpy"}

    Raises
    ------
    MeshError, InputError, OptionError
        The mesh cannot carry the model, a muscle is far from the face or has an empty zone
        (named), or an option is out of range.
    """
    from .integrators import Simulator
    from .model import build_tissue_model
    from .muscles import compile_muscles

    opts = tissue_options(rig.tissue, tissue)
    model = build_tissue_model(mesh, opts, regions=regions)
    jaw = rig.jaw_for(model.mesh, regions)
    muscles = compile_muscles(model, rig.muscles, jaw=jaw)
    return Simulator(model, muscles, jaw=jaw, integrator=integrator, dt="auto" if dt is None else dt, backend=backend)


def landmark_vertices(mesh, rig) -> dict:
    """``{landmark: vertex index}``: the mesh vertex nearest each of the rig's
    :data:`REPORT_LANDMARKS`."""
    from scipy.spatial import cKDTree

    tree = cKDTree(mesh.points)
    return {k: int(tree.query(v)[1]) for k, v in rig.landmarks.items() if k in REPORT_LANDMARKS}


def volume_stats(sim) -> dict:
    """Relative volume change ``(V - V0) / V0`` statistics of the current state.

    ``skin``: the epidermis-fascia prisms where the tissue has its full depth; ``element``: the
    whole three-layer elements where the tissue is also bound to the bone (attachment 1);
    ``all``: every element, including the thinned slivers at the lip and eyelid rims whose tiny
    rest volume makes relative changes large. Folded faces (inverted at rest) are left out.

    Returns
    -------
    dict
        ``{"skin" | "element" | "all": {"min", "max", "p99", "maxAbs": float (fractions),
        "count": int}}``.
    """
    model = sim.model
    t = model.n_elements
    pv = sim.prism_volume_change()
    ev = sim.volume_change()
    ok = np.ones(t, bool)
    if model.folded_faces.size:
        ok &= ~np.isin(model.mesh.triangle_faces(), model.folded_faces)
    full = ok & (model.depth[model.triangles].min(axis=1) >= 1)
    bound = full & (model.attachment[model.triangles].min(axis=1) >= 0.999)

    def st(v):
        a = np.abs(v)
        return {"min": float(v.min()), "max": float(v.max()), "p99": float(np.percentile(a, 99)),
                "maxAbs": float(a.max()), "count": int(v.size)}

    return {"skin": st(pv[:t][full]), "element": st(ev[bound]), "all": st(ev[ok])}
