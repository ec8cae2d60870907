"""Start-up benchmark: how long a user waits before kincal does anything (prints a table; not a test).

    python benchmarks/startup.py [runs]

Each command runs as a whole process, ``runs`` times (default 5) after one warm-up run, and the
median wall time is judged against its target. Python's bytecode cache is allowed (as on a user's
machine; the warm-up writes it even where PYTHONDONTWRITEBYTECODE is set in the environment).
The second table times how fast the API refuses a bad option, before any work.
"""
from __future__ import annotations

import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

BIN = Path(sys.executable).parent
CASES = [
    ("python -c 'import kincal'", [sys.executable, "-c", "import kincal"], 0.3),
    ("kincal --help", [str(BIN / "kincal"), "--help"], 0.4),
    ("kincal show ur5", [str(BIN / "kincal"), "show", "ur5"], 0.5),
]


def wall(cmd: list[str], env: dict) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, check=True)
    return time.perf_counter() - t0


def refusal_times(repeat: int = 20) -> list[tuple[str, float]]:
    """Median time (s) for calibrate, select_poses and compensate to refuse a bad option."""
    import kincal

    ur5 = kincal.load_robot("ur5")
    q = ur5.sample_joints(1000, seed=0)
    meas = kincal.simulate(ur5, q, 15e-6, seed=0)
    calls = {
        "calibrate(loss='huber', method='pso')": lambda: kincal.calibrate(ur5, meas, loss="huber", method="pso"),
        "select_poses(method='fedorov', criterion='A')": lambda: kincal.select_poses(ur5, q, method="fedorov",
                                                                                      criterion="A"),
        "compensate(damping=-1)": lambda: kincal.compensate(ur5, ur5.forward(q), q, damping=-1.0),
    }
    out = []
    for label, call in calls.items():
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            try:
                call()
            except ValueError:
                times.append(time.perf_counter() - t0)
        out.append((label, statistics.median(times)))
    return out


def main(runs: int = 5) -> None:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    print(f"kincal start-up — Python {sys.version.split()[0]}, {os.cpu_count()} cores, median of {runs} runs")
    print(f"{'command':<28} {'median s':>9} {'min s':>7} {'max s':>7} {'target s':>9}  ok")
    for label, cmd, target in CASES:
        wall(cmd, env)  # warm-up: the bytecode cache
        t = np.array([wall(cmd, env) for _ in range(runs)])
        med = float(np.median(t))
        print(f"{label:<28} {med:9.3f} {t.min():7.3f} {t.max():7.3f} {target:9.1f}  {'yes' if med <= target else 'NO'}")
    print(f"\n{'a bad option refused (1000-pose UR5 inputs)':<48} {'median ms':>10} {'target ms':>10}  ok")
    for label, t in refusal_times():
        print(f"{label:<48} {t * 1e3:10.3f} {100:10.0f}  {'yes' if t < 0.1 else 'NO'}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 5)
