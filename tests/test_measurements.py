"""Measurement CSV files: reading and validation of every row."""
from __future__ import annotations

import numpy as np
import pytest

import beamid
from beamid import InputError

GOOD = """# PACE directed force, seed form
experiment,t,quantity,value,sigma
F3,0,y_tip,0.2763,0.0008   # comment after a row
F8,0,y_tip,0.5973,0.0011

F8,0,u_tip,-0.08,0.001
"""


def write(tmp_path, text, name="data.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_reads_rows_comments_and_blank_lines(tmp_path):
    data = beamid.read_measurements(write(tmp_path, GOOD))
    assert data.experiment == ("F3", "F8", "F8")
    assert data.quantity == ("y_tip", "y_tip", "u_tip")
    np.testing.assert_allclose(data.value, [0.2763, 0.5973, -0.08])
    np.testing.assert_allclose(data.sigma, [0.0008, 0.0011, 0.001])
    assert data.lines == (3, 4, 6)


def test_round_trip_through_write(tmp_path):
    data = beamid.read_measurements(write(tmp_path, GOOD))
    out = tmp_path / "copy.csv"
    data.write(out, comment="copy")
    again = beamid.read_measurements(out)
    assert again.rows() == data.rows()


@pytest.mark.parametrize("row, field, fragment", [
    ("F3,0,z_tip,0.1,0.001", "quantity", "'z_tip'"),
    ("F3,0,y_tip,abc,0.001", "value", "'abc'"),
    ("F3,0,y_tip,0.1,0", "sigma", "sigma > 0"),
    ("F3,0,y_tip,0.1,-0.001", "sigma", "sigma > 0"),
    ("F3,zero,y_tip,0.1,0.001", "t", "'zero'"),
    ("F3,0,y_tip,nan,0.001", "value", "finite"),
    ("F3,0,y_tip,0.1", None, "expected 5 fields"),
    ("F3,0,y_tip,0.2763,0.0008", None, "duplicate row"),
])
def test_bad_row_names_file_line_and_field(tmp_path, row, field, fragment):
    text = "experiment,t,quantity,value,sigma\nF3,0,y_tip,0.2763,0.0008\n" + row + "\n"
    path = write(tmp_path, text)
    with pytest.raises(InputError) as err:
        beamid.read_measurements(path)
    msg = str(err.value)
    assert str(path) in msg and "line 3" in msg and fragment in msg
    if field:
        assert f"field {field}" in msg


def test_undefined_experiment(tmp_path):
    path = write(tmp_path, "experiment,t,quantity,value,sigma\nF3,0,y_tip,0.27,0.001\n"
                           "F9,0,y_tip,0.6,0.001\n")
    with pytest.raises(InputError, match=r"line 3: field experiment = 'F9' is not defined"):
        beamid.read_measurements(path, experiments={"F3": beamid.TipForce(fy=3.0)})


def test_missing_header_and_file(tmp_path):
    with pytest.raises(InputError, match="expected the header"):
        beamid.read_measurements(write(tmp_path, "F3,0,y_tip,0.27,0.001\n"))
    with pytest.raises(InputError, match="no such file"):
        beamid.read_measurements(tmp_path / "missing.csv")
    with pytest.raises(InputError, match="no measurement rows"):
        beamid.read_measurements(write(tmp_path, "# nothing\nexperiment,t,quantity,value,sigma\n"))


def test_fit_rejects_nonzero_time_and_wire_force_without_wire(tmp_path):
    model = beamid.pace(axial_coupling=0.0)
    exps = {"F3": beamid.TipForce(fy=3.0)}
    data = beamid.read_measurements(write(tmp_path, "experiment,t,quantity,value,sigma\n"
                                                    "F3,0.5,y_tip,0.27,0.001\n"))
    with pytest.raises(InputError, match="line 2: field t = 0.5, expected 0"):
        beamid.fit(model, exps, data, free=("EI1",))
    data = beamid.read_measurements(write(tmp_path, "experiment,t,quantity,value,sigma\n"
                                                    "F3,0,wire_force,30,0.1\n"))
    with pytest.raises(InputError, match="has no wire"):
        beamid.fit(model, exps, data, free=("EI1",))
