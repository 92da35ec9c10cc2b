"""Spin-up benchmark (issue 28): a 20 s prescribed hub spin-up of the PACE arm
(8 elements per beam, no rotary inertia, no friction; w_s = 1 rad/s reached in
T = 10 s, then steady), the implicit default against RK4 at its largest stable
step, side by side, with their agreement.

RK4's largest stable step: its stability interval on the imaginary axis is
2 sqrt(2) / omega_max, with omega_max the mesh's highest linear frequency (the
spin adds a centrifugal stiffness of order w_s^2, negligible against it); the
run takes 0.95 of it. The agreement is the largest tip |u| or |w| difference at
the 41 output times.
"""
from __future__ import annotations

import sys
import time

import numpy as np

import beamid

T_END = 20.0
NEPB = 8


def main(t_end: float = T_END) -> None:
    model = beamid.pace(J_elbow=0.0, J_tip=0.0)
    law = beamid.SpinUp(w_s=1.0, T=10.0)
    t = np.linspace(0.0, t_end, 41)
    omega_max = float(np.max(beamid.modes(model, NEPB).omega))
    dt = 0.95 * 2.0 * np.sqrt(2.0) / omega_max
    t0 = time.perf_counter()
    imp = beamid.simulate(model, None, t, elements_per_beam=NEPB, loads={"hub": law})
    ti = time.perf_counter() - t0
    t0 = time.perf_counter()
    rk = beamid.simulate(model, None, t, elements_per_beam=NEPB, loads={"hub": law},
                         integrator="rk4", dt=dt)
    tr = time.perf_counter() - t0
    err = float(max(np.max(np.abs(imp.tip_w - rk.tip_w)), np.max(np.abs(imp.tip_u - rk.tip_u))))
    print(f"Spin-up of the PACE arm to {law.w_s} rad/s in {law.T} s, {t_end} s, "
          f"{NEPB} elements per beam (hub angle {law.angle(t_end):.1f} rad at the end)")
    print(f"    implicit simulate(model, None, t, elements_per_beam={NEPB}, "
          f"loads={{'hub': SpinUp(1.0, 10.0)}}): {ti:.4f} s, {imp.info['steps']} steps, "
          f"{imp.info['rejected']} rejected")
    print(f"    RK4      the same, integrator='rk4', dt={dt:.3e} s (0.95 of 2 sqrt 2 / "
          f"omega_max = {omega_max:.4g} rad/s): {tr:.2f} s, {rk.info['steps']} steps")
    print(f"    ratio {tr / ti:.1f}; tip difference {err:.2e} m (largest tip |w| "
          f"{np.max(np.abs(imp.tip_w)):.4f} m); numerical dissipation implicit "
          f"{imp.ledger['numerical'][-1]:.1e} J, RK4 {rk.ledger['numerical'][-1]:.1e} J "
          f"of hub work {imp.ledger['hub'][-1]:.4e} J", flush=True)


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else T_END)
