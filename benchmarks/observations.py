"""Observation-type speed: prints a table (targets from the project's requirements; not a test).

    python benchmarks/observations.py [--real] [--docs]

6-D calibration of 1000 simulated UR5 poses (target ≤ 100 ms) and socket calibration of the 497
real Panda samples (all 8 placements, 8 known distances; target ≤ 200 ms), median of 7 runs after
one warm-up (imports and caches not counted).

``--real``: instead, the accuracy on the two real data sets of other kinds: the Panda's sockets (trained on
one plate placement, tested on the other 7, as the data's authors did) and the positioner's 6-D poses seen by
a camera (even rows fitted, odd rows held out) at three stated rotation σ. ``--docs`` (or
KINCAL_DOCS_TABLES=folder) also writes those tables for the documentation site.
"""
from __future__ import annotations

import csv
import platform
import time

import numpy as np
from scipy.spatial.transform import Rotation

import kincal
from _datasets import POSITIONER_MODEL, dataset
from _docs_table import Table, arguments
from kincal.identify import fit_observations
from kincal.observe import PoseObs, SamePointObs
from kincal.simulate.observations import simulate_poses


def _median_ms(fn, runs: int = 7) -> tuple[float, object]:
    out = fn()
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times)), out


def _poses():
    ur5 = kincal.load_robot("ur5").with_tool_point([0.05, 0.02, 0.1])
    true = kincal.perturb(ur5, seed=3)
    obs = simulate_poses(true, ur5.sample_joints(1000, seed=1), Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix(),
                         15e-6, 0.05e-3, seed=1)
    return lambda: fit_observations(ur5, [obs])


def _sockets():
    robot = kincal.load_robot(dataset("panda_sockets") / "panda.urdf", tip_link="ball_link")
    rows = list(csv.DictReader(open(dataset("panda_sockets") / "samples.csv")))
    q = np.array([[float(r[f"q{k}"]) for k in range(1, 8)] for r in rows])
    place = np.array([r["placement"] for r in rows])
    labels = np.array([f"{r['placement']}/{r['socket']}" for r in rows])
    obs = SamePointObs(q, np.arange(2, len(q) + 2), "samples.csv", labels=labels,
                       distances=tuple((f"{p}/0", f"{p}/1", 0.05) for p in dict.fromkeys(place)), group=place)
    return lambda: fit_observations(robot, [obs])


def _panda():
    """The nominal Panda (URDF, to its ball), the placements (N,) and the socket set of a mask of samples."""
    robot = kincal.load_robot(dataset("panda_sockets") / "panda.urdf", tip_link="ball_link")
    rows = list(csv.DictReader(open(dataset("panda_sockets") / "samples.csv")))
    q = np.array([[float(r[f"q{k}"]) for k in range(1, 8)] for r in rows])
    place = np.array([r["placement"] for r in rows])
    labels = np.array([f"{r['placement']}/{r['socket']}" for r in rows])

    def sockets(mask: np.ndarray, **kw) -> SamePointObs:
        d = tuple((f"{p}/0", f"{p}/1", 0.05) for p in dict.fromkeys(place[mask]))
        return SamePointObs(q[mask], np.flatnonzero(mask) + 2, "samples.csv", labels=labels[mask], distances=d,
                            group=place[mask], **kw)
    return robot, place, sockets


