"""The ``usdface`` command's entry point (kept for ``usdface.cli:main``, the installed script of
usdface 0.2): the command lives in :mod:`usdface.console`."""
from .console import build_parser, main

__all__ = ["main", "build_parser"]

if __name__ == "__main__":
    raise SystemExit(main())
