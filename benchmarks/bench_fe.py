"""Speed of the nonlinear finite element chain (`make bench`).

* static 8 N transverse tip force on PACE with 4, 16, 64 and 256 elements per
  beam: seconds per solve (best of a few) and the log-log slope of time
  against the number of elements (banded storage: near 1);
* one banded tangent assembly (internal force + K_T), seconds per element.

Run: python benchmarks/bench_fe.py [--json]
"""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import beamid
from beamid import _ext


def _best_time(func, repeats):
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - t0)
    return best


def bench_static(model, sizes=(4, 16, 64, 256)):
    rows = []
    load = beamid.TipForce(fy=8.0)
    for nepb in sizes:
        repeats = 5 if nepb <= 64 else 3
        result = {}

        def solve():
            result["r"] = beamid.fe_static(model, load, elements_per_beam=nepb)

        seconds = _best_time(solve, repeats)
        r = result["r"]
        rows.append({"elements_per_beam": nepb, "elements": nepb * model.nbeams,
                     "seconds": seconds, "newton_iterations": r.iterations,
                     "tip_w": r.tip["w"]})
    n = np.log([row["elements"] for row in rows])
    t = np.log([row["seconds"] for row in rows])
    slope = float(np.polyfit(n[1:], t[1:], 1)[0])   # the smallest size is overhead-bound
    return rows, slope


def bench_tangent(nepb=256, nrep=200):
    """Seconds per element of one banded tangent assembly of PACE, timed in
    Fortran by benchmarks/fortran/bench_fe_tangent.f90 (built next to the
    extension)."""
    exe = Path(_ext.__file__).parent / "bench_fe_tangent"
    out = subprocess.run([str(exe), str(nepb), str(nrep)], check=True, capture_output=True,
                         text=True)
    return float(out.stdout.split()[0])


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    model = beamid.pace()
    rows, slope = bench_static(model)
    per_element = bench_tangent()
    if "--json" in argv:
        print(json.dumps({"static_8N": rows, "loglog_slope": slope,
                          "tangent_seconds_per_element": per_element}, indent=2))
        return 0
    print("FE static solve, PACE, 8 N transverse tip force (Newton with load steps)")
    print(f"{'el/beam':>8} {'elements':>9} {'s/solve':>11} {'iters':>6} {'tip w':>12}")
    for row in rows:
        print(f"{row['elements_per_beam']:>8d} {row['elements']:>9d} {row['seconds']:>11.3e} "
              f"{row['newton_iterations']:>6d} {row['tip_w']:>12.9f}")
    print(f"log-log slope of time vs elements (16..256 per beam): {slope:.2f}")
    print(f"one tangent assembly: {per_element * 1e9:.0f} ns per element")
    return 0


if __name__ == "__main__":
    sys.exit(main())
