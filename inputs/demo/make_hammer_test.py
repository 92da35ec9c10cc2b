"""Write hammer_test.csv: the measured hammer test of the loads demo.

The "rig" is the PACE arm without rotary inertia or friction, struck at rest
on the tip by a 20 N, 10 ms half-sine (hammer_fit.nml's &history); the tip's
w (sigma 1e-4 m) and a tip accelerometer normal to the arm (sigma 1e-2
m/s^2) every 0.05 s to 0.7 s, integrated at rtol 1e-11 (the fit uses 1e-9)
on 4 elements per beam, Gaussian errors from seed 7. hammer_fit.nml fits EI1
and rho1 from a start 3 % and 2 % off (docs/loads.md).

    python inputs/demo/make_hammer_test.py
"""
from pathlib import Path

import beamid

TIMES = [round(0.05 * k, 3) for k in range(1, 15)]


def main() -> None:
    arm = beamid.pace(J_elbow=0.0, J_tip=0.0)
    hammer = {"tip_fy": beamid.HalfSine(peak=20.0, duration=0.01)}
    accel = f"accel_n@2:{arm['L2']:g}"
    sigma = {"w_tip": 1e-4, accel: 1e-2}
    release = beamid.Release(None, elements_per_beam=4, rtol=1e-11, loads=hammer)
    data = beamid.simulate_measurements(arm, {"hammer": release}, list(sigma), sigma=sigma,
                                        t=TIMES, seed=7, noise=True)
    lines = ["# Hammer test of the loads demo: the PACE arm at rest struck by a 20 N, 10 ms "
             "half-sine on the tip.",
             "# Written by make_hammer_test.py (rtol 1e-11, 4 elements per beam, seed 7).",
             "experiment,t,quantity,value,sigma"]
    lines += [f"{e},{t:g},{q},{v:.9e},{s:g}" for e, t, q, v, s in
              zip(data.experiment, data.t, data.quantity, data.value, data.sigma)]
    Path(__file__).with_name("hammer_test.csv").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
