"""Matplotlib helpers. Each takes ``ax=None``, draws on that Axes (a new
figure when None) and returns it; none calls ``plt.show()``."""
from __future__ import annotations

from typing import Sequence

from .static import StaticResult


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6, 5))
    return ax


def plot_shapes(results: Sequence[StaticResult], labels: Sequence[str] | None = None,
                ax=None, n: int = 201, style: str = "-", wire: bool = True):
    """Deformed shapes (x, y) of static results, with the wire drawn when present."""
    ax = _axes(ax)
    for i, r in enumerate(results):
        shape = r.shape(n=n)
        label = labels[i] if labels is not None else None
        (line,) = ax.plot(shape.x, shape.y, style, label=label)
        if wire and r.wire_force == r.wire_force:  # not nan
            ax.plot([0.0, r.tip_x], [0.0, r.tip_y], ":", color=line.get_color(), lw=0.8)
        if r.model.nbeams >= 2:
            ax.plot([r.elbow_x], [r.elbow_y], "o", color=line.get_color(), ms=4)
        ax.plot([r.tip_x], [r.tip_y], "s", color=line.get_color(), ms=4)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, lw=0.3)
    if labels is not None:
        ax.legend(fontsize=8)
    return ax
