"""Compliant joints and root in the finite element chain (docs/theory_fe.md, Sec. 8).

A joint with ``elbow_flex`` (``joint<k>_flex``) f > 0 is a hinge: its node keeps
one position (u, w) and gets a second slope pair (w'+, u'+) for the outboard beam,
with the spring energy (psi+ - psi-)^2 / (2 f), psi = atan2(w', 1 + u'). A
``root_flex`` > 0 frees the root slope and holds it with the same spring.

* the hand-coded tangent against central differences, the force against the
  gradient of the energy (hinge and root spring on, cubic law on);
* small loads: the linear two-beam cantilever gains f F L2^2 (elbow) and
  f_r F L^2 (root) in tip deflection, and V = F w_tip / 2 (Clapeyron);
* large deformation: the FE converges to the arc-length solver with the same
  elbow_flex, and the kink equals f times the elbow moment;
* f -> 0 recovers the rigid chain continuously; f = 0 *is* the rigid chain;
* the first transverse frequency and the buckling load fall as f grows.
"""
import numpy as np
import pytest
from numpy.testing import assert_allclose

import beamid
from beamid import _core, fe


@pytest.fixture
def pace():
    return beamid.pace()


def _bent_state(nfree, seed):
    rng = np.random.default_rng(seed)
    return 0.15 * rng.standard_normal(nfree)


@pytest.mark.parametrize("overrides", [dict(elbow_flex=0.05),
                                       dict(elbow_flex=0.05, root_flex=0.02, C1=3.0, C2=5.0),
                                       dict(root_flex=0.01)])
def test_tangent_and_force_against_central_differences(pace, overrides):
    model = pace.replace(**overrides)
    *_, nfree = fe._mesh(model, 2, hinged=True)
    q = _bent_state(nfree, 7)
    sysm = fe.fe_system(model, q, elements_per_beam=2)
    jac, force, energy = sysm["jacobian"], sysm["force"], sysm["energy"]
    h = 1e-6
    jfd = np.empty_like(jac)
    gfd = np.empty(nfree)
    for k in range(nfree):
        dq = np.zeros(nfree)
        dq[k] = h
        plus = fe.fe_system(model, q + dq, elements_per_beam=2)
        minus = fe.fe_system(model, q - dq, elements_per_beam=2)
        jfd[:, k] = (plus["force"] - minus["force"]) / (2 * h)
        gfd[k] = (plus["energy"] - minus["energy"]) / (2 * h)
    scale = np.max(np.abs(jac))
    assert np.max(np.abs(jac - jfd)) <= 1e-7 * scale
    assert_allclose(jac, jac.T, atol=1e-9 * scale)    # conservative: symmetric
    assert np.max(np.abs(force - gfd)) <= 1e-7 * np.max(np.abs(force))
    assert energy > 0.0


