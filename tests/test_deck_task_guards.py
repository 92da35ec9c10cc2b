"""The ladders and identify stages a handle holds (a deck's run,
beamid_api_deck: api_deck_handle_start / _step / _rung, _fit, _diag /
_write; a problem's ladder, beamid_api_estimation api_ladder_open and its
api_ladder_handle_* entries) refuse what does not match what they hold,
with an InputError naming the input, its value and what was expected,
instead of writing or returning garbage; a deck's failure is named as
beamid-batch names it."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import beamid
from beamid import ConvergenceError, InputError, _core_estimation as _ce
from beamid._core import DeckHandle, _call
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


def test_deck_task_entries_take_a_handle_not_a_path(tmp_path):
    """The run of a deck lives in its handle: a path is refused (no run is
    found again by path), and a handle writes its own deck's files only."""
    demo = _demo(tmp_path / "demo")
    other = _copy(tmp_path / "t5", SEED, "table05_fit.nml", "table05_data.csv")
    for entry in (_ce.deck_task_start, _ce.deck_task_write):
        with pytest.raises(InputError) as err:
            entry(str(demo))
        assert str(err.value) == (f"deck: '{demo}', expected a beamid._core.DeckHandle (the "
                                  "run of a deck is held by its handle, not found by path)")
    with DeckHandle(demo) as a, DeckHandle(other) as b:
        _ce.deck_task_start(a)
        with pytest.raises(InputError) as err:
            _ce.deck_task_write(b)          # b ran nothing: a's fit is not b's
        assert str(err.value) == (f"ladder: no ended ladder of {other} (deck_run_start and "
                                  "deck_run_step first)")
        written = _ce.deck_task_write(a)
    assert written and all(Path(p).parent == tmp_path / "demo" / "out" for p in written)
    assert not (tmp_path / "t5" / "out").exists() or not any((tmp_path / "t5" / "out").iterdir())


def test_a_problems_ladder_leaves_a_decks_run_alone(tmp_path):
    """A ladder beamid.improve runs on a problem has its own handle: a deck's
    run started before it writes the files of its own fit afterwards."""
    demo = _demo(tmp_path, "improve")
    deck = read_fit_deck(demo)
    with DeckHandle(demo) as handle:
        _ce.deck_task_start(handle, "fit")
        beamid.improve(deck.model, deck.experiments, deck.data, free=deck.free, max_steps=0)
        _ce.deck_task_write(handle, output="out/after")
    with DeckHandle(demo) as handle:
        _ce.deck_task_start(handle, "fit")
        _ce.deck_task_write(handle, output="out/alone")
    for name in ("estimates", "covariance", "residuals"):
        assert (tmp_path / "out" / f"after_{name}.csv").read_bytes() == \
            (tmp_path / "out" / f"alone_{name}.csv").read_bytes()


def test_ladder_reads_check_the_sizes_of_the_held_ladder(tmp_path):
    """The rung, fit and diag entries of a handle with sizes other than its
    ladder's raise instead of returning garbage or writing out of bounds."""
    demo = _demo(tmp_path, "diagnose")
    deck = read_fit_deck(demo)
    nparams = len(deck.model.names())
    _, _, _, blocks = _candidate_set(deck.model, deck.experiments, deck.candidates)
    starts, flat = _ce._blocks(blocks)
    api = _ce._deck_api
    with DeckHandle(demo) as handle:
        h = handle.id
        _ce.deck_task_start(handle)
        assert _ce.ladder_step(handle)
        info = _call(api.api_deck_handle_rung, h, 1, nparams)[0]
        nfree, nrow, max_iter = int(info[0]), int(info[3]), int(info[4])
        for bad in (nparams + 33, nparams - 4):
            with pytest.raises(InputError) as err:
                _call(api.api_deck_handle_rung, h, 1, bad)
            assert str(err.value) == (f"ladder: nparams = {bad}, expected {nparams} (the "
                                      f"parameters of the deck of handle {h})")
            with pytest.raises(InputError, match=f"nparams = {bad}, expected {nparams}"):
                _ce._fit_call(api.api_deck_handle_fit, nfree, False, h, 1, bad, nfree, nrow,
                              max_iter)
            with pytest.raises(InputError, match=f"nparams = {bad}, expected {nparams}"):
                _call(api.api_deck_handle_diag, h, 1, bad, starts.size - 1, flat.size)
        with pytest.raises(InputError) as err:
            _ce._fit_call(api.api_deck_handle_fit, nfree + 1, False, h, 1, nparams, nfree + 1,
                          nrow, max_iter)
        assert str(err.value) == (f"ladder: nfree = {nfree + 1}, nrow = {nrow}, expected "
                                  f"{nfree} and {nrow} (rung 1 of the deck of handle {h})")
        with pytest.raises(InputError) as err:
            _call(api.api_deck_handle_diag, h, 1, nparams, starts.size - 1, flat.size + 1)
        assert str(err.value) == (f"ladder: ncand = {starts.size - 1}, ncandp = "
                                  f"{flat.size + 1}, expected {starts.size - 1} candidates of "
                                  f"{flat.size} parameters (the deck of handle {h})")
        # the right sizes still read
        assert _ce.ladder_rungs(nparams, blocks, handle)[0]["fit"]["params"].size == nparams


def test_problem_ladder_reads_check_the_sizes(tmp_path):
    """The same refusals from a problem's ladder (api_ladder_handle_*),
    naming its handle."""
    deck = read_fit_deck(_demo(tmp_path, "diagnose"))
    names = deck.model.names()
    _, _, _, blocks = _candidate_set(deck.model, deck.experiments, deck.candidates)
    free = np.array([names.index(n) + 1 for n in deck.free], np.int32)
    with _ce.ladder_start(build_problem(deck.model, deck.experiments, deck.data),
                          deck.model.vector(), free, _ce.prior_table([]), blocks, False, 0.01,
                          0) as run:
        h = run.id
        assert _ce.ladder_step(run)
        bad = len(names) + 33
        with pytest.raises(InputError) as err:
            _call(_ce._api.api_ladder_handle_rung, h, 1, bad)
        assert str(err.value) == (f"ladder: nparams = {bad}, expected {len(names)} (the "
                                  f"parameters of the ladder of handle {h})")
        with pytest.raises(InputError) as err:
            _call(_ce._api.api_ladder_handle_rung, h, 2, len(names))
        assert str(err.value) == "ladder: rung 2, expected 1..1 (start and step a ladder first)"
        assert len(_ce.ladder_rungs(len(names), blocks, run)) == 1


def test_identify_stages_in_order_and_all_before_the_write(tmp_path):
    """The identify stages start in order on one deck's handle, not past the
    last, and the files are written only from all of them: the binding
    never fits a stage itself (so `run once` cannot silently become
    `twice`)."""
    with DeckHandle(_copy(tmp_path, SEED, *STAGES)) as deck:
        with pytest.raises(InputError) as err:
            _ce.deck_task_start(deck, "identify", 2)
        assert str(err.value) == "stage: 2, expected 1 (the stages in order)"
        with pytest.raises(InputError, match="^ladder: no ended ladder of "):
            _ce.deck_task_write(deck)       # the failed start holds nothing
        _ce.deck_task_start(deck, "identify", 1)
        with pytest.raises(InputError) as err:
            _ce.deck_task_write(deck)
        assert str(err.value) == ("identify: 1 of 3 stages fitted, expected all "
                                  "(deck_run_start each stage first)")
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
