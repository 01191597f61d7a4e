"""What a verification's report shows, from the folder ``mitlc verify --out DIR`` wrote.

The spec the rollouts were judged by (``spec.mitl``); the verdict and why; the sampled fraction with
its one-sided Clopper-Pearson bound, ``N``, the seed and the scenario space (the ``init`` box, the
``--vary`` ranges, the ``--disturb`` bounds); the least robust sample; the falsification (method,
budget, rollouts used, the least robustness found); a table of the counterexamples (start, run,
parameters, disturbance, robustness), each with its figure inline (``cex_NNN.png`` as a data URI)
and the ``mitlc check`` line that replays it; the versions. All of it from ``report.json`` and the
files beside it: nothing is rolled out again.
"""

from __future__ import annotations

import base64
import json
import math
from pathlib import Path
from typing import Any

from mitlc.errors import InputError

__all__ = ["MARKER", "FORMAT", "is_verification", "is_verification_page", "verification_data", "verification_body"]

MARKER = "report.json"
"""The file ``mitlc verify --out`` writes last: it marks a verification's folder."""

FORMAT = "mitlc-verify"
"""``report.json``'s ``format``: what makes it mitlc verify's."""

_KEYS = ("sampling", "space", "counterexamples", "exit_status", "violating_rollouts", "formula")


