"""beamid-batch hands decks with release experiments to the dynamic
diagnosis (issue 14): `diagnose` and `improve` on a release deck write the
numbers of beamid.diagnose / beamid.improve (dyn_diagnosis), not those of the
static diagnosis.

The data are made here from the model without rotary inertia and friction
plus tip drag c_tip = 0.01 N s/m and the tip mass's rotary inertia J_tip =
0.01 kg m^2, at rtol 1e-11 (the fits use 1e-9), with Gaussian noise of sigma
1e-4 m from a fixed seed: tip u, w and the elbow's y at 13 times over 1.3 s,
2 elements per beam.
"""
from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

import beamid

SIGMA = 1e-4
TIMES = [round(0.1 * k, 3) for k in range(1, 14)]
BASE = beamid.pace().replace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.0, mu_tip=0.0)
CANDIDATES = ("drag", "rotary_inertia", "kelvin_voigt", "motor_lag", "mesh")

DECK = """&beamid
    task = '{task}'
    output = '{out}'
    preset = 'pace'
/
&model
    J_elbow = 0.0
    J_tip = 0.0
    mu_elbow = 0.0
    mu_tip = 0.0
/
&experiment name = 'free', kind = 'release', fy = 8.0, elements_per_beam = 2 /
&fit
    data = 'release.csv'
    free = 'rho2'
    candidates = {cands}
    alpha = 0.01
/
"""


def _write(folder: Path, task: str, cands=CANDIDATES) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    truth = BASE.replace(c_tip=0.01, J_tip=0.01)
    rel = beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=2, rtol=1e-11)
    exact = beamid.simulate_measurements(truth, {"free": rel}, ["u_tip", "w_tip", "y_elbow"],
                                         sigma=SIGMA, t=TIMES)
    rng = np.random.default_rng(14)
    value = np.asarray(exact.value) + SIGMA * rng.standard_normal(len(exact))
    lines = ["experiment,t,quantity,value,sigma"]
    lines += [f"{e},{t:g},{q},{v:.12e},{s:g}" for e, t, q, v, s in
              zip(exact.experiment, exact.t, exact.quantity, value, exact.sigma)]
    (folder / "release.csv").write_text("\n".join(lines) + "\n")
    deck = folder / f"{task}.nml"
    deck.write_text(DECK.format(task=task, out=str(folder / "out" / task),
                                cands=", ".join(f"'{c}'" for c in cands)))
    return deck


def _rows(path: Path) -> list[dict]:
    lines = path.read_text().splitlines()
    head = lines[0].split(",")
    return [dict(zip(head, line.split(","))) for line in lines[1:]]


def _same(a: float, b: float, rel=1e-8) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return a == pytest.approx(b, rel=rel, abs=1e-9)


def _run(exe: Path, deck: Path) -> None:
    done = subprocess.run([str(exe), str(deck)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr


def test_batch_diagnose_of_a_release_deck_is_the_dynamic_diagnosis(tmp_path, batch_exe):
    deck = _write(tmp_path, "diagnose")
    _run(batch_exe, deck)
    rows = _rows(tmp_path / "out" / "diagnose_ranking.csv")
    from beamid.fit_decks import read_fit_deck
    fd = read_fit_deck(deck)
    fit = beamid.fit(fd.model, fd.experiments, fd.data, free=fd.free)
    diag = beamid.diagnose(fit, fd.candidates, alpha=fd.alpha)
    # one row per tested parameter, candidates in the ranked order
    effects = list(dict.fromkeys(r["effect"] for r in rows))
    assert effects == [c.effect for c in diag]
    assert "motor_lag" in effects and diag["motor_lag"].state == "not seen by these experiments"
    assert [r["state"] for r in rows if r["effect"] == "motor_lag"] == \
        ["not seen by these experiments"]
    for c in diag:
        mine = [r for r in rows if r["effect"] == c.effect]
        if c.state != "tested":
            continue
        assert _same(float(mine[0]["score_drop"]), c.score_drop)
        if c.effect != "mesh":
            # the block as tested: drag and rotary inertia reduced to their
            # tip members, the elbow's left at null
            assert tuple(r["parameter"] for r in mine) == c.params
        if c.refit:
            assert _same(float(mine[0]["refit_drop"]), c.chi2_drop)
            for r in mine[:len(c.params)] if c.effect != "mesh" else ():
                assert _same(float(r["estimate"]), c.estimate[r["parameter"]])
    assert diag.verdict is not None and effects[0] == diag.verdict.effect
    assert rows[0]["significant"] == "1"


def test_batch_improve_of_a_release_deck_is_the_dynamic_ladder(tmp_path, batch_exe):
    # the mesh is tested by the diagnose deck above; here the ladder's steps
    deck = _write(tmp_path, "improve", ("drag", "rotary_inertia", "kelvin_voigt"))
    _run(batch_exe, deck)
    ladder_rows = _rows(tmp_path / "out" / "improve_ladder.csv")
    from beamid.fit_decks import read_fit_deck
    fd = read_fit_deck(deck)
    ladder = beamid.improve(fd.model, fd.experiments, fd.data, free=fd.free,
                            candidates=fd.candidates, alpha=fd.alpha)
    assert [r["effect"] for r in ladder_rows] == ["start"] + list(ladder.effects)
    assert set(ladder.effects) == {"drag", "rotary_inertia"}
    for r, s in zip(ladder_rows, ladder.steps):
        assert _same(float(r["chi2"]), s.chi2, rel=1e-7) and int(r["dof"]) == s.dof
    est = {r["name"]: r for r in _rows(tmp_path / "out" / "improve_estimates.csv")}
    for n, v in ladder.fit.estimates.items():
        assert _same(float(est[n]["estimate"]), v, rel=1e-7)
