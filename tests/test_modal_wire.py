"""Modes about a radial wire's equilibrium (issue 27): the wire of length Lw
from the tip to the root stays on during the modal test (inextensible and
taut: the tip moves on its circle). The FE equilibrium under the wire
converges to the arc-length solution with the mesh; frequencies, damping
ratios, shapes and the tension's derivatives match five-point central
differences (the wire's geometric stiffness T (I - e e^T)/|x|, the bordered
equilibrium sensitivity and the turning constraint all enter them)."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

import beamid

STATIONS = ("shape_n@1:0.4", "shape_n@2:0.3", "shape_psi@2:0.7", "shape_t@2:0.714")


def _tip(model, r):
    """Tip position, tangent angle of the FE equilibrium in r (the tip node's
    free unknowns w, w', u, u' are the last four)."""
    w, dw, u, du = r.q[-4:]
    return model.total_length + u, w, np.arctan2(dw, 1.0 + du)


@pytest.mark.parametrize("lw", [1.4, 1.3])
def test_fe_equilibrium_converges_to_the_arc_length_solution(lw):
    model = beamid.pace()
    arc = beamid.solve_static(model, beamid.RadialWire(lw))
    errs = []
    for nepb in (4, 8, 16):
        r = beamid.modal_analysis(model, beamid.RadialWire(lw), nmodes=1, elements_per_beam=nepb)
        x, y, psi = _tip(model, r)
        assert np.hypot(x, y) == pytest.approx(lw, abs=1e-12)     # on the wire's circle
        errs.append(max(abs(x - arc.tip_x), abs(y - arc.tip_y), abs(psi - arc.tip_angle),
                        abs(r.tension - arc.wire_force) / arc.wire_force))
    # discretization error falls with the mesh (4 -> 8 elements per beam by
    # more than 10x) down to the extensible element's floor (below 5e-5: the
    # bending-induced axial strain of the Epstein-Murray element, as Table 11)
    assert errs[1] < errs[0] / 10
    assert errs[2] < 5e-5
    assert errs[0] > 1e-4   # a coarse mesh is visibly off: the test can fail


def test_the_wire_stiffens_the_arm_across_it_and_takes_a_mode():
    model = beamid.pace(J_elbow=0.0, J_tip=0.0)
    wired = beamid.modal_analysis(model, beamid.RadialWire(1.3), nmodes=3, elements_per_beam=4)
    assert wired.nmodes_model == 32            # one tip motion is held by the wire
    assert wired.tension > 0 and wired.wire_length == 1.3
    with pytest.raises(beamid.InputError, match="has 32 modes"):
        beamid.modal_analysis(model, beamid.RadialWire(1.3), nmodes=33, elements_per_beam=4)
    # the mode shapes keep the tip on the circle: e . (du, dw) = 0 at the tip
    x, y, _ = _tip(model, wired)
    for k in range(3):
        w, _, u, _ = wired.phi[-4:, k]
        assert abs(x * u + y * w) < 1e-12 * np.hypot(x, y) * np.abs(wired.phi[:, k]).max()


@pytest.mark.parametrize("damped", [False, True])
def test_sensitivities_about_the_wire_match_central_differences(damped):
    model = beamid.pace(elbow_flex=0.02, C2=5.0, root_flex=0.01)
    if damped:
        model = model.replace(c_elbow=0.3, eta=1e-3)
    load = beamid.RadialWire(1.35)
    names = ("EI2", "rho1", "elbow_flex", "root_flex", "J_tip", "C2") + \
        (("c_elbow", "eta") if damped else ())

    def run(m, **kw):
        return beamid.modal_analysis(m, load, nmodes=3, elements_per_beam=2,
                                     stations=STATIONS, **kw)

    r = run(model, wrt=names)
    assert r.damped is damped
    for j, n in enumerate(names):
        p = model[n]
        h = 1e-2 * p
        runs = [run(model.replace(**{n: p + k * h})) for k in (-2, -1, 1, 2)]

        def fd(get):
            f = [np.asarray(get(x), dtype=float) for x in runs]
            return (f[0] - 8 * f[1] + 8 * f[2] - f[3]) / (12 * h)

        assert_allclose(r.dtension[j], fd(lambda x: x.tension), rtol=1e-5,
                        atol=1e-7 * r.tension / p)
        assert_allclose(r.dq[:, j], fd(lambda x: x.q), atol=1e-7 / p)
        assert_allclose(r.dfreq[:, j], fd(lambda x: x.freq), rtol=1e-4,
                        atol=1e-6 * r.freq.max() / p)
        if damped:
            assert_allclose(r.dzeta[:, j], fd(lambda x: x.zeta), rtol=1e-4, atol=1e-9 / p)
        for k in (1, 2, 3):
            assert_allclose(r.dshape(k)[:, j], fd(lambda x: x.shape(k)), atol=1e-5 / p)


def test_a_wire_with_a_spin_is_refused():
    with pytest.raises(beamid.InputError, match="no spin about a wired equilibrium"):
        beamid.modal_analysis(beamid.pace(), beamid.RadialWire(1.3), nmodes=2,
                              spin_rate=1.0)


WIRE_DECK = """&beamid
    task = 'fit'
    output = 'out/wired'
    preset = 'pace'
