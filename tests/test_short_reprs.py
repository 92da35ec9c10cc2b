"""Result objects print a short summary, never every array or row (issue 31),
and the command line names its options in refusals that come from the API
(issue 32)."""
from __future__ import annotations

import numpy as np

import beamid
from beamid.cli import main


def test_run_repr_is_a_summary_not_its_arrays():
    run = beamid.simulate(beamid.cantilever(), beamid.TipForce(fy=1.0),
                          np.linspace(0.0, 0.05, 200), elements_per_beam=2)
    text = repr(run)
    assert text.startswith("<Run: 200 output times to 0.05 s (")
    assert "2 elements per beam" in text and len(text) < 200


def test_measurements_repr_is_a_summary_not_its_rows():
    rows = [("R", 0.01 * k, "w_tip", 1e-3 * k, 1e-4) for k in range(600)]
    data = beamid.Measurements.from_rows(rows)
    text = repr(data)
    assert text == "<Measurements: 600 rows from <python>; experiments R; quantities w_tip>"


def test_static_repr_shows_a_wire_force_only_with_a_wire():
    tip = beamid.solve_static(beamid.pace(), beamid.TipForce(fy=8.0))
    assert "wire_force" not in repr(tip) and "nan" not in repr(tip)
    wire = beamid.solve_static(beamid.pace(), beamid.RadialWire(1.3))
    assert "wire_force=" in repr(wire)


def test_api_refusals_name_the_option(capsys, tmp_path):
    code = main(["simulate", "--elements-per-beam", "99999999999",
                 "--output", str(tmp_path / "x")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert err[0].startswith("beamid: error: --elements-per-beam = 99999999999, expected")
    code = main(["simulate", "--set", "foo=1", "--output", str(tmp_path / "x")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err == ["beamid: error: --set foo=1: unknown parameter name 'foo' "
                                 "for a 2-beam chain"]
