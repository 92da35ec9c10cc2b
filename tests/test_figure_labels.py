"""Every figure beamid draws says what it shows: a title, axis labels with
units, legends for its markers. One test per public plotting function and
per figure a command writes (the titles and labels are read back from the
matplotlib objects: the functions return them, and the ``saved_figures``
fixture of conftest.py records every figure a command saves). The images
the docs show are checked where their examples run (tests/test_docs.py)."""
from __future__ import annotations

import shutil
from types import SimpleNamespace

import numpy as np
import pytest

import beamid
from beamid.tables import inputs_dir


def _labelled(texts: dict, name: str) -> None:
    """A title, and on every panel a y label; an x label on at least one."""
    assert texts["title"], f"{name}: no title"
    assert all(texts["ylabels"]), f"{name}: a panel without y label: {texts['ylabels']}"
    assert any(texts["xlabels"]), f"{name}: no x label"


def _short_run(**params):
    model = beamid.pace(J_elbow=0.0, J_tip=0.0).replace(**params)
    return beamid.simulate(model, beamid.TipForce(fy=8.0), [0.0, 0.02, 0.05],
                           elements_per_beam=2, motor_gain=0.2 if "r_motor" in params else 0.0)


# ------------------------------------------------------------ dynamic runs


def test_history_title_says_what_the_run_had():
    from beamid.plotting import plot_history

    plain = plot_history(_short_run()).axes[0].get_title()
    assert plain == "implicit integrator, 2 elements per beam; no friction"
    rub = plot_history(_short_run(mu_elbow=0.01, mu_tip=0.02)).axes[0].get_title()
    assert rub.endswith("; friction (sign law) mu_elbow 0.01, mu_tip 0.02")
    motor = plot_history(_short_run(r_motor=1.0, c_tip=0.01, eta=0.001))
    assert motor.axes[0].get_title().endswith("no friction, drag c_tip 0.01, "
                                              "Kelvin-Voigt eta 0.001, tip motor")
    assert [a.get_ylabel() for a in motor.axes] == ["tip w (m)", "tip u (m)", "energy (N m)",
                                                   "motor torque (N m)"]
    assert motor.axes[-1].get_xlabel() == "time (s)"


def test_cli_simulate_figure(tmp_path, saved_figures, monkeypatch):
    from beamid.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--t-end", "0.05", "--n-out", "3", "-e", "2"]) == 0
    texts = saved_figures["simulate_history.png"]
    _labelled(texts, "simulate_history.png")
    assert texts["title"] == "implicit integrator, 2 elements per beam; no friction"


def test_figure_titles_give_the_span_drawn():
    from beamid.figures import FIGURE_TIMES, figure20, figure21, figure23

    def fake(t):
        return SimpleNamespace(t=t, tip_w=np.zeros_like(t), tip_u=np.zeros_like(t))

    short = {g: fake(np.linspace(0.0, 0.8, 9)) for g in (0.0, 0.2, 2.0)}
    full = {g: fake(FIGURE_TIMES) for g in (0.0, 0.2, 2.0)}
    assert figure20(short).get_title() == "Figure 20. Tip transverse deflection over 0-0.8 s"
    assert figure21(full).get_title() == ("Figure 21. Tip longitudinal deflection over a "
                                          "period (2.6 s)")
    ax = figure23(short)
    assert ax.get_title().endswith("transverse displacements, over 0-0.8 s")
    assert ax.get_xlabel() == "time (s)" and ax.get_ylabel().endswith("(m)")


# ----------------------------------------------------------------- statics


def test_shapes_title_and_marker_legend():
    from beamid.plotting import plot_shapes

    rs = [beamid.solve_static(beamid.pace(), beamid.TipForce(fy=8.0)),
          beamid.solve_static(beamid.pace(), beamid.RadialWire(1.3))]
    ax = plot_shapes(rs, labels=["8 N", "wire"])
    assert ax.get_title() == "static shapes"
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (m)", "y (m)")
    legend = {t.get_text(): h for t, h in zip(ax.get_legend().get_texts(),
                                               ax.get_legend().legend_handles)}
    assert list(legend) == ["8 N", "wire", "elbow", "tip", "wire"][:len(legend)]
    assert legend["elbow"].get_marker() == "o" and legend["tip"].get_marker() == "s"
    assert plot_shapes(rs[:1], title=None).get_title() == ""
    assert plot_shapes(rs[:1], title="x").get_title() == "x"


