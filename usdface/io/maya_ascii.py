"""Maya ASCII (``.ma``) reader for marker motion capture baked to animation curves.

What is a marker
----------------
Every DAG ``transform`` (or ``joint``) with at least one translate channel (``tx``/``ty``/``tz``,
or ``translateX``...) driven by a time-input animation curve (``animCurveTL``, ``animCurveTU``)
through ``connectAttr "<curve>.o" "<node>.tx"``. Curves are found through those connections, never
by name (AnimFace's ``Rcheek_Up`` is driven by ``Rcheek_up_translate*``). Markers are named by the
node's short name and ordered as the nodes are created in the file. A translate channel without a
curve keeps its static ``setAttr`` value (``.t``, ``.tx``...; 0 if never set).

Positions
---------
World positions: each marker's translate is carried through its ancestors' local transforms
(translate, rotate with ``.ro`` rotate order, scale; static or, for translate, animated), e.g.
the ``MoCapData`` group offset of AnimFace's ``NoseMoCap.ma``. An ancestor with pivots, shear,
rotate axis or joint orient, or with animated rotate/scale, is rejected (FormatError) rather than
evaluated approximately. The marker's own rotate/scale do not move its origin and are ignored.
Positions stay in the scene's linear unit (``currentUnit -l``; Maya's default is cm), Y-up.

Time
----
Key times are in the scene's time unit (``currentUnit -t``: game=15, film=24, pal=25, ntsc=30,
show=48, palf=50, ntscf=60 fps, millisec, sec, min, hour, or ``<N>fps``; default film). The capture
rate is the most common key spacing (AnimFace: a key every 0.4 film frame = 60 Hz), snapped to an integer or
NTSC (N/1.001) rate when within 1e-4, unless ``rate`` is given. Frames lie on a regular grid at
that rate starting at the earliest key; a key that falls on the grid (within 1e-3 frame) is
copied exactly, grid frames between a curve's keys are linearly interpolated (Maya's tangents are
not evaluated; the history step counts such samples), and frames outside a curve's key range are
invalid (NaN). When the first key is not on a whole frame of the rate, the capture starts at the
nearest frame and the history records the offset in seconds.

Robustness
----------
Statements must end with ``;`` and the file with Maya's ``// End of <name>.ma`` line; key blocks
(``setAttr ".ktv[a:b]" t0 v0 t1 v1 ...``) must hold exactly their index range and the count
declared by ``setAttr -s N ".ktv"``. A truncated or malformed file raises FormatError naming the
file, line and curve instead of returning short data. So does a translate key that is not a
position: not finite, or more than :data:`MAX_KEY_METERS` (1 km) from the origin (a value such
as 9.9e30 would move the face by 1e31 cm); the message names the curve, the marker channel it
drives, the key, its time and its line. Values that are positions but implausible ones (a spike
of 50 cm) are judged later, by :mod:`usdface.capture.plausibility`.

Speed
-----
One regex pass finds statement starts (a few thousand statements; no per-key Python work), and the
key text of all curves is converted in one ``numpy.fromstring`` call.
"""
from __future__ import annotations

import math
import os
import re
import warnings
from dataclasses import dataclass

import numpy as np

from ..model.capture import Capture
from ..errors import MarkerError
from ..io.limits import check_read_size
from .captures import check_rate_option, read_text, resolve_units
from .maya_scene import DAG_XFORM_TYPES, Node, Scene, XFORM_ATTRS, parse_statements, split_plug

__all__ = ["read_maya_ascii", "MAYA_TIME_UNITS", "MAYA_LINEAR_UNITS"]

#: Maya time unit names -> frames per second
MAYA_TIME_UNITS = {
    "game": 15.0, "film": 24.0, "pal": 25.0, "ntsc": 30.0, "show": 48.0, "palf": 50.0, "ntscf": 60.0,
    "millisec": 1000.0, "sec": 1.0, "min": 1.0 / 60.0, "hour": 1.0 / 3600.0,
}

#: Maya linear unit names (long and short) -> usdface unit names
MAYA_LINEAR_UNITS = {
    "millimeter": "mm", "mm": "mm", "centimeter": "cm", "cm": "cm", "meter": "m", "m": "m",
    "inch": "in", "in": "in", "foot": "ft", "ft": "ft",
}

