"""Logger files, sensors and DataFrames into Measurements (issue 26)."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import beamid

LOGGER = """# PACE rig, release from 8 N
t,gauge_root,acc_tip,x@2:0.714
0.1,1.2e-3,0.15,1.40
0.2,1.1e-3,,1.41
"""
SENSORS = [beamid.Sensor("gauge_root", "strain@1:0.05", 1e-5),
           beamid.Sensor("acc_tip", "accel_n@2:0.714")]


class DataFrame:
    """The part of a pandas DataFrame the readers use (pandas is optional)."""

    def __init__(self, columns: dict):
        self._c = columns
        self.columns = list(columns)

    def __getitem__(self, key):
        return self._c[key]


def test_read_channels_wide_file(tmp_path):
    p = tmp_path / "logger.csv"
    p.write_text(LOGGER)
    data = beamid.read_channels(p, "free", sigma=0.05, sensors=SENSORS)
    assert data.rows() == [
        ("free", 0.1, "strain@1:0.05", 1.2e-3, 1e-5), ("free", 0.1, "accel_n@2:0.714", 0.15, 0.05),
        ("free", 0.1, "x@2:0.714", 1.40, 0.05), ("free", 0.2, "strain@1:0.05", 1.1e-3, 1e-5),
        ("free", 0.2, "x@2:0.714", 1.41, 0.05)]     # an empty field: not sampled
    assert data.lines == (3, 3, 3, 4, 4)
    per_channel = beamid.read_channels(p, "free", sigma={"acc_tip": 0.1, "x@2:0.714": 2e-3},
                                       sensors=SENSORS)
    np.testing.assert_array_equal(per_channel.sigma, [1e-5, 0.1, 2e-3, 1e-5, 2e-3])


@pytest.mark.parametrize("text, kwargs, message", [
    (LOGGER, {"sigma": 0.05}, r"logger.csv, line 2: channel header 'gauge_root' matches no "
     r"sensor \(sensors: none\)"),
    (LOGGER, {"sensors": SENSORS}, r"line 2: channel 'acc_tip' has no sigma"),
    ("time,y_tip\n0.1,abc\n", {"sigma": 1e-3}, r"logger.csv, line 2: field y_tip = 'abc', "
     "expected a number"),
    ("y_tip,t\n0.1,0.2\n", {"sigma": 1e-3}, r"line 1: the first column is 'y_tip', expected "
     "the time"),
    ("t,y_tip\n0.1,0.2,0.3\n", {"sigma": 1e-3}, r"line 2: expected 2 fields"),
])
def test_read_channels_bad_input(tmp_path, text, kwargs, message):
    p = tmp_path / "logger.csv"
    p.write_text(text)
    with pytest.raises(beamid.InputError, match=message):
        beamid.read_channels(p, "free", **kwargs)


def test_sensor_checks_its_observation():
    with pytest.raises(beamid.InputError, match="Sensor 'g': observation = 'strian@1:0.1'"):
        beamid.Sensor("g", "strian@1:0.1")
    with pytest.raises(beamid.InputError, match="sigma = -1"):
        beamid.Sensor("g", "strain@1:0.1", sigma=-1)


def test_dataframes_wide_and_long():
    wide = DataFrame({"t": [0.1, 0.2], "gauge_root": [1.2e-3, 1.1e-3]})
    data = beamid.read_channels(wide, "free", sensors=SENSORS)
    assert data.quantity == ("strain@1:0.05", "strain@1:0.05") and data.source == "<DataFrame>"
    long = DataFrame({"experiment": ["F3"], "t": [0.0], "quantity": ["y_tip"],
                      "value": [0.2763], "sigma": [1e-3]})
    m = beamid.read_measurements(long)
    assert m.rows() == [("F3", 0.0, "y_tip", 0.2763, 1e-3)]
    with pytest.raises(beamid.InputError, match="missing sigma"):
        beamid.read_measurements(DataFrame({"experiment": [], "t": [], "quantity": [],
                                            "value": []}))


def test_real_pandas_if_installed():
    pd = pytest.importorskip("pandas")
    frame = pd.DataFrame({"t": [0.1], "x_tip": [1.3]})
    assert beamid.read_channels(frame, "free", sigma=1e-3).rows() == [
        ("free", 0.1, "x_tip", 1.3, 1e-3)]


DECK = """&beamid task = 'fit', output = 'out/rig', preset = 'pace' /
&model J_tip = 0.0 /
&experiment name = 'free', kind = 'release', fy = 8.0, elements_per_beam = 2 /
&sensor name = 'gauge_root', observation = 'strain@1:0.05', sigma = 1e-5 /
&sensor name = 'acc_tip', observation = 'accel_n@2:0.714' /
&fit data = 'logger.csv', logger_experiment = 'free', logger_sigma = 0.05, free = 'rho2' /
"""


def test_deck_sensor_table_reads_a_logger_file(tmp_path):
    """A deck's &sensor groups and &fit logger_experiment read a logger file
    as read_channels does: the Fortran reader's rows (beamid-batch and the
    command run the deck file) and the Python front's are the same."""
    (tmp_path / "logger.csv").write_text(LOGGER)
    deck_path = tmp_path / "rig.nml"
    deck_path.write_text(DECK)
    deck = beamid.read_deck(deck_path)
    direct = beamid.read_channels(tmp_path / "logger.csv", "free", sigma=0.05, sensors=SENSORS)
    assert deck.data.rows() == direct.rows() and deck.data.lines == direct.lines
    values = beamid._core.read_deck(str(deck_path))
    assert values["ndata"] == 5                      # the Fortran reader's rows
    assert values["sensors"] == [("gauge_root", "strain@1:0.05", 1e-5),
                                 ("acc_tip", "accel_n@2:0.714", None)]


