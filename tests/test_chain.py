"""The measurement chain (issue 29): a record's clock offset, a channel's bias
and scale fitted with the physics as extra columns."""
from __future__ import annotations

import dataclasses
import math
import re
import os
from pathlib import Path

import numpy as np
import pytest

import beamid
from beamid import _core_estimation as _ce
from beamid.chain import ChainSpec, layout, parse_nuisance
from beamid.estimation import build_problem

BASE = beamid.pace().replace(J_elbow=0.0, J_tip=0.0)


def _release(nepb=2, **kw):
    return beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=nepb, **kw)


@pytest.fixture(scope="module")
def small():
    """A short record of tip u and w (rows at 0.1 .. 0.5 s)."""
    exps = {"free": _release()}
    times = [0.1, 0.2, 0.3, 0.4, 0.5]
    data = beamid.simulate_measurements(BASE, exps, ["u_tip", "w_tip"], sigma=1e-3, t=times)
    return exps, data


def test_layout_is_the_fortran_order(small):
    exps, data = small
    spec = parse_nuisance({"scale": [("free", "w_tip")], "bias": ["u_tip", "w_tip"],
                           "time_offset": ["free"]}, exps, data)
    prob = build_problem(BASE, exps, data, chain=spec)
    assert [(k, e, q) for k, e, q in layout(prob, ["free"])] == spec.order(["free"])
    assert spec.names(["free"]) == ("t0[free]", "bias[free:u_tip]", "bias[free:w_tip]",
                                    "scale[free:w_tip]")


def test_chain_columns_match_central_differences(small):
    """The hand-coded columns of t0 (s dh/dt from the state's rates), bias (1)
    and scale (h), and the physics column scaled by s, against central
    differences of the predictions."""
    exps, data = small
    spec = parse_nuisance({"time_offset": {"free": 0.012}, "bias": {("free", "w_tip"): 2e-3},
                           "scale": {("free", "w_tip"): 1.03, ("free", "u_tip"): 0.97}},
                          exps, data)
    prob = build_problem(BASE, exps, data, chain=spec)
    p0 = np.concatenate([BASE.vector(), spec.starts(["free"])])
    npar = BASE.vector().size
    rho2 = BASE.index("rho2") + 1
    wrt = np.array([rho2] + list(range(npar + 1, p0.size + 1)), np.int32)
    pred, jac = _ce.problem_predict(prob, p0, wrt)
    steps = [1e-5, 1e-6, 1e-6, 1e-6, 1e-6]
    for c, (k, h) in enumerate(zip(wrt, steps)):
        pp, pm = p0.copy(), p0.copy()
        pp[k - 1] += h
        pm[k - 1] -= h
        fd = (_ce.problem_predict(prob, pp, np.zeros(0, np.int32))[0]
              - _ce.problem_predict(prob, pm, np.zeros(0, np.int32))[0]) / (2 * h)
        scale = np.max(np.abs(fd))
        assert scale > 0.0
        assert np.max(np.abs(jac[:, c] - fd)) < 2e-4 * scale, (c, jac[:, c], fd)
    # the chain acts as documented: s h(t + t0) + b on w, s h(t + t0) on u
    plain = build_problem(BASE, exps, data)
    shifted = data.__class__.from_rows(
        [(e, t + 0.012, q, 0.0, s) for e, t, q, s in zip(data.experiment, data.t,
                                                          data.quantity, data.sigma)])
    h, _ = _ce.problem_predict(build_problem(BASE, exps, shifted), BASE.vector(),
                               np.zeros(0, np.int32))
    is_w = np.array([q == "w_tip" for q in data.quantity])
    expect = np.where(is_w, 1.03 * h + 2e-3, 0.97 * h)
    assert np.max(np.abs(pred - expect)) < 1e-12
    assert plain.exp_values.shape == (_ce.NEXPVAL, 1)


def _offset_record(t0=0.015, sigma=1e-3, seed=29, rate=500.0, duration=1.3):
    """Tip u and w sampled at ``rate`` over ``duration``, the logger's zero
    t0 after the release; truth at rtol 1e-11 (tighter than the fit's)."""
    times = np.round(np.arange(1, int(round(duration * rate)) + 1) / rate, 6)
    fine = {"free": _release(4, rtol=1e-11)}
    exact = beamid.simulate_measurements(BASE, fine, ["u_tip", "w_tip"], sigma=sigma,
                                         t=times + t0)
    rng = np.random.default_rng(seed)
    rows = [(e, round(t - t0, 6), q, v + sigma * rng.standard_normal(), s)
            for e, t, q, v, s in zip(exact.experiment, exact.t, exact.quantity, exact.value,
                                     exact.sigma)]
    return beamid.Measurements.from_rows(rows)


def test_time_offset_recovers_15_ms_and_rho2():
    data = _offset_record(rate=100.0)    # 260 rows: the doc's 500 Hz record is slower
    exps = {"free": _release(4)}
    start = BASE.replace(rho2=0.5)
    plain = beamid.fit(start, exps, data, free=("rho2",))
    fit = beamid.fit(start, exps, data, free=("rho2",), nuisance={"time_offset": ["free"]})
    assert plain.chi2_per_dof > 5.0                        # the offset wrecks the plain fit
    assert fit.chi2_per_dof < 1.3
    t0, s0 = fit.nuisance["t0[free]"], fit.nuisance_sigmas["t0[free]"]
    assert abs(t0 - 0.015) < 3 * s0 and s0 < 1e-3
    assert abs(fit.estimates["rho2"] - 0.530) < 2 * fit.sigmas["rho2"]
    # the physics covariance is the block of the full inverse
    assert fit.full_cov.shape == (2, 2)
    assert fit.cov[0, 0] == pytest.approx(fit.full_cov[0, 0])
    assert "t0[free]" in fit.summary()


