"""The measurement chain's initial velocity (issue 29): a release that was not
at rest at t = 0, its tip normal velocity v0 fitted with the physics."""
from __future__ import annotations

import numpy as np
import pytest

import beamid
from beamid import _core_estimation as _ce
from beamid.chain import ChainSpec, layout, parse_nuisance
from beamid.estimation import build_problem

from test_chain import _deck16

BASE = beamid.pace().replace(J_elbow=0.0, J_tip=0.0)
NONE = np.zeros(0, np.int32)
V0 = 0.2           # m/s, the tip's normal velocity at the release


def _release(nepb=2, **kw):
    return beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=nepb, **kw)


def _v0_record(v0=V0, sigma=1e-3, seed=7):
    """Tip u and w every 20 ms to 1.3 s of a release thrown with tip normal
    velocity v0; truth at rtol 1e-11 (tighter than the fit's), noise sigma."""
    times = np.round(np.arange(1, 66) * 0.02, 6)
    fine = {"free": _release(2, rtol=1e-11)}
    data0 = beamid.simulate_measurements(BASE, fine, ["u_tip", "w_tip"], sigma=sigma, t=times)
    prob = build_problem(BASE, fine, data0, chain=ChainSpec(v0={"free": 0.0}))
    truth, _ = _ce.problem_predict(prob, np.append(BASE.vector(), v0), NONE)
    rng = np.random.default_rng(seed)
    return data0.with_values(truth + sigma * rng.standard_normal(len(data0)))


@pytest.fixture(scope="module")
def record():
    return _v0_record()


def test_v0_columns_match_central_differences():
    """The v0 column (sensitivities started at ds/dv0(0) = (0, q / w_tip(q))),
    the physics column and the t0 column of a moving start, against central
    differences; the layout puts v0 after the record's t0."""
    exps = {"free": _release()}
    data = beamid.simulate_measurements(BASE, exps, ["u_tip", "w_tip"], sigma=1e-3,
                                        t=[0.1, 0.2, 0.3, 0.4, 0.5])
    spec = parse_nuisance({"initial_velocity": {"free": 0.3}, "time_offset": ["free"]},
                          exps, data)
    prob = build_problem(BASE, exps, data, chain=spec)
    assert layout(prob, ["free"]) == spec.order(["free"]) == [
        ("time_offset", "free", ""), ("initial_velocity", "free", "")]
    assert spec.names(["free"]) == ("t0[free]", "v0[free]")
    p0 = np.concatenate([BASE.vector(), spec.starts(["free"])])
    npar = BASE.vector().size
    wrt = np.array([BASE.index("rho2") + 1, npar + 1, npar + 2], np.int32)
    pred, jac = _ce.problem_predict(prob, p0, wrt)
    for c, (k, h) in enumerate(zip(wrt, [1e-5, 1e-6, 1e-5])):
        pp, pm = p0.copy(), p0.copy()
        pp[k - 1] += h
        pm[k - 1] -= h
        fd = (_ce.problem_predict(prob, pp, NONE)[0] - _ce.problem_predict(prob, pm, NONE)[0]) \
            / (2 * h)
        scale = np.max(np.abs(fd))
        assert scale > 1e-2
        assert np.max(np.abs(jac[:, c] - fd)) < 2e-4 * scale, (c, jac[:, c], fd)
    # v0 = 0 is the release at rest: the plain problem's predictions
    at_rest, _ = _ce.problem_predict(prob, np.append(BASE.vector(), [0.0, 0.0]), NONE)
    plain, _ = _ce.problem_predict(build_problem(BASE, exps, data), BASE.vector(), NONE)
    assert np.max(np.abs(at_rest - plain)) < 1e-12
    assert np.max(np.abs(pred - plain)) > 1e-2


def test_v0_recovered_with_the_physics(record):
    exps = {"free": _release(2)}
    start = BASE.replace(rho2=0.5)
    plain = beamid.fit(start, exps, record, free=("rho2",))
    fit = beamid.fit(start, exps, record, free=("rho2",),
                     nuisance={"initial_velocity": ["free"]})
    assert plain.chi2_per_dof > 20.0                     # the throw wrecks the plain fit
    assert abs(plain.estimates["rho2"] - 0.530) > 0.1
    assert fit.chi2_per_dof < 1.3
    v, sv = fit.nuisance["v0[free]"], fit.nuisance_sigmas["v0[free]"]
    assert abs(v - V0) < 3 * sv and sv < 5e-3
    assert abs(fit.estimates["rho2"] - 0.530) < 2 * fit.sigmas["rho2"]
    # the physics covariance is the block of the full inverse (rho2, v0)
    assert fit.full_cov.shape == (2, 2)
    assert fit.cov[0, 0] == pytest.approx(fit.full_cov[0, 0])
    assert "v0[free]" in fit.summary()


