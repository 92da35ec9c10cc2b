"""A bad-input corpus (issue 16): decks mutated from good ones, hand-written
decks, measurement CSVs and bad API values.

Every deck case asserts that beamid.read_deck raises InputError naming the
file, the variable and the value, that beamid-batch exits 2 with the same
problems on standard error (one per line), that beamid.run gives the same
verdict, and that no output file is left behind.
"""
from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

import beamid
from beamid import InputError

ROOT = Path(__file__).resolve().parents[1]

STATIC = """&beamid
  task = 'static'
  output = 'out/s'
  preset = 'pace'
/
&model
  C = 5.0, 5.0
  axial_coupling = 0.0
/
&load
  kind = 'wire'
  wire_length = 1.3
/
&static
  wrt = 'EI1', 'C2'
  shape_points = 11
/
"""

FE = """&beamid
  task = 'fe_static'
  output = 'out/f'
  preset = 'pace'
/
&load
  kind = 'tip'
  fy = 2.0
/
&fe
  elements_per_beam = 2
  moment_form = 'exact'
  steps = 4
/
"""

SIM = """&beamid
  task = 'simulate'
  output = 'out/d'
  preset = 'pace'
/
&model
  mu_elbow = 0.01
/
&load
  kind = 'tip'
  fy = 2.0
/
&simulate
  t_end = 0.01
  n_out = 3
  elements_per_beam = 2
/
"""

FIT = (ROOT / "inputs" / "demo" / "hidden_effect.nml").read_text()
CSV = (ROOT / "inputs" / "demo" / "hidden_effect.csv").read_text()
GOOD = {"static": STATIC, "fe": FE, "simulate": SIM, "fit": FIT}

