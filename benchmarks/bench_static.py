"""Speed of the arc-length static solver (issue: at most 50 us per solve and at
least 100 times faster than SciPy's solve_bvp on the same problem).

Problem: exact elastica of the PACE arm under an 8 N transverse tip force,
beamid with the sensitivities to EI1 and EI2. Baseline: scipy.integrate.solve_bvp
on the same equations, both beams mapped onto one interval (eight states:
x, y, psi, M per beam), tolerance 1e-8. Both are timed in this run.
"""
from __future__ import annotations

import math
import time

import numpy as np
from scipy.integrate import solve_bvp

import beamid

L1, L2, EI1, EI2, FY = 0.776, 0.714, 11.413, 11.275, 8.0


def best_time(fn, repeat: int, number: int) -> float:
    """Best mean time per call over `repeat` batches of `number` calls."""
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        best = min(best, (time.perf_counter() - t0) / number)
    return best


def scipy_solve():
    # states per beam on t in [0, 1]: x, y, psi, M; s = L t
    def rhs(t, z):
        out = np.empty_like(z)
        for b, (length, ei) in enumerate(((L1, EI1), (L2, EI2))):
            x, y, psi, m = z[4 * b:4 * b + 4]
            out[4 * b] = length * np.cos(psi)
            out[4 * b + 1] = length * np.sin(psi)
            out[4 * b + 2] = length * m / ei
            out[4 * b + 3] = -length * FY * np.cos(psi)   # M' = -(t x P), P = (0, FY)
        return out

    def bc(za, zb):
        return np.array([za[0], za[1], za[2],                       # clamped root
                         za[4] - zb[0], za[5] - zb[1], za[6] - zb[2], za[7] - zb[3],
                         zb[7]])                                     # free tip: M = 0

    t = np.linspace(0.0, 1.0, 11)
    z0 = np.zeros((8, t.size))
    z0[0] = L1 * t
    z0[4] = L1 + L2 * t
    sol = solve_bvp(rhs, bc, t, z0, tol=1e-8, max_nodes=100000)
    if not sol.success:
        raise RuntimeError(sol.message)
    return sol.sol(1.0)[5]


def main() -> None:
    model = beamid.pace()
    load = beamid.TipForce(fy=FY)

    def ours():
        return beamid.solve_static(model, load, wrt=("EI1", "EI2"))

    y_ours, y_scipy = ours().tip_y, scipy_solve()
    t_ours = best_time(ours, repeat=5, number=400)
    t_scipy = best_time(scipy_solve, repeat=3, number=3)
    ratio = t_scipy / t_ours
    print("static solve, PACE exact elastica, 8 N transverse tip force")
    print(f"  tip y: beamid {y_ours:.9f}  solve_bvp {y_scipy:.9f}  "
          f"difference {abs(y_ours - y_scipy):.1e}")
    print(f"  beamid (with d/dEI1, d/dEI2) {t_ours * 1e6:9.1f} us per solve   "
          f"(target <= 50 us: {'met' if t_ours <= 50e-6 else 'NOT met'})")
    print(f"  scipy solve_bvp (tol 1e-8)   {t_scipy * 1e6:9.1f} us per solve")
    print(f"  speed ratio solve_bvp / beamid: {ratio:.0f}   "
          f"(target >= 100: {'met' if ratio >= 100 else 'NOT met'})")


if __name__ == "__main__":
    main()
