"""Side-by-side timing of two builds of beamid in ONE process (a refactor's
"within 5 % of today" rule on a shared, noisy machine).

    PYTHONPATH=DIR python benchmarks/ab_bench.py [--rounds 5] [--only REGEX]
        [--old-inputs OLD_CHECKOUT/inputs] [--old-tangent EXE] [--markdown]

DIR holds a copy of the other build's package under the name ``beamid_old``
(pyfront/beamid of that commit plus its _ext*.so; the package imports itself
relatively, so the copy loads under that name as it is). The figures of
``make bench`` as it stood at that commit are timed alternately old, new,
new, old, ... (the order swaps every round) ``--rounds`` times:

* bench_static: one arc-length solve with d/dEI1, d/dEI2 (mean of a batch);
* bench_fe: the FE static 8 N solve at 4, 16, 64, 256 elements per beam, and
  the tangent assembly's ns per element (the Fortran program
  bench_fe_tangent of each build, ``--old-tangent``; the figure it prints);
* bench_dynamics: (a) and (b) with RK4 and the implicit default, (c) with and
  without rotary inertia, (d) 4..256 elements per beam over 0.2 s, Table 2's
  smooth-law runs, and SciPy's Radau on ``dynamic_system`` (first tenth);
* bench_sensitivity: the plain and the four-sensitivity runs over a quarter
  and half cycle (implicit) and a quarter (RK4);
* bench_dynfit: the Table 16 fit with the default, the exact and the
  central-difference Jacobian;
* bench_dyn_improve: improve on the measured release (slow: about a minute);
* bench_consistency: the serial Monte Carlo runs (Table 5, 1000 replicates;
  Table 3, 400) - the figures with worker processes time process start-up
  on a shared machine and are left out.

Each side reads the decks of its own checkout (``--old-inputs``; the new
side reads this checkout's inputs/). The best of each side and the ratio
new/old are printed, for the wall clock and for the process's CPU time
(steadier when other jobs share the cores; the median of the rounds' CPU
ratios beside it), with the largest difference of the results (the same
numbers are expected: 0).
"""
from __future__ import annotations

import argparse
import importlib
import re
import statistics
import subprocess
import time
from functools import cache
from pathlib import Path
from typing import Any, Callable

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _central_differences(bm):
    """A Release whose Jacobian columns are central differences (bench_dynfit's
    baseline), written for either build: the spec key ``fd`` (today) or the
    twelfth positional value EV_FD (before issue 25)."""
    if hasattr(bm.Release, "spec"):
        class CD(bm.Release):
            def spec(self):
                kind, spec = super().spec()
                return kind, {**spec, "fd": 1.0}
    else:
        class CD(bm.Release):
            def encode(self):
                kind, values = super().encode()
                values = values.copy()
                values[11] = 1.0
                return kind, values
    return CD


