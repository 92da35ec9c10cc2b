"""Experiment families as an open list (issue 25): the core's key table of
experiment specs, experiments crossing the binding by name, and the
refusals that name the experiment, the key and the keys accepted."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import beamid
from beamid import _core, _core_estimation as _ce
from beamid.estimation import build_problem

BASE = beamid.pace()


def _static_problem():
    exps = {"tip": beamid.TipLoad(fy=-2.0), "wire": beamid.RadialWire(1.4)}
    data = beamid.simulate_measurements(BASE, exps, ["x_tip", "y_tip"], sigma=1e-3)
    return build_problem(BASE, exps, data)


def test_key_table_from_the_core():
    keys = _core.spec_keys()
    # the deck's names, in the core's row order, with the families that take them
    assert list(keys)[:12] == ["fx", "fy", "moment", "wire_length", "elements_per_beam",
                               "motor_gain", "integrator", "friction", "rtol", "dt", "v_slip",
                               "fd"]
    assert [k.row for k in keys.values()] == list(range(len(keys)))
    assert _ce.NEXPVAL == len(keys) == 19          # v0, the chain's initial velocity, is 19th
    assert keys["wire_length"].families == ("static", "modal")   # a wire held in a modal test
    assert keys["elements_per_beam"].families == ("release", "modal")   # the FE families
    assert keys["elements_per_beam"].default == 4.0
    assert keys["burn_in"].families == ("static", "release", "modal")
    assert keys["v0"].row == 18 and keys["v0"].default == 0.0
    # a Release builds its spec by these names
    kind, spec = beamid.Release(beamid.TipLoad(fy=-1.0), elements_per_beam=3).spec()
    assert kind == 3 and spec["elements_per_beam"] == 3.0 and spec["fy"] == -1.0
    assert set(spec) <= set(keys)


def test_specs_cross_as_sparse_triples():
    prob = _static_problem()
    exp, key, val = prob.specs()
    # only the keys given: fy = -2 of the tip load, wire_length = 1.4 of the wire
    assert exp.tolist() == [1, 2]
    assert [list(_core.spec_keys())[k - 1] for k in key] == ["fy", "wire_length"]
    assert val.tolist() == [-2.0, 1.4]
    pred, _ = _ce.problem_predict(prob, BASE.vector(), np.zeros(0, np.int32))
    assert pred.shape == (4,) and np.all(np.isfinite(pred))


def test_problem_holds_specs_by_name():
    """The problem keeps each experiment's spec by key name; the positional
    exp_values is derived from it, read-only, and the triples are the same
    whichever form they come from."""
    exps = {"tip": beamid.TipLoad(fy=-2.0), "rel": beamid.Release(beamid.TipLoad(fy=-1.5),
                                                                   elements_per_beam=3)}
    data = beamid.simulate_measurements(BASE, {"tip": exps["tip"]}, ["y_tip"], sigma=1e-3)
    rel = beamid.simulate_measurements(BASE, {"rel": exps["rel"]}, ["w_tip"], sigma=1e-3,
                                       t=[0.05, 0.1])
    prob = build_problem(BASE, exps, data.merge(rel), rows=beamid.chain.RowTreatment("huber"))
    tip, release = prob.exp_specs
    assert tip == {"fx": 0.0, "fy": -2.0, "moment": 0.0, "loss": 1.0, "burn_in": 0.0,
                   "sigma_est": 0.0}
    assert release["elements_per_beam"] == 3.0 and release["fy"] == -1.5
    assert release["loss"] == 1.0
    values = prob.exp_values
    assert values.shape == (_ce.NEXPVAL, 2) and not values.flags.writeable
    assert values[_core.spec_row("elements_per_beam"), 1] == 3.0
    assert values[_core.spec_row("loss"), 0] == 1.0
    for a, b in zip(prob.specs(), _core.spec_triples(values)):
        assert a.tolist() == b.tolist()
    with pytest.raises(beamid.InputError, match=r"experiment 1: spec key 'fz' is unknown; "
                       r"expected one of fx, fy, moment"):
        _core.spec_triples_of([{"fz": 1.0}])


def test_key_not_of_the_family_is_refused():
    prob = _static_problem()
    specs = [dict(spec) for spec in prob.exp_specs]
    specs[1]["elements_per_beam"] = 8.0
    bad = dataclasses.replace(prob, exp_specs=tuple(specs))
    with pytest.raises(beamid.InputError, match=r"experiment 2 \(static\): key "
                       r"elements_per_beam is not a key of a static experiment; expected one "
                       r"of fx, fy, moment, wire_length, t0, bias, scale, loss, burn_in, "
                       r"sigma_est"):
        _ce.problem_predict(bad, BASE.vector(), np.zeros(0, np.int32))


def test_unknown_kind_names_the_registered_kinds():
    prob = _static_problem()
    bad = dataclasses.replace(prob, exp_kind=np.array([1, 9], np.int32))
    with pytest.raises(beamid.InputError, match=r"experiment 2 has kind 9, expected "
                       r"1 \(tip load\), 2 \(wire\), 3 \(release\) or 4 \(modal\)"):
        _ce.problem_predict(bad, BASE.vector(), np.zeros(0, np.int32))


def test_prior_of_several_parameters_reaches_the_fit():
    """The shared set-up (problem_lsq_from_arrays) carries every prior
    parameter: a tight prior pins both estimates at its means."""
    exps = {"tip": beamid.TipLoad(fy=-2.0), "wire": beamid.RadialWire(1.4)}
    data = beamid.simulate_measurements(BASE, exps, ["x_tip", "y_tip"], sigma=1e-3, seed=3)
    ei1, ei2 = BASE["EI1"], BASE["EI2"]
    fit = beamid.fit(BASE, exps, data, free=("EI1", "EI2"),
                     prior={"EI1": (1.05 * ei1, 1e-9), "EI2": (0.95 * ei2, 1e-9)})
    assert abs(fit.estimates["EI1"] / (1.05 * ei1) - 1.0) < 1e-6
    assert abs(fit.estimates["EI2"] / (0.95 * ei2) - 1.0) < 1e-6


def test_family_registry_from_the_core():
    """The fronts ask the core's registry what an experiment is (records in
    time, a mesh of its own), not which class it is."""
    from beamid import loads
    from beamid.diagnosis import _dynamic, _meshed, _modal_only

    fams = _core.families()
    assert list(fams) == ["static", "release", "modal"]
    assert [f.timed for f in fams.values()] == [False, True, False]
    assert [f.mesh_key for f in fams.values()] == ["", "elements_per_beam", "elements_per_beam"]
    assert fams["static"].kinds == {1: "tip load", 2: "wire"}
    assert _core.family_of_kind(3) is fams["release"] and _core.family_of_kind(9) is None
    rel = beamid.Release(beamid.TipLoad(fy=-1.0))
    modal = beamid.Modal(beamid.TipLoad(fy=-1.0))
    assert loads.family(rel).name == "release" and loads.timed(rel)
    assert loads.family(beamid.RadialWire(1.4)).name == "static"
    assert loads.family(modal).meshed and not loads.timed(modal)
    assert loads.family("F3") is None and not loads.timed(3.0)
    static = {"F": beamid.TipForce(fy=3.0)}
    assert not _dynamic(static) and not _meshed(static) and not _modal_only(static)
    assert _dynamic({"r": rel, **static}) and _meshed({"m": modal}) and _modal_only({"m": modal})
    assert not _modal_only({"m": modal, **static})
    # what has no family is refused by name
    with pytest.raises(beamid.InputError, match="experiment 'x': load = 'F3', expected"):
        beamid.fit(BASE, {"x": "F3"}, beamid.simulate_measurements(BASE, static, ["y_tip"],
                                                                    sigma=1e-3))
