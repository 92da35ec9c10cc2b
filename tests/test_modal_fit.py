"""Modal experiments in the inverse problem (issue 27): freq[k], damping[k]
and shape rows in the measurement CSV, mixed modal + static + release fits,
identify stages, diagnosis on modal data, the consistency check, the
simulated modal test, data in from arrays and UFF files, and bad input."""
import sys

import numpy as np
import pytest
from numpy.testing import assert_allclose

import beamid

STATIONS = [f"shape_n@{b}:{s}" for b, s in ((1, 0.2), (1, 0.4), (1, 0.6), (1, 0.776),
                                           (2, 0.2), (2, 0.4), (2, 0.6), (2, 0.714))]
TRUE = beamid.pace(J_elbow=0.0, J_tip=0.0, root_flex=0.01)


def _qs(modes=(1, 2, 3, 4), stations=STATIONS):
    return [f"freq[{k}]" for k in modes] + [f"{s}[{k}]" for k in modes for s in stations]


def test_modal_rows_predicted_as_the_analysis_gives_them():
    exps = {"M3": beamid.Modal(beamid.TipForce(fy=3.0), 2)}
    d = beamid.simulate_measurements(TRUE, exps, _qs((1, 2), STATIONS[:3]))
    r = beamid.modal_analysis(TRUE, beamid.TipForce(fy=3.0), nmodes=2, elements_per_beam=2,
                              stations=STATIONS[:3])
    assert_allclose(d.value[:2], r.freq, rtol=1e-12)
    # signed by the first shape row of each mode
    for k, rows in ((1, slice(2, 5)), (2, slice(5, 8))):
        s = r.shape(k)
        assert_allclose(d.value[rows], s * np.sign(s[0]), rtol=1e-12)
        assert d.value[rows][0] > 0


def test_csv_round_trip(tmp_path):
    d = beamid.simulate_measurements(TRUE, {"M0": beamid.Modal()}, _qs((1,), STATIONS[:2]))
    d.write(tmp_path / "modal.csv")
    text = (tmp_path / "modal.csv").read_text()
    assert "M0,0,shape_n@1:0.2[1]," in text and "M0,0,freq[1]," in text
    back = beamid.read_measurements(tmp_path / "modal.csv")
    assert back.quantity == d.quantity
    assert_allclose(back.value, d.value, rtol=0, atol=0)


def test_mixed_modal_static_release_fit_recovers_exact_data():
    exps = {"M0": beamid.Modal(None, 2), "F3": beamid.TipForce(fy=3.0),
            "R": beamid.Release(beamid.TipForce(fy=3.0), elements_per_beam=2)}
    d = beamid.simulate_measurements(
        TRUE, exps, {"M0": ["freq[1]", "freq[2]", "shape_n@2:0.7[1]", "shape_n@1:0.5[1]"],
                     "F3": ["y_tip"], "R": ["w_tip"]}, t={"R": [0.1, 0.2]})
    f = beamid.fit(TRUE.replace(EI1=11.0, rho1=0.5), exps, d, free=("EI1", "rho1"))
    assert f.estimates["EI1"] == pytest.approx(11.413, rel=1e-7)
    assert f.estimates["rho1"] == pytest.approx(0.532, rel=1e-7)
    assert f.chi2 < 1e-8


def test_identify_stages_stiffness_from_shapes_then_density_from_frequencies():
    static = {"F3": beamid.TipForce(fy=3.0), "F6": beamid.TipForce(fy=6.0)}
    ds = beamid.simulate_measurements(TRUE, static, ["y_tip", "x_elbow", "y_elbow"],
                                      sigma=1e-4, noise=True, seed=4)
    modal = {"M0": beamid.Modal(None, 4)}
    dm = beamid.simulate_measurements(TRUE, modal, ["freq[1]", "freq[2]", "freq[3]"],
                                      sigma=1e-3, noise=True, seed=5)
    start = TRUE.replace(EI1=10.0, EI2=10.0, rho1=0.5, rho2=0.5)
    ident = beamid.identify(start, {"static": (static, ds, ("EI1", "EI2")),
                                    "modal": (modal, dm, ("rho1", "rho2"))})
    final = ident.final
    for n, v in (("EI1", 11.413), ("EI2", 11.275), ("rho1", 0.532), ("rho2", 0.530)):
        assert abs(final.estimates[n] - v) < 3 * final.sigmas[n], n
    assert {r.stage for r in ident.table} == {"static", "modal"}


