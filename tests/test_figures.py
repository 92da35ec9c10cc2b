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
