"""Warm-up drift and the thermal covariate term (issue 35, acceptance 4): prints a table.

    python benchmarks/covariates.py [--repeats 10] [--poses 120] [--auto]

A UR5 with random geometric errors (``perturb``) is measured over one session of ``--poses`` random
poses while it warms up, T = 20 + rise·(1 − exp(−k/τ)), τ a third of the session, its aluminium links
growing by 23e-6 per K (``kincal.simulate.simulate_thermal``: each sample on its own grown robot) with
15 µm tracker noise; the rise is chosen so that the farthest training pose drifts by 0.3 mm over the
session. Two error models are fitted to that session: geometric (it absorbs the mean growth) and
geometric + ``thermal:temperature``. Both are judged on 40 other poses at temperatures drawn inside the
fitted range, against the drift-free truth (the true robot at each held-out temperature, no noise):
held-out RMS error, and the share of the geometric model's error the covariate term removes
(acceptance: ≥ 80 %); "floor": the geometric model fitted to the same poses and temperatures without
any growth, judged the same way — what noise alone leaves. A warm-up lasts the first 100–150 poses
of a real session, hence 120 by default (with 60 the share is 73–86 %: the term's 6 rates cost
variance that 60 noisy poses barely pay for). "refused" checks that a held-out pose 50 % of the range above it is refused.
Scenarios: every link at 23e-6/K ("uniform"), and the base column (j1) warming twice as much as the
rest ("warm base"). With ``--auto`` the model ``auto`` also chooses, and a session with the same
temperatures but no growth shows whether it keeps the term without a drift (it should not).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import kincal
from kincal.errors import ModelError
from kincal.models import with_covariates
from kincal.simulate import ALUMINIUM, link_growth, simulate_thermal, warm_up

DRIFT = 0.3e-3  # m


def trial(seed: int, poses: int, alpha, auto: bool) -> dict:
    nominal = kincal.load_robot("ur5")
    true = kincal.perturb(nominal, seed=seed)
    q = nominal.sample_joints(poses, seed=1000 + seed)
    rise = DRIFT / np.linalg.norm(true.param_jacobian(q) @ link_growth(true, alpha), axis=1).max()
    train = simulate_thermal(true, q, warm_up(poses, 20.0, rise), alpha, 20.0, seed=seed)
    qh = nominal.sample_joints(40, seed=2000 + seed)
    Th = np.random.default_rng(seed).uniform(20.0, 20.0 + rise, 40)
    held = simulate_thermal(true, qh, Th, alpha, 20.0, noise=0.0)
    cold = simulate_thermal(true, qh, np.full(40, 20.0), alpha, 20.0, noise=0.0)
    robot = with_covariates(nominal, ["temperature"])
    out: dict = {"rise": rise, "drift": _rms(held.xyz - cold.xyz)}
    for model in ("geometric", "thermal:temperature"):
        t0 = time.perf_counter()
        fitted = kincal.calibrate(robot, train, error_model=model, diagnose=False).robot
        out[model] = _rms(fitted.forward(held.q) - held.xyz)
        out[model + " s"] = time.perf_counter() - t0
    hot = held.q.copy()
    hot[:, -1] = 20.0 + 1.5 * rise
    try:
        fitted.forward(hot)
        out["refused"] = "no"
    except ModelError:
        out["refused"] = "yes"
    still = simulate_thermal(true, q, train.q[:, -1], 0.0, 20.0, seed=seed)  # the same session, no growth
    out["floor"] = _rms(kincal.calibrate(robot, still, error_model="geometric", diagnose=False).robot.forward(held.q)
                        - cold.xyz)
    if auto:
        out["auto"] = kincal.calibrate(robot, train, error_model="auto", diagnose=False).error_model_choice.chosen
        out["auto, no drift"] = kincal.calibrate(robot, still, error_model="auto",
                                                 diagnose=False).error_model_choice.chosen
    return out


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--poses", type=int, default=120)
    p.add_argument("--auto", action="store_true", help="also let 'auto' choose (with and without a drift)")
    args = p.parse_args()
    scenarios = {"uniform": ALUMINIUM, "warm base": {"j1": 2 * ALUMINIUM, **{f"j{i}": ALUMINIUM for i in range(2, 7)}}}
    head = (f"{'scenario':<10} {'seed':>4} {'rise K':>7} {'drift mm':>9} {'geometric mm':>13} {'thermal mm':>11} "
            f"{'removed':>8} {'floor mm':>9} {'refused':>8}" + (f" {'auto':<22} {'auto, no drift':<22}" if args.auto else ""))
    print(f"UR5, {args.poses} warm-up poses, 40 held-out poses inside the range, 15 µm noise; RMS vs drift-free truth")
    print(head)
    for name, alpha in scenarios.items():
        removed = []
        for seed in range(args.repeats):
            r = trial(seed, args.poses, alpha, args.auto)
            removed.append(1.0 - r["thermal:temperature"] / r["geometric"])
            print(f"{name:<10} {seed:>4} {r['rise']:7.2f} {r['drift'] * 1e3:9.4f} {r['geometric'] * 1e3:13.4f} "
                  f"{r['thermal:temperature'] * 1e3:11.4f} {removed[-1]:8.1%} {r['floor'] * 1e3:9.4f} {r['refused']:>8}"
                  + (f" {r['auto']:<22} {r['auto, no drift']:<22}" if args.auto else ""))
        print(f"{name:<10} removed: median {np.median(removed):.1%}, worst {min(removed):.1%} (acceptance: >= 80 %)")


if __name__ == "__main__":
    main()
