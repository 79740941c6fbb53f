"""Identities of what a layer is made from: a mesh, a take, markers bound to a mesh.

Each identity is the sha256 of the bytes the layer's consumers depend on, defined once here, so
two files can be told to belong together (or not) without comparing file bytes: a file's sha256
changes with anything (a .usda re-export, a comment, the provenance), these only with the data.

- **mesh**: metersPerUnit (float64), faceVertexCounts and faceVertexIndices (int32) and the rest
  points as float32 (what USD stores), in the mesh layer's units, in point order. Units and point
  order matter: a binding's triangles and barycentrics index the points, and its residuals, the
  distance matrices and the RBF widths are lengths in the mesh's units (the same numbers in mm are
  a face ten times smaller). UVs, normals, regions, prim and file names do not: nothing built on
  the mesh reads them (a mesh re-exported with other UVs keeps its bindings).
- **take** (a capture): marker names, rate (float64), start frame and neutral frame (int64),
  units, and the samples as a capture layer holds them: float32 positions with invalid samples
  holding the last valid value, the validity (uint8) and the stabilisation's head motion (float64,
  when there is one). Everything an animation made from the take depends on.
- **markers**: the marker names in the binding's order; **bound points**: the names plus each
  bound point's triangle vertices (int32) and barycentrics (float64) on the mesh: what a distance
  matrix and a transfer are computed from.

Every part is length-prefixed and each kind has its own tag, so no two different inputs share
their bytes. Pure numpy and hashlib: the usd package stores and compares the records
(:mod:`usdface.usd.identity`).
"""
from __future__ import annotations

import hashlib
import json

import numpy as np

from .capture import hold_invalid

__all__ = ["IDENTITY_VERSION", "mesh_identity", "capture_identity", "marker_names_identity",
           "bound_points_identity", "short"]

#: the version of the bytes hashed below; a record of another version cannot be compared
IDENTITY_VERSION = 1

#: hex digits shown to people (messages, `usdface info`)
SHORT = 12


def short(digest: str | None) -> str:
    """The first 12 hex digits of an identity (``None`` -> ``"unknown"``), as messages show it."""
    return "unknown" if not digest else str(digest)[:SHORT]


def _digest(tag: str, *parts) -> str:
    """sha256 over ``tag`` and each part (bytes, str or ndarray), each prefixed by its length."""
    h = hashlib.sha256(f"usdface-identity-{IDENTITY_VERSION}/{tag}".encode())
    for part in parts:
        if isinstance(part, str):
            data = part.encode("utf-8", "surrogatepass")
        elif isinstance(part, bytes):
            data = part
        else:
            data = memoryview(np.ascontiguousarray(part)).cast("B")
        h.update(len(data).to_bytes(8, "little"))
        h.update(data)
    return h.hexdigest()


def _names(names) -> str:
    return json.dumps([str(n) for n in names], ensure_ascii=True)


def mesh_identity(face_vertex_counts, face_vertex_indices, points, meters_per_unit: float | None) -> str:
    """The identity of a mesh (module docstring): 64 hex digits.

    Parameters
    ----------
    face_vertex_counts : array_like, shape (P,), integer
    face_vertex_indices : array_like, shape (sum(counts),), integer
    points : array_like, shape (N, 3)
        Rest positions in the mesh's units; hashed as float32 (a float64 copy of float32 points,
        as readers make, hashes the same as the float32 points a layer stores).
    meters_per_unit : float or None
        The mesh layer's metersPerUnit (None: not authored).
    """
    unit = np.array([np.nan if meters_per_unit is None else meters_per_unit], dtype="<f8")
    return _digest("mesh", unit, np.asarray(face_vertex_counts, dtype="<i4"),
                   np.asarray(face_vertex_indices, dtype="<i4"), np.asarray(points, dtype="<f4").reshape(-1, 3))


def capture_identity(capture) -> str:
    """The identity of a take (module docstring) from a :class:`usdface.model.Capture` (NaN where
    invalid, as readers return it): 64 hex digits, equal for the capture a processor conditioned in
    memory and for the capture layer written from it and read back."""
    valid = capture.valid
    held = hold_invalid(capture.positions, valid).astype("<f4")
    frames = np.array([capture.start_frame, capture.neutral_frame], dtype="<i8")
    head = b"" if capture.head_motion is None else np.asarray(capture.head_motion, dtype="<f8")
    return _digest("take", _names(capture.names), np.array([capture.rate], dtype="<f8"), frames,
                   str(capture.units), held, valid.astype(np.uint8), head)


def marker_names_identity(names) -> str:
    """The identity of a marker set: its names, in order."""
    return _digest("markers", _names(names))


def bound_points_identity(names, triangle_vertices, barycentrics) -> str:
    """The identity of markers bound to a mesh: names, triangle vertices (int32) and barycentrics
    (float64) of each bound point."""
    return _digest("bound-points", _names(names), np.asarray(triangle_vertices, dtype="<i4").reshape(-1, 3),
                   np.asarray(barycentrics, dtype="<f8").reshape(-1, 3))
