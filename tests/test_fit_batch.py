"""beamid-batch runs the estimation decks (fit, compare, diagnose, improve)
without Python: the same files and numbers as beamid.fit_decks, and the same
errors (file, line, field) for malformed measurement CSVs and decks."""
from __future__ import annotations

import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import beamid
from beamid import ConvergenceError, InputError, _core, _core_estimation as _ce
from beamid.fit_decks import read_fit_deck, run_fit_deck

DEMO = Path(__file__).resolve().parent.parent / "inputs" / "demo"
FILES = {"fit": ("estimates", "covariance", "residuals"),
         "compare": ("estimates", "covariance", "residuals", "compare"),
         "diagnose": ("estimates", "covariance", "residuals", "ranking"),
         "improve": ("estimates", "covariance", "residuals", "ranking", "ladder")}


def _deck(folder: Path, task: str = "improve", deck_text=None, csv_text=None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    text = (DEMO / "hidden_effect.nml").read_text().replace("task = 'improve'",
                                                            f"task = '{task}'")
    (folder / "hidden_effect.nml").write_text(deck_text(text) if deck_text else text)
    csv = (DEMO / "hidden_effect.csv").read_text()
    (folder / "hidden_effect.csv").write_text(csv_text(csv) if csv_text else csv)
    return folder / "hidden_effect.nml"


def _batch(exe: Path, deck: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(exe), str(deck)], capture_output=True, text=True, timeout=120)


def _cells(path: Path) -> list[list[str]]:
    return [line.split(",") for line in path.read_text().splitlines()]


def _same_table(a: Path, b: Path) -> None:
    ra, rb = _cells(a), _cells(b)
    assert len(ra) == len(rb) and ra[0] == rb[0], a.name
    for x, y in zip(ra[1:], rb[1:]):
        assert len(x) == len(y), a.name
        for u, v in zip(x, y):
            try:
                fu, fv = float(u), float(v)
            except ValueError:
                assert u == v, (a.name, x, y)
                continue
            if math.isnan(fu) or math.isnan(fv):
                assert math.isnan(fu) and math.isnan(fv), (a.name, x, y)
            else:
                np.testing.assert_allclose(fu, fv, rtol=1e-10, atol=0.0, err_msg=a.name)


@pytest.mark.parametrize("task", ["fit", "compare", "diagnose", "improve"])
def test_batch_and_python_write_the_same_numbers(task, tmp_path, batch_exe):
    bdeck = _deck(tmp_path / "batch", task)
    pdeck = _deck(tmp_path / "python", task)
    run = _batch(batch_exe, bdeck)
    assert run.returncode == 0, run.stderr
    assert run.stderr == ""
    _, files, _ = run_fit_deck(pdeck, plots=False)
    names = sorted(p.name for p in (tmp_path / "batch" / "out").iterdir())
    assert names == sorted(f"hidden_effect_{k}.csv" for k in FILES[task])
    assert sorted(p.name for p in files) == names
    for name in names:
        _same_table(tmp_path / "batch" / "out" / name, tmp_path / "python" / "out" / name)


@pytest.mark.parametrize("task", ["fit", "compare", "diagnose"])
def test_deck_fit_runs_once_for_files_and_result(task, tmp_path, batch_exe, monkeypatch):
    """The deck's fit (and diagnosis) runs once, in the Fortran of beamid-batch
    on the deck (deck_task_start), for both the files, byte for byte the
    batch's, and the result: no second run of the deck, no fit or diagnosis
    through the API. The result has the numbers of the API's own fit."""
    bdeck, pdeck = _deck(tmp_path / "batch", task), _deck(tmp_path / "python", task)
    assert _batch(batch_exe, bdeck).returncode == 0
    calls = []
    for module, name in ((_ce, "deck_task_start"), (_ce, "fit"), (_ce, "problem_diagnose"),
                         (_ce, "ladder_start"), (_core, "run_deck")):
        real = getattr(module, name)
        monkeypatch.setattr(module, name, lambda *a, _real=real, _name=name, **k:
                            calls.append(_name) or _real(*a, **k))
    _, files, out = run_fit_deck(pdeck, plots=False)
    assert calls == ["deck_task_start"]
    names = sorted(p.name for p in (tmp_path / "batch" / "out").iterdir())
    assert sorted(p.name for p in files) == names
    for name in names:
        assert (tmp_path / "python" / "out" / name).read_bytes() == \
            (tmp_path / "batch" / "out" / name).read_bytes(), name
    monkeypatch.undo()
    deck = read_fit_deck(pdeck)
    fit = out if task == "fit" else out.fit
    direct = beamid.fit(deck.model, deck.experiments, deck.data, free=deck.free,
                        prior=deck.prior, max_iter=deck.max_iter)
    assert (fit.estimates, fit.sigmas, fit.chi2, fit.iterations) == \
        (direct.estimates, direct.sigmas, direct.chi2, direct.iterations)
    assert np.array_equal(fit.cov, direct.cov) and fit.summary() == direct.summary()
    if task == "compare":
        assert str(out) == str(beamid.compare(direct))
    if task == "diagnose":
        assert str(out) == str(beamid.diagnose(direct, deck.candidates, alpha=deck.alpha))
        assert out.candidates[0].effect == "axial_coupling"