# (deck, old text, new text, words the message must hold)
MUTATIONS = [
    # values that do not parse for their field
    ("static", "wire_length = 1.3", "wire_length = 'long'", ["wire_length", "'long'", "number"]),
    ("static", "wire_length = 1.3", "wire_length = NaN", ["wire_length", "NaN", "finite"]),
    ("static", "wire_length = 1.3", "wire_length = Inf", ["wire_length", "Inf", "finite"]),
    ("static", "wire_length = 1.3", "wire_length = 1.3, 1.4", ["wire_length", "one"]),
    ("static", "wire_length = 1.3", "wire_length = .true.", ["wire_length", ".true."]),
    ("static", "shape_points = 11", "shape_points = 2.5", ["shape_points", "2.5", "integer"]),
    ("static", "shape_points = 11", "shape_points = 'many'", ["shape_points", "integer"]),
    ("static", "shape_points = 11", "shape_points = 1e3", ["shape_points", "1e3", "integer"]),
    ("static", "shape_points = 11", "shape_points = NaN", ["shape_points", "NaN"]),
    ("static", "shape_points = 11", "shape_points = 99999999999", ["shape_points", "too large"]),
    ("static", "shape_points = 11", "shape_points = 2000000000", ["shape_points", "GiB"]),
    ("static", "shape_points = 11", "shape_points = -3", ["shape_points", "-3"]),
    ("static", "shape_points = 11", "shape_points = 1", ["shape_points", "at least 2"]),
    ("static", "C = 5.0, 5.0", "C = 5.0, 5.0, 5.0", ["&model c", "3 values", "at most 2"]),
    ("static", "C = 5.0, 5.0", "C = 5.0, 'x'", ["c(2)", "'x'", "number"]),
    ("static", "C = 5.0, 5.0", "C = NaN, 5.0", ["c(1)", "NaN"]),
    ("static", "C = 5.0, 5.0", "C = 5.0, Infinity", ["c(2)", "Infinity"]),
    ("static", "C = 5.0, 5.0", "L = 0.7, 0.7, 0.7", ["&model l", "3 values"]),
    ("static", "C = 5.0, 5.0", "EI = 11.0, 11.0, 1.0", ["&model ei", "3 values"]),
    ("static", "C = 5.0, 5.0", "joint_flex = 0.1, 0.2", ["joint_flex", "at most 1"]),
    ("static", "C = 5.0, 5.0", "m_tip = NaN", ["m_tip", "NaN", "finite"]),
    ("static", "C = 5.0, 5.0", "m_tip = 'heavy'", ["m_tip", "'heavy'"]),
    ("static", "C = 5.0, 5.0", "EI = -1.0, 11.0", ["EI1"]),
    ("static", "C = 5.0, 5.0", "L = 0.0, 0.7", ["L1"]),
    ("static", "axial_coupling = 0.0", "axial_coupling = .true.", ["axial_coupling", ".true."]),
    ("static", "axial_coupling = 0.0", "axial_coupling = 'yes'", ["axial_coupling", "'yes'"]),
    ("static", "axial_coupling = 0.0", "axial_coupling = 0.0\n  axial_coupling = 1.0",
     ["axial_coupling", "twice"]),
    ("static", "axial_coupling = 0.0", "axial_coupling = 0.0\n  abc = 1.0",
     ["&model has no variable 'abc'", "valid:", "axial_coupling"]),
    ("static", "axial_coupling = 0.0", "axial_coupling = 0.0\n  elbowflex = 1.0",
     ["'elbowflex'", "elbow_flex"]),
    ("static", "task = 'static'", "task = 'statics'", ["task", "'statics'", "expected one of"]),
    ("static", "task = 'static'", "task = static", ["task", "quoted"]),
    ("static", "task = 'static'", "task = 'static'\n  colour = 'red'", ["'colour'"]),
    ("static", "preset = 'pace'", "preset = 'pacer'", ["preset", "'pacer'"]),
    ("static", "preset = 'pace'", "preset = 'pace'\n  nbeams = 3", ["nbeams = 3", "2 beams"]),
    ("static", "preset = 'pace'", "preset = 'pace'\n  nbeams = 2.0", ["nbeams", "integer"]),
    ("static", "preset = 'pace'", "nbeams = 2000000000", ["nbeams", "2000000000"]),
    ("static", "output = 'out/s'", "output = ''", ["output is missing"]),
    ("static", "output = 'out/s'", "output = 7", ["output", "quoted"]),
    ("static", "kind = 'wire'", "kind = 'rope'", ["kind = 'rope'", "'tip' or 'wire'"]),
    ("static", "kind = 'wire'", "kind = 'tip'", ["kind = 'tip' does not take wire_length"]),
    ("static", "wire_length = 1.3", "wire_length = -1.3", ["wire_length = -1.3", "> 0"]),
    ("static", "wire_length = 1.3", "wire_length = 1.49", ["wire_length = 1.49",
                                                           "shorter than the arm (1.49 m"]),
    ("static", "wire_length = 1.3", "wire_length = 1.3, fy = 2.0", ["does not take fx"]),
    ("static", "wrt = 'EI1', 'C2'", "wrt = 'EI9'", ["wrt = 'EI9'", "parameter name"]),
    ("static", "wrt = 'EI1', 'C2'", "wrt = EI1", ["wrt", "quoted"]),
    ("static", "wrt = 'EI1', 'C2'", "wrt = 'EI1'\n  tol = 0.5", ["tol = 0.5", "below 1e-2"]),
    ("static", "wrt = 'EI1', 'C2'", "wrt = 'EI1'\n  tol = -1e-9", ["tol"]),
    ("static", "wrt = 'EI1', 'C2'", "wrt = 'EI1'\n  tol = 'tight'", ["tol", "'tight'"]),
    # groups: truncated, misspelt, repeated, misplaced, missing
    ("static", "  shape_points = 11\n/\n", "  shape_points = 11\n", ["&static", "not closed"]),
    ("static", "  shape_points = 11\n/\n", "  shape_points = 'eleven'\n/\n",
     ["shape_points", "'eleven'"]),
    ("static", "&load\n  kind = 'wire'\n  wire_length = 1.3\n/\n",
     "&load\n  kind = 'wire'\n  wire_length = 1.3\n", ["&load", "not closed"]),
    ("static", "&static", "&statik", ["unknown group &statik", "expected one of"]),
    ("static", "&static", "&fit", ["&fit", "estimation"]),
    ("static", "&static", "&simulate", ["&simulate", "only for task"]),
    ("static", "&static", "&load", ["&load", "2 times"]),
    ("static", "&beamid", "&beamid2", ["unknown group &beamid2"]),
    ("static", "&load\n  kind = 'wire'\n  wire_length = 1.3\n/\n", "", ["&load is missing"]),
    ("static", "  output = 'out/s'\n", "  output = 'out/s'\n  junk\n", ["junk"]),
    ("static", "&model", "model", ["text outside a group"]),
    # finite elements
    ("fe", "elements_per_beam = 2", "elements_per_beam = 2.5", ["elements_per_beam", "2.5"]),
    ("fe", "elements_per_beam = 2", "elements_per_beam = 'four'", ["elements_per_beam", "four"]),
    ("fe", "elements_per_beam = 2", "elements_per_beam = 0", ["elements_per_beam = 0"]),
    ("fe", "elements_per_beam = 2", "elements_per_beam = -4", ["elements_per_beam = -4"]),
    ("fe", "elements_per_beam = 2", "elements_per_beam = 2000000000",
     ["elements_per_beam = 2000000000", "GiB", "memory"]),
    ("fe", "elements_per_beam = 2", "elements_per_beam = 3000000000", ["too large"]),
    ("fe", "elements_per_beam = 2", "elements_per_beam = NaN", ["elements_per_beam", "NaN"]),
    ("fe", "moment_form = 'exact'", "moment_form = 'eq79'", ["moment_form", "'eq79'"]),
    ("fe", "moment_form = 'exact'", "moment_form = exact", ["moment_form", "quoted"]),
    ("fe", "steps = 4", "steps = -1", ["steps = -1"]),
    ("fe", "steps = 4", "steps = 4.5", ["steps", "4.5", "integer"]),
    ("fe", "steps = 4", "steps = 4\n  rotary_inertia = 'yes'", ["rotary_inertia", ".true."]),
    ("fe", "steps = 4", "steps = 4\n  tol = -1.0", ["tol = -1"]),
    ("fe", "steps = 4", "steps = 4\n  wrt = 'EI1'", ["&fe has no variable 'wrt'"]),
    ("fe", "  steps = 4\n/\n", "  steps = 4\n", ["&fe", "not closed"]),
    ("fe", "  steps = 4\n/\n", "  steps = 'x'\n/\n", ["steps", "'x'"]),
    ("fe", "kind = 'tip'\n  fy = 2.0", "kind = 'wire'\n  wire_length = 1.3",
     ['kind = "wire"', "fe_static"]),
    ("fe", "fy = 2.0", "fy = 2.0, fy = 3.0", ["fy", "twice"]),
    ("fe", "fy = 2.0", "fy = '2'", ["fy", "'2'"]),
    # dynamics
    ("simulate", "t_end = 0.01", "t_end = 'soon'", ["t_end", "'soon'"]),
    ("simulate", "t_end = 0.01", "t_end = NaN", ["t_end", "NaN"]),
    ("simulate", "t_end = 0.01", "t_end = -1.0", ["t_end = -1", "> 0"]),
    ("simulate", "t_end = 0.01", "t_end = 0.01\n  t_out = 0.0, 0.1", ["t_out and t_end"]),
    ("simulate", "t_end = 0.01\n  n_out = 3", "t_out = 0.0, 0.1, 0.05",
     ["ascending", "entry 3"]),
    ("simulate", "t_end = 0.01\n  n_out = 3", "t_out = 0.0, 'x'", ["t_out(2)", "'x'"]),
    ("simulate", "t_end = 0.01\n  n_out = 3", "t_out(3) = 0.5", ["t_out has gaps"]),
    ("simulate", "t_end = 0.01\n  n_out = 3", "n_out = 3", ["needs t_out"]),
    ("simulate", "n_out = 3", "n_out = 3.5", ["n_out", "3.5", "integer"]),
    ("simulate", "n_out = 3", "n_out = 1", ["n_out = 1", "at least 2"]),
    ("simulate", "n_out = 3", "n_out = 2000000000", ["n_out = 2000000000", "GiB"]),
    ("simulate", "elements_per_beam = 2", "elements_per_beam = 2.5", ["elements_per_beam"]),
    ("simulate", "elements_per_beam = 2", "elements_per_beam = 2000000000", ["GiB"]),
    ("simulate", "elements_per_beam = 2", "elements_per_beam = 0", ["elements_per_beam = 0"]),
    ("simulate", "elements_per_beam = 2", "integrator = 'euler'", ["integrator", "euler"]),
    ("simulate", "elements_per_beam = 2", "friction = 'viscous'", ["friction", "viscous"]),
    ("simulate", "elements_per_beam = 2", "dt = -1e-5", ["dt = -1e-05"]),
    ("simulate", "elements_per_beam = 2", "rtol = 'fine'", ["rtol", "'fine'"]),
    ("simulate", "elements_per_beam = 2", "motor_gain = -0.2", ["motor_gain = -0.2"]),
    ("simulate", "elements_per_beam = 2", "t_final = 1.0", ["'t_final'", "valid:"]),
    ("simulate", "  elements_per_beam = 2\n/\n", "  elements_per_beam = 2\n",
     ["&simulate", "not closed"]),
    ("simulate", "  elements_per_beam = 2\n/\n", "  elements_per_beam = 'four'\n/\n",
     ["elements_per_beam", "'four'"]),
    ("simulate", "mu_elbow = 0.01", "mu_elbow = NaN", ["mu_elbow", "NaN"]),
    ("simulate", "mu_elbow = 0.01", "mu_elbow = 0.01\n  mu_elbow = 0.02", ["twice"]),
    ("simulate", "&simulate", "&fe", ["&fe", "simulate"]),
    ("simulate", "kind = 'tip'\n  fy = 2.0", "kind = 'wire'\n  wire_length = 1.3",
     ['kind = "wire"', '"simulate"']),
    # estimation decks
    ("fit", "fy = 2.0 /", "fy = 'two' /", ["&experiment 'F2'", "fy", "'two'"]),
    ("fit", "fy = 2.0 /", "fy = NaN /", ["&experiment 'F2'", "NaN"]),
    ("fit", "kind = 'tip', fy = 2.0 /", "kind = 'rope', fy = 2.0 /", ["'F2'", "'rope'"]),
    ("fit", "kind = 'tip', fy = 2.0 /", "kind = 'wire', fy = 2.0 /", ["'F2'", "wire_length"]),
    ("fit", "name = 'F2', kind", "name = '', kind", ["has no name"]),
    ("fit", "name = 'F4', kind", "name = 'F2', kind", ["'F2' defined twice"]),
    ("fit", "fy = 2.0 /", "fy = 2.0, speed = 3 /", ["&experiment has no variable 'speed'"]),
    ("fit", "free = 'EI1', 'EI2'", "free = 'EI9'", ["free = 'EI9'"]),
    ("fit", "free = 'EI1', 'EI2'", "free = 'EI1', 'EI1'", ["'EI1' twice"]),
    ("fit", "free = 'EI1', 'EI2'\n", "", ["free is missing"]),
    ("fit", "alpha = 0.01", "alpha = 1.5", ["alpha = 1.5"]),
    ("fit", "alpha = 0.01", "alpha = 'small'", ["alpha", "'small'"]),
    ("fit", "alpha = 0.01", "alpha = NaN", ["alpha", "NaN"]),
    ("fit", "alpha = 0.01", "max_iter = 0", ["max_iter = 0"]),
    ("fit", "alpha = 0.01", "max_iter = 2.5", ["max_iter", "2.5", "integer"]),
    ("fit", "alpha = 0.01", "alpha = 0.01, alpha = 0.02", ["alpha", "twice"]),
    ("fit", "alpha = 0.01", "prior_names = 'EI1', prior_means = 11.0",
     ["prior_names, prior_means and prior_sigmas"]),
    ("fit", "alpha = 0.01", "prior_names = 'EI1', prior_means = 11.0, prior_sigmas = 0.0",
     ["prior for 'EI1'"]),
    ("fit", "alpha = 0.01", "prior_names = 'C1', prior_means = 0.0, prior_sigmas = 1.0",
     ["'C1' is not free"]),
    ("fit", "'root_flex'", "'root_flux'", ["candidates = 'root_flux'"]),
    ("fit", "name = 'F2', kind = 'tip', fy = 2.0 /",
     "name = 'F2', kind = 'wire', wire_length = 9.0 /", ["&experiment 'F2'", "wire_length = 9",
                                                         "shorter than the arm"]),
    ("fit", "data = 'hidden_effect.csv'", "data = 'nothere.csv'", ["nothere.csv", "no such file"]),
    ("fit", "data = 'hidden_effect.csv'", "data = ''", ["data is missing"]),
    ("fit", "    alpha = 0.01\n/\n", "    alpha = 0.01\n", ["&fit", "not closed"]),
    ("fit", "    alpha = 0.01\n/\n", "    alpha = 'x'\n/\n", ["alpha", "'x'"]),
    ("fit", "&fit", "&load kind = 'tip' /\n&fit", ["&load does not belong"]),
    ("fit", "preset = 'pace'", "preset = 'cantilever'", ["EI2"]),
    ("fit", "axial_coupling = 0.0", "axial_coupling = 0.0, m_tip = NaN", ["m_tip", "NaN"]),
]

