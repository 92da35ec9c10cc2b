"""Write the measurement CSVs of the dynamic estimation decks (Tables 14-23).

The 'true' model is the dissertation's (Table 1; friction mu_elbow = 0.01,
mu_tip = 0.02; no rotary inertia; r_motor = 1), the release is from the
static shape under an 8 N transverse tip force, 4 elements per beam ("8
elements"), and the measurements are the tip u and w. They are computed at
a tighter tolerance (rtol 1e-11) than the fits use (the default 1e-9), so a
fit does not recover the very numbers it computes. Noisy tables draw their
errors from numpy.random.default_rng(SEED) with the stated sigmas (their
published numbers come from the dissertation's own draws, which are lost).

Run from this folder: python make_dynamic_tables.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

import beamid

HERE = Path(__file__).resolve().parent
TRUTH = beamid.pace().replace(J_elbow=0.0, J_tip=0.0, mu_elbow=0.01, mu_tip=0.02)
LOAD = beamid.TipForce(fy=8.0)
QUARTER, HALF = 0.65, 1.3      # of the 2.6 s period of the dominant mode

#: table: (experiment, motor gain, times, sigma_w, sigma_u, seed or None)
TABLES = {
    "14": ("free", 0.0, np.linspace(0.2, 1.0, 5), 1e-4, 1e-4, None),
    "15": ("free", 0.0, np.linspace(QUARTER / 9, QUARTER, 9), 0.0015, 0.0006, 15),
    "16": ("free", 0.0, np.linspace(HALF / 18, HALF, 18), 0.0015, 0.0006, 16),
    "18": ("free", 0.0, np.linspace(QUARTER / 11, QUARTER, 11), 0.0015, 0.0006, 18),
    "19": ("free", 0.0, np.linspace(0.1, 0.6, 6), 0.0015, 0.0006, 19),
    "22": ("forced", 0.2, np.linspace(QUARTER / 5, QUARTER, 5), 1e-4, 1e-4, None),
    "23": ("forced", 0.2, np.linspace(QUARTER / 5, QUARTER, 5), 0.0008, 0.0020, 23),
}


def write(table: str) -> Path:
    name, gain, times, sw, su, seed = TABLES[table]
    exp = beamid.Release(LOAD, motor_gain=gain, rtol=1e-11)
    data = beamid.simulate_measurements(TRUTH, {name: exp}, ["w_tip", "u_tip"],
                                        sigma={"w_tip": sw, "u_tip": su}, t=list(times),
                                        seed=seed, noise=seed is not None)
    path = HERE / f"table{table}_data.csv"
    noise = (f"Gaussian errors of sigma {sw:g} (w) and {su:g} (u) m, "
             f"numpy.random.default_rng({seed})" if seed is not None else "no errors")
    lines = [f"# Table {table}: tip w and u after the release from 8 N, true parameters, "
             f"{'motor gain %g, ' % gain if gain else ''}rtol 1e-11; {noise}.",
             "# Written by make_dynamic_tables.py.",
             "experiment,t,quantity,value,sigma"]
    for e, t, q, v, s in zip(data.experiment, data.t, data.quantity, data.value, data.sigma):
        lines.append(f"{e},{float(t)!r},{q},{float(v)!r},{float(s)!r}")
    path.write_text("\n".join(lines) + "\n")
    return path


if __name__ == "__main__":
    for table in TABLES:
        print(write(table))
