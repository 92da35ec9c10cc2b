"""The strip thickness of each beam as a model parameter (issue 26): a gauge
reads kappa t/2 (plus the axial strain where the model is extensible) with
t = thick<b> of its beam; d strain / d thick_b = kappa/2 on beam b's gauges
and zero for every other row, in static, release and modal experiments, each
checked against central differences; thickness fitted from gauges and
positions; bad values refused."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

import beamid

PACE_T = 0.00315976
OLD_NAMES = ("L1", "EI1", "EA1", "rho1", "C1", "L2", "EI2", "EA2", "rho2", "C2",
             "m_elbow", "J_elbow", "mu_elbow", "c_elbow", "m_tip", "J_tip", "mu_tip", "c_tip",
             "elbow_flex", "axial_coupling", "root_flex", "eta", "r_motor", "tau_motor")


def _rows(exps, qs, times=(0.0,)):
    return beamid.Measurements.from_rows(
        [(e, t, q, 0.0, 1e-3) for e in exps for t in times for q in qs], source="<test>")


def test_thickness_follows_the_globals_and_defaults_to_pace():
    m = beamid.pace()
    assert m.names()[:24] == OLD_NAMES          # every earlier index kept
    assert m.names()[24:] == ("thick1", "thick2")
    assert m["thick1"] == PACE_T and m["thick2"] == PACE_T
    assert beamid.cantilever().names()[-1] == "thick1"
    assert beamid.cantilever()["thick1"] == PACE_T
    assert beamid.pace(thick2=0.003)["thick2"] == 0.003


@pytest.mark.parametrize("value", [0.0, -0.001, float("nan")])
def test_non_positive_thickness_is_an_input_error(value):
    with pytest.raises(beamid.InputError, match=r"thick2 = .*expected a (positive )?number"):
        beamid.pace(thick2=value)


def test_deck_reads_and_refuses_thickness(tmp_path):
    deck = tmp_path / "d.nml"
    deck.write_text("&beamid task = 'static', output = 'out/d', preset = 'pace' /\n"
                    "&model thick = 0.0030, 0.0032 /\n&load kind = 'tip', fy = 4.0 /\n")
    d = beamid.read_deck(deck)
    assert (d.model["thick1"], d.model["thick2"]) == (0.0030, 0.0032)
    # written back and read again: the same model
    beamid.write_deck(d, tmp_path / "e.nml")
    assert beamid.read_deck(tmp_path / "e.nml").model == d.model
    deck.write_text(deck.read_text().replace("0.0030, 0.0032", "0.0030, -0.002"))
    with pytest.raises(beamid.InputError,
                       match=r"d\.nml: &model: thick2 = -0\.20+E-2, expected a positive number"):
        beamid.read_deck(deck)
    # a deck without a preset gets the PACE thickness
    deck.write_text("&beamid task = 'static', output = 'out/d', nbeams = 1 /\n"
                    "&model l = 0.7, ei = 11.0, ea = 1.0e7, rho = 0.5 /\n"
                    "&load kind = 'tip', fy = 1.0 /\n")
    assert beamid.read_deck(deck).model["thick1"] == PACE_T


def test_gauges_read_their_own_beams_thickness():
    exps = {"M": beamid.TipMoment(3.0)}
    data = _rows(exps, ("strain@1:0.3", "strain@2:0.3", "curvature@1:0.3", "curvature@2:0.3"))
    p0, _ = beamid.estimation.predict(beamid.pace(), exps, data)
    p1, _ = beamid.estimation.predict(beamid.pace(thick1=2 * PACE_T), exps, data)
    assert p1[0] == pytest.approx(2 * p0[0], rel=1e-14)    # kappa t/2, inextensible
    assert p1[0] == pytest.approx(p1[2] * PACE_T, rel=1e-12)
    assert p1[1] == p0[1] and p1[1] == pytest.approx(p1[3] * PACE_T / 2, rel=1e-12)


STATIC = beamid.pace(C1=5.0, C2=3.0, elbow_flex=0.01, thick1=0.0030, thick2=0.0033)
STATIC_EXPS = {"F8": beamid.TipForce(fy=8.0), "W": beamid.RadialWire(1.3),
               "M": beamid.TipMoment(3.0)}
STATIC_QS = ("strain@1:0.05", "strain@2:0.3", "strain@1:0.7", "x@2:0.6", "curvature@1:0.4",
             "moment@1:0.4", "y_tip")


def _central(model, exps, data, name, h):
    yp, _ = beamid.estimation.predict(model.replace(**{name: model[name] + h}), exps, data)
    ym, _ = beamid.estimation.predict(model.replace(**{name: model[name] - h}), exps, data)
    return (yp - ym) / (2 * h)


@pytest.mark.parametrize("name, beam", [("thick1", 1), ("thick2", 2)])
def test_static_strain_thickness_derivative(name, beam):
    data = _rows(STATIC_EXPS, STATIC_QS)
    p, jac = beamid.estimation.predict(STATIC, STATIC_EXPS, data, (name,))
    fd = _central(STATIC, STATIC_EXPS, data, name, 1e-6 * STATIC[name])
    mine = np.array([q.startswith(f"strain@{beam}:") for q in data.quantity])
    assert np.all(jac[~mine, 0] == 0.0) and np.all(fd[~mine] == 0.0)
    assert_allclose(jac[mine, 0], p[mine] / STATIC[name], rtol=1e-12)   # kappa/2
    assert_allclose(jac[:, 0], fd, rtol=1e-7, atol=0)


RELEASE_MODEL = beamid.pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.0, mu_tip=0.0, C1=2.0,
                            thick1=0.0029)
RELEASE = {"free": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=3, rtol=1e-9)}
RELEASE_QS = ("strain@1:0.05", "strain@2:0.2", "curvature@1:0.05", "accel_n@2:0.5", "y_tip")


def test_release_strain_thickness_derivative():
    """The dynamics do not depend on the thickness: the central difference
    is the strain's kappa/2 up to rounding, zero on every other row."""
    data = _rows(RELEASE, RELEASE_QS, times=(0.0, 0.05, 0.2))
    _, jac = beamid.estimation.predict(RELEASE_MODEL, RELEASE, data, ("thick1", "EI1"))
    fd = _central(RELEASE_MODEL, RELEASE, data, "thick1", 1e-5 * RELEASE_MODEL["thick1"])
    q = np.array(data.quantity)
    mine = q == "strain@1:0.05"
    p, _ = beamid.estimation.predict(RELEASE_MODEL, RELEASE, data)
    assert np.all(jac[~mine, 0] == 0.0)
    assert_allclose(jac[mine, 0], p[q == "curvature@1:0.05"] / 2, rtol=1e-12)
    assert_allclose(jac[:, 0], fd, rtol=1e-6, atol=1e-9 * np.max(np.abs(fd)))
    assert np.all(jac[mine, 1] != 0.0)          # the EI1 column is still there


