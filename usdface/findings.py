"""Plausibility findings: the check codes, what accepts them (``--allow CODE``), and how a list
of findings is applied (:func:`report`, :func:`refuse`).

The checks themselves live with what they judge: :mod:`usdface.capture.plausibility` (a
capture's markers), :mod:`usdface.io.limits` (frame counts, rates, resampling, judged by
the readers before they allocate), the binding checks in :mod:`usdface.mesh.judgement`.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from .errors import OptionError, PlausibilityError

if TYPE_CHECKING:  # numpy only names a field's type: `usdface --help` (which lists CHECKS) stays numpy-free
    import numpy as np

log = logging.getLogger("usdface")

__all__ = ["Check", "CHECKS", "Finding", "parse_allow", "refuse", "report"]


@dataclass(frozen=True)
class Check:
    """One plausibility check: its code, default severity, and what accepts or changes it."""

    code: str
    severity: str  # "error" | "warning"
    override: str
    summary: str


CHECKS: dict[str, Check] = {c.code: c for c in (
    Check("zeros", "warning", "--keep-zeros", "exact (0, 0, 0) samples of a C3D file read as gaps"),
    Check("outliers", "error", "--drop-outliers or --allow outliers",
          "samples far from where the neighbouring markers put them"),
    Check("far-markers", "error", "--allow far-markers", "markers far from every other marker all take long"),
    Check("mixed-units", "error", "--allow mixed-units", "some markers a unit factor larger than the others"),
    Check("face-size", "error", "--allow face-size", "markers or mesh span outside 3-80 cm in the declared units"),
    Check("speed", "warning", "--allow speed", "markers faster than 6 face spans per second"),
    Check("stabilize", "warning", "--allow stabilize", "stabilisation that does not reduce the held-out rigid motion"),
    Check("layout-distance", "error", "--allow layout-distance", "layout points far off the mesh surface"),
    Check("fit-residual", "error", "--allow fit-residual", "markers far from their layout points after the fit"),
    Check("unit-scale", "error", "--allow unit-scale", "a fitted capture-to-mesh scale contradicting the units"),
    Check("rate", "error", "--allow rate", "a capture rate outside 1-10000 Hz"),
    Check("frame-count", "error", "--allow frame-count",
          "more than 1,000,000 frames, or frame numbers spanning far more frames than the file holds"),
    Check("resample", "error", "--allow resample",
          "resampling to a rate outside 1-10000 Hz, by more than 100x, or to fewer than 2 frames"),
)}


@dataclass(frozen=True)
class Finding:
    """One plausibility finding.

    Attributes
    ----------
    code : str
        A key of :data:`CHECKS`.
    severity : str
        ``"error"`` or ``"warning"`` (as found; :func:`report` applies ``--allow``).
    message : str
        One line naming the file, markers, frames and the option that accepts it.
    markers : tuple of str
    frames : tuple of int
        Frame numbers (time codes) concerned, if any.
    samples : ndarray (F, M) bool, optional
        For ``outliers``: the offending samples (used by :func:`drop_outliers`).
    """

    code: str
    severity: str
    message: str
    markers: tuple = ()
    frames: tuple = ()
    samples: np.ndarray | None = field(default=None, repr=False, compare=False)

    def summary(self, *, allowed: bool = False) -> dict:
        return {"code": self.code, "severity": self.severity, "allowed": allowed, "message": self.message,
                "markers": list(self.markers), "frames": [int(f) for f in self.frames[:100]]}


def parse_allow(values) -> frozenset:
    """Validate ``--allow`` values (codes, lists, or comma-separated text) into a set of codes."""
    if values is None:
        return frozenset()
    if isinstance(values, str):
        values = [values]
    codes = set()
    for v in values:
        for code in str(v).split(","):
            code = code.strip()
            if not code:
                continue
            if code not in CHECKS:
                raise OptionError(f"--allow {code}: not a plausibility check; known: {', '.join(CHECKS)}")
            codes.add(code)
    return frozenset(codes)


def refuse(findings, *, allow=frozenset()) -> None:
    """Raise :class:`~usdface.errors.PlausibilityError` with every error of ``findings`` that
    ``allow`` does not accept (one message); accepted ones pass silently (a reader's gate: the
    command reports accepted findings once, from the capture's own checks)."""
    allow = parse_allow(allow)
    errors = [f for f in findings if f is not None and f.severity == "error" and f.code not in allow]
    if errors:
        raise PlausibilityError("; ".join(f.message for f in errors), findings=errors)


def report(findings, *, allow=frozenset(), what: str = "") -> list[dict]:
    """Apply ``allow`` to ``findings``: raise on errors not allowed, log the rest.

    Returns the findings as JSON-ready dicts (for the command's summary). Raises
    :class:`~usdface.errors.PlausibilityError` with every unaccepted error in one message.
    """
    allow = parse_allow(allow)
    refuse(findings, allow=allow)
    out = []
    for f in findings:
        allowed = f.code in allow
        if f.severity == "error":
            log.warning("%s (accepted by --allow %s)", f.message, f.code)
        elif allowed:
            log.info("%s", f.message)
        else:
            log.warning("%s", f.message)
        out.append(f.summary(allowed=allowed))
    return out
