"""Pose design on real laser-tracker data: which criterion makes the calibration more accurate?

The measured grid poses of each robot (UR5: 1000, WAM: 216; GTS3800 laser tracker) are the candidate
pool. Each criterion chooses m = 30 and 60 of them; the geometric calibration on their measurements is
scored by the mean position error on the 20 unseen random poses ("test") and on the grid poses not
chosen ("rest"). Reference: the median and quartiles of 20 random subsets, and the fit on the whole
grid. The default (IMSE with coverage) is also drawn with 6 stratification seeds: the median of those
designs and in how many of the 6 they beat the random median show how much the seed matters.
(IDE-based methods move poses off the pool, where nothing was measured, so they cannot take part.)

    python benchmarks/design_real.py [ur5|wam]
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import kincal
from kincal.analysis import free_parameters
from kincal.design import design_problem

DATA = Path(__file__).resolve().parents[1] / "data" / "ur5_wam_gts3800"
SEEDS = 6
CRITERIA = [  # label, select_poses options, region of use
    ("D (Fedorov)", {"criterion": "D"}, None),
    ("I, region = grid", {"criterion": "I"}, None),
    ("I, region = test poses", {"criterion": "I"}, "test"),
    ("D + coverage", {"criterion": "D", "coverage": True}, None),
    ("I + coverage", {"criterion": "I", "coverage": True}, None),
    ("IMSE, weight 0 (= I + coverage)", {"weight": 0.0}, None),
    ("IMSE, weight 0.03", {"weight": 0.03}, None),
    ("IMSE, weight 0.3 (default)", {}, None),
    ("IMSE, weight 3", {"weight": 3.0}, None),
    ("IMSE, region = test poses", {}, "test"),
]


def load(name: str):
    robot = kincal.load_robot(name)
    cols = [f"joint_{i}" for i in range(1, robot.n_joints + 1)]
    read = lambda f: kincal.read_measurements(DATA / f, robot, cols, length_unit="mm", angle_unit="deg")  # noqa: E731
    return robot, read(f"{name}_grid.csv"), read(f"{name}_random.csv")


def run(name: str, n_random: int = 20) -> list[str]:
    robot, grid, test = load(name)
    names = free_parameters(robot, grid.q, "estimate").identifiable  # what a fit on this grid can identify
    P = design_problem(robot, grid.q, names)

    def score(idx) -> np.ndarray:
        fit = kincal.calibrate(robot, grid.subset(idx)).robot
        rest = np.setdiff1d(np.arange(len(grid)), idx)
        return np.array([kincal.evaluate(fit, test).mean, kincal.evaluate(fit, grid.subset(rest)).mean]) * 1e3

    def design(m: int, **kw):
        return kincal.select_poses(robot, grid.q, m=m, problem=P, certify=False, **kw).indices

    everything = kincal.calibrate(robot, grid)
    lines = [f"\n{name.upper()}: pool = {len(grid)} measured grid poses, {P.k} parameters; test = {len(test)} random "
             f"poses; error in mm (mean)",
             f"nominal model: test {kincal.evaluate(robot, test).mean * 1e3:.4f}; calibrated on the whole grid: test "
             f"{kincal.evaluate(everything.robot, test).mean * 1e3:.4f}, grid {everything.stats_after.mean * 1e3:.4f}",
             f"{'m':>3} {'criterion':<34} {'test':>7} {'rest':>7}   beats the random median?"]
    for m in (30, 60):
        rand = np.array([score(design(m, method="random", criterion="D", seed=s)) for s in range(n_random)])
        med = np.median(rand, axis=0)
        q1, q3 = np.percentile(rand, [25, 75], axis=0)
        lines.append(f"{m:>3} {f'random, median of {n_random}':<34} {med[0]:7.4f} {med[1]:7.4f}   quartiles test "
                     f"{q1[0]:.4f}–{q3[0]:.4f}, rest {q1[1]:.4f}–{q3[1]:.4f}")
        for label, kw, region in CRITERIA:
            e = score(design(m, validation_q=test.q if region else None, **kw))
            lines.append(f"{m:>3} {label:<34} {e[0]:7.4f} {e[1]:7.4f}   {_beats(e, med)}")
        seeds = np.array([score(design(m, seed=s)) for s in range(SEEDS)])
        wins = (seeds < med).sum(axis=0)
        lines.append(f"{m:>3} {f'default, median of {SEEDS} seeds':<34} {np.median(seeds[:, 0]):7.4f} "
                     f"{np.median(seeds[:, 1]):7.4f}   seeds beating it: test {wins[0]}/{SEEDS}, rest {wins[1]}/{SEEDS}")
    return lines


def _beats(e: np.ndarray, med: np.ndarray) -> str:
    return " ".join(f"{w}: {'yes' if a < b else 'no'}" for w, a, b in zip(("test", "rest"), e, med))


def main() -> None:
    for name in sys.argv[1:] or ["ur5", "wam"]:
        print("\n".join(run(name)), flush=True)


if __name__ == "__main__":
    main()
