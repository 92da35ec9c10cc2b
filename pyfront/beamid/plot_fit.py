"""Plots for fits, comparisons and improvement ladders (matplotlib).

Every function draws on ``ax`` (a new figure's axes when None) and returns
the axes; none calls ``plt.show()``.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .diagnosis import Comparison, Ladder


def _axes(ax: Any):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6.0, 4.0))
    return ax


def plot_measured_vs_model(cmp: Comparison, quantity: str | None = None, ax: Any = None):
    """Measured values with 1-sigma error bars and the model values against
    load, one series per quantity (or only ``quantity``)."""
    ax = _axes(ax)
    quantities = [quantity] if quantity else list(dict.fromkeys(r.quantity for r in cmp.rows))
    for q in quantities:
        rows = sorted((r for r in cmp.rows if r.quantity == q), key=lambda r: r.load)
        if not rows:
            continue
        x = np.array([r.load for r in rows])
        line = ax.errorbar(x, [r.measured for r in rows], yerr=[r.sigma for r in rows],
                           fmt="o", ms=4, capsize=3, label=f"{q} measured")
        ax.plot(x, [r.model for r in rows], "-", color=line[0].get_color(), alpha=0.7,
                label=f"{q} model")
    ax.set_xlabel("load level")
    ax.set_ylabel("value")
    ax.set_title(f"measured vs model (chi2 = {cmp.chi2:.3g}, dof {cmp.dof})")
    ax.legend(fontsize=7)
    return ax


def plot_normalized_residuals(cmp: Comparison, ax: Any = None):
    """Normalized residuals against load, per quantity, with the +-1 and +-3
    sigma bands."""
    ax = _axes(ax)
    for q in dict.fromkeys(r.quantity for r in cmp.rows):
        rows = sorted((r for r in cmp.rows if r.quantity == q), key=lambda r: r.load)
        ax.plot([r.load for r in rows], [r.normalized for r in rows], "o-", ms=4, label=q)
    for level, style in ((1.0, ":"), (3.0, "--")):
        ax.axhline(level, color="grey", ls=style, lw=0.8)
        ax.axhline(-level, color="grey", ls=style, lw=0.8)
    ax.axhline(0.0, color="black", lw=0.6)
    ax.set_xlabel("load level")
    ax.set_ylabel("(measured - model) / sigma")
    ax.set_title("normalized residuals" + (" (systematic)" if cmp.systematic else ""))
    ax.legend(fontsize=7)
    return ax


def plot_ladder(ladder: Ladder, ax: Any = None):
    """Chi-square per degree of freedom against improvement step (log
    scale), with the effect added at each step and the noise level 1."""
    ax = _axes(ax)
    steps = [s.step for s in ladder.steps]
    chi = [s.chi2_per_dof for s in ladder.steps]
    ax.semilogy(steps, chi, "o-")
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
