"""Dynamic fits that must reach the best fit (issue 30): the mesh checked by
``fit`` itself, and several starts on the consistency runners.

Data: Table 16's (inputs/seed/table16_data.csv: the 4-element-per-beam model
at rtol 1e-11, noise of the stated sigmas from a fixed seed) and a release
measured on a 16-element-per-beam "rig" (rtol 1e-10, sigma 1e-4 m, seed 3).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import beamid
from beamid import robust
from beamid.fit_decks import read_fit_deck
from beamid.tables import inputs_dir

FREE = ("mu_elbow", "mu_tip", "rho1", "rho2")
TRUTH = beamid.pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)


@pytest.fixture(scope="module")
def table16():
    deck = read_fit_deck(inputs_dir("seed") / "table16_fit.nml")
    exps = dict(deck.experiments)
    ref = beamid.fit(deck.model, exps, deck.data, free=FREE)
    return deck, exps, ref


@pytest.fixture(scope="module")
def twenty(table16):
    """20 random starts around Table 16's answer (each parameter times
    U(0.6, 1.4), seed 30) on two local processes."""
    deck, exps, ref = table16
    return beamid.fit(ref.model, exps, deck.data, free=FREE, starts=20, start_spread=0.4,
                      start_seed=30, workers=2)


def test_table16_needs_no_check(table16):
    _, _, ref = table16
    # chi2 33.38 for 32 dof: no mesh check, no more starts
    assert ref.mesh_check is None and ref.starts == () and ref.start_won == "given start"
    assert abs(ref.chi2 - 33.38) < 0.02 and ref.converged


def test_twenty_starts_reach_the_best_or_say_they_did_not(twenty):
    ends = twenty.starts
    assert [e.index for e in ends] == list(range(21))
    best = min(e.chi2 for e in ends)
    assert abs(twenty.chi2 - best) < 1e-12 and abs(best - 33.38) < 0.02
    assert twenty.converged and twenty.stop == "converged"
    # every start either reached the best chi-square (within same_chi2) or
    # is labelled a local minimum with how much higher it ended
    states = [e.state for e in ends]
    assert states.count(robust.LOCAL) == 2 and states.count(robust.FAILED) == 0
    for e in ends:
        if e.state == robust.LOCAL:
            assert 1.5 < e.above_best < 1.7 and e.stop == "converged"
        else:
            # the same minimum to the noise floor's precision (each fit ends
            # when the next step promises less than 0.01: ends 0.011 apart)
            assert e.state in (robust.BEST, robust.SAME) and e.above_best < 0.02
    # the random starts are within 0.6-1.4 times the given start
    for e in ends[1:]:
        for n in FREE:
            assert 0.6 <= e.start[n] / twenty.nominal[n] <= 1.4
    assert "2 ended in local minima, 1.61 to 1.63 higher" in twenty.note


def test_starts_are_the_same_on_any_runner(table16, twenty):
    deck, exps, ref = table16
    serial = beamid.fit(ref.model, exps, deck.data, free=FREE, starts=3, workers=1)
    for a, b in zip(serial.starts[1:], twenty.starts[1:4]):
        assert a.start == b.start
        assert abs(a.chi2 - b.chi2) < 1e-9


def test_a_local_minimum_is_left_for_the_best_start(table16, twenty):
    deck, exps, ref = table16
    local = next(e for e in twenty.starts if e.state == robust.LOCAL)
    start = ref.model.replace(**local.start)
    alone = beamid.fit(start, exps, deck.data, free=FREE, starts=0)
    # one start alone says "converged" at the local minimum
    assert alone.stop == "converged" and abs(alone.chi2 - local.chi2) < 1e-9
    more = beamid.fit(start, exps, deck.data, free=FREE, starts=4)
    assert more.start_won.startswith("random start ") and abs(more.chi2 - 33.38) < 0.02
    given = more.starts[0]
    assert given.state == robust.LOCAL and 1.5 < given.above_best < 1.7
    assert any("it was a local minimum" in w for w in more.warnings)
    # the result is the winner's own fit: its start and path
    won = more.starts[int(more.start_won.split()[-1])]
    assert more.log[0].params == won.start and more.start[FREE[0]] == won.start[FREE[0]]
    assert won.estimates == more.estimates
    assert more.nominal == start


def test_start_arguments_are_checked(table16):
    deck, exps, ref = table16
    for kw, text in (({"starts": -1}, "starts = -1"), ({"starts": True}, "starts = True"),
                     ({"start_spread": 1.5}, "start_spread = 1.5"),
                     ({"start_seed": -2}, "start_seed = -2"),
                     ({"starts": 2**31}, "expected an integer from 0 to 1000"),
                     ({"workers": 0}, "workers = 0"), ({"client": "no host"}, "client = "),
                     ({"mesh": None}, "mesh = None"), ({"grow": "yes"}, "grow = 'yes'")):
        with pytest.raises(beamid.InputError, match=text):
            beamid.fit(ref.model, exps, deck.data, free=FREE, **kw)


@pytest.fixture(scope="module")
def rig16():
    times = np.linspace(0.05, 1.3, 26)
    rig = {"free": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=16, rtol=1e-10)}
    return beamid.simulate_measurements(TRUTH, rig, ["w_tip", "u_tip"], sigma=1e-4, t=times,
                                        seed=3, noise=True)


def test_fit_names_the_mesh_on_data_from_a_finer_mesh(rig16):
    start = TRUTH.replace(mu_elbow=0.015, mu_tip=0.01, rho1=0.5603, rho2=0.5437)
    coarse = {"free": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=4)}
    fit = beamid.fit(start, coarse, rig16, free=FREE)
    assert fit.chi2 / fit.dof > 20            # 1520 for 48 dof
    check = fit.mesh_check
    assert check.likely_cause and check.elements_per_beam == 4 and check.recommended == 16
    assert 25 < check.max_change < 40 and check.at[2] == "w_tip"
    assert check.drop > 1000 and check.refit_chi2 < 100       # 68 at 8 elements per beam
    assert fit.starts == ()                    # more starts cannot help a coarse mesh
    assert any("refit with elements_per_beam=16" in w for w in fit.warnings)
    # at the recommended mesh the data from the finer mesh are recovered
    fine = {"free": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=16)}
    refit = beamid.fit(fit.model, fine, rig16, free=FREE)
    assert refit.converged and refit.mesh_check is None and refit.chi2 / refit.dof <= 1.5
    for n in FREE:
        assert abs(refit.estimates[n] - TRUTH[n]) < 3 * refit.sigmas[n], n


def test_mesh_check_clears_the_mesh_when_the_model_lacks_an_effect():
    # data from the fitted mesh with a tip inertia the model lacks: far above
    # its dof, the refined mesh moves the predictions but does not fit better
    base = beamid.pace().replace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.0, mu_tip=0.0)
    rel = beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=2)
    times = [round(0.1 * k, 3) for k in range(1, 14)]
    data = beamid.simulate_measurements(base.replace(J_tip=0.01), {"free": rel},
                                        ["u_tip", "w_tip"], sigma=1e-4, t=times, seed=14,
                                        noise=True)
    fit = beamid.fit(base, {"free": rel}, data, free=("rho2",), starts=0)
    assert fit.chi2 > 1000
    check = fit.mesh_check
    assert not check.likely_cause and check.drop < 0 and check.max_change > 1.0
    assert "not the likely cause" in check.message
    assert not any("elements_per_beam=" in w for w in fit.warnings)


@pytest.fixture(scope="module")
def strong_drag():
    """A release from a model with a strong tip drag (c_tip = 0.2 N s/m,
    twenty times the demo rig's), made on a finer mesh than the fit's (16
    elements per beam against 8) at rtol 1e-11, sigma 1e-4 m, seed 8."""
    base = beamid.pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)
    rig = {"free": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=16, rtol=1e-11)}
    data = beamid.simulate_measurements(base.replace(c_tip=0.2), rig, ["w_tip", "u_tip"],
                                        sigma=1e-4, t=np.linspace(0.05, 1.3, 26), seed=8,
                                        noise=True)
    rel = {"free": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=8)}
    return base, rel, data


def test_strong_tip_drag_is_recovered_from_a_tenth_of_it(strong_drag):
    base, rel, data = strong_drag
    fit = beamid.fit(base.replace(c_tip=0.02, rho2=0.545), rel, data, free=("rho2", "c_tip"))
    assert fit.converged and fit.chi2 / fit.dof <= 1.5        # 60.2 for 50 dof
    assert abs(fit.estimates["c_tip"] - 0.2) < 3 * fit.sigmas["c_tip"]
    assert abs(fit.estimates["rho2"] - base["rho2"]) < 3 * fit.sigmas["rho2"]
    assert fit.starts == () and fit.mesh_check is None


def test_improve_finds_a_strong_tip_drag_without_an_extra_rung(strong_drag):
    base, rel, data = strong_drag
    ladder = beamid.improve(base.replace(rho2=0.545), rel, data, free=("rho2",),
                            candidates=("drag", "rotary_inertia", "kelvin_voigt"))
    assert ladder.effects == ("drag",)
    fit = ladder.fit
    assert fit.chi2 / fit.dof <= 1.5
    assert abs(fit.estimates["c_tip"] - 0.2) < 3 * fit.sigmas["c_tip"]


# ------------------------------------------------------------------ friction homotopy

def test_release_friction_velocity_is_typed_and_checked():
    rel = beamid.Release(beamid.TipForce(fy=8.0), friction="smooth", friction_velocity=1e-3)
    assert rel.friction_velocity == 1e-3 and rel.encode()[1][10] == 1e-3
    assert beamid.Release.decode(rel.encode()[1]) == rel
    assert "vs = 0.001 m/s" in rel.describe()
    # the default: the library's 1e-4 m/s (0 in the value column)
    plain = beamid.Release(beamid.TipForce(fy=8.0), friction="smooth")
    assert plain.friction_velocity is None and plain.encode()[1][10] == 0.0
    for kw, text in (({"friction": "smooth", "friction_velocity": 0.0},
                      "friction_velocity = 0"),
                     ({"friction": "smooth", "friction_velocity": "fast"},
                      "friction_velocity = 'fast'"),
                     ({"friction": "smooth", "friction_velocity": float("nan")},
                      "friction_velocity = nan"),
                     ({"friction_velocity": 1e-3}, "expected friction='smooth'"),
                     ({"friction": "sign", "friction_velocity": 1e-3},
                      "expected friction='smooth'")):
        with pytest.raises(beamid.InputError, match=text):
            beamid.Release(beamid.TipForce(fy=8.0), **kw)
    # the velocity reaches the integrator: the smooth law's tip moves with it
    t = np.linspace(0.1, 1.3, 13)

    def w_tip(**kw):
        rel = {"r": beamid.Release(beamid.TipForce(fy=8.0), **kw)}
        return np.asarray(beamid.simulate_measurements(TRUTH, rel, ["w_tip"], t=t).value)

    w = {vs: w_tip(friction="smooth", friction_velocity=vs) for vs in (1e-2, 1e-4)}
    sign = w_tip()
    assert np.max(np.abs(w[1e-2] - sign)) > 5 * np.max(np.abs(w[1e-4] - sign))


def test_friction_homotopy_ends_on_the_sign_law_at_the_same_minimum(table16):
    deck, exps, ref = table16
    start = TRUTH.replace(mu_elbow=0.015, mu_tip=0.01, rho1=0.5603, rho2=0.5437)
    fit = beamid.fit(start, exps, deck.data, free=FREE, homotopy=True)
    assert fit.start_won == robust.HOMOTOPY and len(fit.path) == 3
    assert fit.path[0].startswith("smooth law, vs = 0.01 m/s")
    assert fit.path[1].startswith("smooth law, vs = 0.001 m/s")
    assert fit.path[2].startswith("sign law") and fit.converged
    # the sign law's minimum: Table 16's answer
    assert abs(fit.chi2 - ref.chi2) < robust.same_chi2(ref.chi2)
    for n in FREE:
        assert abs(fit.estimates[n] - ref.estimates[n]) < 0.1 * ref.sigmas[n], n
    # nothing to do without friction or on the smooth law
    assert not robust.homotopy_applies(TRUTH.replace(mu_elbow=0.0, mu_tip=0.0), exps, ("rho1",))
    smooth = robust.smooth_friction(exps, 1e-3)
    assert not robust.homotopy_applies(TRUTH, smooth, FREE)
    with pytest.raises(beamid.InputError, match="homotopy = 'yes'"):
        beamid.fit(start, exps, deck.data, free=FREE, homotopy="yes")


# ------------------------------------------------------------------ strong hidden effects

def test_strong_motor_ratio_is_recovered_from_the_nominal_one():
    """A motor ratio of 0.6 (the nominal model's 1.0): data on a finer mesh
    than the fit's (32 elements per beam against 16: at 8 the mesh's error
    moves rho2 by 3.5 sigma of this noise) at rtol 1e-11, sigma 1e-4 m,
    seed 21; fitted from r_motor = 1."""
    base = beamid.pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)
    rig = {"m": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=32, motor_gain=0.2,
                               rtol=1e-11)}
    data = beamid.simulate_measurements(base.replace(r_motor=0.6), rig, ["w_tip", "u_tip"],
                                        sigma=1e-4, t=np.linspace(0.05, 1.3, 26), seed=21,
                                        noise=True)
    rel = {"m": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=16, motor_gain=0.2)}
    fit = beamid.fit(base, rel, data, free=("rho2", "r_motor"))
    assert fit.converged and fit.chi2 / fit.dof <= 1.5
    assert abs(fit.estimates["r_motor"] - 0.6) < 3 * fit.sigmas["r_motor"]
    assert abs(fit.estimates["rho2"] - base["rho2"]) < 3 * fit.sigmas["rho2"]
    assert fit.starts == () and fit.mesh_check is None


def test_strong_root_compliance_is_found_by_improve_without_an_extra_rung():
    """The dissertation's friction and a root compliance of 80 N m/rad
    (root_flex = 0.0125 rad/(N m)), tip u and w at 26 times over 1.3 s made
    on a finer mesh than the fit's (16 elements per beam against 8, the
    issue's held-out case) at rtol 1e-11 with noise 6e-4 and 1e-3 m (seed
    30), fitted from the
    published friction starts: the root_flex rung's fit from the diagnosis'
    refit stops in a local minimum (friction absorbed the compliance at the
    start), the rung is refitted from the nominal model before the ladder
    goes on (issue 30: it added elbow_flex), and no further rung follows."""
    truth = beamid.pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02, root_flex=0.0125)
    rig = {"H": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=16, rtol=1e-11)}
    data = beamid.simulate_measurements(truth, rig, ["u_tip", "w_tip"],
                                        {"u_tip": 6e-4, "w_tip": 1e-3},
                                        t=np.linspace(0.05, 1.3, 26), seed=30, noise=True)
    rel = {"H": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=8)}
    ladder = beamid.improve(beamid.pace(J_elbow=0, J_tip=0, mu_elbow=0.015, mu_tip=0.01), rel,
                            data, free=("mu_elbow", "mu_tip"),
                            candidates=("root_flex", "elbow_flex", "drag"))
    assert ladder.effects == ("root_flex",)
    fit = ladder.fit
    assert fit.chi2 / fit.dof <= 1.5
    for name in ("root_flex", "mu_elbow", "mu_tip"):
        assert abs(fit.estimates[name] - truth[name]) < 3 * fit.sigmas[name], name
    # the rung is at its best: either its fit was (the check did not run:
    # with issue 30's stopping rules the diagnosis' refit reaches chi2 40.3
    # for 49 dof) or the at-its-best refit made it so
    step = ladder["root_flex"]
    assert "at its best" in step.at_best or (step.at_best == "" and
                                             step.fit.chi2 / step.fit.dof <= 1.0)


def test_ten_second_record_is_recovered_at_a_bounded_cost():
    """Table 16's fit on a 10 s release (2 elements per beam, 20 Hz), data at
    rtol 1e-11 with sigma 1e-4 m (seed 10), from the published starts: the
    record is grown (1.25, 2.5, 5, 10 s) and every parameter recovered."""
    t = np.arange(1, 201) / 20.0
    rig = {"long": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=2, rtol=1e-11)}
    data = beamid.simulate_measurements(TRUTH, rig, ["w_tip", "u_tip"], sigma=1e-4, t=t,
                                        seed=10, noise=True)
    rel = {"long": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=2)}
    start = TRUTH.replace(mu_elbow=0.015, mu_tip=0.01, rho1=0.5603, rho2=0.5437)
    fit = beamid.fit(start, rel, data, free=FREE)
    assert fit.converged and fit.chi2 / fit.dof <= 1.5 and len(fit.path) == 4
    for n in FREE:
        assert abs(fit.estimates[n] - TRUTH[n]) < 3 * fit.sigmas[n], n
    # the whole record's window from the 5 s window's estimates: 12
    # iterations measured (14 before the rough windows and the noise-floor
    # rules of issue 30's cost; damped steps of the accurate phase gaining
    # 0.002-0.12 each against the floor of 0.01 at chi2 381: the 2-element
    # mesh is not smooth at that scale); a guard against growth, not the
    # issue's bound (docs/workflow_dynamic.md, "Long records")
    assert fit.iterations <= 14


def test_long_record_full_fit_starts_at_its_optimum():
    """Table 16's fit on a 5 s release at 500 Hz (4 elements per beam, data
    at rtol 1e-11 with sigma 1e-4 m, seed 5, as benchmarks/bench_long_record):
    the record is grown (1.25 and 2.5 s at the rough tolerance, then 5 s)
    and the whole record's fit starts near its optimum, so its iterations
    are bounded: 5 measured (two on the rough model, two rough-Jacobian
    steps and one accurate step), against 10 before issue 30's changes
    (sixteen damped trials of steps below the noise floor in one of them)."""
    t = np.arange(1, 2501) / 500.0
    rig = {"r": beamid.Release(beamid.TipForce(fy=8.0), rtol=1e-11)}
    data = beamid.simulate_measurements(TRUTH, rig, ["w_tip", "u_tip"], sigma=1e-4, t=t,
                                        seed=5, noise=True)
    rel = {"r": beamid.Release(beamid.TipForce(fy=8.0))}
    start = TRUTH.replace(mu_elbow=0.015, mu_tip=0.01, rho1=0.5603, rho2=0.5437)
    fit = beamid.fit(start, rel, data, free=FREE)
    assert fit.converged and len(fit.path) == 3
    assert [p.split(",")[1].strip() for p in fit.path] == [
        "2 iterations", "1 iterations", "5 iterations"]
    assert fit.iterations == 5
    assert fit.chi2 == pytest.approx(5057.54, abs=0.01)
    for n in FREE:
        assert abs(fit.estimates[n] - TRUTH[n]) < 3 * fit.sigmas[n], n