_FPS = re.compile(r"(\d+(?:\.\d+)?)fps$")

for _short, _long in (("t", "translate"), ("r", "rotate"), ("s", "scale")):
    XFORM_ATTRS[_short] = XFORM_ATTRS[_long] = _short
    for _axis in "xyz":
        XFORM_ATTRS[_short + _axis] = XFORM_ATTRS[_long + _axis.upper()] = _short + _axis
for _short, _long in (("ro", "rotateOrder"), ("rp", "rotatePivot"), ("sp", "scalePivot"),
                      ("rpt", "rotatePivotTranslate"), ("spt", "scalePivotTranslate"),
                      ("ra", "rotateAxis"), ("sh", "shear"), ("jo", "jointOrient")):
    XFORM_ATTRS[_short] = XFORM_ATTRS[_long] = _short
_TRANSLATE_CHANNELS = ("tx", "ty", "tz")
_TIME_CURVE_TYPES = ("animCurveTL", "animCurveTU")
# attributes that must be at their defaults on an ancestor, with those defaults
_UNSUPPORTED_ANCESTOR_ATTRS = {"rp": 0.0, "sp": 0.0, "rpt": 0.0, "spt": 0.0, "ra": 0.0, "sh": 0.0, "jo": 0.0}
# Maya rotate orders (.ro): the axis applied first comes first
_ROTATE_ORDERS = ("xyz", "yzx", "zxy", "xzy", "yxz", "zyx")
_ON_GRID_TOLERANCE = 1e-3  # frames
#: a translate key farther than this from the origin (metres) is not a position: the file is broken
MAX_KEY_METERS = 1000.0
_TOKEN = re.compile(r"\S+")


def read_maya_ascii(path, *, units: str | None = None, rate: float | None = None, allow=frozenset()) -> Capture:
    """Read marker motion from a Maya ASCII scene whose markers are transforms animated by curves.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.ma`` file.
    units : str, optional
        Expected linear unit (``"cm"``...). The scene's ``currentUnit -l`` is used; giving a
        different unit is an OptionError (positions are never rescaled).
    rate : float, optional
        Capture rate in Hz of the output grid. Default: inferred from the key spacing.
    allow : set of str
        Plausibility codes accepted (``rate``, ``frame-count``: :mod:`usdface.io.limits`),
        judged on the grid before it is sampled.

    Returns
    -------
    Capture
        ``positions`` (F, M, 3) float64 world positions in the scene's linear unit, Y-up, NaN
        outside a curve's key range; ``rate`` in Hz; ``start_frame`` = time code of the earliest
        key at ``rate``; ``history`` = ({"step": "read", "format": "maya_ascii", "time_unit",
        "key_rate", "interpolated_samples", "time_offset_seconds", "markers"},).

    Raises
    ------
    InputError
        Missing or unreadable file.
    FormatError
        Not a Maya ASCII file, truncated (statement without ``;``, missing ``// End of`` line,
        fewer keys than declared), malformed key blocks, unsupported units or transforms.
    MarkerError
        No animated transform, duplicate marker names, a marker without any valid sample.
    OptionError
        ``units`` contradicting the scene, a non-positive ``rate``.

    Notes
    -----
    See the module docstring for the exact rules (markers, hierarchy, time grid).
    """
    source = os.fspath(path)
    rate = check_rate_option(rate)
    text = read_text(path)
    scene = parse_statements(text, source)
    unit = MAYA_LINEAR_UNITS.get(scene.linear_unit)
    if unit is None:
        raise scene.error(None, f"linear unit {scene.linear_unit!r} (currentUnit -l) is not supported; "
                                f"supported: millimeter, centimeter, meter, inch, foot")
    unit = resolve_units(unit, units, source=source)
    frames_per_second = _time_unit_fps(scene)

    markers, channel_curves = _find_markers(scene)
    if not markers:
        raise MarkerError(
            f"{source}: no marker found: no transform has a translate channel (tx/ty/tz) driven by an "
            f"animCurveTL through connectAttr \"<curve>.o\" \"<node>.tx\""
        )
    ancestors = _ancestor_chains(scene, markers)
    for node in {id(a): a for chain in ancestors for a in chain}.values():
        _check_ancestor(scene, node)
        for channel in _TRANSLATE_CHANNELS:
            curve = _driver_curve(scene, node, channel)
            if curve is not None:
                channel_curves[(id(node), channel)] = curve
    curves = list({id(c): c for c in channel_curves.values()}.values())
    keys = _parse_keys(scene, curves)  # id(curve) -> (times in Maya time units, values)
    _check_key_values(scene, curves, keys, channel_curves, unit)

    grid = _TimeGrid.fit(scene, keys, frames_per_second, rate)
    grid.judge(scene, keys, n_markers=len(markers), rate_given=rate is not None, fps=frames_per_second, allow=allow)
    sampled = {cid: grid.sample(times, values) for cid, (times, values) in keys.items()}

    def local_translate(node):
        """(F, 3) or (3,) translate of one node: curves where driven, else static values."""
        static = _static_translate(node)
        columns = []
        animated = False
        for axis, channel in enumerate(_TRANSLATE_CHANNELS):
            curve = channel_curves.get((id(node), channel))
            if curve is None:
                columns.append(np.full(grid.n_frames, static[axis]))
            else:
                columns.append(sampled[id(curve)])
                animated = True
        return np.stack(columns, axis=1) if animated else static

    positions = np.empty((grid.n_frames, len(markers), 3))
    for m, (node, chain) in enumerate(zip(markers, ancestors)):
        p = np.broadcast_to(local_translate(node), (grid.n_frames, 3))
        for parent in chain:
            linear = _static_linear(scene, parent)
            if linear is not None:
                p = p @ linear.T
            p = p + local_translate(parent)
        positions[:, m] = p
    # A sample is invalid as a whole when any of its coordinates is missing.
    positions[~np.isfinite(positions).all(axis=2)] = np.nan

    step = {
        "step": "read",
        "format": "maya_ascii",
        "time_unit": scene.time_unit,
        "key_rate": grid.key_rate,
        "interpolated_samples": int(grid.interpolated_samples),
        "time_offset_seconds": grid.time_offset_seconds,
        "markers": len(markers),
    }
    capture = Capture(
        names=tuple(n.name for n in markers),
        positions=positions,
        rate=grid.rate,
        units=unit,
        start_frame=grid.start_frame,
        source=source,
        history=(step,),
    )
    capture.check_not_all_invalid()
    return capture