def _read(folder: Path) -> Any:
    try:
        return json.loads((Path(folder) / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None


def _is_ours(doc: Any) -> bool:
    """``report.json`` as mitlc verify writes it: its ``format``, or (written before it had one) its keys."""
    if not isinstance(doc, dict):
        return False
    if doc.get("format") == FORMAT:
        return True
    return all(k in doc for k in _KEYS) and isinstance(doc.get("sampling"), dict)


def is_verification(folder: Path) -> bool:
    """Whether ``folder`` holds a ``report.json`` that ``mitlc verify`` wrote (a user's file of that name
    does not make a folder a verification's)."""
    return (Path(folder) / MARKER).is_file() and _is_ours(_read(folder))


def is_verification_page(path: Path) -> bool:
    """Whether ``path`` is a page mitlc wrote of a verification (what a verification may remove: not a
    user's file, nor a training's page)."""
    from mitlc.cli.reports.page import is_report

    if not is_report(path):
        return False
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return False
    return '<script type="application/json" id="report-data">{"kind":"verification"}</script>' in text


def _png(folder: Path, name: Any) -> str | None:
    """The figure as a data URI, or None where it is missing (or not a PNG, or not in the folder)."""
    if not isinstance(name, str) or Path(name).name != name:
        return None
    try:
        data = (folder / name).read_bytes()
    except OSError:
        return None
    if not data.startswith(b"\x89PNG"):
        return None
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def verification_data(folder: Path) -> dict[str, Any]:
    """What the page shows: report.json, the spec's text and each counterexample's figure."""
    from mitlc.cli.reports.training import _versions

    folder = Path(folder)
    doc = _read(folder)
    if doc is None:
        raise InputError(f"cannot read {MARKER}", file=str(folder))
    if not _is_ours(doc):
        raise InputError(f"{MARKER} is not a mitlc verification's", file=str(folder))
    for key, kind in (("sampling", dict), ("space", dict), ("counterexamples", list)):
        if not isinstance(doc.get(key), kind):
            raise InputError(
                f"{MARKER}: its {key!r} is not a {kind.__name__}: a damaged verification", file=str(folder)
            )
    for key in ("init", "vary", "disturb"):
        if not isinstance(doc["space"].get(key) or {}, dict):
            raise InputError(f"{MARKER}: space {key!r} is not a dict: a damaged verification", file=str(folder))
    try:
        spec_source = (folder / "spec.mitl").read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        spec_source = None
    cex = []
    for rec in doc.get("counterexamples") or []:
        if isinstance(rec, dict):
            cex.append({**rec, "png": _png(folder, rec.get("plot"))})
    spec = doc.get("spec")
    return {
        "kind": "verification",
        "title": Path(str(spec)).name if spec else folder.name,
        "folder": folder.name,
        "report": doc,
        "spec_source": spec_source,
        "counterexamples": cex,
        "versions": _versions(),
    }


def _n(v: Any, digits: int = 4) -> str:
    """A number as ``mitlc verify`` prints it (``%.4g``); ``–`` for none."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        return "–"
    if isinstance(v, int):
        return str(v)
    if not math.isfinite(v):
        return str(v)
    return f"{v:.{digits}g}"


def _range(v: Any) -> str:
    """``[lo, hi]``, as report.json's space holds a range."""
    if isinstance(v, list) and len(v) == 2:
        return f"[{_n(v[0])}, {_n(v[1])}]"
    return str(v)


def _signed(v: Any) -> str:
    return f"{v:+.4g}" if isinstance(v, int | float) and not isinstance(v, bool) else "–"


def _scenario(rec: dict[str, Any], runs: bool) -> dict[str, str]:
    """A scenario's start, run, parameters and disturbance as text."""
    start = ", ".join(f"{n}={_n(v)}" for n, v in (rec.get("start") or {}).items()) or "–"
    params = ", ".join(f"{n}={_n(v)}" for n, v in (rec.get("params") or {}).items()) or "–"
    dist = (
        "; ".join(
            f"d_{n} = " + ", ".join(f"{x:+.4g}" for x in v if isinstance(x, int | float))
            for n, v in (rec.get("disturbance") or {}).items()
            if isinstance(v, list)
        )
        or "–"
    )
    return {"start": start, "run": str(rec.get("run", "–")) if runs else "–", "params": params, "dist": dist}


def _reasons(doc: dict[str, Any]) -> list[str]:
    """Why the verification passed or failed, as ``mitlc verify`` says it."""
    out = []
    n = doc.get("violating_rollouts") or 0
    if n:
        out.append(f"{n} rollout{'s' if n != 1 else ''} violated the spec")
    bound = (doc.get("sampling") or {}).get("lower_bound")
    require = doc.get("require")
    if isinstance(require, int | float) and isinstance(bound, int | float):
        if bound < require:
            out.append(f"the lower bound {bound:.4f} is below --require {require:g}")
        else:
            out.append(f"the lower bound {bound:.4f} meets --require {require:g}")
    if not out:
        out.append("no rollout violated the spec" + ("" if require is not None else " (no --require)"))
    return out


def verification_body(d: dict[str, Any]) -> str:
    """The page's body."""
    from mitlc.cli.reports.page import _e, _kv_table, _table

    doc = d["report"]
    s = doc.get("sampling") or {}
    space = doc.get("space") or {}
    f = doc.get("falsification")
    failed = doc.get("exit_status") != 0
    verdict = '<span class="bad">FAILED</span>' if failed else '<span class="ok">passed</span>'
    conf = s.get("confidence")
    conf_text = f"{conf:.0%}" if isinstance(conf, int | float) else "–"
    bound = s.get("lower_bound")
    bound_text = f"{bound:.4f}" if isinstance(bound, int | float) else "–"
    frac = s.get("fraction")
    frac_text = f"{frac:.1%}" if isinstance(frac, int | float) else "–"
    parts = [
        f"<h1>{_e(d['title'])} <span class=muted>— verification {_e(d['folder'])}</span></h1>",
        f'<p id="verdict">verify: {verdict}: {_e("; ".join(_reasons(doc)))}</p>',
        '<div class="summary">',
        f"<span>satisfied <b>{_e(s.get('satisfied', '–'))}/{_e(s.get('samples', '–'))}</b> ({_e(frac_text)})</span>",
        f'<span>{_e(conf_text)} lower bound <b id="bound">{_e(bound_text)}</b></span>',
        f"<span>N <b>{_e(s.get('samples', '–'))}</b></span>",
        f"<span>seed <b>{_e(doc.get('seed', '–'))}</b></span>",
        f"<span>counterexamples kept <b>{len(d['counterexamples'])}</b></span>",
        "</div>",
        "<h2>Spec</h2>",
        f"<p>judged by the monitor on <code>{_e(doc.get('formula', '–'))}</code> "
        f"(spec {_e(doc.get('spec') or '–')}; policy {_e(doc.get('policy') or '–')})</p>",
    ]
    if d.get("spec_source"):
        parts.append(f"<pre>{_e(d['spec_source'].rstrip())}</pre>")

    parts += [
        "<h2>Sampling</h2>",
        f"<p>{_e(s.get('satisfied', '–'))} of {_e(s.get('samples', '–'))} scenarios drawn uniformly "
        f"(seed {_e(doc.get('seed', '–'))}) satisfy the spec: {_e(frac_text)}; the one-sided Clopper-Pearson "
        f"lower bound at {_e(conf_text)} confidence on the probability that a scenario drawn the same way is "
        f"satisfied is <b>{_e(bound_text)}</b>"
        + (f" (--require {_e(_n(doc['require']))})" if doc.get("require") is not None else "")
        + ". Sampled, not proved: it says nothing of scenarios outside the space below.</p>",
        "<h3>The scenario space</h3>",
    ]
    rows = [[_e(n), "init", _e(_range(v))] for n, v in (space.get("init") or {}).items()]
    rows += [[_e(n), "--vary", _e(_range(v))] for n, v in (space.get("vary") or {}).items()]
    pieces = space.get("pieces", 1)
    rows += [
        [_e(n), "--disturb", _e(f"[-{_n(e)}, {_n(e)}], constant over each of {pieces} spans")]
        for n, e in (space.get("disturb") or {}).items()
    ]
    parts.append(_table(["name", "from", "range"], rows))
    coords = space.get("coordinates") or []
    parts.append(
        f"<p class=muted>coordinates sampled: {_e(', '.join(coords) or 'none (one scenario)')}; "
        f"{_e(doc.get('steps', '–'))} steps of {_e(_n(doc.get('dt')))} s per rollout</p>"
    )
    least = s.get("least_robust") or {}
    runs = "run" in coords
    sc = _scenario(least, runs)
    parts += [
        "<h3>The least robust sample</h3>",
        _table(
            ["robustness", "start", "run", "parameters", "disturbance"],
            [[_e(_signed(least.get("robustness"))), _e(sc["start"]), _e(sc["run"]), _e(sc["params"]), _e(sc["dist"])]],
            {0},
        ),
    ]

    parts.append("<h2>Falsification</h2>")
    if not f:
        parts.append("<p class=muted>none (--budget 0)</p>")
    else:
        found = f.get("found")
        parts.append(
            _table(
                [
                    "method",
                    "budget",
                    "rollouts used",
                    "found",
                    "first counterexample after",
                    "least robustness",
                    "seconds",
                ],
                [
                    [
                        _e(f.get("method", "–")),
                        _e(f.get("budget", "–")),
                        _e(f.get("rollouts", "–")),
                        '<span class="bad">yes</span>' if found else "no",
                        _e(f.get("first_counterexample_after") if found else "–"),
                        _e(_signed(f.get("least_robustness"))),
                        _e(_n(f.get("seconds"), 3)),
                    ]
                ],
                {1, 2, 4, 5, 6},
            )
        )
        parts.append(
            "<p class=muted>The search starts from the least robust sample; the scenarios it visits are not "
            "drawn at random, so they give no probability and never enter the bound.</p>"
        )

    parts.append("<h2>Counterexamples</h2>")
    n = doc.get("violating_rollouts") or 0
    if not d["counterexamples"]:
        parts.append(f"<p class=muted>none: {_e(n)} violating rollouts</p>")
    else:
        parts.append(
            f"<p class=muted>The {len(d['counterexamples'])} least robust of {_e(n)} violating rollouts (sampled or "
            "searched). Each is a trace in the folder; the command beside it, run from the folder's parent, "
            "replays it through the monitor (and exits 1).</p>"
        )
        rows, attrs = [], []
        for k, c in enumerate(d["counterexamples"]):
            sc = _scenario(c, runs)
            trace = str(c.get("trace", ""))
            check = f"mitlc check {d['folder']}/spec.mitl {d['folder']}/{trace}"
            vt = c.get("violation_time")
            img = (
                f'<img class="cex" alt="{_e(trace)}: its states and inputs" src="{c["png"]}">'
                if c.get("png")
                else "<span class=muted>(no figure)</span>"
            )
            rows.append(
                [
                    _e(trace),
                    _e(sc["start"]),
                    _e(sc["run"]),
                    _e(sc["params"]),
                    _e(sc["dist"]),
                    _e(_signed(c.get("robustness"))),
                    _e(f"t = {_n(vt, 3)} s" if isinstance(vt, int | float) else "–")
                    + (f"<br><small>{_e(c['failing'])}</small>" if c.get("failing") else ""),
                    f"<code>{_e(check)}</code>",
                ]
            )
            attrs.append(f' class="cex-row" id="cex-{k}"')
            rows.append([img])
            attrs.append(' class="cex-figure"')
        head = ["trace", "start", "run", "parameters", "disturbance", "robustness", "violated", "replay"]
        table = _table(head, rows, {5}, attrs)
        table = table.replace('<tr class="cex-figure"><td>', '<tr class="cex-figure"><td colspan="8">')
        parts.append(table)

    parts += ["<h2>Versions</h2>", _kv_table(d["versions"])]
    return "\n".join(parts)
