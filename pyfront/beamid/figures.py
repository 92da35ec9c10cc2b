"""The dissertation's dynamic figures (Chapter IV 4.1.5 and Chapter V 5.1.3)
redrawn from beamid runs, as PNG files: ``beamid figures [--out DIR] [NAMES]``.

=========  ==============================================================
figure20   tip transverse deflection w over a period (friction, no motor)
figure21   tip longitudinal deflection u over a period
figure22   beam profiles for a quarter period (0 to 0.65 s)
figure23   effect of the motor gain g (0, 0.2, 2.0) on the tip w
figure24   effect of the motor gain on the tip u
figure25   tip w, u and the motor torque for g = 0.2
=========  ==============================================================

All runs are the dissertation's: the PACE arm without rotary inertia,
friction mu_elbow = 0.01 and mu_tip = 0.02, released from the static shape
under an 8 N transverse tip force, 8 elements, output every 0.01 s over 2.6 s.
They use the implicit integrator at its defaults (the sign law of Eq. 101
with its switches as events, rtol 1e-9; 0.1-0.3 s each; the curves agree
with RK4 at dt = 1e-5 s and the same law to about 3e-7 m).

Plot helpers take ``ax=None`` (a new figure when None), draw on it and return
it; they never call ``plt.show()``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable, Iterable, Mapping, Sequence

import numpy as np

from .dynamics import simulate
from .errors import InputError
from .loads import TipForce
from .model import pace
from .plotting import _axes, agg_pyplot, save_png

__all__ = ["FIGURES", "GAINS", "FIGURE_TIMES", "QUARTER_PERIOD_TIMES", "figure_runs",
           "plot_tip_history", "plot_profiles", "plot_tip_and_torque", "figure20",
           "figure21", "figure22", "figure23", "figure24", "figure25", "figure_names",
           "write_figures"]

#: Motor gains of Figures 23-24 (the text names 0.2 and 2.0; 0 is the free run).
GAINS = (0.0, 0.2, 2.0)
#: Output times of the figure runs (s).
FIGURE_TIMES = np.linspace(0.0, 2.6, 261)
#: Times of the quarter-period profiles of Figure 22 (the period is about 2.6 s).
QUARTER_PERIOD_TIMES = (0.0, 0.13, 0.26, 0.39, 0.52, 0.65)

_LABELS = {"tip_w": "tip transverse deflection w (m)",
           "tip_u": "tip longitudinal deflection u (m)"}


def figure_runs(gains: Iterable[float] = GAINS, t_out: Sequence[float] | None = None,
                integrator: str = "implicit", elements_per_beam: int = 4) -> dict:
    """The runs behind Figures 20-25, one per motor gain: ``{gain: Run}``."""
    model = pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)
    times = FIGURE_TIMES if t_out is None else np.asarray(t_out, dtype=float)
    return {float(g): simulate(model, TipForce(fy=8.0), times,
                               elements_per_beam=elements_per_beam, integrator=integrator,
                               motor_gain=float(g))
            for g in gains}


def plot_tip_history(runs: Sequence, labels: Sequence[str] | None = None,
                     quantity: str = "tip_w", ax=None):
    """One line per run: ``quantity`` (``tip_w``, ``tip_u``, ``tip_angle``,
    ``energy``, ...) against time. Returns the Axes."""
    ax = _axes(ax, (8, 5))
    labels = list(labels) if labels is not None else [None] * len(runs)
    if len(labels) != len(runs):
        raise InputError(f"{len(labels)} labels for {len(runs)} runs")
    for run, label in zip(runs, labels):
        if not hasattr(run, quantity):
            raise InputError(f"a run has no series {quantity!r}")
        ax.plot(run.t, getattr(run, quantity), label=label)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(_LABELS.get(quantity, quantity))
    ax.grid(True, alpha=0.3)
    if any(labels):
        ax.legend(fontsize=9)
    return ax


def plot_profiles(run, times: Sequence[float] = QUARTER_PERIOD_TIMES, ax=None,
                  points_per_element: int = 8):
    """The deformed arm (x = s + u, y = w) at output times of ``run``, one
    line per time. Returns the Axes."""
    ax = _axes(ax, (8, 5))
    for t, (x, y) in zip(times, run.profiles(times, points_per_element=points_per_element)):
        ax.plot(x, y, label=f"t = {t:.2f} s")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=9)
    return ax


def plot_tip_and_torque(run, ax=None):
    """Tip w and u against time on ``ax`` and the motor torque on a twin
    axis at the right (Figure 25). Returns ``ax``; the twin is the Axes
    that shares its x axis (``ax.figure.axes``)."""
    ax = _axes(ax, (8, 5))
    ax.plot(run.t, run.tip_w, label="tip w")
    ax.plot(run.t, run.tip_u, label="tip u")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("tip deflection (m)")
    ax.grid(True, alpha=0.3)
    twin = ax.twinx()
    twin.plot(run.t, run.motor_torque, color="C3", linestyle="--", label="motor torque")
    twin.set_ylabel("motor torque (N m)")
    handles = ax.get_legend_handles_labels()
    more = twin.get_legend_handles_labels()
    ax.legend(handles[0] + more[0], handles[1] + more[1], fontsize=9, loc="upper right")
    return ax


def _runs(runs: Mapping | None, gains: Iterable[float]) -> dict:
    runs = dict(runs or {})
    missing = [g for g in gains if float(g) not in runs]
    if missing:
        runs.update(figure_runs(missing))
    return runs


def _span(run) -> str:
    """The time span of a run's output in words: "over a period (2.6 s)" for
    the dissertation's span, else "over 0-0.8 s"."""
    t0, t1 = float(run.t[0]), float(run.t[-1])
    if abs(t0) < 1e-12 and abs(t1 - FIGURE_TIMES[-1]) < 1e-9:
        return f"over a period ({t1:g} s)"
    return f"over {t0:g}-{t1:g} s"


