"""Observation-type speed: prints a table (targets from the project's requirements; not a test).

    python benchmarks/observations.py

6-D calibration of 1000 simulated UR5 poses (target ≤ 100 ms) and socket calibration of the 497
real Panda samples (all 8 placements, 8 known distances; target ≤ 200 ms), median of 7 runs after
one warm-up (imports and caches not counted).
"""
from __future__ import annotations

import csv
import platform
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import kincal
from kincal.identify import fit_observations
from kincal.observe import SamePointObs
from kincal.simulate.observations import simulate_poses

ROOT = Path(__file__).resolve().parents[1]


def _median_ms(fn, runs: int = 7) -> tuple[float, object]:
    out = fn()
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times)), out


def _poses():
    ur5 = kincal.load_robot("ur5").with_tool_point([0.05, 0.02, 0.1])
    true = kincal.perturb(ur5, seed=3)
    obs = simulate_poses(true, ur5.sample_joints(1000, seed=1), Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix(),
                         15e-6, 0.05e-3, seed=1)
    return lambda: fit_observations(ur5, [obs])


def _sockets():
    robot = kincal.load_robot(ROOT / "tests" / "data" / "urdf" / "panda" / "panda.urdf", tip_link="ball_link")
    rows = list(csv.DictReader(open(ROOT / "data" / "panda_sockets" / "samples.csv")))
    q = np.array([[float(r[f"q{k}"]) for k in range(1, 8)] for r in rows])
    place = np.array([r["placement"] for r in rows])
    labels = np.array([f"{r['placement']}/{r['socket']}" for r in rows])
    obs = SamePointObs(q, np.arange(2, len(q) + 2), "samples.csv", labels=labels,
                       distances=tuple((f"{p}/0", f"{p}/1", 0.05) for p in dict.fromkeys(place)), group=place)
    return lambda: fit_observations(robot, [obs])


def main() -> None:
    print(f"observation types — {platform.processor() or platform.machine()}, Python {platform.python_version()}")
    print(f"{'case':<46} {'median ms':>10} {'target ms':>10} {'iterations':>10}")
    for name, make, target in (("6-D poses, UR5, 1000 poses (sim.)", _poses, 100),
                               ("sockets, Panda, 497 samples (real)", _sockets, 200)):
        ms, fit = _median_ms(make())
        print(f"{name:<46} {ms:10.1f} {target:10d} {fit.iterations:10d}")


if __name__ == "__main__":
    main()
