"""USD's own diagnostics, turned into usdface's one-line messages.

USD reports problems in two ways: a TF_ERROR becomes a ``Tf.ErrorException`` whose text is
wrapped in C++ decorations (``Error in 'pxrInternal_v0_26_11__pxrReserved__::UsdStage::Open' at
line 1287 in file /opt/USD/...``) with USD's real message, such as a parse error's
``file:line:col``, inside; a TF_WARNING (a missing sublayer, a cycle of sublayers, an unresolved
reference) is printed straight to stderr. :func:`trapped` catches the warnings while a stage or
layer opens (``Tf.DiagnosticTrap``), and :func:`error_text` / :func:`warning_text` keep USD's
message without the C++ source locations and namespaces.
"""
from __future__ import annotations

import contextlib
import os
import re
from typing import NamedTuple

from pxr import Tf

__all__ = ["Diagnostic", "trapped", "error_text", "warning_text"]

_NAMESPACE = re.compile(r"pxrInternal_v[0-9_]+?__pxrReserved__+(?:_?pegtl)?::(?:internal::)?")
_STAGE_SUFFIX = re.compile(r"\s*\(instantiating stage on stage @[^@]*@ <0x[0-9a-f]+>\)\s*$")
_GENERIC_OPEN = re.compile(r"^Failed to open layer @[^@]*@$")
_MISSING_SUBLAYER = re.compile(r"Could not load sublayer @(?P<asset>[^@]+)@ of layer @(?P<layer>[^@]+)@")
_MISSING_ASSET = re.compile(r"In <(?P<prim>[^>]*)>: Could not open asset @(?P<asset>[^@]+)@ for (?P<arc>\w+) "
                            r"introduced by @(?P<layer>[^@]+)@")
_CYCLE = re.compile(r"Sublayer hierarchy with root layer @(?P<root>[^@]+)@ has cycles")


class Diagnostic(NamedTuple):
    """A USD warning as one line; ``composition``: it says the stage is incomplete (reported by
    the stage's composition: a missing or unreadable layer, a cycle, an unresolved path)."""

    text: str
    composition: bool


@contextlib.contextmanager
def trapped():
    """Catch USD's warnings and statuses while the block runs; yields the list of
    :class:`Diagnostic` they are put in. Errors still raise as Tf.ErrorException."""
    found: list[Diagnostic] = []
    with Tf.DiagnosticTrap() as trap:
        try:
            yield found
        finally:
            for w in list(trap.GetWarnings()) + list(trap.GetStatuses()):
                found.append(Diagnostic(warning_text(w), "_ReportErrors" in str(w.sourceFunction)))
            trap.Clear()  # cleared, not reposted: nothing reaches stderr


def _commentary(diagnostic) -> str:
    try:
        text = diagnostic.commentary
    except UnicodeDecodeError:
        # the parser quotes the offending text, which is not UTF-8 (a .usda file must be)
        return "the file holds bytes that are not UTF-8 text (a .usda layer is UTF-8)"
    return _NAMESPACE.sub("", str(text)).strip()


def error_text(exc: BaseException) -> str:
    """USD's message(s) in a Tf.ErrorException, most specific first, without C++ decorations."""
    texts = []
    for arg in getattr(exc, "args", ()):
        text = _commentary(arg) if hasattr(arg, "sourceFileName") else _NAMESPACE.sub("", str(arg)).strip()
        if text and text not in texts:
            texts.append(text)
    specific = [t for t in texts if not _GENERIC_OPEN.match(t)]
    return "; ".join(specific or texts) or type(exc).__name__


def warning_text(diagnostic) -> str:
    """One line for a USD warning, in usdface's words for the composition problems it knows."""
    text = _STAGE_SUFFIX.sub("", _commentary(diagnostic))
    m = _MISSING_SUBLAYER.search(text)
    if m:
        state = "cannot be read" if os.path.exists(m["asset"]) else "not found"
        return f"sublayer {m['asset']} of {m['layer']} {state}"
    m = _MISSING_ASSET.search(text)
    if m:
        state = "cannot be read" if os.path.exists(m["asset"]) else "not found"
        return f"{m['arc']} {m['asset']} of prim <{m['prim']}> in {m['layer']} {state}"
    m = _CYCLE.search(text)
    if m:
        return f"the sublayers of {m['root']} form a cycle"
    return text
