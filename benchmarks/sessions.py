"""Several measurement sessions (the tracker moved between them): the stacked fit of the kinematics
and every session's frame against the alternation kincal used before (each session's frame re-fitted
to the current model, all sessions brought into the first frame, the kinematics fitted, until no
kinematic parameter moves more than 1e-10), written out here as the reference. Simulated UR5, 15 µm
noise, each session in its own frame; times are medians of 3 warm runs, one BLAS thread. The last
column is the total squared error of the alternation's model over the stacked one's, less 1 (each
session's frame re-fitted): the alternation's stopping rule (no parameter moving 1e-10 in a round)
can stop short with four sessions, 1e-6 from the optimum the stacked fit reaches.

    python benchmarks/sessions.py [--docs]

``--docs`` (or KINCAL_DOCS_TABLES=folder) also writes the table for the documentation site, without the
times (they depend on the machine's load)."""
import time

import numpy as np

import kincal
from _docs_table import Table
from kincal._threads import blas_threads
from kincal.identify.positions import in_frame_of as _in_frame_of, joined
from kincal.identify.sessions import refit_frame


def alternation(robot, sessions, rounds=30, tol=1e-10):
    model, previous, res = refit_frame(robot, sessions[0]), None, None
    for _ in range(rounds):
        data = [sessions[0]] + [_in_frame_of(model, refit_frame(model, s), s) for s in sessions[1:]]
        res = kincal.calibrate(robot, joined(data), diagnose=False)
        base = set(res.robot.base_params())
        values = np.array([v for n, v in zip(res.robot.params.names, res.robot.params.values) if n not in base])
        model = res.robot
        if previous is not None and float(np.max(np.abs(values - previous))) < tol:
            break
        previous = values
    return res


def sessions_of(robot, true, count, n, seed):
    out = []
    for k in range(count):
        moved = true.with_params({"base.x": 0.1 * k, "base.y": -0.2 * k, "base.rz": 0.3 * k})
        m = kincal.simulate(moved, robot.sample_joints(n, seed=seed + k), 15e-6, seed=seed + 10 + k)
        out.append(kincal.Measurements(m.q, m.xyz, m.joint_names, f"s{k}.csv", m.rows))
    return out


def total_error(model, sessions):
    return sum(float(np.sum((refit_frame(model, s).forward(s.q) - s.xyz) ** 2)) for s in sessions)


def median_time(f, runs=3):
    times, out = [], None
    for _ in range(runs):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return float(np.median(times)), out


def main():
    robot = kincal.load_robot("ur5")
    true = kincal.perturb(robot, 0.5e-3, 0.5e-3, seed=3)
    kin = [n for n in robot.params.names if n not in robot.base_params()]
    table = Table("sessions", "Several sessions: the stacked fit against the alternation", (
        "Simulated UR5 with uniform random errors up to 0.5 mm and 0.5 mrad (seed 3), 15 µm tracker noise, each "
        "session k = 0, 1, … measured in its own frame (base x = 0.1k m, y = −0.2k m, rz = 0.3k rad: the "
        "tracker moved), random poses. The stacked fit (the kinematics and every session's frame in one "
        "problem) against the alternation kincal used before (each session's frame re-fitted to the current "
        "model, the kinematics fitted, until no kinematic parameter moves more than 1e-10 in a round), written "
        "out in the benchmark. Max kinematic difference: the largest difference between their kinematic "
        "parameters (m or rad). Error alt/stacked − 1: the total squared error of the alternation's model over "
        "the stacked one's, less 1 (each session's frame re-fitted). The times and speed-up the benchmark "
        "prints are left out here: they depend on the machine's load."),
        ["sessions", "poses each", "alternation ms", "stacked ms", "speed-up", "max kinematic difference",
         "error alt/stacked - 1"], widths=[8, 10, 15, 11, 9, 25, 22], align="rrrrrrr",
        left_out=("alternation ms", "stacked ms", "speed-up"))
    with blas_threads(1):
        kincal.calibrate(robot, kincal.simulate(robot, robot.sample_joints(30, seed=1), 1e-5), diagnose=False)
        for count, n in ((2, 100), (2, 500), (4, 100), (4, 500)):
            sessions = sessions_of(robot, true, count, n, 40)
            t_old, old = median_time(lambda: alternation(robot, sessions))
            t_new, new = median_time(lambda: kincal.identify.calibrate_sessions(robot, sessions, diagnose=False))
            diff = max(abs(old.robot.params[p] - new.robot.params[p]) for p in kin)
            excess = total_error(old.robot, sessions) / total_error(new.robot, sessions) - 1.0
            table.row(count, n, f"{t_old * 1e3:.0f}", f"{t_new * 1e3:.0f}", f"{t_old / t_new:.1f}x", f"{diff:.2e}",
                      f"{excess:.2e}")
    table.close()


if __name__ == "__main__":
    main()