def test_simulated_modal_test_recovers_ei_rho_and_a_compliance():
    """Data from a finer mesh (16 elements per beam) than the fitted model (8),
    two equilibria (free and under 3 N), modes 1-4 with 8 shape entries each;
    noise 1e-3 relative on the frequencies, 1e-2 on the normalized shape
    entries, seed 7: EI1, rho1 and root_flex within two sigmas (measured:
    0.20, 1.09 and 0.09 sigma)."""
    fine = {"M0": beamid.Modal(None, 16), "M3": beamid.Modal(beamid.TipForce(fy=3.0), 16)}
    exact = beamid.simulate_measurements(TRUE, fine, _qs(), sigma=1.0)
    rng = np.random.default_rng(7)
    rows = []
    for e, t, q, v, _ in exact.rows():
        s = 1e-3 * v if q.startswith("freq") else 1e-2
        rows.append((e, t, q, v + s * rng.standard_normal(), s))
    data = beamid.Measurements.from_rows(rows)
    coarse = {"M0": beamid.Modal(None, 8), "M3": beamid.Modal(beamid.TipForce(fy=3.0), 8)}
    f = beamid.fit(TRUE.replace(EI1=10.5, rho1=0.5, root_flex=0.02), coarse, data,
                   free=("EI1", "rho1", "root_flex"))
    z = {n: (f.estimates[n] - TRUE[n]) / f.sigmas[n] for n in ("EI1", "rho1", "root_flex")}
    assert all(abs(v) < 2 for v in z.values()), z
    assert f.chi2_per_dof < 1.5
    assert f.sigmas["root_flex"] < 0.02 * TRUE["root_flex"]


def test_diagnosis_on_modal_data_finds_rotary_inertia():
    true = beamid.pace(root_flex=0.01)
    exps = {"M0": beamid.Modal(None, 4), "M3": beamid.Modal(beamid.TipForce(fy=3.0), 4)}
    stations = ["shape_n@1:0.4", "shape_n@1:0.776", "shape_n@2:0.4", "shape_n@2:0.714"]
    qs = [f"freq[{k}]" for k in (1, 2, 3, 4, 5)] + [f"{s}[{k}]" for k in (1, 2, 3)
                                                      for s in stations]
    data = beamid.simulate_measurements(
        true, exps, qs, sigma={q: 1e-3 if q.startswith("freq") else 1e-2 for q in qs},
        noise=True, seed=2)
    f = beamid.fit(true.replace(root_flex=0.0, J_tip=0.0, J_elbow=0.0), exps, data,
                   free=("EI1", "rho1"))
    d = beamid.diagnose(f)
    assert d.verdict is not None and d.verdict.effect == "rotary_inertia"
    assert [c.effect for c in d.candidates][0] == "rotary_inertia"


def test_consistency_covers_modal_experiments():
    exps = {"M0": beamid.Modal(None, 2)}
    d = beamid.simulate_measurements(TRUE, exps, ["freq[1]", "freq[2]", "freq[3]"],
                                     sigma=1e-3, noise=True, seed=1)
    f = beamid.fit(TRUE, exps, d, free=("EI1", "rho1"))
    c = beamid.consistency(f, replicates=12, workers=1)
    assert c.replicates == 12
    assert c.failed == 0
    ratio = np.array([c.spread_ratio[n] for n in ("EI1", "rho1")])
    assert np.all((ratio > 0.4) & (ratio < 2.5)), ratio


# ------------------------------------------------------------------- bad input

@pytest.mark.parametrize("qs, match", [
    (["freq[40]"], r"mode 40 asked, but the model of 2 elements per beam has 18 modes"),
    (["freq[1]", "shape_n@1:0.4[2]"], r"shape entry shape_n@1:0.4\[2\] has no frequency row "
                                      r"freq\[2\]"),
    (["damping[1]"], r"damping\[1\] asked of an undamped model"),
    (["x_tip"], "is a modal test"),
])
def test_bad_modal_rows(qs, match):
    with pytest.raises(beamid.InputError, match=match):
        beamid.simulate_measurements(TRUE, {"M0": beamid.Modal(None, 2)}, qs)


