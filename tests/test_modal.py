"""Modal analysis about a static equilibrium (issue 27, beamid.modal): the
straight arm reproduces Tables 9-10, the sensitivities match five-point
central differences (the Fortran test tests/fortran/test_modal.f90 covers
every effect; here the Python path and the normalized shapes), damping,
refusals, MAC and mode pairing."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

import beamid

TWO_PI = 2 * np.pi
# Table 9 (transverse) and Table 10 (axial), rad/s, 8 elements (4 per beam)
TABLE_9_8 = [2.42882, 11.0030, 102.710, 163.049, 373.378, 472.479]
TABLE_10_8 = [1705.61, 4732.07, 20952.8, 23665.4, 41691.0]


@pytest.fixture(scope="module")
def straight():
    return beamid.modal_analysis(beamid.pace(J_elbow=0.0, J_tip=0.0), nmodes=33,
                                 elements_per_beam=4)


def test_straight_arm_reproduces_tables_9_and_10(straight):
    omega = straight.freq * TWO_PI
    md = beamid.modes(beamid.pace(), 4)
    assert_allclose(omega, md.omega, rtol=1e-9)
    transverse = omega[~md.is_axial]
    axial = omega[md.is_axial]
    for value, printed in zip(transverse, TABLE_9_8):
        assert float(f"{value:.6g}") == printed
    for value, printed in zip(axial, TABLE_10_8):
        assert float(f"{value:.6g}") == printed
    assert not straight.damped and np.all(straight.zeta == 0.0)
    assert straight.nmodes_model == 33


def test_a_tip_force_lowers_the_first_frequency():
    model = beamid.pace(J_elbow=0.0, J_tip=0.0)
    loaded = beamid.modal_analysis(model, beamid.TipForce(fx=-5.0), nmodes=2)
    free = beamid.modal_analysis(model, None, nmodes=2)
    assert loaded.freq[0] < free.freq[0]
    pulled = beamid.modal_analysis(model, beamid.TipForce(fx=5.0), nmodes=2)
    assert pulled.freq[0] > free.freq[0]


STATIONS = ("shape_n@1:0.4", "shape_n@2:0.3", "shape_psi@2:0.7", "shape_strain@1:0.1")


def _run(model, load, **kw):
    return beamid.modal_analysis(model, load, nmodes=3, elements_per_beam=2,
                                 stations=STATIONS, **kw)


@pytest.mark.parametrize("damped", [False, True])
def test_sensitivities_match_central_differences(damped):
    model = beamid.pace(elbow_flex=0.02, C2=5.0)
    if damped:
        model = model.replace(c_elbow=0.3, eta=1e-3)
    load = beamid.TipForce(fy=4.0) + beamid.TipMoment(0.5)
    names = ("EI2", "rho1", "elbow_flex", "J_tip") + (("c_elbow", "eta") if damped else ())
    r = _run(model, load, wrt=names)
    assert r.damped is damped
    for j, n in enumerate(names):
        p = model[n]
        h = 1e-2 * p
        runs = [_run(model.replace(**{n: p + k * h}), load) for k in (-2, -1, 1, 2)]

        def fd(get):
            f = [get(x) for x in runs]
            return (f[0] - 8 * f[1] + 8 * f[2] - f[3]) / (12 * h)

        assert_allclose(r.dfreq[:, j], fd(lambda x: x.freq), rtol=1e-4, atol=1e-6 * r.freq.max() / p)
        if damped:
            assert_allclose(r.dzeta[:, j], fd(lambda x: x.zeta), rtol=1e-4, atol=1e-9 / p)
        for k in (1, 2, 3):
            assert_allclose(r.dshape(k)[:, j], fd(lambda x: x.shape(k)), atol=1e-5 / p)
    if not damped:
        assert np.all(r.dzeta == 0.0)


def test_shapes_are_unit_normalized_with_the_largest_entry_positive():
    r = _run(beamid.pace(), beamid.TipForce(fy=3.0))
    for k in (1, 2, 3):
        s = r.shape(k)
        assert np.linalg.norm(s) == pytest.approx(1.0, abs=1e-14)
        assert s[np.argmax(np.abs(s))] > 0


def test_damping_ratios_of_a_damped_model():
    r = beamid.modal_analysis(beamid.pace(c_tip=0.5, eta=1e-3), nmodes=4)
    assert r.damped
    assert np.all(r.zeta > 0) and np.all(r.zeta < 0.2)
    # light damping: frequencies close to the undamped ones
    r0 = beamid.modal_analysis(beamid.pace(), nmodes=4)
    assert_allclose(r.freq, r0.freq, rtol=2e-2)


def test_friction_and_axial_coupling_have_zero_columns():
    r = beamid.modal_analysis(beamid.pace(mu_tip=0.02), nmodes=2,
                              wrt=("mu_tip", "axial_coupling", "EI1"))
    assert np.all(r.dfreq[:, :2] == 0.0) and np.all(r.dfreq[:, 2] > 0)


@pytest.mark.parametrize("kwargs, match", [
    (dict(load=beamid.RadialWire(1.6)), "not shorter than the arm|wire length Lw = 1.6"),
    (dict(nmodes=40), "has 33 modes"),
    (dict(wrt=("L1",)), "the mesh depends on it"),
    (dict(wrt=("elbow_flex",)), "locked joint"),
    (dict(wrt=("root_flex",)), "clamped root"),
    (dict(stations=("shape_q@1:0.1",)), "station kind"),
    (dict(stations=("shape_n@3:0.1",)), "beam = 3"),
    (dict(stations=("shape_n@1:0.9",)), "expected at most L1"),
])
def test_bad_input(kwargs, match):
    args = dict(model=beamid.pace(), load=None)
    args.update(kwargs)
    with pytest.raises(beamid.InputError, match=match):
        beamid.modal_analysis(**args)


def test_mode_beyond_the_computed_ones():
    r = beamid.modal_analysis(beamid.pace(), nmodes=2, stations=STATIONS)
    with pytest.raises(beamid.InputError, match="mode = 3, expected 1..2"):
        r.shape(3)


def test_an_unstable_equilibrium_has_no_modes():
    pcr = beamid.buckling_load(beamid.pace(), 4).load
    with pytest.raises(beamid.BeamidError, match="not stable|no convergence|Newton"):
        beamid.modal_analysis(beamid.pace(), beamid.TipForce(fx=-1.5 * pcr), nmodes=2)


# ------------------------------------------------------------------ MAC, pairing

def test_mac_of_modes_with_themselves():
    r = beamid.modal_analysis(beamid.pace(), nmodes=4, stations=STATIONS + (
        "shape_n@1:0.7", "shape_n@2:0.6", "shape_t@2:0.7"))
    m = beamid.mac(r.shapes, r.shapes)
    assert_allclose(np.diag(m), 1.0, rtol=1e-12)
    assert m.shape == (4, 4)
    assert np.all((m >= 0) & (m <= 1 + 1e-12))


def test_pairing_with_unequal_counts_reports_unpaired_modes():
    model = np.eye(4)[:, :3]
    measured = np.array([[1.0, 0.0], [0.05, 0.02], [0.0, 1.0], [0.0, 0.0]])
    # measured mode 2 looks like model mode 3 but its frequency is far from it
    p = beamid.pair_modes([1.0, 9.0], measured, [1.05, 2.0, 3.1], model)
    assert [(i, j) for i, j, _, _ in p.pairs] == [(1, 1)]
    assert p.unpaired_measured == (2,) and p.unpaired_model == (2, 3)
    assert p.model_mode(2) is None and p.model_mode(1) == 1
    assert "measured 2 (9 Hz) -> no partner" in p.report()
    q = beamid.pair_modes([1.0, 3.0], measured, [1.05, 2.0, 3.1], model)
    assert [(i, j) for i, j, _, _ in q.pairs] == [(1, 1), (2, 3)]
    assert p.changes(q) == ["measured mode 2: model mode None -> 3"]


def test_pairing_never_forces_a_poor_match():
    p = beamid.pair_modes([1.0], [[1.0], [1.0]], [1.0], [[1.0], [-1.2]], min_mac=0.6)
    assert p.pairs == () and p.unpaired_measured == (1,)


def test_plot_mac_labels():
    p = beamid.pair_modes([1.0, 2.0], np.eye(3)[:, :2], [1.0, 2.0, 3.0], np.eye(3))
    ax = beamid.plot_mac(p)
    assert ax.get_title() == "MAC, measured vs model modes"
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("model mode", "measured mode")
    assert len(ax.patches) == 2


@pytest.mark.parametrize("nepb", [2, 8])
def test_straight_arm_matches_the_linear_modes_at_other_meshes(nepb):
    """4 and 16 elements of Tables 9-10: the same numbers as beamid.modes,
    whose tests pin the published digits (tests/test_fe_modes.py)."""
    model = beamid.pace(J_elbow=0.0, J_tip=0.0)
    md = beamid.modes(model, nepb)
    r = beamid.modal_analysis(model, nmodes=md.omega.size, elements_per_beam=nepb)
    assert_allclose(r.freq * TWO_PI, md.omega, rtol=1e-9)