STATIONS = ("shape_n@1:0.4", "shape_strain@1:0.1", "shape_strain@2:0.3")


@pytest.mark.parametrize("name", ["thick1", "thick2"])
def test_modal_shape_strain_thickness_derivative(name):
    model = beamid.pace(thick1=0.0030)
    r = beamid.modal_analysis(model, beamid.TipForce(fy=4.0), nmodes=3, elements_per_beam=2,
                              stations=STATIONS, wrt=(name,))
    assert np.all(r.dfreq == 0.0)
    h = 1e-3 * model[name]
    runs = [beamid.modal_analysis(model.replace(**{name: model[name] + k * h}),
                                  beamid.TipForce(fy=4.0), nmodes=3, elements_per_beam=2,
                                  stations=STATIONS) for k in (-1, 1)]
    for k in (1, 2, 3):
        fd = (runs[1].shape(k) - runs[0].shape(k)) / (2 * h)
        d = r.dshape(k)[:, 0]
        assert_allclose(d, fd, rtol=1e-6, atol=1e-9 * np.max(np.abs(fd)))
        assert np.all(d != 0.0)     # every entry of the unit-normalized shape moves


def test_modal_family_rows_thickness_derivative():
    """Shape rows are unit-normalized together per mode: a thickness moves
    every row of that mode through the norm."""
    model = beamid.pace(thick1=0.0030)
    exps = {"M0": beamid.Modal(None, elements_per_beam=2)}
    qs = ("freq[1]", "shape_n@1:0.4[1]", "shape_strain@1:0.1[1]", "shape_n@2:0.3[1]")
    data = _rows(exps, qs)
    _, jac = beamid.estimation.predict(model, exps, data, ("thick1",))
    fd = _central(model, exps, data, "thick1", 1e-4 * model["thick1"])
    assert jac[0, 0] == 0.0 and np.all(jac[1:, 0] != 0.0)
    assert_allclose(jac[:, 0], fd, rtol=1e-6, atol=1e-9 * np.max(np.abs(fd)))