def real_sockets() -> None:
    """MUKCa's protocol on its own data: trained on front_center, tested on the 7 other placements."""
    robot, place, sockets = _panda()
    train = place == "front_center"
    authors = kincal.load_robot(dataset("panda_sockets") / "panda_2_calibrated_by_authors.urdf",
                                tip_link="ball_link")
    table = Table("panda_sockets", "Panda sockets, real data: trained on one placement, tested on seven", (
        "panda_sockets (497 samples, a ball on the flange seated in two sockets 50 mm apart on a plate "
        "put at 8 places): fitted on the front_center placement, tested on the other 7, as the data's authors "
        "did. Their metrics, mm: consistency = the mean over the samples of the distance of each predicted "
        "ball centre from its socket's mean (training and test placements); distance error = the error of the "
        "50 mm between the two socket means, smallest and largest over the 7 test placements. Rows: the nominal "
        "URDF; the calibration the authors released (panda_2_calibrated_by_authors.urdf); kincal with its "
        "default learned prior; kincal by plain least squares (prior none); kincal with the 50 mm stated "
        "loosely (σ 1 mm instead of 0.1 mm)."),
        ["model", "training consistency mm", "test consistency mm", "test distance error mm"], widths=[34],
        align="lrrr")
    models = {"nominal URDF": robot, "authors' calibration": authors,
              "kincal (learned prior)": fit_observations(robot, [sockets(train)]).robot,
              "kincal, least squares (prior none)": fit_observations(robot, [sockets(train)], prior="none").robot,
              "kincal, 50 mm stated to σ 1 mm": fit_observations(robot, [sockets(train, std_distance=1e-3)]).robot}
    for label, model in models.items():
        a, b = (sockets(m).stats(model, model.params.values, None) for m in (train, ~train))
        d = [g["distance_error"] * 1e3 for g in b["groups"]]
        table.row(label, f"{a['mean_abs'] * 1e3:.3f}", f"{b['mean_abs'] * 1e3:.3f}", f"{min(d):.3f}–{max(d):.3f}")
    table.close()


def real_positioner() -> None:
    """The positioner's 6-D poses: even rows fitted, odd rows held out, at three stated rotation σ."""
    robot = kincal.load_robot(POSITIONER_MODEL)
    rows = list(csv.DictReader(open(dataset("positioner_6d") / "measurements.csv")))
    q = np.array([[float(r["q1"]), float(r["q2"])] for r in rows])
    xyz = np.array([[float(r[k]) for k in "xyz"] for r in rows])
    R = Rotation.from_quat([[float(r[k]) for k in ("qx", "qy", "qz", "qw")] for r in rows]).as_matrix()
    even, odd = np.arange(0, len(q), 2), np.arange(1, len(q), 2)
    table = Table("positioner_6d", "Positioner seen by a camera, real 6-D poses: held out", (
        f"positioner_6d ({len(q)} poses of a target on a two-axis positioner, seen by a camera): fitted on "
        "the even rows with the position σ stated as 0.1 mm and the rotation σ as in the first column, judged "
        "on the odd rows strictly: in the fitted camera frame with the fitted target, nothing re-fitted; "
        "mean position error, mm, and mean rotation error, mrad. Whitened RMS: the training residual over its "
        "stated σ (1 when the σ are right)."),
        ["stated rotation σ", "held-out position mm", "held-out rotation mrad", "whitened RMS"], align="rrrr")
    for std_rot in (0.1e-3, 1e-3, 10e-3):
        fit = fit_observations(robot, [PoseObs(q[even], even + 2, "measurements.csv", xyz=xyz[even], R=R[even],
                                               std_pos=0.1e-3, std_rot=std_rot)])
        test = PoseObs(q[odd], odd + 2, "measurements.csv", xyz=xyz[odd], R=R[odd],
                       target_rotation=fit.observations[0].target_rotation)
        s = test.stats(fit.robot, fit.robot.params.values, np.array([fit.nuisance[f"target.r{a}"] for a in "xyz"]))
        table.row(f"{std_rot * 1e3:g} mrad", f"{s['mean'] * 1e3:.3f}", f"{s['mean_rotation'] * 1e3:.3f}",
                  f"{fit.whitened_rms:.1f}")
    table.close()


def main() -> None:
    if "--real" in arguments():
        real_sockets()
        print()
        real_positioner()
        return
    print(f"observation types — {platform.processor() or platform.machine()}, Python {platform.python_version()}")
    print(f"{'case':<46} {'median ms':>10} {'target ms':>10} {'iterations':>10}")
    for name, make, target in (("6-D poses, UR5, 1000 poses (sim.)", _poses, 100),
                               ("sockets, Panda, 497 samples (real)", _sockets, 200)):
        ms, fit = _median_ms(make())
        print(f"{name:<46} {ms:10.1f} {target:10d} {fit.iterations:10d}")


if __name__ == "__main__":
    main()
