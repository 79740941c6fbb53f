"""QC reports: one self-contained HTML page per shot or batch (see ``usdface report``).

- :mod:`.data` — :func:`gather_shot`: the numbers of a run's output folder (:class:`ShotData`),
  from the summary, the shot's reader and the capture the report pipeline hands over (no USD here);
- :mod:`.plots` — plotly figure specifications (plain dicts) of those numbers;
- :mod:`.pictures` — contact sheet, binding, displacement and hybrid-weight pictures (JPEG bytes);
- :mod:`.sections` — hooks for optional sections (the blend-shape solve);
- :mod:`.html`, :mod:`.build` — the page; :mod:`.output` — the page and its media folder on disk.

plotly (for its plotly.js) is needed when a page is written, not at import.
"""
from ..lazy import lazy_exports

#: public name -> submodule, loaded on first use
_EXPORTS = {"ShotData": "data", "gather_shot": "data", "load_run_summary": "data", "find_shot": "data",
            "Section": "sections", "register": "sections", "check_report_output": "output"}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())

__all__ = ["Section", "ShotData", "check_report_output", "find_shot", "gather_shot", "load_run_summary", "register"]
