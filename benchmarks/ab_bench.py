"""Side-by-side timing of two builds of beamid in ONE process (a refactor's
"within 5 % of today" rule on a shared, noisy machine).

    PYTHONPATH=DIR python benchmarks/ab_bench.py [--rounds 5]

DIR holds a copy of the other build's package under the name ``beamid_old``
(pyfront/beamid of that commit plus its _ext*.so). The runs of ``make bench``'s
main figures (bench_dynamics (a), (b), (c); bench_sensitivity's plain and
four-sensitivity runs; a bench_dynfit-sized fit of a release) are timed
alternately old, new, old, new, ... ``--rounds`` times; the best of each side and
the ratio new/old are printed, for the wall clock and for the process's CPU time
(steadier when other jobs share the cores), with the largest difference of the
results (the same numbers are expected: 0).
"""
from __future__ import annotations

import argparse
import importlib
import time

import numpy as np


def cases(bm):
    rel = bm.TipForce(fy=8.0)
    seed = bm.pace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)
    t27 = np.linspace(0.0, 2.6, 27)
    q36 = np.linspace(0.65 / 36, 0.65, 36)
    wrt = ("mu_elbow", "mu_tip", "rho1", "rho2")
    return {
        "dyn (a) implicit 2.6 s": lambda: bm.simulate(seed, rel, t27).tip_w,
        "dyn (b) implicit motor": lambda: bm.simulate(seed, rel, t27, motor_gain=0.2).tip_w,
        "dyn (c) implicit pace()": lambda: bm.simulate(bm.pace(), rel, t27).tip_w,
        "dyn rk4 0.26 s": lambda: bm.simulate(seed, rel, t27[:4], integrator="rk4").tip_w,
        "sens plain quarter": lambda: bm.simulate(seed, rel, q36, elements_per_beam=4).tip_w,
        "sens 4 wrt quarter": lambda: bm.simulate(seed, rel, q36, elements_per_beam=4,
                                                  wrt=wrt).d["tip_w"]["rho1"],
        "sens rk4 4 wrt 0.1 s": lambda: bm.simulate(seed, rel, q36[:6], integrator="rk4",
                                                    wrt=wrt).d["tip_w"]["rho1"],
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--old", default="beamid_old", help="package name of the old build")
    ap.add_argument("--new", default="beamid", help="package name of the new build")
    args = ap.parse_args()
    old = importlib.import_module(args.old)
    new = importlib.import_module(args.new)
    co, cn = cases(old), cases(new)
    print(f"old: {old._ext.__file__}\nnew: {new._ext.__file__}")
    for name in co:
        to, tn, co_, cn_, diff = [], [], [], [], 0.0
        for _ in range(args.rounds):
            t0, c0 = time.perf_counter(), time.process_time()
            a = co[name]()
            to.append(time.perf_counter() - t0)
            co_.append(time.process_time() - c0)
            t0, c0 = time.perf_counter(), time.process_time()
            b = cn[name]()
            tn.append(time.perf_counter() - t0)
            cn_.append(time.process_time() - c0)
            diff = max(diff, float(np.max(np.abs(np.asarray(a) - np.asarray(b)))))
        print(f"{name:26s} wall old {min(to):8.4f} new {min(tn):8.4f} new/old "
              f"{min(tn) / min(to):6.3f} | cpu old {min(co_):8.4f} new {min(cn_):8.4f} "
              f"new/old {min(cn_) / min(co_):6.3f} | max|diff| {diff:.1e}", flush=True)


if __name__ == "__main__":
    main()
