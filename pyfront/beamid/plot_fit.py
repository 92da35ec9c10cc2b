"""Plots for fits, comparisons and improvement ladders (matplotlib).

Every function draws on ``ax`` (a new figure's axes when None) and returns
the axes; none calls ``plt.show()``.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import observations
from .diagnosis import Comparison, Ladder
from .errors import InputError
from .plotting import _axes


def quantity_unit(quantity: str) -> str:
    """The unit of a measured quantity (``m``, ``rad``, ``N``, ``N m``, ...):
    the core's observation table (beamid.observations); a name that is no
    observation is read by its words (angle: rad, moment or torque: N m,
    force: N, else m)."""
    try:
        return observations.unit(quantity)
    except InputError:
        pass
    q = quantity.lower()
    if "angle" in q:
        return "rad"
    if "moment" in q or "torque" in q:
        return "N m"
    if "force" in q:
        return "N"
    return "m"


def _quantities(cmp: Comparison) -> list[str]:
    return list(dict.fromkeys(r.quantity for r in cmp.rows))


def plot_measured_vs_model(cmp: Comparison, quantity: str | None = None, ax: Any = None):
    """Measured values with 1-sigma error bars and the model values against
    load for ``quantity`` (or for every quantity when they all have one unit;
    quantities of different units never share an axis: give ``quantity`` or
    draw them all with :func:`plot_compare`)."""
    quantities = [quantity] if quantity else _quantities(cmp)
    units = {quantity_unit(q) for q in quantities}
    if len(units) > 1:
        raise InputError(f"quantities {', '.join(quantities)} have different units "
                         f"({', '.join(sorted(units))}): give quantity= or use plot_compare")
    ax = _axes(ax, (6.0, 4.0))
    for q in quantities:
        rows = sorted((r for r in cmp.rows if r.quantity == q), key=lambda r: r.load)
        if not rows:
            continue
        x = np.array([r.load for r in rows])
        line = ax.errorbar(x, [r.measured for r in rows], yerr=[r.sigma for r in rows],
                           fmt="o", ms=4, capsize=3, label=f"{q} measured (+- sigma)")
        ax.plot(x, [r.model for r in rows], "-", color=line[0].get_color(), alpha=0.7,
                label=f"{q} model")
    ax.set_xlabel("load level (N, or N m for moments)")
    ax.set_ylabel(f"value ({units.pop() if units else '-'})")
    ax.set_title(f"measured vs model (chi2 = {cmp.chi2:.3g}, dof {cmp.dof})")
    ax.legend(fontsize=7)
    return ax


def plot_normalized_residuals(cmp: Comparison, ax: Any = None):
    """Normalized residuals against load, per quantity, with the +-1 and +-3
    sigma bands (each in the legend)."""
    ax = _axes(ax, (6.0, 4.0))
    for q in _quantities(cmp):
        rows = sorted((r for r in cmp.rows if r.quantity == q), key=lambda r: r.load)
        ax.plot([r.load for r in rows], [r.normalized for r in rows], "o-", ms=4, label=q)
    _sigma_bands(ax)
    ax.set_xlabel("load level (N, or N m for moments)")
    ax.set_ylabel("(measured - model) / sigma (-)")
    ax.set_title("normalized residuals" + (" (systematic)" if cmp.systematic else ""))
    ax.legend(fontsize=7)
    return ax


def _sigma_bands(ax: Any) -> None:
    for level, style in ((1.0, ":"), (3.0, "--")):
        ax.axhline(level, color="grey", ls=style, lw=0.8, label=f"+-{level:g} sigma")
        ax.axhline(-level, color="grey", ls=style, lw=0.8, label="_nolegend_")
    ax.axhline(0.0, color="black", lw=0.6, label="model (0)")


def plot_compare(cmp: Comparison, fig: Any = None):
    """The compare figure: one column per measured quantity, each panel in
    that quantity's unit, experiments along x (in the order of the data).

    - top row: measured values with 1-sigma error bars and the model values;
    - middle row: measured - model with 1-sigma error bars (the bars are
      visible here; beside values of order 1 a sigma of 1e-4 is not);
    - bottom panel: normalized residuals of every quantity (dimensionless)
      with the +-1 and +-3 sigma bands.

    Every line has a legend entry. Returns the figure (``fig`` when given)."""
    if hasattr(cmp, "series"):     # time histories (beamid.dyn_diagnosis)
        from .dyn_diagnosis import plot_time_comparison
        return plot_time_comparison(cmp, fig=fig)
    import matplotlib.pyplot as plt

    quantities = _quantities(cmp)
    experiments = list(dict.fromkeys(r.experiment for r in cmp.rows))
    xpos = {e: i for i, e in enumerate(experiments)}
    nq = max(len(quantities), 1)
    if fig is None:
        fig = plt.figure(figsize=(3.6 * nq + 1.0, 9.0))
    grid = fig.add_gridspec(3, nq)
    for j, q in enumerate(quantities):
        rows = [r for r in cmp.rows if r.quantity == q]
        x = np.array([xpos[r.experiment] for r in rows], dtype=float)
        unit = quantity_unit(q)
        top = fig.add_subplot(grid[0, j])
        top.errorbar(x, [r.measured for r in rows], yerr=[r.sigma for r in rows], fmt="o",
                     ms=4, capsize=4, color="C0", label="measured (+- sigma)")
        top.plot(x, [r.model for r in rows], "x", ms=7, color="C3", label="model")
        top.set_title(q, fontsize=10)
        top.set_ylabel(f"{q} ({unit})")
        mid = fig.add_subplot(grid[1, j], sharex=top)
        mid.errorbar(x, [r.measured - r.model for r in rows], yerr=[r.sigma for r in rows],
                     fmt="o", ms=4, capsize=4, color="C0", label="measured - model (+- sigma)")
        mid.axhline(0.0, color="C3", lw=0.8, label="model")
        mid.set_ylabel(f"measured - model ({unit})")
        for ax in (top, mid):
            ax.set_xticks(range(len(experiments)), experiments, fontsize=8)
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=7)
    bottom = fig.add_subplot(grid[2, :])
    for q in quantities:
        rows = [r for r in cmp.rows if r.quantity == q]
        bottom.plot([xpos[r.experiment] for r in rows], [r.normalized for r in rows], "o",
                    ms=5, label=q)
    _sigma_bands(bottom)
    bottom.set_xticks(range(len(experiments)), experiments, fontsize=8)
    bottom.set_xlabel("experiment")
    bottom.set_ylabel("(measured - model) / sigma (-)")
    bottom.grid(True, alpha=0.3)
    bottom.legend(fontsize=7, ncol=2)
    fig.suptitle(f"measured vs model: chi2 = {cmp.chi2:.4g}, dof {cmp.dof}"
                 + (" (systematic residuals)" if cmp.systematic else ""), fontsize=11)
    fig.tight_layout()
    return fig


def plot_ladder(ladder: Ladder, ax: Any = None):
    """Chi-square per degree of freedom against improvement step (log
    scale), with the effect added at each step and the noise level 1."""
    ax = _axes(ax, (6.0, 4.0))
    steps = [s.step for s in ladder.steps]
    chi = [s.chi2_per_dof for s in ladder.steps]
    ax.semilogy(steps, chi, "o-", label="chi2 / dof after each step")
    for s in ladder.steps:
        ax.annotate(s.effect or "start", (s.step, s.chi2_per_dof), textcoords="offset points",
                    xytext=(5, 5), fontsize=8)
    ax.axhline(1.0, color="grey", ls="--", lw=0.8, label="noise level (chi2/dof = 1)")
    ax.set_xticks(steps)
    ax.set_xlabel("improvement step")
    ax.set_ylabel("chi2 / dof")
    ax.set_title("error against step")
    ax.legend(fontsize=7)
    return ax