# -- statements --------------------------------------------------------------------------------


# -- markers, hierarchy ------------------------------------------------------------------------


def _driver_index(scene: Scene) -> dict:
    """(id(node), canonical attr) -> (source node or None, source plug, text position), built once."""
    index = scene.drivers
    if index is None:
        index = {}
        for src, dst, pos in scene.connections:
            dst_node_name, dst_attr = split_plug(dst)
            canonical = XFORM_ATTRS.get(dst_attr)
            if canonical is None:
                continue
            dst_node = scene.find(dst_node_name, pos)
            if dst_node is None:
                continue
            src_node = scene.find(split_plug(src)[0], pos)
            targets = [canonical + a for a in "xyz"] if canonical in ("t", "r", "s") else [canonical]
            for target in targets:
                index[(id(dst_node), target)] = (src_node, src, pos)
        scene.drivers = index
    return index


def _driver_curve(scene: Scene, node: Node, channel: str) -> Node | None:
    """The time curve driving ``node.channel``; FormatError if something else drives it."""
    driver = _driver_index(scene).get((id(node), channel))
    if driver is None:
        return None
    src_node, src_plug, pos = driver
    if src_node is not None and src_node.kind in _TIME_CURVE_TYPES and split_plug(src_plug)[1] in ("o", "output"):
        return src_node
    what = f"a {src_node.kind} node" if src_node is not None else "an unknown node"
    raise scene.error(scene.line_of(pos), f"{node.name}.{channel} is driven by {src_plug!r} ({what}); only animation "
                            f"curves ({', '.join(_TIME_CURVE_TYPES)}) can be read")


