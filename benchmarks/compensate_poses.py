"""Full-pose compensation speed: prints a table (targets from the project's requirements; not a test).

    python benchmarks/compensate_poses.py

UR5 pose targets (the poses the nominal controller reaches at random commands; the real robot is the
nominal one with 0.5 mm / 0.05 deg errors), solved by ``kincal.compensate.poses.solve_poses`` from the
nominal commands: time and peak memory of the solve, each size in a fresh process (peak memory is
per process). The requirement is end to end — CSV in, CSV out: 10⁶ targets ≤ 10 s and ≤ 2 GB, 10⁴
≤ 0.3 s; the CSV columns are the "CSV" column (reading with numpy's C parser, writing with %-format).
"""
from __future__ import annotations

import json
import platform
import resource
import subprocess
import sys
import time

import numpy as np

SIZES = (10**3, 10**4, 10**5, 10**6)


def one(n: int) -> dict:
    import kincal
    from kincal.compensate.poses import solve_poses

    nominal = kincal.load_robot("ur5").with_tool_point([0.03, -0.02, 0.12])
    true = kincal.perturb(nominal, seed=4)
    q0 = nominal.sample_joints(n, seed=1)
    p, R, _, _ = nominal.pose_and_jacobian(q0)
    t0 = time.perf_counter()
    sol = solve_poses(true, p, R, q0)
    solve = time.perf_counter() - t0
    src, out = f"/tmp/kincal-bench-{n}-in.csv", f"/tmp/kincal-bench-{n}-out.csv"
    np.savetxt(src, np.column_stack([q0, p, R.reshape(n, 9)]), fmt="%.10f", delimiter=",")  # the user's file
    t0 = time.perf_counter()
    np.loadtxt(src, delimiter=",")  # reading the targets (16 columns) ...
    np.savetxt(out, sol.q, fmt="%.10f", delimiter=",")  # ... and writing the commands
    io = time.perf_counter() - t0
    return {"n": n, "solve_s": solve, "csv_s": io, "converged": float(sol.converged.mean()),
            "peak_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6}


def main() -> None:
    if len(sys.argv) == 2:
        print(json.dumps(one(int(sys.argv[1]))))
        return
    print(f"pose compensation — {platform.processor() or platform.machine()}, Python {platform.python_version()}")
    print(f"{'targets':>9} {'solve s':>8} {'CSV s':>7} {'total s':>8} {'target s':>9} {'peak GB':>8} {'converged':>9}")
    for n in SIZES:
        r = json.loads(subprocess.run([sys.executable, __file__, str(n)], capture_output=True, text=True,
                                      check=True).stdout)
        target = {10**4: "0.3", 10**6: "10"}.get(n, "–")
        print(f"{n:>9} {r['solve_s']:8.3f} {r['csv_s']:7.2f} {r['solve_s'] + r['csv_s']:8.2f} {target:>9} "
              f"{r['peak_gb']:8.2f} {r['converged']:9.3f}")


if __name__ == "__main__":
    main()
