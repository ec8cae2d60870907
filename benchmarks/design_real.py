"""Pose design on real laser-tracker data: which criterion makes the calibration more accurate?

The measured grid poses of each robot (UR5: 1000, WAM: 216; GTS3800 laser tracker) are the candidate
pool. Each criterion chooses m = 30 and 60 of them; the geometric calibration on their measurements is
scored by the mean position error on the 20 unseen random poses ("test") and on the grid poses not
chosen ("rest"). Reference: the median and quartiles of 20 random subsets, and the fit on the whole
grid. The default (IMSE with coverage) is also drawn with 6 stratification seeds: the median of those
designs and in how many of the 6 they beat the random median show how much the seed matters.
(IDE-based methods move poses off the pool, where nothing was measured, so they cannot take part.)

    python benchmarks/design_real.py [ur5|wam] [--random N] [--docs]

``--random N``: N random subsets instead of 20. ``--docs`` (or KINCAL_DOCS_TABLES=folder) also writes the
tables for the documentation site: every criterion, and a summary (random median, D-optimal, the default).
"""
from __future__ import annotations


import numpy as np

import kincal
from _datasets import dataset
from _docs_table import Table, arguments
from kincal.analysis import free_parameters
from kincal.design import design_problem

DATA = dataset("ur5_wam_gts3800")
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


PROTOCOL = ("ur5_wam_gts3800: the measured grid poses of each robot (UR5 1000, WAM 216) are the candidate "
            "pool; each criterion chooses m of them, the geometric calibration on their measurements is scored by "
            "the mean 3-D position error, mm, on the 20 unseen random poses (test) and on the grid poses not chosen "
            "(rest). Random: the median of {n} random subsets (seeds 0 to {last}). The default (IMSE, weight 0.3, "
            "with coverage) is also drawn with {seeds} stratification seeds.")


def tables(n_random: int) -> tuple[Table, Table]:
    """The full table (every criterion) and the summary (random median, D-optimal, the default)."""
    protocol = PROTOCOL.format(n=n_random, last=n_random - 1, seeds=SEEDS)
    full = Table("design_real", "Pose design on the measured grids: every criterion", protocol + (
        " The last column says whether a design beats the random median on each score; for the random row it "
        "gives the quartiles, for the seeds row in how many seeds the default beat it."),
        ["robot", "m", "criterion", "test", "rest", "beats the random median?"], widths=[5, 3, 34, 7, 7, 0],
        align="lrlrrl")
    summary = Table("design_summary", "Pose design on the measured grids: the default against random and D",
                    protocol + " Whole grid: the calibration on every grid pose, scored on the test poses.",
                    ["robot", "m", "random median test / rest", "D-optimal test / rest", "IMSE (default) test / rest",
                     "whole grid test"], align="lrrrrr")
    return full, summary


def run(name: str, full: Table, n_random: int = 20) -> list[list]:
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
    whole = kincal.evaluate(everything.robot, test).mean * 1e3
    print(f"\n{name.upper()}: pool = {len(grid)} measured grid poses, {P.k} parameters; test = {len(test)} random "
          f"poses; error in mm (mean)\nnominal model: test {kincal.evaluate(robot, test).mean * 1e3:.4f}; calibrated "
          f"on the whole grid: test {whole:.4f}, grid {everything.stats_after.mean * 1e3:.4f}", flush=True)
    summary = []
    for m in (30, 60):
        rand = np.array([score(design(m, method="random", criterion="D", seed=s)) for s in range(n_random)])
        med = np.median(rand, axis=0)
        q1, q3 = np.percentile(rand, [25, 75], axis=0)
        full.row(name.upper(), m, f"random, median of {n_random}", f"{med[0]:.4f}", f"{med[1]:.4f}",
                 f"quartiles test {q1[0]:.4f}–{q3[0]:.4f}, rest {q1[1]:.4f}–{q3[1]:.4f}")
        shown = {}
        for label, kw, region in CRITERIA:
            e = score(design(m, validation_q=test.q if region else None, **kw))
            shown[label] = f"{e[0]:.4f} / {e[1]:.4f}"
            full.row(name.upper(), m, label, f"{e[0]:.4f}", f"{e[1]:.4f}", _beats(e, med))
        seeds = np.array([score(design(m, seed=s)) for s in range(SEEDS)])
        wins = (seeds < med).sum(axis=0)
        full.row(name.upper(), m, f"default, median of {SEEDS} seeds", f"{np.median(seeds[:, 0]):.4f}",
                 f"{np.median(seeds[:, 1]):.4f}", f"seeds beating it: test {wins[0]}/{SEEDS}, rest {wins[1]}/{SEEDS}")
        summary.append([name.upper(), m, f"{med[0]:.4f} / {med[1]:.4f}", shown["D (Fedorov)"],
                        shown["IMSE, weight 0.3 (default)"], f"{whole:.4f}"])
    return summary


def _beats(e: np.ndarray, med: np.ndarray) -> str:
    return " ".join(f"{w}: {'yes' if a < b else 'no'}" for w, a, b in zip(("test", "rest"), e, med))


def main() -> None:
    args = arguments()
    n_random = 20
    if "--random" in args:
        i = args.index("--random")
        n_random, args = int(args[i + 1]), args[:i] + args[i + 2:]
    full, summary = tables(n_random)
    rows = [r for name in args or ["ur5", "wam"] for r in run(name, full, n_random)]
    full.close()
    print()
    for r in rows:
        summary.row(*r)
    summary.close()


if __name__ == "__main__":
    main()