def test_batch_improve_finds_the_hidden_effects(tmp_path, batch_exe):
    deck = _deck(tmp_path, "improve")
    assert _batch(batch_exe, deck).returncode == 0
    ladder = _cells(tmp_path / "out" / "hidden_effect_ladder.csv")
    assert [row[1] for row in ladder[1:]] == ["start", "axial_coupling", "elbow_flex"]
    est = {row[0]: (float(row[1]), float(row[2]))
           for row in _cells(tmp_path / "out" / "hidden_effect_estimates.csv")[1:5]}
    assert abs(est["elbow_flex"][0] - 0.003) < 3 * est["elbow_flex"][1]
    assert abs(est["axial_coupling"][0] - 1.0) < 3 * est["axial_coupling"][1]


def _line(n: int, text: str, new: str) -> str:
    lines = text.splitlines()
    lines[n - 1] = new
    return "\n".join(lines) + "\n"


# (id, change of the demo CSV, text both messages must hold)
BAD_CSV = [
    ("unknown_quantity", lambda t: t.replace("F2,0,y_tip", "F2,0,y_tipp"),
     "hidden_effect.csv, line 6: field quantity = 'y_tipp', expected one of"),
    ("non_numeric_value", lambda t: _line(5, t, "F2,0,x_tip,1.47a,0.0001"),
     "hidden_effect.csv, line 5: field value = '1.47a', expected a number"),
    ("non_finite_value", lambda t: _line(5, t, "F2,0,x_tip,nan,0.0001"),
     "hidden_effect.csv, line 5: field value = 'nan', expected a finite number"),
    ("non_numeric_t", lambda t: _line(8, t, "F4,zero,x_tip,1.43,0.0001"),
     "hidden_effect.csv, line 8: field t = 'zero', expected a number"),
    ("zero_sigma", lambda t: _line(7, t, "F2,0,tip_angle,0.1967,0"),
     "hidden_effect.csv, line 7: field sigma = 0, expected sigma > 0"),
    ("negative_sigma", lambda t: _line(7, t, "F2,0,tip_angle,0.1967,-2e-4"),
     "hidden_effect.csv, line 7: field sigma = -0.0002, expected sigma > 0"),
    ("duplicate_row", lambda t: t + "F2,0,x_tip,1.47,0.0001\n",
     "hidden_effect.csv, line 20: duplicate row: experiment 'F2', t = 0, quantity 'x_tip' "
     "already given ("),
    ("undefined_experiment", lambda t: t.replace("M3,0,y_tip", "M4,0,y_tip"),
     "hidden_effect.csv, line 18: field experiment = 'M4' is not defined (experiments: "
     "F2, F4, F6, F8, M3)"),
    ("missing_column", lambda t: t.replace("value,sigma", "value").replace(
        ",0.0001\n", "\n"), "hidden_effect.csv, line 4: expected the header "
     "experiment,t,quantity,value,sigma, got 'experiment,t,quantity,value'"),
    ("missing_header", lambda t: t.replace("experiment,t,quantity,value,sigma\n", ""),
     "hidden_effect.csv, line 4: expected the header experiment,t,quantity,value,sigma"),
    ("short_row", lambda t: _line(9, t, "F4,0,y_tip,0.3677"),
     "hidden_effect.csv, line 9: expected 5 fields (experiment,t,quantity,value,sigma), "
     "got 4"),
    ("empty_experiment", lambda t: _line(9, t, " ,0,y_tip,0.3677,1e-4"),
     "hidden_effect.csv, line 9: field experiment is empty"),
    ("negative_t", lambda t: _line(9, t, "F4,-1,y_tip,0.3677,1e-4"),
     "hidden_effect.csv, line 9: field t = -1, expected t >= 0"),
    ("static_t", lambda t: _line(9, t, "F4,0.5,y_tip,0.3677,1e-4"),
     "hidden_effect.csv, line 9: field t = 0.5, expected 0 for the static experiment 'F4'"),
    ("wire_force_without_wire", lambda t: _line(9, t, "F4,0,wire_force,3.1,0.1"),
     "hidden_effect.csv, line 9: field quantity = 'wire_force', but experiment 'F4' has "
     "no wire"),
    ("no_rows", lambda t: t.split("experiment,t")[0] + "experiment,t,quantity,value,sigma\n",
     "hidden_effect.csv: no measurement rows after the header"),
]


