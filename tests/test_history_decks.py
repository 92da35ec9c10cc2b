"""Load histories in decks (issue 28): the &history group in simulate and
estimation decks, run by beamid-batch and by the beamid command alike, and its
errors naming file, line and field."""
from __future__ import annotations

import io
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import beamid
from beamid.decks import read_deck
from beamid.fit_decks import read_fit_deck, run_fit_deck

ROOT = Path(__file__).resolve().parent.parent
DEMO = ROOT / "inputs" / "demo"
BEAMID = Path(sys.executable).parent / "beamid"

SIM = """&beamid task = 'simulate', output = 'out/h', preset = 'pace' /
&model J_elbow = 0.0, J_tip = 0.0 /
&load kind = 'tip', fy = 0.0 /
&simulate t_end = 0.2, n_out = 5 /
"""


def _run(argv, cwd):
    return subprocess.run([str(a) for a in argv], capture_output=True, text=True, cwd=cwd)


def _deck(tmp_path, text, name="deck.nml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_simulate_deck_same_in_both_programs(tmp_path, batch_exe):
    """The hammer-test deck: one summary line and the same history file from
    beamid-batch and `beamid simulate DECK`, with the hammer's work column;
    the run is beamid.simulate's with the deck's HalfSine."""
    shutil.copy(DEMO / "hammer_test.nml", tmp_path / "hammer_test.nml")
    batch = _run([batch_exe, "hammer_test.nml"], tmp_path)
    assert batch.returncode == 0, batch.stderr
    csv = tmp_path / "out" / "hammer_test_history.csv"
    first = csv.read_text()     # the batch's; the command writes the file again
    cli = _run([BEAMID, "simulate", "hammer_test.nml", "--no-plots"], tmp_path)
    assert cli.returncode == 0, cli.stderr
    assert cli.stdout.splitlines()[0] == batch.stdout.splitlines()[0]
    assert "tip w at the end 0.0032545 m" in batch.stdout
    head = first.splitlines()[0].split(",")
    assert head[head.index("motor") + 1] == "tip_fy"
    a = np.loadtxt(csv, delimiter=",", skiprows=1)
    b = np.loadtxt(io.StringIO(first), delimiter=",", skiprows=1)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)
    deck = read_deck(tmp_path / "hammer_test.nml")
    assert deck.simulate["loads"] == [("tip_fy", beamid.HalfSine(20.0, 0.001))]


def test_spin_up_deck_and_its_hub_column(tmp_path, batch_exe):
    shutil.copy(DEMO / "spin_up.nml", tmp_path / "spin_up.nml")
    batch = _run([batch_exe, "spin_up.nml"], tmp_path)
    assert batch.returncode == 0, batch.stderr
    rows = (tmp_path / "out" / "spin_up_history.csv").read_text().splitlines()
    head = rows[0].split(",")
    last = [float(x) for x in rows[-1].split(",")]
    hub, energy = last[head.index("hub")], last[head.index("energy")]
    assert hub == pytest.approx(3.8742e-06, rel=1e-4) and energy == pytest.approx(hub, rel=1e-3)


def test_fit_deck_with_a_hammer_history(tmp_path):
    """hammer_fit.nml: the release carries the deck's HalfSine in Python as in
    the Fortran run; EI1 and rho1 within 2 sigma of the truth."""
    for name in ("hammer_fit.nml", "hammer_test.csv"):
        shutil.copy(DEMO / name, tmp_path / name)
    deck = read_fit_deck(tmp_path / "hammer_fit.nml")
    assert deck.experiments["hammer"].loads == (("tip_fy", beamid.HalfSine(20.0, 0.01)),)
    _, files, fit = run_fit_deck(deck, plots=False)
    assert fit.stop == "converged" and len(files) == 3
    for name, true in (("EI1", 11.413), ("rho1", 0.532)):
        assert abs(fit.estimates[name] - true) < 2 * fit.sigmas[name], name


