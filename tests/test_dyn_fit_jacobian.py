"""How the fit uses the Jacobian (docs/workflow.md, "How the fit uses the
Jacobian"): releases on the implicit integrator steer Gauss-Newton with
sensitivities integrated at rtol 1e-6 and confirm the end point with the
accurate ones; ``jacobian="exact"`` uses the accurate ones throughout.

The Table 16 data (inputs/seed/table16_data.csv) were simulated at a finer
tolerance with noise of the stated sigmas from a fixed seed.
"""
from __future__ import annotations

import numpy as np
import pytest

import beamid
from beamid.estimation import predict
from beamid.fit_decks import read_fit_deck
from beamid.tables import inputs_dir

FREE = ("mu_elbow", "mu_tip", "rho1", "rho2")


@pytest.fixture(scope="module")
def table16():
    deck = read_fit_deck(inputs_dir("seed") / "table16_fit.nml")
    exps = dict(deck.experiments)
    rough = beamid.fit(deck.model, exps, deck.data, free=FREE)
    exact = beamid.fit(deck.model, exps, deck.data, free=FREE, jacobian="exact")
    return deck, exps, rough, exact


def test_rough_steering_reaches_the_accurate_fits_estimates(table16):
    _, _, rough, exact = table16
    assert rough.stop == "converged" and exact.stop == "converged"
    for name in FREE:
        # within the fit's own convergence tolerance (the noise floor: every
        # parameter within 0.1 sigma of the linearized minimum)
        assert abs(rough.estimates[name] - exact.estimates[name]) < 0.1 * exact.sigmas[name], name
    assert abs(rough.chi2 - exact.chi2) < 0.02


def test_covariance_is_the_accurate_jacobians_at_the_final_point(table16):
    deck, exps, rough, _ = table16
    # predictions and Jacobian at the user's tolerance, at the estimates
    pred, jac = predict(rough.model, exps, deck.data, wrt=FREE)
    sigma = np.asarray(deck.data.sigma)
    np.testing.assert_allclose([r.model for r in rough.residuals], pred, rtol=0, atol=1e-14)
    a = jac / sigma[:, None]
    cov = np.linalg.inv(a.T @ a)
    np.testing.assert_allclose([rough.sigmas[n] for n in FREE], np.sqrt(np.diag(cov)),
                               rtol=1e-6)
    np.testing.assert_allclose(rough.cov, cov, rtol=1e-6, atol=1e-12 * np.max(np.abs(cov)))


def test_static_fit_is_the_same_either_way():
    model = beamid.pace().replace(EI1=10.0, EI2=12.0)
    exps = {"F3": beamid.TipForce(fy=3.0), "F8": beamid.TipForce(fy=8.0)}
    data = beamid.simulate_measurements(beamid.pace(), exps, ["x_tip", "y_tip"], sigma=1e-4,
                                        seed=5, noise=True)
    a = beamid.fit(model, exps, data, free=("EI1", "EI2"))
    b = beamid.fit(model, exps, data, free=("EI1", "EI2"), jacobian="exact")
    assert a.iterations == b.iterations
    assert [a.estimates[n] for n in ("EI1", "EI2")] == [b.estimates[n] for n in ("EI1", "EI2")]
    assert np.array_equal(a.cov, b.cov)


def test_mixed_static_and_dynamic_fit_steers_its_release_too():
    truth = beamid.pace().replace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)
    rel = beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=4)
    fine = beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=4, rtol=1e-11)
    exps = {"F3": beamid.TipForce(fy=3.0), "free": rel}
    data = beamid.simulate_measurements(truth, {"F3": exps["F3"]}, ["y_tip"], sigma=1e-4,
                                        seed=21, noise=True).merge(
        beamid.simulate_measurements(truth, {"free": fine}, ["w_tip", "u_tip"], sigma=1e-4,
                                     t=[0.3, 0.6, 0.9], seed=22, noise=True))
    start = truth.replace(EI1=10.8, mu_tip=0.015, rho2=0.55)
    free = ("EI1", "mu_tip", "rho2")
    rough = beamid.fit(start, exps, data, free=free)
    exact = beamid.fit(start, exps, data, free=free, jacobian="exact")
    assert rough.converged and exact.converged
    for name in free:
        assert abs(rough.estimates[name] - exact.estimates[name]) < 0.1 * exact.sigmas[name]
        assert rough.sigmas[name] == pytest.approx(exact.sigmas[name], rel=0.02)
    _, jac = predict(rough.model, exps, data, wrt=free)
    a = jac / np.asarray(data.sigma)[:, None]
    np.testing.assert_allclose([rough.sigmas[n] for n in free],
                               np.sqrt(np.diag(np.linalg.inv(a.T @ a))), rtol=1e-6)


def test_unknown_jacobian_mode_is_bad_input():
    deck = read_fit_deck(inputs_dir("seed") / "table16_fit.nml")
    with pytest.raises(beamid.InputError, match="jacobian = 'fd'"):
        beamid.fit(deck.model, dict(deck.experiments), deck.data, free=FREE, jacobian="fd")