def cases(bm, inputs: Path) -> dict[str, tuple[int, Callable[[], Callable[[], Any]]]]:
    """name -> (calls per timing, a builder of the timed call); the timed call
    returns numbers to compare between the builds. Builders do their set-up
    (decks, reference fits, data) untimed."""
    from importlib import import_module
    dyn = import_module(bm.__name__ + ".dynamics")
    decks = import_module(bm.__name__ + ".fit_decks")
    rel = bm.TipForce(fy=8.0)
    seed = bm.pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)
    t27 = np.linspace(0.0, 2.6, 27)
    wrt = ("mu_elbow", "mu_tip", "rho1", "rho2")
    out: dict[str, tuple[int, Callable[[], Callable[[], Any]]]] = {}

    def add(name, number, fn=None, builder=None):
        out[name] = (number, builder if builder is not None else (lambda: fn))

    def tip(run):
        return np.concatenate([run.tip_u, run.tip_w])

    # bench_static
    pace = bm.pace()
    add("static arc-length d/dEI", 200,
        lambda: bm.solve_static(pace, rel, wrt=("EI1", "EI2")).tip_y)
    # bench_fe
    for n, number in ((4, 20), (16, 10), (64, 3), (256, 1)):
        add(f"fe_static {n} el/beam", number,
            lambda n=n: bm.fe_static(pace, rel, elements_per_beam=n).tip["w"])
    # bench_dynamics, Table 1
    add("dyn (a) rk4", 1, lambda: tip(bm.simulate(seed, rel, t27, integrator="rk4")))
    add("dyn (a) implicit", 1, lambda: tip(bm.simulate(seed, rel, t27)))
    add("dyn (b) rk4 motor", 1,
        lambda: tip(bm.simulate(seed, rel, t27, integrator="rk4", motor_gain=0.2)))
    add("dyn (b) implicit motor", 1, lambda: tip(bm.simulate(seed, rel, t27, motor_gain=0.2)))
    norot = bm.pace(J_elbow=0.0, J_tip=0.0)
    add("dyn (c) pace() rotary", 1, lambda: tip(bm.simulate(pace, rel, t27)))
    add("dyn (c) pace(J=0)", 1, lambda: tip(bm.simulate(norot, rel, t27)))
    for n in (4, 16, 64, 256):
        add(f"dyn (d) {n} el/beam 0.2 s", 1,
            lambda n=n: tip(bm.simulate(seed, rel, [0.0, 0.2], elements_per_beam=n)))
    # bench_dynamics, Table 2 (smooth law) and SciPy's Radau on dynamic_system
    smooth = dict(friction="smooth", friction_velocity=1e-2)
    add("dyn T2 rk4 smooth", 1,
        lambda: tip(bm.simulate(seed, rel, t27, integrator="rk4", **smooth)))
    add("dyn T2 implicit smooth 1e-6", 1,
        lambda: tip(bm.simulate(seed, rel, t27, rtol=1e-6, **smooth)))

    def radau():
        from scipy.integrate import solve_ivp
        nepb = 4
        first = bm.simulate(seed, rel, t27[:2], **smooth)
        y0 = first.states[:, 0]
        n = first.nfree
        minv = np.linalg.inv(dyn.dynamic_system(seed, y0[:n], y0[n:], nepb)["M"])

        def rhs(_t, y):
            o = dyn.dynamic_system(seed, y[:n], y[n:], nepb, **smooth)
            return np.concatenate([y[n:], minv @ o["force"]])

        def jac(_t, y):
            o = dyn.dynamic_system(seed, y[:n], y[n:], nepb, **smooth)
            top = np.hstack([np.zeros((n, n)), np.eye(n)])
            return np.vstack([top, np.hstack([-minv @ o["K"], -minv @ o["C"]])])

        t_c = t27[t27 <= 0.26 + 1e-12]
        atol = np.concatenate([np.full(n, 1e-6), np.full(n, 1e-3)])
        return lambda: solve_ivp(rhs, (0.0, 0.26), y0, method="Radau", t_eval=t_c, jac=jac,
                                 rtol=1e-6, atol=atol).y[n - 4]

    add("dyn scipy Radau smooth", 1, builder=radau)
    # bench_sensitivity
    for label, span, integrators in (("quarter", 0.65, ("implicit", "rk4")),
                                     ("half", 1.3, ("implicit",))):
        t36 = np.linspace(span / 36, span, 36)
        for integ in integrators:
            kw = dict(t_out=t36, elements_per_beam=4, integrator=integ)
            add(f"sens {label} {integ} plain", 1,
                lambda kw=kw: tip(bm.simulate(seed, rel, **kw)))
            add(f"sens {label} {integ} 4 wrt", 1,
                lambda kw=kw: np.array([bm.simulate(seed, rel, wrt=wrt, **kw).d["tip_w"][p]
                                        for p in wrt]).ravel())

    # bench_dynfit
    @cache
    def table16():
        deck = decks.read_fit_deck(inputs / "seed" / "table16_fit.nml")
        return deck, dict(deck.experiments)

    def fit16(jacobian=None, fd=False):
        def make():
            deck, exps = table16()
            if fd:
                cd = _central_differences(bm)
                exps = {n: cd(x.load) for n, x in exps.items()}
            kw = {} if jacobian is None else {"jacobian": jacobian}
            return lambda: np.array([bm.fit(deck.model, exps, deck.data, free=wrt,
                                            **kw).estimates[p] for p in wrt])
        return make

    add("dynfit default", 1, builder=fit16())
    add("dynfit exact", 1, builder=fit16("exact"))
    add("dynfit central diff", 1, builder=fit16(fd=True))

    # bench_consistency (serial)
    def mc(table, replicates):
        def make():
            deck = decks.read_fit_deck(inputs / "seed" / f"{table}_fit.nml")
            f = bm.fit(deck.model, deck.experiments, deck.data, free=deck.free)
            return lambda: np.concatenate([
                np.asarray(v, float).ravel() for v in bm.consistency(
                    f, replicates=replicates, seed=7, workers=1,
                    progress_bar=False).estimates.values()])
        return make

    add("consistency T5 1000 serial", 1, builder=mc("table05", 1000))
    add("consistency T3 400 serial", 1, builder=mc("table03", 400))

    # bench_dyn_improve
    def improve():
        base = bm.pace().replace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.0, mu_tip=0.0)
        truth = base.replace(c_tip=0.01, J_tip=0.01)
        times = [round(0.05 * k, 3) for k in range(1, 27)]
        fine = bm.Release(bm.TipForce(fy=8.0), elements_per_beam=8, rtol=1e-11)
        exact = bm.simulate_measurements(truth, {"free": fine}, ["u_tip", "w_tip"],
                                         sigma=1e-4, t=times)
        rng = np.random.default_rng(6)
        data = exact.with_values(np.asarray(exact.value)
                                 + 1e-4 * rng.standard_normal(len(exact)))
        exps = {"free": bm.Release(bm.TipForce(fy=8.0), elements_per_beam=8)}
        return lambda: np.array([s.chi2 for s in
                                 bm.improve(base, exps, data, free=("rho2",)).steps])

    add("dyn_improve release", 1, builder=improve)
    return out


