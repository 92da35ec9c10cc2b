"""Modes of the arm about a steady hub spin (issue 28): the in-plane
(chordwise) bending frequencies of a uniform rotating cantilever against the
spin rate.

Reference: the first two flapwise frequencies of a uniform rotating
cantilever without hub radius (Hodges & Rutkowski, AIAA J. 19(11), 1981;
Wright, Smith, Thresher & Wang, J. Appl. Mech. 49, 1982; the comparison
table of Yoo & Shin, J. Sound Vib. 212(5), 1998), in the dimensionless rate
gamma = Omega T and frequency omega T, T = sqrt(rho A L^4 / EI). Without the
Coriolis coupling of stretching and in-plane bending (Yoo & Shin's "coupling
effect ignored", the conventional model) the chordwise frequencies follow
from them exactly: omega_c^2 = omega_f^2 - Omega^2 (the in-plane motion sees
the flapwise centrifugal stiffening and the softening -Omega^2 on top). A
fine mesh reproduces every tabulated number to its last digit.
"""
import numpy as np
import pytest

import beamid

# gamma: (first, second flapwise omega T) of the references above
FLAP = {1.0: (3.6816, 22.1810), 2.0: (4.1373, 22.6149), 5.0: (6.4495, 25.4461),
        10.0: (11.2023, 33.6404)}


def arm(slenderness: float) -> beamid.Model:
    """L = EI = rho A = 1 (T = 1 s: rad/s are the dimensionless numbers),
    EA / EI = slenderness^2 (slenderness L sqrt(A / I))."""
    return beamid.cantilever(L=1.0, EI=1.0, rho=1.0, EA=slenderness**2)


@pytest.mark.parametrize("gamma", sorted(FLAP))
def test_chordwise_frequencies_against_the_flapwise_table(gamma: float) -> None:
    # very stiff axially (slenderness 3000): the inextensible beam of the
    # references; the flapwise numbers implied agree to a unit of the table's
    # last digit (32 elements: 3.68164 4.13732 6.44955 11.20234 and 22.18102
    # 22.61493 25.44611 33.64046)
    r = beamid.modal_analysis(arm(3e3), nmodes=2, elements_per_beam=32, spin_rate=gamma,
                              coriolis=False)
    chord = r.freq * 2 * np.pi
    assert np.sqrt(chord**2 + gamma**2) == pytest.approx(FLAP[gamma], abs=1e-4)
    assert r.spin_rate == gamma
    # the Coriolis coupling vanishes with the stretching: the gyroscopic
    # eigenproblem gives the same frequencies, undamped
    rc = beamid.modal_analysis(arm(3e3), nmodes=2, elements_per_beam=32, spin_rate=gamma)
    assert rc.freq == pytest.approx(r.freq, rel=2e-5)
    assert not rc.damped and np.all(rc.zeta == 0.0)


def test_coriolis_lowers_the_chordwise_frequencies_of_an_extensible_beam() -> None:
    # slenderness 70 (Yoo & Shin's example): the coupling with stretching
    # lowers the first chordwise frequency, more as the spin grows
    low = []
    for gamma in (2.0, 5.0, 10.0):
        kw = dict(nmodes=1, elements_per_beam=8, spin_rate=gamma)
        plain = beamid.modal_analysis(arm(70.0), coriolis=False, **kw).freq[0]
        coupled = beamid.modal_analysis(arm(70.0), **kw).freq[0]
        low.append(1 - coupled / plain)
    assert low[0] == pytest.approx(6.2e-4, rel=0.02)
    assert low[2] == pytest.approx(1.52e-2, rel=0.02)
    assert low[0] < low[1] < low[2]


def test_zero_spin_is_the_non_rotating_analysis() -> None:
    model = beamid.pace(J_elbow=0.0, J_tip=0.0)
    kw = dict(nmodes=5, elements_per_beam=4, stations=("shape_n@2:0.714", "shape_n@1:0.4"))
    base = beamid.modal_analysis(model, beamid.TipForce(fy=0.5), **kw)
    zero = beamid.modal_analysis(model, beamid.TipForce(fy=0.5), spin_rate=0.0, **kw)
    for name in ("freq", "zeta", "q", "phi", "shapes"):
        assert np.array_equal(getattr(zero, name), getattr(base, name)), name
    # and a vanishing spin goes through the gyroscopic eigenproblem continuously
    tiny = beamid.modal_analysis(model, beamid.TipForce(fy=0.5), spin_rate=1e-6, **kw)
    assert tiny.freq == pytest.approx(base.freq, rel=1e-6)
    # damping and spin together: the state-space roots carry both
    damped = model.replace(c_tip=0.5)
    d0 = beamid.modal_analysis(damped, nmodes=3)
    d1 = beamid.modal_analysis(damped, nmodes=3, spin_rate=1e-6)
    assert d1.damped and d1.zeta == pytest.approx(d0.zeta, rel=1e-7)


def test_spin_refusals() -> None:
    model = beamid.pace(J_elbow=0.0, J_tip=0.0)
    with pytest.raises(beamid.InputError, match="spin_rate = nan, expected a finite"):
        beamid.modal_analysis(model, spin_rate=float("nan"))
    with pytest.raises(beamid.InputError, match="sensitivities of the modes about a steady"):
        beamid.modal_analysis(model, spin_rate=1.0, wrt=("EI1",))
    with pytest.raises(beamid.InputError, match="needs a clamped root"):
        beamid.modal_analysis(model.replace(root_flex=0.01), spin_rate=2.0)
    with pytest.raises(beamid.InputError, match="coriolis = 1, expected True or False"):
        beamid.modal_analysis(model, spin_rate=2.0, coriolis=1)


def test_gyroscopic_frequency_matches_a_simulated_spinning_arm() -> None:
    # an independent check of the Coriolis coupling: the nonlinear hub-frame
    # dynamics spun up slowly to gamma = 10, tapped at the tip; the tip's
    # oscillation (zero crossings) runs at the gyroscopic mode's frequency
    # (5.0129 against 5.0134 rad/s), not at the uncoupled one (5.0910)
    arm70 = arm(70.0)
    t = np.linspace(0.0, 22.0, 4401)
    run = beamid.simulate(arm70, None, t, elements_per_beam=8, rtol=1e-10,
                          loads={"hub": beamid.SpinUp(w_s=10.0, T=10.0),
                                 "tip_fy": beamid.HalfSine(peak=0.01, duration=0.05, start=11.0)})
    late = t > 11.2
    w = run.tip_w[late] - run.tip_w[late].mean()
    tt = t[late]
    i = np.where((w[:-1] < 0) & (w[1:] >= 0))[0]
    up = tt[i] - w[i] * (tt[i + 1] - tt[i]) / (w[i + 1] - w[i])
    measured = 2 * np.pi * (up.size - 1) / (up[-1] - up[0])
    kw = dict(nmodes=1, elements_per_beam=8, spin_rate=10.0)
    coupled = beamid.modal_analysis(arm70, **kw).freq[0] * 2 * np.pi
    plain = beamid.modal_analysis(arm70, coriolis=False, **kw).freq[0] * 2 * np.pi
    assert measured == pytest.approx(coupled, rel=2e-3)
    assert abs(measured - plain) > 5 * abs(measured - coupled)