@pytest.mark.parametrize("change, message", [
    ("logger_experiment = 'free'", "logger.csv, line 2: channel 'acc_tip' has no sigma"),
    ("logger_experiment = 'gone', logger_sigma = 0.05",
     "logger_experiment = 'gone' is not defined (experiments: free)"),
    ("logger_experiment = 'free', logger_sigma = -1.0", "logger_sigma = -1, expected a sigma > 0"),
])
def test_deck_logger_bad_input(tmp_path, change, message):
    (tmp_path / "logger.csv").write_text(LOGGER)
    deck_path = tmp_path / "rig.nml"
    deck_path.write_text(DECK.replace("logger_experiment = 'free', logger_sigma = 0.05", change))
    with pytest.raises(beamid.InputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        beamid.read_deck(deck_path)


def test_deck_sensor_bad_input(tmp_path):
    (tmp_path / "logger.csv").write_text(LOGGER.replace("gauge_root", "gauge"))
    deck_path = tmp_path / "rig.nml"
    deck_path.write_text(DECK.replace("'strain@1:0.05'", "'strian@1:0.05'"))
    with pytest.raises(beamid.InputError) as err:
        beamid.read_deck(deck_path)
    assert "&sensor 'gauge_root': observation = 'strian@1:0.05': unknown observation kind" \
        in str(err.value)
    deck_path.write_text(DECK)
    with pytest.raises(beamid.InputError, match="logger.csv, line 2: channel header 'gauge' "
                       r"matches no sensor \(sensors: gauge_root, acc_tip\)"):
        beamid.read_deck(deck_path)


def test_deck_logger_same_output_from_both_fronts(tmp_path, batch_exe):
    """beamid-batch and `beamid fit` run a deck reading a logger file through
    its sensor table and write the same files."""
    rig = beamid.pace().replace(J_tip=0.0, rho2=0.531)
    release = beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=2)
    t = (0.05, 0.1, 0.15, 0.2)
    sim = beamid.simulate_measurements(rig, {"free": release}, ["strain@1:0.05", "accel_n@2:0.714"],
                                       sigma={"strain@1:0.05": 1e-5, "accel_n@2:0.714": 0.05},
                                       t=t)
    q = np.array(sim.quantity)
    lines = ["t,gauge_root,acc_tip"] + [
        f"{ti},{sim.value[q == 'strain@1:0.05'][i]:.9e},{sim.value[q == 'accel_n@2:0.714'][i]:.9e}"
        for i, ti in enumerate(t)]
    outs = []
    for front in ("batch", "cli"):
        d = tmp_path / front
        d.mkdir()
        (d / "logger.csv").write_text("\n".join(lines) + "\n")
        (d / "rig.nml").write_text(DECK)
        cmd = [str(batch_exe), "--quiet", str(d / "rig.nml")] if front == "batch" else \
            [sys.executable, "-m", "beamid", "fit", str(d / "rig.nml")]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
        outs.append({f: (d / "out" / f).read_text()
                     for f in ("rig_estimates.csv", "rig_residuals.csv")})
    assert outs[0] == outs[1]
    est = outs[0]["rig_estimates.csv"].splitlines()[1].split(",")
    assert est[0] == "rho2" and abs(float(est[1]) - 0.531) < 1e-6