def _tangent(exe: Path) -> float:
    """bench_fe_tangent's own figure: seconds per element of one banded
    tangent assembly at 256 elements per beam (200 repetitions)."""
    res = subprocess.run([str(exe), "256", "200"], check=True, capture_output=True, text=True)
    return float(res.stdout.split()[0])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--only", default="", help="regular expression on the figures' names")
    ap.add_argument("--old", default="beamid_old", help="package name of the old build")
    ap.add_argument("--new", default="beamid", help="package name of the new build")
    ap.add_argument("--old-inputs", type=Path, default=ROOT / "inputs",
                    help="the old checkout's inputs/ (its decks)")
    ap.add_argument("--old-tangent", type=Path, default=None,
                    help="the old build's bench_fe_tangent program")
    ap.add_argument("--markdown", action="store_true", help="also print a Markdown table")
    args = ap.parse_args()
    old = importlib.import_module(args.old)
    new = importlib.import_module(args.new)
    co, cn = cases(old, args.old_inputs), cases(new, ROOT / "inputs")
    print(f"old: {old._ext.__file__}\nnew: {new._ext.__file__}", flush=True)
    pick = re.compile(args.only)
    rows = []
    for name in co:
        if not pick.search(name):
            continue
        number = co[name][0]
        fo, fn = co[name][1](), cn[name][1]()
        to, tn, po, pn, diff = [], [], [], [], 0.0
        for r in range(args.rounds):
            for side in ((0, 1) if r % 2 == 0 else (1, 0)):
                f, tw, tc = ((fo, to, po), (fn, tn, pn))[side]
                t0, c0 = time.perf_counter(), time.process_time()
                for _ in range(number):
                    res = f()
                tw.append((time.perf_counter() - t0) / number)
                tc.append((time.process_time() - c0) / number)
                if side == 0:
                    a = res
                else:
                    b = res
            diff = max(diff, float(np.max(np.abs(np.asarray(a) - np.asarray(b)))))
        med = statistics.median(y / x for x, y in zip(po, pn))
        rows.append((name, min(to), min(tn), min(po), min(pn), med, diff))
        print(f"{name:30s} wall old {min(to):9.3e} new {min(tn):9.3e} new/old "
              f"{min(tn) / min(to):6.3f} | cpu old {min(po):9.3e} new {min(pn):9.3e} "
              f"new/old {min(pn) / min(po):6.3f} (median {med:6.3f}) | max|diff| {diff:.1e}",
              flush=True)
    new_tangent = Path(new._ext.__file__).parent / "bench_fe_tangent"
    if args.old_tangent and pick.search("fe tangent ns/element") and new_tangent.exists():
        to, tn = [], []
        for r in range(args.rounds):
            for side in ((0, 1) if r % 2 == 0 else (1, 0)):
                (to, tn)[side].append(_tangent((args.old_tangent, new_tangent)[side]))
        rows.append(("fe tangent ns/element", min(to) * 1e9, min(tn) * 1e9, None, None,
                     statistics.median(y / x for x, y in zip(to, tn)), 0.0))
        print(f"{'fe tangent ns/element':30s} old {min(to) * 1e9:9.1f} new {min(tn) * 1e9:9.1f} "
              f"new/old {min(tn) / min(to):6.3f} (median {rows[-1][5]:6.3f}; the program's "
              f"own figure)", flush=True)
    if args.markdown:
        print(f"\n| figure | old wall s | new wall s | wall new/old | old CPU s | new CPU s "
              f"| CPU new/old | median CPU ratio | max diff |\n|---|---|---|---|---|---|---|---|---|")
        for name, wo, wn, co_, cn_, med, diff in rows:
            if co_ is None:
                print(f"| {name} | {wo:.1f} ns | {wn:.1f} ns | {wn / wo:.3f} | | | | "
                      f"{med:.3f} | |")
            else:
                print(f"| {name} | {wo:.4g} | {wn:.4g} | {wn / wo:.3f} | {co_:.4g} | {cn_:.4g} "
                      f"| {cn_ / co_:.3f} | {med:.3f} | {diff:.0e} |")


if __name__ == "__main__":
    main()
