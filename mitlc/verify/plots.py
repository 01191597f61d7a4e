"""The figure of one counterexample: its states and inputs against time, where it failed."""

from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np

__all__ = ["counterexample_png"]


def counterexample_png(
    states: np.ndarray,
    actions: np.ndarray,
    dt: float,
    state_names: Sequence[str],
    input_names: Sequence[str],
    title: str,
    violation_time: float | None = None,
    periodic: Sequence[str] = (),
) -> bytes:
    """PNG bytes: a panel per state variable and per input of one rollout (``states (N + 1, n)``,
    ``actions (N,)`` or ``(N, m)``), a dashed line at ``violation_time`` (seconds); an angle of
    ``periodic`` is drawn without its jumps from pi to -pi."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    acts = actions[:, None] if actions.ndim == 1 else actions
    n, m = states.shape[1], acts.shape[1]
    t = np.arange(states.shape[0]) * dt
    fig = Figure(figsize=(7.0, 1.8 * (n + m) + 0.5))
    FigureCanvasAgg(fig)
    axes = [fig.add_subplot(n + m, 1, i + 1) for i in range(n + m)]
    for i in range(n):
        y = states[:, i].copy()
        if state_names[i] in periodic:
            y[1:][np.abs(np.diff(y)) > np.pi] = np.nan
        axes[i].plot(t, y, "k-", lw=1.2)
        axes[i].set_ylabel(state_names[i])
    for j in range(m):
        axes[n + j].step(t[:-1], acts[:, j], "k-", where="post", lw=1.0)
        axes[n + j].set_ylabel(input_names[j])
    for ax in axes:
        if violation_time is not None and np.isfinite(violation_time):
            ax.axvline(violation_time, color="tab:red", ls="--", lw=1.0)
        ax.set_xlim(t[0], t[-1])
        ax.grid(alpha=0.3)
    axes[0].set_title(title, fontsize=9)
    axes[-1].set_xlabel("time [s]" + ("; dashed: where it was violated" if violation_time is not None else ""))
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    return buf.getvalue()
