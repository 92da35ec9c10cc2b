"""Arc-length static solver (Chapter III): published values, exact solutions,
hand-coded sensitivities against central differences, and bad input."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

import beamid
from beamid.tables import check_deck, seed_decks

SEED = 0.0   # shear-only form of Eq. 9 (Tables 2-5)
EXACT = 1.0  # Kirchhoff elastica


# ------------------------------------------------------------------ published

STATIC_DECKS = [d for d in seed_decks() if d.task == "static"]


@pytest.mark.parametrize("deck", STATIC_DECKS, ids=lambda d: d.path.stem)
def test_seed_decks_reproduce_published_values(deck):
    for check in check_deck(deck):
        if check.deviation:
            continue
        assert check.ok, (f"Table {check.table} {check.row} {check.quantity}: published "
                          f"{check.published}, ours {check.ours}")


def test_table2_rows_at_published_digits():
    expected = {0: (33.3, 0.506, 1.197), 1: (37.6, 0.573, 1.167), 5: (53.3, 0.643, 1.130),
                10: (72.1, 0.668, 1.115), 20: (109.3, 0.686, 1.104)}
    for c, (force, x, y) in expected.items():
        r = beamid.solve_static(beamid.pace(axial_coupling=SEED, C1=c, C2=c),
                                beamid.RadialWire(1.3))
        assert round(r.wire_force, 1) == force
        assert round(r.tip_x, 3) == x
        assert round(r.tip_y, 3) == y


def test_table2_last_force_is_a_pinned_deviation():
    # Table 2 prints 145.3 N for C = 30; the model gives 146.3 N (docs/deviations.md).
    r = beamid.solve_static(beamid.pace(axial_coupling=SEED, C1=30.0, C2=30.0),
                            beamid.RadialWire(1.3))
    assert round(r.wire_force, 1) == 146.3
    assert (round(r.tip_x, 3), round(r.tip_y, 3)) == (0.693, 1.100)


def test_directed_force_range_of_section_3_2_2():
    y3 = beamid.solve_static(beamid.pace(axial_coupling=SEED), beamid.TipForce(fy=3.0)).tip_y
    y8 = beamid.solve_static(beamid.pace(axial_coupling=SEED), beamid.TipForce(fy=8.0)).tip_y
    assert abs(y3 - 0.276332) <= 1e-6
    assert abs(y8 - 0.597325) <= 1e-6


def test_exact_form_matches_table12_32_element_row():
    r = beamid.solve_static(beamid.pace(axial_coupling=EXACT), beamid.TipForce(fy=8.0))
    got = [r.tip_y, math.sin(r.tip_angle), r.tip_x - 1.49, math.cos(r.tip_angle) - 1.0]
    assert_allclose(got, [0.628433, 0.612040, -0.170106, -0.209172], atol=1e-6)


def test_seed_form_is_five_percent_short_of_the_exact_form_at_8N():
    seed = beamid.solve_static(beamid.pace(axial_coupling=SEED), beamid.TipForce(fy=8.0))
    exact = beamid.solve_static(beamid.pace(axial_coupling=EXACT), beamid.TipForce(fy=8.0))
    assert_allclose(exact.tip_y / seed.tip_y - 1.0, 0.0521, atol=5e-4)


# ---------------------------------------------------------- exact solutions

def _circle_tip(m: float, ei=(11.413, 11.275), lengths=(0.776, 0.714)):
    x = y = psi = 0.0
    for e, length in zip(ei, lengths):
        k = m / e
        x += (math.sin(psi + k * length) - math.sin(psi)) / k
        y += (math.cos(psi) - math.cos(psi + k * length)) / k
        psi += k * length
    return x, y, psi


@pytest.mark.parametrize("moment", [1.0, 18.0, 45.0, 60.0])
@pytest.mark.parametrize("a", [SEED, 0.5, EXACT])
def test_pure_tip_moment_gives_the_circle(moment, a):
    # 60 N m rolls the arm through more than one and a half turns.
    r = beamid.solve_static(beamid.pace(axial_coupling=a), beamid.TipMoment(moment))
    x, y, psi = _circle_tip(moment)
    assert_allclose([r.tip_x, r.tip_y, r.tip_angle], [x, y, psi], atol=1e-8)
    shape = r.shape(n=51)
    assert_allclose(shape.moment, moment, rtol=1e-9)


def test_tip_moment_with_cubic_law_has_constant_curvature():
    # M = EI k + C k^3 (Eq. 16) with constant M: k solves the cubic on each beam.
    m, c1, c2 = 10.0, 5.0, 20.0
    r = beamid.solve_static(beamid.pace(C1=c1, C2=c2), beamid.TipMoment(m))
    k1 = np.roots([c1, 0.0, 11.413, -m]).real.max()
    k2 = np.roots([c2, 0.0, 11.275, -m]).real.max()
    assert_allclose(r.tip_angle, k1 * 0.776 + k2 * 0.714, rtol=1e-9)


@pytest.mark.parametrize("fx,fy,mt", [(0.0, 8.0, 0.0), (-3.0, 5.0, 2.0), (4.0, -6.0, -1.0)])
def test_exact_form_root_moment_balances_the_tip_load(fx, fy, mt):
    # Exact elastica: the internal force is constant, so the root moment is the
    # moment of the tip load about the root.
    r = beamid.solve_static(beamid.pace(C1=3.0, elbow_flex=0.01),
                            beamid.TipForce(fx, fy) + beamid.TipMoment(mt))
    assert_allclose(r.root_moment, r.tip_x * fy - r.tip_y * fx + mt, rtol=1e-7, atol=1e-9)


def test_exact_form_wire_carries_no_root_moment():
    r = beamid.solve_static(beamid.pace(), beamid.RadialWire(1.3))
    assert abs(r.root_moment) < 1e-8 * r.wire_force
    assert_allclose(math.hypot(r.tip_x, r.tip_y), 1.3, rtol=1e-12)
    assert abs(r.shape(n=11).moment[-1]) < 1e-8


def test_seed_form_moment_is_linear_in_arc_length():
    # dQ/ds = 0 (Eq. 9): M(s) = Q (L - s) under a wire (zero tip moment, Eq. 23).
    r = beamid.solve_static(beamid.pace(axial_coupling=SEED, C1=5.0), beamid.RadialWire(1.2))
    shape = r.shape(n=41)
    assert_allclose(shape.moment, r.root_moment * (1.0 - shape.s / 1.49), atol=1e-8)


@pytest.mark.parametrize("a", [SEED, EXACT])
def test_small_load_approaches_linear_cantilever_theory(a):
    # Eq. 111 with the missing 1/6: y = F L^3 / (3 EI) at the tip; the relative
    # error of the nonlinear solution falls like F^2.
    cant = beamid.cantilever(L=0.776, EI=11.413)
    errors = []
    for f in (0.01, 0.02, 0.04):
        r = beamid.solve_static(cant.replace(axial_coupling=a), beamid.TipForce(fy=f))
        linear = f * 0.776**3 / (3.0 * 11.413)
        errors.append(abs(r.tip_y / linear - 1.0))
    orders = np.log2(np.array(errors[1:]) / np.array(errors[:-1]))
    assert_allclose(orders, 2.0, atol=0.05)


def test_exact_form_is_conservative_maxwell_betti():
    # d(y_tip)/d(fx) = d(x_tip)/d(fy) for a conservative fixed-direction load.
    model, h = beamid.pace(C1=2.0), 1e-4

    def tip(fx, fy):
        r = beamid.solve_static(model, beamid.TipForce(fx, fy))
        return np.array([r.tip_x, r.tip_y])

    fx, fy = 1.0, 4.0
    dx = (tip(fx + h, fy) - tip(fx - h, fy)) / (2 * h)
    dy = (tip(fx, fy + h) - tip(fx, fy - h)) / (2 * h)
    assert_allclose(dx[1], dy[0], rtol=1e-6)


def test_shape_ends_at_the_tip_and_joint():
    r = beamid.solve_static(beamid.pace(elbow_flex=0.02), beamid.TipForce(fy=5.0))
    shape = r.shape(s=[0.0, 0.776, 1.49])
    assert_allclose([shape.x[0], shape.y[0], shape.psi[0]], 0.0, atol=1e-15)
    assert_allclose([shape.x[1], shape.y[1]], [r.elbow_x, r.elbow_y], atol=1e-12)
    assert_allclose([shape.x[2], shape.y[2], shape.psi[2]], [r.tip_x, r.tip_y, r.tip_angle],
                    atol=1e-12)


def test_elbow_flex_kinks_the_slope_by_flex_times_moment():
    f = 0.05
    r = beamid.solve_static(beamid.pace(elbow_flex=f), beamid.TipMoment(3.0))
    assert_allclose(r.tip_angle, 3.0 / 11.413 * 0.776 + f * 3.0 + 3.0 / 11.275 * 0.714,
                    rtol=1e-10)
    r = beamid.solve_static(beamid.pace(root_flex=f), beamid.TipMoment(3.0))
    assert_allclose(r.tip_angle, f * 3.0 + 3.0 / 11.413 * 0.776 + 3.0 / 11.275 * 0.714,
                    rtol=1e-10)


# ------------------------------------------------------------ wide range

@pytest.mark.parametrize("a", [SEED, EXACT])
@pytest.mark.parametrize("fraction", [0.98, 0.7, 0.42])
def test_wire_converges_over_the_claimed_range(a, fraction):
    # Section 3.1.5: wire lengths from 98 % down to 42 % of the arm.
    lw = fraction * 1.49
    r = beamid.solve_static(beamid.pace(axial_coupling=a), beamid.RadialWire(lw))
    assert r.wire_force > 0.0
    assert_allclose(math.hypot(r.tip_x, r.tip_y), lw, rtol=1e-8)


def test_large_force_needs_and_gets_continuation():
    r = beamid.solve_static(beamid.pace(axial_coupling=SEED), beamid.TipForce(fy=50.0)
                            + beamid.TipMoment(5.0))
    assert r.load_steps > 1
    direct = beamid.solve_static(beamid.pace(axial_coupling=SEED), beamid.TipForce(fy=50.0)
                                 + beamid.TipMoment(5.0), tol=1e-12)
    assert_allclose([r.tip_x, r.tip_y], [direct.tip_x, direct.tip_y], atol=1e-8)


def test_tolerance_controls_the_error():
    ref = beamid.solve_static(beamid.pace(), beamid.RadialWire(1.0), tol=1e-13)
    errs = [abs(beamid.solve_static(beamid.pace(), beamid.RadialWire(1.0), tol=t).tip_x
                - ref.tip_x) for t in (1e-5, 1e-7, 1e-9)]
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 1e-8


# -------------------------------------------------------------- sensitivities

PARAMS = ("L1", "EI1", "C1", "L2", "EI2", "C2", "elbow_flex", "root_flex", "axial_coupling")
LOADS = {"tip": beamid.TipForce(fx=-2.0, fy=7.0) + beamid.TipMoment(1.0),
         "wire": beamid.RadialWire(1.2)}


@pytest.mark.parametrize("load", LOADS.values(), ids=LOADS.keys())
def test_sensitivities_match_central_differences(load):
    base = beamid.pace(C1=3.0, C2=7.0, elbow_flex=0.01, root_flex=0.02, axial_coupling=0.5)
    r = beamid.solve_static(base, load, wrt=PARAMS, tol=1e-12)
    for p in PARAMS:
        h = 1e-5 * max(abs(base[p]), 0.01)
        plus = beamid.solve_static(base.replace(**{p: base[p] + h}), load, tol=1e-12)
        minus = beamid.solve_static(base.replace(**{p: base[p] - h}), load, tol=1e-12)
        for name, value in plus.outputs.items():
            if math.isnan(value):
                continue
            fd = (value - minus.outputs[name]) / (2 * h)
            # scale: the output's magnitude per unit relative change of the parameter
            scale = max(abs(fd), 1e-3 * max(abs(value), 1e-3) / max(abs(base[p]), 0.01))
            assert abs(r.d[name][p] - fd) <= 1e-6 * scale + 1e-9, (p, name, r.d[name][p], fd)


def test_sensitivity_aliases_and_seed_example():
    m = beamid.pace(axial_coupling=0.0, C1=5.0, C2=20.0)
    r = beamid.solve_static(m, beamid.RadialWire(1.3), wrt=("EI1", "C2"))
    assert r.d["y_tip"] is r.d["tip_y"]
    assert set(r.d["tip_y"]) == {"EI1", "C2"}
    assert math.isnan(beamid.solve_static(m, beamid.TipForce(fy=1.0)).wire_force)


# ---------------------------------------------------------------- bad input

@pytest.mark.parametrize("name,value", [("L1", -0.5), ("EI2", 0.0), ("EA1", -1.0),
                                        ("rho2", 0.0), ("C1", float("nan")),
                                        ("EI1", float("inf")), ("m_tip", -1.0),
                                        ("elbow_flex", -0.1), ("axial_coupling", 1.5)])
def test_nonphysical_parameters_raise_input_error(name, value):
    with pytest.raises(beamid.InputError, match=name):
        beamid.pace(**{name: value})


def test_unknown_parameter_name_is_named():
    with pytest.raises(beamid.InputError, match="EI3.*did you mean"):
        beamid.pace(EI3=1.0)
    with pytest.raises(beamid.InputError, match="unknown parameter name 'Ei1'"):
        beamid.solve_static(beamid.pace(), beamid.TipForce(fy=1.0), wrt=("Ei1",))


def test_joint1_aliases_the_elbow():
    assert beamid.pace(m_joint1=2.0)["m_elbow"] == 2.0
    assert beamid.pace(joint1_flex=0.1)["elbow_flex"] == 0.1


@pytest.mark.parametrize("lw,match", [(1.49, "not shorter than the arm"),
                                      (2.0, "not shorter than the arm"),
                                      (0.05, "too short to reach")])
def test_wire_length_checked(lw, match):
    with pytest.raises(beamid.InputError, match=match):
        beamid.solve_static(beamid.pace(), beamid.RadialWire(lw))


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -1.0, 0.0])
def test_bad_wire_and_force_values(bad):
    with pytest.raises(beamid.InputError):
        beamid.RadialWire(bad)
    if bad != bad or abs(bad) == float("inf"):
        with pytest.raises(beamid.InputError, match="fy"):
            beamid.TipForce(fy=bad)


def test_compressed_wire_is_a_convergence_error_naming_the_load():
    with pytest.raises(beamid.ConvergenceError, match="Lw = 0.2"):
        beamid.solve_static(beamid.pace(axial_coupling=EXACT), beamid.RadialWire(0.298))


def test_bad_tolerance_and_shape_requests():
    with pytest.raises(beamid.InputError, match="tol"):
        beamid.solve_static(beamid.pace(), beamid.TipForce(fy=1.0), tol=0.5)
    r = beamid.solve_static(beamid.pace(), beamid.TipForce(fy=1.0))
    with pytest.raises(beamid.InputError, match="ascend"):
        r.shape(s=[0.5, 0.1])
    with pytest.raises(beamid.InputError, match="at least 2"):
        r.shape(n=1)


def test_model_api():
    m = beamid.pace(axial_coupling=0.0, C1=5.0, C2=20.0)
    p = m.params
    assert (p["EI1"], p["C2"], p["axial_coupling"]) == (11.413, 20.0, 0.0)
    assert_allclose(p["EA1"], 1.37174e7, rtol=1e-5)
    assert (p["m_elbow"], p["J_tip"]) == (4.280, 15.244e-4)
    assert m.total_length == pytest.approx(1.49)
    c = beamid.cantilever(L=1.0, EI=2.0)
    assert (c.nbeams, c["L1"], c["EI1"], c["C1"]) == (1, 1.0, 2.0, 0.0)
    assert_allclose(c["EA1"], 12 * 2.0 / 0.00315976**2)
    r = beamid.solve_static(c, beamid.TipForce(fy=0.001))
    assert math.isnan(r.elbow_x)


def test_static_result_keeps_its_constructor_keywords():
    """StaticResult (public, in beamid.__all__) takes outputs= and doutputs=
    as before it became a slotted dataclass (whose fields are private)."""
    model = beamid.pace()
    solved = beamid.solve_static(model, beamid.TipForce(0.0, 3.0), wrt=("EI1",))
    made = beamid.StaticResult(model=model, load=solved.load, wrt=solved.wrt,
                               outputs=solved._outputs, doutputs=solved._doutputs,
                               unknowns=solved.unknowns, newton_iterations=2, load_steps=1,
                               tol=solved.tol)
    assert np.array_equal(list(made.outputs.values()), list(solved.outputs.values()),
                          equal_nan=True)
    assert made.d["tip_y"] == solved.d["tip_y"]
    assert (made.newton_iterations, made.load_steps, made.tol) == (2, 1, solved.tol)
    assert made.shape(5).x.tolist() == solved.shape(5).x.tolist()
    with pytest.raises(TypeError, match="_outputs"):
        beamid.StaticResult(model, solved.load, (), _outputs=solved._outputs)
