"""Statistical efficiency of calibration (simulation): validation RMS against the Cramér–Rao prediction.

UR5, 60 random poses, 15 µm tracker noise, random errors (±0.5 mm, ±0.05°), 200 noise-free validation
poses, over several seeds; also the same with the data in a tracker frame 30° and 3 m away. With
``--kinds N``, then every kind of measurement (points, 6-D poses, markers, sockets, planes, points and
sockets together) on a UR5 (DH) and the Panda (URDF), N seeds each, 150 poses, 15 µm / 0.05 mrad noise.

    python benchmarks/efficiency.py [seeds] [--kinds N] [--docs]

``--docs`` (or KINCAL_DOCS_TABLES=folder) also writes the tables for the documentation site.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import kincal
from _datasets import dataset
from _docs_table import Table, arguments
from kincal.analysis import stacked_jacobian
from kincal.identify import fit_observations
from kincal.identify.registration import kabsch
from kincal.models.transforms import rot_zyx

NOISE = 15e-6
ROOT = Path(__file__).resolve().parents[1]
TOOL = np.array([0.05, 0.02, 0.1])
TARGET = Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix()  # the 6-D target's rotation on the flange
MARKERS = np.array([[0.05, 0.0, 0.1], [-0.03, 0.05, 0.08], [0.0, -0.06, 0.12]])
PLANES = {"table": (np.array([0, 0, 1.0]), -0.05), "step": (np.array([0, 0, 1.0]), 0.05),
          "wall": (np.array([1.0, 0, 0]), 0.35), "side": (np.array([0, 1.0, 0.0]), -0.3)}
KINDS = ["point", "pose", "markers", "same-point", "plane", "mixed"]

sys.path[:0] = [str(ROOT / "tests" / "observe"), str(ROOT / "tests")]  # the simulated sets and the Cramér–Rao
# check are the tests' own (tests/observe/test_observations.py, which reads tests/conftest.py)
from test_observations import _columns, _cramer_rao, _sets, _sockets, _validation  # noqa: E402


def run(seeds: int) -> None:
    ur5 = kincal.load_robot("ur5")
    R, t = rot_zyx(np.deg2rad(30), 0.0, 0.0), np.array([3.0, 0.0, 0.0])
    rows = []
    for seed in range(seeds):
        true = kincal.perturb(ur5, seed=100 + seed)
        q, qv = ur5.sample_joints(60, seed=200 + seed), ur5.sample_joints(200, seed=300 + seed)
        res = kincal.calibrate(ur5, kincal.simulate(true, q, NOISE, seed=seed), base="fixed")
        rms = kincal.evaluate(res.robot, kincal.simulate(true, qv, 0.0)).rms
        J, Jv = stacked_jacobian(res.robot, q, res.names), stacked_jacobian(res.robot, qv, res.names)
        cr = NOISE * np.sqrt(np.trace(Jv @ np.linalg.inv(J.T @ J) @ Jv.T) / len(qv))
        moved = true.with_base_transform(R, t)
        res_t = kincal.calibrate(ur5, kincal.simulate(moved, q, NOISE, seed=seed), base="estimate")
        rms_t = kincal.evaluate(res_t.robot, kincal.simulate(moved, qv, 0.0)).rms
        Jt, Jtv = stacked_jacobian(res_t.robot, q, res_t.names), stacked_jacobian(res_t.robot, qv, res_t.names)
        cr_t = NOISE * np.sqrt(np.trace(Jtv @ np.linalg.inv(Jt.T @ Jt) @ Jtv.T) / len(qv))
        rows.append((seed, len(res.names), rms, cr, len(res_t.names), rms_t, cr_t))
    print("base fixed, data in the base frame | base estimated, data in a frame 30° and 3 m away")
    table = Table("efficiency", "Point calibration against the Cramér–Rao prediction (simulated UR5)", (
        f"Simulated UR5, {seeds} seeds: uniform random errors up to 0.5 mm and 0.05°, 60 random poses, "
        "15 µm tracker noise per axis; validation RMS of the 3-D error on 200 noise-free random poses, µm, "
        "against its Cramér–Rao prediction σ·sqrt(tr(Jv (JᵀJ)⁻¹ Jvᵀ)/N) at the fitted model. K: parameters "
        "fitted. Left: the base frame fixed, data in the base frame; right (moved): the base frame estimated, "
        "data in a tracker frame turned 30° and 3 m away. Ratio 1 is the best any unbiased estimator does."),
        ["seed", "K", "RMS µm", "CR µm", "ratio", "K moved", "RMS µm moved", "CR µm moved", "ratio moved"],
        widths=[4, 3, 8, 8, 6])
    for seed, k, rms, cr, kt, rms_t, cr_t in rows:
        table.row(seed, k, f"{rms * 1e6:.2f}", f"{cr * 1e6:.2f}", f"{rms / cr:.3f}",
                  kt, f"{rms_t * 1e6:.2f}", f"{cr_t * 1e6:.2f}", f"{rms_t / cr_t:.3f}")
    a = np.array([(r[2], r[3], r[5], r[6]) for r in rows])
    m = a.mean(axis=0) * 1e6
    table.row("mean", "", f"{m[0]:.2f}", f"{m[1]:.2f}", f"{m[0] / m[1]:.3f}",
              "", f"{m[2]:.2f}", f"{m[3]:.2f}", f"{m[2] / m[3]:.3f}")
    table.close()


def _setup_z(kind: str, fit, true, sets: list) -> list[float]:
    """z-scores of the set-up parameters that have a truth: the 6-D target's rotation, the socket points."""
    z: list[float] = []
    if kind == "pose":
        t0 = fit.observations[0].target_rotation
        truth = Rotation.from_matrix(t0.T @ TARGET).as_rotvec()
        z += [(fit.nuisance[f"target.r{a}"] - t) / fit.std[f"target.r{a}"] for a, t in zip("xyz", truth)]
    if kind in ("same-point", "mixed"):
        sockets = sets[-1]
        seats = true.forward(sockets.q)  # each label's mean seat position (the seats scatter by σ)
        if kind == "same-point":  # the base is a gauge: compare in the frame the fit kept (the nominal's)
            R, t = kabsch(seats, fit.robot.forward(sockets.q))
            seats = seats @ R.T + t
        for lab in sockets.points():
            mean = seats[sockets.labels == lab].mean(axis=0)
            z += [(fit.nuisance[f"point[{lab}].{a}"] - mean[k]) / fit.std[f"point[{lab}].{a}"]
                  for k, a in enumerate("xyz")]
    return z


