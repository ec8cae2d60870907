"""DETMAX-IDE against DETMAX in Guo et al. 2024's setting: prints a table (not a test).

    python benchmarks/ide.py

The 3T2R hybrid (guo3t2r), a pool of 1000 random poses, m = 60, the comprehensive index, 150
generations; for each setting of IDE's F0 (eq. 21), crossover probability cr (eq. 25) and population,
10 seeds: the index's gain over the DETMAX design IDE starts from (mean, range) and the number of
generations that improved it. The defaults (F0 = 0.2, cr = 0.2, 30) are the best row measured here.
"""
from __future__ import annotations

import numpy as np

import kincal
from kincal.design import design_problem

SETTINGS = [(1.1, 0.6, 30), (0.8, 0.6, 30), (0.5, 0.6, 30), (0.5, 0.6, 60), (0.5, 0.9, 30), (0.5, 0.3, 30),
            (0.5, 0.2, 30), (0.5, 0.1, 30), (0.3, 0.3, 30), (0.3, 0.1, 30), (0.2, 0.2, 30)]


def main() -> None:
    robot = kincal.load_robot("guo3t2r")
    pool = kincal.candidate_pool(robot, 1000, seed=1)
    P = design_problem(robot, pool)
    print(f"{'F0':>4} {'cr':>4} {'pop':>4} {'mean gain %':>12} {'range %':>14} {'improving gens':>15} {'runs with none':>15}")
    for f0, cr, pop in SETTINGS:
        gains, improved = [], []
        for seed in range(10):
            d = kincal.select_poses(robot, pool, m=60, method="detmax-ide", criterion="comprehensive", seed=seed,
                                    problem=P, certify=False, generations=150, f0=f0, cr=cr, population=pop)
            h = np.array(d.history)  # generation 0: the DETMAX design
            gains.append(100 * (h[-1] / h[0] - 1))
            improved.append(int(np.sum(np.diff(h) > 0)))
        print(f"{f0:4.1f} {cr:4.1f} {pop:4d} {np.mean(gains):12.3f} {f'{min(gains):.3f}-{max(gains):.3f}':>14} "
              f"{np.mean(improved):15.1f} {sum(i == 0 for i in improved):15d}")


if __name__ == "__main__":
    main()
