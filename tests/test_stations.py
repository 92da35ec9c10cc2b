"""Observations at any station (issue 26): x, y, psi, curvature, moment and
gauge strain in static and release experiments, velocities and
accelerations in releases, each with hand-coded sensitivities checked
against central differences."""
from __future__ import annotations

import numpy as np
import pytest

import beamid

STATIC = beamid.pace().replace(C1=5.0, C2=3.0, elbow_flex=0.01)
STATIC_EXPS = {"F8": beamid.TipForce(fy=8.0), "W": beamid.RadialWire(1.3),
               "M": beamid.TipMoment(3.0)}
STATIC_QS = ("x@2:0.6", "y@2:0.6", "psi@2:0.6", "x@1:0.7", "psi@2:0", "curvature@1:0.4",
             "moment@1:0.4", "strain@1:0.05", "y@1:0.3", "curvature@2:0")


def _rows(exps, qs, times=(0.0,)):
    return beamid.Measurements.from_rows(
        [(e, t, q, 0.0, 1e-3) for e in exps for t in times for q in qs], source="<test>")


def test_station_at_the_end_is_the_tip_and_the_elbow():
    qs = ("x_tip", "y_tip", "tip_angle", "x@2:0.714", "y@2:0.714", "psi@2:0.714",
          "x_elbow", "y_elbow", "x@1:0.776", "y@1:0.776", "x@1:0", "y@1:0", "psi@1:0")
    p, _ = beamid.estimation.predict(STATIC, STATIC_EXPS, _rows(STATIC_EXPS, qs))
    p = p.reshape(len(STATIC_EXPS), len(qs))
    np.testing.assert_allclose(p[:, 3:6], p[:, 0:3], atol=1e-9)
    np.testing.assert_allclose(p[:, 8:10], p[:, 6:8], atol=1e-9)
    assert np.all(p[:, 10:] == 0.0)          # the clamp
    # strain = kappa t / 2 on the clockwise side: positive for a counter-clockwise bend
    ps, _ = beamid.estimation.predict(STATIC, {"M": STATIC_EXPS["M"]},
                                      _rows({"M": 0}, ("strain@1:0.3", "curvature@1:0.3",
                                                       "moment@1:0.3")))
    assert ps[1] > 0 and ps[0] == pytest.approx(ps[1] * 0.00315976 / 2, rel=1e-12)
    # a pure tip moment: M = EI k + C k^3 = 3 N m all along the arm
    assert ps[2] == pytest.approx(3.0, rel=1e-7)


@pytest.mark.parametrize("name", ["EI1", "EI2", "C1", "L1", "L2", "elbow_flex"])
def test_static_station_sensitivities(name):
    data = _rows(STATIC_EXPS, STATIC_QS)
    _, jac = beamid.estimation.predict(STATIC, STATIC_EXPS, data, (name,))
    h = 1e-6 * max(abs(STATIC[name]), 1e-2)
    yp, _ = beamid.estimation.predict(STATIC.replace(**{name: STATIC[name] + h}), STATIC_EXPS, data)
    ym, _ = beamid.estimation.predict(STATIC.replace(**{name: STATIC[name] - h}), STATIC_EXPS, data)
    fd = (yp - ym) / (2 * h)
    np.testing.assert_allclose(jac[:, 0], fd, atol=1e-6 * np.max(np.abs(fd)))


RELEASE_MODEL = beamid.pace().replace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.0, mu_tip=0.0,
                                      C1=2.0)
RELEASE = {"free": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=4, rtol=1e-12)}
RELEASE_QS = ("x@2:0.714", "y@2:0.5", "psi@2:0.2", "curvature@1:0.4", "moment@1:0.4",
              "strain@1:0.05", "vel_t@2:0.5", "vel_n@2:0.5", "accel_t@2:0.5", "accel_n@2:0.5")


def test_release_station_values():
    qs = ("x_tip", "y_tip", "tip_angle", "x@2:0.714", "y@2:0.714", "psi@2:0.714",
          "vel_t@2:0.5", "vel_n@2:0.5")
    p, _ = beamid.estimation.predict(RELEASE_MODEL, RELEASE,
                                     _rows(RELEASE, qs, times=(0.0, 0.3)))
    p = p.reshape(2, len(qs))
    np.testing.assert_allclose(p[:, 3:6], p[:, 0:3], rtol=0, atol=1e-12)
    assert np.all(p[0, 6:] == 0.0)           # released at rest
    assert abs(p[1, 7]) > 0.1                # swinging back at 0.3 s