def kind_trial(robot, kind: str, seed: int) -> tuple[float, list[float]]:
    """One seed: the validation RMS over its Cramér–Rao prediction, and the set-up parameters' z-scores."""
    true = kincal.perturb(robot, 0.5e-3, 0.5e-3, seed=seed)
    q = robot.sample_joints(150, seed=seed)
    if kind in ("pose", "same-point", "mixed"):  # a truth for the set-up: errors only where the data see them
        seen = fit_observations(robot, _sets(kind, true, q, seed)).names
        true = kincal.perturb(robot, 0.5e-3, 0.5e-3, seed=seed, names=seen)
    sets = _sets(kind, true, q, seed)
    fit = fit_observations(robot, sets)
    if not fit.converged or fit.verdict.status == "refused":
        raise RuntimeError(f"{kind}, seed {seed}: the fit did not converge or was refused")
    err, predicted = _validation(kind, fit, true, seed)
    return err / predicted, _setup_z(kind, fit, true, sets)


def run_kinds(seeds: int) -> None:
    robots = {"UR5 (DH)": kincal.load_robot("ur5").with_tool_point(TOOL),
              "Panda (URDF)": kincal.load_robot(dataset("panda_sockets") / "panda.urdf",
                                                tip_link="ball_link")}
    table = Table("cramer_rao", "Every kind of measurement against the Cramér–Rao prediction (simulation)", (
        f"Simulated, {seeds} seeds per robot and kind: uniform random errors up to 0.5 mm and 0.5 mrad on every "
        "parameter (on those the data see, for poses, sockets and mixed, so that the set-up parameters have a "
        "truth); 150 random poses; noise 15 µm per axis and 0.05 mrad, the σ stated to the fit. Points: a "
        "tracker; pose: 6-D poses of a target; markers: three markers on the flange; sockets: a 50 mm "
        "two-socket plate at 6 places, 25 seats per socket; planes: contacts with four planes, two known; "
        "mixed: 40 tracker poses and the sockets at 10 seats each. Ratio: validation RMS over its Cramér–Rao "
        "prediction at the stated σ, on 200 new poses with rigid motions projected out (markers: the first "
        "marker; planes: 60 new contacts); 1 is the best any unbiased estimator does. |z|: the set-up "
        "parameters that have a truth (the 6-D target's rotation, the socket points) against their σ."),
        ["robot", "kind", "seeds", "mean ratio", "min ratio", "max ratio", "set-up z-scores", "largest |z|"],
        widths=[12, 10], align="llrrrrrr")
    for label, robot in robots.items():
        for kind in KINDS:
            ratios, z = [], []
            for seed in range(seeds):
                ratio, zs = kind_trial(robot, kind, seed)
                ratios.append(ratio)
                z += zs
            table.row(label, "sockets" if kind == "same-point" else kind, seeds, f"{np.mean(ratios):.3f}",
                      f"{min(ratios):.3f}", f"{max(ratios):.3f}", len(z), f"{np.max(np.abs(z)):.2f}" if z else "—")
    table.close()


def main() -> None:
    args = arguments()
    kinds = 0
    if "--kinds" in args:
        i = args.index("--kinds")
        kinds, args = int(args[i + 1]), args[:i] + args[i + 2:]
    run(int(args[0]) if args else 20)
    if kinds:
        print()
        run_kinds(kinds)


if __name__ == "__main__":
    main()