def _tip_figure(runs, gains: Sequence[float], quantity: str, title: str, ax):
    """``quantity`` of the runs of ``gains`` against time (labelled by gain
    when several), titled with ``title`` and the runs' time span."""
    runs = _runs(runs, gains)
    shown = [runs[float(g)] for g in gains]
    ax = plot_tip_history(shown, [f"g = {g:g}" for g in gains]
                          if len(gains) > 1 else None, quantity=quantity, ax=ax)
    ax.set_title(f"{title} {_span(shown[0])}")
    return ax


def figure20(runs: Mapping | None = None, ax=None):
    """Figure 20: tip transverse deflection over a period (friction); the
    title gives the span of the runs drawn."""
    return _tip_figure(runs, [0.0], "tip_w", "Figure 20. Tip transverse deflection", ax)


def figure21(runs: Mapping | None = None, ax=None):
    """Figure 21: tip longitudinal deflection over a period (friction); the
    title gives the span of the runs drawn."""
    return _tip_figure(runs, [0.0], "tip_u", "Figure 21. Tip longitudinal deflection", ax)


def figure22(runs: Mapping | None = None, ax=None):
    """Figure 22: beam profiles for a quarter period."""
    ax = plot_profiles(_runs(runs, [0.0])[0.0], QUARTER_PERIOD_TIMES, ax=ax)
    ax.set_title("Figure 22. Beam profiles for 1/4 period")
    return ax


def figure23(runs: Mapping | None = None, ax=None):
    """Figure 23: effect of the gain values on the tip transverse displacement."""
    return _tip_figure(runs, GAINS, "tip_w", "Figure 23. Effect of gain values on tip "
                       "transverse displacements,", ax)


def figure24(runs: Mapping | None = None, ax=None):
    """Figure 24: effect of the gain values on the tip longitudinal displacement."""
    return _tip_figure(runs, GAINS, "tip_u", "Figure 24. Effect of gain values on tip "
                       "longitudinal displacements,", ax)


def figure25(runs: Mapping | None = None, ax=None):
    """Figure 25: tip displacements and motor torque for g = 0.2."""
    run = _runs(runs, [0.2])[0.2]
    ax = plot_tip_and_torque(run, ax=ax)
    peak = int(np.argmax(np.abs(run.motor_torque)))
    ax.set_title(f"Figure 25. Control and tip displacements, g = 0.2 (peak torque "
                 f"{abs(run.motor_torque[peak]):.3f} N m at {run.t[peak]:.2f} s)", fontsize=10)
    return ax


#: name -> drawing function (runs=None, ax=None) -> Axes
FIGURES: dict[str, Callable] = {f.__name__: f for f in (figure20, figure21, figure22,
                                                        figure23, figure24, figure25)}


def figure_names(names: Iterable[str] = ()) -> list[str]:
    """Canonical names of the requested figures (``20``, ``fig20``,
    ``figure20`` all mean ``figure20``); all when none is given."""
    out = []
    for name in names:
        key = str(name).lower().replace("figure", "").replace("fig", "").strip(" _-")
        if f"figure{key}" not in FIGURES:
            raise InputError(f"unknown figure {name!r}, expected one of: "
                             f"{', '.join(FIGURES)} (or 20 ... 25)")
        out.append(f"figure{key}")
    return out or list(FIGURES)


def write_figures(out: str | Path, names: Iterable[str] = (), runs: Mapping | None = None,
                  dpi: int = 110) -> list[Path]:
    """Draw the named figures (all by default) as ``out/figureNN.png``; the
    runs are computed once (only the gains the figures need) unless given."""
    agg_pyplot()
    wanted = figure_names(names)
    gains = {0.0} if set(wanted) <= {"figure20", "figure21", "figure22"} else set(GAINS)
    if wanted == ["figure25"]:
        gains = {0.2}
    runs = _runs(runs, sorted(gains))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for name in wanted:
        fig = FIGURES[name](runs).figure
        fig.tight_layout()
        written.append(save_png(fig, out / f"{name}.png", dpi))
    return written