GAUGE_LOADS = {"F4": beamid.TipForce(fy=4.0), "F8": beamid.TipForce(fy=8.0),
               "M": beamid.TipMoment(3.0)}
GAUGE_SIGMAS = {"strain@1:0.05": 1e-5, "strain@2:0.1": 1e-5, "x_elbow": 1e-3,
                "y_elbow": 1e-3, "x_tip": 1e-3, "y_tip": 1e-3}


def _gauge_data(rig):
    """The rig's gauges and markers under three static loads, made by the
    other formulation (the finite elements' static shape, 16 elements per
    beam, extensible: a release's rows at t = 0) with noise of the sensors'
    sigmas from a fixed seed."""
    fine = {k: beamid.Release(v, elements_per_beam=16) for k, v in GAUGE_LOADS.items()}
    clean = beamid.simulate_measurements(rig, fine, list(GAUGE_SIGMAS), sigma=GAUGE_SIGMAS,
                                         t=[0.0])
    noisy = np.asarray(clean.value) + np.random.default_rng(26).normal(0.0, clean.sigma)
    return beamid.Measurements.from_rows(
        list(zip(clean.experiment, clean.t, clean.quantity, noisy, clean.sigma)),
        source="<gauges>")


def test_fit_recovers_a_thickness_from_gauges_and_markers():
    rig = beamid.pace(thick1=0.0034, thick2=0.0030)
    data = _gauge_data(rig)
    res = beamid.fit(beamid.pace(), GAUGE_LOADS, data, free=("EI1", "EI2", "thick1", "thick2"))
    for name in ("EI1", "EI2", "thick1", "thick2"):
        assert abs(res.estimates[name] - rig[name]) < 3 * res.sigmas[name], name
    # thick1 told apart from the PACE value it started from
    assert abs(res.estimates["thick1"] - PACE_T) > 5 * res.sigmas["thick1"]
    assert res.warnings == ()


def test_thickness_and_a_gauge_scale_are_not_separable():
    """strain = s kappa t/2: a gauge channel's scale s and its beam's
    thickness enter as a product; the fit says so."""
    data = _gauge_data(beamid.pace(thick1=0.0034))
    res = beamid.fit(beamid.pace(), GAUGE_LOADS, data, free=("EI1", "EI2", "thick1"),
                     nuisance={"scale": ["strain@1:0.05"]})
    assert res.sigmas["thick1"] == np.inf
    assert "thick1: not determined by these data" in res.warnings


def test_parameter_names_of_a_long_chain_have_no_buffer_cap():
    """The names come one by one from the core (no text buffer bounds the
    chain: a 8192-character buffer cut it at about 90 beams): a chain of
    MAX_BEAMS beams is named, the thicknesses last."""
    from beamid.model import MAX_BEAMS

    names = beamid._core.param_names(MAX_BEAMS)
    assert len(names) == len(set(names)) > 6 * MAX_BEAMS
    assert names[-1] == f"thick{MAX_BEAMS}" and names[-MAX_BEAMS] == "thick1"
    model = beamid.Model(MAX_BEAMS, np.ones(len(names)))
    assert model.names()[:2] == ("L1", "EI1")
