"""Pose design on real laser-tracker data: the 1000 measured UR5 grid poses are the candidate pool.

Choose 30 and 60 poses with each pool method, calibrate on their measurements, evaluate on the 20
unseen random poses; compare with 20 random subsets (mean ± sd) and with calibrating on all 1000.
(IDE-based methods move poses off the pool, where nothing was measured, so they cannot take part.)

    python benchmarks/design_real.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

import kincal
from kincal.design import design_problem, relaxed_bound, select_poses

DATA = Path(__file__).resolve().parents[1] / "data" / "ur5_wam_gts3800"
COLS = [f"joint_{i}" for i in range(1, 7)]


def main(n_random: int = 20) -> None:
    ur5 = kincal.load_robot("ur5")
    grid = kincal.read_measurements(DATA / "ur5_grid.csv", ur5, COLS, length_unit="mm", angle_unit="deg")
    test = kincal.read_measurements(DATA / "ur5_random.csv", ur5, COLS, length_unit="mm", angle_unit="deg")
    P = design_problem(ur5, grid.q)

    def score(idx) -> float:
        return kincal.evaluate(kincal.calibrate(ur5, grid.subset(idx)).robot, test).mean * 1e3

    print(f"UR5 grid pool: {len(grid)} measured poses, {P.k} parameters; test: {len(test)} unseen poses")
    print(f"nominal model on the test poses: mean {kincal.evaluate(ur5, test).mean * 1e3:.4f} mm; "
          f"calibrated on all {len(grid)}: mean {score(np.arange(len(grid))):.4f} mm")
    print(f"{'m':>3} {'method':<22} {'D-eff':>7} {'test mean mm':>13}")
    for m in (30, 60):
        b = relaxed_bound(P, m)
        for method, kw in (("detmax", {}), ("fedorov", {}), ("fedorov", {"restarts": 3})):
            d = select_poses(ur5, grid.q, m=m, method=method, criterion="D", seed=0, problem=P, bound=b, **kw)
            label = method + (f" +{kw['restarts']} restarts" if kw else "")
            print(f"{m:>3} {label:<22} {d.efficiency:7.4f} {score(d.indices):13.4f}")
        effs, errs = [], []
        for s in range(n_random):
            d = select_poses(ur5, grid.q, m=m, method="random", criterion="D", seed=s, problem=P, bound=b)
            effs.append(d.efficiency)
            errs.append(score(d.indices))
        print(f"{m:>3} {f'random ({n_random} subsets)':<22} {np.mean(effs):7.4f} "
              f"{np.mean(errs):8.4f} ± {np.std(errs, ddof=1):.4f}")


if __name__ == "__main__":
    main()
