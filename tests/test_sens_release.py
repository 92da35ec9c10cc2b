"""Forward sensitivities of a release (issue 13; Eq. 135-140, 161-162):
every parameter the dynamics depend on against central differences of the
plain runs, for both integrators, with friction (the sign law with events),
drag, Kelvin-Voigt damping, rotary inertia and the motor (with and without
its lag) switched on in turn; the release load's components; the released
shape; a zero column for a parameter the dynamics ignore.

The measure: the normalized sensitivity p dy/dp against p times the central
difference, relative to the quantity's own range over the run. Mesh: 2
elements per beam, spans of 0.03-0.1 s (the switches of the sign law happen
within the first 0.02 s)."""
import numpy as np
import pytest

import beamid

QTYS = ("tip_w", "tip_u", "tip_angle", "energy", "motor_torque")
BASE = dict(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)


def _runs(model, names, integrator, span, gain=0.0, fy=8.0, rel=1e-5, nt=4):
    t = np.linspace(0.0, span, nt)
    kw = dict(t_out=t, elements_per_beam=2, integrator=integrator, motor_gain=gain)
    if integrator == "implicit":
        kw["rtol"] = 1e-11
    run = beamid.simulate(model, release=beamid.TipForce(fy=fy), wrt=names, **kw)
    worst = {}
    for p in names:
        if p == "load_fy":
            h = rel * fy
            rp = beamid.simulate(model, release=beamid.TipForce(fy=fy + h), **kw)
            rm = beamid.simulate(model, release=beamid.TipForce(fy=fy - h), **kw)
            pv = fy
        else:
            pv = model[p]
            h = rel * abs(pv)
            rp = beamid.simulate(model.replace(**{p: pv + h}), release=beamid.TipForce(fy=fy),
                                 **kw)
            rm = beamid.simulate(model.replace(**{p: pv - h}), release=beamid.TipForce(fy=fy),
                                 **kw)
        for q in QTYS:
            y = getattr(run, q)
            scale = max(np.ptp(y), 1e-3 * np.max(np.abs(y)), 1e-12)
            fd = (getattr(rp, q) - getattr(rm, q)) / (2 * h)
            worst[(p, q)] = np.max(np.abs(pv * (run.d[q][p] - fd))) / scale
    return run, worst


CASES = {
    # name: (model overrides, parameters, motor gain, implicit span, rk4 span)
    "friction": (BASE, ("EI1", "EA1", "rho1", "EI2", "rho2", "m_elbow", "m_tip", "mu_elbow",
                        "mu_tip", "load_fy"), 0.0, 0.1, 0.03),
    "drag": (dict(BASE, c_elbow=0.5, c_tip=0.3), ("c_elbow", "c_tip", "rho1", "EI2"), 0.0,
             0.1, 0.03),
    "kelvin_voigt": (dict(BASE, eta=0.01), ("eta", "EI1", "EI2", "rho2"), 0.0, 0.1, 0.03),
    "rotary": (dict(mu_elbow=0.01, mu_tip=0.02), ("J_elbow", "J_tip", "rho1", "m_tip"), 0.0,
               0.1, 0.03),
    "motor": (BASE, ("r_motor", "mu_tip", "EI2"), 0.2, 0.03, 0.03),
    "motor_lag": (dict(BASE, tau_motor=0.01), ("r_motor", "tau_motor", "rho1", "mu_tip"), 0.2,
                  0.1, 0.03),
    # stick-slip: the components stick and unstick dozens of times
    "stick_slip": (dict(J_elbow=0.0, J_tip=0.0, mu_elbow=0.05, mu_tip=0.05),
                   ("mu_elbow", "mu_tip", "rho1", "EI2", "load_fy"), 0.0, 0.2, 0.05),
    "hinges": (dict(BASE, elbow_flex=0.01, root_flex=0.005), ("elbow_flex", "root_flex", "EI1"),
               0.0, 0.1, 0.03),
}


