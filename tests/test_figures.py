"""Figures 20-25 (beamid.figures): each draws the curves of its runs, the
PNG files are written, and `beamid figures` calls them. Agg backend
(conftest.py); the runs are short (0.75 s, past the peak torque) to keep the tests fast."""
from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest
from numpy.testing import assert_allclose

from beamid import InputError
from beamid.cli import main as cli_main
from beamid.figures import (FIGURES, GAINS, QUARTER_PERIOD_TIMES, figure20, figure21,
                            figure22, figure23, figure24, figure25, figure_names,
                            figure_runs, plot_tip_history, write_figures)

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def runs():
    return figure_runs(t_out=np.linspace(0.0, 0.75, 76))


def _lines(ax):
    return [(line.get_xdata(), line.get_ydata()) for line in ax.get_lines()]


def test_runs_are_the_dissertations(runs):
    assert sorted(runs) == sorted(GAINS)
    free = runs[0.0]
    assert free.integrator == "implicit" and free.elements_per_beam == 4
    assert free.tip_w[0] == pytest.approx(0.627036, abs=1e-6)    # 8 N static shape
    assert np.all(free.motor_torque == 0.0)
    assert free.ledger["friction_tip"][-1] < 0.0                  # friction is on
    assert np.max(np.abs(runs[0.2].motor_torque)) == pytest.approx(0.347, abs=0.003)


@pytest.mark.parametrize("func, quantity", [(figure20, "tip_w"), (figure21, "tip_u")])
def test_tip_history_figures(func, quantity, runs):
    ax = func(runs)
    (x, y), = _lines(ax)
    assert_allclose(x, runs[0.0].t)
    assert_allclose(y, getattr(runs[0.0], quantity))
    assert ax.get_title().startswith(f"Figure {func.__name__[-2:]}.")
    plt.close(ax.figure)


def test_figure22_profiles(runs):
    ax = figure22(runs)
    lines = _lines(ax)
    assert len(lines) == len(QUARTER_PERIOD_TIMES)
    for (x, y), (px, py) in zip(lines, runs[0.0].profiles(QUARTER_PERIOD_TIMES)):
        assert_allclose(x, px)
        assert_allclose(y, py)
    # the profiles end at the tip of the run
    k = int(np.argmin(np.abs(runs[0.0].t - 0.65)))
    assert lines[-1][1][-1] == pytest.approx(runs[0.0].tip_w[k])
    assert lines[-1][0][-1] == pytest.approx(0.776 + 0.714 + runs[0.0].tip_u[k])
    plt.close(ax.figure)


@pytest.mark.parametrize("func, quantity", [(figure23, "tip_w"), (figure24, "tip_u")])
def test_gain_figures(func, quantity, runs):
    ax = func(runs)
    lines = _lines(ax)
    assert len(lines) == len(GAINS)
    for (x, y), g in zip(lines, GAINS):
        assert_allclose(y, getattr(runs[g], quantity))
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["g = 0", "g = 0.2", "g = 2"]
    plt.close(ax.figure)


def test_figure25_tip_and_torque(runs):
    ax = figure25(runs)
    run = runs[0.2]
    (x, w), (_, u) = _lines(ax)
    assert_allclose(w, run.tip_w)
    assert_allclose(u, run.tip_u)
    twin = [a for a in ax.figure.axes if a is not ax]
    assert len(twin) == 1
    (_, torque), = _lines(twin[0])
    assert_allclose(torque, run.motor_torque)
    assert "peak torque 0.347" in ax.get_title()
    plt.close(ax.figure)


def test_helpers_draw_on_the_given_axes(runs):
    fig, ax = plt.subplots()
    assert plot_tip_history([runs[0.0]], ["free"], ax=ax) is ax
    assert figure20(runs, ax=ax) is ax
    with pytest.raises(InputError):
        plot_tip_history([runs[0.0]], ["a", "b"], ax=ax)
    plt.close(fig)


def test_write_figures_writes_pngs(runs, tmp_path):
    before = set(plt.get_fignums())   # other tests may leave their own figures open
    paths = write_figures(tmp_path / "figs", runs=runs)
    assert [p.name for p in paths] == [f"{n}.png" for n in FIGURES]
    for p in paths:
        assert p.read_bytes()[:8] == PNG and p.stat().st_size > 10_000
    assert set(plt.get_fignums()) <= before      # every figure it opened is closed


def test_figure_names():
    assert figure_names(["20", "fig21", "Figure25"]) == ["figure20", "figure21", "figure25"]
    assert figure_names([]) == list(FIGURES)
    with pytest.raises(InputError, match="unknown figure"):
        figure_names(["19"])


def test_cli_figures(tmp_path, capsys):
    assert cli_main(["figures", "--out", str(tmp_path), "22"]) == 0
    assert (tmp_path / "figure22.png").read_bytes()[:8] == PNG
    assert "wrote" in capsys.readouterr().out
    assert cli_main(["figures", "--out", str(tmp_path), "26"]) == 2


# ---------------------------------------------------------------- compare figure

def _unit(label: str) -> str:
    """The unit in the last parentheses of an axis label."""
    assert label.endswith(")"), label
    return label[label.rindex("(") + 1:-1]


