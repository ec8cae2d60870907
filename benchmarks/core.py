"""Core speed benchmark: prints a table (targets from the project's requirements; not a test).

    python benchmarks/core.py
"""
from __future__ import annotations

import platform
import resource
import time

import numpy as np

import kincal


def best_of(fn, repeat: int = 15, number: int = 5) -> tuple[float, float]:
    """Best mean time of ``number`` calls over ``repeat`` rounds (s), and page faults per call."""
    fn()
    best, faults = np.inf, 0
    for _ in range(repeat):
        f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        best = min(best, (time.perf_counter() - t0) / number)
        faults += resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0
    return best, faults / (repeat * number)


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
         best_of(lambda: kincal.calibrate(ur5, meas), repeat=7, number=2), 50e-3),
    ]
    print(f"kincal core benchmark — Python {platform.python_version()}, NumPy {np.__version__}, "
          f"{platform.machine()}")
    print(f"{'case':<68} {'time':>10} {'target':>10}  ok   page faults/call")
    for name, (t, faults), target in rows:
        print(f"{name:<68} {t * 1e3:>7.2f} ms {target * 1e3:>7.1f} ms  {'yes' if t <= target else 'NO ':<4} {faults:8.0f}")


if __name__ == "__main__":
    main()
