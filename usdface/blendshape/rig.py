"""A blend-shape rig in memory: a neutral mesh and named per-vertex offsets (pure numpy, no pxr).

Rigs come in the forms studios have (the USD form is read by
:mod:`usdface.usd.blendshape_layer`):

- an ``.npz`` with ``names[K]``, ``deltas[K, N, 3]`` and optionally ``neutral[N, 3]``, offsets in
  the mesh's units (the layout of ``sample_assets/meshes/makehuman_hm08_face_units_cm.npz``);
- a folder of same-topology meshes ``<shape>.obj`` (or any mesh suffix usdface reads) beside a
  neutral mesh: each shape's offsets are its points minus the neutral's.

A rig is checked once, when it is made: unique names, finite offsets, one topology, and (when
given a mesh) a neutral that matches the mesh's points.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import FormatError, InputError, MeshError, list_names
from ..model.mesh import Binding, FaceMesh

__all__ = ["BlendShapeRig", "load_npz_rig", "load_mesh_folder_rig", "check_neutral", "marker_basis",
           "NEUTRAL_TOLERANCE"]

#: a neutral may differ from the mesh's points by this fraction of the mesh's bounding-box diagonal
#: (float32 storage of either; the MakeHuman NPZ differs from its OBJ by 4e-6 cm, 1.5e-7 of 25 cm)
NEUTRAL_TOLERANCE = 1e-5


@dataclass(frozen=True, eq=False)
class BlendShapeRig:
    """Named blend shapes over one neutral mesh.

    Attributes
    ----------
    names : tuple of str, length K
        Shape names, unique, in the rig's order (the order of every weight array).
    deltas : ndarray, shape (K, N, 3), float64
        Offset of every vertex at weight 1, mesh units. ``neutral + sum_k w_k deltas[k]`` is the
        posed mesh (linear blend shapes, UsdSkel's and every DCC's model).
    mesh : FaceMesh
        The neutral mesh (topology, UVs, units, points = the neutral).
    source : str
        Where the shapes came from (file or folder), for messages.
    notes : tuple of str
        What was done on reading (e.g. in-between shapes dropped), for the summary.
    """

    names: tuple[str, ...]
    deltas: np.ndarray
    mesh: FaceMesh
    source: str = ""
    notes: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.names)
        object.__setattr__(self, "names", names)
        where = f" {self.source}" if self.source else ""
        seen, dups = set(), []
        for n in names:
            if n in seen:
                dups.append(n)
            seen.add(n)
        if dups:
            raise FormatError(f"blend shapes{where}: duplicate shape names {list_names(sorted(set(dups)))}; "
                              "every shape needs its own name")
        empty = [n for n in names if not n]
        if empty:
            raise FormatError(f"blend shapes{where}: a shape has an empty name")
        d = np.asarray(self.deltas, dtype=np.float64)
        n_points = self.mesh.n_points
        if d.ndim != 3 or d.shape[0] != len(names) or d.shape[2] != 3:
            raise FormatError(f"blend shapes{where}: offsets must have shape (K={len(names)}, N, 3); got {d.shape}")
        if d.shape[1] != n_points:
            raise MeshError(f"blend shapes{where}: offsets for {d.shape[1]} vertices, the neutral mesh "
                            f"{self.mesh.source or self.mesh.name} has {n_points}")
        bad = [names[k] for k in np.flatnonzero(~np.isfinite(d).all(axis=(1, 2)))]
        if bad:
            raise FormatError(f"blend shapes{where}: NaN or infinite offsets in shape(s) {list_names(bad)}")
        object.__setattr__(self, "deltas", d)
        object.__setattr__(self, "notes", tuple(self.notes))

    # -- shape -----------------------------------------------------------------------------------
    @property
    def n_shapes(self) -> int:
        return len(self.names)

    @property
    def n_points(self) -> int:
        return self.mesh.n_points

    @property
    def neutral(self) -> np.ndarray:
        """(N, 3) float64 neutral points (the mesh's)."""
        return self.mesh.points

    @property
    def units(self) -> str | None:
        return self.mesh.units

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise InputError(f"shape {name!r} not in the rig{(' ' + self.source) if self.source else ''}; it has "
                             f"{self.n_shapes} shapes: {list_names(self.names)}") from None

    # -- evaluation ------------------------------------------------------------------------------
    def evaluate(self, weights) -> np.ndarray:
        """Posed points for weights.

        Parameters
        ----------
        weights : array_like, shape (F, K) or (K,)

        Returns
        -------
        ndarray, shape (F, N, 3) or (N, 3), float64
            ``neutral + sum_k w_k deltas[k]`` (mesh units).
        """
        w = np.asarray(weights, dtype=np.float64)
        single = w.ndim == 1
        w2 = np.atleast_2d(w)
        if w2.shape[1] != self.n_shapes:
            raise InputError(f"weights for {w2.shape[1]} shapes, the rig has {self.n_shapes}")
        flat = self.deltas.reshape(self.n_shapes, -1)
        out = (w2 @ flat).reshape(w2.shape[0], self.n_points, 3) + self.neutral[None]
        return out[0] if single else out

    def subset(self, names) -> "BlendShapeRig":
        """The rig with only ``names`` (in that order)."""
        idx = [self.index(n) for n in names]
        return BlendShapeRig(tuple(self.names[i] for i in idx), self.deltas[idx], self.mesh, source=self.source,
                             notes=self.notes)

    def without(self, name: str) -> "BlendShapeRig":
        """The rig without shape ``name``."""
        self.index(name)
        return self.subset([n for n in self.names if n != name])

    def with_mesh(self, mesh: FaceMesh) -> "BlendShapeRig":
        """The same offsets over another neutral mesh of the same topology (e.g. with regions read)."""
        check_same_topology(self.mesh, mesh, what=f"mesh {mesh.source or mesh.name}")
        return BlendShapeRig(self.names, self.deltas, mesh, source=self.source, notes=self.notes)

    def max_displacement(self) -> np.ndarray:
        """(K,) largest vertex offset of each shape (mesh units)."""
        return np.linalg.norm(self.deltas, axis=2).max(axis=1)


def marker_basis(rig: BlendShapeRig, binding: Binding) -> np.ndarray:
    """What each shape does to each bound marker point.

    Parameters
    ----------
    rig : BlendShapeRig
    binding : Binding
        Markers bound on the rig's mesh (triangle vertices + barycentrics).

    Returns
    -------
    ndarray, shape (M, K, 3), float64
        ``basis[m, k] = sum_j b_mj deltas[k, tri_mj]``: the displacement of marker m's bound
        surface point when shape k is at weight 1 (mesh units). The solver fits
        ``d_m(f) ~ sum_k w_k(f) basis[m, k]``.
    """
    if binding.triangle_vertices.max() >= rig.n_points:
        raise MeshError(f"binding refers to vertex {int(binding.triangle_vertices.max())} but the rig's mesh has "
                        f"{rig.n_points} vertices")
    return np.einsum("mj,kmjd->mkd", binding.barycentrics, rig.deltas[:, binding.triangle_vertices])


def check_same_topology(reference: FaceMesh, other: FaceMesh, *, what: str) -> None:
    """Raise MeshError naming ``what`` when ``other`` has another vertex count or other polygons."""
    if other.n_points != reference.n_points:
        raise MeshError(f"{what} has another topology: {other.n_points} vertices, the neutral "
                        f"{reference.source or reference.name} has {reference.n_points}")
    if (other.face_vertex_counts.shape != reference.face_vertex_counts.shape
            or other.face_vertex_indices.shape != reference.face_vertex_indices.shape
            or not np.array_equal(other.face_vertex_counts, reference.face_vertex_counts)
            or not np.array_equal(other.face_vertex_indices, reference.face_vertex_indices)):
        raise MeshError(f"{what} has another topology: its polygons differ from the neutral "
                        f"{reference.source or reference.name}'s ({other.n_faces} vs {reference.n_faces} faces)")


def check_neutral(neutral, mesh: FaceMesh, *, source: str, tolerance: float = NEUTRAL_TOLERANCE) -> float:
    """Raise MeshError when a rig's stored neutral does not match the mesh's points.

    Returns the largest deviation (mesh units). The tolerance is a fraction of the mesh's
    bounding-box diagonal (:data:`NEUTRAL_TOLERANCE`).
    """
    n = np.asarray(neutral, dtype=np.float64)
    if n.shape != mesh.points.shape:
        raise MeshError(f"blend shapes {source}: the neutral has {n.shape[0] if n.ndim == 2 else n.shape} points, "
                        f"the mesh {mesh.source or mesh.name} has {mesh.n_points}")
    if not np.isfinite(n).all():
        raise FormatError(f"blend shapes {source}: the neutral has NaN or infinite points")
    dev = np.linalg.norm(n - mesh.points, axis=1)
    diag = float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
    worst = int(np.argmax(dev))
    if dev[worst] > tolerance * diag:
        raise MeshError(f"blend shapes {source}: the neutral does not match the mesh {mesh.source or mesh.name} "
                        f"(vertex {worst} is {dev[worst]:.4g} {mesh.units or 'units'} away; {int((dev > tolerance * diag).sum())} "
                        f"vertices differ by more than {tolerance * diag:.3g}); the offsets belong to another face")
    return float(dev[worst])


def read_shapes_npz(path, *, check: bool = True) -> tuple[list[str], np.ndarray | None, np.ndarray]:
    """Read an ``.npz`` of shapes: ``names`` (K,) str, ``deltas`` (K, N, 3) float (vertex offsets
    in the mesh's units), ``neutral`` (N, 3) optional. With ``check``, the deltas' shape and
    finiteness are checked here (a rig checks them, with the shape named, when it is built).

    Returns
    -------
    names : list of str
    neutral : ndarray (N, 3) float64 or None
    deltas : ndarray (K, N, 3) float64
    """
    from ..io.npz import load_npz

    p = Path(os.fspath(path))
    if not p.is_file():
        raise InputError(f"--shapes {p}: no such file")
    z = load_npz(p, label=f"shapes file {p}")  # headers checked against the file before any allocation
    missing = [k for k in ("names", "deltas") if k not in z]
    if missing:
        raise FormatError(f"shapes file {p}: missing array(s) {', '.join(missing)}; has {', '.join(sorted(z))}")
    names = [str(n) for n in z["names"]]
    deltas = np.asarray(z["deltas"], dtype=np.float64)
    neutral = np.asarray(z["neutral"], dtype=np.float64) if "neutral" in z else None
    if check:
        if deltas.ndim != 3 or deltas.shape[0] != len(names) or deltas.shape[2] != 3:
            raise FormatError(f"shapes file {p}: deltas must have shape ({len(names)}, N, 3); got {deltas.shape}")
        if not np.isfinite(deltas).all():
            raise FormatError(f"shapes file {p}: deltas contain NaN or infinite values")
    return names, neutral, deltas


def load_npz_rig(path, mesh: FaceMesh) -> BlendShapeRig:
    """Read an ``.npz`` rig (``names[K]``, ``deltas[K, N, 3]``, optional ``neutral[N, 3]``) over ``mesh``.

    Parameters
    ----------
    path : str or os.PathLike
    mesh : FaceMesh
        The neutral mesh; offsets are in its units. A stored ``neutral`` must match its points
        (:func:`check_neutral`).
    """
    p = Path(os.fspath(path))
    names, neutral, deltas = read_shapes_npz(p, check=False)  # the rig checks names and values itself
    if deltas.ndim == 3 and deltas.shape[1] != mesh.n_points and deltas.shape[0] == len(names):
        raise MeshError(f"shapes file {p}: offsets for {deltas.shape[1]} vertices, the mesh "
                        f"{mesh.source or mesh.name} has {mesh.n_points} (another topology)")
    if neutral is not None:
        check_neutral(neutral, mesh, source=str(p))
    return BlendShapeRig(tuple(names), deltas, mesh, source=str(p))


def load_mesh_folder_rig(folder, mesh: FaceMesh, *, units: str | None = None) -> BlendShapeRig:
    """Read a folder of same-topology meshes ``<shape>.<suffix>`` as offsets from ``mesh``.

    Shapes are taken in file-name order; a file named like the neutral mesh is skipped. Each
    shape's vertex count and polygons must equal the neutral's (the error names the shape).
    """
    from ..io.meshes import MESH_SUFFIXES, read_mesh

    d = Path(os.fspath(folder))
    if not d.is_dir():
        raise InputError(f"--shapes {d}: no such folder")
    files = sorted(f for f in d.iterdir() if f.is_file() and f.suffix.lower() in MESH_SUFFIXES)
    neutral_src = Path(mesh.source).resolve() if mesh.source else None
    files = [f for f in files if neutral_src is None or f.resolve() != neutral_src]
    if not files:
        raise InputError(f"--shapes {d}: no shape meshes ({', '.join(MESH_SUFFIXES)}) in the folder")
    stems = [f.stem for f in files]
    dup = sorted({s for s in stems if stems.count(s) > 1})
    if dup:
        raise FormatError(f"--shapes {d}: duplicate shape names {list_names(dup)} (one file per shape name)")
    deltas = np.empty((len(files), mesh.n_points, 3))
    for k, f in enumerate(files):
        shape = read_mesh(f, units=units or mesh.units, check_degenerate=False)
        check_same_topology(mesh, shape, what=f"shape {f.stem!r} ({f})")
        deltas[k] = shape.points - mesh.points
    return BlendShapeRig(tuple(stems), deltas, mesh, source=str(d))