HAND = {
    "empty": ("", ["&beamid is missing"]),
    "only_comments": ("! nothing here\n", ["&beamid is missing"]),
    "binary": ("\x00\x01\x02&beamid\n", ["text outside a group"]),
    "no_preset_missing_structure": (
        "&beamid task = 'static', output = 'o', nbeams = 2 /\n&model L = 1.0 /\n"
        "&load kind = 'tip', fy = 1.0 /\n", ["&model is missing L2", "EI1"]),
    "no_preset_no_model": ("&beamid task = 'static', output = 'o', nbeams = 1 /\n"
                           "&load kind = 'tip', fy = 1.0 /\n", ["&model is missing"]),
    "nbeams_zero": ("&beamid task = 'static', output = 'o', nbeams = 0 /\n",
                    ["nbeams = 0"]),
    "elbow_on_one_beam": ("&beamid task = 'static', output = 'o', preset = 'cantilever' /\n"
                          "&model elbow_flex = 0.1 /\n&load kind = 'tip', fy = 1.0 /\n",
                          ["elbow_flex", "one beam"]),
    "equals_without_name": ("&beamid = 'static' /\n", ["'=' without a variable name"]),
    "value_without_name": ("&beamid 'static' /\n", ["without a variable name"]),
    "cut_in_string": ("&beamid task = 'static\n", ["&beamid", "not closed"]),
    "bad_subscript": ("&beamid task = 'static', output = 'o', preset = 'pace' /\n"
                      "&model L(0) = 1.0 /\n&load kind = 'tip', fy = 1.0 /\n", ["index >= 1"]),
    "published_lengths": (STATIC + "&published table = '2', quantity = 'x_tip', 'y_tip', "
                          "value = 1.0, digits = 3 /\n", ["&published", "equally long"]),
    "published_digits": (STATIC + "&published table = '2', quantity = 'x_tip', value = 1.0, "
                         "digits = 2.5 /\n", ["digits(1) = 2.5", "integer"]),
    "published_value": (STATIC + "&published table = '2', quantity = 'x_tip', value = 'one', "
                        "digits = 3 /\n", ["value(1) = 'one'"]),
    "published_unknown": (STATIC + "&published table = '2', quantity = 'x_tip', value = 1.0, "
                          "digits = 3, page = 7 /\n", ["&published has no variable 'page'"]),
    "many_problems": ("&beamid task = 'static', output = 'o', preset = 'pace' /\n"
                      "&model m_tip = NaN, EI = 1, 2, 3 /\n&load kind = 'tip', fy = 'x' /\n"
                      "&static shape_points = 2.5 /\n",
                      ["m_tip", "&model ei", "fy", "shape_points"]),
}


