"""Statistical efficiency of calibration (simulation): validation RMS against the Cramér–Rao prediction.

UR5, 60 random poses, 15 µm tracker noise, random errors (±0.5 mm, ±0.05°), 200 noise-free validation
poses, over several seeds; also the same with the data in a tracker frame 30° and 3 m away.

    python benchmarks/efficiency.py [seeds]
"""
from __future__ import annotations

import sys

import numpy as np

import kincal
from kincal.analysis import stacked_jacobian
from kincal.models.transforms import rot_zyx

NOISE = 15e-6


def run(seeds: int) -> None:
    ur5 = kincal.load_robot("ur5")
    R, t = rot_zyx(np.deg2rad(30), 0.0, 0.0), np.array([3.0, 0.0, 0.0])
    rows = []
    for seed in range(seeds):
        true = kincal.perturb(ur5, seed=100 + seed)
        q, qv = ur5.sample_joints(60, seed=200 + seed), ur5.sample_joints(200, seed=300 + seed)
        res = kincal.calibrate(ur5, kincal.simulate(true, q, NOISE, seed=seed), base="fixed")
        rms = kincal.evaluate(res.robot, kincal.simulate(true, qv, 0.0)).rms
        J, Jv = stacked_jacobian(res.robot, q, res.names), stacked_jacobian(res.robot, qv, res.names)
        cr = NOISE * np.sqrt(np.trace(Jv @ np.linalg.inv(J.T @ J) @ Jv.T) / len(qv))
        moved = true.with_base_transform(R, t)
        res_t = kincal.calibrate(ur5, kincal.simulate(moved, q, NOISE, seed=seed), base="estimate")
        rms_t = kincal.evaluate(res_t.robot, kincal.simulate(moved, qv, 0.0)).rms
        Jt, Jtv = stacked_jacobian(res_t.robot, q, res_t.names), stacked_jacobian(res_t.robot, qv, res_t.names)
        cr_t = NOISE * np.sqrt(np.trace(Jtv @ np.linalg.inv(Jt.T @ Jt) @ Jtv.T) / len(qv))
        rows.append((seed, len(res.names), rms, cr, len(res_t.names), rms_t, cr_t))
    print("base fixed, data in the base frame | base estimated, data in a frame 30° and 3 m away")
    print(f"{'seed':>4} {'K':>3} {'RMS µm':>8} {'CR µm':>8} {'ratio':>6} | {'K':>3} {'RMS µm':>8} {'CR µm':>8} {'ratio':>6}")
    for seed, k, rms, cr, kt, rms_t, cr_t in rows:
        print(f"{seed:>4} {k:>3} {rms * 1e6:8.2f} {cr * 1e6:8.2f} {rms / cr:6.3f} | "
              f"{kt:>3} {rms_t * 1e6:8.2f} {cr_t * 1e6:8.2f} {rms_t / cr_t:6.3f}")
    a = np.array([(r[2], r[3], r[5], r[6]) for r in rows])
    m = a.mean(axis=0) * 1e6
    print(f"mean     {m[0]:8.2f} {m[1]:8.2f} {m[0] / m[1]:6.3f} |     {m[2]:8.2f} {m[3]:8.2f} {m[2] / m[3]:6.3f}")


if __name__ == "__main__":
    run(int(sys.argv[1]) if len(sys.argv) > 1 else 20)