def _find_markers(scene: Scene) -> tuple[list, dict]:
    drivers = _driver_index(scene)
    markers, channel_curves = [], {}
    for node in scene.nodes:
        if node.kind not in DAG_XFORM_TYPES:
            continue
        driven = [c for c in _TRANSLATE_CHANNELS if (id(node), c) in drivers]
        curves = {}
        for channel in driven:
            src_node = drivers[(id(node), channel)][0]
            if src_node is not None and src_node.kind in _TIME_CURVE_TYPES:
                curves[channel] = src_node
        if not curves:
            continue
        for channel in driven:  # every driven channel of a marker must be a readable curve
            curves[channel] = _driver_curve(scene, node, channel)
        markers.append(node)
        for channel, curve in curves.items():
            channel_curves[(id(node), channel)] = curve
    return markers, channel_curves


def _ancestor_chains(scene: Scene, markers: list) -> list:
    chains = []
    for node in markers:
        chain, parent = [], node.parent
        while parent is not None:
            chain.append(parent)
            parent = parent.parent
        chains.append(chain)
    return chains


def _check_ancestor(scene: Scene, node: Node) -> None:
    drivers = _driver_index(scene)
    for attr in ("rx", "ry", "rz", "sx", "sy", "sz", "ro"):
        if (id(node), attr) in drivers:
            raise scene.error(scene.line_of(drivers[(id(node), attr)][2]),
                              f"group {node.name!r} above markers has an animated {attr}; only animated "
                              f"translate is supported on groups")
    for attr, default in _UNSUPPORTED_ANCESTOR_ATTRS.items():
        values = node.static.get(attr)
        if values and any(v != default for v in values):
            raise scene.error(scene.line_of(node.pos), f"group {node.name!r} above markers sets .{attr} = {values}; pivots, "
                                         f"shear, rotate axis and joint orient are not supported on groups")


def _static_vector(node: Node, attr: str, default: float) -> np.ndarray:
    values = list(node.static.get(attr, [default] * 3))
    values += [default] * (3 - len(values))
    for axis, name in enumerate("xyz"):
        single = node.static.get(attr + name)
        if single:
            values[axis] = single[0]
    return np.array(values[:3], dtype=np.float64)


def _static_translate(node: Node) -> np.ndarray:
    return _static_vector(node, "t", 0.0)


def _static_linear(scene: Scene, node: Node) -> np.ndarray | None:
    """3x3 rotate*scale of a group (column vectors), or None when it is the identity."""
    angles = _static_vector(node, "r", 0.0)
    scale = _static_vector(node, "s", 1.0)
    if not angles.any() and (scale == 1.0).all():
        return None
    if scene.angle_unit.startswith("deg"):
        angles = np.radians(angles)
    order = _ROTATE_ORDERS[int(node.static.get("ro", [0])[0]) % 6]
    rotation = np.eye(3)
    for axis in order:  # the first axis of the order is applied first
        i = "xyz".index(axis)
        c, s = math.cos(angles[i]), math.sin(angles[i])
        j, k = (i + 1) % 3, (i + 2) % 3
        r = np.eye(3)
        r[j, j] = r[k, k] = c
        r[j, k], r[k, j] = -s, s
        rotation = r @ rotation
    return rotation @ np.diag(scale)


# -- keys --------------------------------------------------------------------------------------

def _parse_keys(scene: Scene, curves: list) -> dict:
    """Convert the key blocks of ``curves`` to arrays: id(curve) -> (times, values), in Maya
    time units. All key text is converted in one numpy call; the per-block path only runs to
    name the bad block when the counts disagree."""
    text = scene.text
    blocks = [(curve, b) for curve in curves for b in curve.key_blocks]
    expected = sum(2 * (last - first + 1) for _, (first, last, _, _, _) in blocks)
    numbers = None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            numbers = np.fromstring(" ".join(text[s:e] for _, (_, _, s, e, _) in blocks), sep=" ")
    except (DeprecationWarning, ValueError):
        numbers = None
    if numbers is None or numbers.size != expected:
        numbers = _parse_blocks_one_by_one(scene, blocks)

    keys, offset = {}, 0
    for curve in curves:
        n_numbers = sum(2 * (last - first + 1) for first, last, _, _, _ in curve.key_blocks)
        own = numbers[offset:offset + n_numbers]
        offset += n_numbers
        keys[id(curve)] = _assemble_curve(scene, curve, own)
    return keys