# -------------------------------------------------------------- estimation


@pytest.fixture(scope="module")
def demo_ladder():
    from beamid.fit_decks import read_fit_deck

    deck = read_fit_deck(inputs_dir("demo") / "hidden_effect.nml")
    return beamid.improve(deck.model, deck.experiments, deck.data, free=deck.free)


def test_compare_plots(demo_ladder):
    from beamid.plot_fit import (plot_compare, plot_measured_vs_model,
                                 plot_normalized_residuals)

    from conftest import figure_texts

    cmp = beamid.compare(demo_ladder[0].fit)
    ax = plot_measured_vs_model(cmp, "y_tip")
    assert ax.get_title().startswith("measured vs model (chi2 = ")
    assert ax.get_xlabel().startswith("load level") and ax.get_ylabel() == "value (m)"
    ax = plot_normalized_residuals(cmp)
    assert ax.get_title() == "normalized residuals (systematic)"
    assert ax.get_ylabel() == "(measured - model) / sigma (-)"
    texts = figure_texts(plot_compare(cmp, title="start"))
    _labelled(texts, "compare")
    assert texts["title"] == ("start: measured vs model: chi2 = 4.392e+04, dof 13, "
                              "chi2/dof = 3378 (systematic residuals)")


def test_ladder_labels_say_what_each_step_did(demo_ladder):
    from beamid.plot_fit import ladder_labels, ladder_titles, plot_ladder

    assert ladder_labels(demo_ladder) == ["start", "axial_coupling", "elbow_flex"]
    assert ladder_titles(demo_ladder) == ("start (step 0, no effect added)",
                                          "final fit (step 2: axial_coupling, elbow_flex added)")
    # a rung that replaces a member of a block says so (the dynamic demo's last rung)
    step = SimpleNamespace
    fake = SimpleNamespace(steps=[
        step(step=0, effect=None, chi2_per_dof=32.6, params=(), removed=()),
        step(step=1, effect="drag", chi2_per_dof=2.86, params=("c_elbow",), removed=()),
        step(step=2, effect="rotary_inertia", chi2_per_dof=1.03, params=("J_tip",),
             removed=()),
        step(step=3, effect="drag", chi2_per_dof=0.71, params=("c_tip",),
             removed=("c_elbow",))])
    ax = plot_ladder(fake)
    assert [t.get_text() for t in ax.texts] == ["start", "drag", "rotary_inertia",
                                                "drag: c_tip instead of c_elbow"]
    assert (ax.get_title(), ax.get_xlabel(), ax.get_ylabel()) == (
        "error against step", "improvement step", "chi2 / dof")


def test_cli_improve_figures(tmp_path, saved_figures):
    from beamid.fit_decks import run_fit_deck

    for f in ("hidden_effect.nml", "hidden_effect.csv"):
        shutil.copy(inputs_dir("demo") / f, tmp_path / f)
    run_fit_deck(str(tmp_path / "hidden_effect.nml"))
    assert saved_figures["hidden_effect_ladder.png"]["title"] == "error against step"
    start = saved_figures["hidden_effect_compare_start.png"]
    final = saved_figures["hidden_effect_compare_final.png"]
    assert start["title"].startswith("start (step 0, no effect added): measured vs model: "
                                     "chi2 = 4.392e+04, dof 13, chi2/dof = 3378")
    assert final["title"].startswith("final fit (step 2: axial_coupling, elbow_flex added): "
                                     "measured vs model: chi2 = 14.55, dof 11, chi2/dof = 1.323")
    for name, texts in saved_figures.items():
        _labelled(texts, name)


@pytest.fixture(scope="module")
def table05_fit():
    from beamid.fit_decks import read_fit_deck

    deck = read_fit_deck(inputs_dir("seed") / "table05_fit.nml")
    return beamid.fit(deck.model, deck.experiments, deck.data, free=deck.free)