@pytest.mark.parametrize("integrator", ["implicit", "rk4"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_sensitivities_match_central_differences(case, integrator):
    over, names, gain, span_i, span_r = CASES[case]
    model = beamid.pace(**over)
    span = span_i if integrator == "implicit" else span_r
    run, worst = _runs(model, names, integrator, span, gain=gain)
    bad = {k: v for k, v in worst.items() if v > 2e-4}
    assert not bad, bad
    # the checks are not vacuous: every parameter moves the tip
    for p in names:
        assert np.max(np.abs(run.d["tip_w"][p])) > 0.0, p


def test_friction_events_are_crossed():
    """The friction cases switch within their spans, both ways (a velocity
    reaching zero, a sticking component starting to slide): the jump
    condition is exercised, not avoided."""
    model = beamid.pace(**BASE)
    run = beamid.simulate(model, beamid.TipForce(fy=8.0), t_out=[0.0, 0.1],
                          elements_per_beam=2, wrt=("mu_tip",))
    kinds = [ev.kind for ev in run.events]
    assert kinds.count("unstick") >= 2 and kinds.count("zero_velocity") >= 2


def test_released_shape_sensitivity_is_the_static_one():
    """At t = 0 the sensitivity is that of the static equilibrium (implicit
    function theorem), checked against central differences of beamid's
    static finite element solve; the velocity sensitivity is zero."""
    model = beamid.pace(**BASE)
    run = beamid.simulate(model, beamid.TipForce(fy=8.0), t_out=[0.0], elements_per_beam=2,
                          wrt=("EI1", "EA2", "load_fy"))
    for p in ("EI1", "EA2"):
        h = 1e-6 * model[p]
        wp = beamid.simulate(model.replace(**{p: model[p] + h}), beamid.TipForce(fy=8.0),
                             t_out=[0.0], elements_per_beam=2).tip_w[0]
        wm = beamid.simulate(model.replace(**{p: model[p] - h}), beamid.TipForce(fy=8.0),
                             t_out=[0.0], elements_per_beam=2).tip_w[0]
        np.testing.assert_allclose(run.d["tip_w"][p][0], (wp - wm) / (2 * h), rtol=1e-6)
        nfree = run.nfree
        assert np.all(run.dstates[p][nfree:2 * nfree, 0] == 0.0)
    wp = beamid.simulate(model, beamid.TipForce(fy=8.0 + 1e-5), t_out=[0.0],
                         elements_per_beam=2).tip_w[0]
    wm = beamid.simulate(model, beamid.TipForce(fy=8.0 - 1e-5), t_out=[0.0],
                         elements_per_beam=2).tip_w[0]
    np.testing.assert_allclose(run.d["tip_w"]["load_fy"][0], (wp - wm) / 2e-5, rtol=1e-6)


def test_parameters_the_dynamics_ignore_give_zero_columns():
    """axial_coupling belongs to the arc-length model only; r_motor and
    tau_motor do nothing without a motor; fx with fy alone is not zero (the
    load direction changes the shape)."""
    model = beamid.pace(**BASE)
    run = beamid.simulate(model, beamid.TipForce(fy=8.0), t_out=[0.0, 0.02, 0.05],
                          elements_per_beam=2, wrt=("axial_coupling", "r_motor", "tau_motor",
                                                    "load_fx"))
    for p in ("axial_coupling", "r_motor", "tau_motor"):
        for q in beamid.SENSITIVITY_QUANTITIES:
            assert np.all(run.d[q][p] == 0.0), (p, q)
    assert np.max(np.abs(run.d["tip_u"]["load_fx"])) > 1e-3


def test_sensitivity_names_and_errors():
    model = beamid.pace(**BASE)
    run = beamid.simulate(model, beamid.TipForce(fy=8.0), t_out=[0.0, 0.01],
                          elements_per_beam=2, wrt="rho1")
    assert set(beamid.SENSITIVITY_QUANTITIES) <= set(run.d)
    np.testing.assert_array_equal(run.d["tip_w"]["rho1"], run.d["w_tip"]["rho1"])
    np.testing.assert_array_equal(run.d["x_tip"]["rho1"], run.d["u_tip"]["rho1"])
    with pytest.raises(beamid.InputError, match="unknown parameter"):
        beamid.simulate(model, beamid.TipForce(fy=8.0), t_out=[0.01], wrt=("rho9",))
    with pytest.raises(beamid.InputError, match="L1"):
        beamid.simulate(model, beamid.TipForce(fy=8.0), t_out=[0.01], elements_per_beam=2,
                        wrt=("L1",))
    with pytest.raises(beamid.InputError, match="elbow_flex"):
        beamid.simulate(model, beamid.TipForce(fy=8.0), t_out=[0.01], elements_per_beam=2,
                        wrt=("elbow_flex",))
    with pytest.raises(beamid.InputError, match="modes"):
        beamid.simulate(model, beamid.TipForce(fy=8.0), t_out=[0.01], elements_per_beam=2,
                        wrt=("rho1",), modes=4)


def test_stage_iteration_residual_update_is_exact():
    """After its first pass the implicit stage iteration takes the residual of a
    correction dZ as (K0 - K(Y_i)) dZ_q,i (the solves invert lam^2 M + K0 exactly;
    constant mass, no velocity coupling): the same sensitivities as evaluating the
    residual afresh, which a drag of 1e-300 forces (C is then nonzero, the state
    is bit for bit the same). A wrong update leaves 1e-6 to 1e-4 of the range;
    the global error against rtol 1e-12 runs is 2e-4, too coarse to see it."""
    model = beamid.pace(**BASE)
    t = np.linspace(0.65 / 36, 0.65, 36)
    names = ("mu_elbow", "mu_tip", "rho1", "rho2")
    kw = dict(t_out=t, elements_per_beam=4, wrt=names)
    upd = beamid.simulate(model, beamid.TipForce(fy=8.0), **kw)
    full = beamid.simulate(model.replace(c_tip=1e-300), beamid.TipForce(fy=8.0), **kw)
    assert np.array_equal(upd.tip_w, full.tip_w)
    for q in ("tip_w", "tip_u"):
        for p in names:
            err = np.max(np.abs(upd.d[q][p] - full.d[q][p])) / np.ptp(full.d[q][p])
            assert err < 1e-10, (q, p, err)