def test_bias_and_scale_recovered():
    exps = {"free": _release(2)}
    times = np.round(np.arange(1, 66) * 0.02, 6)
    data0 = beamid.simulate_measurements(BASE, {"free": _release(2, rtol=1e-11)},
                                         ["u_tip", "w_tip"], sigma=1e-3, t=times)
    rng = np.random.default_rng(3)
    w = np.array([q == "w_tip" for q in data0.quantity])
    values = np.where(w, data0.value + 0.004, 1.05 * data0.value) \
        + 1e-3 * rng.standard_normal(len(data0))
    data = data0.with_values(values)
    fit = beamid.fit(BASE, exps, data, free=("rho2",),
                     nuisance={"bias": [("free", "w_tip")], "scale": [("free", "u_tip")]})
    b, sb = fit.nuisance["bias[free:w_tip]"], fit.nuisance_sigmas["bias[free:w_tip]"]
    s, ss = fit.nuisance["scale[free:u_tip]"], fit.nuisance_sigmas["scale[free:u_tip]"]
    assert abs(b - 0.004) < 3 * sb and sb < 5e-4
    assert abs(s - 1.05) < 3 * ss and ss < 0.01
    assert abs(fit.estimates["rho2"] - 0.530) < 3 * fit.sigmas["rho2"]
    assert fit.chi2_per_dof < 1.3


def test_bad_nuisance_input(small):
    exps, data = small
    with pytest.raises(beamid.InputError, match=r"channel \('free', 'y_elbow'\) does not exist"):
        beamid.fit(BASE, exps, data, free=("rho2",), nuisance={"bias": [("free", "y_elbow")]})
    with pytest.raises(beamid.InputError, match="no experiment 'nope'"):
        beamid.fit(BASE, exps, data, free=("rho2",), nuisance={"time_offset": ["nope"]})
    with pytest.raises(beamid.InputError, match="unknown kind 'offset'"):
        beamid.fit(BASE, exps, data, free=("rho2",), nuisance={"offset": ["free"]})
    static = {"F3": beamid.TipForce(fy=3.0)}
    sdata = beamid.simulate_measurements(BASE, static, ["y_tip"], sigma=1e-3)
    with pytest.raises(beamid.InputError, match="static; a time offset needs a record"):
        beamid.fit(BASE, static, sdata, free=("EI1",), nuisance={"time_offset": ["F3"]})


def test_fortran_refuses_a_static_time_offset():
    """The core checks what it is given (decks reach it without Python)."""
    static = {"F3": beamid.TipForce(fy=3.0)}
    sdata = beamid.simulate_measurements(BASE, static, ["y_tip"], sigma=1e-3)
    prob = build_problem(BASE, static, sdata, chain=ChainSpec(t0={"F3": 0.0}))
    with pytest.raises(beamid.InputError, match="time offset asked for a static experiment"):
        _ce.problem_predict(prob, np.append(BASE.vector(), 0.0), np.zeros(0, np.int32))


RIG_CANDIDATES = ("friction", "drag", "rotary_inertia", "kelvin_voigt", "clock_offset",
                  "channel_bias", "channel_scale", "gross_errors", "noise")


def test_diagnose_blames_the_clock_not_the_physics():
    """The 15 ms example (at 100 Hz): the verdict is the clock offset, a
    cause of the measurement chain, and its refit gives rho2 within its
    sigma of the truth."""
    data = _offset_record(rate=100.0)
    exps = {"free": _release(4)}
    plain = beamid.fit(BASE.replace(rho2=0.5), exps, data, free=("rho2",))
    d = beamid.diagnose(plain)
    assert d.verdict is not None and d.verdict.effect == "clock_offset"
    assert d.verdict.cause == "measurement chain" and d["drag"].cause == "physics"
    assert d.message.startswith("measurement chain, not physics: clock_offset")
    t0 = d.verdict.estimate["t0[free]"]
    assert abs(t0 - 0.015) < 3 * d.verdict.sigma["t0[free]"]
    refit = beamid.add_effect(plain, "clock_offset")
    assert abs(refit.estimates["rho2"] - 0.530) < 2 * refit.sigmas["rho2"]
    assert d.verdict.refit_model["rho2"] == pytest.approx(refit.estimates["rho2"], abs=1e-4)
    with pytest.raises(beamid.InputError, match="no parameter left to add"):
        beamid.add_effect(refit, "clock_offset")