def test_identify_plot(tmp_path, saved_figures):
    from beamid.fit_decks import run_identify

    # the command's figure (two static decks as stages) and the method behind it
    for deck in ("table04_fit.nml", "table05_fit.nml"):
        shutil.copy(inputs_dir("seed") / deck, tmp_path / deck)
    for csv in ("table04_data.csv", "table05_data.csv"):
        shutil.copy(inputs_dir("seed") / csv, tmp_path / csv)
    run_identify([str(tmp_path / "table04_fit.nml"), str(tmp_path / "table05_fit.nml")])
    (name,) = [n for n in saved_figures if n.endswith("_identify.png")]
    texts = saved_figures[name]
    assert texts["title"] == "what each stage taught: relative sigma after it"
    assert texts["xlabels"] == ["parameter"]
    assert texts["ylabels"] == ["sigma / estimate after the stage (-)"]


def test_design_plot_axis(table05_fit):
    cands = {"M3": beamid.TipMoment(3.0), "Lw1.3": beamid.RadialWire(1.3),
             "F12": beamid.TipForce(fy=12.0)}
    adv = beamid.design(table05_fit, cands, ["x_tip", "tip_angle"],
                        sigma={"x_tip": 1e-3, "tip_angle": 1e-3}, target="EI2")
    ax = adv.plot()
    assert ax.get_xlabel() == "predicted sigma of EI2 (N m^2)"
    assert ax.get_title().startswith("which measurement next")
    ax.figure.canvas.draw()
    shown = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
    assert len(shown) >= 3, shown            # not one label on a log axis
    d = beamid.design(table05_fit, cands, ["x_tip"], sigma={"x_tip": 1e-3}, target=None)
    assert d.plot().get_xlabel().endswith("(geometric mean of the sigmas, mixed units)")


def test_design_log_ticks():
    from beamid.design import _log_ticks

    assert _log_ticks(0.03, 1.0) == [0.05, 0.1, 0.2, 0.5, 1.0]
    assert _log_ticks(0.052, 0.098) == [0.06, 0.07, 0.08, 0.09]
    assert _log_ticks(2.0, 2000.0) == [2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0,
                                       1000.0, 2000.0]


def test_consistency_histograms_have_y_labels(table05_fit):
    mc = beamid.consistency(table05_fit, replicates=20, seed=1)
    fig = mc.plot()
    assert [a.get_ylabel() for a in fig.axes] == ["probability density"] * 3
    assert [a.get_xlabel() for a in fig.axes] == ["(EI1 - truth) / sigma (-)",
                                                 "(EI2 - truth) / sigma (-)", "chi2 (-)"]
    assert all(a.get_title() for a in fig.axes)


def test_time_comparison_title():
    base = beamid.pace().replace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.0, mu_tip=0.0)
    rel = {"free": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=2)}
    data = beamid.simulate_measurements(base.replace(rho2=0.55), rel, ["w_tip"], sigma=1e-4,
                                        t=[0.2, 0.4, 0.6], noise=True, seed=3)
    fit = beamid.fit(base, rel, data, free=("rho2",))
    fig = beamid.compare(fit).plot(title="free")
    assert fig._suptitle.get_text().startswith("free: measured vs model: chi2 = ")
    assert [a.get_xlabel() for a in fig.axes] == ["", "t (s)"]
    assert fig.axes[0].get_ylabel() == "w_tip (m)"


def test_demo_forms_figure(tmp_path, saved_figures):
    from beamid.demo import _forms_figure

    _forms_figure(tmp_path / "forms.png", "tip forces", [beamid.TipForce(fy=4.0)],
                  lambda r, i: f"fy = {4.0 * (i + 1):g} N")
    texts = saved_figures["forms.png"]
    _labelled(texts, "forms.png")
    assert texts["title"] == "tip forces"
    assert texts["titles"] == ["seed form (axial_coupling = 0)",
                               "exact elastica (axial_coupling = 1)"]
    assert texts["xlabels"] == ["x (m)", "x (m)"]