def _parse_blocks_one_by_one(scene: Scene, blocks: list) -> np.ndarray:
    parts = []
    for curve, (first, last, start, end, pos) in blocks:
        want = 2 * (last - first + 1)
        chunk = scene.text[start:end]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                values = np.fromstring(chunk, sep=" ")
            except ValueError:
                values = np.empty(0)
        if values.size != want:
            tokens = chunk.split()
            bad = next((t for t in tokens if not _is_number(t)), None)
            detail = f"{bad!r} is not a number" if bad is not None else f"it holds {len(tokens)} numbers"
            raise scene.error(
                scene.line_of(pos),
                f"curve {curve.name!r}: key block .ktv[{first}:{last}] must hold {want // 2} time/value pairs "
                f"({want} numbers) but {detail}: the file is truncated or malformed",
            )
        parts.append(values)
    return np.concatenate(parts) if parts else np.empty(0)


def _check_key_values(scene: Scene, curves: list, keys: dict, channel_curves: dict, unit: str) -> None:
    """FormatError for a translate key that is not a position (not finite, beyond 1 km)."""
    from ..units import METERS_PER_UNIT

    limit = MAX_KEY_METERS / METERS_PER_UNIT[unit]
    drives = {}
    for (node_id, channel), curve in channel_curves.items():
        node = next((n for n in scene.nodes if id(n) == node_id), None)
        drives.setdefault(id(curve), f"{node.name}.{channel}" if node is not None else channel)
    for curve in curves:
        times, values = keys[id(curve)]
        bad = np.flatnonzero(~(np.abs(values) <= limit))
        if not bad.size:
            continue
        k = int(bad[0])
        line = _key_line(scene, curve, k)
        where = f" (line {line})" if line else ""
        more = f"; {bad.size - 1} more such key(s) on this curve" if bad.size > 1 else ""
        raise scene.error(None, f"curve {curve.name!r} (driving {drives.get(id(curve), 'a marker')}): key {k} at time "
                                f"{times[k]:g}{where} has value {values[k]:g} {unit}, not a position (more than "
                                f"{MAX_KEY_METERS:g} m from the origin){more}: the file is corrupt; fix or delete "
                                "the key")


