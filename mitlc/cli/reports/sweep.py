"""What a sweep's report shows, from its ``results.json``.

The grid as a table (one row per configuration: its axes' values, the seeds finished, the mean,
lowest and highest success rate, the final return, the monitor's blame of the failing runs) and a
heat map of the mean success rate over the first two swept axes (the others and the seeds averaged,
as ``sweep.png``). A sweep's task keeps no training folder of its own, so each cell links to its
configurations' rows, and each row to its seeds' records (the task's own training, as the sweep
recorded it: success, returns, blame, wall time, host).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from mitlc.errors import InputError

__all__ = ["sweep_data", "sweep_body"]

_TABLES = {"setting": "settings", "weight": "weights", "option": "options"}


def _label(v: Any) -> str:
    from mitlc.sweep.grid import format_value

    return format_value(v)


def sweep_data(folder: Path) -> dict[str, Any]:
    """The sweep's records grouped by configuration, with the axes' values in the order first met."""
    path = Path(folder) / "results.json"
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as exc:
        raise InputError(f"cannot read results.json: {exc}", file=str(folder)) from None
    if not isinstance(doc, dict) or doc.get("format") != "mitlc-sweep" or not isinstance(doc.get("results"), list):
        raise InputError("results.json is not a mitlc sweep's", file=str(folder))
    header = doc.get("header") or {}
    axes_doc = doc.get("axes") or {}
    axes = []
    for name, a in axes_doc.items():
        if not isinstance(a, dict) or a.get("kind") not in _TABLES:
            raise InputError(f"results.json: axis {name!r} is not a setting, weight or option", file=str(folder))
        axes.append({"name": name, "kind": a["kind"], "key": a.get("key"), "labels": []})
    configs: dict[tuple[str, ...], dict[str, Any]] = {}
    for rec in doc["results"]:
        if not isinstance(rec, dict):
            continue
        labels = []
        for a in axes:
            value = (rec.get(_TABLES[a["kind"]]) or {}).get(a["key"])
            label = _label(value)
            if label not in a["labels"]:
                a["labels"].append(label)
            labels.append(label)
        cfg = configs.setdefault(tuple(labels), {"labels": labels, "records": []})
        cfg["records"].append(rec)
    for a in axes:  # numbers in their order, words as met
        try:
            a["labels"].sort(key=float)
        except ValueError:
            pass
    rows = []
    for i, cfg in enumerate(sorted(configs.values(), key=lambda c: _order(axes, c["labels"]))):
        recs = sorted(cfg["records"], key=lambda r: r.get("seed", 0))
        rates = [r["success_rate"] for r in recs if isinstance(r.get("success_rate"), int | float)]
        finals = [r["final_return"] for r in recs if isinstance(r.get("final_return"), int | float)]
        failing: dict[str, int] = {}
        for r in recs:
            for part, n in (r.get("failing") or {}).items():
                failing[part] = failing.get(part, 0) + int(n)
        rows.append(
            {
                "id": f"cfg-{i}",
                "labels": cfg["labels"],
                "seeds": len(recs),
                "finished": len(rates),
                "mean": sum(rates) / len(rates) if rates else None,
                "min": min(rates) if rates else None,
                "max": max(rates) if rates else None,
                "final_return": sum(finals) / len(finals) if finals else None,
                "failing": failing,
                "records": recs,
            }
        )
    return {
        "kind": "sweep",
        "title": Path(str(header.get("spec") or folder)).name,
        "folder": Path(folder).name,
        "header": header,
        "axes": axes,
        "configs": rows,
    }


def _order(axes: list[dict[str, Any]], labels: list[str]) -> tuple[int, ...]:
    return tuple(a["labels"].index(v) for a, v in zip(axes, labels, strict=True))


def _heat(d: dict[str, Any]) -> str:
    from mitlc.cli.reports.page import _e, viridis

    swept = [i for i, a in enumerate(d["axes"]) if len(a["labels"]) > 1]
    if not swept:
        return "<p class=muted>nothing is swept: one configuration</p>"
    xi = swept[0]
    yi = swept[1] if len(swept) > 1 else None
    xa = d["axes"][xi]
    ya = d["axes"][yi] if yi is not None else None
    ylabels = ya["labels"] if ya else [""]
    out = ['<table class="heat">', "<thead><tr>", f"<th>{_e(ya['name']) if ya else ''} \\ {_e(xa['name'])}</th>"]
    out += [f"<th>{_e(v)}</th>" for v in xa["labels"]]
    out.append("</tr></thead><tbody>")
    for yv in reversed(ylabels):  # the highest value on top, as a plot's y axis
        out.append(f"<tr><th>{_e(yv)}</th>")
        for xv in xa["labels"]:
            cells = [c for c in d["configs"] if c["labels"][xi] == xv and (yi is None or c["labels"][yi] == yv)]
            rates = [
                r["success_rate"] for c in cells for r in c["records"] if isinstance(r.get("success_rate"), int | float)
            ]
            if not rates:
                out.append('<td class="cell">–</td>')
                continue
            mean = sum(rates) / len(rates)
            color = "#111" if mean > 0.6 else "#fff"
            target = cells[0]["id"]
            title = (
                f"{xa['name']}={xv}"
                + (f", {ya['name']}={yv}" if ya else "")
                + f": mean success {mean:.2f} over {len(rates)} tasks"
            )
            out.append(
                f'<td class="cell" style="background:{viridis(mean)};color:{color}">'
                f'<a href="#{target}" title="{_e(title)}">{mean:.2f}<br><small>({len(rates)})</small></a></td>'
            )
        out.append("</tr>")
    out.append("</tbody></table>")
    others = [a["name"] for i, a in enumerate(d["axes"]) if i in swept and i not in (xi, yi)]
    over = "seeds" + (" and " + ", ".join(others) if others else "")
    out.append(f"<p class=muted>mean success rate over {over} (tasks per cell); a cell links to its configurations</p>")
    return "\n".join(out)


def _num(v: Any, digits: int = 2) -> str:
    if not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v):
        return "–"
    return f"{v:.{digits}f}"


def sweep_body(d: dict[str, Any]) -> str:
    """The page's body: the heat map, the grid's table and each configuration's seeds."""
    from mitlc.cli.reports.page import _e

    h = d["header"]
    parts = [
        f"<h1>{_e(d['title'])} <span class=muted>— sweep {_e(d['folder'])}</span></h1>",
        '<div class="summary">',
        f"<span>configurations <b>{len(d['configs'])}</b></span>",
        f"<span>tasks <b>{sum(c['seeds'] for c in d['configs'])}</b></span>",
        f"<span>runs per task <b>{_e(h.get('runs', '–'))}</b></span>",
        f"<span>trials per run <b>{_e(h.get('trials', '–'))}</b></span>",
        "</div>",
        (
            f'<p class="notes">sweep in progress: the tasks finished so far. This page reloads every '
            f"{d['reload_s']} s; when the sweep ends, the full report replaces it.</p>"
            if d.get("reload_s")
            else ""
        ),
        "<h2>Success over the grid</h2>",
        _heat(d),
        "<h2>The grid</h2>",
        "<table><thead><tr>",
    ]
    names = [a["name"] for a in d["axes"]]
    heads = [*names, "seeds", "success (mean)", "min–max", "final return", "failing runs, by blame"]
    parts += [f"<th>{_e(n)}</th>" for n in heads]
    parts.append("</tr></thead><tbody>")
    for c in d["configs"]:
        blame = ", ".join(f"{k}: {v}" for k, v in sorted(c["failing"].items())) or "–"
        cells = [f"<td>{_e(v)}</td>" for v in c["labels"]]
        cells += [
            f"<td class=num>{c['finished']}/{c['seeds']}</td>",
            f'<td class=num><a href="#{c["id"]}">{_num(c["mean"])}</a></td>',
            f"<td class=num>{_num(c['min'])}–{_num(c['max'])}</td>",
            f"<td class=num>{_num(c['final_return'], 1)}</td>",
            f"<td>{_e(blame)}</td>",
        ]
        parts.append(f"<tr>{''.join(cells)}</tr>")
    parts.append("</tbody></table>")
    parts.append("<h2>Each configuration's tasks</h2>")
    for c in d["configs"]:
        shown = ", ".join(f"{n}={v}" for n, v in zip(names, c["labels"], strict=True)) or "the one configuration"
        parts.append(f'<h3 id="{c["id"]}">{_e(shown)}</h3>')
        parts.append(
            "<table><thead><tr><th>seed</th><th>task</th><th>success</th><th>final return</th>"
            "<th>greedy return</th><th>failing runs, by blame</th><th>wall s</th><th>host</th><th>error</th>"
            "</tr></thead><tbody>"
        )
        for r in c["records"]:
            blame = ", ".join(f"{k}: {v}" for k, v in sorted((r.get("failing") or {}).items())) or "–"
            parts.append(
                "<tr>"
                f"<td class=num>{_e(r.get('seed'))}</td><td><code>{_e(r.get('task'))}</code></td>"
                f"<td class=num>{_num(r.get('success_rate'))}</td><td class=num>{_num(r.get('final_return'), 1)}</td>"
                f"<td class=num>{_num(r.get('greedy_return'), 1)}</td><td>{_e(blame)}</td>"
                f"<td class=num>{_num(r.get('wall_s'), 1)}</td><td>{_e(r.get('host') or '–')}</td>"
                f"<td>{_e(r.get('error') or '')}</td>"
                "</tr>"
            )
        parts.append("</tbody></table>")
    return "\n".join(parts)