def test_four_hidden_flaws_found_and_named():
    """Hidden effects: the tip mass's rotary inertia (physics), a 5 ms clock
    offset, a 4 mm bias of w and three gross errors (the chain), data at a
    tighter tolerance with sigma 1 mm from a fixed seed. diagnose names the
    gross errors first (exactly the three rows); without them the ladder
    ends with the other three, each named as what it is, and nothing more
    significant."""
    truth = BASE.replace(J_tip=0.01)
    times = np.round(np.arange(1, 131) / 100.0, 6)
    fine = {"free": _release(2, rtol=1e-11)}
    exact = beamid.simulate_measurements(truth, fine, ["u_tip", "w_tip"], sigma=1e-3,
                                         t=times + 0.005)
    rng = np.random.default_rng(7)
    w = np.array([q == "w_tip" for q in exact.quantity])
    vals = exact.value + 1e-3 * rng.standard_normal(len(exact)) + np.where(w, 4e-3, 0.0)
    vals[[31, 120, 207]] += [0.03, -0.035, 0.04]
    data = beamid.Measurements.from_rows(
        [(e, round(t - 0.005, 6), q, v, s)
         for e, t, q, v, s in zip(exact.experiment, exact.t, exact.quantity, vals, exact.sigma)])
    exps = {"free": _release(2)}
    d = beamid.diagnose(beamid.fit(BASE, exps, data, free=("rho2",)), RIG_CANDIDATES)
    assert d.verdict.effect == "gross_errors" and d.verdict.cause == "measurement chain"
    assert d.verdict.params == ("row 31", "row 120", "row 207")
    assert d.message.startswith("measurement chain, not physics: gross_errors")
    clean = beamid.add_effect(d.fit, "gross_errors")
    assert len(clean.data) == len(data) - 3
    assert clean.note.startswith("gross errors left out: rows 31 (free w_tip t = 0.16)")
    lad = beamid.improve(BASE, exps, clean.data, free=("rho2",), candidates=RIG_CANDIDATES)
    fit = lad.fit
    assert set(lad.effects) >= {"clock_offset", "channel_bias", "rotary_inertia"}
    assert set(fit.nuisance) == {"t0[free]", "bias[free:w_tip]"}
    assert abs(fit.nuisance["t0[free]"] - 0.005) < 3 * fit.nuisance_sigmas["t0[free]"]
    assert abs(fit.nuisance["bias[free:w_tip]"] - 0.004) < \
        3 * fit.nuisance_sigmas["bias[free:w_tip]"]
    assert abs(fit.estimates["J_tip"] - 0.01) < 3 * fit.sigmas["J_tip"]
    assert abs(fit.estimates["rho2"] - 0.530) < 3 * fit.sigmas["rho2"]
    assert lad.steps[-1].diagnosis.verdict is None
    assert "J_tip" in fit.free and "eta" not in fit.free


def test_null_data_claim_nothing():
    """The right model, data at a tighter tolerance with honest noise: no
    chain parameter and no effect is claimed."""
    times = np.round(np.arange(1, 66) * 0.02, 6)
    exact = beamid.simulate_measurements(BASE, {"free": _release(2, rtol=1e-11)},
                                         ["u_tip", "w_tip"], sigma=1e-3, t=times)
    rng = np.random.default_rng(11)
    data = exact.with_values(exact.value + 1e-3 * rng.standard_normal(len(exact)))
    fit = beamid.fit(BASE.replace(rho2=0.5), {"free": _release(2)}, data, free=("rho2",))
    d = beamid.diagnose(fit, RIG_CANDIDATES)
    assert d.verdict is None
    assert not any(c.significant for c in d)
    assert d.message.startswith("residuals not explained by any known effect")


#: noise draws of the coverage check: make test's short run, and make
#: test-check's long one (BEAMID_FUZZ_PROFILE=long) whose tolerances are the
#: "few percent" of issue 29
COVERAGE_DRAWS = 5000 if os.environ.get("BEAMID_FUZZ_PROFILE") == "long" else 600


def _binomial_band(p: float, n: int, k: float = 3.0) -> float:
    """k standard deviations of a share p observed in n independent draws."""
    return k * math.sqrt(p * (1.0 - p) / n)


def test_coverage_of_t0_and_bias_sigmas():
    """Monte Carlo: over COVERAGE_DRAWS noise draws (fixed seed) the
    estimates of a clock offset t0 and a channel bias fall within 1 and 2 of
    their sigmas as often as a normal law says (68.3 %, 95.4 %), within 3
    binomial standard deviations of the draws (short run, 600 draws: 5.7
    and 2.6 points; long run, 5000 draws: 2.0 and 0.9 points), and their
    mean square standardized error is 1 within 3 sd (sqrt(2 / n) each).

    One draw is a fit of rho2, t0 and the bias of w on 60 rows (tip u and
    w at 30 times over 0.6 s, sigma 1 mm) on one element per beam
    integrated at rtol 1e-6 (its data too: the same model), so a draw costs
    ~0.01 s CPU; the nuisance parameters start at the truth (the fit's end
    point does not depend on it; fewer iterations)."""
    times = np.round(np.arange(1, 31) * 0.02, 6)
    exps = {"free": _release(1, rtol=1e-6)}
    exact = beamid.simulate_measurements(BASE, exps, ["u_tip", "w_tip"], sigma=1e-3,
                                         t=times + 0.01)
    w = np.array([q == "w_tip" for q in exact.quantity])
    base_rows = [(e, round(t - 0.01, 6), q, s) for e, t, q, s in
                 zip(exact.experiment, exact.t, exact.quantity, exact.sigma)]
    rng = np.random.default_rng(2029)
    n = COVERAGE_DRAWS
    z = []
    for _ in range(n):
        v = exact.value + np.where(w, 2e-3, 0.0) + 1e-3 * rng.standard_normal(len(exact))
        data = beamid.Measurements.from_rows([(e, t, q, vk, s) for (e, t, q, s), vk
                                              in zip(base_rows, v)])
        fit = beamid.fit(BASE, exps, data, free=("rho2",),
                         nuisance={"time_offset": {"free": 0.01},
                                   "bias": {("free", "w_tip"): 2e-3}})
        z.append([(fit.nuisance["t0[free]"] - 0.01) / fit.nuisance_sigmas["t0[free]"],
                  (fit.nuisance["bias[free:w_tip]"] - 2e-3)
                  / fit.nuisance_sigmas["bias[free:w_tip]"]])
    z = np.abs(np.array(z))
    p1, p2 = math.erf(1.0 / math.sqrt(2.0)), math.erf(2.0 / math.sqrt(2.0))
    one, two = np.mean(z < 1.0, axis=0), np.mean(z < 2.0, axis=0)
    assert np.all(np.abs(one - p1) < _binomial_band(p1, n)), (one, n)
    assert np.all(np.abs(two - p2) < _binomial_band(p2, n)), (two, n)
    assert np.all(np.abs(np.mean(z ** 2, axis=0) - 1.0) < 3.0 * math.sqrt(2.0 / n)), \
        (np.mean(z ** 2, axis=0), n)


