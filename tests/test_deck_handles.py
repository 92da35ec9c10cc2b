"""A deck is read once per run (issue 25, the fronts): the deck file and
each measurement file it names are opened once by `beamid fit` / `beamid run`
and by beamid-batch (counted under strace), and a deck's run is held by the
handle its caller owns (beamid._core.DeckHandle), not by module state found
again by path: two handles of one deck run two tasks side by side."""
from __future__ import annotations

import gc
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from beamid import InputError, _core, _core_estimation as _ce
from beamid.fit_decks import read_fit_deck, run_fit_deck

ROOT = Path(__file__).resolve().parent.parent
SEED, DEMO = ROOT / "inputs" / "seed", ROOT / "inputs" / "demo"
STRACE = shutil.which("strace")


def _copy(folder: Path, source: Path, *names: str) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        shutil.copy(source / name, folder / name)
    return [folder / name for name in names]


def _opens(cmd: list[str], files: list[Path], cwd: Path) -> dict[str, int]:
    """How often the command opens each file (openat under strace -f)."""
    run = subprocess.run([STRACE, "-f", "-e", "trace=open,openat", "-o", "/dev/stderr", *cmd],
                         capture_output=True, text=True, check=False, cwd=cwd, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    lines = run.stderr.splitlines()
    assert any("openat" in line for line in lines)
    return {f.name: sum(f'"{f}"' in line for line in lines) for f in files}


def _beamid() -> list[str]:
    exe = Path(sys.executable).with_name("beamid")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "beamid"]


@pytest.mark.skipif(STRACE is None, reason="needs strace")
@pytest.mark.parametrize("front", ["beamid fit", "beamid-batch"])
def test_fit_deck_and_its_csv_are_opened_once(front, tmp_path, batch_exe):
    """`beamid fit --no-plots table14_fit.nml` opened the deck 8 times and
    its CSV 14 times; now each once, as beamid-batch."""
    deck, csv = _copy(tmp_path, SEED, "table14_fit.nml", "table14_data.csv")
    cmd = ([*_beamid(), "fit", "--no-plots", str(deck)] if front == "beamid fit"
           else [str(batch_exe), str(deck)])
    assert _opens(cmd, [deck, csv], tmp_path) == {deck.name: 1, csv.name: 1}


@pytest.mark.skipif(STRACE is None, reason="needs strace")
def test_identify_deck_opens_each_stage_file_once(tmp_path):
    """A three-stage identify deck run by `beamid run`: the deck and its
    three CSVs, each once."""
    files = _copy(tmp_path, SEED, "identify_three_stages.nml", "table05_data.csv",
                  "table16_data.csv", "table23_data.csv")
    cmd = [*_beamid(), "run", "--no-plots", str(files[0])]
    assert _opens(cmd, files, tmp_path) == {f.name: 1 for f in files}


@pytest.mark.skipif(STRACE is None, reason="needs strace")
def test_static_deck_run_opens_the_deck_once(tmp_path):
    deck = _copy(tmp_path, SEED, "table02_c05.nml")[0]
    assert _opens([*_beamid(), "run", str(deck)], [deck], tmp_path) == {deck.name: 1}


def test_two_handles_of_one_deck_hold_two_runs(tmp_path):
    """The binding's deck runs are found by handle only: a fit and a
    diagnosis of the same deck file started side by side each write their
    own task's files from their own ladder."""
    deck = _copy(tmp_path, DEMO, "hidden_effect.nml", "hidden_effect.csv")[0]
    with _core.DeckHandle(deck) as a, _core.DeckHandle(deck) as b:
        assert a.id != b.id
        _ce.deck_task_start(a, "fit")
        _ce.deck_task_start(b, "diagnose")
        while not _ce.ladder_step(b):                   # b's rung; a is untouched
            pass
        assert len(_ce.ladder_rungs(len(read_fit_deck(deck).model.names()), [], a)) == 1
        fa = _ce.deck_task_write(a, output="out/a")
        fb = _ce.deck_task_write(b, output="out/b")
    assert sorted(Path(p).name for p in fa) == ["a_covariance.csv", "a_estimates.csv",
                                                 "a_residuals.csv"]
    assert "b_ranking.csv" in [Path(p).name for p in fb]
    # the fit of both ladders is the same fit: the estimates agree byte for byte
    assert (tmp_path / "out" / "a_estimates.csv").read_bytes() == \
        (tmp_path / "out" / "b_estimates.csv").read_bytes()