@pytest.mark.parametrize("name, match", [
    ("freq", r"needs a mode number: freq\[mode\]"),
    ("freq[0]", "expected a mode number >= 1"),
    ("freq[x]", "expected a mode number >= 1"),
    ("shape_n[1]", "needs a station"),
    ("x_tip[1]", "takes no mode number"),
])
def test_bad_modal_names(name, match):
    with pytest.raises(beamid.InputError, match=match):
        beamid.observations.parse(name)


def test_modal_kinds_in_a_static_experiment_are_refused():
    # simulated rows get the same row-naming message as a fit's data
    with pytest.raises(beamid.InputError, match=r"row 1: field quantity = 'freq\[1\]', but "
                       r"experiment 'F' is static \(only a modal experiment measures freq\)"):
        beamid.simulate_measurements(TRUE, {"F": beamid.TipForce(fy=1.0)}, ["freq[1]"])
    d = beamid.Measurements.from_rows([("F", 0.0, "freq[1]", 0.4, 1e-3)])
    with pytest.raises(beamid.InputError, match="only a modal experiment measures freq"):
        beamid.fit(TRUE, {"F": beamid.TipForce(fy=1.0)}, d, free=("EI1",))


def test_a_modal_row_needs_t_zero():
    d = beamid.Measurements.from_rows([("M0", 0.5, "freq[1]", 0.4, 1e-3)])
    with pytest.raises(beamid.InputError, match="expected 0 for the modal experiment"):
        beamid.fit(TRUE, {"M0": beamid.Modal()}, d, free=("EI1",))


def test_a_damped_model_predicts_damping_rows():
    model = TRUE.replace(c_tip=0.5)
    d = beamid.simulate_measurements(model, {"M0": beamid.Modal(None, 2)},
                                     ["freq[1]", "damping[1]", "damping[2]"], sigma=1e-4)
    r = beamid.modal_analysis(model, nmodes=2, elements_per_beam=2)
    assert_allclose(d.value[1:], r.zeta, rtol=1e-12)
    f = beamid.fit(model.replace(c_tip=0.3), {"M0": beamid.Modal(None, 2)}, d,
                   free=("c_tip",))
    assert f.estimates["c_tip"] == pytest.approx(0.5, rel=1e-6)


# ------------------------------------------------------------------- data in

def test_modal_rows_from_arrays_as_ema_returns_them():
    r = beamid.modal_analysis(TRUE, nmodes=3, elements_per_beam=2, stations=STATIONS[:4])
    # complex shapes with an arbitrary phase per mode, as EMA software gives them
    phase = np.exp(1j * np.array([0.3, -1.2, 2.0]))
    d = beamid.modal_rows("M0", r.freq, r.shapes * phase, STATIONS[:4], damping=[0.01] * 3)
    assert d.quantity[:3] == ("freq[1]", "freq[2]", "freq[3]")
    assert d.quantity[3:6] == ("damping[1]", "damping[2]", "damping[3]")
    s1 = r.shape(1)
    first = int(np.argmax(np.abs(s1)))
    assert d.quantity[6] == f"{STATIONS[first]}[1]"         # the largest entry first
    assert_allclose(sorted(d.value[6:10]), sorted(s1), atol=1e-12)
    f = beamid.fit(TRUE.replace(EI1=11.0), {"M0": beamid.Modal(None, 2)},
                   beamid.Measurements.from_rows([x for x in d.rows() if "damping" not in x[2]]),
                   free=("EI1",))
    assert f.estimates["EI1"] == pytest.approx(11.413, rel=1e-6)
    with pytest.raises(beamid.InputError, match="expected 3 distinct model mode numbers"):
        beamid.modal_rows("M0", r.freq, modes=[1, 1, 2])
    with pytest.raises(beamid.InputError, match=r"expected \(4, 3\)"):
        beamid.modal_rows("M0", r.freq, r.shapes[:3], STATIONS[:4])


