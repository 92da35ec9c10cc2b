"""Logger files, sensors and DataFrames into Measurements (issue 26)."""
from __future__ import annotations

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
