"""Figures of training results: learning curves and rollouts (matplotlib, no files written).

Every function returns a :class:`matplotlib.figure.Figure`; :func:`png_bytes`
renders one, and only the CLI writes files.
"""

from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np

__all__ = ["learning_curve", "rollout_figure", "png_bytes"]


def _figure(*args, **kwargs):
    from matplotlib.figure import Figure

    return Figure(*args, **kwargs)


def png_bytes(fig, dpi: int = 110) -> bytes:
    """Render a figure to PNG bytes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return buf.getvalue()


def learning_curve(returns: np.ndarray, title: str = "", label: str | None = None, fig=None, color: str | None = None):
    """Mean return per trial over runs, with the 10-90 % band (like Figure 4-3).

    ``returns`` is ``(runs, trials)``.  Pass ``fig`` to draw several curves on one axes.
    """
    returns = np.asarray(returns, dtype=float)
    if fig is None:
        fig = _figure(figsize=(6.4, 3.6))
        ax = fig.add_subplot(1, 1, 1)
        ax.set_xlabel("trial")
        ax.set_ylabel("return (sum of rewards)")
        ax.grid(alpha=0.3)
    else:
        ax = fig.axes[0]
    trials = np.arange(1, returns.shape[1] + 1)
    mean = returns.mean(axis=0)
    lo, hi = np.percentile(returns, [10, 90], axis=0) if returns.shape[0] > 1 else (mean, mean)
    line = ax.plot(trials, mean, lw=1.5, label=label or f"mean of {returns.shape[0]} runs", color=color)[0]
    ax.fill_between(trials, lo, hi, alpha=0.2, color=line.get_color(), lw=0, label=None if label else "10-90 % of runs")
    if title:
        ax.set_title(title)
    ax.legend(loc="lower right", fontsize=8)
    return fig


_PALETTE = ["#c8e6c9", "#ffcdd2", "#fff9c4", "#bbdefb", "#e1bee7", "#ffe0b2", "#d7ccc8", "#cfd8dc"]


def rollout_figure(
    states: np.ndarray,
    actions: np.ndarray,
    regions: np.ndarray,
    region_names: Sequence[str],
    dt: float,
    state_names: Sequence[str],
    u_max: float | None = None,
    title: str = "",
    verdicts: Sequence[bool] | None = None,
    inputs: Sequence[tuple[str, float, float]] | None = None,
):
    """State, velocity and input against time for a few rollouts.

    ``states (B, N+1, n)``, ``actions (B, N)`` (or ``(B, N, m)`` for ``m`` inputs, a panel
    each, named and bounded by ``inputs``: ``(name, lo, hi)`` per input); ``regions (B, N+1)``
    indexes ``region_names``: the background of each panel is coloured by the marked place
    of the first rollout's state region net (like Figures 3-7, 4-13).
    """
    B, N1, n = states.shape
    acts = actions[:, :, None] if actions.ndim == 2 else actions
    m = acts.shape[2]
    if inputs is None and u_max is not None:
        inputs = [("u", -u_max, u_max)]
    t = np.arange(N1) * dt
    fig = _figure(figsize=(7.0, 2.0 * (n + m) + 0.4))
    axes = [fig.add_subplot(n + m, 1, i + 1) for i in range(n + m)]
    reg = regions[0]
    starts = np.flatnonzero(np.r_[True, reg[1:] != reg[:-1]])
    ends = np.r_[starts[1:], N1]
    used = set()
    for ax in axes:
        for s, e in zip(starts, ends, strict=True):
            j = int(reg[s])
            lab = region_names[j] if j not in used and ax is axes[0] else None
            if lab:
                used.add(j)
            ax.axvspan(
                t[s] - dt / 2,
                t[min(e, N1 - 1)] + dt / 2 if e < N1 else t[-1],
                color=_PALETTE[j % len(_PALETTE)],
                lw=0,
                label=lab,
            )
    for i in range(n):
        for b in range(B):
            style = "-" if verdicts is None or verdicts[b] else "--"
            y = states[b, :, i].copy()
            if state_names[i] == "q":  # do not draw the jump from pi to -pi
                y[1:][np.abs(np.diff(y)) > np.pi] = np.nan
            axes[i].plot(
                t, y, style, lw=1.2 if b == 0 else 0.7, color="k" if b == 0 else None, alpha=1.0 if b == 0 else 0.6
            )
        axes[i].set_ylabel(state_names[i])
    for j in range(m):
        ax = axes[n + j]
        for b in range(B):
            ax.step(
                t[:-1],
                acts[b, :, j],
                where="post",
                lw=1.0 if b == 0 else 0.6,
                color="k" if b == 0 else None,
                alpha=1.0 if b == 0 else 0.6,
            )
        if inputs is not None:
            name, lo, hi = inputs[j]
            pad = 0.05 * (hi - lo)
            ax.set_ylim(lo - pad, hi + pad)
            ax.set_ylabel(name)
        else:
            ax.set_ylabel("u" if m == 1 else f"u[{j}]")
    axes[-1].set_xlabel("time [s]")
    axes[0].legend(loc="upper right", fontsize=7, title="marking (first rollout)", title_fontsize=7)
    if title:
        axes[0].set_title(title)
    for ax in axes:
        ax.set_xlim(t[0], t[-1])
        ax.grid(alpha=0.3)
    return fig
