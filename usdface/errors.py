"""One exception hierarchy for usdface.

Every error names what is wrong (file, prim, marker, option) and what was expected, so the CLI can
print it as is and exit non-zero: ``exit_code`` 2 for bad input or usage (the class default), 1 for
a failure of the environment while working (:class:`EnvironmentFault`: disk full, read-only
folder, permission, memory, a folder locked by another run).
"""
from __future__ import annotations


class UsdFaceError(Exception):
    """Base class of every error usdface raises on purpose."""

    #: the command line's exit code for this error (2: bad input or usage)
    exit_code = 2


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


class MixedLayersError(InputError):
    """Layers made for different meshes, takes or bound markers given together (a binding made on
    another face, an analysis of other bound points, an animation of another take): the message
    names both files and the identities that differ (:mod:`usdface.usd.identity`)."""


class PlausibilityError(InputError):
    """Data that reads fine but cannot be what it claims (a marker 50 cm off the face, a capture in
    metres declared cm...). The message names each finding and the ``--allow`` option that accepts
    it (:mod:`usdface.capture.plausibility`)."""

    def __init__(self, message: str, findings=()):
        super().__init__(message)
        self.findings = tuple(findings)


class ComputeError(UsdFaceError):
    """A computation cannot give a meaningful result (singular system, infinite distances...)."""


class EnvironmentFault(UsdFaceError):
    """The machine, not the input, stopped the work: a file could not be written or read (disk full,
    read-only file system, permission), memory ran out, or a folder is in use. Exit code 1."""

    exit_code = 1


class ResourceError(EnvironmentFault):
    """Not enough memory or disk for the requested work; the message says the estimate."""


class WriteError(EnvironmentFault):
    """A file could not be written; the message names the file and the cause (disk full, ...)."""


class LockedError(EnvironmentFault):
    """An output folder is being written by another usdface process (named with host and pid)."""


def stop_signals() -> tuple:
    """The signals that stop a usdface command and remove its partial work, as this platform has
    them: SIGINT (Ctrl-C), SIGTERM (a farm scheduler), SIGHUP (a closed terminal or ssh session)."""
    import signal

    return tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


class Interrupted(KeyboardInterrupt):
    """The process was asked to stop (SIGINT = Ctrl-C, exit 130; SIGTERM = a scheduler, exit 143;
    SIGHUP = a closed terminal, exit 129).

    A KeyboardInterrupt, so every ``finally`` runs and the partial work is removed as for Ctrl-C.
    """

    def __init__(self, signum: int):
        import signal

        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


class DependencyError(EnvironmentFault):
    """An optional dependency (or a part of it, such as an encoder) is missing; the message names
    the extra or package to install."""


class SchemaRegistrationError(UsdFaceError):
    """usdface's USD schemas could not be registered in this process."""


def list_names(names, limit: int = 12) -> str:
    """Format a list of names for an error message, abbreviated past ``limit``."""
    names = list(names)
    shown = ", ".join(str(n) for n in names[:limit])
    if len(names) > limit:
        shown += f", ... ({len(names)} in all)"
    return shown
