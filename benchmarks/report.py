"""Report benchmark: size and generation time of the report of the real UR5 calibration (1000 poses
+ 20 held out). Targets: < 1 MB, < 3 s.

    python benchmarks/report.py
"""
from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import kincal
from _datasets import dataset

DATA = dataset("ur5_wam_gts3800")
COLS = [f"joint_{i}" for i in range(1, 7)]


def main() -> None:
    ur5 = kincal.load_robot("ur5")
    read = lambda name: kincal.read_measurements(DATA / name, ur5, COLS, length_unit="mm", angle_unit="deg")  # noqa
    train, test = read("ur5_grid.csv"), read("ur5_random.csv")
    res = kincal.calibrate(ur5, train)
    kincal.build_report(res, test)  # warm up (fonts, imports)
    times = []
    with tempfile.TemporaryDirectory() as d:
        for _ in range(3):
            t0 = time.perf_counter()
            rep = kincal.build_report(res, test)
            rep.write(Path(d) / "report.html")
            times.append(time.perf_counter() - t0)
        size = os.path.getsize(Path(d) / "report.html")
    t = sorted(times)[1]
    print(f"{'case':<52} {'value':>10} {'target':>8}  ok")
    print(f"{'report size, 1000 + 20 poses':<52} {size / 1e6:>7.3f} MB {'1 MB':>8}  {'yes' if size < 1e6 else 'NO'}")
    print(f"{'report generation (median of 3), 1000 + 20 poses':<52} {t:>8.2f} s {'3 s':>8}  {'yes' if t < 3 else 'NO'}")


if __name__ == "__main__":
    main()