def test_handles_are_released(tmp_path):
    """close() (or the end of a with block, or the deck's collection) frees
    the deck in the extension; a closed or unknown handle is refused."""
    deck = _copy(tmp_path, DEMO, "hidden_effect.nml", "hidden_effect.csv")[0]
    gc.collect()
    before = _core.decks_open()
    handle = _core.DeckHandle(deck)
    assert _core.decks_open() == before + 1
    handle.close()
    handle.close()                      # again: nothing happens
    assert _core.decks_open() == before and handle.closed
    with pytest.raises(ValueError, match="closed"):
        handle.values()
    fd = read_fit_deck(deck)
    assert _core.decks_open() == before + 1 and fd.handle is not None
    run_fit_deck(fd, plots=False)
    del fd
    gc.collect()
    assert _core.decks_open() == before
    with pytest.raises(InputError, match=r"handle: 0, expected the handle of an open deck"):
        _core._call(_core._deck_api.api_deck_handle_sizes, 0)


def test_a_bad_deck_holds_no_handle(tmp_path):
    bad = tmp_path / "bad.nml"
    bad.write_text("&beamid task = 'fit', nbeams = 0 /\n")
    before = _core.decks_open()
    with pytest.raises(InputError, match="bad.nml"):
        _core.DeckHandle(bad)
    assert _core.decks_open() == before


def test_a_run_uses_the_deck_as_opened(tmp_path):
    """The run reads nothing again: a CSV changed after the open changes
    neither the rows the handle returns nor the files its run writes (the
    path-based entries read the deck again and had to refuse this case)."""
    deck, csv = _copy(tmp_path, DEMO, "hidden_effect.nml", "hidden_effect.csv")
    with _core.DeckHandle(deck) as handle:
        rows = handle.data()
        csv.write_text("\n".join(csv.read_text().splitlines()[:-1]) + "\n")   # a row less
        assert len(handle.data()[1]) == len(rows[1]) == handle.values()["ndata"]
        _ce.deck_task_start(handle, "fit")
        files = _ce.deck_task_write(handle)
    residuals = next(Path(p) for p in files if p.endswith("_residuals.csv"))
    assert len(residuals.read_text().splitlines()) == len(rows[1]) + 1    # header + rows


def test_identify_stages_in_order_on_a_handle(tmp_path):
    """The stages of an identify deck start in order on its handle and the
    files are written only from all of them."""
    deck = _copy(tmp_path, SEED, "identify_three_stages.nml", "table05_data.csv",
                 "table16_data.csv", "table23_data.csv")[0]
    with _core.DeckHandle(deck) as handle:
        with pytest.raises(InputError) as err:
            _ce.deck_task_start(handle, "identify", 2)
        assert str(err.value) == "stage: 2, expected 1 (the stages in order)"
        with pytest.raises(InputError, match="^ladder: no ended ladder of "):
            _ce.deck_task_write(handle)
        _ce.deck_task_start(handle, "identify", 1)
        with pytest.raises(InputError) as err:
            _ce.deck_task_write(handle)
        assert str(err.value) == ("identify: 1 of 3 stages fitted, expected all "
                                  "(deck_run_start each stage first)")
        with pytest.raises(InputError) as err:     # the stage's ladder has one rung
            _core._call(_core._deck_api.api_deck_handle_rung, handle.id, 2, 3)
        assert str(err.value) == "ladder: rung 2, expected 1..1 (start and step a ladder first)"
