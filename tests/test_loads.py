"""Load histories of a dynamic experiment (issue 28): tip forces, torques and the
open-loop motor in time, their sensitivities, the ledger, bad input."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.linalg import eigh

import beamid
from beamid.dynamics import dynamic_system


def _tip_w_index(run) -> int:
    return next(k for k in range(run.nfree) if np.array_equal(run.states[k], run.tip_w))


def half_sine_modal(K, M, i, peak, T, t):
    """Tip response of the undamped linear arm M q'' + K q = e_i peak sin(pi t/T)
    (t < T) by modal superposition (Duhamel's integral in closed form)."""
    w2, phi = eigh(K, M)
    om = np.sqrt(w2)
    Om = np.pi / T
    a = np.minimum(t, T)
    out = np.zeros_like(t)
    for r, w in enumerate(om):
        def prim(tau):
            return 0.5 * (np.sin((Om + w) * tau - w * t) / (Om + w)
                          - np.sin((Om - w) * tau + w * t) / (Om - w))
        out += phi[i, r] ** 2 * peak * (prim(a) - prim(0.0)) / w
    return out


@pytest.mark.parametrize("integrator,kw,tol", [("implicit", {"rtol": 1e-11}, 1e-11),
                                               ("rk4", {"dt": 2e-6}, 1e-13)])
def test_half_sine_impulse_matches_modal_superposition(integrator, kw, tol):
    # a hammer's 0.01 N, 2 ms half-sine on the tip of the uniform cantilever,
    # 4 elements: at this amplitude the nonlinear element is the linear arm, whose
    # response is the sum over all its modes of Duhamel's integral
    model = beamid.cantilever()
    t = np.linspace(0.0, 0.02, 41)
    run = beamid.simulate(model, None, t, elements_per_beam=4, integrator=integrator,
                          loads={"tip_fy": beamid.HalfSine(0.01, 0.002)}, **kw)
    n = run.nfree
    sysd = dynamic_system(model, np.zeros(n), np.zeros(n), elements_per_beam=4)
    ref = half_sine_modal(sysd["K"], sysd["M"], _tip_w_index(run), 0.01, 0.002, t)
    assert np.max(np.abs(run.tip_w)) == pytest.approx(2.5953526e-6, rel=1e-6)
    assert np.max(np.abs(run.tip_w - ref)) < tol
    # the pulse's work is all in the arm at the end (no dissipation)
    assert run.ledger["tip_fy"][-1] == pytest.approx(run.energy[-1], rel=1e-6)


def test_history_sensitivities_match_central_differences():
    model = beamid.cantilever()
    t = np.linspace(0.0, 0.02, 11)

    def run(peak=5.0, T=0.002, ei=11.413, wrt=None):
        return beamid.simulate(beamid.cantilever(EI1=ei), None, t, elements_per_beam=4,
                               rtol=1e-12, wrt=wrt,
                               loads={"tip_fy": beamid.HalfSine(peak, T)})

    base = run(wrt=("tip_fy_amplitude", "tip_fy_duration", "EI1"))
    assert model.params["EI1"] == 11.413
    for name, shifted, h in (("tip_fy_amplitude", lambda d: run(peak=5.0 + d), 1e-3),
                             ("tip_fy_duration", lambda d: run(T=0.002 + d), 1e-7),
                             ("EI1", lambda d: run(ei=11.413 + d), 1e-3)):
        fd = (shifted(h).tip_w - shifted(-h).tip_w) / (2 * h)
        an = base.d["tip_w"][name]
        assert np.max(np.abs(an - fd)) <= 1e-6 * np.max(np.abs(an)), name
    assert np.max(np.abs(base.d["tip_w"]["tip_fy_duration"])) == pytest.approx(0.64256, rel=1e-4)


def test_rk4_sensitivity_across_the_pulse_end():
    # the half-sine's duration derivative jumps to 0 at its end: the step landing
    # there and the one leaving it take the two sides (first order otherwise)
    t = np.linspace(0.0, 0.004, 5)

    def run(T=0.002, wrt=None):
        return beamid.simulate(beamid.cantilever(), None, t, elements_per_beam=4,
                               integrator="rk4", dt=1e-6, wrt=wrt,
                               loads={"tip_fy": beamid.HalfSine(5.0, T)})

    an = run(wrt=("tip_fy_duration",)).d["tip_w"]["tip_fy_duration"]
    fd = (run(0.002 + 1e-7).tip_w - run(0.002 - 1e-7).tip_w) / 2e-7
    assert an[-1] == pytest.approx(0.19157907, rel=1e-6)
    assert np.max(np.abs(an - fd)) < 5e-9


def test_open_loop_motor_reproduces_the_feedback_law():
    # the Chapter V feedback torque, recorded and played back open loop (a
    # table through every recorded time), gives the same motion
    model = beamid.pace(J_elbow=0.0, J_tip=0.0)
    t = np.linspace(0.0, 0.25, 2501)
    fb = beamid.simulate(model, beamid.TipForce(fy=8.0), t, motor_gain=0.2, rtol=1e-10)
    ol = beamid.simulate(model, beamid.TipForce(fy=8.0), t, rtol=1e-10,
                         loads={"motor_open": beamid.Table(t, fb.motor_torque)})
    assert np.max(np.abs(ol.tip_w - fb.tip_w)) < 1e-7
    assert np.all(ol.motor_torque == 0.0)
    assert ol.ledger["motor_open"][-1] == pytest.approx(fb.ledger["motor"][-1], rel=1e-4)
    assert abs(ol.ledger["numerical"][-1]) < 1e-7


def test_ledger_closes_with_each_loads_work():
    model = beamid.pace(J_elbow=0.0, J_tip=0.0)
    t = np.linspace(0.0, 0.05, 11)
    loads = [("tip_fy", beamid.Table([0.0, 0.01, 0.02], [0.0, 3.0, 0.0])),
             ("tip_fx", beamid.Step(-1.0, start=0.0137)),
             ("tip_torque", beamid.HalfSine(0.2, 0.004, start=0.005)),
             ("tip_fy", beamid.Chirp(0.5, 5.0, 40.0, 0.04))]
    runs = {i: beamid.simulate(model, None, t, integrator=i, loads=loads,
                               **({"dt": 1e-5} if i == "rk4" else {}))
            for i in ("implicit", "rk4")}
    imp, rk = runs["implicit"], runs["rk4"]
    names = ("tip_fy", "tip_fx", "tip_torque", "tip_fy_2")
    assert tuple(imp.ledger)[-5:-1] == names
    assert np.max(np.abs(imp.tip_w - rk.tip_w)) < 1e-6
    for run in (imp, rk):
        total = sum(abs(run.ledger[n][-1]) for n in names)
        assert abs(run.ledger["numerical"][-1]) < 1e-6 * total
        assert run.energy[-1] == pytest.approx(sum(run.ledger[n][-1] for n in names),
                                               rel=1e-5)
    # the table's rows, the step and the pulse ends are breakpoints: one extra
    # force evaluation each for RK4 (rates after the breakpoint)
    assert rk.info["fevals"] == 4 * rk.info["steps"] + 1 + 6


def test_table_from_csv_and_its_errors(tmp_path):
    good = tmp_path / "hammer.csv"
    good.write_text("t,force\n0,0\n0.001,10\n0.002,0\n")
    tab = beamid.Table.from_csv(good, "force")
    assert tab.times == (0.0, 0.001, 0.002) and tab.values == (0.0, 10.0, 0.0)
    bad = tmp_path / "bad.csv"
    bad.write_text("t,force\n0,0\n0.002,10\n0.001,0\n")
    with pytest.raises(beamid.InputError, match=r"bad.csv: line 4: field 't' = 0.001 is not "
                                                r"after the previous row's 0.002"):
        beamid.Table.from_csv(bad, "force")
    bad.write_text("t,force\n0,0\n0.001,ten\n")
    with pytest.raises(beamid.InputError, match=r"bad.csv: line 3: field 'force' = 'ten'"):
        beamid.Table.from_csv(bad, "force")
    with pytest.raises(beamid.InputError, match=r"line 1: no column 'fy'"):
        beamid.Table.from_csv(good, "fy")
    with pytest.raises(beamid.InputError, match=r"row 2: t = 0.0 is not after row 1"):
        beamid.Table([0.0, 0.0], [1.0, 2.0])


def test_bad_histories():
    model = beamid.cantilever()
    t = [0.0, 0.01]
    with pytest.raises(beamid.InputError, match=r"HalfSine duration = 0.0, expected a "
                                                r"finite number > 0"):
        beamid.HalfSine(1.0, 0.0)
    with pytest.raises(beamid.InputError, match=r"load history 1 \(tip_fy\): starts at "
                                                r"t = 0.2\d*E-1 s, after the experiment \(last "
                                                r"output time 0.1\d*E-1 s\)"):
        beamid.simulate(model, None, t, loads={"tip_fy": beamid.Step(1.0, start=0.02)})
    with pytest.raises(beamid.InputError, match=r"target 'tip_fz'"):
        beamid.simulate(model, None, t, loads={"tip_fz": beamid.Step(1.0)})
    with pytest.raises(beamid.InputError, match=r"wrt: unknown parameter 'tip_fy_duration'"):
        beamid.simulate(model, None, t, loads={"tip_fy": beamid.Step(1.0)},
                        wrt="tip_fy_duration")
    fmax = np.max(beamid.modes(model, 2).omega) / (2 * np.pi)
    with pytest.warns(UserWarning, match=rf"a chirp reaches 1e\+06 Hz, above the highest "
                                         rf"frequency of the mesh \({fmax:.6g} Hz"):
        beamid.simulate(model, None, t, elements_per_beam=2,
                        loads={"tip_fy": beamid.Chirp(0.1, 0.0, 1e6, 0.01)})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        beamid.simulate(model, None, t, elements_per_beam=2,
                        loads={"tip_fy": beamid.Chirp(0.1, 0.0, 100.0, 0.01)})


# ------------------------------------------------------------ hub rotation


@pytest.mark.parametrize("ws,T,t_end", [(10.0, 5.0, 7.0), (40.0, 3.0, 5.0)])
def test_steady_spin_matches_the_spinning_cantilever(ws, T, t_end):
    # after a smooth spin-up the uniform cantilever spins steadily: the root axial
    # force is rho A w_s^2 L^2 / 2 and the tip stretch rho A w_s^2 L^3 / (3 EA)
    # (the bar's u(s) = rho A w^2 (L^2 s - s^3/3)/(2 EA), cubic: the element
    # holds it exactly); w_s = 40 rad/s is above the first bending frequency
    # (27 rad/s) and the spin-up stays bounded, as the geometrically nonlinear
    # element stiffens the arm (a linear model diverges: Kane, Ryan and
    # Banerjee 1987)
    model = beamid.cantilever()
    p = model.params
    t = np.linspace(0.0, t_end, int(t_end * 40) + 1)
    run = beamid.simulate(model, None, t, elements_per_beam=4, rtol=1e-10,
                          loads={"hub": beamid.SpinUp(ws, T)})
    late = t > T + 0.5
    n0 = p["rho1"] * ws**2 * p["L1"]**2 / 2
    stretch = p["rho1"] * ws**2 * p["L1"]**3 / (3 * p["EA1"])
    # the first free unknown is the root's u' (the axial strain at the clamp)
    assert p["EA1"] * run.states[0][late].mean() == pytest.approx(n0, rel=2e-5)
    assert run.tip_u[late].mean() == pytest.approx(stretch, rel=5e-4)
    assert np.max(np.abs(run.tip_w)) < 0.03
    assert np.max(np.abs(run.tip_w[late])) < 1e-4
    # the relative energy ledger closes with the hub's work line
    assert abs(run.ledger["numerical"][-1]) < 1e-7 * run.ledger["hub"][-1]
    assert run.ledger["hub"][-1] == pytest.approx(run.energy[-1], rel=1e-6)


def test_hub_speed_sensitivity_matches_central_differences():
    t = np.linspace(0.0, 1.5, 16)

    def run(ws, wrt=None):
        return beamid.simulate(beamid.cantilever(), None, t, elements_per_beam=4,
                               rtol=1e-12, wrt=wrt, loads={"hub": beamid.SpinUp(ws, 1.0)})

    an = run(20.0, ("hub_speed",))
    for q in ("tip_w", "tip_u"):
        fd = (getattr(run(20.0 + 1e-4), q) - getattr(run(20.0 - 1e-4), q)) / 2e-4
        assert np.max(np.abs(an.d[q]["hub_speed"] - fd)) < 1e-6 * np.max(np.abs(fd)), q


def test_hub_law_bad_input():
    with pytest.raises(beamid.InputError, match=r"SpinUp T = 0.0, expected a finite number > 0"):
        beamid.SpinUp(10.0, 0.0)
    with pytest.raises(beamid.InputError, match=r"needs a clamped root .* no rotary inertia"):
        beamid.simulate(beamid.pace(), None, [0.0, 0.1], loads={"hub": beamid.SpinUp(1.0, 1.0)})
    with pytest.raises(beamid.InputError, match=r"loads\['hub'\] = .*expected a SpinUp"):
        beamid.simulate(beamid.cantilever(), None, [0.0, 0.1], loads={"hub": beamid.Step(1.0)})
    law = beamid.SpinUp(6.0, 15.0)
    assert law.angle([0.0, 15.0, 20.0]) == pytest.approx([0.0, 45.0, 75.0])


def test_hub_angle_table_follows_the_law_it_samples():
    # the spin-up law sampled every 0.05 s, as a table of the hub angle (a
    # natural cubic spline): the same spin-up to the spline's accuracy
    model = beamid.cantilever()
    law = beamid.SpinUp(10.0, 5.0)
    knots = np.linspace(0.0, 8.0, 161)
    table = beamid.Table(knots, law.angle(knots))
    t = np.linspace(0.0, 7.0, 281)
    a = beamid.simulate(model, None, t, elements_per_beam=4, rtol=1e-10, loads={"hub": law})
    b = beamid.simulate(model, None, t, elements_per_beam=4, rtol=1e-10, loads={"hub": table})
    assert np.max(np.abs(a.tip_w - b.tip_w)) < 1e-6
    assert np.max(np.abs(a.tip_w)) == pytest.approx(0.00478194, rel=1e-5)
    late = t > 5.5
    assert b.tip_u[late].mean() == pytest.approx(6.0409e-7, rel=1e-4)
    assert abs(b.ledger["numerical"][-1]) < 1e-7 * b.ledger["hub"][-1]
    # its scale's sensitivity against central differences
    short = t[:41]

    def run(scale, wrt=None):
        return beamid.simulate(model, None, short, elements_per_beam=4, rtol=1e-12, wrt=wrt,
                               loads={"hub": beamid.Table(knots, law.angle(knots), scale)})

    an = run(1.0, ("hub_scale",)).d["tip_w"]["hub_scale"]
    fd = (run(1.0 + 1e-6).tip_w - run(1.0 - 1e-6).tip_w) / 2e-6
    assert np.max(np.abs(an - fd)) < 1e-6 * np.max(np.abs(fd))
    with pytest.raises(beamid.InputError, match=r"hub angle table needs at least 2 rows"):
        beamid.simulate(model, None, short, loads={"hub": beamid.Table([0.0], [0.0])})


# ------------------------------------------------------------ beamid simulate --loads


def test_cli_simulate_with_a_loads_csv(tmp_path, monkeypatch, capsys):
    from beamid.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "hammer.csv").write_text("t,tip_fy\n0,0\n0.0005,20\n0.001,0\n")
    assert main(["simulate", "--loads", "hammer.csv", "--fy", "0", "--t-end", "0.2",
                 "--n-out", "5", "--no-plots", "-o", "out/hammer"]) == 0
    table = np.genfromtxt(tmp_path / "out/hammer_history.csv", delimiter=",", names=True)
    assert "tip_fy" in table.dtype.names
    # the same run through the API: a triangle of 20 N peak over 1 ms
    run = beamid.simulate(beamid.pace(J_elbow=0.0, J_tip=0.0), None,
                          np.linspace(0.0, 0.2, 5), elements_per_beam=4,
                          loads={"tip_fy": beamid.Table([0, 0.0005, 0.001], [0, 20, 0])})
    assert table["tip_w"] == pytest.approx(run.tip_w, rel=1e-12, abs=1e-15)
    assert table["tip_fy"][-1] == pytest.approx(run.ledger["tip_fy"][-1], rel=1e-12)
    assert table["tip_w"][-1] == pytest.approx(0.0013048, rel=1e-4)
    (tmp_path / "bad.csv").write_text("t,tip_fy\n0,0\n0.001,20\n0.0005,0\n")
    capsys.readouterr()
    assert main(["simulate", "--loads", "bad.csv", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert "bad.csv: line 4: field 't' = 0.0005 is not after the previous row's 0.001" in err
    (tmp_path / "bad.csv").write_text("t,tip_fz\n0,0\n")
    assert main(["simulate", "--loads", "bad.csv", "--no-plots"]) == 2
    assert "column 'tip_fz' is not a target" in capsys.readouterr().err


@pytest.mark.parametrize("integrator,kw", [("implicit", {"rtol": 1e-12}), ("rk4", {"dt": 1e-6})])
def test_step_start_sensitivity_takes_the_jump_condition(integrator, kw):
    # a step's start moves the time where the force jumps: the state
    # sensitivities jump there by (f- - f+) d t0/d start (the only term: the
    # force's own derivative is zero away from the jump)
    t = np.linspace(0.0, 0.02, 11)

    def run(start, wrt=None):
        return beamid.simulate(beamid.cantilever(), None, t, elements_per_beam=4,
                               integrator=integrator, wrt=wrt,
                               loads={"tip_fy": beamid.Step(2.0, start=start)}, **kw)

    an = run(0.0033, ("tip_fy_start",)).d["tip_w"]["tip_fy_start"]
    fd = (run(0.0033 + 1e-7).tip_w - run(0.0033 - 1e-7).tip_w) / 2e-7
    assert np.max(np.abs(an)) == pytest.approx(0.41192818, rel=1e-6)
    assert np.max(np.abs(an - fd)) < 1e-8
    assert np.all(an[t < 0.0033] == 0.0)