def _write_uff(path, r, nodes):
    pyuff = pytest.importorskip("pyuff")
    uff = pyuff.UFF(str(path))
    sets = []
    for k in range(r.freq.size):
        shape = r.shapes[:, k]
        sets.append(pyuff.prepare_55(
            model_type=1, id1="beamid", id2="NONE", id3="NONE", id4="NONE", id5="NONE",
            analysis_type=2, data_ch=2, spec_data_type=8, data_type=2, n_data_per_node=3,
            r1=np.zeros_like(shape), r2=shape, r3=np.zeros_like(shape), node_nums=nodes,
            load_case=1, mode_n=k + 1, modal_m=0, freq=float(r.freq[k]),
            modal_damp_vis=0.0, modal_damp_his=0.0))
    x = np.linspace(0.0, 10.0, 11)
    sets.append(pyuff.prepare_58(
        id1="frf", rsp_node=1, rsp_dir=2, ref_node=1, ref_dir=2, func_type=4,
        ord_data_type=2, data=np.sin(x), x=x, abscissa_spacing=1, num_pts=11,
        abscissa_spec_data_type=18, ordinate_spec_data_type=12, orddenom_spec_data_type=13,
        z_axis_spec_data_type=0))
    uff.write_sets(sets, mode="overwrite")


def test_read_uff_on_a_file_pyuff_writes(tmp_path):
    r = beamid.modal_analysis(TRUE, nmodes=3, elements_per_beam=2, stations=STATIONS[:4])
    _write_uff(tmp_path / "test.uff", r, [11, 12, 13, 14])
    got = beamid.read_uff(tmp_path / "test.uff", "M0",
                          {11: STATIONS[0], 12: STATIONS[1], 13: STATIONS[2], 14: STATIONS[3]})
    assert_allclose(got.frequencies, r.freq, rtol=1e-5)   # pyuff writes 6 digits
    assert got.data.quantity[0] == "freq[1]"
    assert_allclose(sorted(got.data.value[3:7]), sorted(r.shape(1)), atol=1e-5)
    assert len(got.functions) == 1 and got.functions[0][1].size == 11
    with pytest.raises(beamid.InputError, match="has no node 99"):
        beamid.read_uff(tmp_path / "test.uff", "M0", {99: STATIONS[0]})


def test_read_uff_without_pyuff_says_what_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyuff", None)
    (tmp_path / "x.uff").write_text("    -1\n")
    with pytest.raises(beamid.InputError, match=r"needs the optional package pyuff: pip install "
                                                r"'beamid\[uff\]'"):
        beamid.read_uff(tmp_path / "x.uff", "M0", {1: "shape_n@1:0.4"})


def test_a_mode_that_moves_across_another_during_a_fit_is_reported():
    """A soft EA1 drops the first axial mode below the third transverse one:
    model mode 3 at the start is mode 4 at the end (followed by MAC)."""
    from beamid.estimation import _mode_crossings

    exps = {"M0": beamid.Modal(None, 2)}
    d = beamid.Measurements.from_rows([("M0", 0.0, "freq[3]", 1.0, 1e-3),
                                       ("M0", 0.0, "freq[1]", 1.0, 1e-3)])
    (w,) = _mode_crossings(TRUE, TRUE.replace(EA1=1e3), exps, d)
    assert w.startswith("experiment 'M0': model mode 3 at the start is mode 4 at the end of "
                        "the fit (MAC 1.00)")
    assert _mode_crossings(TRUE, TRUE.replace(EA1=1.3e7), exps, d) == ()


# ------------------------------------------------------------------- decks

MODAL_DECK = """&beamid
    task = '{task}'
    output = 'out/modal'
    preset = 'pace'
/
&model
    J_elbow = 0.0
    J_tip = 0.0
    root_flex = {root_flex}
/
&experiment name = 'M0', kind = 'modal', elements_per_beam = 4 {extra}/
&experiment name = 'M3', kind = 'modal', fy = 3.0, elements_per_beam = 4 /
&fit
    data = 'modal.csv'
    free = {free}
/
"""


@pytest.fixture()
def modal_deck_dir(tmp_path):
    exps = {"M0": beamid.Modal(None, 4), "M3": beamid.Modal(beamid.TipForce(fy=3.0), 4)}
    qs = ["freq[1]", "freq[2]", "freq[3]", "shape_n@1:0.4[1]", "shape_n@2:0.714[1]",
          "shape_n@2:0.714[2]", "shape_n@1:0.5[2]"]
    d = beamid.simulate_measurements(TRUE, exps, qs, sigma={
        q: 1e-3 if q.startswith("freq") else 1e-2 for q in qs}, noise=True, seed=3)
    d.write(tmp_path / "modal.csv")
    (tmp_path / "out").mkdir()
    return tmp_path


