"""Marker layouts: where each capture marker sits on a particular mesh.

A layout is a small JSON file made for one mesh (or one topology)::

    {
      "format": "usdface-layout/1",
      "units": "cm",
      "markers": {
        "Chin": {"vertex": 812},
        "NoseHead": {"point": [0.0, 70.91, 16.52]}
      }
    }

- ``"vertex"``: a vertex index of the mesh (tied to its topology);
- ``"point"``: a position in the mesh's space, in the layout's ``units`` (converted when the mesh
  has other units), projected onto the surface when bound; survives remeshing.

``"units"`` is optional (default: the mesh's own units). No other keys are allowed: a misspelt key
is an error rather than silently ignored.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import FormatError, MeshError, list_names
from ..fileutil import write_text_atomic
from ..inputfiles import FLOAT32_MAX, read_json
from ..units import METERS_PER_UNIT, scale_between
from ..model.mesh import FaceMesh

__all__ = ["LAYOUT_FORMAT", "LayoutMarker", "Layout", "read_layout", "write_layout"]

#: the ``"format"`` tag of layout files this version reads and writes
LAYOUT_FORMAT = "usdface-layout/1"

_TOP_KEYS = ("format", "units", "markers")


@dataclass(frozen=True)
class LayoutMarker:
    """One layout entry: exactly one of ``vertex`` or ``point``.

    Attributes
    ----------
    name : str
        Marker name (as in the capture).
    vertex : int, optional
        Mesh vertex index.
    point : tuple of 3 float, optional
        Position in the layout's units and the mesh's space.
    """

    name: str
    vertex: int | None = None
    point: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if (self.vertex is None) == (self.point is None):
            raise FormatError(f"layout marker {self.name!r}: give exactly one of vertex or point")
        if self.point is not None:
            pt = tuple(float(x) for x in self.point)
            if len(pt) != 3 or not all(math.isfinite(x) and abs(x) <= FLOAT32_MAX for x in pt):
                raise FormatError(f"layout marker {self.name!r}: point must be 3 finite numbers within float32's "
                                  f"range; got {self.point!r}")
            object.__setattr__(self, "point", pt)
        if self.vertex is not None:
            if isinstance(self.vertex, bool) or int(self.vertex) != self.vertex or self.vertex < 0:
                raise FormatError(f"layout marker {self.name!r}: vertex must be an integer >= 0; got {self.vertex!r}")
            object.__setattr__(self, "vertex", int(self.vertex))


@dataclass(frozen=True)
class Layout:
    """A marker layout for one mesh.

    Attributes
    ----------
    markers : tuple of LayoutMarker
        Entries in file order; names unique.
    units : str or None
        Unit of the ``point`` entries; None means "the mesh's units".
    source : str
        The file the layout came from (for messages).
    """

    markers: tuple[LayoutMarker, ...]
    units: str | None = "cm"
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "markers", tuple(self.markers))
        where = f" {self.source}" if self.source else ""
        if self.units is not None and self.units not in METERS_PER_UNIT:
            raise FormatError(f"layout{where}: unknown units {self.units!r}; expected one of {', '.join(METERS_PER_UNIT)}")
        if not self.markers:
            raise FormatError(f"layout{where} has no markers")
        seen, dups = set(), []
        for m in self.markers:
            if m.name in seen:
                dups.append(m.name)
            seen.add(m.name)
        if dups:
            raise FormatError(f"layout{where} has duplicate markers: {list_names(dups)}")

    @classmethod
    def from_points(cls, names, points, *, units: str | None = "cm", source: str = "") -> "Layout":
        """A layout of ``point`` entries from names (M,) and positions (M, 3)."""
        pts = np.asarray(points, dtype=np.float64)
        if pts.shape != (len(names), 3):
            raise FormatError(f"layout points must have shape ({len(names)}, 3); got {pts.shape}")
        return cls(tuple(LayoutMarker(str(n), point=tuple(p)) for n, p in zip(names, pts)), units=units, source=source)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.markers)

    @property
    def n_markers(self) -> int:
        return len(self.markers)

    def __getitem__(self, name: str) -> LayoutMarker:
        for m in self.markers:
            if m.name == name:
                return m
        raise KeyError(name)

    def positions(self, mesh: FaceMesh, names=None) -> np.ndarray:
        """Positions of the entries in ``mesh``'s space and units.

        Parameters
        ----------
        mesh : FaceMesh
        names : sequence of str, optional
            Order (and subset) of markers; default the layout's order.

        Returns
        -------
        ndarray, shape (M, 3), float64
            Vertex entries give the vertex position; point entries are scaled from the layout's
            units to the mesh's when both are known and differ.

        Raises
        ------
        MeshError
            A vertex entry is outside the mesh's vertex range.
        KeyError
            A name in ``names`` is not in the layout.
        """
        names = self.names if names is None else tuple(names)
        factor = 1.0
        if self.units is not None and mesh.units is not None and self.units != mesh.units:
            factor = scale_between(self.units, mesh.units)
        out = np.empty((len(names), 3))
        bad = []
        for i, n in enumerate(names):
            m = self[n]
            if m.vertex is not None:
                if m.vertex >= mesh.n_points:
                    bad.append(f"{n} (vertex {m.vertex})")
                    continue
                out[i] = mesh.points[m.vertex]
            else:
                out[i] = np.asarray(m.point) * factor
        if bad:
            where = f" {self.source}" if self.source else ""
            mesh_where = mesh.source or mesh.name
            raise MeshError(
                f"layout{where}: vertex index out of range for mesh {mesh_where} "
                f"({mesh.n_points} vertices, 0..{mesh.n_points - 1}): {list_names(bad)}"
            )
        self._check_spread(names, out, mesh)
        return out

    def _check_spread(self, names, positions: np.ndarray, mesh: FaceMesh) -> None:
        """FormatError when markers share one position: all of them (a layout made of one copied
        entry), or two (a copy-paste slip; two markers cannot drive one point)."""
        if len(names) < 2:
            return
        where = f"layout {self.source}" if self.source else "layout"
        _, first, inverse, counts = np.unique(positions, axis=0, return_index=True, return_inverse=True,
                                              return_counts=True)
        inverse = inverse.ravel()
        units = mesh.units or "units"
        if counts.size == 1:
            p = positions[0]
            raise FormatError(f"{where}: all {len(names)} markers are at one point ({p[0]:.6g}, {p[1]:.6g}, "
                              f"{p[2]:.6g}) {units} on mesh {mesh.source or mesh.name}; a layout places each marker "
                              f"where it sits on the face")
        shared = np.flatnonzero(counts > 1)
        if shared.size:
            groups = [[names[i] for i in np.flatnonzero(inverse == g)] for g in shared]
            text = "; ".join(" and ".join(g) for g in groups[:6]) + (f"; ... ({shared.size} groups)" if shared.size > 6 else "")
            raise FormatError(f"{where}: markers at the same point on mesh {mesh.source or mesh.name}: {text}; each "
                              f"marker needs its own place (a copied entry?)")


def read_layout(path) -> Layout:
    """Read a marker layout JSON file.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Layout

    Raises
    ------
    InputError
        The file does not exist or cannot be read.
    FormatError
        Not JSON, wrong ``"format"`` tag, unknown keys, unknown units, or a bad marker entry (the
        message names the file and the marker).
    """
    path = Path(os.fspath(path))
    data = read_json(path, label=f"layout file {path}")
    if not isinstance(data, dict):
        raise FormatError(f"layout file {path}: top level must be a JSON object; got {type(data).__name__}")
    unknown = [k for k in data if k not in _TOP_KEYS]
    if unknown:
        raise FormatError(f"layout file {path}: unknown key(s) {list_names(unknown)}; expected {', '.join(_TOP_KEYS)}")
    fmt = data.get("format")
    if fmt != LAYOUT_FORMAT:
        raise FormatError(f"layout file {path}: format tag is {fmt!r}; expected {LAYOUT_FORMAT!r}")
    units = data.get("units")
    if units is not None and units not in METERS_PER_UNIT:
        raise FormatError(f"layout file {path}: unknown units {units!r}; expected one of {', '.join(METERS_PER_UNIT)}")
    markers = data.get("markers")
    if not isinstance(markers, dict) or not markers:
        raise FormatError(f"layout file {path}: 'markers' must be a non-empty object of name -> entry")
    entries = []
    for name, entry in markers.items():
        entries.append(_parse_entry(path, name, entry))
    return Layout(tuple(entries), units=units, source=str(path))


def _parse_entry(path: Path, name: str, entry) -> LayoutMarker:
    where = f"layout file {path}, marker {name!r}"
    if not isinstance(entry, dict) or len(entry) != 1 or next(iter(entry)) not in ("vertex", "point"):
        raise FormatError(f"{where}: entry must be {{\"vertex\": index}} or {{\"point\": [x, y, z]}}; got {json.dumps(entry)}")
    key, value = next(iter(entry.items()))
    if key == "vertex":
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise FormatError(f"{where}: vertex must be an integer >= 0; got {json.dumps(value)}")
        return LayoutMarker(name, vertex=value)
    if (
        not isinstance(value, list)
        or len(value) != 3
        or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value)
    ):
        raise FormatError(f"{where}: point must be a list of 3 finite numbers; got {json.dumps(value)}")
    if any(abs(x) > FLOAT32_MAX for x in value):
        raise FormatError(f"{where}: point {json.dumps(value)} is beyond the range of the float32 coordinates "
                          f"USD stores (|x| <= {FLOAT32_MAX:.4g}); not a position on a face")
    return LayoutMarker(name, point=tuple(float(x) for x in value))


def write_layout(path, layout: Layout, *, decimals: int | None = 6) -> Path:
    """Write a layout as JSON (atomically: temporary file, then rename).

    Parameters
    ----------
    path : str or os.PathLike
    layout : Layout
    decimals : int, optional
        Round point coordinates to this many decimals (default 6); None keeps full precision.

    Returns
    -------
    Path
        The written file.
    """
    path = Path(os.fspath(path))
    markers = {}
    for m in layout.markers:
        if m.vertex is not None:
            markers[m.name] = {"vertex": m.vertex}
        else:
            pt = [round(x, decimals) if decimals is not None else x for x in m.point]
            markers[m.name] = {"point": [0.0 if x == 0 else x for x in pt]}
    data = {"format": LAYOUT_FORMAT}
    if layout.units is not None:
        data["units"] = layout.units
    data["markers"] = markers
    # one marker per line: readable diffs
    lines = [f"  {json.dumps(k)}: {json.dumps(v)}" for k, v in markers.items()]
    head = ",\n".join(f"  {json.dumps(k)}: {json.dumps(v)}" for k, v in data.items() if k != "markers")
    text = "{\n" + head + ',\n  "markers": {\n' + ",\n".join("  " + ln for ln in lines) + "\n  }\n}\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(path, text)
    return path
