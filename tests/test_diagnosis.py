"""Compare, diagnose, add_effect, improve: hidden-effect cases, one per candidate.

Synthetic data inside the tests: noise sigma 1e-4 (m and rad) from a fixed
seed, from a model with one effect switched on, fitted with the model that
lacks it (seed form, EI1 and EI2 free). Experiments: tip forces 2-8 N along
+y and a 3 N m tip moment; measured x_tip, y_tip and tip_angle.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import beamid
from beamid import InputError

SIGMA = 1e-4
FREE = ("EI1", "EI2")


def experiments():
    exps = {f"F{f:g}": beamid.TipForce(fy=f) for f in (2.0, 4.0, 6.0, 8.0)}
    exps["M3"] = beamid.TipMoment(3.0)
    return exps


def hidden(seed=11, **effect):
    truth = beamid.pace(axial_coupling=0.0).replace(**effect)
    exps = experiments()
    data = beamid.simulate_measurements(truth, exps, ["x_tip", "y_tip", "tip_angle"], sigma=SIGMA,
                           noise=True, seed=seed)
    fit = beamid.fit(beamid.pace(axial_coupling=0.0), exps, data, free=FREE)
    return fit


def within_noise(fit):
    # chi-square within three standard deviations of its expectation
    return fit.chi2 < fit.dof + 3.0 * math.sqrt(2.0 * fit.dof)


@pytest.mark.parametrize("effect, truth", [
    ("elbow_flex", {"elbow_flex": 0.004}),
    ("root_flex", {"root_flex": 0.003}),
    ("material_cubic", {"C1": 3.0, "C2": 5.0}),
    ("axial_coupling", {"axial_coupling": 1.0}),   # exact form fitted with the seed form
])
def test_hidden_effect_is_ranked_first_and_recovered(effect, truth):
    fit = hidden(**truth)
    assert not within_noise(fit)
    diag = beamid.diagnose(fit)
    assert diag.verdict is not None and diag.verdict.effect == effect
    assert diag.candidates[0].effect == effect
    top = diag.candidates[0]
    assert top.p_value < 1e-6 and top.refit and top.score_drop > 0
    # the linear score predicts the actual drop to first order
    assert top.score_drop == pytest.approx(top.lr_drop, rel=0.5)
    better = beamid.add_effect(fit, effect)
    assert within_noise(better), better.summary()
    assert better.chi2_per_dof < 2.0
    for name, value in truth.items():
        assert abs(better.estimates[name] - value) < 3.0 * better.sigmas[name], name
    assert effect in diag.message


def test_no_hidden_effect_finds_nothing_significant():
    fit = hidden()
    assert within_noise(fit)
    diag = beamid.diagnose(fit)
    assert diag.verdict is None
    assert "residuals not explained by any known effect" in diag.message
    assert "consistent with the noise" in diag.message
    for c in diag.candidates:
        if c.state == "tested":
            assert c.p_value > diag.alpha_each


def test_one_sided_compliance_with_wrong_sign_is_not_offered():
    # a stiffer first beam than assumed looks like a negative root compliance
    truth = beamid.pace(axial_coupling=0.0, EI1=12.5)
    exps = experiments()
    data = beamid.simulate_measurements(truth, exps, ["x_tip", "y_tip", "tip_angle"], sigma=SIGMA)
    fit = beamid.fit(beamid.pace(axial_coupling=0.0), exps, data, free=("EI2",))
    diag = beamid.diagnose(fit, ["root_flex", "elbow_flex"])
    root = diag["root_flex"]
    assert not root.physical and root.score_drop == 0.0 and root.p_value == 1.0
    assert diag.verdict is None or diag.verdict.effect != "root_flex"


def test_ambiguous_candidates_are_named_with_a_separating_measurement():
    # with only y_tip under forces, a root compliance and a softer first beam
    # cubic term explain the data about as well
    truth = beamid.pace(axial_coupling=0.0, root_flex=0.002)
    exps = {f"F{f:g}": beamid.TipForce(fy=f) for f in (3.0, 5.0, 6.5, 8.0)}
    data = beamid.simulate_measurements(truth, exps, ["y_tip"], sigma=1e-3, noise=True, seed=3)
    fit = beamid.fit(beamid.pace(axial_coupling=0.0), exps, data, free=("EI2",))
    diag = beamid.diagnose(fit, ["root_flex", "elbow_flex"])
    assert diag.verdict is not None
    assert diag.rivals, str(diag)
    rival = diag.rivals[0]
    assert {diag.verdict.effect, rival.effect} == {"root_flex", "elbow_flex"}
    assert "ambiguous" in diag.message and rival.effect in diag.message
    exp, quantity, nsig = rival.separating
    assert exp in exps and quantity in ("x_tip", "y_tip", "tip_angle", "x_elbow", "y_elbow")
    assert nsig > 0.0 and f"measure {quantity} in experiment {exp}" in diag.message


def test_improve_ladder_falls_to_the_noise():
    fit0 = hidden(elbow_flex=0.004, C1=3.0, C2=5.0)
    ladder = beamid.improve(beamid.pace(axial_coupling=0.0), fit0.experiments, fit0.data,
                            free=FREE)
    assert set(ladder.effects) == {"elbow_flex", "material_cubic"}
    chi = [s.chi2_per_dof for s in ladder.steps]
    assert all(b < a for a, b in zip(chi, chi[1:]))
    assert within_noise(ladder.fit)
    assert ladder.steps[-1].diagnosis.verdict is None
    text = str(ladder)
    assert "(start)" in text and "elbow_flex" in text and "material_cubic" in text


def test_compare_finds_structure_in_a_bad_fit_and_none_in_a_good_one():
    bad = beamid.compare(hidden(axial_coupling=1.0))
    assert bad.systematic and bad.p_value < 1e-6
    assert bad.chi2 == pytest.approx(sum(r.normalized ** 2 for r in bad.rows))
    good = beamid.compare(hidden())
    assert not good.systematic
    assert good.expected == good.dof
    assert good.expected_sigma == pytest.approx(math.sqrt(2 * good.dof))
    assert len(good.rows) == 15 and set(good.per_experiment) == set(experiments())
    assert "no systematic structure" in str(good)


def test_trend_test_sees_a_drift_against_load():
    # residuals that grow with the load are structure even if chi2 is modest
    truth = beamid.pace(axial_coupling=0.0)
    exps = {f"F{f:g}": beamid.TipForce(fy=f) for f in np.linspace(1.0, 8.0, 12)}
    data = beamid.simulate_measurements(truth, exps, ["y_tip"], sigma=1e-3)
    drift = data.with_values(data.value + 1e-3 * np.linspace(-2.0, 2.0, 12) ** 3 / 3.0)
    fit = beamid.fit(truth, exps, drift, free=("EI1",))
    cmp = beamid.compare(fit)
    names = {t.name: t for t in cmp.tests}
    assert names["runs test"].p_value < 0.05 or names["trend against load"].p_value < 0.05


def test_diagnose_input_errors():
    fit = hidden()
    with pytest.raises(InputError, match="unknown effect 'gravity'"):
        beamid.diagnose(fit, ["gravity"])
    with pytest.raises(InputError, match="alpha = 2"):
        beamid.diagnose(fit, alpha=2.0)
    with pytest.raises(InputError, match="already free"):
        beamid.add_effect(beamid.add_effect(fit, "root_flex"), "root_flex")


def test_free_and_switched_on_candidates_are_skipped():
    fit = hidden(C1=3.0, C2=5.0)
    withc = beamid.add_effect(fit, "material_cubic")
    diag = beamid.diagnose(withc)
    assert diag["material_cubic"].state == "already free"
    exact = beamid.fit(beamid.pace(axial_coupling=1.0), fit.experiments, fit.data, free=FREE)
    assert beamid.diagnose(exact)["axial_coupling"].state == "already switched on"
