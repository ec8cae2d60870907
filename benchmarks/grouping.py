"""Repeated-pose grouping speed: prints a table (not a test).

    python benchmarks/grouping.py [--no-reference]

``duplicate_groups`` (ISO 9283 repeated poses, run by every ``calibrate``) and a whole
``kincal.calibrate`` on 1,000, 20,000 and 100,000 simulated UR5 poses, simulated as in
benchmarks/core.py (``perturb`` seed 1, 15 µm noise), with the UR5's repeat tolerance (1e-4 rad).
Grouping is timed on four kinds of poses:

* distinct: random poses, none repeated (what calibrate sees in this table);
* repeated x5: every pose five times, joints jittered within ±0.4 tol (a repeatability test);
* slow path: a stream along straight joint paths between random poses, 0.3 tol per sample, with
  50 samples of dwell (0.1 tol jitter) at each pose: long chains, a new group every few samples;
* random walk: ±0.5 tol per joint per sample around one pose (dense: a hard case).

Best of three runs after a warm-up (calibrate at 100,000 poses: one run); µs/pose staying flat from
1,000 to 100,000 poses is linear scaling. "quadratic" is the former all-pairs grouping (kept here
as the reference) on the distinct poses, one run, up to 20,000 poses.
"""
from __future__ import annotations

import platform
import sys
import time

import numpy as np

import kincal
from kincal.identify.verdict import Thresholds, duplicate_groups, repeat_tolerance

SIZES = (1_000, 20_000, 100_000)


def quadratic_groups(q: np.ndarray, tol: np.ndarray) -> list[np.ndarray]:
    """The former O(N²) grouping, for comparison only."""
    label = np.full(len(q), -1)
    for i in range(len(q)):
        if label[i] >= 0:
            continue
        close = np.all(np.abs(q[i:] - q[i]) <= tol, axis=1) & (label[i:] < 0)
        label[i:][close] = i
    groups = [np.flatnonzero(label == g) for g in np.unique(label)]
    return sorted((g for g in groups if len(g) > 1), key=lambda g: g[0])


def best(fn, runs: int = 3) -> float:
    """Best wall time of ``runs`` calls after one warm-up (s)."""
    fn()
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def slow_path(ur5, n: int, tol: np.ndarray, rng) -> np.ndarray:
    """n samples of a slow stream: straight joint paths at 0.3 tol per sample, 50 samples of dwell."""
    parts, size, seed = [], 0, 100
    while size < n:
        a, b = ur5.sample_joints(2, seed=seed)
        steps = int(np.ceil(np.max(np.abs(b - a) / tol) / 0.3))
        parts += [a + rng.normal(0.0, 0.1, (50, len(a))) * tol, a + np.linspace(0.0, 1.0, steps)[:, None] * (b - a)]
        size, seed = size + 50 + steps, seed + 1
    return np.vstack(parts)[:n]


def cases(ur5, n: int, tol: np.ndarray) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(n)
    distinct = ur5.sample_joints(n, seed=2)
    return {"distinct": distinct,
            "repeated x5": np.repeat(distinct[: n // 5], 5, axis=0) + rng.uniform(-0.4, 0.4, (n, 6)) * tol,
            "slow path": slow_path(ur5, n, tol, rng),
            "random walk": distinct[0] + np.cumsum(rng.choice([-0.5, 0.5], (n, 6)) * tol, axis=0)}


def main() -> None:
    reference = "--no-reference" not in sys.argv[1:]
    ur5 = kincal.load_robot("ur5")
    true = kincal.perturb(ur5, seed=1)
    tol = repeat_tolerance(ur5.joint_types, Thresholds())
    print(f"repeated-pose grouping — Python {platform.python_version()}, NumPy {np.__version__}, "
          f"{platform.machine()}; each cell: best time (µs per pose)")
    names = ["distinct", "repeated x5", "slow path", "random walk", "quadratic", "calibrate"]
    print(f"{'poses':>7}  " + "".join(f"{h:>20}" for h in names) + "  verdict")
    for n in SIZES:
        data = cases(ur5, n, tol)
        times = [best(lambda q=q: duplicate_groups(q, tol)) for q in data.values()]
        q = data["distinct"]
        times.append(best(lambda: quadratic_groups(q, tol), runs=1) if reference and n <= 20_000 else None)
        meas = kincal.simulate(true, q, noise=15e-6, seed=3)
        times.append(best(lambda: kincal.calibrate(ur5, meas), runs=1 if n > 20_000 else 3))
        verdict = kincal.calibrate(ur5, meas).verdict.status
        cells = "".join(f"{'—':>20}" if t is None else f"{t * 1e3:>9.1f} ms ({t / n * 1e6:5.1f})" for t in times)
        print(f"{n:>7}  {cells}  {verdict}")
    print("('quadratic': the former grouping, distinct poses; a calibrate that is not 'good' also runs the "
          "diagnosis, several more fits)")


if __name__ == "__main__":
    main()