@pytest.mark.parametrize("change,expected", [c[1:] for c in BAD_CSV],
                         ids=[c[0] for c in BAD_CSV])
def test_malformed_csv_fails_in_both_readers(change, expected, tmp_path, batch_exe):
    deck = _deck(tmp_path, "diagnose", csv_text=change)
    with pytest.raises(InputError) as info:
        read_fit_deck(deck)
    run = _batch(batch_exe, deck)
    assert run.returncode == 2, run.stderr
    assert expected in str(info.value)
    lines = run.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("beamid-batch: error: ")
    # the same message, word for word (both fronts run the same reader)
    assert lines[0][len("beamid-batch: error: "):] == str(info.value)
    assert not (tmp_path / "out").exists()


# (id, change of the demo deck, text both messages must hold)
BAD_DECKS = [
    ("free_unknown", lambda t: t.replace("free = 'EI1', 'EI2'", "free = 'EI9'"),
     "&fit free = 'EI9' is not a parameter name"),
    ("free_twice", lambda t: t.replace("free = 'EI1', 'EI2'", "free = 'EI1', 'EI1'"),
     "&fit free names parameter 'EI1' twice"),
    ("free_missing", lambda t: t.replace("free = 'EI1', 'EI2'", ""),
     "&fit free is missing"),
    ("kind_unknown", lambda t: t.replace("kind = 'tip', fy = 2.0", "kind = 'rope', fy = 2.0"),
     "&experiment 'F2': kind = 'rope', expected 'tip' or 'wire'"),
    ("wire_without_length", lambda t: t.replace("kind = 'tip', fy = 2.0", "kind = 'wire'"),
     "&experiment 'F2': kind = 'wire' needs wire_length (m)"),
    ("wire_with_force", lambda t: t.replace("kind = 'tip', fy = 2.0",
                                            "kind = 'wire', wire_length = 1.3, fy = 2.0"),
     "&experiment 'F2': kind = 'wire' does not take fx, fy or moment"),
    ("tip_with_wire_length", lambda t: t.replace("fy = 2.0", "fy = 2.0, wire_length = 1.3"),
     "&experiment 'F2': kind = 'tip' does not take wire_length"),
    ("experiment_twice", lambda t: t.replace("name = 'F4'", "name = 'F2'"),
     "&experiment name = 'F2' defined twice"),
    ("experiment_unnamed", lambda t: t.replace("name = 'F4', ", ""),
     "&experiment number 2 has no name"),
    ("no_experiments", lambda t: "\n".join(l for l in t.splitlines()
                                           if not l.startswith("&experiment")),
     "no &experiment groups: define at least one experiment"),
    ("experiment_removed", lambda t: t.replace("&experiment name = 'M3', kind = 'tip', "
                                               "moment = 3.0 /", ""),
     "line 17: field experiment = 'M3' is not defined"),
    ("fit_missing", lambda t: t.split("&fit")[0], "group &fit is missing"),
    ("fit_twice", lambda t: t + "&fit data = 'x.csv' /\n", "group &fit appears 2 times"),
    ("data_missing", lambda t: t.replace("data = 'hidden_effect.csv'", ""),
     "&fit data is missing: give the measurement CSV file"),
    ("candidate_unknown", lambda t: t.replace("'root_flex'", "'gravity'"),
     "&fit candidates = 'gravity' is not a known effect, expected one of: axial_coupling, "
     "material_cubic, elbow_flex, root_flex"),
    ("alpha_out_of_range", lambda t: t.replace("alpha = 0.01", "alpha = 1.5"),
     "&fit alpha = 1.5, expected a significance level in (0, 1)"),
    ("max_iter_zero", lambda t: t.replace("alpha = 0.01", "alpha = 0.01, max_iter = 0"),
     "&fit max_iter = 0, expected at least 1"),
    ("prior_lengths", lambda t: t.replace("alpha = 0.01", "prior_names = 'EI1', "
                                          "prior_means = 11.4"),
     "&fit prior_names, prior_means and prior_sigmas must have equal lengths (got 1, 1, 0)"),
    ("prior_not_free", lambda t: t.replace("alpha = 0.01", "prior_names = 'C1', "
                                           "prior_means = 0.0, prior_sigmas = 1.0"),
     "&fit prior_names = 'C1' is not free (free: EI1, EI2)"),
    ("prior_sigma_zero", lambda t: t.replace("alpha = 0.01", "prior_names = 'EI1', "
                                             "prior_means = 11.4, prior_sigmas = 0.0"),
     "&fit prior for 'EI1' = (11.4, 0), expected a finite mean and sigma > 0"),
    ("load_group", lambda t: t + "&load kind = 'tip', fy = 1.0 /\n",
     "group &load does not belong in an estimation deck, expected one of: beamid model "
     "experiment fit"),
    ("nbeams_mismatch", lambda t: t.replace("preset = 'pace'", "preset = 'pace', nbeams = 3"),
     "&beamid nbeams = 3 but preset 'pace' has 2 beams"),
    ("elbow_on_cantilever", lambda t: t.replace("preset = 'pace'", "preset = 'cantilever'")
     .replace("axial_coupling = 0.0", "elbow_flex = 0.001"),
     "&model elbow_flex is given but the chain has one beam"),
]


