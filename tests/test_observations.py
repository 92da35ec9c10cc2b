"""The one observation table of the core (issue 25) as Python reads it."""
from __future__ import annotations

import numpy as np
import pytest

import beamid
from beamid import observations
from beamid.design import DEFAULT_QUANTITIES
from beamid.measurements import QUANTITIES


def test_table_holds_todays_quantities_in_code_order():
    ks = observations.kinds()
    assert list(ks)[:9] == ["x_tip", "y_tip", "tip_angle", "wire_force", "x_elbow", "y_elbow",
                            "u_tip", "w_tip", "motor_torque"]
    assert tuple(ks) == QUANTITIES
    assert ks["wire_force"].families == {"static"} and ks["wire_force"].needs == "wire"
    assert ks["motor_torque"].families == {"release"} and ks["motor_torque"].needs == "motor"
    assert ks["motor_torque"].sigma == 1e-2 and ks["wire_force"].sigma == 0.1
    assert ks["x_tip"].twin == "u_tip" and ks["w_tip"].twin == "y_tip"
    assert [ks[q].code for q in ("x_tip", "motor_torque")] == [1, 9]


def test_public_names_are_derived_from_the_core():
    assert DEFAULT_QUANTITIES == ("x_tip", "y_tip", "tip_angle", "x_elbow", "y_elbow",
                                  "wire_force")
    assert beamid.SENSITIVITY_QUANTITIES == ("u_tip", "w_tip", "x_tip", "y_tip", "tip_angle",
                                             "x_elbow", "y_elbow", "motor_torque", "energy")
    assert observations.probe_kinds("static") == ("x_tip", "y_tip", "tip_angle", "wire_force",
                                                  "x_elbow", "y_elbow")
    assert observations.probe_kinds("release") == ("u_tip", "w_tip", "tip_angle", "x_elbow",
                                                   "y_elbow", "motor_torque")
    assert observations.unit("tip_angle") == "rad"
    assert observations.unit("motor_torque") == "N m"
    assert observations.unit("wire_force") == "N"


def test_parse_names_the_problem():
    o = observations.parse("  y_tip ")
    assert (o.kind, o.code, o.label) == ("y_tip", 2, "y_tip")
    with pytest.raises(beamid.InputError, match="unknown observation kind \"strain_root\""):
        observations.parse("strain_root")
    with pytest.raises(beamid.InputError, match="takes no locus"):
        observations.parse("x_tip@1:0.3")


def test_can_measure_follows_the_table():
    assert observations.can_measure("wire_force", "release") == "family"
    assert observations.can_measure("wire_force", "static") == "wire"
    assert observations.can_measure("wire_force", "static", has_wire=True) == ""
    assert observations.can_measure("motor_torque", "release") == "motor"
    assert observations.can_measure("motor_torque", "static") == "family"
