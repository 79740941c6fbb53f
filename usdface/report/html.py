"""One self-contained HTML file: plotly.js inlined once, figures as JSON, pictures as data URIs,
movies as relative links into a sibling folder. Opens from file:// with no network request."""
from __future__ import annotations

import base64
import html
import json
from pathlib import Path

from ..errors import DependencyError

__all__ = ["Page", "plotly_js"]

_CSS = """
body{font-family:-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:0;color:#222;background:#f2f3f5}
header{background:#24262b;color:#eee;padding:14px 24px}header h1{margin:0;font-size:21px}
header p{margin:4px 0 0;color:#aab;font-size:13px}main{padding:12px 24px 40px;max-width:1400px}
section.shot{background:#fff;border-radius:6px;padding:8px 18px 18px;margin:16px 0;box-shadow:0 1px 3px #0002}
h2{font-size:19px;margin:12px 0 6px}h3{font-size:15px;margin:18px 0 4px;color:#333}
p.note{color:#555;font-size:13px;margin:2px 0 8px;max-width:1000px}
.cards{display:flex;flex-wrap:wrap;gap:8px;margin:8px 0}.card{background:#f4f6f9;border-radius:5px;padding:6px 10px;
font-size:13px}.card b{display:block;font-size:16px}
table{border-collapse:collapse;font-size:12.5px;margin:6px 0}td,th{border-bottom:1px solid #e3e3e8;padding:3px 8px;
text-align:left;vertical-align:top}th{background:#f4f6f9}td.num{text-align:right;font-variant-numeric:tabular-nums}
.warn{background:#fff4e0;border-left:4px solid #f2b134;padding:6px 10px;font-size:13px;margin:6px 0}
td figure{margin:0}.err{color:#b00020}.ok{color:#2a7d2a}img.pic{max-width:100%;border:1px solid #ddd;border-radius:4px}
.pics{display:flex;flex-wrap:wrap;gap:12px;align-items:flex-start}.pics figure{margin:0}
figcaption{font-size:12px;color:#555}video{max-width:100%;background:#000;border-radius:4px}
.plot{width:100%;min-height:300px}details summary{cursor:pointer;font-size:13px;color:#345}
code{font-size:12px;background:#f4f6f9;padding:1px 4px;border-radius:3px}
"""

_BOOT = """
(function(){
  var errors = [];
  document.querySelectorAll('div.plot').forEach(function(div){
    try {
      var fig = JSON.parse(document.getElementById(div.getAttribute('data-src')).textContent);
      Plotly.newPlot(div, fig.data, fig.layout, {responsive: true, displaylogo: false,
                                                 modeBarButtonsToRemove: ['sendDataToCloud']});
    } catch (e) { errors.push(div.id + ': ' + e); console.error('usdface report: plot ' + div.id + ': ' + e); }
  });
  window.usdfaceReport = {plots: document.querySelectorAll('div.plot').length, errors: errors};
})();
"""


def plotly_js() -> str:
    """plotly.js as the plotly Python package ships it (MIT), to inline once per report."""
    try:
        from importlib.resources import files

        text = (files("plotly") / "package_data" / "plotly.min.js").read_text(encoding="utf-8")
    except (ImportError, ModuleNotFoundError, FileNotFoundError) as exc:
        raise DependencyError('reports need plotly (its plotly.js is embedded in the HTML): pip install '
                              '"usdface[media]"') from exc
    return text


def esc(value) -> str:
    return html.escape(str(value), quote=True)


class Page:
    """An HTML page built piece by piece; :meth:`render` gives the whole text."""

    def __init__(self, title: str, subtitle: str = ""):
        self.title, self.subtitle = title, subtitle
        self.parts: list[str] = []
        self._figs: list[str] = []

    def add(self, text: str) -> None:
        self.parts.append(text)

    def heading(self, text: str, level: int = 3, anchor: str | None = None) -> None:
        a = f' id="{esc(anchor)}"' if anchor else ""
        self.add(f"<h{level}{a}>{esc(text)}</h{level}>")

    def note(self, text: str, *, raw: bool = False) -> None:
        self.add(f'<p class="note">{text if raw else esc(text)}</p>')

    def warning(self, text: str) -> None:
        self.add(f'<div class="warn">{esc(text)}</div>')

    def cards(self, items) -> None:
        self.add('<div class="cards">' + "".join(f'<div class="card"><b>{esc(v)}</b>{esc(k)}</div>'
                                                 for k, v in items) + "</div>")

    def table(self, header, rows, *, raw_columns=(), numeric=()) -> None:
        head = "".join(f"<th>{esc(h)}</th>" for h in header)
        body = []
        for row in rows:
            cells = []
            for k, v in enumerate(row):
                cls = ' class="num"' if k in numeric else ""
                cells.append(f"<td{cls}>{v if k in raw_columns else esc(v)}</td>")
            body.append("<tr>" + "".join(cells) + "</tr>")
        self.add(f"<table><tr>{head}</tr>{''.join(body)}</table>")

    def figure(self, fig: dict, caption: str = "") -> str:
        """Add a plotly figure; returns its element id."""
        k = len(self._figs)
        fid = f"plot-{k}"
        payload = json.dumps({"data": fig["data"], "layout": fig["layout"]}, separators=(",", ":"), allow_nan=False)
        self._figs.append(f'<script type="application/json" id="{fid}-data">{payload.replace("</", "<" + chr(92) + "/")}'
                          "</script>")
        key = esc(fig.get("key", ""))
        self.add(f'<div class="plot" id="{fid}" data-src="{fid}-data" data-key="{key}"></div>')
        if caption:
            self.note(caption)
        return fid

    def picture(self, data: bytes, caption: str = "", *, alt: str = "", width: int | None = None) -> str:
        kind = "png" if data[:8] == b"\x89PNG\r\n\x1a\n" else "jpeg"
        src = f"data:image/{kind};base64," + base64.b64encode(data).decode("ascii")
        w = f' style="max-width:{int(width)}px"' if width else ""
        return (f'<figure><img class="pic" src="{src}" alt="{esc(alt or caption)}"{w}>'
                f"<figcaption>{esc(caption)}</figcaption></figure>")

    def pictures(self, items) -> None:
        self.add('<div class="pics">' + "".join(items) + "</div>")

    def video(self, rel_path: str, caption: str = "", *, width: int = 960) -> None:
        src = esc(Path(rel_path).as_posix())
        self.add(f'<figure><video controls preload="metadata" src="{src}" style="width:{int(width)}px"></video>'
                 f'<figcaption>{esc(caption)} (<a href="{src}">{src}</a>)</figcaption></figure>')

    def render(self) -> str:
        from .. import __version__

        sub = f"<p>{esc(self.subtitle)}</p>" if self.subtitle else ""
        return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                f"<meta name=\"generator\" content=\"usdface {esc(__version__)}\">"
                f"<title>{esc(self.title)}</title><style>{_CSS}</style>"
                f"<script>{plotly_js()}</script></head><body>"
                f"<header><h1>{esc(self.title)}</h1>{sub}</header><main>"
                + "\n".join(self.parts) + "</main>" + "\n".join(self._figs)
                + f"<script>{_BOOT}</script></body></html>\n")
