"""The in-memory capture: marker names, positions per frame, validity, rate and units.

Readers in :mod:`usdface.io` return a :class:`Capture`; conditioning functions in
:mod:`usdface.capture` take one and return a new one (inputs are never modified); the USD layer
code writes and reads it.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..errors import MarkerError, list_names


@dataclass(frozen=True)
class Capture:
    """Marker motion capture.

    Attributes
    ----------
    names : tuple of str, length M
        Marker names, unique, in a stable order (the file's order).
    positions : ndarray, shape (F, M, 3), float64
        Marker positions per frame in ``units``; NaN where a sample is invalid (missing).
        In a stabilised capture these are head-local positions: world = head_motion[f] @ local.
    rate : float
        Capture rate in Hz (frames per second). Frame ``f`` is at time ``(start_frame + f) / rate``.
    units : str or None
        Linear unit of ``positions`` (``"mm"``, ``"cm"``, ``"m"``...), None when unknown.
    start_frame : int
        Time code of the first frame (time code = frame index at the capture rate).
    neutral_frame : int
        Index (0-based, into the F frames) of the neutral frame: the frame the user or the
        automatic choice named, always inside ``neutral_window``.
    source : str
        The file the capture came from (as given, for provenance).
    head_motion : ndarray, shape (F, 4, 4), float64, optional
        Rigid head transform per frame removed by stabilisation, column-vector convention
        (world = head_motion[f] @ [local, 1]). None when the capture was not stabilised.
    history : tuple of dict
        Conditioning steps applied, in order, each a JSON-serialisable dict with a ``"step"`` key.
    neutral_window : (int, int), optional
        Frames ``start <= f < end`` the rest pose is averaged over (:mod:`usdface.capture.rest`;
        set by :func:`usdface.capture.neutral.set_rest_pose`). None: the neutral frame alone
        (captures read from files, and capture layers written by usdface 0.2).

    The rest pose (:attr:`neutral`) is computed from ``positions`` over the window when first
    asked for, so it always lives in the positions' space (head-local once stabilised) and follows
    every step that changes the positions.
    """

    names: tuple[str, ...]
    positions: np.ndarray
    rate: float
    units: str | None = None
    start_frame: int = 0
    neutral_frame: int = 0
    source: str = ""
    head_motion: np.ndarray | None = None
    history: tuple[dict, ...] = field(default_factory=tuple)
    neutral_window: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.names)
        object.__setattr__(self, "names", names)
        pos = np.asarray(self.positions, dtype=np.float64)
        object.__setattr__(self, "positions", pos)
        where = f" in {self.source}" if self.source else ""
        if pos.ndim != 3 or pos.shape[2] != 3:
            raise MarkerError(f"capture positions{where} must have shape (frames, markers, 3); got {pos.shape}")
        if pos.shape[0] == 0:
            raise MarkerError(f"capture{where} has zero frames")
        if pos.shape[1] == 0:
            raise MarkerError(f"capture{where} has zero markers")
        if len(names) != pos.shape[1]:
            raise MarkerError(f"capture{where} has {len(names)} names for {pos.shape[1]} markers")
        seen, dups = set(), []
        for n in names:
            if n in seen:
                dups.append(n)
            seen.add(n)
        if dups:
            raise MarkerError(f"capture{where} has duplicate marker names: {list_names(sorted(set(dups)))}")
        if not (np.isfinite(self.rate) and self.rate > 0):
            raise MarkerError(f"capture{where} rate must be a positive number of Hz; got {self.rate}")
        if not 0 <= self.neutral_frame < pos.shape[0]:
            raise MarkerError(
                f"capture{where}: neutral frame index {self.neutral_frame} outside 0..{pos.shape[0] - 1}"
            )
        if self.neutral_window is not None:
            object.__setattr__(self, "neutral_window", _check_window(self.neutral_window, self.neutral_frame,
                                                                     pos.shape[0], where))
        if self.head_motion is not None:
            hm = np.asarray(self.head_motion, dtype=np.float64)
            if hm.shape != (pos.shape[0], 4, 4):
                raise MarkerError(f"capture{where}: head_motion must have shape ({pos.shape[0]}, 4, 4); got {hm.shape}")
            object.__setattr__(self, "head_motion", hm)
        object.__setattr__(self, "history", tuple(self.history))

    # -- shape -----------------------------------------------------------------------------------
    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def n_markers(self) -> int:
        return self.positions.shape[1]

    @property
    def valid(self) -> np.ndarray:
        """(F, M) bool: True where the sample is a real measurement."""
        return np.isfinite(self.positions).all(axis=2)

    @property
    def times(self) -> np.ndarray:
        """(F,) float64 time codes (frame indices at the capture rate)."""
        return self.start_frame + np.arange(self.n_frames, dtype=np.float64)

    @property
    def neutral_frames(self) -> tuple[int, int]:
        """``(start, end)``: the frames ``start <= f < end`` the rest pose comes from."""
        if self.neutral_window is None:
            return (self.neutral_frame, self.neutral_frame + 1)
        return self.neutral_window

    @cached_property
    def neutral(self) -> np.ndarray:
        """(M, 3) read-only rest pose: every displacement is measured from it.

        The positions at the neutral frame when there is no window (NaN where invalid there);
        otherwise each marker's robust average over its valid samples in the window
        (:func:`usdface.capture.rest.robust_rest_pose`; NaN for a marker with none).
        """
        a, b = self.neutral_frames
        if b - a == 1:
            rest = self.positions[a].copy()
        else:
            from .rest import robust_rest_pose

            rest = robust_rest_pose(self.positions[a:b])[0]
        rest.flags.writeable = False
        return rest

    def describe_neutral(self) -> str:
        """'neutral frame 12' or 'neutral frames 0-17' (inclusive), for messages."""
        a, b = self.neutral_frames
        return f"neutral frame {a}" if b - a == 1 else f"neutral frames {a}-{b - 1}"

    def index(self, name: str) -> int:
        """Index of marker ``name``; MarkerError naming the known markers if absent."""
        try:
            return self.names.index(name)
        except ValueError:
            raise MarkerError(
                f"marker {name!r} not in capture{(' ' + self.source) if self.source else ''}; "
                f"capture has {self.n_markers} markers: {list_names(self.names)}"
            ) from None

    def world_positions(self) -> np.ndarray:
        """(F, M, 3) positions with the stabilisation head motion put back."""
        if self.head_motion is None:
            return self.positions.copy()
        r = self.head_motion[:, :3, :3]
        t = self.head_motion[:, :3, 3]
        return np.einsum("fij,fmj->fmi", r, self.positions) + t[:, None, :]

    def replace(self, step: dict | None = None, **changes) -> "Capture":
        """A copy with ``changes`` applied and, when given, ``step`` appended to the history."""
        if step is not None:
            changes["history"] = self.history + (dict(step),)
        return dataclasses.replace(self, **changes)

    def check_not_all_invalid(self) -> None:
        """Raise MarkerError naming markers that have no valid sample at all."""
        dead = [n for n, ok in zip(self.names, self.valid.any(axis=0)) if not ok]
        if dead:
            raise MarkerError(
                f"capture{(' ' + self.source) if self.source else ''}: no valid sample for marker(s) {list_names(dead)}"
            )


def hold_invalid(positions: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Replace invalid samples by the last valid one (the first valid one before any).

    Parameters
    ----------
    positions : ndarray, shape (F, M, D)
    valid : ndarray, shape (F, M), bool

    Returns
    -------
    ndarray, shape (F, M, D), with no NaN for markers that have at least one valid sample.
    """
    f = positions.shape[0]
    idx = np.where(valid, np.arange(f)[:, None], -1)
    np.maximum.accumulate(idx, axis=0, out=idx)
    first = valid.argmax(axis=0)
    idx = np.where(idx < 0, first[None, :], idx)
    return np.take_along_axis(positions, idx[:, :, None], axis=0)


def _check_window(window, neutral_frame: int, n_frames: int, where: str) -> tuple[int, int]:
    """``(start, end)`` as ints with ``0 <= start <= neutral_frame < end <= n_frames``."""
    try:
        a, b = (int(v) for v in window)
        ok = all(float(v) == int(v) for v in window)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise MarkerError(f"capture{where}: neutral window must be two frame indices (start, end); got {window!r}")
    if not 0 <= a <= neutral_frame < b <= n_frames:
        raise MarkerError(f"capture{where}: neutral window [{a}, {b}) must hold the neutral frame {neutral_frame} "
                          f"and lie within 0..{n_frames}")
    return (a, b)