@pytest.fixture(scope="module")
def gross():
    """65 times of tip u and w (sigma 1 mm, fixed seed) with three gross
    errors of 40-60 sigma."""
    times = np.round(np.arange(1, 66) * 0.02, 6)
    exact = beamid.simulate_measurements(BASE, {"free": _release(2, rtol=1e-11)},
                                         ["u_tip", "w_tip"], sigma=1e-3, t=times)
    rng = np.random.default_rng(5)
    clean = exact.value + 1e-3 * rng.standard_normal(len(exact))
    v = clean.copy()
    v[[10, 51, 90]] += [0.05, -0.04, 0.06]
    return exact.with_values(clean), exact.with_values(v)


@pytest.mark.parametrize("loss", ["huber", "cauchy"])
def test_robust_loss_finds_the_gross_errors(gross, loss):
    clean, data = gross
    exps = {"free": _release(2)}
    start = BASE.replace(rho2=0.5)
    ref = beamid.fit(start, exps, clean, free=("rho2",))
    plain = beamid.fit(start, exps, data, free=("rho2",))
    fit = beamid.fit(start, exps, data, free=("rho2",), loss=loss)
    assert plain.chi2_per_dof > 30 and plain.gross_errors == ()
    assert fit.gross_errors == (10, 51, 90) and fit.loss == loss
    assert fit.dof == ref.dof - 3 and fit.chi2_per_dof < 1.2
    # the robust estimate stays within half a sigma of the clean data's
    assert abs(fit.estimates["rho2"] - ref.estimates["rho2"]) < 0.5 * ref.sigmas["rho2"]
    assert abs(plain.estimates["rho2"] - ref.estimates["rho2"]) > 1.0 * ref.sigmas["rho2"]
    assert fit.weights[[10, 51, 90]].max() < 0.1 and np.median(fit.weights) > 0.9
    cmp = beamid.compare(fit)
    assert int(np.sum(cmp["free", "u_tip"].flagged)) == 2
    assert int(np.sum(cmp["free", "w_tip"].flagged)) == 1
    assert "gross errors (|normalized residual| > 3.5): free u_tip t = 0.12 s" in str(cmp)
    assert not cmp.systematic


def test_unknown_sigma_estimated_per_channel(gross):
    clean, _ = gross
    exps = {"free": _release(2)}
    ones = beamid.Measurements.from_rows(
        [(e, t, q, v, 1.0) for e, t, q, v in zip(clean.experiment, clean.t, clean.quantity,
                                                 clean.value)])
    stated = beamid.fit(BASE, exps, clean, free=("rho2",))
    fit = beamid.fit(BASE, exps, ones, free=("rho2",), estimate_sigma=True)
    assert set(fit.sigma_estimates) == {"free:u_tip", "free:w_tip"}
    for s, sd in fit.sigma_estimates.values():
        assert abs(s - 1e-3) < 3 * sd and sd == pytest.approx(s / np.sqrt(2 * 64.5), rel=0.02)
    assert fit.dof == stated.dof - 2
    assert abs(fit.estimates["rho2"] - stated.estimates["rho2"]) < 0.2 * stated.sigmas["rho2"]
    assert fit.sigmas["rho2"] == pytest.approx(stated.sigmas["rho2"], rel=0.25)   # noise of s
    assert fit.flags["rho2"] == "ok"
    assert "sigma of free:u_tip estimated from the residuals" in fit.summary()


def test_burn_in_rows_shown_not_fitted(gross):
    clean, _ = gross
    exps = {"free": _release(2)}
    bad = clean.with_values(np.where(clean.t < 0.1, clean.value + 0.05, clean.value))
    fit = beamid.fit(BASE, exps, bad, free=("rho2",), burn_in=0.1)
    ref = beamid.fit(BASE, exps, clean, free=("rho2",))
    assert int(np.sum(~fit.fitted_rows)) == 8              # t = 0.02 .. 0.08, u and w
    assert fit.dof == ref.dof - 8
    assert abs(fit.estimates["rho2"] - ref.estimates["rho2"]) < 0.5 * ref.sigmas["rho2"]
    assert len(fit.residuals) == len(bad)                   # shown
    assert min(abs(r.normalized) for r, u in zip(fit.residuals, fit.fitted_rows) if not u) > 20