/
&model
    J_elbow = 0.0
    J_tip = 0.0
/
&experiment name = 'W', kind = 'modal', wire_length = 1.3, elements_per_beam = 16 {extra}/
&fit
    data = 'wired.csv'
    free = 'EI1', 'EI2'
/
"""


def test_a_wired_modal_deck_in_python_and_in_the_batch(tmp_path, batch_exe):
    """A deck's modal experiment held by a radial wire (wire_length): its
    frequencies and shapes (made at 32 elements per beam, fitted at 16: the
    bent arm's third frequency moves by 0.08 Hz from 8 to 16 elements per
    beam, by 0.002 Hz from 16 to 32; sigma 1e-2, seed 5) give EI1 and EI2
    within 3 sigma of the values that made them, in beamid.run and in
    beamid-batch alike; a tip force beside the wire is refused naming it."""
    import subprocess

    truth = beamid.pace(J_elbow=0.0, J_tip=0.0, EI1=11.0, EI2=9.5)
    qs = ["freq[1]", "freq[2]", "freq[3]", "shape_n@1:0.4[1]", "shape_n@2:0.714[1]",
          "shape_n@1:0.4[2]", "shape_n@2:0.714[2]"]
    d = beamid.simulate_measurements(
        truth, {"W": beamid.Modal(beamid.RadialWire(1.3), 32)}, qs, sigma=1e-2, noise=True,
        seed=5)
    d.write(tmp_path / "wired.csv")
    (tmp_path / "out").mkdir()
    deck = tmp_path / "wired.nml"
    deck.write_text(WIRE_DECK.format(extra=""))
    r = beamid.run(str(deck))
    assert r.experiments["W"] == beamid.Modal(beamid.RadialWire(1.3), 16)
    for name in ("EI1", "EI2"):
        assert abs(r.estimates[name] - truth[name]) < 3 * r.sigmas[name], name
    assert r.sigmas["EI1"] < 0.05 and r.chi2 < 3 * r.dof
    done = subprocess.run([str(batch_exe), str(deck)], capture_output=True, text=True,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    est = (tmp_path / "out" / "wired_estimates.csv").read_text()
    line = next(x for x in est.splitlines() if x.startswith("EI1,"))
    assert float(line.split(",")[1]) == pytest.approx(r.estimates["EI1"], rel=1e-9)
    deck.write_text(WIRE_DECK.format(extra=", fy = 2.0 "))
    with pytest.raises(beamid.InputError, match="wire_length"):
        beamid.run(str(deck))
