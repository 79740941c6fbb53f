"""What every processor returns: the layers and files it wrote, its summary and its report."""
from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Result"]


@dataclass
class Result:
    """One processor's result.

    Attributes
    ----------
    layers : dict
        {output name: the layer written}: an ``Sdf.Layer`` when the output was authored in memory
        (the Python API's ``into``), else the file's path (str).
    files : dict
        {output name: path} of the other files written (CSV, PNG, JSON, movies...). Non-USD
        outputs are written only where a path was given.
    summary : dict
        What ``usdface COMMAND --json`` prints: plain JSON types.
    text : list of str
        The lines ``usdface COMMAND`` prints.
    exit_code : int
        0, or 1 when the processor ran but found errors (``check``, a batch with failed shots).
    """

    layers: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)
    summary: dict = field(default_factory=dict, repr=False)
    text: list = field(default_factory=list, repr=False)
    exit_code: int = 0
    #: what the usdface 0.2 API function returned where that was not a Result (a summary dict, a
    #: list of findings): reading a Result as that still works for one minor version, with a
    #: DeprecationWarning
    legacy: Any = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        # files by their path as text (a Path, a str); in-memory layers stay the objects
        self.layers = {k: os.fspath(v) if isinstance(v, os.PathLike) else v for k, v in self.layers.items()}
        self.files = {k: os.fspath(v) if isinstance(v, os.PathLike) else v for k, v in self.files.items()}

    @classmethod
    def from_summary(cls, summary: dict, *, layers: dict | None = None, files: dict | None = None) -> "Result":
        """A Result from a summary dict whose ``_text`` and ``_exit`` keys hold the printed lines and
        the exit code (private keys are taken out of the summary)."""
        public = {k: v for k, v in summary.items() if not k.startswith("_")}
        return cls(layers=dict(layers or {}), files=dict(files or {}), summary=public,
                   text=list(summary.get("_text", [])), exit_code=int(summary.get("_exit", 0)))

    @property
    def layer(self):
        """The first layer written (most processors write one)."""
        return next(iter(self.layers.values()), None)

    @property
    def ok(self) -> bool:
        return self.exit_code == 0

    def __bool__(self) -> bool:  # a Result is always true, whatever its legacy length
        return True

    # -- the 0.2 return types, for one minor version --------------------------------------------

    def _legacy(self, what: str):
        if self.legacy is None:
            raise TypeError(f"a Result is not a {what}: use .summary, .layers, .files or .text")
        warnings.warn(f"this usdface.api function returns a Result since usdface 0.3; use .summary (the dict it "
                      f"returned before) or .summary['findings'] ({what} access is deprecated and goes in 0.4)",
                      DeprecationWarning, stacklevel=3)
        return self.legacy

    def __getitem__(self, key):
        return self._legacy("mapping or list")[key]

    def __iter__(self):
        return iter(self._legacy("mapping or list"))

    def __len__(self):
        return len(self._legacy("mapping or list"))

    def __contains__(self, key):
        return key in self._legacy("mapping or list")

    def get(self, key, default=None):
        return self._legacy("mapping").get(key, default)

    def keys(self):
        return self._legacy("mapping").keys()

    def items(self):
        return self._legacy("mapping").items()

    def values(self):
        return self._legacy("mapping").values()
