"""What a reader sees (issue 31): the classes of `beamid reproduce`'s
deviations, and result objects that print a short summary (their table),
never every replicate."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

import beamid
from beamid.tables import (DEVIATION_CLASSES, LAST_DIGIT_UNITS, Check, format_checks,
                           inputs_dir)

ROOT = Path(__file__).resolve().parents[1]


def _check(ours, published=1.2345, digits=4, deviation=True, kind="", section=""):
    return Check("9", "row", "q", published, ours, digits, deviation, kind, section)


def test_deviation_classes():
    unit = 1e-4
    assert _check(1.2345 + 0.9 * unit).status == "ok"
    assert _check(1.2345 + 2.0 * unit, kind="random draws").status == "deviation: last digit"
    assert LAST_DIGIT_UNITS == 3.0
    assert _check(1.2345 + 3.5 * unit).status == "deviation: unexplained"
    assert _check(1.30, kind="formulation", section="Static estimation").status == \
        "deviation: formulation (Static estimation)"
    assert _check(1.30, kind="random draws").status == "deviation: random draws (in character)"
    assert _check(1.30, kind="unexplained").status == "deviation: unexplained"
    assert _check(1.30, deviation=False).status == "FAIL"
    text = format_checks([_check(1.2345), _check(1.2347), _check(1.30, kind="random draws"),
                          _check(1.30, kind="random draws"), _check(1.30, deviation=False)])
    assert text.splitlines()[-1] == ("1 reproduced, 3 documented deviations (1 last digit, "
                                     "2 random draws), 1 failed")


def test_every_documented_deviation_of_the_seed_decks_names_its_section():
    """A deck that classes its deviations names a section (a heading of
    docs/deviations.md) for a formulation; the classes are the documented ones."""
    headings = re.findall(r"^## (.+)$", (ROOT / "docs" / "deviations.md").read_text(), re.M)
    kinds = set()
    for path in sorted(inputs_dir("seed").glob("*.nml")):
        for pub in beamid.read_deck(path).published:
            if not pub.deviations:
                continue
            kinds.add(pub.kind)
            assert pub.kind in ("", *DEVIATION_CLASSES[1:]), path
            if pub.kind:
                assert any(h.startswith(pub.section) for h in headings), (path, pub.section)
    assert {"formulation", "random draws", "unexplained"} <= kinds
    # the classes and the final count are explained on the page
    page = (ROOT / "docs" / "deviations.md").read_text()
    for cls in DEVIATION_CLASSES:
        assert f'"{cls}"' in page


def test_a_bad_deviation_kind_is_refused(tmp_path):
    deck = tmp_path / "d.nml"
    deck.write_text("&beamid task = 'static', output = 'o', preset = 'pace' /\n"
                    "&load kind = 'tip', fy = 4.0 /\n"
                    "&published table = 'x', row = 'r', quantity = 'y_tip', value = 0.3, "
                    "digits = 3, kind = 'misprint', deviation = 'y_tip' /\n")
    with pytest.raises(beamid.InputError, match="kind = 'misprint', expected 'formulation'"):
        beamid.read_deck(deck)


@pytest.fixture(scope="module")
def table5_fit():
    deck = beamid.read_deck(inputs_dir("seed") / "table05_fit.nml")
    return beamid.fit(deck.model, deck.experiments, deck.data, free=deck.free)


def test_result_objects_print_a_summary(table5_fit):
    fit = table5_fit
    mc = beamid.consistency(fit, replicates=300, workers=1)
    assert str(mc) == mc.table() and len(str(mc)) < 3000
    assert repr(mc).startswith("<Consistency: 300 replicates") and len(repr(mc)) < 300
    assert str(fit) == fit.summary()
    assert repr(fit).startswith("<FitResult converged") and "EI1 = 11.4" in repr(fit)
    cmp = beamid.compare(fit)
    diag = beamid.diagnose(fit)
    ladder = beamid.improve(fit.model, fit.experiments, fit.data, free=fit.free, max_steps=1)
    adv = beamid.design(fit, {"M2": beamid.TipMoment(2.0)}, ["tip_angle"], sigma=1e-3)
    for obj in (fit, cmp, diag, ladder, ladder.steps[0], adv):
        assert len(repr(obj)) < 400, (type(obj).__name__, len(repr(obj)))
        assert len(str(obj)) < 5000, type(obj).__name__
    assert str(adv) == adv.table(20)
