"""QC reports: one self-contained HTML page per shot or batch (see ``usdface report``).

- :mod:`.data` — :func:`gather_shot`: the numbers of a run's output folder (:class:`ShotData`);
- :mod:`.plots` — plotly figure specifications (plain dicts) of those numbers;
- :mod:`.pictures` — contact sheet, binding, displacement and hybrid-weight pictures (PNG bytes);
- :mod:`.sections` — hooks for optional sections (the blend-shape solve);
- :mod:`.html`, :mod:`.build` — the page.

plotly (for its plotly.js) is needed when a page is written, not at import.
"""
from .data import ShotData, gather_shot
from .sections import Section, register

__all__ = ["Section", "ShotData", "gather_shot", "register"]
