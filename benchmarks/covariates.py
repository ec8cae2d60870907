"""Warm-up drift and the thermal covariate term (issue 35, acceptance 4): prints a table.

    python benchmarks/covariates.py [--repeats 10] [--poses 120] [--auto] [--docs]

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
variance that 60 noisy poses barely pay for). "refused" checks that a held-out pose 50 % of the range
above it is refused.
Scenarios: every link at 23e-6/K ("uniform"), and the base column (j1) warming twice as much as the
rest ("warm base"). With ``--auto`` the model ``auto`` also chooses, and a session with the same
temperatures but no growth shows whether it keeps the term without a drift (it should not).
With ``--docs`` (or KINCAL_DOCS_TABLES=folder) the table and a summary per scenario are also written for
the documentation site.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import kincal
from _docs_table import Table
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


def tables(args: argparse.Namespace) -> tuple[Table, Table]:
    """The table of every session and the summary per scenario."""
    protocol = (
        f"Simulated UR5 with random geometric errors, {args.repeats} sessions (seeds 0 to {args.repeats - 1}) per "
        f"scenario of {args.poses} random poses measured while it warms up (T = 20 °C + rise·(1 − exp(−k/τ)), "
        "τ a third of the session; the rise chosen so that the farthest pose drifts by 0.3 mm), its links "
        "growing by 23e-6 per K (uniform), or the base column twice as much (warm base); 15 µm tracker noise. "
        "Two models fitted: geometric, and geometric + thermal:temperature. Judged on 40 other poses at "
        "temperatures inside the fitted range against the drift-free truth: RMS of the 3-D error, mm. "
        "Removed: the share of the geometric model's error the term removes (acceptance: 80 % or more). "
        "Floor: the geometric model fitted to the same poses without any growth, judged the same way (what "
        "noise alone leaves). Refused: a held-out temperature 50 % of the range above it is refused."
        + (" Auto: what error_model='auto' chose on the session, and on the same session without growth."
           if args.auto else ""))
    auto = ["auto", "auto, no drift"] if args.auto else []
    every = Table("covariates", "Warm-up drift and the thermal term: every session", protocol,
                  ["scenario", "seed", "rise K", "drift mm", "geometric mm", "thermal mm", "removed", "floor mm",
                   "refused", *auto], widths=[10, 4, 7, 9, 13, 11, 8, 9, 8, 22, 22],
                  align="lrrrrrrrr" + "ll" * bool(auto))
    summary = Table("covariates_summary", "Warm-up drift and the thermal term: per scenario", protocol,
                    ["scenario", "sessions", "removed, median", "removed, worst", "geometric mm", "thermal mm",
                     "floor mm", "refused", *(["auto kept the term", "auto kept it without drift"] if auto else [])],
                    widths=[10, 8, 15, 14, 13, 13, 13, 7])
    return every, summary


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--poses", type=int, default=120)
    p.add_argument("--auto", action="store_true", help="also let 'auto' choose (with and without a drift)")
    p.add_argument("--docs", action="store_true", help="also write the tables for the documentation site")
    args = p.parse_args()
    scenarios = {"uniform": ALUMINIUM, "warm base": {"j1": 2 * ALUMINIUM, **{f"j{i}": ALUMINIUM for i in range(2, 7)}}}
    every, summary = tables(args)
    print(f"UR5, {args.poses} warm-up poses, 40 held-out poses inside the range, 15 µm noise; RMS vs drift-free truth")
    results = {}
    for name, alpha in scenarios.items():
        removed, runs = [], []
        for seed in range(args.repeats):
            r = trial(seed, args.poses, alpha, args.auto)
            runs.append(r)
            removed.append(1.0 - r["thermal:temperature"] / r["geometric"])
            every.row(name, seed, f"{r['rise']:.2f}", f"{r['drift'] * 1e3:.4f}", f"{r['geometric'] * 1e3:.4f}",
                      f"{r['thermal:temperature'] * 1e3:.4f}", f"{removed[-1]:.1%}", f"{r['floor'] * 1e3:.4f}",
                      r["refused"], *([r["auto"], r["auto, no drift"]] if args.auto else []))
        print(f"{name:<10} removed: median {np.median(removed):.1%}, worst {min(removed):.1%} (acceptance: >= 80 %)")
        results[name] = (removed, runs)
    every.close()
    print()
    for name, (removed, runs) in results.items():
        summary.row(*_summary(name, removed, runs, args.auto))
    summary.close()


def _summary(name: str, removed: list[float], runs: list[dict], auto: bool) -> list[str]:
    """One scenario's row: the share removed, the ranges of the three errors (mm), the counts."""
    span = lambda key: f"{min(r[key] for r in runs) * 1e3:.4f}–{max(r[key] for r in runs) * 1e3:.4f}"  # noqa: E731
    n = len(runs)
    row = [name, str(n), f"{np.median(removed):.1%}", f"{min(removed):.1%}", span("geometric"),
           span("thermal:temperature"), span("floor"), f"{sum(r['refused'] == 'yes' for r in runs)}/{n}"]
    if auto:
        row += [f"{sum('thermal' in r['auto'] for r in runs)}/{n}",
                f"{sum('thermal' in r['auto, no drift'] for r in runs)}/{n}"]
    return row

if __name__ == "__main__":
    main()
