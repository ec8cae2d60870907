"""Full-pose compensation end to end — CSV in, CSV out, through the command line: prints a table.

    python benchmarks/compensate_poses.py [--sizes 1000,10000,100000,1000000]

A UR5 calibrated from 80 simulated tracker poses (the real robot: the nominal one with errors) and
6-D targets (quaternions) that the nominal controller reaches at random commands over the whole
joint ranges, singularities included, in a CSV of 13 columns. Each size runs
``kincal compensate CAL TARGETS --pose --skip-unreachable -o OUT`` five times (10⁶: three), and the
median is printed with the range (a shared machine's speed drifts by 20 %): wall time from start to exit
(start-up, reading, solving, every check, writing) and the peak memory of all its processes
together (sampled every 50 ms). The requirement: 10⁶ targets ≤ 10 s and ≤ 2 GB, 10⁴ ≤ 0.3 s of work
(the "work" column: wall time less the command's start-up, measured on a 1-row file).
"""
from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

TARGETS = {10**4: 0.3, 10**6: 10.0}


def _files(folder: Path, sizes) -> tuple[Path, dict]:
    import kincal
    from kincal.observe import from_matrices

    nominal = kincal.load_robot("ur5")
    true = kincal.perturb(nominal, seed=4)
    res = kincal.calibrate(nominal, kincal.simulate(true, nominal.sample_joints(80, seed=2), 15e-6, seed=3))
    cal = folder / "cal.yaml"
    kincal.save_robot(res.robot, cal, calibration=res.record())
    files = {}
    for n in (1, *sizes):
        q0 = nominal.sample_joints(n, seed=1)
        p, R, _, _ = nominal.pose_and_jacobian(q0)
        files[n] = folder / f"targets-{n}.csv"
        np.savetxt(files[n], np.column_stack([q0, p, from_matrices(R, "quat-wxyz")]), fmt="%.10f", delimiter=",",
                   header="j1,j2,j3,j4,j5,j6,x,y,z,qw,qx,qy,qz", comments="")
    return cal, files


def _rss(pid: int) -> int:
    """Resident memory (bytes) of a process and all its descendants."""
    total, todo = 0, [pid]
    while todo:
        p = todo.pop()
        try:
            for line in Path(f"/proc/{p}/status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    total += int(line.split()[1]) * 1024
            for task in Path(f"/proc/{p}/task").iterdir():
                todo += [int(c) for c in (task / "children").read_text().split()]
        except (FileNotFoundError, ProcessLookupError):
            continue
    return total


def run(cal: Path, src: Path, out: Path) -> tuple[float, float, str]:
    cmd = [sys.executable, "-m", "kincal.cli", "compensate", str(cal), str(src), "--pose", "--skip-unreachable",
           "--joint-cols", "j1,j2,j3,j4,j5,j6", "-o", str(out)]
    report = out.with_suffix(".txt")
    with open(report, "w") as fh:  # a file, not a pipe: a long report would fill a pipe
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=fh, stderr=subprocess.PIPE, text=True)
        peak = 0
        while proc.poll() is None:
            peak = max(peak, _rss(proc.pid))
            time.sleep(0.05)
        wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"kincal compensate failed ({proc.returncode}): {proc.stderr.read()}")
    line = next(x for x in report.read_text().splitlines() if " targets (targets in " in x)
    return wall, peak / 1e9, "/".join(line.split(" targets (")[0].split(" of "))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="1000,10000,100000,1000000")
    sizes = [int(s) for s in ap.parse_args().sizes.split(",")]
    print(f"pose compensation, CSV in and out — {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, Python {platform.python_version()}")
    with tempfile.TemporaryDirectory() as tmp:
        cal, files = _files(Path(tmp), sizes)
        start = float(np.median([run(cal, files[1], Path(tmp) / "out.csv")[0] for _ in range(5)]))
        print(f"start-up (1 target): {start:.2f} s (median of 5)")
        print(f"{'targets':>9} {'wall s':>7} {'range s':>11} {'work s':>7} {'target s':>9} {'peak GB':>8} "
              f"{'accepted':>17}")
        for n in sizes:
            runs = [run(cal, files[n], Path(tmp) / "out.csv") for _ in range(3 if n >= 10**6 else 5)]
            wall, peak, accepted = float(np.median([r[0] for r in runs])), max(r[1] for r in runs), runs[0][2]
            target = TARGETS.get(n)
            spread = f"{min(r[0] for r in runs):.2f}-{max(r[0] for r in runs):.2f}"
            print(f"{n:>9} {wall:7.2f} {spread:>11} {wall - start:7.2f} {'–' if target is None else f'{target:g}':>9} "
                  f"{peak:8.2f} {accepted:>17}")


if __name__ == "__main__":
    main()