def test_bad_row_treatment_input(small):
    exps, data = small
    with pytest.raises(beamid.InputError, match="loss = 'l1', expected one of linear, huber"):
        beamid.fit(BASE, exps, data, free=("rho2",), loss="l1")
    with pytest.raises(beamid.InputError, match="estimate_sigma: channel"):
        beamid.fit(BASE, exps, data, free=("rho2",), estimate_sigma=[("free", "y_elbow")])
    with pytest.raises(beamid.InputError, match="burn_in"):
        beamid.fit(BASE, exps, data, free=("rho2",), burn_in=-1.0)
    static = {"F3": beamid.TipForce(fy=3.0)}
    sdata = beamid.simulate_measurements(BASE, static, ["y_tip"], sigma=1e-3)
    with pytest.raises(beamid.InputError, match="burn_in: experiment 'F3' is static"):
        beamid.fit(BASE, static, sdata, free=("EI1",), burn_in={"F3": 0.1})
    with pytest.raises(beamid.InputError, match="burn-in leaves no row"):
        beamid.fit(BASE, exps, data, free=("rho2",), burn_in=10.0)


def test_noise_larger_than_stated():
    """The right model, noise 1.5 times the stated sigma: the verdict is the
    measurement chain's noise, and its refit estimates the sigmas."""
    times = np.round(np.arange(1, 66) * 0.02, 6)
    exact = beamid.simulate_measurements(BASE, {"free": _release(2, rtol=1e-11)},
                                         ["u_tip", "w_tip"], sigma=1e-3, t=times)
    rng = np.random.default_rng(12)
    data = exact.with_values(exact.value + 1.5e-3 * rng.standard_normal(len(exact)))
    fit = beamid.fit(BASE, {"free": _release(2)}, data, free=("rho2",))
    d = beamid.diagnose(fit, RIG_CANDIDATES)
    assert d.verdict is not None and d.verdict.effect == "noise"
    f = d.verdict.estimate["sigma factor"]
    assert abs(f - 1.5) < 3 * d.verdict.sigma["sigma factor"]
    assert "the stated sigmas are too small by a factor" in d.message
    refit = beamid.add_effect(fit, "noise")
    for s, sd in refit.sigma_estimates.values():
        assert abs(s - 1.5e-3) < 3 * sd
    assert beamid.diagnose(refit, RIG_CANDIDATES).verdict is None


@pytest.mark.parametrize("lag", [0.0, 0.01])
def test_time_offset_column_of_every_quantity(lag):
    """The t0 column (the quantity's rate from the state) against central
    differences for every quantity a release with a motor measures: the
    tip angle by the chain rule, the motor torque from the acceleration (no
    lag) or the lag's state rate."""
    model = BASE.replace(tau_motor=lag, mu_elbow=0.0, mu_tip=0.0)
    exps = {"m": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=2, motor_gain=0.2,
                                rtol=1e-12)}
    qs = ["u_tip", "w_tip", "tip_angle", "x_elbow", "y_elbow", "motor_torque"]
    data = beamid.simulate_measurements(model, exps, qs, sigma=1e-3, t=[0.05, 0.2, 0.45])
    spec = ChainSpec(t0={"m": 0.01})
    prob = build_problem(model, exps, data, chain=spec)
    p0 = np.append(model.vector(), 0.01)
    _, jac = _ce.problem_predict(prob, p0, np.array([p0.size], np.int32))
    h = 2e-7   # the torque rate carries the fast modes: a short step
    none = np.zeros(0, np.int32)
    fd = (_ce.problem_predict(prob, p0 + np.eye(p0.size)[-1] * h, none)[0]
          - _ce.problem_predict(prob, p0 - np.eye(p0.size)[-1] * h, none)[0]) / (2 * h)
    for q in qs:
        rows = np.array([x == q for x in data.quantity])
        scale = np.max(np.abs(fd[rows]))
        assert scale > 0.0, q
        # the torque's rate carries the fast modes the motor excites: central
        # differences of whole runs resolve it to a few 1e-4 only
        tol = 2e-3 if q == "motor_torque" else 1e-4
        assert np.max(np.abs(jac[rows, 0] - fd[rows])) < tol * scale, q


#: station and encoder observations of a release whose t0 column the core
#: computes (the accelerations have none: test below)
STATION_QS = ("x@2:0.714", "y@2:0.5", "psi@2:0.2", "curvature@1:0.4", "moment@1:0.4",
              "strain@1:0.05", "vel_t@2:0.5", "vel_n@2:0.5", "elbow_rotation",
              "root_rotation")


def test_time_offset_column_of_station_observations():
    """The t0 column of station and encoder observations (the directional
    derivative along the state's rate: positions, angles, curvature, moment
    and strain along the velocities, station velocities along the
    accelerations) against central differences in t0; the fixed points'
    alongside."""
    model = BASE.replace(mu_elbow=0.0, mu_tip=0.0, C1=2.0, elbow_flex=0.02, root_flex=0.02)
    exps = {"m": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=4, rtol=1e-12)}
    qs = ("w_tip",) + STATION_QS
    data = beamid.simulate_measurements(model, exps, list(qs), sigma=1e-3,
                                        t=[0.05, 0.2, 0.45])
    spec = ChainSpec(t0={"m": 0.01})
    prob = build_problem(model, exps, data, chain=spec)
    p0 = np.append(model.vector(), 0.01)
    _, jac = _ce.problem_predict(prob, p0, np.array([p0.size], np.int32))
    h = 1e-6
    none = np.zeros(0, np.int32)
    fd = (_ce.problem_predict(prob, p0 + np.eye(p0.size)[-1] * h, none)[0]
          - _ce.problem_predict(prob, p0 - np.eye(p0.size)[-1] * h, none)[0]) / (2 * h)
    for q in qs:
        rows = np.array([x == q for x in data.quantity])
        scale = np.max(np.abs(fd[rows]))
        assert scale > 0.0, q
        # the tangential velocity carries the fast axial modes: central
        # differences of whole runs resolve its rate to about 1 % at 0.45 s
        # (at 0.05 s to 3e-7 with h = 1e-7)
        tol = 2e-2 if q.startswith("vel_t") else 2e-3 if q.startswith("strain") else 2e-4
        assert np.max(np.abs(jac[rows, 0] - fd[rows])) < tol * scale, (q, jac[rows, 0],
                                                                          fd[rows])