def _key_line(scene: Scene, curve: Node, key: int) -> int | None:
    """File line of key ``key``'s value in ``curve``'s key blocks."""
    for first, last, start, end, _ in curve.key_blocks:
        if first <= key <= last:
            want = 2 * (key - first) + 1  # the value token of the pair
            for i, m in enumerate(_TOKEN.finditer(scene.text, start, end)):
                if i == want:
                    return scene.line_of(m.start())
    return None


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _assemble_curve(scene: Scene, curve: Node, numbers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if not curve.key_blocks:
        raise scene.error(scene.line_of(curve.pos), f"curve {curve.name!r} drives a marker but has no keys (.ktv)")
    pairs = numbers.reshape(-1, 2)
    order = sorted(range(len(curve.key_blocks)), key=lambda i: curve.key_blocks[i][0])
    offsets = np.cumsum([0] + [last - first + 1 for first, last, _, _, _ in curve.key_blocks])
    expected_first = 0
    pieces = []
    for i in order:
        first, last, _, _, pos = curve.key_blocks[i]
        if first != expected_first:
            raise scene.error(scene.line_of(pos), f"curve {curve.name!r}: key block .ktv[{first}:{last}] follows "
                                                  f"key {expected_first - 1}; keys {expected_first}..{first - 1} are missing or repeated")
        pieces.append(pairs[offsets[i]:offsets[i + 1]])
        expected_first = last + 1
    n_keys = expected_first
    if curve.declared_keys is not None and curve.declared_keys != n_keys:
        raise scene.error(scene.line_of(curve.pos), f"curve {curve.name!r} declares {curve.declared_keys} keys (setAttr -s) "
                                      f"but its key blocks hold {n_keys}: the file is truncated or malformed")
    pairs = pieces[0] if len(pieces) == 1 else np.concatenate(pieces)
    times, values = pairs[:, 0], pairs[:, 1]
    if n_keys > 1 and not (np.diff(times) > 0).all():
        bad = int(np.argmin(np.diff(times) > 0))
        raise scene.error(scene.line_of(curve.pos), f"curve {curve.name!r}: key times must increase; key {bad + 1} at "
                                      f"{times[bad + 1]:g} follows {times[bad]:g}")
    return times, values


def _time_unit_fps(scene: Scene) -> float:
    unit = scene.time_unit
    if unit in MAYA_TIME_UNITS:
        return MAYA_TIME_UNITS[unit]
    m = _FPS.match(unit)
    if m and float(m.group(1)) > 0:
        return float(m.group(1))
    raise scene.error(None, f"time unit {unit!r} (currentUnit -t) is not supported; expected one of "
                            f"{', '.join(MAYA_TIME_UNITS)} or '<N>fps'")


def _snap_rate(raw: float) -> float:
    """Snap a measured rate to an integer or NTSC (N/1.001) rate when it is within 1e-4."""
    for candidate in (round(raw), round(raw * 1.001) / 1.001):
        if candidate > 0 and abs(raw - candidate) <= 1e-4 * candidate:
            return float(candidate)
    return float(raw)


@dataclass
class _TimeGrid:
    rate: float
    key_rate: float | None
    first_key: float          # earliest key time, Maya time units
    frames_per_unit: float    # grid frames per Maya time unit
    n_frames: int
    start_frame: int
    time_offset_seconds: float
    interpolated_samples: int = 0

    @classmethod
    def fit(cls, scene: Scene, keys: dict, fps: float, rate: float | None) -> "_TimeGrid":
        # the most common key spacing over all curves (one median, robust to a missing key)
        diffs = [np.diff(t) for t, _ in keys.values() if t.size > 1]
        key_rate = _snap_rate(fps / float(np.median(np.concatenate(diffs)))) if diffs else None
        if rate is None:
            if key_rate is None:
                raise scene.error(None, "every curve has a single key, so the capture rate cannot be inferred; pass --rate (rate=..., Hz)")
            rate = key_rate
        first = min(float(t[0]) for t, _ in keys.values())
        last = max(float(t[-1]) for t, _ in keys.values())
        frames_per_unit = rate / fps
        # judged (rate, frame-count, memory) by the reader before any array is made
        span = (last - first) * frames_per_unit + _ON_GRID_TOLERANCE
        n_frames = math.floor(span) + 1 if math.isfinite(span) else math.inf
        start = first / fps * rate
        start_frame = int(round(start))
        offset = (start - start_frame) / rate
        return cls(rate=float(rate), key_rate=key_rate, first_key=first, frames_per_unit=frames_per_unit,
                   n_frames=n_frames, start_frame=start_frame,
                   time_offset_seconds=0.0 if abs(offset) < 1e-12 else float(offset))

    def judge(self, scene: Scene, keys: dict, *, n_markers: int, rate_given: bool, fps: float, allow) -> None:
        """The grid's rate and frame count against :mod:`usdface.io.limits`, and the memory
        the frames need, before any array is made (keys 1e-9 frame apart are 2.4e10 Hz)."""
        spacing = 1.0 / (self.key_rate or self.rate) * fps
        origin = "given with --rate" if rate_given else f"inferred from keys {spacing:g} {scene.time_unit} frames apart"
        most_keys = max(t.size for t, _ in keys.values())
        self.n_frames = check_read_size(what=scene.source, frames=self.n_frames, markers=n_markers, rate=self.rate,
                                        rate_origin=origin, samples=most_keys, noun="keys on its longest curve",
                                        allow=allow)

    def sample(self, times: np.ndarray, values: np.ndarray) -> np.ndarray:
        """(n_frames,) values of one curve on the grid: exact at keys on the grid, linear between
        keys, NaN outside the curve's key range."""
        u = (times - self.first_key) * self.frames_per_unit
        nearest = np.rint(u)
        on_grid = np.abs(u - nearest) <= _ON_GRID_TOLERANCE
        u = np.where(on_grid, nearest, u)
        frames = np.arange(self.n_frames, dtype=np.float64)
        if on_grid.all() and u.size == self.n_frames and u[0] == 0.0 and (np.diff(u) == 1.0).all():
            return values.astype(np.float64, copy=True)
        sampled = np.interp(frames, u, values, left=np.nan, right=np.nan)
        if u.size == 1:
            sampled[frames != u[0]] = np.nan
        inside = (frames >= u[0]) & (frames <= u[-1])
        self.interpolated_samples += int(inside.sum() - np.isin(frames[inside], u[on_grid]).sum())
        return sampled
