"""The improve ladder runs a rung per call into Fortran (beamid_ladder's
ladder_step): beamid.improve's progress bar moves per rung, and an improve
deck (beamid improve DECK, beamid.run) runs its ladder once, for the files
(byte for byte beamid-batch's) and for the Python result."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

import beamid
from beamid import _core, _core_estimation as _ce, diagnosis
from beamid.fit_decks import run_fit_deck

DEMO = Path(__file__).resolve().parent.parent / "inputs" / "demo"


def _elbow_flex_problem():
    truth = beamid.pace(axial_coupling=0.0, elbow_flex=0.004)
    exps = {f"F{f:g}": beamid.TipForce(fy=f) for f in (2.0, 4.0, 6.0, 8.0)}
    data = beamid.simulate_measurements(truth, exps, ["x_tip", "y_tip", "tip_angle"],
                                        sigma=1e-4)
    return beamid.pace(axial_coupling=0.0), exps, data


def test_improve_draws_its_bar_a_rung_at_a_time(monkeypatch, capsys):
    pytest.importorskip("tqdm")
    from beamid.progress import progress

    steps = []
    real_step = _ce.ladder_step

    def step(run) -> bool:
        done = real_step(run)
        steps.append(done)
        return done

    seen = []

    def drawn(iterable, total=None, desc="", enabled=None):   # as on a terminal
        seen.append((total, desc))
        return progress(iterable, total=total, desc=desc, enabled=True)

    monkeypatch.setattr(_ce, "ladder_step", step)
    monkeypatch.setattr(diagnosis, "progress", drawn)
    model, exps, data = _elbow_flex_problem()
    ladder = beamid.improve(model, exps, data, free=("EI1", "EI2"),
                            candidates=("elbow_flex", "axial_coupling"))
    # one call per rung diagnosed, the last one ends the ladder
    assert ladder.effects == ("elbow_flex",)
    assert steps == [False, True]
    assert seen == [(3, "improve")]            # at most one rung per candidate + the start
    assert "improve" in capsys.readouterr().err


def test_improve_deck_runs_its_ladder_once_and_writes_the_batch_bytes(tmp_path, batch_exe,
                                                                     monkeypatch):
    decks = {}
    for side in ("batch", "python"):
        (tmp_path / side).mkdir()
        for name in ("hidden_effect.nml", "hidden_effect.csv"):
            shutil.copy(DEMO / name, tmp_path / side / name)
        decks[side] = tmp_path / side / "hidden_effect.nml"
    run = subprocess.run([str(batch_exe), str(decks["batch"])], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0, run.stderr

    calls = []
    for module, name in ((_ce, "deck_task_start"), (_ce, "ladder_start"),
                         (_core, "run_deck")):
        real = getattr(module, name)
        monkeypatch.setattr(module, name, lambda *a, _real=real, _name=name:
                            calls.append(_name) or _real(*a))
    _, files, ladder = run_fit_deck(decks["python"], plots=False)
    assert calls == ["deck_task_start"]      # one ladder, no second run for the files
    names = sorted(p.name for p in (tmp_path / "batch" / "out").iterdir())
    assert sorted(p.name for p in files) == names and len(names) == 5
    for name in names:
        assert (tmp_path / "python" / "out" / name).read_bytes() == \
            (tmp_path / "batch" / "out" / name).read_bytes(), name
    # the result is the ladder the files hold
    rows = (tmp_path / "python" / "out" / "hidden_effect_ladder.csv").read_text().splitlines()
    assert [r.split(",")[1] for r in rows[1:]] == ["start", *ladder.effects]
    assert [float(r.split(",")[2]) for r in rows[1:]] == pytest.approx(
        [s.chi2 for s in ladder.steps], rel=1e-12)

    calls.clear()
    assert beamid.run(decks["python"]).effects == ladder.effects
    assert calls == ["deck_task_start"]


def test_improve_ladders_from_two_threads_run_side_by_side():
    """Each improve owns its ladder (a handle of the binding, no lock): two
    ladders started from two threads overlap and each ends as it does
    alone."""
    import threading

    model, exps, data = _elbow_flex_problem()
    truth2 = beamid.pace(axial_coupling=0.0, root_flex=0.003)
    data2 = beamid.simulate_measurements(truth2, exps, ["x_tip", "y_tip", "tip_angle"],
                                         sigma=1e-4)
    cases = [(data, ("elbow_flex", "axial_coupling")), (data2, ("root_flex", "elbow_flex"))]
    alone = [beamid.improve(model, exps, d, free=("EI1", "EI2"), candidates=c)
             for d, c in cases]
    assert [a.effects for a in alone] == [("elbow_flex",), ("root_flex",)]
    got: dict[int, object] = {}

    def run(k: int) -> None:
        for _ in range(3):     # several ladders each, so that they overlap
            got[k] = beamid.improve(model, exps, cases[k][0], free=("EI1", "EI2"),
                                    candidates=cases[k][1])

    threads = [threading.Thread(target=run, args=(k,)) for k in (0, 1)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in (0, 1):
        assert got[k].effects == alone[k].effects
        assert [s.chi2 for s in got[k].steps] == [s.chi2 for s in alone[k].steps]


def test_two_ladder_handles_interleaved_each_end_as_alone():
    """Two ladders open at once, stepped in turn: each handle returns its
    own rungs, equal to those of its ladder run alone, and closing them
    releases both."""
    from beamid.diagnosis import _candidate_set
    from beamid.estimation import _free_indices, _prior_arrays, build_problem

    model, exps, data = _elbow_flex_problem()
    truth2 = beamid.pace(axial_coupling=0.0, root_flex=0.003)
    data2 = beamid.simulate_measurements(truth2, exps, ["x_tip", "y_tip", "tip_angle"],
                                         sigma=1e-4)
    cands = ("elbow_flex", "axial_coupling", "root_flex")
    with_mesh, effects, _names, blocks = _candidate_set(model, exps, cands)
    free_idx = _free_indices(model, ("EI1", "EI2"))[1]
    ptable = _prior_arrays(model, ("EI1", "EI2"), None)[1]
    nparams = model.vector().size

    def start(d):
        return _ce.ladder_start(build_problem(model, exps, d), model.vector(), free_idx,
                                ptable, blocks, with_mesh, 0.01, len(effects))

    def rungs(run):
        return [(r["effect"], r["fit"]["chi2"], tuple(r["fit"]["params"]))
                for r in _ce.ladder_rungs(nparams, blocks, run)]

    alone = []
    for d in (data, data2):
        with start(d) as run:
            while not _ce.ladder_step(run):
                pass
            alone.append(rungs(run))
    assert [[r[0] for r in a] for a in alone] == [[None, "1"], [None, "3"]]
    before = _ce.ladders_open()
    a, b = start(data), start(data2)
    assert a.id != b.id and _ce.ladders_open() == before + 2
    done = [False, False]
    while not all(done):            # a rung of a, a rung of b, ...
        for k, run in enumerate((a, b)):
            if not done[k]:
                done[k] = _ce.ladder_step(run)
    assert [rungs(a), rungs(b)] == alone
    a.close()
    b.close()
    b.close()                       # again: nothing happens
    assert _ce.ladders_open() == before and a.closed
    with pytest.raises(ValueError, match="closed"):
        _ce.ladder_step(a)
    with pytest.raises(beamid.InputError, match=r"^handle: 0, expected the handle of an "
                       r"open ladder \(api_ladder_open, not closed\)$"):
        _core._call(_ce._api.api_ladder_handle_step, 0)


def test_a_ladder_is_indexed_by_rung_and_by_added_effect():
    model, exps, data = _elbow_flex_problem()
    ladder = beamid.improve(model, exps, data, free=("EI1", "EI2"),
                            candidates=("elbow_flex", "axial_coupling"))
    assert len(ladder) == 2 and [s.step for s in ladder] == [0, 1]
    assert ladder[0].effect is None and ladder[-1] is ladder.steps[-1]
    assert ladder["elbow_flex"] is ladder[1] and "elbow_flex" in ladder
    assert "axial_coupling" not in ladder
    assert abs(ladder["elbow_flex"].estimates["elbow_flex"] - 0.004) < 3e-4
    assert ladder[1].chi2 < ladder[0].chi2
    with pytest.raises(KeyError, match="axial_coupling.*added: elbow_flex"):
        ladder["axial_coupling"]
    with pytest.raises(TypeError):
        ladder[1.0]
