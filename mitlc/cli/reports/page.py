"""The HTML of a report: one file with its styles, script, data and pictures inline.

:func:`report_html` takes what :mod:`~mitlc.cli.reports.training` or
:mod:`~mitlc.cli.reports.sweep` gathered and returns the page's text. Tables are written here,
as HTML; the charts and the net's animation are drawn in the browser by ``report.js`` from the
page's JSON data (``<script type="application/json" id="report-data">``). A first small script
records any script error or ``console.error`` on the page (``data-errors`` on ``<html>``, and
``#report-errors``), and the main script marks the page ``data-ready="1"`` when it has run to its
end: what tests/test_report.py reads in headless Chromium.
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Callable
from importlib import resources
from pathlib import Path
from typing import Any

__all__ = ["REPORT", "BODIES", "GENERATOR", "is_report", "report_html", "embed_json", "viridis"]

REPORT = "report.html"
"""The report's file name in the folder it describes."""

_RECORDER = """
(function () {
  var seen = [];
  function record(what) {
    seen.push(String(what));
    document.documentElement.setAttribute("data-errors", String(seen.length));
    var box = document.getElementById("report-errors");
    if (box) { box.textContent = seen.join("\\n"); }
  }
  window.addEventListener("error", function (e) { record(e.message || "error"); });
  window.addEventListener("unhandledrejection", function (e) { record(e.reason); });
  var original = console.error;
  console.error = function () {
    record(Array.prototype.join.call(arguments, " "));
    original.apply(console, arguments);
  };
})();
"""


GENERATOR = '<meta name="generator" content="mitlc report">'
"""The line that makes a ``report.html`` mitlc's (:func:`is_report`)."""


def is_report(path: Path) -> bool:
    """Whether ``path`` is a page mitlc wrote (so mitlc may replace or remove it); a user's file of that
    name is never touched."""
    try:
        with path.open("rb") as f:
            head = f.read(600)
    except OSError:
        return False
    return GENERATOR.encode() in head


def _asset(name: str) -> str:
    return resources.files("mitlc.cli.reports").joinpath(name).read_text(encoding="utf-8")


def embed_json(data: Any) -> str:
    """``data`` as JSON that is safe inside a ``<script>`` element (no ``</`` to close it early)."""
    text = json.dumps(data, separators=(",", ":"), allow_nan=False, ensure_ascii=False)
    return text.replace("</", "<\\/").replace("<!--", "<\\!--")


def _e(v: object) -> str:
    return html.escape(str(v), quote=True)


def _fmt(v: object, digits: int = 3) -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        if not math.isfinite(v):
            return str(v)
        return (
            f"{v:.{digits}g}"
            if abs(v) >= 1e4 or (v != 0 and abs(v) < 1e-3)
            else f"{v:.{digits}f}".rstrip("0").rstrip(".")
        )
    return str(v)


def viridis(v: float) -> str:
    """A colour for ``v`` in [0, 1] on matplotlib's viridis scale (five stops, linearly between),
    as sweep.png draws its heat map."""
    stops = [(68, 1, 84), (59, 82, 139), (33, 145, 140), (94, 201, 98), (253, 231, 37)]
    v = min(1.0, max(0.0, v)) * (len(stops) - 1)
    i = min(int(v), len(stops) - 2)
    f = v - i
    rgb = [round(a + (b - a) * f) for a, b in zip(stops[i], stops[i + 1], strict=True)]
    return "#" + "".join(f"{c:02x}" for c in rgb)


def _page(title: str, body: str, data: Any, script: bool, reload_s: int | None = None) -> str:
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        GENERATOR,
        f'<meta http-equiv="refresh" content="{int(reload_s)}">' if reload_s else "",
        f"<title>{_e(title)}</title>",
        f"<script>{_RECORDER}</script>",
        f"<style>{_asset('report.css')}</style>",
        "</head>",
        "<body>",
        body,
        '<pre id="report-errors"></pre>',
        f'<script type="application/json" id="report-data">{embed_json(data)}</script>',
        f"<script>{_asset('report.js')}</script>"
        if script
        else "<script>document.documentElement.setAttribute('data-ready', '1');</script>",
        "</body>",
        "</html>",
        "",
    ]
    return "\n".join(parts)


