"""Issue 35, acceptance 1: false alarms and detection of `compare` and `check` in simulation.

A "true" robot: the bundled model with random geometric errors (kincal.perturb, seed 1) and an unmodelled
harmonic error (harmonics:2 on every joint with a lever arm, random coefficients scaled to 0.1 mm RMS of the
tool position over the joint ranges). Each pair: two calibrations on different random pose sets (N poses,
15 µm noise), or a calibration and a 10-pose check chosen by `design --check` from 400 random poses. A change
is a 0.01° joint zero (the robot reaches its joint 0.01° further) or a 0.1 mm link length.

    python benchmarks/change_detection.py [PAIRS] [ROBOT] [CASES] [TESTS]   # defaults: 40 ur5 all compare,check;
                            # ROBOT: ur5 or panda; CASES e.g. none,2,3,link (joint numbers); TESTS: compare, check
Prints a table: rejection rate (false alarms for "none") and how often the changed parameter is named first (itself, or
a change that acts the same at the poses, which the suspect lists: a link's length in its two frames' terms).
"""
import sys
import time

import numpy as np

import kincal
from kincal.design import check_poses
from kincal.identify import Calibrated, check, compare
from kincal.models import extend

from _datasets import dataset
from _docs_table import Table

NOISE, HARMONIC, POSES = 15e-6, 0.1e-3, 100


def truth(nominal, seed=1):
    """The perturbed geometry with the unmodelled harmonic error (0.1 mm RMS over the joint ranges)."""
    ext = extend(kincal.perturb(nominal, seed=seed), "harmonics:2")
    idx = ext.params.indices(list(ext.term_names))
    v = ext.params.values.copy()
    v[idx] = 1e-6 * np.random.default_rng(seed + 1000).standard_normal(idx.size)
    q = nominal.sample_joints(500, seed=seed + 7)
    plain = ext.params.values.copy()
    plain[idx] = 0.0
    rms = np.sqrt(np.mean(np.sum((ext.forward(q, v) - ext.forward(q, plain)) ** 2, axis=1)))
    v[idx] *= HARMONIC / rms
    return ext.with_params(v)


def measure(robot, q, change, seed):
    """Positions of ``robot`` at q, its joint ``change`` = ("zero", j, rad) applied to the joints it reaches."""
    reached = q.copy()
    if change and change[0] == "zero":
        reached[:, change[1]] += change[2]
    return kincal.simulate(robot, reached, NOISE, seed).xyz


def calibrated(nominal, robot, q, change, seed):
    m = kincal.Measurements(q, measure(robot, q, change, seed), nominal.joint_names)
    res = kincal.calibrate(nominal, m, kincal.FitOptions(diagnose=False))
    return Calibrated.of(res.robot, res.record(), f"seed {seed}")


def _named(test, name):
    """Whether the first suspect is the change ``name``, or names it among the changes that act the same."""
    first = test.suspects[0]
    return name in (first.name, *(a.lstrip("−") for a in first.also))


def run(nominal, true, change, pairs, tests=("compare", "check")):
    changed = true
    if change and change[0] == "param":
        v = true.params.as_dict()
        v[change[1]] += change[2]
        changed = true.with_params(v)
    name = None if change is None else (f"{nominal.joint_names[change[1]]} zero" if change[0] == "zero" else change[1])
    out: dict = {t: [] for t in tests}
    for k in range(pairs):
        a = calibrated(nominal, true, nominal.sample_joints(POSES, seed=100 + 2 * k), None, k)
        if "compare" in tests:
            b = calibrated(nominal, changed, nominal.sample_joints(POSES, seed=101 + 2 * k), change, 1000 + k)
            t = compare(a, b)
            out["compare"].append((t.changed, _named(t, name)))
        if "check" not in tests:
            continue
        pool = nominal.sample_joints(400, seed=3000 + k)
        q = pool[check_poses(a.robot, pool, 10, a.repeat)]
        t = check(a, q, measure(changed, q, change, 2000 + k))
        out["check"].append((t.changed, _named(t, name)))
    return out


PANDA = dataset("panda_sockets") / "panda.urdf"
LINKS = {"ur5": "j3.a", "panda": "panda_joint5.z"}  # the forearm: 0.392 m and 0.384 m long


def main():
    pairs = int(sys.argv[1]) if len(sys.argv) > 1 else 40
    robot = sys.argv[2] if len(sys.argv) > 2 else "ur5"
    nominal = kincal.load_robot(PANDA, tip_link="ball_link") if robot == "panda" else kincal.load_robot(robot)
    true = truth(nominal)
    cases = [("none", None)] + [(f"joint {j + 1} zero +0.01°", ("zero", j, np.deg2rad(0.01)))
                                for j in range(min(nominal.n_joints, 6))] + \
        [(f"{LINKS[robot]} +0.1 mm", ("param", LINKS[robot], 1e-4))]
    if len(sys.argv) > 3:
        wanted = sys.argv[3].split(",")
        keys = ["none"] + [str(j + 1) for j in range(min(nominal.n_joints, 6))] + ["link"]
        cases = [c for c, k in zip(cases, keys) if k in wanted]
    tests = tuple(sys.argv[4].split(",")) if len(sys.argv) > 4 else ("compare", "check")
    print(f"{robot}: {POSES} poses per calibration, {NOISE * 1e6:.0f} µm noise, {HARMONIC * 1e3:.1f} mm unmodelled "
          f"harmonic, {pairs} pairs per case")
    which = sys.argv[3].replace(",", "_") if len(sys.argv) > 3 else "all"
    table = Table(f"change_detection_{robot}_{which}",
                  f"Has it changed? compare and check on a simulated {robot.upper() if robot == 'ur5' else 'Panda'}",
                  f"A perturbed {robot} with an unmodelled harmonic error (harmonics:2 on every joint, 0.1 mm RMS "
                  f"over the joint ranges), {NOISE * 1e6:.0f} µm noise; each pair: a calibration on {POSES} random "
                  f"poses "
                  f"and either a second calibration on other poses (compare) or a check on 10 poses chosen by "
                  f"design --check from 400 random ones (check), frame re-fitted, α = 5 %; {pairs} pairs per case. "
                  f"'rejected' is the false-alarm rate for 'none' and the detection rate otherwise; 'named first' "
                  f"counts the changed parameter (or a change acting the same at the poses) as the first suspect.",
                  ["case", "test", "rejected", "named first", "s"], widths=[24, 8, 9, 12, 6], align="llrrr",
                  left_out=("s",))
    for label, change in cases:
        t0 = time.perf_counter()
        out = run(nominal, true, change, pairs, tests)
        for test, rows in out.items():
            rej = np.mean([r for r, _ in rows])
            named = f"{np.mean([n for r, n in rows]):.1%}" if change else "—"
            table.row(label, test, f"{rej:.1%}", named, f"{time.perf_counter() - t0:.0f}")
    table.close()

if __name__ == "__main__":
    main()
