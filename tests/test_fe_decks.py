"""The FE seed decks reproduce their &published values within one unit of
the last published digit, except listed deviations.

They live in inputs/seed beside the arc-length decks (tasks fe_static and
fe_modes, group &fe: docs/fe.md); beamid reproduce and beamid-batch run them."""
from pathlib import Path

import f90nml
import pytest

import beamid
from beamid import fe

DECK_DIR = Path(__file__).resolve().parents[1] / "inputs" / "seed"
DECKS = sorted(p for p in DECK_DIR.glob("*.nml") if "_fe" in p.stem)


def _as_list(value):
    return value if isinstance(value, list) else [value]


def test_there_are_decks_for_every_fe_table():
    tables = {p.name.split("_")[0] for p in DECKS}
    assert tables == {"table06", "table07", "table09", "table10", "table11", "table12"}


@pytest.mark.parametrize("path", DECKS, ids=[p.stem for p in DECKS])
def test_fe_deck_reproduces_published_values(path):
    nml = f90nml.read(str(path))
    head, load_group, opts = nml["beamid"], nml.get("load", {}), nml.get("fe", {})
    assert head["task"] in fe.FE_TASKS
    assert set(opts) <= set(fe.FE_GROUP)
    model = getattr(beamid, head["preset"])()
    load = beamid.TipForce(fx=load_group.get("fx", 0.0), fy=load_group.get("fy", 0.0)) \
        + beamid.TipMoment(load_group.get("moment", 0.0))
    published = _as_list(nml["published"])
    quantities = [q for pub in published for q in _as_list(pub["quantity"])]
    ours = fe.evaluate_fe(head["task"], model, load,
                          elements_per_beam=opts.get("elements_per_beam", 4),
                          moment_form=opts.get("moment_form", "eq78"),
                          rotary_inertia=opts.get("rotary_inertia", False),
                          point_masses=opts.get("point_masses", True),
                          quantities=quantities)
    for pub in published:
        deviations = set(_as_list(pub.get("deviation", [])))
        for q, value, digits in zip(_as_list(pub["quantity"]), _as_list(pub["value"]),
                                    _as_list(pub["digits"])):
            ok = abs(ours[q] - value) <= 10.0 ** -digits * (1 + 1e-9)
            assert ok != (q in deviations), (path.name, q, ours[q], value)
