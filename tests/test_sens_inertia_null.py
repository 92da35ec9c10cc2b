"""Forward sensitivity of the rotary inertias J_elbow, J_tip (Table 1; M(q)
of Eq. 130-132) at their null value J = 0, where the integrators take the
constant-mass path: the parameter terms -(dM/dJ) a and the gyroscopic term
of Eq. 132 must still drive the sensitivity (without them it is zero, as the
state's sensitivity starts at zero).

J >= 0, so the check is against a one-sided second-order difference
(-3 y(0) + 4 y(h) - y(2h)) / (2 h) at h = 1e-8 kg m^2, both integrators, with
and without friction. The response is strongly curved in J: on a coarse mesh
the end nodes' slope inertia from the consistent beam mass is small (it
scales with the element length cubed), so J of 1e-6..1e-5 kg m^2 already
changes the high modes; a secant over 1e-5 differs from the derivative at 0
by tens of percent. That is asserted too: it is why differences at h = 1e-6
(or central ones, which J >= 0 does not allow) disagree with the derivative,
and why the dynamic diagnosis scores J with a one-sided column over a finite
step."""
import numpy as np
import pytest

import beamid

H = 1e-8
REL = beamid.TipForce(fy=8.0)


def _kw(integrator):
    span = 0.1 if integrator == "implicit" else 0.03
    kw = dict(t_out=np.linspace(0.0, span, 4), elements_per_beam=2, integrator=integrator)
    if integrator == "implicit":
        kw["rtol"] = 1e-11
    return kw


@pytest.mark.parametrize("friction", [False, True])
@pytest.mark.parametrize("integrator", ["implicit", "rk4"])
def test_inertia_sensitivity_at_zero_matches_one_sided_differences(integrator, friction):
    over = dict(J_elbow=0.0, J_tip=0.0)
    if friction:
        over.update(mu_elbow=0.01, mu_tip=0.02)
    model = beamid.pace(**over)
    kw = _kw(integrator)
    run = beamid.simulate(model, release=REL, wrt=("J_elbow", "J_tip"), **kw)
    for p in ("J_elbow", "J_tip"):
        r1 = beamid.simulate(model.replace(**{p: H}), release=REL, **kw)
        r2 = beamid.simulate(model.replace(**{p: 2 * H}), release=REL, **kw)
        for q in ("tip_w", "tip_angle"):
            d = run.d[q][p]
            fd = (-3 * getattr(run, q) + 4 * getattr(r1, q) - getattr(r2, q)) / (2 * H)
            scale = np.max(np.abs(fd))
            assert scale > 0.0, (p, q)
            assert np.max(np.abs(d - fd)) < 1e-2 * scale, (p, q, d, fd)


def test_inertia_response_is_curved_near_zero():
    """The derivative at J = 0 holds only for J well below 1e-5 kg m^2 here."""
    model = beamid.pace(J_elbow=0.0, J_tip=0.0)
    kw = _kw("implicit")
    run = beamid.simulate(model, release=REL, wrt=("J_tip",), **kw)
    big = beamid.simulate(model.replace(J_tip=1e-5), release=REL, **kw)
    d = run.d["tip_angle"]["J_tip"]
    secant = (big.tip_angle - run.tip_angle) / 1e-5
    assert np.max(np.abs(secant - d)) > 0.1 * np.max(np.abs(d))