def test_a_modal_fit_deck_runs_in_python_and_in_the_batch(modal_deck_dir, batch_exe):
    import subprocess

    deck = modal_deck_dir / "modal.nml"
    deck.write_text(MODAL_DECK.format(task="fit", extra="", root_flex=0.02,
                                      free="'EI1', 'rho1', 'root_flex'"))
    r = beamid.run(str(deck))
    assert r.estimates["root_flex"] == pytest.approx(0.01, abs=3 * r.sigmas["root_flex"])
    assert r.experiments["M3"] == beamid.Modal(beamid.TipForce(fy=3.0), 4)
    done = subprocess.run([str(batch_exe), str(deck)], capture_output=True, text=True,
                          cwd=modal_deck_dir)
    assert done.returncode == 0, done.stderr
    text = (modal_deck_dir / "out" / "modal_residuals.csv").read_text()
    assert "M3,0,shape_n@2:0.714[2]," in text


def test_a_modal_diagnose_deck(modal_deck_dir, batch_exe):
    import subprocess

    deck = modal_deck_dir / "modal.nml"
    deck.write_text(MODAL_DECK.format(task="diagnose", extra="", root_flex=0.0, free="'EI1', 'rho1'\n"
                                      "    candidates = 'root_flex', 'rotary_inertia'"))
    done = subprocess.run([str(batch_exe), str(deck)], capture_output=True, text=True,
                          cwd=modal_deck_dir)
    assert done.returncode == 0, done.stderr
    ranking = (modal_deck_dir / "out" / "modal_ranking.csv").read_text().splitlines()
    tested = {line.split(",")[1] for line in ranking[1:] if line.split(",")[2] == "tested"}
    assert tested == {"root_flex", "rotary_inertia"}
    # both lower the frequencies the clamped model over-predicts: a modal test
    # of these modes alone does not tell a compliant root from tip inertia
    # (the first-order root_flex is negative once EI1 has absorbed the misfit)
    first = ranking[1].split(",")
    assert first[1] == "rotary_inertia" and float(first[4]) > 100


def test_a_modal_experiment_refuses_release_options(modal_deck_dir):
    deck = modal_deck_dir / "modal.nml"
    deck.write_text(MODAL_DECK.format(task="fit", extra=", motor_gain = 0.2 ", root_flex=0.0,
                                      free="'EI1'"))
    with pytest.raises(beamid.InputError, match="kind = 'modal' does not take motor_gain"):
        beamid.run(str(deck))


def test_the_mesh_candidate_refines_modal_tests_beside_releases():
    coarse = {"R": beamid.Release(beamid.TipForce(fy=3.0), elements_per_beam=2),
              "M0": beamid.Modal(None, 2)}
    fine = {"R": beamid.Release(beamid.TipForce(fy=3.0), elements_per_beam=8),
            "M0": beamid.Modal(None, 8)}
    d = beamid.simulate_measurements(TRUE, fine, {"R": ["w_tip"],
                                                  "M0": ["freq[1]", "freq[2]", "freq[3]"]},
                                     t={"R": [0.1, 0.3]}, sigma=1e-4)
    f = beamid.fit(TRUE, coarse, d, free=("EI1",))
    dg = beamid.diagnose(f, candidates=("mesh", "rotary_inertia"))
    assert dg.verdict.effect == "mesh"
    assert "(freq[3] in experiment M0)" in dg.message


@pytest.mark.parametrize("static", [False, True])
def test_the_mesh_candidate_refines_modal_tests_alone(static):
    """Modal tests alone (and beside a static experiment, which has no mesh
    of its own): data from a finer mesh (8 elements per beam against 2),
    sigma 1e-4 on the frequencies, noise with seed 3. diagnose's mesh test
    finds the coarse mesh, its line names the frequency that moves most,
    add_effect and improve refine the modal tests."""
    coarse = {"M0": beamid.Modal(None, 2), "M3": beamid.Modal(beamid.TipForce(fy=3.0), 2)}
    fine = {"M0": beamid.Modal(None, 8), "M3": beamid.Modal(beamid.TipForce(fy=3.0), 8)}
    qs = {"M0": ["freq[1]", "freq[2]", "freq[3]"], "M3": ["freq[1]", "freq[2]", "freq[3]"]}
    if static:
        coarse["F3"] = fine["F3"] = beamid.TipForce(fy=3.0)
        qs["F3"] = ["y_tip"]
    d = beamid.simulate_measurements(TRUE, fine, qs, sigma=1e-4, noise=True, seed=3)
    f = beamid.fit(TRUE, coarse, d, free=("EI1",))
    dg = beamid.diagnose(f, candidates=("mesh", "rotary_inertia"))
    assert dg.verdict.effect == "mesh"
    assert dg.mesh.elements_per_beam == 2 and dg.mesh.recommended >= 8
    assert dg.mesh.chi2_drop > 100.0
    assert dg.mesh.max_change_at[2] == "freq[3]"
    assert "refine the mesh: at 4 elements per beam instead of 2" in dg.message
    refined = beamid.add_effect(f, "mesh")
    assert refined.experiments["M0"].elements_per_beam == 4
    assert refined.chi2 < f.chi2 / 10
    lad = beamid.improve(TRUE, coarse, d, free=("EI1",), candidates=("mesh",))
    assert lad.steps[1].effect.startswith("mesh (")
    assert lad.steps[1].fit.experiments["M3"].elements_per_beam == dg.mesh.recommended
    assert lad.steps[1].chi2 < f.chi2 / 10


