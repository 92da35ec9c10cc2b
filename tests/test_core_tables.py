"""Code tables defined once in the core and read by Python, which keeps no copy
(issue 25): the observation kinds without a rate, the load targets and
history kinds, the hub's names, the global parameters and the parameter units."""
from __future__ import annotations

import numpy as np
import pytest

import beamid
from beamid import _core, chain, decks, observations
from beamid import _core_dynamics as _cd
from beamid import _core_estimation as _ce
from beamid import load_histories as lh
from beamid.design import Advice, Ranking
from beamid.plot_fit import parameter_unit


def test_no_rate_kinds_are_the_core_tables_rate_column():
    text = _core._text(_core._deck_api.api_observation_table())
    rows = [line.split(";") for line in text.splitlines() if line.strip()]
    assert len(rows) == len(observations.kinds()) == 31
    assert {r[9] for r in rows} == {"rate", "no_rate"}
    from_core = tuple(r[0] for r in rows if r[9] == "no_rate")
    assert chain.NO_RATE_KINDS == from_core == ("accel_t", "accel_n", "reaction_x",
                                                "reaction_y", "reaction_moment")
    ks = observations.kinds()
    assert ks["vel_n"].rate and ks["hub_torque"].rate and not ks["reaction_moment"].rate
    # the about text after the new column is whole (it may hold ';')
    assert ks["accel_t"].about == "acceleration along the local tangent (an accelerometer)"


def test_a_clock_offset_is_refused_on_a_load_cell_record():
    """The Python check reads the table: a record with load-cell rows takes
    no clock offset, one with velocity rows does."""
    class Data:
        experiment = ("m", "m", "n")
        quantity = ("reaction_y", "w_tip", "vel_n@1:0.2")

    assert chain._no_rate_rows(Data, "m") == ["reaction_y"]
    assert chain._no_rate_rows(Data, "n") == []


def test_load_targets_and_kinds_are_the_cores():
    assert lh.TARGETS == {name: i + 1 for i, name in _ce.code_names(10).items()}
    assert lh.TARGETS == {"tip_fx": 1, "tip_fy": 2, "tip_torque": 3, "motor_open": 4, "hub": 5}
    assert lh._KIND == {"table": 1, "half_sine": 2, "step": 3, "chirp": 4, "spin_up": 5}


def test_load_columns_carry_the_cores_codes():
    """Columns written with the core's codes name their work lines and
    parameters as the core does, and read back to the same histories."""
    loads = [("tip_fx", beamid.Step(1.0)), ("tip_fy", beamid.HalfSine(2.0, 0.01)),
             ("tip_torque", beamid.Chirp(0.1, 1.0, 5.0, 0.2)),
             ("motor_open", beamid.Table((0.0, 0.1), (0.0, 1.0))),
             ("tip_fy", beamid.Step(-1.0, 0.05))]
    spec, tab = lh.columns(loads)
    assert list(spec[0]) == [1, 2, 3, 4, 2] and list(spec[1]) == [3, 2, 4, 1, 3]
    works, pnames = _cd.load_names(spec, tab)
    assert works == ("tip_fx", "tip_fy", "tip_torque", "motor_open", "tip_fy_2")
    assert pnames[:3] == ("tip_fx_amplitude", "tip_fx_start", "tip_fy_amplitude")
    assert lh.from_columns(spec, tab) == loads


def test_hub_names_come_from_the_library():
    spin = lh.columns([("hub", beamid.SpinUp(2.0, 0.5))])
    table = lh.columns([("hub", beamid.Table((0.0, 0.5, 1.0), (0.0, 0.1, 0.4)))])
    assert spin[0][:2, 0].tolist() == [5, 5] and table[0][:2, 0].tolist() == [5, 1]
    assert _cd.load_names(*spin) == (("hub",), ("hub_speed",))
    assert _cd.load_names(*table) == (("hub",), ("hub_scale",))
    both = lh.columns([("tip_fy", beamid.Step(1.0)), ("hub", beamid.SpinUp(2.0, 0.5))])
    assert _cd.load_names(*both) == (("tip_fy", "hub"),
                                     ("tip_fy_amplitude", "tip_fy_start", "hub_speed"))


def test_global_parameters_are_the_cores():
    for nb in (1, 2, 3):
        names, groups = _core.param_names(nb), _core.param_groups(nb)
        assert tuple(n for n, g in zip(names, groups) if g == "global") == decks._GLOBAL
        assert groups.count("beam") == 6 * nb and groups.count("point") == 4 * nb
        assert groups.count("joint") == nb - 1
    assert decks._GLOBAL == ("axial_coupling", "root_flex", "eta", "r_motor", "tau_motor")


def test_deck_round_trip_keeps_the_global_parameters(tmp_path):
    model = beamid.pace(axial_coupling=0.0, root_flex=0.002, eta=1e-4, r_motor=0.5,
                        tau_motor=0.01)
    deck = decks.Deck(path=tmp_path / "a.nml", task="static", output="out/a",
                      model=model, load=beamid.TipForce(0.0, 4.0))
    beamid.write_deck(deck, tmp_path / "b.nml")
    again = beamid.read_deck(tmp_path / "b.nml")
    assert again.model == model
    assert [again.model.params[g] for g in decks._GLOBAL] == [0.0, 0.002, 1e-4, 0.5, 0.01]


def test_parameter_units_are_the_cores():
    units = dict(zip(_core.param_names(3), _core.param_units(3)))
    assert units == {n: parameter_unit(n) for n in _core.param_names(3)}
    assert [units[n] for n in ("L1", "EI2", "EA3", "rho1", "C2", "thick3")] == \
        ["m", "N m^2", "N", "kg/m", "N m^4", "m"]
    assert [units[n] for n in ("m_tip", "J_elbow", "mu_joint2", "c_tip")] == \
        ["kg", "kg m^2", "-", "N s/m"]
    assert [units[n] for n in ("elbow_flex", "joint2_flex", "root_flex", "eta", "r_motor",
                               "tau_motor", "axial_coupling")] == \
        ["rad/(N m)", "rad/(N m)", "rad/(N m)", "s", "N m s", "s", "-"]
    assert parameter_unit("EI12") == "N m^2" and parameter_unit("hub_speed") == "-"
    assert parameter_unit("m_joint7") == "kg" and parameter_unit("joint12_flex") == "rad/(N m)"
    assert parameter_unit("thick" + "9" * 5000) == "m"     # no chain of that size is built
    assert [parameter_unit(n) for n in ("EI0", "EI01", "joint1_flex", "")] == ["-"] * 4
    with pytest.raises(beamid.InputError, match="parameter_unit: name"):
        parameter_unit(3)


def test_design_axis_label_has_the_cores_unit():
    adv = Advice(target="EI1", free=("EI1",), current=1.0, ranking=Ranking(), sigma={},
                 sensitivity={}, loads={})
    assert adv.criterion_label == "predicted sigma of EI1 (N m^2)"
    adv = Advice(target="c_tip", free=("c_tip",), current=1.0, ranking=Ranking(), sigma={},
                 sensitivity={}, loads={})
    assert adv.criterion_label == "predicted sigma of c_tip (N s/m)"
    assert np.isfinite(adv.current)