@pytest.mark.parametrize("change,expected", [c[1:] for c in BAD_DECKS],
                         ids=[c[0] for c in BAD_DECKS])
def test_malformed_estimation_deck_fails_in_both(change, expected, tmp_path, batch_exe):
    deck = _deck(tmp_path, "improve", deck_text=change)
    with pytest.raises(InputError) as info:
        read_fit_deck(deck)
    run = _batch(batch_exe, deck)
    assert run.returncode == 2, run.stderr
    assert expected in str(info.value)
    # both fronts report the same problems, one per line
    lines = [l[len("beamid-batch: error: "):] for l in run.stderr.splitlines()]
    assert lines == str(info.value).splitlines()
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("change,word", [
    (lambda t: t.replace("fy = 4.0", "fz = 4.0"), "fz"),
    (lambda t: t.replace("alpha = 0.01", "alpha = 0.01, bogus = 1"), "bogus"),
    (lambda t: t.replace("fy = 4.0", "fy = 'four'"), "experiment"),
], ids=["experiment_variable", "fit_variable", "experiment_value"])
def test_namelist_errors_fail_cleanly_in_both(change, word, tmp_path, batch_exe):
    deck = _deck(tmp_path, "fit", deck_text=change)
    with pytest.raises(InputError, match=word):
        read_fit_deck(deck)
    run = _batch(batch_exe, deck)
    assert run.returncode == 2 and len(run.stderr.splitlines()) == 1
    assert str(deck) in run.stderr and word in run.stderr.lower()
    assert not (tmp_path / "out").exists()


def test_estimation_groups_are_not_for_static_decks(tmp_path, batch_exe):
    deck = tmp_path / "static.nml"
    deck.write_text("&beamid task = 'static', output = 'out/s', preset = 'pace' /\n"
                    "&load kind = 'tip', fy = 3.0 /\n"
                    "&experiment name = 'F2', kind = 'tip', fy = 2.0 /\n")
    run = _batch(batch_exe, deck)
    assert run.returncode == 2
    assert "group &experiment is only for the estimation tasks" in run.stderr
    assert not (tmp_path / "out").exists()


def test_missing_data_file(tmp_path, batch_exe):
    deck = _deck(tmp_path, "fit", deck_text=lambda t: t.replace("hidden_effect.csv", "no.csv"))
    with pytest.raises(InputError, match="cannot open measurement file .*no.csv"):
        read_fit_deck(deck)
    run = _batch(batch_exe, deck)
    assert run.returncode == 2  # a missing input file is bad input (docs/decks.md)
    assert f"cannot open measurement file {tmp_path}/no.csv: no such file" in run.stderr
    assert not (tmp_path / "out").exists()


def test_no_convergence_writes_nothing(tmp_path, batch_exe):
    deck = _deck(tmp_path, "fit", deck_text=lambda t: t.replace("alpha = 0.01",
                                                                "max_iter = 1"))
    with pytest.raises(ConvergenceError):
        run_fit_deck(deck, plots=False)
    assert not (tmp_path / "out").exists()
    run = _batch(batch_exe, deck)
    assert run.returncode == 3 and len(run.stderr.splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_demo_deck_files_ship_for_both(tmp_path, batch_exe):
    """The shipped demo deck runs as is (relative data path, task improve)."""
    for name in ("hidden_effect.nml", "hidden_effect.csv"):
        shutil.copy(DEMO / name, tmp_path / name)
    assert _batch(batch_exe, tmp_path / "hidden_effect.nml").returncode == 0
    assert (tmp_path / "out" / "hidden_effect_ladder.csv").exists()


def test_two_groups_on_one_line_are_both_read(tmp_path, batch_exe):
    """The deck reader locates each group itself, so a second group after a
    '/' on the same line is read, by both fronts alike."""
    deck = _deck(tmp_path, "fit", deck_text=lambda t: t.replace(
        "fy = 4.0 /\n&experiment", "fy = 4.0 / &experiment"))
    assert "F6" in read_fit_deck(deck).experiments
    assert _batch(batch_exe, deck).returncode == 0