def test_a_modal_deck_tries_the_modal_candidates_by_default(modal_deck_dir):
    """A deck of modal tests alone without `candidates`: the modal defaults
    (the core's effects table, as beamid.diagnose); `mesh` named in such a
    deck is the mesh test of its modal tests."""
    deck = modal_deck_dir / "modal.nml"
    deck.write_text(MODAL_DECK.format(task="diagnose", extra="", root_flex=0.0,
                                      free="'EI1', 'rho1'"))
    dg = beamid.run(str(deck))
    effects = {c.effect for c in dg.candidates}
    assert effects == {"rotary_inertia", "root_flex", "elbow_flex", "drag", "kelvin_voigt"}
    ranking = (modal_deck_dir / "out" / "modal_ranking.csv").read_text().splitlines()
    assert {line.split(",")[1] for line in ranking[1:]} == effects
    deck.write_text(MODAL_DECK.format(task="diagnose", extra="", root_flex=0.0,
                                      free="'EI1', 'rho1'\n    candidates = 'mesh'"))
    dg = beamid.run(str(deck))
    assert dg.mesh is not None and dg.mesh.elements_per_beam == 4
    assert dg.mesh.state == "tested" and dg.mesh.recommended >= 8


def test_compare_on_modal_data_shows_what_the_model_misses():
    """compare on a modal fit (docs/modal.md): one row per frequency and
    shape entry with the fit's own model values and normalized residuals; a
    clamped model fitted to the frequencies of a compliant root (root_flex
    0.02; data at 16 elements per beam, fitted at 8; seed 3, sigma 1e-3 Hz)
    is systematically off (the frequencies
    over-predicted); with the compliance in the model the chi-square falls a
    hundredfold and the compliance is recovered."""
    exps = {"M0": beamid.Modal(None, 8), "M3": beamid.Modal(beamid.TipForce(fy=3.0), 8)}
    qs = ["freq[1]", "freq[2]", "freq[3]", "shape_n@1:0.4[1]", "shape_n@2:0.714[1]"]
    sig = {q: 1e-3 if q.startswith("freq") else 1e-2 for q in qs}
    truth = TRUE.replace(root_flex=0.02)
    d = beamid.simulate_measurements(truth, {k: beamid.Modal(v.load, 16) for k, v in
                                             exps.items()}, qs, sigma=sig, noise=True, seed=3)
    clamped = beamid.fit(TRUE, exps, d, free=("EI1", "rho1"))
    c = beamid.compare(clamped)
    assert [(r.experiment, r.quantity) for r in c.rows] == list(zip(d.experiment, d.quantity))
    for row, res in zip(c.rows, clamped.residuals):
        assert row.model == res.model and row.normalized == res.normalized
    assert c.systematic
    assert all(r.normalized < -5 for r in c.rows if r.quantity in ("freq[1]", "freq[2]"))
    compliant = beamid.fit(TRUE.replace(root_flex=0.01), exps, d,
                           free=("EI1", "rho1", "root_flex"))
    c2 = beamid.compare(compliant)
    # (this draw's chi-square stays 24 for 7 dof even on the data's own mesh:
    # two rows of 2.8 and 3.3 sigma)
    assert c2.chi2 < 0.01 * c.chi2
    assert abs(compliant.estimates["root_flex"] - 0.02) < 3 * compliant.sigmas["root_flex"]
