"""What a sweep found: a row per configuration (means over seeds), a table, a heat map."""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from typing import Any

from mitlc.sweep.grid import Axis, SweepPlan

# ---------------------------------------------------------------- summaries and the heat map


def summarize(plan: SweepPlan, records: Mapping[str, Mapping[str, Any]]) -> list[dict]:
    """One row per configuration (in grid order): the axis values, means over the finished seeds, and
    ``failing``: how many runs (summed over seeds) the monitor blames on each subformula."""
    import numpy as np

    groups: dict[tuple[str, ...], list[Mapping[str, Any]]] = {}
    for t in plan.tasks:
        groups.setdefault(t.labels, [])
        if t.key in records:
            groups[t.labels].append(records[t.key])
    rows = []
    for labels, recs in groups.items():
        ok = [r for r in recs if r.get("error") is None]

        def mean(m: str, ok: list[Mapping[str, Any]] = ok) -> float | None:
            return float(np.mean([r[m] for r in ok])) if ok else None

        rows.append(
            {
                **dict(zip((a.name for a in plan.axes), labels, strict=True)),
                "seeds": len(recs),
                "errors": len(recs) - len(ok),
                "success_rate": mean("success_rate"),
                "success_min": min((r["success_rate"] for r in ok), default=None),
                "success_max": max((r["success_rate"] for r in ok), default=None),
                "final_return": mean("final_return"),
                "failing": dict(sum((Counter(r.get("failing") or {}) for r in ok), Counter())),
                "wall_s": float(np.mean([r["wall_s"] for r in recs])) if recs else None,
            }
        )
    return rows


def format_table(plan: SweepPlan, rows: Sequence[Mapping[str, Any]], markdown: bool = False) -> str:
    """The summary as an aligned text table (or a Markdown table)."""

    def num(v: float | None, fmt: str) -> str:
        return "-" if v is None else format(v, fmt)

    head = [a.name for a in plan.axes] + [
        "seeds",
        "success (mean)",
        "min-max",
        "final return",
        "wall s",
        "failing runs, by blame",
    ]
    body = []
    for r in rows:
        seeds = f"{r['seeds']}/{len(plan.seeds)}" + (f" ({r['errors']} diverged)" if r["errors"] else "")
        body.append(
            [str(r[a.name]) for a in plan.axes]
            + [
                seeds,
                num(r["success_rate"], ".2f"),
                "-" if r["success_min"] is None else f"{r['success_min']:.2f}-{r['success_max']:.2f}",
                num(r["final_return"], ".1f"),
                num(r["wall_s"], ".1f"),
                ", ".join(f"{k}: {n}" for k, n in sorted(r["failing"].items(), key=lambda kv: -kv[1])) or "-",
            ]
        )
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "|".join(" --- " for _ in head) + "|"]
        lines += ["| " + " | ".join(row) + " |" for row in body]
        return "\n".join(lines)
    widths = [max(len(h), *(len(row[i]) for row in body)) if body else len(h) for i, h in enumerate(head)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True)).rstrip()]
    lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip() for row in body]
    return "\n".join(lines)


def heatmap_axes(plan: SweepPlan) -> tuple[Axis, ...]:
    """The first two axes with more than one value (the heat map's x and y)."""
    return tuple(a for a in plan.axes if a.swept)[:2]


def heatmap_grid(plan: SweepPlan, records: Mapping[str, Mapping[str, Any]]):
    """``(x_axis, y_axis or None, mean, count)``: success rate over the first two swept axes.

    ``mean[y, x]`` is the mean over seeds (and over any further axes) of the
    finished tasks' success rates, NaN where none finished; ``count[y, x]``
    how many tasks it averages.  None when nothing is swept.
    """
    import numpy as np

    shown = heatmap_axes(plan)
    if not shown:
        return None
    x_axis = shown[0]
    y_axis = shown[1] if len(shown) > 1 else None
    idx = {a.name: i for i, a in enumerate(plan.axes)}
    ny = len(y_axis.labels) if y_axis else 1
    sums = np.zeros((ny, len(x_axis.labels)))
    counts = np.zeros((ny, len(x_axis.labels)), dtype=int)
    for t in plan.tasks:
        r = records.get(t.key)
        if r is None or r.get("success_rate") is None:
            continue
        xi = x_axis.labels.index(t.labels[idx[x_axis.name]])
        yi = y_axis.labels.index(t.labels[idx[y_axis.name]]) if y_axis else 0
        sums[yi, xi] += r["success_rate"]
        counts[yi, xi] += 1
    mean = np.full(sums.shape, np.nan)
    np.divide(sums, counts, out=mean, where=counts > 0)
    return x_axis, y_axis, mean, counts


def heatmap_figure(plan: SweepPlan, records: Mapping[str, Mapping[str, Any]], title: str = ""):
    """The heat map of :func:`heatmap_grid` as a matplotlib Figure (None when nothing is swept).

    Each cell shows the mean and, in brackets, how many tasks it averages;
    cells with no finished task are left blank.
    """
    import numpy as np
    from matplotlib.figure import Figure

    hm = heatmap_grid(plan, records)
    if hm is None:
        return None
    x_axis, y_axis, grid, counts = hm
    ny = grid.shape[0]
    fig = Figure(figsize=(1.2 + 1.0 * len(x_axis.labels), 1.3 + 0.7 * ny))
    ax = fig.add_subplot(1, 1, 1)
    im = ax.imshow(np.ma.masked_invalid(grid), cmap="viridis", vmin=0.0, vmax=1.0, aspect="auto", origin="lower")
    ax.set_xticks(range(len(x_axis.labels)), x_axis.labels)
    ax.set_xlabel(x_axis.name)
    if y_axis:
        ax.set_yticks(range(ny), y_axis.labels)
        ax.set_ylabel(y_axis.name)
    else:
        ax.set_yticks([])
    for yi in range(ny):
        for xi in range(len(x_axis.labels)):
            if counts[yi, xi]:
                v = grid[yi, xi]
                ax.text(
                    xi,
                    yi,
                    f"{v:.2f}\n({counts[yi, xi]})",
                    ha="center",
                    va="center",
                    fontsize=8,
                    color="black" if v > 0.6 else "white",
                )
    others = [a.name for a in plan.axes if a.swept and a not in (x_axis, y_axis)]
    over = "seeds" + (" and " + ", ".join(others) if others else "")
    ax.set_title(title or f"success rate, mean over {over} (n per cell)", fontsize=9)
    fig.colorbar(im, ax=ax, label="success rate")
    return fig
