"""One exception hierarchy for usdface.

Every error names what is wrong (file, prim, marker, option) and what was expected, so the CLI can
print it as is and exit non-zero.
"""
from __future__ import annotations


class UsdFaceError(Exception):
    """Base class of every error usdface raises on purpose."""


class InputError(UsdFaceError):
    """A file, prim or value given to usdface is missing, unreadable or malformed."""


class FormatError(InputError):
    """A file could be opened but its content is not what its format requires."""


class OptionError(UsdFaceError):
    """A command-line option or keyword argument has a bad or conflicting value."""


class MarkerError(InputError):
    """Marker sets disagree (names missing, duplicated, all invalid...)."""


class MeshError(InputError):
    """A mesh has no faces, degenerate faces, or topology usdface cannot use."""


class PlausibilityError(InputError):
    """Data that reads fine but cannot be what it claims (a marker 50 cm off the face, a capture in
    metres declared cm...). The message names each finding and the ``--allow`` option that accepts
    it (:mod:`usdface.capture.plausibility`)."""

    def __init__(self, message: str, findings=()):
        super().__init__(message)
        self.findings = tuple(findings)


class ComputeError(UsdFaceError):
    """A computation cannot give a meaningful result (singular system, infinite distances...)."""


class ResourceError(UsdFaceError):
    """Not enough memory or disk for the requested work; the message says the estimate."""


class SchemaRegistrationError(UsdFaceError):
    """usdface's USD schemas could not be registered in this process."""


def list_names(names, limit: int = 12) -> str:
    """Format a list of names for an error message, abbreviated past ``limit``."""
    names = list(names)
    shown = ", ".join(str(n) for n in names[:limit])
    if len(names) > limit:
        shown += f", ... ({len(names)} in all)"
    return shown
