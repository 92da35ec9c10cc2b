"""Monte Carlo consistency (issue 17): coverage of honest sigmas, the
Fortran summary against numpy, reproducibility on every runner, failures
counted, outputs written."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

import beamid
from beamid import InputError
from beamid.consistency import NOMINAL, replicate_generator

ROOT = Path(__file__).resolve().parents[1]
#: Table 4/5 loads (3 to 8 N along +y) and the Table 5 sigmas.
LOADS = (3.0, 3.0 + 5.0 / 3.0, 3.0 + 10.0 / 3.0, 8.0)
SIGMAS = np.array([0.0008, 0.0009, 0.0010, 0.0011])


@pytest.fixture(scope="module")
def table5_fit():
    from beamid.fit_decks import read_fit_deck

    deck = read_fit_deck(ROOT / "inputs" / "seed" / "table05_fit.nml")
    return beamid.fit(deck.model, deck.experiments, deck.data, free=deck.free)


@pytest.fixture(scope="module")
def well_posed_fit():
    """EI1, EI2 from tip y and elbow y at the four loads, sigma 2e-4: the
    estimates move by well under 1 % over the noise (close to linear)."""
    truth = beamid.pace(axial_coupling=0.0)
    exps = {f"F{f:.2f}": beamid.TipForce(fy=f) for f in LOADS}
    data = beamid.simulate_measurements(truth, exps, ["y_tip", "y_elbow"], sigma=2e-4,
                                        noise=True, seed=11)
    return beamid.fit(truth.replace(EI1=10.75, EI2=10.5), exps, data, free=("EI1", "EI2"))


def test_coverage_near_nominal_for_a_well_posed_fit(well_posed_fit):
    n = 120
    mc = beamid.consistency(well_posed_fit, replicates=n, seed=7, workers=1)
    assert mc.failed == 0 and mc.flagged == 0 and mc.used.all()
    for name in ("EI1", "EI2"):
        for k in (1, 2, 3):
            se = math.sqrt(NOMINAL[k] * (1 - NOMINAL[k]) / n)
            assert abs(mc.coverage[name][k] - NOMINAL[k]) < 3 * se + 1 / n, (name, k)
        # reported sigma against the spread of the estimates: equal within the
        # sampling error of a standard deviation over n draws (~ 1/sqrt(2n) = 6.5 %)
        assert 0.82 < mc.spread_ratio[name] < 1.2, name
        assert abs(mc.bias[name]) < 3 * mc.spread[name] / math.sqrt(n)
        assert abs(mc.z_mean[name]) < 0.3 and 0.8 < mc.z_std[name] < 1.2
        assert mc.estimates[name].shape == mc.sigmas[name].shape == (n,)
    # chi-square of the replicates against chi2(dof): mean dof, variance 2 dof
    assert mc.dof == 6
    assert abs(mc.chi2.mean() - mc.dof) < 3 * math.sqrt(2 * mc.dof / n)
    assert np.all((mc.chi2_p >= 0) & (mc.chi2_p <= 1))
    assert 0.0 <= np.mean(mc.chi2_p < 0.05) < 0.12


def test_summary_in_fortran_matches_numpy(table5_fit):
    mc = beamid.consistency(table5_fit, replicates=40, seed=3, workers=1)
    for name in mc.free:
        est, sig = mc.estimates[name], mc.sigmas[name]
        z = (est - mc.truth[name]) / sig
        np.testing.assert_allclose(mc.normalized[name], z, rtol=1e-14)
        for k in (1, 2, 3):
            assert mc.coverage[name][k] == np.mean(np.abs(z) <= k)
        np.testing.assert_allclose(mc.bias[name], est.mean() - mc.truth[name], rtol=1e-10)
        np.testing.assert_allclose(mc.spread[name], est.std(ddof=1), rtol=1e-10)
        np.testing.assert_allclose(mc.rms_sigma[name], np.sqrt(np.mean(sig ** 2)), rtol=1e-12)
        np.testing.assert_allclose(mc.spread_ratio[name],
                                   np.sqrt(np.mean(sig ** 2)) / est.std(ddof=1), rtol=1e-10)
        np.testing.assert_allclose(mc.z_std[name], z.std(ddof=1), rtol=1e-10)
    # chi-square p-values: for 2 dof the survival function is exp(-x/2)
    np.testing.assert_allclose(mc.chi2_p, np.exp(-mc.chi2 / 2.0), rtol=1e-10)


def test_replicate_k_is_the_documented_draw(table5_fit):
    mc = beamid.consistency(table5_fit, replicates=5, seed=42, workers=1)
    k = 3
    z = np.random.default_rng(np.random.SeedSequence(42).spawn(5)[k]).standard_normal(4)
    truth = np.array([r.model for r in table5_fit.residuals])
    data = table5_fit.data.with_values(truth + z * table5_fit.data.sigma)
    ref = beamid.fit(table5_fit.start, table5_fit.experiments, data, free=table5_fit.free)
    assert mc.estimates["EI2"][k] == ref.estimates["EI2"]
    assert mc.sigmas["EI1"][k] == ref.sigmas["EI1"]
    assert mc.chi2[k] == ref.chi2


def _same(a, b):
    for name in a.free:
        np.testing.assert_array_equal(a.estimates[name], b.estimates[name])
        np.testing.assert_array_equal(a.sigmas[name], b.sigmas[name])
    np.testing.assert_array_equal(a.chi2, b.chi2)
    np.testing.assert_array_equal(a.iterations, b.iterations)
    assert a.status == b.status and a.coverage == b.coverage


def test_same_seed_same_replicates_serial_processes_and_dask(table5_fit):
    n = 24
    serial = beamid.consistency(table5_fit, replicates=n, seed=7, workers=1)
    local = beamid.consistency(table5_fit, replicates=n, seed=7, workers=2)
    assert serial.runner == "serial" and local.runner == "2 local processes"
    _same(serial, local)
    # the default times a few replicates and keeps a run this cheap in-process
    default = beamid.consistency(table5_fit, replicates=n, seed=7)
    assert default.runner == "serial"
    _same(serial, default)
    other = beamid.consistency(table5_fit, replicates=n, seed=8, workers=1)
    assert not np.array_equal(other.estimates["EI2"], serial.estimates["EI2"])
    # a longer run starts with the same replicates
    longer = beamid.consistency(table5_fit, replicates=n + 6, seed=7, workers=1)
    np.testing.assert_array_equal(longer.estimates["EI2"][:n], serial.estimates["EI2"])

    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            on_dask = beamid.consistency(table5_fit, replicates=n, seed=7, client=client)
        # a scheduler address works as well (a client is made and closed)
        by_address = beamid.consistency(table5_fit, replicates=n, seed=7,
                                        client=cluster.scheduler_address)
    assert on_dask.runner == "Dask, 2 workers"
    _same(serial, on_dask)
    _same(serial, by_address)


def test_batched_replicates_are_the_one_at_a_time_fits(table5_fit, monkeypatch):
    """Without releases the core fits the replicates a chunk at a time
    (beamid_replicates): every number is the one beamid.fit gives for the
    replicate's data, with a prior redrawn too, and a replicate whose fit does
    not end cleanly is refitted through beamid.fit for its message."""
    import importlib

    mc_mod = importlib.import_module("beamid.consistency")
    fit = beamid.fit(table5_fit.start, table5_fit.experiments, table5_fit.data,
                     free=table5_fit.free, prior={"EI2": (11.0, 0.3)})
    monkeypatch.setattr(mc_mod, "BATCH", 5)   # chunks of 5: 3 calls, the last short
    # a modal test is batched too (its family is not timed)
    truth = beamid.pace()
    mexps = {"M": beamid.Modal(beamid.TipLoad(fy=-1.0), elements_per_beam=4)}
    mdata = beamid.simulate_measurements(truth, mexps, ["freq[1]", "freq[2]", "freq[3]"],
                                         sigma=1e-3, noise=True, seed=3)
    modal = beamid.fit(truth.replace(EI1=10.0, EI2=11.0), mexps, mdata, free=("EI1", "EI2"))
    for case, options in ((table5_fit, None), (fit, None), (modal, None),
                          (table5_fit, {"max_iter": 4})):
        spec = mc_mod._spec(case, 7, options)
        assert mc_mod._batch(spec) is not None
        batched = beamid.consistency(case, replicates=12, seed=7, workers=1, options=options)
        with monkeypatch.context() as m:
            m.setattr(mc_mod, "_batch", lambda spec: None)
            single = beamid.consistency(case, replicates=12, seed=7, workers=1,
                                        options=options)
        _same(batched, single)
        np.testing.assert_array_equal(batched.chi2_prior, single.chi2_prior)
        assert batched.messages == single.messages and batched.flags == single.flags
        # and each equals beamid.fit on the replicate's own data
        data, prior = mc_mod._replicate_inputs(spec, 3)
        if options is None:
            one = beamid.fit(case.start, case.experiments, data, free=case.free, prior=prior)
            assert [batched.estimates[n][3] for n in case.free] == \
                [one.estimates[n] for n in case.free]
            assert batched.chi2[3] == one.chi2 and batched.iterations[3] == one.iterations
    # with max_iter 4 some replicates do not converge: they keep fit's message
    assert "not converged" in batched.status and "ok" in batched.status
    assert all(m for m, st in zip(batched.messages, batched.status) if st != "ok")
    # a fitted vector the core's parameter check refuses (as a Model of it would):
    # the replicate goes through beamid.fit, which says so
    spec = mc_mod._spec(table5_fit, 7, None)
    calls = []

    def refuse_third(nbeams, params):
        calls.append(1)
        if len(calls) == 3:
            raise InputError("EI1 = -1, expected > 0")

    monkeypatch.setattr(mc_mod._core, "check_params", refuse_third)
    ran = []
    monkeypatch.setattr(mc_mod, "_run_one", lambda spec, k: ran.append(k) or {"k": k})
    records = mc_mod._batch(spec).records([0, 1, 2, 3])
    assert ran == [2] and [r["k"] for r in records] == [0, 1, 2, 3]
    assert records[2] == {"k": 2} and records[3]["status"] == "ok"


def test_replicates_entry_checks_its_arrays(table5_fit):
    from beamid import _core_estimation as ce
    from beamid.estimation import build_problem

    prob = build_problem(table5_fit.start, table5_fit.experiments, table5_fit.data)
    p0 = table5_fit.start.vector()
    free = np.array([table5_fit.start.index(n) + 1 for n in table5_fit.free], np.int32)
    ys = np.tile(np.asarray(table5_fit.data.value, float)[:, None], (1, 2))
    table = ce.prior_table([(2, 11.0, 0.3)])
    with pytest.raises(InputError, match=r"a priori means 3, expected nprior x nrep = 2"):
        ce._call(ce._api.api_fit_replicates, prob.nbeams, p0, free, table,
                 *prob.rows()[:10], prob.row_sigma, 0.0, *prob.histories(), 50, ys,
                 np.zeros(3))
    out = ce.fit_replicates(prob, p0, free, ce.prior_table([]), ys, np.zeros((0, 2)))
    # the data themselves, twice: the fit of the data, twice
    for j, name in enumerate(table5_fit.free):
        assert out["params"][free[j] - 1, 0] == out["params"][free[j] - 1, 1] == \
            table5_fit.estimates[name]
        assert out["sigmas"][j, 1] == table5_fit.sigmas[name]
    assert out["code"].tolist() == [0, 0] and out["stop"] == ["converged"] * 2


def test_failed_replicates_are_counted_not_dropped(table5_fit):
    # one Gauss-Newton iteration cannot converge from the Table 5 start
    mc = beamid.consistency(table5_fit, replicates=6, seed=1, workers=1,
                            options={"max_iter": 1})
    assert mc.failed == 6 and not mc.used.any()
    assert mc.status == ("not converged",) * 6
    assert mc.estimates["EI1"].shape == (6,)
    assert all(math.isnan(c) for c in mc.coverage["EI1"].values())
    text = mc.table()
    assert "6 failed" in text and "6 x not converged" in text


def test_prior_is_redrawn_with_the_data(table5_fit):
    fit = beamid.fit(table5_fit.start, table5_fit.experiments, table5_fit.data,
                     free=table5_fit.free, prior={"EI2": (11.0, 0.3)})
    mc = beamid.consistency(fit, replicates=80, seed=5, workers=1)
    assert mc.failed == 0
    # with the prior as a measurement of the truth, EI2 covers as it should
    assert abs(mc.coverage["EI2"][1] - NOMINAL[1]) < 3 * math.sqrt(0.683 * 0.317 / 80) + 0.02
    assert np.all(mc.chi2_prior > 0)


def test_outputs_csv_png_and_table(table5_fit, tmp_path):
    mc = beamid.consistency(table5_fit, replicates=12, seed=7, workers=1)
    csv = mc.to_csv(tmp_path / "mc.csv")
    lines = [ln for ln in csv.read_text().splitlines() if not ln.startswith("#")]
    assert lines[0].startswith("replicate,status,iterations,chi2,chi2_prior,dof,chi2_p,EI1,")
    assert len(lines) == 13
    first = lines[1].split(",")
    assert float(first[7]) == mc.estimates["EI1"][0]
    png = tmp_path / "mc.png"
    mc.plot(png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(tmp_path.glob("*.tmp*"))
    text = mc.table()
    assert "EI2" in text and "nominal" in text and "chi2(2)" in text


def test_bad_arguments(table5_fit, monkeypatch):
    with pytest.raises(InputError, match="replicates"):
        beamid.consistency(table5_fit, replicates=1)
    with pytest.raises(InputError, match="seed"):
        beamid.consistency(table5_fit, seed=-1)
    with pytest.raises(InputError, match="workers"):
        beamid.consistency(table5_fit, replicates=4, workers=0)
    with pytest.raises(InputError, match="FitResult"):
        beamid.consistency("fit")
    with pytest.raises(InputError, match="Client"):
        beamid.consistency(table5_fit, replicates=4, client=3.0)
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(ImportError, match=r"pip install beamid\[dask\]"):
        beamid.consistency(table5_fit, replicates=4, client="tcp://127.0.0.1:8786")


def test_cli_consistency_writes_table_csv_and_png(tmp_path, capsys, monkeypatch):
    from beamid.cli import main

    deck = ROOT / "inputs" / "seed" / "table05_fit.nml"
    code = main(["consistency", str(deck), "--replicates", "30", "--seed", "7",
                 "--workers", "1", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0
    assert "30 replicates (seed 7, serial); 30 converged" in out
    csv = tmp_path / "table05_fit_consistency.csv"
    assert len([ln for ln in csv.read_text().splitlines() if not ln.startswith("#")]) == 31
    assert (tmp_path / "table05_fit_consistency.png").is_file()
    # the command is the API: same numbers as beamid.consistency on the deck's fit
    from beamid.fit_decks import read_fit_deck

    d = read_fit_deck(deck)
    fit = beamid.fit(d.model, d.experiments, d.data, free=d.free)
    api = beamid.consistency(fit, replicates=30, seed=7, workers=1)
    assert f"{api.spread_ratio['EI2']:.3f}" in out
    # Dask missing: exit 2 with the install hint
    monkeypatch.setitem(sys.modules, "distributed", None)
    code = main(["consistency", str(deck), "--replicates", "4", "--scheduler",
                 "tcp://127.0.0.1:1", "--out", str(tmp_path / "x")])
    assert code == 2 and "pip install beamid[dask]" in capsys.readouterr().err
    assert not (tmp_path / "x").exists() or not list((tmp_path / "x").iterdir())


def test_module_doctests():
    import doctest
    import importlib

    # (beamid.consistency and beamid.design are the functions; the modules by name)
    for name in ("beamid.consistency", "beamid.design"):
        module = importlib.import_module(name)
        assert doctest.testmod(module, optionflags=doctest.ELLIPSIS).failed == 0


def test_cli_unwritable_output_exits_4(tmp_path, capsys):
    from beamid.cli import main

    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    deck = ROOT / "inputs" / "seed" / "table05_fit.nml"
    code = main(["consistency", str(deck), "--replicates", "4", "--workers", "1",
                 "--out", str(blocker / "sub")])
    assert code == 4 and "cannot write" in capsys.readouterr().err


def test_table5_ei2_errors_are_skewed_not_mis_sized(table5_fit):
    # EI2 enters y_tip through 1/EI2: the sigma is right in size, the misses
    # one-sided (docs/consistency.md); EI1 is symmetric
    mc = beamid.consistency(table5_fit, replicates=400, seed=7, workers=1)
    assert abs(mc.spread_ratio["EI2"] - 1.0) < 0.1
    below, above = mc.tails("EI2")
    assert below > 2 * above
    b1, a1 = mc.tails("EI1")
    assert abs(b1 - a1) < 0.02
    compliance = 1.0 / mc.estimates["EI2"]
    skew = lambda x: np.mean((x - x.mean()) ** 3) / x.std() ** 3   # noqa: E731
    assert skew(mc.estimates["EI2"]) > 0.25 and abs(skew(compliance)) < 0.12


def test_cli_consistency_on_a_dynamic_deck(tmp_path, capsys):
    """`beamid consistency DECK` on a release deck (Table 19: the friction
    from the tip w and u after the release, with a priori information): the
    replicates refit the dynamic fit; the a priori means are redrawn too."""
    from beamid.cli import main

    deck = ROOT / "inputs" / "seed" / "table19_fit.nml"
    code = main(["consistency", str(deck), "--replicates", "3", "--seed", "7",
                 "--workers", "1", "--out", str(tmp_path), "--no-plots"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "3 replicates (seed 7, serial); 3 converged" in out
    lines = [ln for ln in (tmp_path / "table19_fit_consistency.csv").read_text().splitlines()
             if not ln.startswith("#")]
    assert lines[0].startswith("replicate,status,iterations,chi2,chi2_prior,dof,chi2_p,mu_elbow")
    rows = [ln.split(",") for ln in lines[1:]]
    assert len(rows) == 3 and all(r[1] in ("ok", "flagged") for r in rows)   # converged
    assert all(float(r[4]) > 0.0 for r in rows)             # the a priori rows count
    assert len({r[7] for r in rows}) == 3                   # three different estimates