@pytest.mark.parametrize("name, tol", [("EI1", 5e-3), ("rho2", 2e-2)])
def test_release_station_sensitivities(name, tol):
    """Central differences of whole runs at rtol 1e-12 with a small step
    (1e-5 relative): the axial modes make the tangential components vary
    fast, so they get a looser bound."""
    data = _rows(RELEASE, RELEASE_QS, times=(0.0, 0.05, 0.3))
    _, jac = beamid.estimation.predict(RELEASE_MODEL, RELEASE, data, (name,))
    h = 1e-5 * abs(RELEASE_MODEL[name])
    yp, _ = beamid.estimation.predict(RELEASE_MODEL.replace(**{name: RELEASE_MODEL[name] + h}),
                                      RELEASE, data)
    ym, _ = beamid.estimation.predict(RELEASE_MODEL.replace(**{name: RELEASE_MODEL[name] - h}),
                                      RELEASE, data)
    fd = (yp - ym) / (2 * h)
    q = np.array(data.quantity)
    for kind in RELEASE_QS:
        rows = q == kind
        scale = np.max(np.abs(fd[rows])) + 1e-300
        loose = 0.15 if kind.startswith(("vel_t", "accel_t", "strain")) else tol
        err = np.max(np.abs(jac[rows, 0] - fd[rows])) / scale
        assert err < loose, (kind, err)


@pytest.mark.parametrize("q, message", [
    ("x@3:0.1", "beam 3 does not exist, expected 1..2"),
    ("x@2:0.9", "station s = 0.9 is beyond beam 2, expected 0 <= s <= 0.714"),
    ("strain@1:-0.1", "arc length s = -0.1"),
    ("x@a:0.1", 'beam "a"'),
    ("strian@1:0.1", "expected one of"),
])
def test_bad_stations_name_the_row(q, message):
    data = beamid.Measurements.from_rows([("free", 0.1, "y_tip", 0.0, 1e-3)], source="d.csv") \
        if q.startswith(("strian", "x@a", "strain@1:-")) else \
        beamid.Measurements.from_rows([("free", 0.1, q, 0.0, 1e-3)], source="d.csv")
    with pytest.raises(beamid.InputError, match=message.replace("(", r"\(")):
        if q.startswith(("strian", "x@a", "strain@1:-")):
            beamid.Measurements.from_rows([("free", 0.1, q, 0.0, 1e-3)], source="d.csv")
        else:
            beamid.estimation.predict(RELEASE_MODEL, RELEASE, data)


def test_acceleration_of_a_static_experiment_is_refused():
    data = beamid.Measurements.from_rows([("F8", 0.0, "accel_n@2:0.5", 0.0, 1e-2)],
                                         source="d.csv")
    with pytest.raises(beamid.InputError, match="d.csv, row 1: field quantity = "
                       "'accel_n@2:0.5', but experiment 'F8' is static"):
        beamid.estimation.predict(STATIC, STATIC_EXPS, data)


def test_encoders_read_the_joint_rotations():
    """elbow_rotation and root_rotation: zero at a locked joint, the
    compliance times the moment at a compliant one (static and release
    alike), with sensitivities against central differences."""
    qs = ("elbow_rotation", "root_rotation", "psi@1:0", "moment@1:0")
    exps = {"F8": beamid.TipForce(fy=8.0),
            "free": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=4, rtol=1e-12)}
    rows = [("F8", 0.0, q, 0.0, 1e-3) for q in qs] + \
        [("free", t, q, 0.0, 1e-3) for t in (0.0, 0.2) for q in qs]
    data = beamid.Measurements.from_rows(rows, source="<test>")
    locked, _ = beamid.estimation.predict(beamid.pace(), exps, data)
    assert np.all(locked.reshape(3, 4)[:, :3] == 0.0)
    model = beamid.pace().replace(elbow_flex=0.02, root_flex=0.02, C1=2.0)
    wrt = ("EI1", "elbow_flex", "root_flex")
    p, jac = beamid.estimation.predict(model, exps, data, wrt)
    p = p.reshape(3, 4)
    np.testing.assert_allclose(p[:, 1], p[:, 2], rtol=0, atol=1e-14)   # psi at the clamp
    assert p[0, 1] == pytest.approx(0.02 * p[0, 3], rel=1e-9)          # f_root M(0), static
    assert p[0, 0] == pytest.approx(0.08056, abs=1e-5)                 # f M(L1), static
    np.testing.assert_allclose(p[1, :2], p[0, :2], rtol=1e-3)          # the FE at t = 0
    for j, name in enumerate(wrt):
        h = 1e-6 * max(abs(model[name]), 1e-2)
        yp, _ = beamid.estimation.predict(model.replace(**{name: model[name] + h}), exps, data)
        ym, _ = beamid.estimation.predict(model.replace(**{name: model[name] - h}), exps, data)
        fd = (yp - ym) / (2 * h)
        np.testing.assert_allclose(jac[:, j], fd, atol=1e-4 * np.max(np.abs(fd)), err_msg=name)


def test_elbow_encoder_needs_an_elbow():
    one = beamid.cantilever()
    data = beamid.Measurements.from_rows([("F", 0.0, "elbow_rotation", 0.0, 1e-3)],
                                         source="d.csv")
    with pytest.raises(beamid.InputError, match="has no elbow"):
        beamid.estimation.predict(one, {"F": beamid.TipForce(fy=1.0)}, data)


LOAD_CELL = ("reaction_x", "reaction_y", "reaction_moment")


