"""Matplotlib helpers. The plots take ``ax=None``, draw on that Axes (a new
figure when None) and return it; none calls ``plt.show()``."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .static import StaticResult


def agg_pyplot(agg: bool = True, force: bool = True) -> Any:
    """``matplotlib.pyplot`` on the Agg backend (files only, no window; with
    ``agg`` False, as it is; ``force``: as matplotlib.use's)."""
    import matplotlib

    if agg:
        matplotlib.use("Agg", force=force)
    import matplotlib.pyplot as plt

    return plt


def save_png(fig: Any, path: str | Path, dpi: int = 110) -> Path:
    """Write ``fig`` as a PNG file at ``path``, close it, return the path."""
    import matplotlib.pyplot as plt

    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return Path(path)


def _axes(ax: Any, figsize: tuple[float, float] = (6, 5)) -> Any:
    """``ax``, or the axes of a new figure of ``figsize`` (inches) when None."""
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=figsize)
    return ax


def plot_shapes(results: Sequence[StaticResult], labels: Sequence[str] | None = None,
                ax=None, n: int = 201, style: str = "-", wire: bool = True,
                title: str | None = "static shapes"):
    """Deformed shapes (x, y) of static results, with the wire drawn when
    present (dotted), the elbow as a circle and the tip as a square (both in
    the legend), titled ``title`` (None: no title). Returns the Axes."""
    ax = _axes(ax)
    elbows = wires = False
    for i, r in enumerate(results):
        shape = r.shape(n=n)
        label = labels[i] if labels is not None else None
        (line,) = ax.plot(shape.x, shape.y, style, label=label)
        if wire and r.wire_force == r.wire_force:  # not nan
            ax.plot([0.0, r.tip_x], [0.0, r.tip_y], ":", color=line.get_color(), lw=0.8)
            wires = True
        if r.model.nbeams >= 2:
            ax.plot([r.elbow_x], [r.elbow_y], "o", color=line.get_color(), ms=4)
            elbows = True
        ax.plot([r.tip_x], [r.tip_y], "s", color=line.get_color(), ms=4)
    # the markers' meaning, once, in black (the colours are the results')
    if elbows:
        ax.plot([], [], "o", color="k", ms=4, label="elbow")
    if results:
        ax.plot([], [], "s", color="k", ms=4, label="tip")
    if wires:
        ax.plot([], [], ":", color="k", lw=0.8, label="wire")
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if title:
        ax.set_title(title)
    ax.grid(True, lw=0.3)
    if results:
        ax.legend(fontsize=8)
    return ax


def run_effects(run) -> str:
    """What a dynamic run had, in words, for a figure title: the friction
    coefficients and law (or "no friction"), drag, Kelvin-Voigt damping, the
    motor (with its gain's torque ratio), e.g. ``"friction (sign law) mu_elbow
    0.01, mu_tip 0.02"`` or ``"no friction"``."""
    model = getattr(run, "_model", None)
    p = dict(getattr(model, "params", {}) or {})
    mu = {k: v for k, v in p.items() if k.startswith("mu_") and v}
    parts = [(f"friction ({run.friction} law) " + ", ".join(f"{k} {v:g}" for k, v in mu.items()))
             if mu else "no friction"]
    drag = {k: v for k, v in p.items() if k.startswith("c_") and v}
    if drag:
        parts.append("drag " + ", ".join(f"{k} {v:g}" for k, v in drag.items()))
    if p.get("eta"):
        parts.append(f"Kelvin-Voigt eta {p['eta']:g}")
    if np.any(np.asarray(run.motor_torque, dtype=float) != 0.0):
        parts.append("tip motor")
    return ", ".join(parts)


def plot_history(run, fig=None):
    """The time history of a dynamic run (:class:`beamid.Run`) on its own
    figure, one panel per quantity and unit: tip w (m), tip u (m), the energy
    ledger (N m: E - E0, the work of the effects and the integrator's own
    error ``numerical``) and, when the motor acts, its torque (N m, its own
    panel). Returns the figure (``fig`` when given, else a new one)."""
    import matplotlib.pyplot as plt

    torque = np.asarray(run.motor_torque, dtype=float)
    panels = 4 if np.any(torque != 0.0) else 3
    if fig is None:
        fig = plt.figure(figsize=(8, 2.4 * panels))
    axes = fig.subplots(panels, 1, sharex=True)
    t = np.asarray(run.t, dtype=float)
    axes[0].plot(t, run.tip_w, label="tip w")
    axes[0].set_ylabel("tip w (m)")
    axes[1].plot(t, run.tip_u, color="C1", label="tip u")
    axes[1].set_ylabel("tip u (m)")
    axes[2].plot(t, run.energy_change, color="C2", label="E - E0")
    axes[2].plot(t, run.work, "--", color="C3", label="work of the effects")
    axes[2].plot(t, run.ledger["numerical"], ":", color="C7", label="numerical (E - E0 - work)")
    axes[2].set_ylabel("energy (N m)")
    if panels == 4:
        axes[3].plot(t, torque, color="C4", label="motor torque")
        axes[3].set_ylabel("motor torque (N m)")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    axes[-1].set_xlabel("time (s)")
    axes[0].set_title(f"{run.integrator} integrator, {run.elements_per_beam} elements per "
                      f"beam; {run_effects(run)}", fontsize=10)
    fig.tight_layout()
    return fig