@pytest.fixture(scope="module")
def comparison():
    import beamid
    from beamid.fit_decks import read_fit_deck
    from beamid.tables import inputs_dir

    deck = read_fit_deck(inputs_dir("demo") / "hidden_effect.nml")
    result = beamid.fit(deck.model, deck.experiments, deck.data, free=deck.free)
    return beamid.compare(result)


def _legend_texts(ax):
    return [t.get_text() for t in ax.get_legend().get_texts()]


def _drawn(ax):
    """Labels of everything drawn on ax that should be in the legend: lines
    and error-bar containers, excluding matplotlib's private children."""
    labels = [line.get_label() for line in ax.get_lines()
              if not line.get_label().startswith("_")]
    labels += [c.get_label() for c in ax.containers if not c.get_label().startswith("_")]
    return labels


def test_compare_figure_one_panel_per_quantity_and_unit(comparison):
    from beamid.plot_fit import plot_compare, quantity_unit

    fig = plot_compare(comparison)
    quantities = ["x_tip", "y_tip", "tip_angle"]
    assert [quantity_unit(q) for q in quantities] == ["m", "m", "rad"]
    axes = fig.axes
    assert len(axes) == 2 * len(quantities) + 1         # value and residual per quantity
    for j, q in enumerate(quantities):
        top, mid = axes[2 * j], axes[2 * j + 1]
        assert top.get_title() == q
        assert _unit(top.get_ylabel()) == _unit(mid.get_ylabel()) == quantity_unit(q)
    # no two units on one axis: each panel's y label names exactly one unit
    assert _unit(axes[-1].get_ylabel()) == "-"
    # the 15 measurements of the demo deck: 5 experiments along x
    assert [t.get_text() for t in axes[0].get_xticklabels()] == ["F2", "F4", "F6", "F8", "M3"]
    plt.close(fig)


def test_compare_figure_error_bars_are_visible(comparison):
    from beamid.plot_fit import plot_compare

    fig = plot_compare(comparison)
    for mid in fig.axes[1:-1:2]:
        bars, = [c for c in mid.containers]
        # the bars (+-sigma) span a visible share of the residual panel's y range
        lo, hi = mid.get_ylim()
        segments = bars.lines[2][0].get_segments()
        heights = [abs(s[1][1] - s[0][1]) for s in segments]
        assert min(heights) / (hi - lo) > 0.005
        assert min(heights) >= 2 * 1e-4 * (1 - 1e-9)       # 2 sigma, the smallest sigma
    plt.close(fig)


def test_compare_figure_every_line_has_a_legend_entry(comparison):
    from beamid.plot_fit import plot_compare

    fig = plot_compare(comparison)
    for ax in fig.axes:
        texts = _legend_texts(ax)
        assert sorted(texts) == sorted(_drawn(ax)), ax.get_ylabel()
    bottom = _legend_texts(fig.axes[-1])
    assert {"+-1 sigma", "+-3 sigma", "model (0)"} <= set(bottom)     # the dashed band too
    assert {"x_tip", "y_tip", "tip_angle"} <= set(bottom)
    plt.close(fig)


def test_measured_vs_model_refuses_mixed_units(comparison):
    from beamid.plot_fit import plot_measured_vs_model, plot_normalized_residuals

    with pytest.raises(InputError, match="different units"):
        plot_measured_vs_model(comparison)
    ax = plot_measured_vs_model(comparison, "tip_angle")
    assert _unit(ax.get_ylabel()) == "rad"
    assert sorted(_legend_texts(ax)) == sorted(_drawn(ax))
    ax2 = plot_normalized_residuals(comparison)
    assert sorted(_legend_texts(ax2)) == sorted(_drawn(ax2))
    plt.close("all")


def test_history_figure_panels(runs):
    from beamid.plotting import plot_history

    free = plot_history(runs[0.0])
    assert [_unit(ax.get_ylabel()) for ax in free.axes] == ["m", "m", "N m"]
    motor = plot_history(runs[0.2])
    assert [ax.get_ylabel() for ax in motor.axes] == [
        "tip w (m)", "tip u (m)", "energy (N m)", "motor torque (N m)"]
    for ax in motor.axes:
        assert sorted(_legend_texts(ax)) == sorted(_drawn(ax))
    (t, w), = _lines(motor.axes[0])
    assert_allclose(w, runs[0.2].tip_w)
    plt.close("all")


def test_quantity_units_of_every_registered_quantity():
    """Lengths in m, angles in rad, forces in N, the motor torque in N m (it
    was labelled m before the units came from one table)."""
    from beamid.plot_fit import quantity_unit

    got = {q: quantity_unit(q) for q in ("x_tip", "y_tip", "u_tip", "w_tip", "x_elbow",
                                         "y_elbow", "tip_angle", "wire_force",
                                         "motor_torque")}
    assert got == {"x_tip": "m", "y_tip": "m", "u_tip": "m", "w_tip": "m", "x_elbow": "m",
                   "y_elbow": "m", "tip_angle": "rad", "wire_force": "N",
                   "motor_torque": "N m"}
