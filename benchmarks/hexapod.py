"""A hexapod (Stewart platform), issue 33's speed targets: the fit of the real Jugglebot session S1 (108 poses,
legs in motor revolutions, joint-space residual; target 0.2 s) and 10^4 platform target poses turned into leg
commands by the calibrated model (target 1 s). The data are used in place from ../shared/datasets.

    python benchmarks/hexapod.py
"""
from __future__ import annotations

import time

import numpy as np

import kincal
from kincal.compensate import compensate
from kincal.identify import fit_observations
from kincal.observe import ObservationFormat, in_joint_space, read_observations
from _datasets import dataset

DATA = dataset("stewart_jugglebot")


def timed(fn, repeat: int = 7) -> tuple[float, float]:
    """Best and median of ``repeat`` runs (s), after one warm-up run."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times), float(np.median(times))


def main() -> None:
    robot = kincal.load_robot("hexapod")
    fmt = ObservationFormat("pose", length_unit="mm", angle_unit="rev", orientation="quat-xyzw")
    s1 = in_joint_space(read_observations(str(DATA / "S1.csv"), robot, fmt))
    res = fit_observations(robot, [s1])
    fit = timed(lambda: fit_observations(robot, [s1]))
    fit_c = timed(lambda: fit_observations(robot, [s1], error_model="compliance"))
    q = robot.sample_joints(10_000, seed=1)
    p, _, R, _ = robot.frame_and_rates(q)
    comp = compensate(res.robot, p, rotations=R)
    comp_t = timed(lambda: compensate(res.robot, p, rotations=R), repeat=3)
    print(f"{'case':<58} {'best':>9} {'median':>9} {'target':>8}")
    print(f"{'Jugglebot S1 fit (108 poses, 48 parameters, joint space)':<58} {fit[0]:8.3f}s {fit[1]:8.3f}s {'0.2 s':>8}")
    print(f"{'the same with the legs compliance (49 parameters)':<58} {fit_c[0]:8.3f}s {fit_c[1]:8.3f}s {'0.2 s':>8}")
    print(f"{'10^4 platform poses -> leg commands (closed form, checked)':<58} {comp_t[0]:8.3f}s {comp_t[1]:8.3f}s "
          f"{'1 s':>8}")
    print(f"(fit: {len(res.names)} robot + {len(res.nuisance)} set-up parameters, {len(res.identifiability.frames)} "
          f"gauge freedoms; commands accepted {comp.ok.sum()} of {len(comp.ok)}, largest model residual "
          f"{np.max(comp.residual[comp.ok]) * 1e3:.2e} mm)")


if __name__ == "__main__":
    main()