def test_time_offset_refused_on_acceleration_rows():
    """An accelerometer's rate (the jerk) is not computed: a clock offset on
    its record is an InputError naming it, in Python and in the core, and
    diagnose leaves that record's clock offset out of its candidates."""
    exps = {"m": _release()}
    data = beamid.simulate_measurements(BASE, exps, ["w_tip", "accel_n@2:0.5"], sigma=1e-2,
                                        t=[0.1, 0.2, 0.3])
    with pytest.raises(beamid.InputError, match=r"experiment 'm' has rows of accel_n@2:0.5, "
                       r"whose rate \(the jerk\)"):
        beamid.fit(BASE, exps, data, free=("EI1",), nuisance={"time_offset": ["m"]})
    prob = build_problem(BASE, exps, data)
    specs = [dict(spec) for spec in prob.exp_specs]
    specs[0]["t0"] = 1.0     # key t0 past the Python check
    bad = dataclasses.replace(prob, exp_specs=tuple(specs))
    with pytest.raises(beamid.InputError, match="observes accel_n@2:0.5, whose rate"):
        _ce.problem_predict(bad, np.append(BASE.vector(), 0.0), np.zeros(0, np.int32))
    own, cand = beamid.chain.candidate_spec(beamid.fit(BASE, exps, data, free=("EI1",)),
                                            {"time_offset", "bias"})
    assert cand.t0 == {} and ("m", "accel_n@2:0.5") in cand.bias


def test_bias_and_scale_of_a_station_channel():
    """Channels are keyed by the observation's name (a strain gauge and a
    marker): a bias on the gauge and a scale on the marker are recovered,
    the names written as given (0.050 is 0.05) and in the core's order."""
    model = BASE.replace(C1=2.0)
    exps = {"m": _release(4)}
    qs = ["w_tip", "strain@1:0.05", "y@2:0.5"]
    times = np.round(np.arange(1, 201) / 200.0, 6)
    clean = beamid.simulate_measurements(model, exps, qs, sigma=1e-3, t=times)
    rng = np.random.default_rng(7)
    sig = {"w_tip": 1e-3, "strain@1:0.05": 2e-6, "y@2:0.5": 1e-3}
    rows = []
    for e, t, q, v in zip(clean.experiment, clean.t, clean.quantity, clean.value):
        v = v + 5e-5 if q == "strain@1:0.05" else (1.04 * v if q == "y@2:0.5" else v)
        rows.append((e, float(t), q, v + sig[q] * rng.standard_normal(), sig[q]))
    data = beamid.Measurements.from_rows(rows)
    spec = parse_nuisance({"bias": [("m", "strain@1:0.050")], "scale": ["y@2:0.5"]}, exps,
                          data)
    assert spec.names(["m"]) == ("bias[m:strain@1:0.05]", "scale[m:y@2:0.5]")
    prob = build_problem(model, exps, data, chain=spec)
    assert prob.observation_names() == ("w_tip", "y@2:0.5", "strain@1:0.05")
    assert [(k, e, q) for k, e, q in layout(prob, ["m"])] == spec.order(["m"])
    fit = beamid.fit(model, exps, data, free=("EI1",), nuisance=spec)
    b, s = fit.nuisance["bias[m:strain@1:0.05]"], fit.nuisance["scale[m:y@2:0.5]"]
    assert abs(b - 5e-5) < 3 * fit.nuisance_sigmas["bias[m:strain@1:0.05]"]
    assert abs(s - 1.04) < 3 * fit.nuisance_sigmas["scale[m:y@2:0.5]"]
    assert fit.chi2_per_dof < 1.3


# --------------------------------------------------------- rows without sigma

def _without_sigma(data, quantity):
    """``data`` with the sigma of every row of ``quantity`` not given."""
    return beamid.Measurements.from_rows(
        [(e, t, q, v, None if q == quantity else s) for e, t, q, v, s in data.rows()])


def test_sigma_missing_without_estimation_is_refused(small, tmp_path):
    """Rows with no sigma (None, or an empty CSV field) and no estimation
    asked: InputError naming the channel; the deck reader names the line."""
    exps, data = small
    bare = _without_sigma(data, "w_tip")
    assert np.isnan(bare.sigma).sum() == 5 and not np.isnan(bare.sigma[:1]).any()
    with pytest.raises(beamid.InputError, match=r"sigma missing: 5 rows have no sigma .*"
                       r"\('free', 'w_tip'\).*estimate_sigma"):
        beamid.fit(BASE, exps, bare, free=("rho2",))
    with pytest.raises(beamid.InputError, match="sigma missing"):      # another channel's
        beamid.fit(BASE, exps, bare, free=("rho2",), estimate_sigma=[("free", "u_tip")])
    with pytest.raises(beamid.InputError, match="improve: sigma missing"):
        beamid.improve(BASE, exps, bare, free=("rho2",), candidates=["drag"])
    path = tmp_path / "d.csv"
    bare.write(path)
    assert ",w_tip," in path.read_text() and path.read_text().count(",\n") == 5
    again = beamid.read_measurements(path)
    assert np.array_equal(np.isnan(again.sigma), np.isnan(bare.sigma))
    with pytest.raises(beamid.InputError, match="expected sigma > 0"):
        beamid.Measurements.from_rows([("free", 0.1, "w_tip", 0.1, 0.0)])


