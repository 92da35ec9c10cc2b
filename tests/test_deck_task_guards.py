"""The binding's held ladder and identify stages (beamid_api_estimation:
api_deck_task_start / api_ladder_step / api_ladder_rung, _fit, _diag /
api_deck_task_write) refuse what does not match what they hold, with an
InputError naming the input, its value and what was expected, instead of
writing or returning garbage; a deck's failure is named as beamid-batch
names it."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import beamid
from beamid import ConvergenceError, InputError, _core_estimation as _ce
from beamid._core import _call
from beamid.diagnosis import _candidate_set
from beamid.estimation import build_problem
from beamid.fit_decks import read_fit_deck, run_fit_deck

ROOT = Path(__file__).resolve().parent.parent
DEMO, SEED = ROOT / "inputs" / "demo", ROOT / "inputs" / "seed"
STAGES = ("identify_three_stages.nml", "table05_data.csv", "table16_data.csv",
          "table23_data.csv")


def _copy(folder: Path, source: Path, *names: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        shutil.copy(source / name, folder / name)
    return folder / names[0]


def _demo(folder: Path, task: str = "fit") -> Path:
    deck = _copy(folder, DEMO, "hidden_effect.nml", "hidden_effect.csv")
    deck.write_text(deck.read_text().replace("task = 'improve'", f"task = '{task}'"))
    return deck


def test_a_deck_ladders_failure_names_the_experiment_as_the_batch(tmp_path, batch_exe):
    """A solver failure inside a dynamic deck's diagnosis (RK4 at dt = 1e-5 s
    is stable at 4 elements per beam, not at the mesh test's 8) reaches
    Python named as beamid-batch names it: "(experiment 'free' of DECK)",
    not "(experiment 1)", and whole (the message is not cut to 256)."""
    deck = _copy(tmp_path, DEMO, "dynamic_hidden_effect.nml")
    rows = (DEMO / "dynamic_hidden_effect.csv").read_text().splitlines()
    (tmp_path / "dynamic_hidden_effect.csv").write_text(   # t <= 0.1 s: a short run
        "\n".join(rows[:3] + [r for r in rows[3:] if float(r.split(",")[1]) <= 0.1]) + "\n")
    deck.write_text(deck.read_text().replace("task = 'improve'", "task = 'diagnose'")
                    .replace("elements_per_beam = 4 /",
                             "elements_per_beam = 4, integrator = 'rk4', dt = 1e-5 /")
                    .replace("'drag', 'rotary_inertia', 'kelvin_voigt', 'motor_lag', 'mesh'",
                             "'mesh'"))
    run = subprocess.run([str(batch_exe), str(deck)], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 3, run.stderr
    with pytest.raises(ConvergenceError) as err:
        run_fit_deck(deck, plots=False)
    message = str(err.value)
    assert f"(experiment 'free' of {deck})" in message and "(experiment 1)" not in message
    assert message.endswith("(mesh test at twice the elements per beam)")
    # (the checking build also writes runtime warnings to stderr: the error line)
    errors = [ln for ln in run.stderr.splitlines() if ln.startswith("beamid-batch: error:")]
    assert errors == [f"beamid-batch: error: {message}"]


def test_deck_task_write_refuses_another_deck(tmp_path):
    """The held fit of one deck is not written under another deck's name."""
    demo = _demo(tmp_path / "demo")
    other = _copy(tmp_path / "t5", SEED, "table05_fit.nml", "table05_data.csv")
    with _ce.LADDER_LOCK:
        _ce.deck_task_start(str(demo))
        with pytest.raises(InputError) as err:
            _ce.deck_task_write(str(other))
        with pytest.raises(InputError, match=r"run as 'diagnose', expected '.*' run as 'fit'"):
            _ce.deck_task_write(str(demo), "diagnose")
    assert str(err.value) == (f"path: '{other}' run as 'fit', expected '{demo}' run as "
                              "'fit' (the deck api_deck_task_start started last)")
    assert not (tmp_path / "t5" / "out").exists() or not any((tmp_path / "t5" / "out").iterdir())


def test_deck_task_write_refuses_a_problems_ladder(tmp_path):
    """A ladder beamid.improve started on a problem is not written as a deck's."""
    demo = _demo(tmp_path, "improve")
    deck = read_fit_deck(demo)
    with _ce.LADDER_LOCK:
        _ce.deck_task_start(str(demo))
        beamid.improve(deck.model, deck.experiments, deck.data, free=deck.free, max_steps=0)
        with pytest.raises(InputError, match="ladder: no ended ladder of a deck"):
            _ce.deck_task_write(str(demo))
    assert not (tmp_path / "out").exists()


