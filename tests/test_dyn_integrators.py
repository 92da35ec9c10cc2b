"""RK4 and the implicit Radau IIA integrator: agreement, observed order,
energy ledgers, and clean errors on bad input."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

import beamid
from beamid.dynamics import simulate

RELEASE = beamid.TipForce(fy=8.0)


@pytest.fixture(scope="module")
def model():
    return beamid.pace(J_elbow=0.0, J_tip=0.0)


def test_implicit_agrees_with_rk4_free(model):
    t = np.linspace(0.0, 0.3, 7)
    ref = simulate(model, RELEASE, t, integrator="rk4")
    imp = simulate(model, RELEASE, t, rtol=1e-7)
    assert_allclose(imp.tip_w, ref.tip_w, atol=2e-7)
    assert_allclose(imp.tip_u, ref.tip_u, atol=2e-7)
    # the implicit scheme's numerical dissipation is its own ledger line
    assert np.max(np.abs(imp.ledger["numerical"])) < 1e-5
    assert imp.info["steps"] < ref.info["steps"] / 20


def test_rk4_observed_order_4(model):
    # a soft axial stiffness makes the chain non-stiff, so dt is in the
    # asymptotic range of the method
    soft = model.replace(EA1=1e3, EA2=1e3)
    t = [0.0, 0.2]
    fine = simulate(soft, RELEASE, t, elements_per_beam=1, integrator="rk4", dt=1.25e-4)
    errs = []
    for dt in (2e-3, 1e-3):
        r = simulate(soft, RELEASE, t, elements_per_beam=1, integrator="rk4", dt=dt)
        errs.append(np.max(np.abs(r.q[:, -1] - fine.q[:, -1])))
    order = np.log2(errs[0] / errs[1])
    assert 3.5 < order < 4.6, (errs, order)


def test_implicit_error_falls_with_tolerance(model):
    t = np.linspace(0.0, 1.0, 5)
    ref = simulate(model, RELEASE, t, elements_per_beam=2, rtol=1e-10)
    e = [np.max(np.abs(simulate(model, RELEASE, t, elements_per_beam=2, rtol=r).tip_w
                       - ref.tip_w)) for r in (1e-5, 1e-8)]
    assert e[1] < e[0] / 10
    assert e[1] < 1e-7


def test_smooth_friction_same_law_agreement(model):
    m = model.replace(mu_elbow=0.01, mu_tip=0.02)
    t = np.linspace(0.0, 0.5, 6)
    ref = simulate(m, RELEASE, t, integrator="rk4", friction="smooth",
                   friction_velocity=1e-2)
    imp = simulate(m, RELEASE, t, rtol=1e-7, friction="smooth", friction_velocity=1e-2)
    assert imp.friction == "smooth"
    assert_allclose(imp.tip_w, ref.tip_w, atol=1e-6)
    assert_allclose(imp.work, ref.work, atol=1e-6)
    assert np.max(np.abs(ref.ledger["numerical"])) < 1e-9


@pytest.mark.parametrize("kwargs", [
    {"integrator": "euler"},
    {"friction": "viscous"},
    {"dt": -1.0, "integrator": "rk4"},
    {"rtol": 0.0},
    {"motor_gain": -0.2},
    {"elements_per_beam": 0},
    {"elements_per_beam": 1.5},
])
def test_bad_input(model, kwargs):
    with pytest.raises(beamid.InputError):
        simulate(model, RELEASE, [0.0, 0.01], **kwargs)


def test_bad_times(model):
    with pytest.raises(beamid.InputError):
        simulate(model, RELEASE, [0.0, 0.02, 0.01])
    with pytest.raises(beamid.InputError):
        simulate(model, RELEASE, [-0.1, 0.0])
    with pytest.raises(beamid.InputError):
        simulate(model, beamid.RadialWire(1.3), [0.0, 0.01])


def test_elbow_flex_hinge_conserves_energy(model):
    # the compliant elbow is a hinge spring of the FE chain: RK4 keeps the total
    # energy (strain + spring + kinetic) and the release is stiffer without it
    t = np.linspace(0.0, 0.1, 3)
    hinge = simulate(model.replace(elbow_flex=0.01), RELEASE, t, elements_per_beam=2,
                     integrator="rk4")
    rigid = simulate(model, RELEASE, t, elements_per_beam=2, integrator="rk4")
    assert np.ptp(hinge.energy) < 1e-9 * hinge.energy[0]
    assert hinge.tip_w[0] > rigid.tip_w[0] + 0.01
    with pytest.raises(beamid.InputError, match="flex"):
        simulate(model.replace(elbow_flex=-0.01), RELEASE, [0.0, 0.01])


@pytest.mark.parametrize("elements", [1, 2, 4])
def test_symmetric_and_pivoted_factorizations_agree(elements):
    # Without a motor lag the Radau iteration matrices are symmetric and are
    # factored as L D L^T without pivoting; a lag (here on a vanishing motor
    # gain, so the physics is the same) sends them through band LU with
    # partial pivoting. Both must give the same motion. The meshes cover the
    # constant-bandwidth fast paths of the symmetric kernels (half-bandwidth 7;
    # 9, 17 and 33 unknowns: shorter than, just over and well over 2 x 7).
    m = beamid.pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)
    t = np.linspace(0.0, 0.3, 4)
    kw = dict(rtol=1e-8, friction="smooth", friction_velocity=1e-2, elements_per_beam=elements)
    sym = simulate(m, RELEASE, t, **kw)
    lu = simulate(m.replace(tau_motor=1e-3), RELEASE, t, motor_gain=1e-12, **kw)
    assert np.max(np.abs(lu.motor_torque)) < 1e-10
    assert_allclose(sym.tip_w, lu.tip_w, atol=1e-9)
    assert_allclose(sym.tip_u, lu.tip_u, atol=1e-9)
