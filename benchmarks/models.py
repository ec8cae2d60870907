"""Error models on the real UR5 and WAM tracker data: geometric, without β, compliance, gravity
regressor, joint-angle harmonics and a combination vs auto
(joint-space blocked cross-validation with the prediction-σ guard), and their cost. Targets: auto
≤ 0.090 mm on the UR5's 20 held-out poses; a single extended fit ≤ 100 ms and auto ≤ 2 s (1000 poses).

    python benchmarks/models.py
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import kincal

DATA = Path(__file__).resolve().parents[1] / "data" / "ur5_wam_gts3800"


def timed(fn, repeat: int = 5):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, float(np.median(times))


def main() -> None:
    print(f"{'robot':<5} {'model':<30} {'params':>6} {'held-out mean mm':>17} {'fit time':>10}")
    for name, n in (("ur5", 6), ("wam", 7)):
        robot = kincal.load_robot(name)
        cols = [f"joint_{i}" for i in range(1, n + 1)]
        read = lambda f: kincal.read_measurements(DATA / f, robot, cols, length_unit="mm", angle_unit="deg")  # noqa
        train, test = read(f"{name}_grid.csv"), read(f"{name}_random.csv")
        models = ["geometric", "nobeta", "gravity-regressor", "harmonics:1", "harmonics:2",
                  "gravity-regressor+harmonics:2", "auto"]
        if any(j.mass > 0 for j in robot.joints):
            models[2:2] = ["compliance", "compliance+harmonics:2"]
        for model in models:
            kw = {"error_model": model, "use_q": test.q} if model == "auto" else {"error_model": model}
            res, t = timed(lambda: kincal.calibrate(robot, train, **kw), repeat=3 if model == "auto" else 5)
            label = model if model != "auto" else f"auto={res.error_model_choice.chosen}"
            print(f"{name:<5} {label:<30} {len(res.names):>6} {kincal.evaluate(res.robot, test).mean * 1e3:>17.4f} "
                  f"{t * 1e3:>7.0f} ms")
    print("targets: ur5 auto <= 0.090 mm; extended fit <= 100 ms; auto <= 2000 ms (1000 poses)")


if __name__ == "__main__":
    main()
