#!/usr/bin/python3
"""The reference a researcher would write: scipy's solve_ivp per point (Debian's python3-scipy).

Integrates the coupled model (model.md §1) with its tangent (variational) equations over tau in [0, 500] with
RK45 (rtol 1e-8, atol 1e-10), then FRF (absolute velocity, on the 0.01 grid of the window) and the LLE from the
tangent's growth over the window. Prints one JSON object: points, seconds, points_per_second and the per-point
values, for bench_sweep.sh to compare with `bistable run` on the same points.

usage: scipy_reference.py ALPHA,... OMEGA,...
"""
import json
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp

ETA, ETA_R, PHI, LAM, EPS = 0.1, 0.075, 2.0, 0.8, 1.0
T_END, T_KEEP, DT = 500.0, 250.0, 0.01


def rhs(t, z, alpha, omega):
    y, v, yr, vr = z[0:4]
    w = z[4:8]
    f = alpha * omega * omega * np.sin(omega * t)
    c = ETA_R * (v - vr) + LAM * LAM * (y - yr)
    dv = f - ETA * v + y - EPS * y ** 3 - PHI * c
    dvr = f + c
    cw = ETA_R * (w[1] - w[3]) + LAM * LAM * (w[0] - w[2])
    dw1 = -ETA * w[1] - (-1.0 + 3 * EPS * y * y) * w[0] - PHI * cw
    return [v, dv, vr, dvr, w[1], dw1, w[3], cw]


def point(alpha, omega):
    z0 = [1.0, 0.0, 1.0, 0.0, 0.5, -0.5, 0.5, -0.5]
    t_eval = np.arange(T_KEEP, T_END + DT / 2, DT)
    sol = solve_ivp(rhs, (0.0, T_END), z0, method="RK45", rtol=1e-8, atol=1e-10, t_eval=t_eval, args=(alpha, omega))
    v_abs = sol.y[1] + alpha * omega * np.cos(omega * sol.t)
    frf = 20 * np.log10(np.max(np.abs(v_abs)) / (alpha * omega))
    w = sol.y[4:8]
    lle = (np.log(np.linalg.norm(w[:, -1])) - np.log(np.linalg.norm(w[:, 0]))) / (T_END - T_KEEP)
    return frf, lle


def main():
    alphas = [float(a) for a in sys.argv[1].split(",")]
    omegas = [float(w) for w in sys.argv[2].split(",")]
    t0 = time.perf_counter()
    values = []
    for a in alphas:
        for w in omegas:
            frf, lle = point(a, w)
            values.append({"alpha": a, "omega": w, "frf_db": frf, "lle": lle})
    seconds = time.perf_counter() - t0
    n = len(values)
    print(json.dumps({"points": n, "seconds": seconds, "points_per_second": n / seconds, "values": values}))


if __name__ == "__main__":
    main()