def _table(
    head: list[str], rows: list[list[str]], numeric: set[int] | None = None, row_attrs: list[str] | None = None
) -> str:
    numeric = numeric or set()
    out = ["<table>", "<thead><tr>"]
    out += [f"<th{' class=num' if i in numeric else ''}>{_e(h)}</th>" for i, h in enumerate(head)]
    out.append("</tr></thead><tbody>")
    for j, row in enumerate(rows):
        attrs = row_attrs[j] if row_attrs else ""
        cells = "".join(f"<td{' class=num' if i in numeric else ''}>{c}</td>" for i, c in enumerate(row))
        out.append(f"<tr{attrs}>{cells}</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


def _kv_table(items: dict[str, Any]) -> str:
    rows = [[_e(k), _e(json.dumps(v) if isinstance(v, dict | list) else _fmt(v))] for k, v in items.items()]
    return _table(["name", "value"], rows)


def _notes(notes: list[str]) -> str:
    return "".join(f'<p class="notes">{_e(n)}</p>' for n in notes)


_VERDICT_HEAD = [
    "run",
    "verdict",
    "robustness",
    "failing part",
    "violated at",
    "greedy return",
    "final return",
    "diverged at trial",
]


def _training_body(d: dict[str, Any]) -> str:
    s = d["summary"]
    rate = s.get("success_rate")
    wall = f"{_fmt(s['wall_s'], 1)} s" if s.get("wall_s") is not None else "–"
    parts = [
        f"<h1>{_e(d['title'])} <span class=muted>— training {_e(d['folder'])}</span></h1>",
        '<div class="summary">',
        f"<span>learner <b>{_e(s['learner'])}</b></span>",
        f"<span>runs <b>{_e(s['runs'])}</b></span>",
        f"<span>trials <b>{_e(s['trials'])}</b></span>",
        f"<span>seed <b>{_e(_fmt(s['seed']))}</b></span>",
        f"<span>success rate <b>{_e(_fmt(rate, 2)) if rate is not None else '–'}</b></span>",
        f"<span>training time <b>{_e(wall)}</b></span>",
        "</div>",
        _notes(d["notes"]),
    ]
    if d.get("formula") or d.get("spec_source"):
        parts.append("<h2>Spec and reward</h2>")
    if d.get("spec_source"):
        parts.append(f"<pre>{_e(d['spec_source'].rstrip())}</pre>")
    if d.get("formula"):
        parts.append(
            f"<p>formula <code>{_e(d.get('formula'))}</code>; "
            f"judged by the monitor on <code>{_e(d.get('check'))}</code></p>"
        )
    if d.get("reward"):
        parts.append(
            "<p>compiled reward r(M<sub>k</sub>, M<sub>k+1</sub>) (p: tokens in place p at step k+1, ~p: at step k):"
            "</p>"
            f'<pre class="wrap">{_e(d["reward"])}</pre>'
        )
    ro = d.get("rollout")
    if ro is not None:
        options = "".join(
            f'<option value="{r}">run {r} ({"satisfied" if v["verdict"] else "violated"})</option>'
            for r, v in enumerate(d["verdicts"])
        )
        parts += [
            "<h2>A run's greedy rollout</h2>",
            "<p class=muted>From the run's evaluation start, as mitlc train judged it. The net's marking at each step "
            "is the runtime's, stepped along this rollout; a marked place is yellow, with its tokens.</p>",
            '<div class="controls">',
            f'<label>run <select id="run">{options}</select></label>',
            '<button id="play" type="button">▶ play</button>',
            '<input id="step" type="range" min="0" max="0" value="0" step="1" aria-label="step">',
            '<span id="step-label"></span>',
            "</div>",
            '<p>this run: <span id="run-verdict"></span></p>',
            '<div class="rollout">',
            f'<div id="net">{d["net_svg"] or "<p class=muted>(the net is not drawn)</p>"}</div>',
            '<div id="trajectory"></div>',
            "</div>",
        ]
    parts += ["<h2>Learning curves</h2>", '<div id="curves"></div>']
    rows, attrs = [], []
    for r, v in enumerate(d["verdicts"]):
        verdict = (
            "–"
            if v["verdict"] is None
            else '<span class="ok">satisfied</span>'
            if v["verdict"]
            else '<span class="bad">violated</span>'
        )
        rob = v.get("robustness_text") or _fmt(v.get("robustness"))
        rows.append(
            [
                str(r),
                verdict,
                _e(rob),
                _e(v.get("failing") or "–"),
                _e(_fmt(v.get("violation_time"))) + (" s" if v.get("violation_time") is not None else ""),
                _e(_fmt(v.get("greedy_return"), 1)),
                _e(_fmt(v.get("final_return"), 1)),
                _e(v["diverged"]) if v.get("diverged") is not None else "–",
            ]
        )
        attrs.append(f' class="run-row" data-run="{r}"' if ro is not None else "")
    if rows:
        parts += [
            "<h2>Verdicts</h2>",
            (
                "<p class=muted>Each run's verdict by the criteria, as metrics.json records it."
                if s["learner"] == "hyrl"
                else "<p class=muted>Each run's greedy rollout judged by the monitor: the verdict, the robustness, "
                "the smallest failing part of the formula and the time from which the violation was certain."
            )
            + (" Click a row to see its rollout." if ro is not None else "")
            + "</p>",
            f'<div id="verdicts">{_table(_VERDICT_HEAD, rows, {0, 2, 4, 5, 6, 7}, attrs)}</div>',
        ]
    parts.append("<h2>Settings and versions</h2>")
    if d["options"]:
        parts += ["<h3>compile options</h3>", _kv_table(d["options"])]
    if d["settings"]:
        parts += ["<h3>trainer settings</h3>", _kv_table(d["settings"])]
    if d.get("race"):
        parts += [
            "<details><summary>the race of exploration designs</summary>",
            f"<pre>{_e(json.dumps(d['race'], indent=1))}</pre></details>",
        ]
    parts += ["<h3>folder and versions</h3>", _kv_table({**d["manifest"], **d["versions"]})]
    return "\n".join(parts)


def _sweep_body(d: dict[str, Any]) -> str:
    from mitlc.cli.reports.sweep import sweep_body

    return sweep_body(d)


def _verification_body(d: dict[str, Any]) -> str:
    from mitlc.cli.reports.verification import verification_body

    return verification_body(d)


BODIES: dict[str, Callable[[dict[str, Any]], str]] = {
    "training": _training_body,
    "sweep": _sweep_body,
    "verification": _verification_body,
}
"""A page's kind -> its body's HTML from the gathered data (:data:`mitlc.cli.report.KINDS` gathers it)."""


def report_html(data: dict[str, Any]) -> str:
    """The page of a training's (``data["kind"] == "training"``), a sweep's or another kind's data
    (:data:`BODIES`). A training's data go into the page for its script (but for the net's SVG, which is
    in the page already); a sweep's and a verification's pages are all HTML."""
    kind = data["kind"]
    title = f"{data['title']}: mitlc {kind} report"
    if kind == "training":
        page_data = {k: v for k, v in data.items() if k != "net_svg"}
        return _page(title, BODIES[kind](data), page_data, script=True, reload_s=data.get("reload_s"))
    return _page(title, BODIES[kind](data), {"kind": kind}, script=False, reload_s=data.get("reload_s"))
