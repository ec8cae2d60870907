"""Core speed benchmark: prints a table (targets from the project's requirements; not a test).

    python benchmarks/core.py
"""
from __future__ import annotations

import platform
import resource
import time

import numpy as np

import kincal


def best_of(fn, repeat: int = 40, number: int = 5) -> tuple[float, float, float]:
    """Best and median mean time of ``number`` calls over ``repeat`` rounds (s), page faults per call.

    The best round is the figure compared with the target (least disturbed by other load on a shared
    machine); the median shows how noisy the machine was.
    """
    fn()
    times, faults = [], 0
    for _ in range(repeat):
        f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        times.append((time.perf_counter() - t0) / number)
        faults += resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0
    return min(times), float(np.median(times)), faults / (repeat * number)


def main() -> None:
    ur5 = kincal.load_robot("ur5")
    q10k = ur5.sample_joints(10_000, seed=0)
    q1k = q10k[:1000]
    true = kincal.perturb(ur5, seed=1)
    meas = kincal.simulate(true, ur5.sample_joints(1000, seed=2), noise=15e-6, seed=3)
    res = kincal.calibrate(ur5, meas)

    rows = [
        ("FK, 10,000 configurations (UR5)", best_of(lambda: ur5.forward(q10k)), 3e-3),
        ("parameter Jacobian, 1,000 configurations (UR5, 35 params)", best_of(lambda: ur5.param_jacobian(q1k)), 1e-3),
        (f"UR5 calibration, 1,000 poses ({len(res.names)} params, {res.iterations} LM iterations)",
         best_of(lambda: kincal.calibrate(ur5, meas), repeat=15, number=2), 50e-3),
    ]
    print(f"kincal core benchmark — Python {platform.python_version()}, NumPy {np.__version__}, "
          f"{platform.machine()}")
    print(f"{'case':<66} {'best':>9} {'median':>9} {'target':>9}  ok   page faults/call")
    for name, (t, med, faults), target in rows:
        print(f"{name:<66} {t * 1e3:>6.2f} ms {med * 1e3:>6.2f} ms {target * 1e3:>6.1f} ms  "
              f"{'yes' if t <= target else 'NO ':<4} {faults:8.0f}")


if __name__ == "__main__":
    main()