def _cases():
    cases = []
    for k, (deck, old, new, words) in enumerate(MUTATIONS):
        text = GOOD[deck]
        assert old in text, (deck, old)
        cases.append(pytest.param(deck, text.replace(old, new, 1), words,
                                  id=f"{deck}-{k}-{new.strip()[:30]}"))
    for name, (text, words) in HAND.items():
        cases.append(pytest.param("hand", text, words, id=f"hand-{name}"))
    return cases


def _write_deck(tmp_path: Path, kind: str, text: str) -> Path:
    if kind == "fit":
        (tmp_path / "hidden_effect.csv").write_text(CSV)
    deck = tmp_path / "deck.nml"
    deck.write_text(text)
    return deck


@pytest.mark.parametrize("kind,text,words", _cases())
def test_bad_deck_same_verdict_from_both_fronts(tmp_path, batch_exe, kind, text, words):
    deck = _write_deck(tmp_path, kind, text)
    with pytest.raises(InputError) as info:
        beamid.read_deck(deck)
    message = str(info.value)
    assert str(deck) in message
    for word in words:
        assert word.lower() in message.lower(), (word, message)
    proc = subprocess.run([str(batch_exe), str(deck)], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2, proc.stderr
    lines = [l.removeprefix("beamid-batch: error: ") for l in proc.stderr.splitlines()]
    assert lines == message.splitlines()
    with pytest.raises(InputError) as again:
        beamid.run(deck)
    assert str(again.value) == message and again.value.exit_code == 2
    assert not [p for p in tmp_path.rglob("*") if p.suffix in (".csv", ".tmp")
                and p.name != "hidden_effect.csv"]


# ------------------------------------------------------------ measurement CSVs

HEADER = "experiment,t,quantity,value,sigma\n"
CSV_CASES = {
    "value_text": (HEADER + "F2,0,y_tip,abc,0.001\n", ["line 2", "value", "abc"]),
    "value_nan": (HEADER + "F2,0,y_tip,nan,0.001\n", ["line 2", "value", "nan"]),
    "value_inf": (HEADER + "F2,0,y_tip,inf,0.001\n", ["line 2", "value"]),
    "sigma_zero": (HEADER + "F2,0,y_tip,0.1,0\n", ["line 2", "sigma"]),
    "sigma_negative": (HEADER + "F2,0,y_tip,0.1,-1\n", ["line 2", "sigma"]),
    "sigma_text": (HEADER + "F2,0,y_tip,0.1,small\n", ["line 2", "sigma", "small"]),
    "t_negative": (HEADER + "F2,-1,y_tip,0.1,0.001\n", ["line 2", "t"]),
    "t_text": (HEADER + "F2,now,y_tip,0.1,0.001\n", ["line 2", "t", "now"]),
    "quantity": (HEADER + "F2,0,z_tip,0.1,0.001\n", ["line 2", "quantity", "z_tip"]),
    "four_fields": (HEADER + "F2,0,y_tip,0.1\n", ["line 2", "5 fields"]),
    "six_fields": (HEADER + "F2,0,y_tip,0.1,0.1,9\n", ["line 2", "5 fields"]),
    "empty_experiment": (HEADER + ",0,y_tip,0.1,0.001\n", ["line 2", "experiment"]),
    "duplicate": (HEADER + "F2,0,y_tip,0.1,0.001\nF2,0,y_tip,0.2,0.001\n",
                  ["line 3", "duplicate"]),
    "no_header": ("F2,0,y_tip,0.1,0.001\n", ["header"]),
    "wrong_header": ("exp,t,q,v,s\nF2,0,y_tip,0.1,0.001\n", ["header"]),
    "empty": ("", ["header"]),
    "no_rows": (HEADER, ["no measurement rows"]),
}


@pytest.mark.parametrize("text,words", list(CSV_CASES.values()), ids=list(CSV_CASES))
def test_bad_csv_both_fronts(tmp_path, batch_exe, text, words):
    csv = tmp_path / "hidden_effect.csv"
    csv.write_text(text)
    with pytest.raises(InputError) as info:
        beamid.read_measurements(csv)
    message = str(info.value)
    assert str(csv) in message
    for word in words:
        assert word.lower() in message.lower(), (word, message)
    deck = tmp_path / "deck.nml"
    deck.write_text(FIT)
    proc = subprocess.run([str(batch_exe), str(deck)], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2 and message in proc.stderr
    with pytest.raises(InputError):
        beamid.run(deck)
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------ files and paths

def test_missing_and_directory_decks(tmp_path, batch_exe):
    for path, word in ((tmp_path / "nope.nml", "no such file"), (tmp_path, "directory")):
        with pytest.raises(InputError, match=word):
            beamid.read_deck(path)
        with pytest.raises(InputError, match=word):
            beamid.run(path)
        proc = subprocess.run([str(batch_exe), str(path)], capture_output=True, text=True)
        assert proc.returncode == 2 and word in proc.stderr and str(path) in proc.stderr


@pytest.mark.parametrize("output,blocker", [("blocked/s", "blocked"),
                                            ("out/s", "out/s_shape.csv")])
def test_unwritable_output_leaves_nothing(tmp_path, batch_exe, output, blocker):
    """A parent that is a file, or an output name taken by a directory: exit 4
    from the batch program, InputError naming the path from Python, and no
    file left behind (the first file is not kept when the second fails)."""
    deck = tmp_path / "deck.nml"
    deck.write_text(STATIC.replace("out/s", output))
    target = tmp_path / blocker
    if blocker == "blocked":
        target.write_text("a file, not a folder")
    else:
        target.mkdir(parents=True)
    proc = subprocess.run([str(batch_exe), str(deck)], capture_output=True, text=True)
    assert proc.returncode == 4, proc.stderr
    assert str(tmp_path / blocker.split("/")[0]) in proc.stderr
    with pytest.raises(InputError, match="cannot") as info:
        beamid.run(deck)
    assert info.value.exit_code == 4  # what `beamid run` exits with
    left = [p for p in tmp_path.rglob("*") if p.is_file() and p.suffix in (".csv", ".tmp")]
    assert left == []


def test_batch_says_what_it_wrote(tmp_path, batch_exe):
    deck = tmp_path / "deck.nml"
    deck.write_text(STATIC)
    proc = subprocess.run([str(batch_exe), str(deck)], capture_output=True, text=True)
    assert proc.returncode == 0
    assert proc.stdout.splitlines()[1:] == [f"wrote {tmp_path / 'out/s_summary.csv'}",
                                            f"wrote {tmp_path / 'out/s_shape.csv'}"]
    assert proc.stdout.startswith(f"{deck}: tip (")
    quiet = subprocess.run([str(batch_exe), "--quiet", str(deck)], capture_output=True,
                           text=True)
    assert quiet.returncode == 0 and quiet.stdout == ""
    version = subprocess.run([str(batch_exe), "--version"], capture_output=True, text=True)
    assert version.stdout.strip() == f"beamid-batch {beamid.__version__}"
    mode = (tmp_path / "out/s_summary.csv").stat().st_mode & 0o777
    assert mode & 0o644 == 0o644  # an ordinary file, readable by others


# ------------------------------------------------------------ API values

@pytest.fixture(scope="module")
def static_result():
    return beamid.solve_static(beamid.pace(), beamid.TipForce(fy=2.0))


API_CASES = {
    "read_measurements_none": (lambda r: beamid.read_measurements(None), ["path"]),
    "read_measurements_int": (lambda r: beamid.read_measurements(3), ["path", "3"]),
    "read_deck_none": (lambda r: beamid.read_deck(None), ["path"]),
    "run_none": (lambda r: beamid.run(None), ["deck"]),
    "shape_nan": (lambda r: r.shape(s=[math.nan]), ["s", "nan"]),
    "shape_inf": (lambda r: r.shape(s=[0.1, math.inf]), ["s", "inf"]),
    "shape_beyond": (lambda r: r.shape(s=[5.0]), ["s", "5"]),
    "shape_negative": (lambda r: r.shape(s=[-0.1]), ["s", "-0.1"]),
    "shape_n_one": (lambda r: r.shape(n=1), ["n", "1"]),
    "shape_n_float": (lambda r: r.shape(n=2.5), ["n", "2.5"]),
    "shape_n_huge": (lambda r: r.shape(n=2_000_000_000), ["n", "GiB"]),
    "modes_shape_zero": (lambda r: beamid.modes(beamid.pace(), 2).shape(0), ["mode", "0"]),
    "modes_shape_big": (lambda r: beamid.modes(beamid.pace(), 2).shape(10_000), ["mode"]),
    "modes_huge_mesh": (lambda r: beamid.modes(beamid.pace(), 2_000_000_000),
                        ["elements_per_beam", "GiB"]),
    "modes_float_mesh": (lambda r: beamid.modes(beamid.pace(), 2.5), ["elements_per_beam"]),
    "fe_static_huge_mesh": (lambda r: beamid.fe_static(beamid.pace(), beamid.TipForce(fy=1.0),
                                                       2_000_000_000),
                            ["elements_per_beam", "GiB"]),
    "fe_static_zero_mesh": (lambda r: beamid.fe_static(beamid.pace(), beamid.TipForce(fy=1.0),
                                                       0), ["elements_per_beam"]),
    "model_nan": (lambda r: beamid.Model(1, [math.nan] * 15), []),
    "tipforce_nan": (lambda r: beamid.TipForce(fy=math.nan), ["fy"]),
    "wire_negative": (lambda r: beamid.RadialWire(-1.0), []),
    "solve_static_not_a_load": (lambda r: beamid.solve_static(beamid.pace(), "tip"), ["load"]),
    "solve_static_wrt_unknown": (lambda r: beamid.solve_static(beamid.pace(),
                                                               beamid.TipForce(fy=1.0),
                                                               wrt=("EI9",)), ["EI9"]),
    "model_huge": (lambda r: beamid.Model(2_000_000_000, []), ["nbeams", "1000"]),
    "model_float_beams": (lambda r: beamid.Model(2.5, []), ["nbeams", "2.5"]),
    "buckling_dense_too_big": (lambda r: beamid.buckling_load(beamid.pace(), 100_000),
                               ["GiB"]),
    "axial_dense_too_big": (lambda r: beamid.axial_modes_linear(beamid.pace(), 100_000),
                            ["GiB"]),
    "fe_path_huge": (lambda r: beamid.fe_path(beamid.pace(), None, beamid.TipForce(fy=1.0), 4,
                                              max_points=2_000_000_000), ["max_points", "GiB"]),
    "simulate_huge_mesh": (lambda r: beamid.simulate(beamid.pace(), beamid.TipForce(fy=1.0),
                                                     [0.0, 0.1],
                                                     elements_per_beam=2_000_000_000),
                           ["elements_per_beam", "GiB"]),
    "simulate_huge_history": (lambda r: beamid.simulate(beamid.pace(), beamid.TipForce(fy=1.0),
                                                        np.linspace(0.0, 1.0, 20_000_000)),
                              ["t_out", "GiB"]),
    "compare_none": (lambda r: beamid.compare(None), ["fit", "None"]),
    "fit_tol_negative": (lambda r: beamid.fit(beamid.pace(), EXPS, _data(), tol=-1),
                         ["tol", "-1"]),
    "fit_tol_nan": (lambda r: beamid.fit(beamid.pace(), EXPS, _data(), tol=math.nan),
                    ["tol", "nan"]),
    "fit_max_iter_zero": (lambda r: beamid.fit(beamid.pace(), EXPS, _data(), max_iter=0),
                          ["max_iter"]),
    "fit_max_iter_float": (lambda r: beamid.fit(beamid.pace(), EXPS, _data(), max_iter=2.5),
                           ["max_iter", "2.5"]),
    "fit_data_none": (lambda r: beamid.fit(beamid.pace(), EXPS, None), ["data"]),
    "fit_free_unknown": (lambda r: beamid.fit(beamid.pace(), EXPS, _data(), free=("EI9",)),
                         ["EI9"]),
    "simulate_quantity_unknown": (lambda r: beamid.simulate_measurements(
        beamid.pace(), EXPS, ["z_tip"]), ["z_tip"]),
    "simulate_quantity_map_missing": (lambda r: beamid.simulate_measurements(
        beamid.pace(), EXPS, {"F2": ["y_tip"]}), ["F4"]),
    "simulate_sigma_map_missing": (lambda r: beamid.simulate_measurements(
        beamid.pace(), EXPS, ["y_tip"], sigma={"x_tip": 1e-3}), ["sigma", "y_tip"]),
    "simulate_sigma_zero": (lambda r: beamid.simulate_measurements(
        beamid.pace(), EXPS, ["y_tip"], sigma=0.0), ["sigma"]),
    "simulate_quantities_str": (lambda r: beamid.simulate_measurements(
        beamid.pace(), EXPS, "y_tip"), ["quantities"]),
    # issue 32: a segfault and seven bare ValueError/TypeError, each now an
    # InputError that names the argument and shows the value
    "improve_max_steps_negative": (lambda r: beamid.improve(beamid.pace(), EXPS, _data(),
                                                            max_steps=-1),
                                   ["max_steps = -1", "integer >= 0"]),
    "fe_static_start_str": (lambda r: beamid.fe_static(beamid.pace(), beamid.TipForce(fy=8.0),
                                                       4, start="abc"), ["start = 'abc'"]),
    "fit_free_none": (lambda r: beamid.fit(beamid.pace(), EXPS, _data(), free=None),
                      ["free = None", "names"]),
    "model_values_str": (lambda r: beamid.Model(1, "abcdefghijklm"),
                         ["values = 'abcdefghijklm'", "numbers"]),
    "from_rows_value_str": (lambda r: beamid.Measurements.from_rows(
        [("F2", 0, "y_tip", "abc", 0.1)]), ["row 1", "value = 'abc'", "number"]),
    "simulate_motor_gain_str": (lambda r: beamid.simulate(
        beamid.pace(), beamid.TipForce(fy=1.0), [0.0, 0.01], motor_gain="high"),
        ["motor_gain = 'high'", ">= 0"]),
    "simulate_t_out_str": (lambda r: beamid.simulate(
        beamid.pace(), beamid.TipForce(fy=1.0), t_out=["a", "b"]),
        ["t_out = ['a', 'b']", "numbers"]),
    "solve_static_tol_str": (lambda r: beamid.solve_static(
        beamid.pace(), beamid.TipForce(fy=1.0), tol="fine"), ["tol = 'fine'", "tolerance"]),
}

EXPS = {"F2": beamid.TipForce(fy=2.0), "F4": beamid.TipForce(fy=4.0)}


def _data():
    return beamid.simulate_measurements(beamid.pace(), EXPS, ["y_tip", "x_tip"])


@pytest.mark.parametrize("call,words", list(API_CASES.values()), ids=list(API_CASES))
def test_bad_api_value_raises_input_error(static_result, call, words):
    with pytest.raises(InputError) as info:
        call(static_result)
    for word in words:
        assert word.lower() in str(info.value).lower(), (word, str(info.value))


# ------------------------------------------------------------ beyond buckling

@pytest.mark.parametrize("factor,negative", [(0.5, 0), (0.95, 0), (1.05, 1), (2.0, 1),
                                             (4.5, 1), (10.0, 2)])
def test_compression_beyond_buckling_is_flagged_unstable(factor, negative):
    """The straight cantilever under a compressive tip force stays an
    equilibrium past the buckling load Pcr, but an unstable one: the
    tangent's negative eigenvalue count is the number of critical loads
    passed (the clamped-free column's second is 9 Pcr)."""
    m = beamid.cantilever()
    pcr = beamid.buckling_load(m, 4).load
    r = beamid.fe_static(m, beamid.TipForce(fx=-factor * pcr), 4)
    assert r.tip["w"] == 0.0
    assert r.negative_eigenvalues == negative
    assert r.stable == (negative == 0)


def test_buckled_branch_is_stable():
    m = beamid.cantilever()
    pcr = beamid.buckling_load(m, 4).load
    r = beamid.fe_static(m, beamid.TipForce(fx=-2 * pcr, fy=0.01 * pcr), 4)
    assert r.tip["w"] > 0.1 and r.stable


# ------------------------------------------------------------ long lists

def test_long_value_list_is_read_in_linear_time(tmp_path):
    """A million output times: the reader grows its value lists
    geometrically, so the deck is read (and its bad dt reported) quickly; the
    times themselves are checked against the bound of 10^7."""
    times = ", ".join(f"{k * 1e-3:g}" for k in range(1_000_000))
    deck = tmp_path / "long.nml"
    deck.write_text(SIM.replace("t_end = 0.01\n  n_out = 3", f"t_out = {times}\n  dt = -1.0"))
    with pytest.raises(InputError, match="dt = -1, expected 0"):
        beamid.read_deck(deck)


# ------------------------------------------------------------ random damage

def test_randomly_damaged_decks_never_crash(tmp_path):
    """400 decks damaged at random (characters deleted, inserted, the file
    cut short; fixed seed) are read in-process: each is a deck or an
    InputError naming the file, never a crash or a foreign exception (the
    same mutations ran clean in a -fcheck=all build of the reader)."""
    import random

    rng = random.Random(7)
    alphabet = "&/!'\",=*() \n\t.0123456789eEabcdefxyz_-+TF"
    (tmp_path / "hidden_effect.csv").write_text(CSV)
    outcomes = {"deck": 0, "error": 0}
    for _ in range(400):
        chars = list(rng.choice(list(GOOD.values())))
        for _ in range(rng.randint(1, 6)):
            op, k = rng.random(), rng.randrange(len(chars) + 1)
            if op < 0.4 and chars:
                del chars[min(k, len(chars) - 1)]
            elif op < 0.8:
                chars.insert(k, rng.choice(alphabet))
            else:
                chars = chars[:k]
        deck = tmp_path / "deck.nml"
        deck.write_text("".join(chars))
        try:
            beamid.read_deck(deck)
            outcomes["deck"] += 1
        except InputError as err:
            assert str(deck) in str(err)
            outcomes["error"] += 1
    assert outcomes["error"] > 200 and outcomes["deck"] > 20, outcomes


def test_non_ascii_paths(tmp_path, batch_exe):
    """Paths reach Fortran as bytes, so a folder named in any language works
    from both fronts and appears intact in the messages."""
    folder = tmp_path / "dossier é"
    folder.mkdir()
    deck = folder / "déck.nml"
    deck.write_text(STATIC)
    assert beamid.run(deck).wire_force > 0
    assert subprocess.run([str(batch_exe), "-q", str(deck)]).returncode == 0
    deck.write_text(STATIC.replace("1.3", "'long'"))
    with pytest.raises(InputError, match="dossier é/déck.nml, line 12: &load wire_length = .long.: expected") as info:
        beamid.read_deck(deck)
    assert len(str(info.value).splitlines()) == 1  # no follow-up "needs wire_length"
