"""Nonconservative effects: hand-coded Jacobians against central differences,
energy balance (change in energy = work of each effect), the motor runs."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

import beamid
from beamid.dynamics import dynamic_system, simulate

RELEASE = beamid.TipForce(fy=8.0)
ALL_EFFECTS = dict(mu_elbow=0.01, mu_tip=0.02, c_elbow=0.3, c_tip=0.2, eta=0.01)


def _random_state(n, seed):
    rng = np.random.default_rng(seed)
    return 0.05 * rng.standard_normal(n), 0.3 * rng.standard_normal(n)


@pytest.mark.parametrize("tau", [0.0, 1e-3])
def test_jacobians_match_central_differences(tau):
    model = beamid.pace(tau_motor=tau, **ALL_EFFECTS)   # rotary inertia J from Table 1
    nepb = 2
    probe = dynamic_system(model, np.zeros(17), np.zeros(17), nepb, motor_gain=0.2)
    n = probe["M"].shape[0]
    q, v = _random_state(n, 3)
    x = 0.05
    kw = dict(motor_gain=0.2, friction="smooth", friction_velocity=0.05, torque_state=x)
    base = dynamic_system(model, q, v, nepb, **kw)
    h = 1e-6    # q steps; v steps are larger (F is at most quadratic in v except
    hv = 1e-4   # the smooth friction) to keep the round-off of NLT ~ 1e6 N small
    kfd = np.empty((n, n))
    cfd = np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = h
        kfd[:, j] = -(dynamic_system(model, q + e, v, nepb, **kw)["force"]
                      - dynamic_system(model, q - e, v, nepb, **kw)["force"]) / (2 * h)
        ev = e * (hv / h)
        cfd[:, j] = -(dynamic_system(model, q, v + ev, nepb, **kw)["force"]
                      - dynamic_system(model, q, v - ev, nepb, **kw)["force"]) / (2 * hv)
    scale_k = np.max(np.abs(base["K"]))
    assert_allclose(base["K"], kfd, atol=1e-6 * scale_k)
    assert_allclose(base["C"], cfd, atol=1e-6 * max(1.0, np.max(np.abs(base["C"]))))
    if tau > 0:
        # dF/dT and the lag equation's couplings
        ht = 1e-2   # F is linear in T
        kw2 = dict(kw, torque_state=x + ht)
        kw3 = dict(kw, torque_state=x - ht)
        bfd = (dynamic_system(model, q, v, nepb, **kw2)["force"]
               - dynamic_system(model, q, v, nepb, **kw3)["force"]) / (2 * ht)
        assert_allclose(base["b"], bfd, atol=1e-7)
        assert base["e"] == pytest.approx(-1.0 / tau)
    else:
        assert np.all(base["b"] == 0.0)


def test_friction_power_is_minus_mu_N_speed():
    model = beamid.pace(mu_elbow=0.01, mu_tip=0.02)
    probe = dynamic_system(model, np.zeros(17), np.zeros(17), 2, friction="sign")
    n = probe["M"].shape[0]
    q, v = _random_state(n, 5)
    out = dynamic_system(model, q, v, 2, friction="sign")
    # tip u, w are the 3rd and 1st unknowns of the last node: n-4+0 is w_tip
    w_tip, u_tip = v[n - 4], v[n - 2]
    assert out["power"][1] == pytest.approx(-0.02 * 1.038 * 9.81 * (abs(w_tip) + abs(u_tip)))


@pytest.mark.parametrize("effects, integrator", [
    (dict(c_elbow=0.3, c_tip=0.2), "rk4"),
    (dict(eta=0.005), "implicit"),
    (dict(mu_elbow=0.01, mu_tip=0.02), "implicit"),
])
def test_energy_change_equals_work(effects, integrator):
    model = beamid.pace(J_elbow=0.0, J_tip=0.0, **effects)
    t = np.linspace(0.0, 0.2, 5)
    kw = {"rtol": 1e-8} if integrator == "implicit" else {}
    run = simulate(model, RELEASE, t, elements_per_beam=2, integrator=integrator, **kw)
    assert run.work[-1] < -1e-4                       # the effect did work
    assert np.max(np.abs(run.ledger["numerical"])) < 1e-6


def test_rotary_inertia_conserves_energy():
    model = beamid.pace()                             # J from Table 1
    t = np.linspace(0.0, 0.1, 3)
    run = simulate(model, RELEASE, t, elements_per_beam=2, integrator="rk4")
    assert np.ptp(run.energy) < 1e-9
    plain = simulate(model.replace(J_elbow=0.0, J_tip=0.0), RELEASE, t, elements_per_beam=2,
                     integrator="rk4")
    assert 1e-7 < np.max(np.abs(run.tip_w - plain.tip_w)) < 1e-3   # small (Figure 19)


def test_motor_gain_02_peak_torque_and_balance():
    """Chapter V: g = 0.2 keeps the peak torque near 0.35 N m; the energy
    change equals the work of the motor and friction."""
    model = beamid.pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)
    t = np.linspace(0.0, 0.8, 41)
    run = simulate(model, RELEASE, t, motor_gain=0.2, rtol=1e-8, friction="smooth",
                   friction_velocity=1e-2)
    peak = np.max(np.abs(run.motor_torque))
    assert peak == pytest.approx(0.347, abs=0.003)      # at t = 0.71 s
    assert run.ledger["motor"][-1] < 0
    assert np.max(np.abs(run.ledger["numerical"])) < 1e-5
    # with a 1 ms current-loop lag the response barely changes
    lag = simulate(model.replace(tau_motor=1e-3), RELEASE, t, motor_gain=0.2, rtol=1e-8,
                   friction="smooth", friction_velocity=1e-2)
    assert np.max(np.abs(lag.tip_w - run.tip_w)) < 1e-3
    assert np.max(np.abs(lag.ledger["numerical"])) < 1e-5


def test_profiles_end_at_tip():
    model = beamid.pace(J_elbow=0.0, J_tip=0.0)
    run = simulate(model, RELEASE, [0.0, 0.1], elements_per_beam=2)
    (x0, y0), (x1, y1) = run.profiles([0.0, 0.1], points_per_element=4)
    assert x0.size == 4 * 4 + 1
    assert y1[-1] == pytest.approx(run.tip_w[1])
    assert x0[-1] == pytest.approx(0.776 + 0.714 + run.tip_u[0])
    with pytest.raises(beamid.InputError):
        run.profiles([0.05])


def test_chapter5_motor_period_energy_rk4():
    """Chapter V, g = 0.2 with friction: after one period the energy change
    (and the work) is 1.2967753 N m (RK4, sign law, as the dissertation)."""
    model = beamid.pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)
    run = simulate(model, RELEASE, [0.0, 2.6], integrator="rk4", motor_gain=0.2)
    assert run.energy_change[-1] == pytest.approx(-1.2967753, abs=3e-7)
    assert run.work[-1] == pytest.approx(run.energy_change[-1], abs=2e-9)


def test_damping_with_elbow_hinge_jacobian_and_work():
    """Kelvin-Voigt damping on a chain with a compliant elbow: the element loop
    follows the hinge's outboard slopes (mesh el_dof), so the damping Jacobians
    match central differences and the energy change equals the work."""
    model = beamid.pace(J_elbow=0.0, J_tip=0.0, eta=0.01, elbow_flex=0.05)
    nepb = 2
    n = dynamic_system(model, np.zeros(19), np.zeros(19), nepb)["M"].shape[0]
    assert n == 19                      # 17 rigid unknowns + the hinge's (w', u')
    q, v = _random_state(n, 11)
    base = dynamic_system(model, q, v, nepb)
    kfd, cfd = np.empty((n, n)), np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1e-6
        kfd[:, j] = -(dynamic_system(model, q + e, v, nepb)["force"]
                      - dynamic_system(model, q - e, v, nepb)["force"]) / 2e-6
        e[j] = 1e-4
        cfd[:, j] = -(dynamic_system(model, q, v + e, nepb)["force"]
                      - dynamic_system(model, q, v - e, nepb)["force"]) / 2e-4
    assert_allclose(base["K"], kfd, atol=1e-6 * np.max(np.abs(base["K"])))
    assert_allclose(base["C"], cfd, atol=1e-7 * np.max(np.abs(base["C"])))
    # eta EI on the axial-bending modes is beyond RK4's stability at 1e-5 s
    run = simulate(model, RELEASE, [0.0, 0.05, 0.1], rtol=1e-8)
    assert run.ledger["damping"][-1] < -1e-4
    assert np.max(np.abs(run.ledger["numerical"])) < 1e-6


def test_damping_with_elbow_hinge_equals_rigid_when_slopes_agree():
    """At a state whose outboard hinge slopes equal the inboard ones the
    curvature field is the rigid chain's, so are the damping power and force."""
    nepb = 2
    rigid = beamid.pace(J_elbow=0.0, J_tip=0.0, eta=0.01)
    hinged = rigid.replace(elbow_flex=0.05)
    q, v = _random_state(17, 13)
    # rigid free order: node 1 u', then [w, w', u, u'] per node; the elbow is
    # node 3 (free 5..8), which a hinge numbers [w'-, u'-, w, u, w'+, u'+]
    order = list(range(5)) + [6, 8, 5, 7, 6, 8] + list(range(9, 17))

    def damping(model, qq, vv):
        zero = beamid.pace(J_elbow=0.0, J_tip=0.0).replace(
            elbow_flex=model["elbow_flex"])
        full = dynamic_system(model, qq, vv, nepb)
        none = dynamic_system(zero, qq, vv, nepb)
        return full["power"][4], full["force"] - none["force"]

    p_r, f_r = damping(rigid, q, v)
    p_h, f_h = damping(hinged, q[order], v[order])
    assert p_r < 0.0
    assert p_h == pytest.approx(p_r, rel=1e-12)
    # the hinged force summed over the two slope pairs is the rigid one
    f_sum = np.zeros(17)
    np.add.at(f_sum, order, f_h)
    assert_allclose(f_sum, f_r, atol=1e-10 * np.max(np.abs(f_r)))


def test_damping_acts_on_the_outboard_hinge_slope():
    """Only the outboard slope w'+ of the elbow hinge moves: the first element of
    beam 2 bends at a rate, so damping dissipates and resists that slope."""
    model = beamid.pace(J_elbow=0.0, J_tip=0.0, eta=0.01, elbow_flex=0.05)
    v = np.zeros(19)
    v[9] = 1.0                          # w'+ of the elbow (free order above)
    out = dynamic_system(model, np.zeros(19), v, 2)
    plain = dynamic_system(model.replace(eta=0.0), np.zeros(19), v, 2)
    fd = out["force"] - plain["force"]
    assert out["power"][4] < 0.0
    assert out["power"][4] == pytest.approx(fd @ v, rel=1e-12)
    assert fd[9] < 0.0
    assert np.all(fd[:5] == 0.0)        # beam 1 does not see the outboard slope
