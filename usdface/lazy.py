"""Package names loaded on first use (PEP 562), so that importing one light module of a package
(the options read a package's constants) does not load the package's heavy modules (numba kernels,
scipy) at the command line's start-up."""
from __future__ import annotations

import importlib
from typing import Callable


def lazy_exports(package: str, exports: dict[str, str], namespace: dict) -> tuple[Callable, Callable]:
    """``(__getattr__, __dir__)`` for ``package`` whose public names live in submodules.

    ``exports``: {public name: submodule (relative, without the dot)}; ``namespace``: the
    package's ``globals()``, where a loaded name is kept so the next access is a plain lookup.
    """
    def __getattr__(name: str):
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{module}"), name)
        namespace[name] = value
        return value

    def __dir__():
        return sorted(set(namespace) | set(exports))

    return __getattr__, __dir__
