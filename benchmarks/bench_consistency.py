"""Speed of the Monte Carlo consistency check (issue 17): 1000 replicates of
the Table 5 design (inputs/seed/table05_fit.nml: EI1, EI2 from the tip y
under four directed forces, sigmas 0.0008 ... 0.0011), serially in this
process (the baseline), on the local cores (processes) and on a two-worker
Dask LocalCluster, all in this run. Replicates per second for each, and the
ratio against the serial run. The figures include starting the worker
processes (they import beamid), which is what a user pays; the default
(workers=None) times a few replicates first and stays in this process when
starting processes would not pay.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

import beamid
from beamid.fit_decks import read_fit_deck

ROOT = Path(__file__).resolve().parents[1]
REPLICATES = 1000


def timed(**kwargs):
    t0 = time.perf_counter()
    mc = beamid.consistency(FIT, replicates=REPLICATES, seed=7, progress_bar=False, **kwargs)
    return mc, time.perf_counter() - t0


def main() -> None:
    global FIT
    deck = read_fit_deck(ROOT / "inputs" / "seed" / "table05_fit.nml")
    FIT = beamid.fit(deck.model, deck.experiments, deck.data, free=deck.free)
    cores = len(os.sched_getaffinity(0))
    rows = []
    serial, t_serial = timed(workers=1)
    rows.append(("serial (this process)", t_serial, serial))
    local, t_local = timed(workers=None)
    rows.append((f"default local ({local.runner})", t_local, local))
    forced, t_forced = timed(workers=cores)
    rows.append((f"{cores} local processes (workers={cores})", t_forced, forced))
    try:
        import distributed
    except ImportError:
        print("dask not installed (pip install beamid[dask]): LocalCluster run skipped")
    else:
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                      dashboard_address=None) as cluster, \
                distributed.Client(cluster) as client:
            client.run(lambda: __import__("beamid"))   # workers warm: time the work
            on_dask, t_dask = timed(client=client)
        rows.append(("Dask LocalCluster, 2 workers", t_dask, on_dask))
    print(f"Table 5 design, {REPLICATES} replicates, {cores} cores")
    print(f"{'runner':<40}{'seconds':>9}{'replicates/s':>14}{'vs serial':>11}")
    for name, t, mc in rows:
        print(f"{name:<40}{t:>9.3f}{REPLICATES / t:>14.0f}{t_serial / t:>11.2f}")
        for n in mc.free:   # every runner gives the same replicates
            assert np.array_equal(mc.estimates[n], serial.estimates[n]), name
    print(f"sigma/spread: EI1 {serial.spread_ratio['EI1']:.3f}, "
          f"EI2 {serial.spread_ratio['EI2']:.3f}; failed {serial.failed}")
    # for scale: a heavier refit (Table 3, four parameters from two radial-wire
    # experiments, ~5 ms a replicate), where starting processes can pay
    d3 = read_fit_deck(ROOT / "inputs" / "seed" / "table03_fit.nml")
    fit3 = beamid.fit(d3.model, d3.experiments, d3.data, free=d3.free)
    n3 = 400
    times = {}
    for w in (1, cores):
        t0 = time.perf_counter()
        beamid.consistency(fit3, replicates=n3, seed=7, workers=w, progress_bar=False)
        times[w] = time.perf_counter() - t0
    print(f"Table 3 design, {n3} replicates: {n3 / times[1]:.0f}/s in this process, "
          f"{n3 / times[cores]:.0f}/s on {cores} local processes "
          f"({times[1] / times[cores]:.2f}x)")


if __name__ == "__main__":
    main()
