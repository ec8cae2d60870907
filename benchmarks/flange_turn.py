"""Whose flange turn pose commands should follow after a calibration from points: prints a table.

    python benchmarks/flange_turn.py [--seeds 6]

Simulated robots with their true errors, calibrated from the positions of one measured point; for each, 30 pose
targets in the calibration's joint ranges are compensated twice (the flange turned as the calibrated model turns
it, and as the nominal model does) and the true flange's RMS rotation from the targets is measured (mrad). Three
rules decide between the two: the calibrated turn is followed when it is at least 3σ, with σ

* "covariance": the calibration's covariance alone;
* "held direct": that, and each parameter held at nominal as too weakly determined with its recorded σ as an
  independent turn (the rule of an earlier kincal);
* "kincal": :func:`kincal.compensate.flange_turn` (the covariance, and the turn the estimated parameters made
  by taking up the real errors of those kept at nominal, beyond those parameters' own turns).

Cases: the README's UR5 (its estimates from the real data ``ur5_wam_gts3800/ur5_grid.csv``, the parameters it
keeps at nominal off by up to 0.05° and 0.5 mm, or 0.29°: "big"; its 1000 joint vectors, 65 µm noise); a UR5
measured 31 mm out on the flange's axis, and 120 mm out off it; a FANUC LR Mate 30 mm out on the axis at 100
poses within ±0.25 or ±1 rad of one pose; a KR 6 50 mm out on the axis, and 150 mm out off it (default errors,
200 poses, 15 µm). Per case the mean over the seeds: followed, nominal, the better of the two, and what each rule
chose, and how often kincal followed.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from shared_data import shared_dataset  # noqa: E402

CASES = ("ur5 README", "ur5 README big", "ur5 31 mm on axis", "ur5 120 mm lever", "lrmate ±0.25 rad",
         "lrmate ±1 rad", "kr6 50 mm on axis", "kr6 150 mm lever")


def _readme(kincal, seed: int, angle: float):
    """The README's UR5 as a true robot: its calibration's estimates, the rest off nominal; and its joints."""
    ur5 = kincal.load_robot("ur5")
    meas = kincal.read_measurements(shared_dataset("ur5_wam_gts3800") / "ur5_grid.csv", ur5,
                                    joint_cols=[f"joint_{i}" for i in range(1, 7)], length_unit="mm", angle_unit="deg")
    real = kincal.calibrate(ur5, meas, kincal.FitOptions(diagnose=False))
    rng = np.random.default_rng(seed)
    kept = {n: ur5.params[n] + rng.uniform(-1, 1) * (0.5e-3 if k == "length" else angle)
            for n, k in zip(ur5.params.names, ur5.params.kinds) if n not in real.names and n not in ur5.base_params()}
    true = real.robot.with_params({**{n: ur5.params[n] for n in ur5.base_params()}, **kept})
    return ur5.with_tool_point(real.robot.tool_point()), true, meas.q, 65e-6


def _case(kincal, label: str, seed: int):
    """(nominal, true, calibration joints, noise m) of a case."""
    if label.startswith("ur5 README"):
        return _readme(kincal, seed, np.deg2rad(0.29 if label.endswith("big") else 0.05))
    tool = {"ur5 31 mm on axis": [0, 0, 0.031], "ur5 120 mm lever": [0.03, -0.02, 0.12], "kr6 50 mm on axis":
            [0, 0, 0.05], "kr6 150 mm lever": [0.02, -0.01, 0.15]}.get(label, [0, 0, 0.03])
    name = "ur5" if label.startswith("ur5") else "kuka_kr6r900sixx" if label.startswith("kr6") else "fanuc_lrmate200id"
    nominal = kincal.load_robot(name).with_tool_point(tool)
    q = nominal.sample_joints(200, seed=seed + 100)
    if label.startswith("lrmate"):
        span = 0.5 if "0.25" in label else 2.0
        q = np.random.default_rng(seed + 10).random((100, 6)) - 0.5
        q = np.clip(np.radians([0, 10, 0, 0, -30, 0]) + q * span, nominal.lower, nominal.upper)
    return nominal, kincal.perturb(nominal, seed=seed), q, 15e-6


def _errors(kincal, fit, nominal, true):
    """The true flange's RMS rotation from 30 targets (mrad): commands following the calibrated turn, the nominal."""
    from kincal.compensate import command_models, compensate_poses
    from kincal.models.transforms import rotation_log
    unc = fit.uncertainty()
    model, nom = command_models(fit.robot, nominal.params.as_dict(), frame="measurement")
    qt = unc.lower + np.random.default_rng(7).random((30, nominal.n_joints)) * (unc.upper - unc.lower)
    p, R = nom.forward(qt), nom.flange_rotation(qt)
    runs = [compensate_poses(model, p, R, qt, nominal=nom, orientation=o) for o in (None, nom)]
    ok = runs[0].ok & runs[1].ok
    return [1e3 * float(np.sqrt(np.mean(np.sum(rotation_log(true.flange_rotation(r.q[ok]) @ np.swapaxes(
        R[ok], 1, 2)) ** 2, axis=1)))) for r in runs]


def _rules(kincal, fit, nominal) -> dict:
    """Whether each rule follows the calibrated turn."""
    from kincal.compensate import flange_turn
    from kincal.compensate.turn import TURN_Z, _sigma, _turn_jacobian, poses_in
    unc = fit.uncertainty()
    turn = flange_turn(fit.robot, nominal, unc.covariance, unc.names, unc.lower, unc.upper)
    q = poses_in(fit.robot, unc.lower, unc.upper, nominal)
    alone = _sigma(fit.robot, q, unc.covariance, tuple(unc.names))
    held = list(fit.weak)
    direct = alone**2 + sum(fit.weak[n] ** 2 * float(np.mean(np.sum(_turn_jacobian(fit.robot, q, [n]) ** 2, axis=1)))
                            for n in held)
    return {"covariance": turn.change >= TURN_Z * alone, "held direct": turn.change >= TURN_Z * np.sqrt(direct),
            "kincal": turn.determined}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=6)
    args = parser.parse_args()
    import kincal
    print("| case | followed | nominal | better | covariance | held direct | kincal | kincal follows |")
    print("|---|---|---|---|---|---|---|---|")
    for label in CASES:
        rows = []
        for seed in range(args.seeds):
            nominal, true, q, noise = _case(kincal, label, seed)
            fit = kincal.calibrate(nominal, kincal.simulate(true, q, noise, seed), kincal.FitOptions(diagnose=False))
            follow, kept = _errors(kincal, fit, nominal, true)
            rules = _rules(kincal, fit, nominal)
            rows.append([follow, kept, min(follow, kept), *[follow if rules[k] else kept for k in rules],
                         rules["kincal"]])
        m = np.mean(np.array(rows, float), axis=0)
        print(f"| {label} | " + " | ".join(f"{v:.2f}" for v in m[:6]) + f" | {int(m[6] * len(rows))}/{len(rows)} |")


if __name__ == "__main__":
    main()