def test_fit_files_refuse_predictions_of_other_rows(tmp_path):
    """The deck's data changed between the fit and the write (fewer rows):
    no residuals file with predictions read past their end."""
    demo = _demo(tmp_path)
    with _ce.LADDER_LOCK:
        _ce.deck_task_start(str(demo))
        csv = tmp_path / "hidden_effect.csv"
        lines = csv.read_text().splitlines()
        csv.write_text("\n".join(lines[:-1]) + "\n")
        nrow = len(read_fit_deck(demo).data.value)
        with pytest.raises(InputError) as err:
            _ce.deck_task_write(str(demo))
    assert str(err.value) == (f"fit: predictions of {nrow + 1} rows, expected {nrow} "
                              f"(the data rows of {demo})")
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_ladder_reads_check_the_sizes_of_the_held_ladder(tmp_path):
    """api_ladder_rung, _fit and _diag with sizes other than the held
    ladder's raise instead of returning garbage or writing out of bounds."""
    demo = _demo(tmp_path, "diagnose")
    deck = read_fit_deck(demo)
    nparams = len(deck.model.names())
    _, _, _, blocks = _candidate_set(deck.model, deck.experiments, deck.candidates)
    starts, flat = _ce._blocks(blocks)
    with _ce.LADDER_LOCK:
        _ce.deck_task_start(str(demo))
        assert _ce.ladder_step()
        info = _call(_ce._api.api_ladder_rung, 1, nparams)[0]
        nfree, nrow, max_iter = int(info[0]), int(info[3]), int(info[4])
        for bad in (nparams + 33, nparams - 4):
            with pytest.raises(InputError) as err:
                _call(_ce._api.api_ladder_rung, 1, bad)
            assert str(err.value) == (f"ladder: nparams = {bad}, expected {nparams} (the "
                                      "parameters of the ladder started last)")
            with pytest.raises(InputError, match=f"nparams = {bad}, expected {nparams}"):
                _ce._fit_call(_ce._api.api_ladder_fit, nfree, False, 1, bad, nfree, nrow,
                              max_iter)
            with pytest.raises(InputError, match=f"nparams = {bad}, expected {nparams}"):
                _call(_ce._api.api_ladder_diag, 1, bad, starts.size - 1, flat.size)
        with pytest.raises(InputError) as err:
            _ce._fit_call(_ce._api.api_ladder_fit, nfree + 1, False, 1, nparams, nfree + 1,
                          nrow, max_iter)
        assert str(err.value) == (f"ladder: nfree = {nfree + 1}, nrow = {nrow}, expected "
                                  f"{nfree} and {nrow} (rung 1 of the ladder started last)")
        with pytest.raises(InputError) as err:
            _call(_ce._api.api_ladder_diag, 1, nparams, starts.size - 1, flat.size + 1)
        assert str(err.value) == (f"ladder: ncand = {starts.size - 1}, ncandp = "
                                  f"{flat.size + 1}, expected {starts.size - 1} candidates of "
                                  f"{flat.size} parameters (the ladder started last)")
        # the right sizes still read
        assert _ce.ladder_rungs(nparams, blocks)[0]["fit"]["params"].size == nparams


def test_identify_stages_in_order_and_all_before_the_write(tmp_path):
    """The identify stages start in order on one deck, not past the last,
    and the files are written only from all of them: the binding never
    fits a stage itself (so `run once` cannot silently become `twice`)."""
    deck = str(_copy(tmp_path, SEED, *STAGES))
    with _ce.LADDER_LOCK:
        with pytest.raises(InputError) as err:
            _ce.deck_task_start(deck, "identify", 2)
        assert str(err.value) == "stage: 2, expected 1 (the stages in order)"
        with pytest.raises(InputError, match="^ladder: no ended ladder of a deck"):
            _ce.deck_task_write(deck)       # the failed start holds nothing
        _ce.deck_task_start(deck, "identify", 1)
        with pytest.raises(InputError) as err:
            _ce.deck_task_write(deck)
        assert str(err.value) == ("identify: 1 of 3 stages fitted, expected all "
                                  "(api_deck_task_start each stage first)")
        with pytest.raises(InputError, match=r"^stage: 3, expected 2 \(the stages in order\)"):
            _ce.deck_task_start(deck, "identify", 3)
        for stage in (1, 2, 3):
            _ce.deck_task_start(deck, "identify", stage)
        with pytest.raises(InputError) as err:
            _ce.deck_task_start(deck, "identify", 4)
        assert str(err.value) == "identify: all 3 stages are fitted"
        for stage in (1, 2, 3):     # the failed start dropped the ladder: fit them again
            _ce.deck_task_start(deck, "identify", stage)
        written = _ce.deck_task_write(deck)
    assert len(written) == 10 and all(Path(p).exists() for p in written)


def test_a_full_prior_covariance_of_the_wrong_size():
    deck = read_fit_deck(DEMO / "hidden_effect.nml")
    names = deck.model.names()
    prior = _ce.prior_table([(names.index("EI1") + 1, 11.0, 1.0),
                             (names.index("EI2") + 1, 11.0, 1.0)])
    with pytest.raises(InputError) as err:
        _ce.fit(build_problem(deck.model, deck.experiments, deck.data), deck.model.vector(),
                np.array([names.index("EI1") + 1]), prior, prior_cov=np.ones(3))
    assert str(err.value) == "prior: prior_cov has 3 values, expected nprior**2 = 4"
