"""The dynamic demo ladder (inputs/demo/dynamic_hidden_effect.nml, run by
`make demo`): the rig's data hide the tip mass's rotary inertia (Table 1,
J_tip = 15.244e-4 kg m^2) and tip drag (c_tip = 0.01 N s/m); improve must add
exactly these, in order, and nothing spurious.

The data were made by inputs/demo/make_dynamic_hidden_effect.py at rtol
1e-11 (the fits use 1e-9) with Gaussian noise of sigma 1e-4 m from seed 2026.
Over half a period the elbow's drag coefficient explains the swing's decay
about as well as the tip's (chi-square 105.7 against 104.7 + the rotary
inertia's share), so the first rung picks c_elbow; once the rotary inertia
is in, the tip's coefficient is tested, fits better, and takes its place.
"""
from __future__ import annotations

from pathlib import Path

import beamid
from beamid.fit_decks import read_fit_deck

DECK = Path(__file__).resolve().parent.parent / "inputs" / "demo" / "dynamic_hidden_effect.nml"
TRUE = {"c_tip": 0.01, "J_tip": 15.244e-4, "rho2": 0.530}


def test_demo_ladder_adds_drag_then_rotary_inertia_and_nothing_spurious():
    deck = read_fit_deck(DECK)
    ladder = beamid.improve(deck.model, deck.experiments, deck.data, free=deck.free,
                            prior=deck.prior, candidates=deck.candidates, alpha=deck.alpha,
                            max_iter=deck.max_iter)
    # the rungs, in order: drag (elbow, as tested), the tip's rotary inertia,
    # the tip's drag in place of the elbow's
    assert ladder.effects == ("drag", "rotary_inertia", "drag")
    assert [s.params for s in ladder.steps] == [(), ("c_elbow",), ("J_tip",), ("c_tip",)]
    assert ladder.steps[3].removed == ("c_elbow",)
    assert "c_tip instead of c_elbow" in str(ladder)
    final = ladder.fit
    # nothing spurious: exactly the hidden effects are free, the others off
    assert final.free == ("rho2", "J_tip", "c_tip")
    for n in ("c_elbow", "eta", "tau_motor"):
        assert final.model[n] == 0.0
    for n, v in TRUE.items():
        assert abs(final.estimates[n] - v) <= 3.0 * final.sigmas[n], n
    # the fit is consistent with the noise and nothing more is significant
    last = ladder.steps[-1].diagnosis
    assert last.verdict is None and "consistent with the noise" in last.message
    assert final.chi2_per_dof < 1.2 and ladder.steps[0].chi2_per_dof > 30
    # the mesh (the data's own, at a tighter tolerance) was tested once and
    # found adequate; the motor lag is not seen without a motor
    assert ladder.steps[0].diagnosis.mesh is not None
    assert not ladder.steps[0].diagnosis.mesh.significant
    assert last.not_seen == ("motor_lag",)