def test_diagnose_names_the_initial_velocity(record):
    exps = {"free": _release(2)}
    plain = beamid.fit(BASE.replace(rho2=0.5), exps, record, free=("rho2",))
    d = beamid.diagnose(plain, candidates=("drag", "kelvin_voigt", "clock_offset",
                                           "initial_velocity", "noise"))
    assert d.verdict is not None and d.verdict.effect == "initial_velocity"
    assert d.verdict.cause == "measurement chain"
    assert d.message.startswith("measurement chain, not physics: initial_velocity")
    assert abs(d.verdict.estimate["v0[free]"] - V0) < 3 * d.verdict.sigma["v0[free]"]
    refit = beamid.add_effect(plain, "initial_velocity")
    assert abs(refit.estimates["rho2"] - 0.530) < 2 * refit.sigmas["rho2"]
    with pytest.raises(beamid.InputError, match="no parameter left to add"):
        beamid.add_effect(refit, "initial_velocity")
    # a candidate by name, not among the release's defaults
    assert "initial_velocity" not in beamid.DYNAMIC_CANDIDATES
    assert beamid.diagnosis.EFFECTS["initial_velocity"].cause == "measurement chain"


def test_bad_initial_velocity_input(record):
    exps = {"free": _release(2)}
    with pytest.raises(beamid.InputError, match="initial_velocity'\\]: no experiment 'nope'"):
        beamid.fit(BASE, exps, record, free=("rho2",), nuisance={"initial_velocity": ["nope"]})
    static = {"F3": beamid.TipForce(fy=3.0)}
    sdata = beamid.simulate_measurements(BASE, static, ["y_tip"], sigma=1e-3)
    with pytest.raises(beamid.InputError, match="static; an initial velocity needs a release"):
        beamid.fit(BASE, static, sdata, free=("EI1",), nuisance={"initial_velocity": ["F3"]})
    # the core checks what it is given (decks reach it without Python)
    prob = build_problem(BASE, static, sdata, chain=ChainSpec(v0={"F3": 0.0}))
    with pytest.raises(beamid.InputError, match="initial velocity v0 asked for an experiment "
                                                "that is not a release"):
        _ce.problem_predict(prob, np.append(BASE.vector(), 0.0), NONE)
    # a release without a tip deflection has no shape to move
    flat = {"free": beamid.Release(beamid.TipForce(fx=0.0), elements_per_beam=2)}
    prob = build_problem(BASE, flat, record, chain=ChainSpec(v0={"free": 0.0}))
    with pytest.raises(beamid.InputError, match="the static shape has no tip deflection"):
        _ce.problem_predict(prob, np.append(BASE.vector(), 0.1), NONE)


def test_deck_initial_velocity_key(tmp_path):
    """&fit initial_velocity = 'free': the deck (the Fortran reader) fits what
    beamid.fit fits with nuisance={'initial_velocity': ['free']}."""
    deck = beamid.read_deck(_deck16(tmp_path, "  initial_velocity = 'free'\n"))
    assert deck.nuisance.names(["free"]) == ("v0[free]",)
    fit = beamid.run(deck)
    api = beamid.fit(deck.model, deck.experiments, deck.data, free=deck.free,
                     nuisance={"initial_velocity": ["free"]})
    for n, v in api.estimates.items():
        assert fit.estimates[n] == pytest.approx(v, rel=1e-9, abs=1e-12)
    assert fit.nuisance["v0[free]"] == pytest.approx(api.nuisance["v0[free]"], rel=1e-9,
                                                     abs=1e-12)
    # Table 16's release is at rest: v0 within a few sigmas of 0
    assert abs(fit.nuisance["v0[free]"]) < 3 * fit.nuisance_sigmas["v0[free]"]
    est = (tmp_path / "out" / "t16_estimates.csv").read_text().splitlines()
    assert est[5].split(",")[0] == "v0[free]"
    with pytest.raises(beamid.InputError, match="initial_velocity = 'held': no experiment "
                                                "of that name"):
        beamid.read_deck(_deck16(tmp_path, "  initial_velocity = 'held'\n"))


def test_simulate_through_the_chain(record):
    """simulate_measurements(nuisance=...) reads the data through the chain:
    the same rows as the problem's prediction at (model, v0), noise from the
    same seed."""
    times = np.round(np.arange(1, 66) * 0.02, 6)
    fine = {"free": _release(2, rtol=1e-11)}
    sim = beamid.simulate_measurements(BASE, fine, ["u_tip", "w_tip"], sigma=1e-3, t=times,
                                       noise=True, seed=7,
                                       nuisance={"initial_velocity": {"free": V0}})
    assert np.max(np.abs(sim.value - record.value)) < 1e-14
    at_rest = beamid.simulate_measurements(BASE, fine, ["u_tip", "w_tip"], sigma=1e-3,
                                           t=times)
    assert np.max(np.abs(sim.value - at_rest.value)) > 0.05