def test_load_cell_balances_the_tip_load():
    """The clamp's reaction on the arm: minus the tip force, and minus the
    moment of the load about the clamp (static, and the FE at t = 0 before
    the release)."""
    model = beamid.pace().replace(C1=2.0)
    exps = {"F": beamid.TipForce(fx=-2.0, fy=8.0), "M": beamid.TipMoment(3.0),
            "free": beamid.Release(beamid.TipForce(fx=-2.0, fy=8.0), elements_per_beam=8,
                                   rtol=1e-10)}
    rows = [(e, 0.0, q, 0.0, 1e-2) for e in exps for q in LOAD_CELL + ("x_tip", "y_tip")]
    p, _ = beamid.estimation.predict(model, exps, beamid.Measurements.from_rows(rows))
    p = p.reshape(3, 5)
    for k in (0, 2):
        rx, ry, rm, x, y = p[k]
        assert rx == pytest.approx(2.0, rel=1e-6) and ry == pytest.approx(-8.0, rel=1e-6)
        # moment of the tip force (-2, 8) at the tip (x, y) about the clamp, opposed
        assert rm == pytest.approx(-(x * 8.0 - y * -2.0), rel=1e-3 if k else 1e-7)
    np.testing.assert_allclose(p[1, :3], [0.0, 0.0, -3.0], atol=1e-9)


def test_load_cell_after_the_release_is_the_arm_s_momentum_rate():
    """After the release no force acts on the arm but the clamp's: the
    reaction swings with the arm and changes sign with the tip's motion."""
    model = RELEASE_MODEL
    data = _rows(RELEASE, LOAD_CELL, times=(0.0, 0.02, 0.3))
    p, _ = beamid.estimation.predict(model, RELEASE, data)
    p = p.reshape(3, 3)
    assert p[0, 1] == pytest.approx(-8.0, rel=1e-6)
    assert abs(p[1, 1] - p[0, 1]) > 1.0        # the inertia takes over at once
    assert np.all(np.isfinite(p))


@pytest.mark.parametrize("name", ["EI1", "C1", "L1", "elbow_flex", "root_flex"])
def test_static_load_cell_sensitivities(name):
    model = STATIC.replace(root_flex=0.01)
    data = _rows(STATIC_EXPS, LOAD_CELL)
    _, jac = beamid.estimation.predict(model, STATIC_EXPS, data, (name,))
    h = 1e-6 * max(abs(model[name]), 1e-2)
    yp, _ = beamid.estimation.predict(model.replace(**{name: model[name] + h}), STATIC_EXPS, data)
    ym, _ = beamid.estimation.predict(model.replace(**{name: model[name] - h}), STATIC_EXPS, data)
    fd = (yp - ym) / (2 * h)
    np.testing.assert_allclose(jac[:, 0], fd, atol=1e-6 * max(np.max(np.abs(fd)), 1e-3))


@pytest.mark.parametrize("name", ["EI1", "EA1", "rho1", "rho2", "C1", "eta", "root_flex"])
def test_release_load_cell_sensitivities(name):
    """Hand-coded columns of the load cell in a release (inertia, internal
    force and structural damping of the first element) against central
    differences of whole runs (step 1e-4 relative: at 1e-5 and below the
    integrator's error, through the fast axial modes, swamps the difference
    quotient of reaction_x; the axial component gets a looser bound)."""
    model = RELEASE_MODEL.replace(eta=2e-3, root_flex=0.01)
    data = _rows(RELEASE, LOAD_CELL, times=(0.0, 0.05, 0.3))
    _, jac = beamid.estimation.predict(model, RELEASE, data, (name,))
    h = 1e-4 * abs(model[name])
    yp, _ = beamid.estimation.predict(model.replace(**{name: model[name] + h}), RELEASE, data)
    ym, _ = beamid.estimation.predict(model.replace(**{name: model[name] - h}), RELEASE, data)
    fd = (yp - ym) / (2 * h)
    q = np.array(data.quantity)
    for kind in LOAD_CELL:
        rows = q == kind
        scale = np.max(np.abs(fd[rows])) + 1e-12
        err = np.max(np.abs(jac[rows, 0] - fd[rows])) / scale
        assert err < (5e-2 if kind == "reaction_x" else 3e-2), (kind, err)


def test_simulated_static_station_rows():
    """simulate_measurements of static experiments takes station observations
    (they were refused: 'unknown quantity'): a gauge reads kappa t/2 of the
    same station's curvature, and the tip rows are those of the arc-length
    solution read by name."""
    m = beamid.pace()
    exps = {"F": beamid.TipForce(fy=3.0)}
    d = beamid.simulate_measurements(m, exps, ["x_tip", "strain@1:0.05", "curvature@1:0.05"],
                                     sigma=1e-6)
    plain = beamid.simulate_measurements(m, exps, ["x_tip"], sigma=1e-6)
    x, strain, kappa = d.value
    assert x == pytest.approx(plain.value[0], rel=1e-12, abs=0.0)
    assert strain == pytest.approx(0.5 * m.vector()[m.names().index("thick1")] * kappa,
                                   rel=1e-12)
    assert kappa > 0.0
