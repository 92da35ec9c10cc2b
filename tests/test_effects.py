"""The candidate effects are one table in the core (Fortran beamid_effects,
issue 25): the Python Effect list, the default candidates and the bounds of
the estimation problems all read it; register_effect still adds user blocks."""
import math

import numpy as np
import pytest

import beamid
from beamid import _core_estimation as _ce
from beamid.diagnosis import EFFECTS, MODAL_CANDIDATES, STATIC_CANDIDATES, Effect, register_effect

#: what each built-in effect switches on, by pattern, for nbeams = 1, 2, 3
PATTERNS = {
    "axial_coupling": lambda names: ["axial_coupling"],
    "material_cubic": lambda names: [n for n in names if n[0] == "C" and n[1:].isdigit()],
    "elbow_flex": lambda names: ["elbow_flex"] if "elbow_flex" in names else [],
    "root_flex": lambda names: ["root_flex"],
    "friction": lambda names: [n for n in names if n.startswith("mu_")],
    "drag": lambda names: [n for n in names if n.startswith("c_")],
    "rotary_inertia": lambda names: [n for n in names if n.startswith("J_")],
    "kelvin_voigt": lambda names: ["eta"],
    "motor_lag": lambda names: ["tau_motor"],
    "mesh": lambda names: [],
}


@pytest.mark.parametrize("nbeams", [1, 2, 3])
def test_builtin_effects_are_the_core_table(nbeams):
    model = beamid.Model(nbeams, np.ones(len(beamid._core.param_names(nbeams))))
    names = list(model.names())
    assert list(EFFECTS)[:len(PATTERNS)] == list(PATTERNS)
    table = _ce.effect_table(nbeams)
    assert list(table) == list(PATTERNS)
    for name, pattern in PATTERNS.items():
        assert list(EFFECTS[name].params(model)) == pattern(names), name
        assert [names[i] for i in table[name].params] == pattern(names), name
        assert EFFECTS[name].description == table[name].description
    if nbeams == 3:
        assert EFFECTS["friction"].params(model) == ("mu_elbow", "mu_joint2", "mu_tip")


def test_families_defaults_and_bounds():
    """The default candidate lists keep their order; sidedness follows from
    the null value and the bounds."""
    assert STATIC_CANDIDATES == ("axial_coupling", "material_cubic", "elbow_flex", "root_flex")
    assert _ce.default_effects("dynamic") == ("friction", "drag", "rotary_inertia",
                                              "kelvin_voigt", "motor_lag", "elbow_flex",
                                              "root_flex", "mesh")
    # the measurement chain's candidates (beamid.chain) come before the mesh
    assert beamid.DYNAMIC_CANDIDATES == ("friction", "drag", "rotary_inertia", "kelvin_voigt",
                                         "motor_lag", "elbow_flex", "root_flex",
                                         "clock_offset", "channel_bias", "channel_scale",
                                         "gross_errors", "noise", "mesh")
    kinds = {n: e.kinds for n, e in EFFECTS.items() if n in PATTERNS}
    assert kinds["elbow_flex"] == kinds["root_flex"] == ("static", "dynamic", "modal")
    assert kinds["axial_coupling"] == kinds["material_cubic"] == ("static",)
    assert all(kinds[n] == ("dynamic",) for n in ("friction", "motor_lag", "mesh"))
    assert kinds["drag"] == kinds["rotary_inertia"] == ("dynamic", "modal")
    # modal tests alone (issue 27): the defaults of beamid.diagnose and of a deck
    assert _ce.default_effects("modal") == MODAL_CANDIDATES == (
        "rotary_inertia", "root_flex", "elbow_flex", "drag", "kelvin_voigt")
    assert [n for n in PATTERNS if not EFFECTS[n].one_sided] == ["material_cubic"]
    assert (EFFECTS["material_cubic"].lower, EFFECTS["material_cubic"].upper) == \
        (-math.inf, math.inf)
    assert (EFFECTS["axial_coupling"].lower, EFFECTS["axial_coupling"].upper) == (0.0, 1.0)
    assert all(EFFECTS[n].null_value == 0.0 for n in PATTERNS)


def test_fit_bounds_are_the_table_bounds():
    """axial_coupling is bounded by 1 (the table's upper bound): a fit that
    would take it beyond (the data of a softer first beam) stops there,
    flagged at its bound."""
    truth = beamid.pace(axial_coupling=1.0, EI1=10.0)
    exps = {f"F{f:g}": beamid.TipForce(fy=f) for f in (2.0, 5.0, 8.0)}
    data = beamid.simulate_measurements(truth, exps, ["x_tip", "y_tip"], sigma=1e-4)
    fit = beamid.fit(beamid.pace(axial_coupling=0.5), exps, data, free=("axial_coupling",))
    assert fit.estimates["axial_coupling"] == 1.0
    assert fit.flags["axial_coupling"] == "at a physical bound"


def test_register_effect_adds_a_user_block():
    """A user block of two parameters beside the table's effects: tested by
    diagnose like any other."""
    block = Effect("both_hinges", "elbow and root compliance together",
                   lambda m: ("elbow_flex", "root_flex"))
    register_effect(block)
    try:
        truth = beamid.pace(axial_coupling=0.0, elbow_flex=0.004)
        exps = {f"F{f:g}": beamid.TipForce(fy=f) for f in (2.0, 4.0, 6.0, 8.0)}
        data = beamid.simulate_measurements(truth, exps, ["x_tip", "y_tip", "tip_angle"],
                                            sigma=1e-4)
        fit = beamid.fit(beamid.pace(axial_coupling=0.0), exps, data, free=("EI1", "EI2"))
        d = beamid.diagnose(fit, ["elbow_flex", "both_hinges"])
        assert d["both_hinges"].state == "tested"
        assert d["both_hinges"].params == ("elbow_flex", "root_flex")
        assert d.verdict.effect == "elbow_flex"
    finally:
        EFFECTS.pop("both_hinges")