def test_sigma_missing_is_estimated_when_asked():
    """A channel with no sigma given and estimate_sigma: the fit starts
    its sigma from the channel's spread and estimates it (1 mm noise)."""
    times = np.round(np.arange(1, 41) * 0.03, 6)
    exps = {"free": _release()}
    exact = beamid.simulate_measurements(BASE, exps, ["u_tip", "w_tip"], sigma=1e-3, t=times)
    rng = np.random.default_rng(3)
    noisy = exact.with_values(exact.value + 1e-3 * rng.standard_normal(len(exact)))
    bare = _without_sigma(noisy, "w_tip")
    fit = beamid.fit(BASE, exps, bare, free=("rho2",), estimate_sigma=["w_tip"])
    s, sd = fit.sigma_estimates["free:w_tip"]
    assert abs(s - 1e-3) < 3 * sd and 0.05e-3 < sd < 0.2e-3
    ref = beamid.fit(BASE, exps, noisy, free=("rho2",), estimate_sigma=["w_tip"])
    # the same minimum from different weights on the way: within the fit's
    # noise floor (every parameter within 0.1 sigma of the linearized
    # minimum; issue 30's stopping rules end there, 6e-5 relative apart)
    assert abs(fit.estimates["rho2"] - ref.estimates["rho2"]) < 0.1 * ref.sigmas["rho2"]
    assert s == pytest.approx(ref.sigma_estimates["free:w_tip"][0], rel=1e-3)


def _deck16(tmp_path, fit_keys="", blank_w=False):
    """Table 16's fit deck (release from 8 N, 36 rows of tip w and u) in
    ``tmp_path`` with ``fit_keys`` added to its &fit group; ``blank_w``:
    the w rows without sigma."""
    seed = Path(__file__).resolve().parent.parent / "inputs" / "seed"
    lines = (seed / "table16_data.csv").read_text().splitlines()
    if blank_w:
        lines = [ln.rsplit(",", 1)[0] + "," if ",w_tip," in ln else ln for ln in lines]
    (tmp_path / "table16_data.csv").write_text("\n".join(lines) + "\n")
    text = (seed / "table16_fit.nml").read_text().replace(
        "output = 'out/table16_fit'", "output = 'out/t16'")
    text = text.replace("  free = 'mu_elbow', 'mu_tip', 'rho1', 'rho2'\n",
                        "  free = 'mu_elbow', 'mu_tip', 'rho1', 'rho2'\n" + fit_keys)
    deck = tmp_path / "t16.nml"
    deck.write_text(text)
    return deck


def test_deck_sigma_missing_names_the_line(tmp_path):
    deck = _deck16(tmp_path, blank_w=True)
    with pytest.raises(beamid.InputError, match=r"&fit data: sigma missing: .*table16_data"
                       r"\.csv, line 4 has no sigma .*no estimation is asked"):
        beamid.read_deck(deck)


CHAIN_KEYS = ("  time_offset = 'free'\n  bias = 'free:w_tip'\n  loss = 'huber'\n"
              "  estimate_sigma = 'u_tip'\n  burn_in = 0.1\n")


def test_deck_chain_keys_fit_as_the_api(tmp_path):
    """&fit's time_offset, bias, loss, estimate_sigma and burn_in: the deck
    (the Fortran of beamid-batch) fits what beamid.fit fits with the same
    arguments; its files name the nuisance parameters and give each row's
    sigma as judged, weight and gross-error flag."""
    deck = beamid.read_deck(_deck16(tmp_path, CHAIN_KEYS))
    assert deck.nuisance.names(["free"]) == ("t0[free]", "bias[free:w_tip]")
    assert deck.treatment == beamid.chain.RowTreatment("huber", {"free": 0.1},
                                                       (("free", "u_tip"),))
    fit = beamid.run(deck)
    api = beamid.fit(deck.model, deck.experiments, deck.data, free=deck.free,
                     nuisance={"time_offset": ["free"], "bias": [("free", "w_tip")]},
                     loss="huber", burn_in=0.1, estimate_sigma=["u_tip"])
    for n, v in api.estimates.items():
        assert fit.estimates[n] == pytest.approx(v, rel=1e-9, abs=1e-12)
    for n, v in api.nuisance.items():
        assert fit.nuisance[n] == pytest.approx(v, rel=1e-9, abs=1e-12)
        assert fit.nuisance_sigmas[n] == pytest.approx(api.nuisance_sigmas[n], rel=1e-6)
    assert fit.sigma_estimates["free:u_tip"] == pytest.approx(
        api.sigma_estimates["free:u_tip"], rel=1e-6)
    assert fit.dof == api.dof == 36 - 6 - 2 - 1     # 2 burn-in rows, 1 estimated sigma
    est = (tmp_path / "out" / "t16_estimates.csv").read_text().splitlines()
    assert [ln.split(",")[0] for ln in est[1:7]] == ["mu_elbow", "mu_tip", "rho1", "rho2",
                                                     "t0[free]", "bias[free:w_tip]"]
    res = (tmp_path / "out" / "t16_residuals.csv").read_text().splitlines()
    assert res[0].endswith(",sigma,normalized,weight,gross_error")
    first_u = res[2].split(",")
    assert first_u[2] == "u_tip" and float(first_u[7]) == 0.0       # burn-in: weight 0
    assert float(first_u[5]) == pytest.approx(api.sigma_estimates["free:u_tip"][0], rel=1e-6)


