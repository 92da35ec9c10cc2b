"""Experiment advisor (issue 17): predicted sigmas against refits with
simulated data, the information algebra against numpy, Measurements.merge,
ranking access."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import beamid
from beamid import InputError
from beamid import _core_estimation as dc
from beamid.design import information

ROOT = Path(__file__).resolve().parents[1]
SIGMA = {"y_tip": 1e-3, "x_tip": 1e-3, "tip_angle": 2e-3, "y_elbow": 1e-3,
         "x_elbow": 1e-3, "wire_force": 0.1}
CANDIDATES = {"F2": beamid.TipForce(fy=2.0), "F12": beamid.TipForce(fy=12.0),
              "M1": beamid.TipMoment(1.0), "M3": beamid.TipMoment(3.0),
              "Lw1.4": beamid.RadialWire(1.4)}


@pytest.fixture(scope="module")
def table5_fit():
    from beamid.fit_decks import read_fit_deck

    deck = read_fit_deck(ROOT / "inputs" / "seed" / "table05_fit.nml")
    return beamid.fit(deck.model, deck.experiments, deck.data, free=deck.free)


@pytest.fixture(scope="module")
def advice(table5_fit):
    return beamid.design(table5_fit, CANDIDATES, list(SIGMA), sigma=SIGMA, target="EI2")


def test_information_is_the_inverse_covariance(table5_fit, advice):
    info = information(table5_fit)
    np.testing.assert_allclose(info, np.linalg.inv(table5_fit.cov), rtol=1e-8)
    cov, sig, dcrit, rank = dc.information_covariance(info)
    assert rank == 2
    np.testing.assert_allclose(cov, table5_fit.cov, rtol=1e-8)
    np.testing.assert_allclose(dcrit, np.linalg.det(table5_fit.cov) ** 0.25, rtol=1e-8)
    assert advice.current == pytest.approx(table5_fit.sigmas["EI2"], rel=1e-8)


def test_rank_candidates_against_numpy():
    rng = np.random.default_rng(0)
    a = rng.standard_normal((6, 3))
    info = a.T @ a
    rows = rng.standard_normal((3, 5))
    sig = np.array([0.5, 1.0, 2.0, 0.1, 1.0])
    for target in (0, 1, 3):
        base, crit, order = dc.rank_candidates(info, rows, sig, target)
        want = []
        for c in range(5):
            cov = np.linalg.inv(info + np.outer(rows[:, c], rows[:, c]) / sig[c] ** 2)
            want.append(np.linalg.det(cov) ** (1 / 6) if target == 0
                        else math.sqrt(cov[target - 1, target - 1]))
        np.testing.assert_allclose(crit, want, rtol=1e-10)
        assert list(order) == list(np.argsort(want, kind="stable"))
        cov0 = np.linalg.inv(info)
        np.testing.assert_allclose(base, np.linalg.det(cov0) ** (1 / 6) if target == 0
                                   else math.sqrt(cov0[target - 1, target - 1]), rtol=1e-10)
    with pytest.raises(InputError, match="sigma"):
        dc.rank_candidates(info, rows, -sig, 1)
    with pytest.raises(InputError, match="symmetric"):
        dc.information_covariance(np.array([[1.0, 2.0], [0.0, 1.0]]))


def test_candidate_rows_are_the_static_sensitivities(table5_fit, advice):
    # the advisor's row is d(quantity)/d(free) of solve_static(..., wrt=free)
    r = beamid.solve_static(table5_fit.model, CANDIDATES["M3"], wrt=table5_fit.free)
    np.testing.assert_allclose(advice.sensitivity[("M3", "tip_angle")],
                               [r.d["tip_angle"][n] for n in table5_fit.free], rtol=1e-10)
    r = beamid.solve_static(table5_fit.model, CANDIDATES["Lw1.4"], wrt=table5_fit.free)
    np.testing.assert_allclose(advice.sensitivity[("Lw1.4", "wire_force")],
                               [r.d["wire_force"][n] for n in table5_fit.free], rtol=1e-10)


def _refit_with(fit, key, sigma, noise_seed=None):
    e, q = key
    extra = beamid.simulate_measurements(fit.model, {e: CANDIDATES[e]}, [q], sigma=sigma,
                                         noise=noise_seed is not None, seed=noise_seed)
    merged = fit.data.merge(extra)
    exps = {**fit.experiments, e: CANDIDATES[e]}
    return beamid.fit(fit.start, exps, merged, free=fit.free)


def test_predicted_sigma_equals_the_refit_sigma(table5_fit, advice):
    keys = [advice.ranking[0].key, advice.ranking[1].key, advice.ranking[len(advice.ranking) // 2].key,
            advice.ranking[-1].key]
    refit = []
    for key in keys:
        # data exactly at the model: the estimates stay, so the refit's sigma
        # (Eq. 55 at its estimates) is the prediction to solver accuracy
        res = _refit_with(table5_fit, key, SIGMA[key[1]])
        assert res.converged
        np.testing.assert_allclose(res.sigmas["EI2"], advice.ranking[key].predicted, rtol=1e-5)
        refit.append(res.sigmas["EI2"])
        # with noise the refit moves, and so does its sigma: still close
        noisy = _refit_with(table5_fit, key, SIGMA[key[1]], noise_seed=4)
        assert noisy.sigmas["EI2"] == pytest.approx(advice.ranking[key].predicted, rel=0.25)
    assert refit == sorted(refit)        # the ranking is the refits' order
    assert refit[0] < 0.2 * table5_fit.sigmas["EI2"]


def test_d_criterion_against_a_refit(table5_fit):
    adv = beamid.design(table5_fit, CANDIDATES, ["y_elbow", "tip_angle"], sigma=SIGMA,
                        target=None)
    assert adv.target is None and "D-criterion" in adv.table()
    key = adv.ranking[0].key
    res = _refit_with(table5_fit, key, SIGMA[key[1]])
    np.testing.assert_allclose(np.linalg.det(res.cov) ** 0.25, adv.ranking[0].predicted,
                               rtol=1e-5)


def test_undetermined_target_becomes_determined():
    truth = beamid.pace(axial_coupling=0.0)
    exps = {"F8": beamid.TipForce(fy=8.0)}
    data = beamid.simulate_measurements(truth, exps, ["y_tip"], sigma=1e-3)
    fit = beamid.fit(truth, exps, data, free=("EI1", "EI2"))
    assert math.isinf(fit.sigmas["EI2"])
    adv = beamid.design(fit, {"M2": beamid.TipMoment(2.0), "F8": exps["F8"]},
                        ["tip_angle"], sigma=1e-3, target="EI2")
    assert math.isinf(adv.current)
    assert all(math.isfinite(v) for _, v in adv.ranking)
    key = adv.ranking[0].key
    extra = beamid.simulate_measurements(truth, {key[0]: adv.loads[key[0]]}, [key[1]],
                                         sigma=1e-3)
    res = beamid.fit(truth, {**exps, **adv.loads}, data.merge(extra), free=fit.free)
    np.testing.assert_allclose(res.sigmas["EI2"], adv.ranking[0].predicted, rtol=1e-5)


def test_ranking_is_indexable_by_rank_and_key(advice):
    best = advice.ranking[0]
    assert best == advice.ranking[best.key] == advice.ranking[best.key[0], best.key[1]]
    key, value = best                    # an entry unpacks as (key, predicted)
    assert advice.ranking.rank(key) == 0 and value == best.predicted
    values = [v for _, v in advice.ranking]
    assert values == sorted(values)
    assert advice.ranking[-1].predicted >= advice.ranking[1].predicted
    with pytest.raises(KeyError, match="no candidate"):
        advice.ranking["F2", "no_such"]
    # wire force only where there is a wire: skipped, named, not ranked
    assert ("F2", "wire_force", ) not in advice.ranking.keys()
    assert any(e == "F2" and q == "wire_force" for e, q, _ in advice.skipped)
    assert ("Lw1.4", "wire_force") in advice.ranking.keys()
    assert advice.gain(key) > 1.0


def test_merge_and_its_duplicate_error(table5_fit):
    data = table5_fit.data
    extra = beamid.simulate_measurements(table5_fit.model, {"M1": CANDIDATES["M1"]},
                                         ["tip_angle", "y_tip"], sigma=1e-3)
    merged = data.merge(extra)
    assert len(merged) == len(data) + 2
    assert merged.experiment[-2:] == ("M1", "M1") and merged.quantity[-1] == "y_tip"
    np.testing.assert_array_equal(merged.value[:len(data)], data.value)
    dup = beamid.simulate_measurements(table5_fit.model,
                                       {"F8.00": table5_fit.experiments["F8.00"]}, ["y_tip"])
    with pytest.raises(InputError, match=r"duplicate row: experiment 'F8.00'.*quantity "
                                         r"'y_tip' is in both .*table05_data.csv, line"):
        data.merge(dup)
    with pytest.raises(InputError, match="Measurements"):
        data.merge([("F3", 0, "y_tip", 0.1, 1e-3)])


def test_bad_arguments(table5_fit):
    with pytest.raises(InputError, match="target"):
        beamid.design(table5_fit, CANDIDATES, ["y_tip"], target="EI9")
    with pytest.raises(InputError, match="sigma has no entry"):
        beamid.design(table5_fit, CANDIDATES, ["y_tip"], sigma={"x_tip": 1e-3})
    with pytest.raises(InputError, match="differs from the fit's experiment"):
        beamid.design(table5_fit, {"F3.00": beamid.TipForce(fy=5.0)}, ["y_elbow"])
    with pytest.raises(InputError, match="quantity"):
        beamid.design(table5_fit, CANDIDATES, ["z_tip"])
    with pytest.raises(InputError, match="candidates"):
        beamid.design(table5_fit, {}, ["y_tip"])


def test_plot_writes_a_png(advice, tmp_path):
    path = tmp_path / "advice.png"
    advice.plot(path, top=8)
    assert path.read_bytes()[:4] == b"\x89PNG"


def test_cli_design_prints_ranks_and_draws(tmp_path, capsys):
    from beamid.cli import main

    deck = str(ROOT / "inputs" / "seed" / "table05_fit.nml")
    code = main(["design", deck, "--moment", "3", "--wire", "1.4", "--quantities",
                 "tip_angle", "wire_force", "--sigma", "tip_angle=2e-3", "wire_force=0.1",
                 "--target", "EI2", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0
    assert "predicted sigma of EI2: now 0.75" in out
    rows = (tmp_path / "table05_fit_design.csv").read_text().splitlines()
    assert rows[1] == "rank,experiment,quantity,sigma,predicted"
    assert rows[2].startswith("1,") and len(rows) == 2 + 3   # M3/tip_angle, Lw1.4 x 2
    assert (tmp_path / "table05_fit_design.png").read_bytes()[:4] == b"\x89PNG"
    # a quantity the deck never measured gets the default sigma, said in a line
    code = main(["design", deck, "--moment", "3", "--quantities", "tip_angle",
                 "--out", str(tmp_path)])
    assert code == 0
    assert ("sigma of tip_angle: 0.001 rad (default: the deck has no tip_angle rows; set it "
            "with --sigma tip_angle=VALUE)") in capsys.readouterr().out


def test_predicted_covariance_of_two_added_rows(table5_fit, advice):
    from beamid.design import predicted_covariance

    rows = [(advice.sensitivity[k], advice.sigma[k]) for k in
            (("M3", "tip_angle"), ("Lw1.4", "wire_force"))]
    cov, sig = predicted_covariance(table5_fit, rows)
    info = information(table5_fit) + sum(np.outer(g, g) / s ** 2 for g, s in rows)
    np.testing.assert_allclose(cov, np.linalg.inv(info), rtol=1e-9)
    extra = beamid.simulate_measurements(table5_fit.model, {"M3": CANDIDATES["M3"]},
                                         ["tip_angle"], sigma=SIGMA["tip_angle"])
    extra = extra.merge(beamid.simulate_measurements(
        table5_fit.model, {"Lw1.4": CANDIDATES["Lw1.4"]}, ["wire_force"],
        sigma=SIGMA["wire_force"]))
    res = beamid.fit(table5_fit.start, {**table5_fit.experiments, "M3": CANDIDATES["M3"],
                                        "Lw1.4": CANDIDATES["Lw1.4"]},
                     table5_fit.data.merge(extra), free=table5_fit.free)
    np.testing.assert_allclose([res.sigmas[n] for n in res.free], sig, rtol=1e-5)


def test_information_covariance_rank_deficient():
    # a parameter with a component in an unseen direction gets sigma = inf,
    # the others keep theirs (as the fit's SVD covariance does)
    cov, sig, dcrit, rank = dc.information_covariance(np.diag([4.0, 0.0]))
    assert rank == 1 and sig[0] == 0.5 and math.isinf(sig[1]) and math.isinf(dcrit)
    a = np.array([[1.0, 1.0, 0.0], [2.0, 2.0, 0.0], [0.0, 0.0, 3.0]])
    _, sig, _, rank = dc.information_covariance(a.T @ a)
    assert rank == 2 and math.isinf(sig[0]) and math.isinf(sig[1])
    assert sig[2] == pytest.approx(1.0 / math.sqrt(9.0 + 0.0), rel=1e-12)


# ------------------------------------------------- release candidates (issue 17)

def test_release_times_ranked_and_checked_by_refits():
    """Which measurement times determine the densities after Table 15's
    design (w, u at nine times over 1/4 cycle)? The advisor ranks single
    rows of the same release at later times by the predicted sigma of rho1;
    refits on the merged data (data.merge(simulated rows)) confirm the
    predicted sigmas of the four best and the four worst rows and their
    order. Data from the tighter integrator (rtol 1e-11) than the fits use,
    without noise, so the refits sit where the prediction was linearized and
    the check is of the first-order algebra and the release sensitivities."""
    from beamid.design import predicted_covariance, time_label

    truth = beamid.pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)
    rel = beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=4)
    fine = {"free": beamid.Release(beamid.TipForce(fy=8.0), elements_per_beam=4, rtol=1e-11)}
    sig = {"w_tip": 0.0015, "u_tip": 0.0006}
    t15 = [0.65 * k / 9 for k in range(1, 10)]
    free = ("mu_elbow", "mu_tip", "rho1", "rho2")
    data = beamid.simulate_measurements(truth, fine, ["w_tip", "u_tip"], sigma=sig, t=t15)
    base = beamid.fit(truth, {"free": rel}, data, free=free)
    times = [0.8, 1.0, 1.2, 1.4, 1.6, 1.8, 2.0, 2.2, 2.4]
    adv = beamid.design(base, {"free": rel}, ["w_tip", "u_tip"], sigma=sig, target="rho1",
                        times=times)
    assert len(adv.ranking) == 18 and adv.ranking[0].key[1] == time_label(
        adv.ranking[0].key[1].split("@")[0], float(adv.ranking[0].key[1].split("@")[1]))
    assert adv.current == pytest.approx(base.sigmas["rho1"], rel=1e-6)
    refit = {}
    for name, keys in (("best", adv.ranking.keys()[:4]), ("worst", adv.ranking.keys()[-4:])):
        _, predicted = predicted_covariance(base, [(adv.sensitivity[k], adv.sigma[k])
                                                   for k in keys])
        rows = [("free", float(lab.split("@")[1]), lab.split("@")[0], 0.0, adv.sigma[(e, lab)])
                for e, lab in keys]
        new = beamid.Measurements.from_rows(rows, source="<candidates>")
        new = new.with_values(beamid.estimation.predict(truth, fine, new)[0])
        fit = beamid.fit(truth, {"free": rel}, data.merge(new), free=free)
        refit[name] = fit.sigmas["rho1"]
        for j, p in enumerate(free):
            assert fit.sigmas[p] == pytest.approx(predicted[j], rel=0.02), (name, p)
    assert refit["best"] < 0.8 * refit["worst"] < 0.8 * base.sigmas["rho1"]
    with pytest.raises(InputError, match="give its measurement times"):
        beamid.design(base, {"free": rel}, ["w_tip"], sigma=sig, target="rho1")
    with pytest.raises(InputError, match="expected finite times > 0"):
        beamid.design(base, {"free": (rel, [0.0, 1.0])}, ["w_tip"], sigma=sig, target="rho1")


def test_cli_design_on_a_release_deck(tmp_path, capsys):
    """`beamid design DECK --times ...` on a release deck (Table 19): the
    deck's release at the given times, measuring the deck's own quantities
    (w and u) with their sigmas; without --times it says what to give."""
    from beamid.cli import main

    deck = str(ROOT / "inputs" / "seed" / "table19_fit.nml")
    code = main(["design", deck, "--times", "0.8", "1.6", "2.4", "--target", "mu_elbow",
                 "--out", str(tmp_path), "--no-plots"])
    out = capsys.readouterr().out
    assert code == 0, out
    rows = (tmp_path / "table19_fit_design.csv").read_text().splitlines()
    assert rows[1] == "rank,experiment,quantity,sigma,predicted" and len(rows) == 2 + 6
    labels = {r.split(",")[2] for r in rows[2:]}
    assert labels == {f"{q}@{t}" for q in ("w_tip", "u_tip") for t in ("0.8", "1.6", "2.4")}
    assert "predicted sigma of mu_elbow" in out
    # without --times: the deck's own measurement times, said in a line
    assert main(["design", deck, "--out", str(tmp_path / "x"), "--no-plots"]) == 0
    assert ("measurement times: 0.1 0.2 0.3 0.4 0.5 0.6 s (the deck's own; set them with "
            "--times)") in capsys.readouterr().out


# ------------------------------------------- defaults on the bundled decks (issue 31)

#: a representative subset of the bundled estimation decks (the whole set, 14
#: decks, takes about 15 s): static with and without a quantity's rows, a
#: dynamic release deck, a three-stage identify deck
BUNDLED = [("seed", "table03_fit.nml"), ("seed", "table05_fit.nml"),
           ("seed", "table19_fit.nml"), ("seed", "identify_three_stages.nml"),
           ("demo", "hidden_effect.nml")]


@pytest.mark.parametrize("folder, name", BUNDLED)
def test_cli_design_runs_on_a_bundled_deck_without_options(folder, name, tmp_path, capsys):
    from beamid.cli import main
    from beamid.tables import inputs_dir

    deck = inputs_dir(folder) / name
    assert main(["design", str(deck), "--out", str(tmp_path), "--no-plots"]) == 0
    out = capsys.readouterr().out
    rows = (tmp_path / f"{deck.stem}_design.csv").read_text().splitlines()
    assert rows[1] == "rank,experiment,quantity,sigma,predicted" and len(rows) > 3
    assert all(float(r.split(",")[3]) > 0 for r in rows[2:])
    if name in ("table05_fit.nml", "hidden_effect.nml"):    # no x_elbow rows: the default
        assert "sigma of x_elbow: 0.001 m (default" in out
    if name in ("table19_fit.nml", "identify_three_stages.nml"):
        assert "(the deck's own; set them with --times)" in out


def test_cli_design_argument_errors_come_first_in_the_command_lines_words(
        monkeypatch, capsys):
    import sys

    from beamid.cli import main

    mc = sys.modules["beamid.consistency"]     # (beamid.consistency is the function)
    from beamid.tables import inputs_dir

    def no_fit(*args, **kwargs):
        raise AssertionError("the deck's fit ran before the arguments were checked")

    monkeypatch.setattr(mc, "_fit", no_fit)
    deck = str(inputs_dir("seed") / "table05_fit.nml")
    for argv, words in (
            (["--target", "foo"], "--target foo: not a free parameter of"),
            (["--sigma", "x_tip=abc"], "--sigma x_tip=abc: 'abc' is not a sigma"),
            (["--sigma", "bogus=1"], "--sigma bogus=1: unknown quantity 'bogus'"),
            (["--quantities", "tip_x"], "--quantities tip_x: unknown quantity")):
        assert main(["design", deck, *argv, "--no-plots"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("beamid: error: ") and words in err, err
        assert "None" not in err and len(err.splitlines()) == 1


def test_cli_design_ranks_station_observations(tmp_path, capsys):
    """A strain gauge or a curvature at a station is a candidate like a tip
    position; its default sigma is the observation table's (1e-6 for a gauge),
    printed; a gauge at 0.05 m on beam 1 of Table 5's arm predicts EI2 much
    better than a tip position (the root's curvature carries the whole moment)."""
    from beamid.cli import main
    from beamid.tables import inputs_dir

    deck = str(inputs_dir("seed") / "table05_fit.nml")
    assert main(["design", deck, "--quantities", "x_tip", "strain@1:0.05", "--target", "EI2",
                 "--out", str(tmp_path), "--no-plots"]) == 0
    out = capsys.readouterr().out
    assert "sigma of strain@1:0.05: 1e-06 (default: the deck has no strain@1:0.05 rows" in out
    rows = [r.split(",") for r in
            (tmp_path / "table05_fit_design.csv").read_text().splitlines()[2:]]
    assert [r[2] for r in rows[:4]] == ["strain@1:0.05"] * 4
    assert float(rows[0][4]) < 0.2 * float(rows[-1][4])
    # the table's columns widen for the long name
    assert "1     F8.00         strain@1:0.05       1e-06" in out
    assert main(["design", deck, "--quantities", "strain@1", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert "--quantities strain@1: unknown quantity 'strain@1' (station \"1\"" in err


def test_design_of_a_forced_release_with_an_accelerometer(tmp_path, capsys):
    """hammer_fit.nml measures accel_n@2:0.714: its design ranks the
    accelerometer's times beside the tip's (the deck's own quantities)."""
    from beamid.cli import main
    from beamid.tables import inputs_dir

    deck = str(inputs_dir("demo") / "hammer_fit.nml")
    assert main(["design", deck, "--out", str(tmp_path), "--no-plots"]) == 0
    rows = [r.split(",") for r in
            (tmp_path / "hammer_fit_design.csv").read_text().splitlines()[2:]]
    labels = {r[2].rsplit("@", 1)[0] for r in rows}
    assert labels == {"w_tip", "accel_n@2:0.714"}
    assert all(float(r[4]) > 0 for r in rows)
