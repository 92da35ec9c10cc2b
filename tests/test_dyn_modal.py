"""Modal truncation (Section 4.1.4, Eq. 127-129): the nonlinear finite element
dynamics integrated in the coordinates of a subset of the linear modes,
compared with the full model. 8 elements (4 per beam), no rotary inertia, free
vibration from the 8 N static shape, as in the dissertation."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

import beamid
from beamid.dynamics import simulate

RELEASE = beamid.TipForce(fy=8.0)
T = np.linspace(0.0, 0.2, 5)
#: Eq. 129: the fifteen modes the dissertation kept by Skelton's modal cost
EQ129 = [1, 2, 3, 4, 5, 10, 15, 19, 20, 21, 22, 23, 24, 25, 28]


@pytest.fixture(scope="module")
def model():
    return beamid.pace(J_elbow=0.0, J_tip=0.0)


@pytest.fixture(scope="module")
def full(model):
    return simulate(model, RELEASE, T, rtol=1e-8)


def _tip_error(run, ref):
    return max(np.max(np.abs(run.tip_w - ref.tip_w)), np.max(np.abs(run.tip_u - ref.tip_u)))


def test_all_modes_is_the_full_model(model, full):
    run = simulate(model, RELEASE, T, rtol=1e-8, modes=full.nfree)
    assert run.modes == tuple(range(1, 34))
    assert _tip_error(run, full) < 1e-6
    assert_allclose(run.energy[0], full.energy[0], rtol=1e-12)
    # states come back physical (q = Phi eta); the slopes carry the unresolved
    # axial vibration, which the two coordinate systems damp differently
    assert run.states.shape == full.states.shape
    assert_allclose(run.q[:, -1], full.q[:, -1], atol=5e-5)


def test_all_modes_rk4_matches_full_rk4(model):
    t = [0.0, 0.003]
    ref = simulate(model, RELEASE, t, integrator="rk4")
    run = simulate(model, RELEASE, t, integrator="rk4", modes=ref.nfree)
    assert_allclose(run.states, ref.states, atol=1e-9)


def test_error_falls_as_modes_are_added(model, full):
    """Nested sets: the dissertation's fifteen (Eq. 129), the 30 lowest (its
    'neglecting #31, #32, #33'), every mode but #8, all 33."""
    sets = [EQ129, list(range(1, 31)), [m for m in range(1, 34) if m != 8],
            list(range(1, 34))]
    errs = [_tip_error(simulate(model, RELEASE, T, rtol=1e-8, modes=s), full) for s in sets]
    assert errs[0] > 1e-2             # "significantly different" (Figure 18)
    assert 1e-4 < errs[1] < 1e-2      # the highest axial modes matter
    assert errs[2] < 2e-5             # the lowest-cost transverse mode hardly does
    assert errs[3] < 1e-6
    assert errs[0] > errs[1] > errs[2] > errs[3]


def test_transverse_modes_only_lock_the_membrane(model, full):
    """Without the axial modes u cannot follow the foreshortening of the large
    deflection (u ~ -int w'^2/2): the projected static shape carries a huge
    membrane strain energy EA (w'^2/2)^2 instead of 2.25 N m."""
    run = simulate(model, RELEASE, [0.0, 0.001], rtol=1e-8, modes="transverse")
    assert len(run.modes) == 16
    assert run.energy[0] > 1e4 * full.energy[0]
    assert abs(run.tip_u[0]) < 1e-9            # no axial displacement left
    assert_allclose(run.tip_w[0], full.tip_w[0], atol=1e-12)


def test_modal_with_effects_matches_full(model):
    """Rotary inertia (M(q) in modal coordinates), friction, damping and the
    lagged motor, all modes: same response and work as the full model."""
    m = beamid.pace(tau_motor=1e-3, mu_elbow=0.01, mu_tip=0.02, eta=0.01)
    t = [0.0, 0.05, 0.1]
    ref = simulate(m, RELEASE, t, motor_gain=0.2, rtol=1e-9)
    run = simulate(m, RELEASE, t, motor_gain=0.2, rtol=1e-9, modes=ref.nfree)
    assert_allclose(run.tip_w, ref.tip_w, atol=1e-6)
    assert_allclose(run.work, ref.work, atol=1e-6)
    assert_allclose(run.motor_torque, ref.motor_torque, atol=1e-4)


@pytest.mark.parametrize("modes", [0, 34, [1, 1], [0, 2], [1.5], "axial", True, []])
def test_bad_modes(model, modes):
    with pytest.raises(beamid.InputError):
        simulate(model, RELEASE, [0.0, 0.01], modes=modes)


@pytest.mark.parametrize("tau", [0.0, 1e-3])
def test_projected_jacobians_match_central_differences(tau):
    """K~ = Phi^T K Phi and C~ = Phi^T C Phi (and the projected motor-lag
    couplings) against central differences of F~(eta, eta') = Phi^T F."""
    from beamid.dynamics import dynamic_system
    model = beamid.pace(tau_motor=tau, mu_elbow=0.01, mu_tip=0.02, c_elbow=0.3, eta=0.01)
    modes = [1, 2, 3, 5, 8, 9, 12]
    k = len(modes)
    rng = np.random.default_rng(7)
    eta, etad = 0.03 * rng.standard_normal(k), 0.2 * rng.standard_normal(k)
    kw = dict(motor_gain=0.2, friction="smooth", friction_velocity=0.05, torque_state=0.05,
              modes=modes)
    base = dynamic_system(model, eta, etad, 2, **kw)
    assert base["K"].shape == (k, k)
    kfd, cfd = np.empty((k, k)), np.empty((k, k))
    for j in range(k):
        e = np.zeros(k)
        e[j] = 1e-6
        kfd[:, j] = -(dynamic_system(model, eta + e, etad, 2, **kw)["force"]
                      - dynamic_system(model, eta - e, etad, 2, **kw)["force"]) / 2e-6
        e[j] = 1e-5
        cfd[:, j] = -(dynamic_system(model, eta, etad + e, 2, **kw)["force"]
                      - dynamic_system(model, eta, etad - e, 2, **kw)["force"]) / 2e-5
    scale = np.max(np.abs(base["K"]))
    assert_allclose(base["K"], kfd, atol=1e-6 * scale)
    assert_allclose(base["C"], cfd, atol=1e-6 * np.max(np.abs(base["C"])))
    # rotary inertia (Table 1's J) makes M~ = Phi^T M(q) Phi differ from I
    assert_allclose(base["M"], base["M"].T, atol=1e-14)
    assert np.max(np.abs(base["M"] - np.eye(k))) > 1e-6
    if tau > 0:
        full = dynamic_system(model, np.zeros(17), np.zeros(17), 2, motor_gain=0.2)
        assert base["b"].shape == (k,) and np.any(base["b"] != 0.0)
        assert base["e"] == full["e"]
