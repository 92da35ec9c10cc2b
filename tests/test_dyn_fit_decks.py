"""Estimation decks with release experiments: both fronts, same bytes; bad rows."""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import beamid
from beamid.tables import inputs_dir

BATCH = Path(sys.executable).parent / "beamid-batch"


def _copy(tmp_path: Path, table: str) -> Path:
    for name in (f"table{table}_fit.nml", f"table{table}_data.csv"):
        shutil.copy(inputs_dir("seed") / name, tmp_path / name)
    return tmp_path / f"table{table}_fit.nml"


@pytest.mark.parametrize("task", ["fit", "compare"])
def test_release_deck_same_bytes_from_both_fronts(tmp_path, task):
    """Table 22's deck (a release with the motor): beamid-batch and beamid.run
    write the same files, and the estimate is Table 22's."""
    deck = _copy(tmp_path, "22")
    deck.write_text(deck.read_text().replace("task = 'fit'", f"task = '{task}'"))
    run = subprocess.run([str(BATCH), str(deck)], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    out = tmp_path / "out"
    batch = {p.name: p.read_bytes() for p in out.iterdir()}
    shutil.rmtree(out)
    result = beamid.run(deck)
    python = {p.name: p.read_bytes() for p in out.iterdir()}
    assert batch == python and len(batch) == (3 if task == "fit" else 4)
    fitted = result if task == "fit" else result.fit
    assert fitted.estimates["r_motor"] == pytest.approx(1.0, abs=1e-4)
    rows = (out / "table22_fit_residuals.csv").read_text().splitlines()
    assert rows[1].startswith("forced,0.13,w_tip,")


def test_release_deck_reads_options(tmp_path):
    deck = _copy(tmp_path, "22")
    d = beamid.read_deck(deck)
    x = d.experiments["forced"]
    assert isinstance(x, beamid.Release)
    assert x.motor_gain == 0.2 and x.elements_per_beam == 4 and x.integrator == "implicit"


@pytest.mark.parametrize("line, words", [
    ("&experiment name = 'forced', kind = 'release', fy = 8.0, motor_gain = -1 /",
     "motor_gain = -1"),
    ("&experiment name = 'forced', kind = 'release', fy = 8.0, integrator = 'euler' /",
     "integrator = 'euler'"),
    ("&experiment name = 'forced', kind = 'tip', fy = 8.0, motor_gain = 0.2 /",
     "does not take motor_gain"),
])
def test_bad_release_experiment(tmp_path, line, words):
    deck = _copy(tmp_path, "22")
    text = deck.read_text().splitlines()
    text = [line if t.startswith("&experiment") else t for t in text]
    deck.write_text("\n".join(text) + "\n")
    with pytest.raises(beamid.InputError, match=words):
        beamid.read_deck(deck)
    run = subprocess.run([str(BATCH), str(deck)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and words in run.stderr


def test_motor_torque_without_motor_names_the_line(tmp_path):
    deck = _copy(tmp_path, "22")
    deck.write_text(deck.read_text().replace("motor_gain = 0.2", "motor_gain = 0.0"))
    csv = tmp_path / "table22_data.csv"
    csv.write_text(csv.read_text() + "forced,0.5,motor_torque,0.1,0.01\n")
    n = len(csv.read_text().splitlines())
    with pytest.raises(beamid.InputError, match=rf"table22_data.csv, line {n}.*motor_torque"):
        beamid.read_deck(deck)
    run = subprocess.run([str(BATCH), str(deck)], capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and f"line {n}" in run.stderr


def test_table15_fit_stalls_flagged_where_the_release_cannot_be_solved():
    # Table 15's noisy quarter cycle pulls mu_tip towards 0. The sign law's
    # start used to chatter below about 1e-3 ("does not settle") and the fit
    # came back flagged at its last good point; since issue 12 the release runs
    # for any mu >= 0, so the fit converges there, with mu_tip poorly
    # determined (the true 0.02 within one sigma)
    seed = inputs_dir("seed")
    model = beamid.pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.015, mu_tip=0.01,
                        rho1=0.5603, rho2=0.5437)
    data = beamid.read_measurements(seed / "table15_data.csv")
    fit = beamid.fit(model, {"free": beamid.Release(beamid.TipForce(fy=8.0),
                                                    elements_per_beam=4)},
                     data, free=("mu_elbow", "mu_tip", "rho1", "rho2"))
    assert fit.stop in ("converged", "stalled", "runaway")        # not raised
    assert 0.0 <= fit.estimates["mu_tip"] < 0.005
    assert abs(fit.estimates["mu_tip"] - 0.02) < fit.sigmas["mu_tip"]
    assert abs(fit.estimates["mu_elbow"] - 0.0108) < 0.002       # well determined
    assert fit.sigmas["rho1"] > 0.1                               # densities are not