@pytest.mark.parametrize("keys, message", [
    ("  loss = 'tukey'\n", "loss = 'tukey', expected one of linear, huber, cauchy"),
    ("  time_offset = 'held'\n", "time_offset = 'held': no experiment of that name"),
    ("  bias = 'free:x_elbow'\n", "bias = 'free:x_elbow': no data row of x_elbow in "
                                  "experiment 'free'"),
    ("  scale = 'free:nonsense'\n", "scale = 'free:nonsense': expected a channel"),
    ("  burn_in = -1\n", "burn_in = '-1.00000000000000000E+00', expected a time >= 0"),
])
def test_deck_chain_keys_refused(tmp_path, keys, message):
    with pytest.raises(beamid.InputError, match=re.escape(message)):
        beamid.read_deck(_deck16(tmp_path, keys))


def test_deck_sigma_missing_estimated(tmp_path):
    """A deck whose w rows have no sigma fits with estimate_sigma naming
    them; the estimate is near the 1.5 mm the data were drawn with."""
    deck = beamid.read_deck(_deck16(tmp_path, "  estimate_sigma = 'w_tip'\n", blank_w=True))
    fit = beamid.run(deck)
    s, sd = fit.sigma_estimates["free:w_tip"]
    assert abs(s - 1.5e-3) < 3 * sd


def test_cli_chain_options_are_the_deck_keys(tmp_path, capsys):
    """beamid fit DECK with the measurement chain's options writes the bytes
    the deck with the same &fit items writes (one reader: the options are
    &fit items), and a bad option is refused by that reader."""
    from beamid.cli import main
    keyed = tmp_path / "keyed"
    keyed.mkdir()
    _deck16(keyed, CHAIN_KEYS)
    assert main(["fit", str(keyed / "t16.nml"), "--no-plots"]) == 0
    plain = _deck16(tmp_path)
    assert main(["fit", str(plain), "--no-plots", "--time-offset", "free", "--bias",
                 "free:w_tip", "--loss", "huber", "--estimate-sigma", "u_tip",
                 "--burn-in", "0.1"]) == 0
    for suffix in ("_estimates.csv", "_covariance.csv", "_residuals.csv"):
        assert (tmp_path / "out" / f"t16{suffix}").read_bytes() == \
            (keyed / "out" / f"t16{suffix}").read_bytes()
    assert main(["fit", str(plain), "--no-plots", "--time-offset", "held"]) == 2
    assert "&fit time_offset = 'held': no experiment of that name (experiments: free)" in \
        capsys.readouterr().err


def test_improve_ladder_adds_gross_errors_then_stops(gross):
    """The Fortran ladder's row candidates (named): three lost markers make
    the first rung `gross_errors` (a Huber loss; the rows flagged), after
    which the noise is as stated and the ladder ends."""
    _, dirty = gross
    exps = {"free": _release(2)}
    ladder = beamid.improve(BASE.replace(rho2=0.5), exps, dirty, free=("rho2",),
                            candidates=["gross_errors", "noise"])
    assert [s.effect for s in ladder.steps] == [None, "gross_errors"]
    fit = ladder.fit
    assert fit.loss == "huber" and fit.gross_errors == (10, 51, 90)
    assert abs(fit.estimates["rho2"] - 0.530) < 3 * fit.sigmas["rho2"]
    assert fit.chi2_per_dof < 1.3 < ladder.steps[0].chi2_per_dof


def test_improve_ladder_adds_noise(gross):
    """Noise about twice the stated sigma and nothing else: the ladder's rung
    `noise` estimates each channel's sigma as beamid.fit(estimate_sigma=True)
    does, near the spread of the noise drawn (stated 1 mm)."""
    clean, _ = gross
    rng = np.random.default_rng(11)
    noisy = clean.with_values(clean.value + 1.7e-3 * rng.standard_normal(len(clean)))
    start = BASE.replace(rho2=0.5)
    ladder = beamid.improve(start, {"free": _release(2)}, noisy,
                            free=("rho2",), candidates=["gross_errors", "noise"])
    assert [s.effect for s in ladder.steps] == [None, "noise"]
    api = beamid.fit(start, {"free": _release(2)}, noisy, free=("rho2",),
                     estimate_sigma=True)
    exact = beamid.simulate_measurements(BASE, {"free": _release(2, rtol=1e-11)},
                                         ["u_tip", "w_tip"], sigma=1e-3, t=clean.t[::2])
    for q in ("u_tip", "w_tip"):
        s, sd = ladder.fit.sigma_estimates[f"free:{q}"]
        assert (s, sd) == pytest.approx(api.sigma_estimates[f"free:{q}"], rel=1e-9)
        rows = np.array([x == q for x in noisy.quantity])
        drawn = np.std(noisy.value[rows] - exact.value[rows])
        assert 1.4e-3 < drawn and abs(s - drawn) < 2 * sd
    assert abs(ladder.fit.chi2_per_dof - 1.0) < 0.1
