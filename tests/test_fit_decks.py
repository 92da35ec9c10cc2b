"""Estimation decks: the demo deck runs, writes its files, and agrees with the API."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import beamid
from beamid import InputError
from beamid.fit_decks import read_fit_deck, run_fit_deck

DEMO = Path(__file__).resolve().parent.parent / "inputs" / "demo"


@pytest.fixture()
def demo(tmp_path):
    for name in ("hidden_effect.nml", "hidden_effect.csv"):
        shutil.copy(DEMO / name, tmp_path / name)
    return tmp_path / "hidden_effect.nml"


def test_demo_deck_improve_finds_both_hidden_effects(demo):
    text, files, ladder = run_fit_deck(demo, plots=False)
    assert ladder.effects == ("axial_coupling", "elbow_flex")
    assert ladder.steps[0].chi2_per_dof > 1000 and ladder.steps[-1].chi2_per_dof < 2.0
    est = ladder.fit.estimates
    sig = ladder.fit.sigmas
    for name, truth in (("EI1", 11.413), ("EI2", 11.275), ("axial_coupling", 1.0),
                        ("elbow_flex", 0.003)):
        assert abs(est[name] - truth) < 3 * sig[name], name
    assert all(f.exists() for f in files)
    rows = (demo.parent / "out" / "hidden_effect_ladder.csv").read_text().splitlines()
    assert rows[0] == "step,effect,chi2,dof,chi2_per_dof" and len(rows) == 4
    assert "not explained by any known effect" in text


def test_deck_files_match_the_python_api(demo):
    deck = read_fit_deck(demo)
    deck = type(deck)(**{**deck.__dict__, "task": "diagnose"})
    _, files, diag = run_fit_deck(deck, plots=False)
    direct = beamid.fit(deck.model, deck.experiments, deck.data, free=deck.free)
    lines = Path(f"{deck.output_prefix}_estimates.csv").read_text().splitlines()
    values = {l.split(",")[0]: float(l.split(",")[1]) for l in lines[1:3]}
    np.testing.assert_allclose([values["EI1"], values["EI2"]],
                               [direct.estimates["EI1"], direct.estimates["EI2"]], rtol=1e-12)
    ranking = Path(f"{deck.output_prefix}_ranking.csv").read_text().splitlines()
    assert ranking[1].split(",")[1] == diag.candidates[0].effect == "axial_coupling"


def test_bad_estimation_decks(tmp_path, demo):
    text = demo.read_text()
    bad = tmp_path / "bad.nml"
    bad.write_text(text.replace("free = 'EI1', 'EI2'", "free = 'EI9'"))
    with pytest.raises(InputError, match="free = 'EI9' is not a parameter name"):
        read_fit_deck(bad)
    bad.write_text(text.replace("kind = 'tip', fy = 2.0", "kind = 'rope', fy = 2.0"))
    with pytest.raises(InputError, match="kind = 'rope'"):
        read_fit_deck(bad)
    bad.write_text(text.replace("&experiment name = 'M3', kind = 'tip', moment = 3.0 /", ""))
    with pytest.raises(InputError, match="field experiment = 'M3' is not defined"):
        read_fit_deck(bad)


def test_a_fit_deck_runs_as_its_file_reads(demo):
    """The Fortran runs the deck file (its fit once, for the files and the
    result): a FitDeck with a field other than task replaced raises instead
    of labelling the file's fit with the replaced field (EI2 with EI1's
    sigma); a replaced task runs."""
    import dataclasses

    deck = read_fit_deck(demo)
    swapped = dataclasses.replace(deck, task="fit", free=("EI2", "EI1"))
    with pytest.raises(InputError) as err:
        run_fit_deck(swapped, plots=False)
    assert str(err.value) == (
        f"run_fit_deck: free = ('EI2', 'EI1'), expected ('EI1', 'EI2') (as {demo} reads: a "
        "FitDeck runs as its file reads, only task and output may be replaced; write the "
        "change into the deck file)")
    other = dataclasses.replace(deck, data=dataclasses.replace(deck.data,
                                                               value=deck.data.value * 1.01),
                                alpha=0.05)
    with pytest.raises(InputError, match=r"^run_fit_deck: data differs; alpha = 0\.05, "
                                         r"expected 0\.01 \(as "):
        run_fit_deck(other, plots=False)
    assert not (demo.parent / "out").exists()
    from beamid.fit_decks import _same      # NaN fields (a value not given) compare equal
    assert _same({"a": (float("nan"), np.array([1.0, np.nan]))},
                 {"a": (float("nan"), np.array([1.0, np.nan]))})
    assert not _same((1.0, "EI1"), (1.0, "EI2")) and not _same(np.zeros(2), np.zeros(3))
    fit = run_fit_deck(dataclasses.replace(deck, task="fit"), plots=False)[2]
    direct = beamid.fit(deck.model, deck.experiments, deck.data, free=deck.free)
    assert fit.free == deck.free == ("EI1", "EI2")
    assert (fit.estimates, fit.sigmas) == (direct.estimates, direct.sigmas)


@pytest.mark.parametrize("task", ["diagnose", "improve"])
def test_deck_progress_bar_says_its_task(task, demo, monkeypatch):
    """A diagnose deck is one diagnosis: no bar (as before the fit ran
    once); an improve deck's bar is labelled improve, drawn on a tty only."""
    import beamid.diagnosis as diagnosis

    bars = []
    real = diagnosis.progress
    monkeypatch.setattr(diagnosis, "progress", lambda it, total=None, desc="", enabled=None:
                        bars.append((desc, enabled)) or real(it, total, desc, enabled))
    deck = read_fit_deck(demo)
    run_fit_deck(type(deck)(**{**deck.__dict__, "task": task}), plots=False)
    assert bars == [("diagnose", False)] if task == "diagnose" else bars == [("improve", None)]


def test_a_fit_deck_with_another_output_writes_there(demo, tmp_path):
    """`beamid demo` replaces its decks' output: the files go there (the
    bytes of the deck's own run), none next to the deck file."""
    import dataclasses

    deck = read_fit_deck(demo)
    own = run_fit_deck(dataclasses.replace(deck, task="compare"), plots=False)[1]
    moved = dataclasses.replace(deck, task="compare", output=str(tmp_path / "elsewhere" / "x"))
    files = run_fit_deck(moved, plots=False)[1]
    assert [p.parent for p in files] == [tmp_path / "elsewhere"] * 4
    assert sorted(p.name.replace("x_", "hidden_effect_") for p in files) == \
        sorted(p.name for p in own)
    for a in own:
        b = tmp_path / "elsewhere" / a.name.replace("hidden_effect_", "x_")
        assert b.read_bytes() == a.read_bytes(), a.name
