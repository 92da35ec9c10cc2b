"""Compare on time histories (issue 14): measured against model over time,
chi-square against its expectation and the tests for structure in time
(runs, lag-1 autocorrelation, residual-amplitude trend) computed in Fortran
(beamid_dyn_diagnosis time_structure), and the PNG figure."""
from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest

import beamid
from beamid import _core_estimation as _core_dyndiag

SIGMA = 1e-4
TIMES = [round(0.1 * k, 3) for k in range(1, 14)]
BASE = beamid.pace().replace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.0, mu_tip=0.0)


def _fit(truth, seed=3):
    fine = {"free": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=2, rtol=1e-11)}
    exact = beamid.simulate_measurements(truth, fine, ["u_tip", "w_tip"], sigma=SIGMA, t=TIMES)
    rng = np.random.default_rng(seed)
    data = exact.with_values(np.asarray(exact.value) + SIGMA * rng.standard_normal(len(exact)))
    exps = {"free": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=2)}
    return beamid.fit(BASE, exps, data, free=("rho2",))


def test_time_structure_exact_values():
    """Two runs of three: runs 2 (expected 4), lag-1 autocorrelation 1/2
    about the mean 0, no amplitude trend; rows in any time order."""
    t = np.array([5.0, 0.0, 1.0, 2.0, 3.0, 4.0])
    r = np.array([-1.0, 1.0, 1.0, 1.0, -1.0, -1.0])
    out = _core_dyndiag.time_structure(t, r)
    var = 2 * 9 * (18 - 6) / (36 * 5)
    assert out[0] == 2 and out[1] == pytest.approx(4.0)
    assert out[2] == pytest.approx((2 - 4) / math.sqrt(var))
    assert out[4] == pytest.approx(0.5) and out[5] == pytest.approx(0.5 * math.sqrt(6))
    assert out[7] == pytest.approx(0.0, abs=1e-15) and out[9] == pytest.approx(1.0)
    # a growing amplitude: slope of |r| per second, z with var(|r|) = 1 - 2/pi
    grow = _core_dyndiag.time_structure(np.arange(4.0), np.array([1.0, -2.0, 3.0, -4.0]))
    assert grow[7] == pytest.approx(1.0)
    assert grow[8] == pytest.approx(math.sqrt(5.0) / math.sqrt(1 - 2 / math.pi))
    assert grow[4] < 0     # alternating signs: negative autocorrelation
    assert all(math.isnan(v) for v in _core_dyndiag.time_structure(np.arange(2.0), np.ones(2)))


def test_missing_damping_leaves_structure_in_time(tmp_path):
    cmp = beamid.compare(_fit(BASE.replace(eta=1e-3)))
    assert isinstance(cmp, beamid.TimeComparison) and len(cmp) == 2
    w = cmp["free", "w_tip"]
    assert w.unit == "m" and list(w.t) == TIMES
    np.testing.assert_allclose(w.normalized, (w.measured - w.model) / w.sigma)
    assert w.chi2 == pytest.approx(float(np.sum(w.normalized ** 2)))
    assert cmp.systematic and cmp.p_value < 1e-10
    # damping missing: the misfit grows with time
    assert w.amplitude_slope > 0 and w.amplitude_p < 1e-6
    assert w.autocorrelation > 0.3
    assert "systematic structure in time" in str(cmp)
    fig = cmp.plot(tmp_path / "cmp.png")
    assert (tmp_path / "cmp.png").stat().st_size > 10_000
    axes = fig.axes
    assert len(axes) == 4      # per quantity: history over residuals
    tops = [a for a in axes if a.get_ylabel().endswith("(m)")]
    assert len(tops) == 2
    for ax in axes:            # every line in the legend
        labels = [t.get_text() for t in ax.get_legend().get_texts()]
        assert len(labels) >= 2 and all(labels)
    top = tops[0]
    assert {"model", "measured +- sigma"} <= {t.get_text() for t in top.get_legend().get_texts()}


def test_noise_only_is_not_systematic():
    cmp = beamid.compare(_fit(BASE))
    assert not cmp.systematic
    assert cmp.chi2 == pytest.approx(cmp.fit.chi2)
    assert abs(cmp.chi2 - cmp.expected) < 3 * cmp.expected_sigma
    for s in cmp.series:
        assert s.runs_p > 0.001 and s.autocorrelation_p > 0.001