@pytest.mark.parametrize("group, message", [
    ("&history target = 'tip_fy', form = 'table', t = 0.0, 0.2, 0.1, value = 0, 1, 0 /",
     "deck.nml, line 5: &history t(3) = 0.10000000 is not after t(2) = 0.20000000 "
     "(times must increase)"),
    ("&history target = 'tip_fy', form = 'step', amplitude = 1.0, start = 0.5 /",
     "deck.nml, line 5: &history start = 0.50000000 s is after the experiment's last time "
     "0.20000000 s"),
    ("&history target = 'hub', form = 'spin_up', w_s = 1.0, T = 0.0 /",
     "deck.nml, line 5: &history T = 0.0000000, expected > 0 (the spin-up time, s)"),
    ("&history target = 'tip_fy', form = 'half_sine', amplitude = 1.0 /",
     "deck.nml, line 5: &history duration is missing"),
    ("&history target = 'tip_fz', form = 'step', amplitude = 1.0 /",
     "deck.nml, line 5: &history target = 'tip_fz', expected one of: tip_fx tip_fy "
     "tip_torque motor_open hub"),
    # the forms in beamid_loads' code order (HIST_NAMES, the names Python reads)
    ("&history target = 'tip_fy', form = 'ramp', amplitude = 1.0 /",
     "deck.nml, line 5: &history form = 'ramp', expected one of: table half_sine step "
     "chirp spin_up"),
    ("&history target = 'tip_fy', form = 'step', amplitude = 1.0, w_s = 2.0 /",
     "deck.nml, line 5: &history w_s is not a field of this form (it takes: amplitude start)"),
    ("&history target = 'tip_fy', form = 'table', file = 'f.csv', column = 'force' /",
     "f.csv, line 4: field 't' = 0.10000000 is not after the previous row's 0.20000000 "
     "(times must increase)"),
    ("&history target = 'tip_fy', form = 'table', file = 'f.csv', column = 'push' /",
     "f.csv, line 1: no column 'push' (header: t,force)"),
])
def test_bad_history_groups_name_file_line_and_field(tmp_path, batch_exe, group, message):
    (tmp_path / "f.csv").write_text("t,force\n0.0,0\n0.2,1\n0.1,0\n")
    deck = _deck(tmp_path, SIM + group + "\n")
    with pytest.raises(beamid.InputError) as err:
        read_deck(deck)
    assert message in str(err.value)
    batch = _run([batch_exe, deck], tmp_path)
    assert batch.returncode == 2 and message in batch.stderr


def test_history_of_an_estimation_deck_names_a_release(tmp_path):
    for name in ("hammer_fit.nml", "hammer_test.csv"):
        shutil.copy(DEMO / name, tmp_path / name)
    deck = tmp_path / "hammer_fit.nml"
    deck.write_text(deck.read_text().replace("experiment = 'hammer'", "experiment = 'hamer'"))
    with pytest.raises(beamid.InputError, match=r"line 18: &history experiment = 'hamer', "
                       r"expected the name of a release &experiment"):
        read_fit_deck(deck)


def test_chirp_above_the_mesh_warns_naming_the_frequency(tmp_path):
    deck = _deck(tmp_path, SIM + "&history target = 'tip_fy', form = 'chirp', "
                 "amplitude = 1.0, f0 = 0.0, f1 = 50000.0, duration = 0.1 /\n")
    loads = read_deck(deck).simulate["loads"]
    # (the mesh's highest: an axial mode near 28.7 kHz at 4 elements per beam)
    with pytest.warns(UserWarning, match=r"a chirp reaches 50000 Hz, above the highest "
                      r"frequency of the mesh \(28659\.9 Hz at elements_per_beam = 4\)"):
        beamid.simulate(beamid.pace(J_elbow=0.0, J_tip=0.0), None, [0.0, 1e-5], loads=loads)


def test_chirp_above_the_mesh_warned_by_batch_too(tmp_path, batch_exe):
    """beamid-batch writes the same warning to stderr (the library returns it,
    deck_warnings), runs the deck and exits 0; a chirp within the mesh: none."""
    text = SIM.replace("t_end = 0.2, n_out = 5", "t_end = 0.002, n_out = 3")
    deck = _deck(tmp_path, text + "&history target = 'tip_fy', form = 'chirp', "
                 "amplitude = 1.0, f0 = 0.0, f1 = 50000.0, duration = 0.002 /\n")
    run = _run([batch_exe, deck], tmp_path)
    assert run.returncode == 0, run.stderr
    assert run.stderr == (f"beamid-batch: warning: {deck}: &history 1: a chirp reaches "
                          "50000 Hz, above the highest frequency of the mesh (28659.9 Hz at "
                          "elements_per_beam = 4): the response there is the mesh's, not the "
                          "arm's\n")
    assert "_history.csv" in run.stdout
    low = _deck(tmp_path, text + "&history target = 'tip_fy', form = 'chirp', "
                "amplitude = 1.0, f0 = 0.0, f1 = 50.0, duration = 0.002 /\n", "low.nml")
    run = _run([batch_exe, low], tmp_path)
    assert run.returncode == 0 and run.stderr == "", run.stderr
