"""Plots for fits, comparisons and improvement ladders (matplotlib).

Every function draws on ``ax`` (a new figure's axes when None) and returns
the axes; none calls ``plt.show()``.
"""
from __future__ import annotations

import re
from typing import Any

import numpy as np

from . import _check, _core
from .diagnosis import Comparison, Ladder
from .dyn_diagnosis import plot_time_comparison
from .errors import InputError
from .measurements import quantity_unit  # noqa: F401 - the plots' unit rule, kept here too
from .plotting import _axes


def parameter_unit(name: str) -> str:
    """The unit of a model parameter (``EI1`` -> ``N m^2``), "-" when it has
    none (friction coefficients, ``axial_coupling``) or is not a model
    parameter: the core's unit table (beamid_model, ``_core.param_units``).
    A unit does not depend on the beam or joint number, so the name is
    looked up in a chain of 3 beams with its numbers above 2 written 2."""
    _check.text("parameter_unit: name", name, empty=True)
    probe = re.sub(r"[1-9]\d+|[3-9]", "2", name)
    return dict(zip(_core.param_names(3), _core.param_units(3))).get(probe, "-")


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


def plot_compare(cmp: Comparison, fig: Any = None, title: str | None = None):
    """The compare figure: one column per measured quantity, each panel in
    that quantity's unit, experiments along x (in the order of the data).

    - top row: measured values with 1-sigma error bars and the model values;
    - middle row: measured - model with 1-sigma error bars (the bars are
      visible here; beside values of order 1 a sigma of 1e-4 is not);
    - bottom panel: normalized residuals of every quantity (dimensionless)
      with the +-1 and +-3 sigma bands.

    Every line has a legend entry; ``title`` (e.g. which fit: "start" or
    "final fit") goes before the chi-square in the figure's title. Returns the
    figure (``fig`` when given)."""
    title = _check.text("title", title, empty=True, none=True)
    if hasattr(cmp, "series"):     # time histories (beamid.dyn_diagnosis)
        return plot_time_comparison(cmp, fig=fig, title=title)
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
    fig.suptitle((f"{title}: " if title else "")
                 + f"measured vs model: chi2 = {cmp.chi2:.4g}, dof {cmp.dof}"
                 + (f", chi2/dof = {cmp.chi2 / cmp.dof:.4g}" if cmp.dof > 0 else "")
                 + (" (systematic residuals)" if cmp.systematic else ""), fontsize=11)
    fig.tight_layout()
    return fig


def ladder_labels(ladder: Ladder) -> list[str]:
    """What each rung of a ladder did, in words: "start", the effect it added,
    or, for a rung that replaced a member of a block, e.g. "drag: c_tip
    instead of c_elbow" (``LadderStep.params`` instead of ``.removed``)."""
    labels = []
    for s in ladder.steps:
        if not s.effect:
            labels.append("start")
        elif s.removed:
            labels.append(f"{s.effect}: {', '.join(s.params)} instead of "
                          f"{', '.join(s.removed)}")
        else:
            labels.append(s.effect)
    return labels


def ladder_titles(ladder: Ladder) -> tuple[str, str]:
    """Titles of a ladder's two compare figures: which fit each shows, the
    start and the final one (its step and the parameters its effects added)."""
    last = len(ladder.steps) - 1
    if last == 0:
        return "start (step 0, no effect added)", "final fit = start (no effect added)"
    added = [p for p in ladder.fit.free if p not in ladder.steps[0].fit.free]
    return ("start (step 0, no effect added)",
            f"final fit (step {last}: {', '.join(added)} added)")


def plot_ladder(ladder: Ladder, ax: Any = None):
    """Chi-square per degree of freedom against improvement step (log
    scale), with what each step did (:func:`ladder_labels`) and the noise
    level 1."""
    ax = _axes(ax, (6.0, 4.0))
    steps = [s.step for s in ladder.steps]
    chi = [s.chi2_per_dof for s in ladder.steps]
    ax.semilogy(steps, chi, "o-", label="chi2 / dof after each step")
    last = len(ladder.steps) - 1
    for k, (s, text) in enumerate(zip(ladder.steps, ladder_labels(ladder))):
        right = k == last and k > 0      # the last label to the left: it stays inside
        ax.annotate(text, (s.step, s.chi2_per_dof), textcoords="offset points",
                    xytext=(-5, 6) if right else (5, 5), ha="right" if right else "left",
                    fontsize=8)
    ax.axhline(1.0, color="grey", ls="--", lw=0.8, label="noise level (chi2/dof = 1)")
    ax.set_xticks(steps)
    ax.set_xlabel("improvement step")
    ax.set_ylabel("chi2 / dof")
    ax.set_title("error against step")
    ax.legend(fontsize=7)
    return ax