def test_unknown_counts_and_band(pace):
    """f = 0 keeps the rigid numbering; a hinge adds w'+, u'+, a root hinge w'(0);
    the half-bandwidth stays 7."""
    for overrides, extra in [({}, 0), (dict(elbow_flex=0.01), 2), (dict(root_flex=0.01), 1),
                             (dict(elbow_flex=0.01, root_flex=0.01), 3)]:
        model = pace.replace(**overrides)
        nnode, nfree, nhinge, band = _core.fe_mesh_sizes(2, model.vector(), 4)
        assert (nnode, nfree, nhinge, band) == (9, 4 * 9 - 3 + extra, extra // 2, 7)
        md = beamid.modes(model, 4)
        assert md.phi.shape == (nfree, nfree)
        # the hinge's outboard slopes are components 5 (w'+) and 6 (u'+) at the elbow
        assert sorted(md.dofs[md.dofs[:, 1] >= 5].tolist()) == \
            ([[5, 5], [5, 6]] if extra >= 2 else [])


def _stepped_cantilever(p, force, f_elbow=0.0, f_root=0.0):
    """Linear tip deflection of the two-beam cantilever under a transverse tip
    force with a hinge spring at the elbow (f) and at the root (f_r):
    F/(3 EI1) (L^3 - L2^3) + F L2^3/(3 EI2) + f F L2^2 + f_r F L^2."""
    l1, l2 = p["L1"], p["L2"]
    total = l1 + l2
    return force * ((total**3 - l2**3) / (3 * p["EI1"]) + l2**3 / (3 * p["EI2"])
                    + f_elbow * l2**2 + f_root * total**2)


@pytest.mark.parametrize("f_elbow, f_root", [(0.0, 0.0), (0.02, 0.0), (0.0, 0.01),
                                             (0.02, 0.01)])
def test_small_load_matches_linear_theory(pace, f_elbow, f_root):
    force = 1e-3
    model = pace.replace(elbow_flex=f_elbow, root_flex=f_root)
    r = beamid.fe_static(model, beamid.TipForce(fy=force), 2)
    exact = _stepped_cantilever(pace.params, force, f_elbow, f_root)
    assert r.tip["w"] == pytest.approx(exact, rel=1e-6)
    # Clapeyron: the strain energy (springs included) is half the work of the load
    assert r.energy == pytest.approx(0.5 * force * r.tip["w"], rel=1e-6)
    # the hinge angle is f times the elbow moment F L2 (to first order)
    elbow = 2
    assert r.kink[elbow] == pytest.approx(f_elbow * force * pace["L2"], rel=1e-6, abs=1e-15)
    if f_root:
        assert np.arctan2(r.nodes["dw"][0], 1 + r.nodes["du"][0]) == \
            pytest.approx(f_root * force * (pace["L1"] + pace["L2"]), rel=1e-6)
    else:
        assert r.nodes["dw"][0] == 0.0


@pytest.fixture(scope="module")
def arclength_8n():
    model = beamid.pace(elbow_flex=0.01)
    return model, beamid.solve_static(model, beamid.TipForce(fy=8.0))


def test_large_deformation_converges_to_the_arclength_solver(arclength_8n):
    """8 N on the arm with elbow_flex = 0.01: the FE tip converges to the
    arc-length elastica with the same kink law (the last 1e-6 is the axial
    stretch the arc-length model leaves out, as for the rigid arm)."""
    model, s = arclength_8n
    errors = []
    for n in (2, 4, 8, 16):
        r = beamid.fe_static(model, beamid.TipForce(fy=8.0), n)
        errors.append(abs(r.tip["w"] - s.tip_y))
        if n == 16:
            assert r.y[-1] == pytest.approx(s.tip_y, abs=2e-6)
            assert r.x[-1] == pytest.approx(s.tip_x, abs=2e-6)
            assert r.angle[-1] == pytest.approx(s.tip_angle, abs=2e-6)
            elbow = 16
            assert r.x[elbow] == pytest.approx(s.elbow_x, abs=2e-6)
            assert r.y[elbow] == pytest.approx(s.elbow_y, abs=2e-6)
            # kink = f M_elbow, M_elbow = moment of the tip force about the elbow
            moment = 8.0 * (r.x[-1] - r.x[elbow])
            assert r.kink[elbow] == pytest.approx(0.01 * moment, rel=1e-9)
            assert 0.045 < r.kink[elbow] < 0.046
            # the inboard slope of the elbow node is the arc-length elbow angle
            assert r.angle[elbow] == pytest.approx(s.outputs["elbow_angle"], abs=2e-6)
    assert errors[0] > errors[1] > errors[2] > errors[3]
    assert errors[0] > 5e-3 and errors[3] < 2e-6


def test_hinge_deflects_more_than_the_locked_elbow(arclength_8n):
    model, _ = arclength_8n
    locked = beamid.fe_static(beamid.pace(), beamid.TipForce(fy=8.0), 4)
    hinged = beamid.fe_static(model, beamid.TipForce(fy=8.0), 4)
    assert hinged.tip["w"] - locked.tip["w"] == pytest.approx(0.0178, abs=5e-4)
    assert np.all(locked.kink == 0.0)


def test_restart_from_a_hinged_result(arclength_8n):
    """The outboard slopes travel with the result: Newton restarted from it
    converges at once, and r.q is the free vector of fe_system."""
    model, _ = arclength_8n
    r = beamid.fe_static(model, beamid.TipForce(fy=8.0), 2)
    again = beamid.fe_static(model, beamid.TipForce(fy=8.0), 2, start=r)
    assert again.iterations <= 2
    assert_allclose(again.outboard["dw"], r.outboard["dw"], atol=1e-12)
    sysm = fe.fe_system(model, r.q, beamid.TipForce(fy=8.0), elements_per_beam=2)
    assert np.max(np.abs(sysm["force"] - sysm["load"])) < 1e-8
    assert sysm["energy"] == pytest.approx(r.energy, rel=1e-14)


def test_zero_compliance_is_the_rigid_chain_and_the_limit_is_continuous(pace):
    """f = 0 is the dissertation's locked elbow (shared w', u'). As f -> 0 the
    hinge converges linearly in f to a locked elbow whose slope unknowns stay
    split (tangent directions equal, strains free): the same continuum, a
    different discretization, which agrees with the shared one to 7.5e-5 m at 4
    elements per beam, 2.6e-6 at 8 and 2.3e-8 at 16 (docs/theory_fe.md)."""
    load = beamid.TipForce(fy=8.0)
    rigid = beamid.fe_static(pace, load, 4)
    assert_allclose(rigid.outboard["dw"], rigid.nodes["dw"], rtol=0, atol=0)
    # Table 12, 8 elements (4 per beam): unchanged
    assert rigid.tip["w"] == pytest.approx(0.627036, abs=1e-6)
    tips = {}
    for f in (1e-3, 1e-5, 1e-7, 1e-11):
        tips[f] = beamid.fe_static(pace.replace(elbow_flex=f), load, 4).tip["w"]
    gaps = [tips[f] - tips[1e-11] for f in (1e-3, 1e-5, 1e-7)]
    # the hinge's extra deflection is linear in f
    assert gaps[0] > gaps[1] > gaps[2] > 0.0
    assert gaps[1] / gaps[2] == pytest.approx(100.0, rel=2e-3)
    assert tips[1e-11] - rigid.tip["w"] == pytest.approx(7.55e-5, abs=1e-6)
    for n, bound in ((8, 5e-6), (16, 1e-7)):
        limit = beamid.fe_static(pace.replace(elbow_flex=1e-11), load, n).tip["w"]
        assert abs(limit - beamid.fe_static(pace, load, n).tip["w"]) < bound


def test_first_transverse_frequency_and_buckling_load_fall_with_f(pace):
    omegas, loads = [], []
    for f in (0.0, 1e-3, 1e-2, 1e-1):
        model = pace.replace(elbow_flex=f)
        md = beamid.modes(model, 4)
        omegas.append(md.transverse[0])
        loads.append(beamid.buckling_load(model, 4).load)
        # u and w still decouple at the straight chain: one more mode in each family
        assert (md.transverse.size, md.axial.size) == ((17, 18) if f else (16, 17))
    assert omegas[0] == pytest.approx(2.42882, abs=1e-5)
    assert all(a > b for a, b in zip(omegas, omegas[1:]))
    assert all(a > b for a, b in zip(loads, loads[1:]))
    assert omegas[1] == pytest.approx(omegas[0], rel=0.05)
    # a soft elbow: the first mode is mostly the hinge swinging the outboard beam
    md = beamid.modes(pace.replace(elbow_flex=1e-1), 4)
    out = md.shape_outboard(1)
    shape = md.shape(1)
    assert abs(out["dw"][4] - shape["dw"][4]) > 0.3 * np.max(np.abs(shape["dw"]))


def test_dynamics_release_with_a_hinge_conserves_energy():
    """The dynamics builds on the same mesh: with elbow_flex it starts from the
    hinged static shape (two more unknowns) and, without dissipation, keeps
    its energy to the integrator's tolerance."""
    model = beamid.pace(elbow_flex=0.01, J_elbow=0.0, J_tip=0.0)
    run = beamid.simulate(model, beamid.TipForce(fy=8.0), np.linspace(0.0, 0.3, 4),
                          elements_per_beam=2)
    static = beamid.fe_static(model, beamid.TipForce(fy=8.0), 2)
    assert run.nfree == 19
    assert run.tip_w[0] == pytest.approx(static.tip["w"], abs=1e-12)
    assert run.energy[0] == pytest.approx(static.energy, rel=1e-12)
    assert np.max(np.abs(run.energy_change)) < 2e-6
