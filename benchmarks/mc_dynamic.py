"""Monte Carlo consistency of the dynamic designs of Tables 16, 19 and 20
(issue 17): do the sigmas the fits report hold?

For each deck the fit of its own data is the truth; every replicate redraws
the noise of the deck's rows (and of its a priori values) around the model at
the estimates and refits from the deck's starting values
(:func:`beamid.consistency`, local processes). The issue asks for 1000
replicates per table; a replicate is one whole dynamic fit, so the number run
is what fits in the time budget (``--budget`` seconds of wall time per table on
``--workers`` processes, estimated from the time of the deck's own fit; the
default 300 s gives a quick look), reported with the measured time per
replicate. Writes ``docs/mc/tableNN_consistency.csv`` (every replicate) and
``.png`` (normalized errors against N(0, 1)) and appends the summary tables to
``docs/mc/summary.txt``; docs/consistency.md quotes the 1000-replicate run:

    .venv/bin/python benchmarks/mc_dynamic.py --budget 1e9 16 19 20   # ~22 min on 2 cores
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import beamid
from beamid.fit_decks import read_fit_deck
from beamid.tables import inputs_dir

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "mc"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("tables", nargs="*", default=["16", "19", "20"])
    ap.add_argument("--budget", type=float, default=300.0, help="wall seconds per table")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--max", type=int, default=1000, help="replicates at most (the issue's 1000)")
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    for table in args.tables:
        deck = read_fit_deck(inputs_dir("seed") / f"table{table}_fit.nml")
        t0 = time.perf_counter()
        base = beamid.fit(deck.model, deck.experiments, deck.data, free=deck.free,
                          prior=deck.prior, max_iter=deck.max_iter)
        t_fit = time.perf_counter() - t0
        n = max(2, min(args.max, int(args.budget * args.workers / t_fit)))
        t0 = time.perf_counter()
        mc = beamid.consistency(base, replicates=n, seed=args.seed, workers=args.workers,
                                options={"max_iter": deck.max_iter}, progress_bar=False)
        wall = time.perf_counter() - t0
        mc.to_csv(OUT / f"table{table}_consistency.csv")
        mc.plot(OUT / f"table{table}_consistency.png")
        head = (f"Table {table}: {n} replicates of {args.max} asked in {wall:.0f} s on "
                f"{args.workers} processes ({wall * args.workers / n:.2f} s of one core per "
                f"replicate; the deck's own fit {t_fit:.2f} s, {base.iterations} iterations, "
                f"stop {base.stop}); 1000 would take {1000 * wall / n / 60:.0f} min here")
        print(head)
        print(mc.table())
        with open(OUT / "summary.txt", "a") as fh:
            fh.write(head + "\n" + mc.table() + "\n\n")
        if not math.isfinite(wall):
            raise SystemExit(1)


if __name__ == "__main__":
    main()
