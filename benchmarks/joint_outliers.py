"""False alarms of the outlier rule on a joint-space residual: clean simulated hexapod poses (80 per calibration, as
``kincal simulate hexapod --perturb --poses 80 --type pose --seed S`` writes them, legs read exactly), fitted with
``--residual joint``, and the share of calibrations that name an outlier sample; then one pose moved 5 mm or turned
20 mrad, and how often that row is named. Not a test: run it on two versions to compare their rules.

    python benchmarks/joint_outliers.py [--seeds 100]
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import kincal
from kincal.cli import main as kincal_main
from kincal.identify import fit_observations
from kincal.observe import ObservationFormat, read_observations

REV = 2 * np.pi  # rad per motor revolution, the legs' reading unit
SCENARIOS = [  # name, position noise simulated (mm), σ stated: legs (rev; None: the default), positions (mm)
    ("poses 0.1 mm, 1 mrad, stated so; legs' σ default", 0.1, None, 0.1),
    ("poses 0.015 mm, 1 mrad, stated so", 0.015, None, 0.015),
    ("poses 0.015 mm stated 0.1 mm", 0.015, None, 0.1),
    ("poses 0.015 mm stated 0.1 mm; legs stated 0.006 rev", 0.015, 0.006, 0.1),
]
BAD = 28  # the sample moved or turned


def simulated(folder: Path, seed: int, noise_mm: float):
    """The poses ``kincal simulate`` writes for ``seed``, read back as a pose set."""
    path = folder / f"poses_{seed}_{noise_mm:g}.csv"
    with contextlib.redirect_stdout(io.StringIO()):
        kincal_main(["simulate", "hexapod", "--perturb", "--poses", "80", "--type", "pose", "-o", str(path),
                     "--seed", str(seed), "--noise", str(noise_mm)])
    return read_observations(str(path), kincal.load_robot("hexapod"), ObservationFormat("pose"))


def named(obs, std_joint: float | None) -> list[int]:
    """The rows the verdict names as outliers."""
    res = fit_observations(kincal.load_robot("hexapod"), [obs], residual="joint",
                           joint_std=None if std_joint is None else std_joint * REV)
    return [int(obs.rows[i]) for i in res.outliers[0]]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    seeds = range(ap.parse_args().seeds)
    print(f"{'clean calibrations (80 poses each) naming an outlier':<58} {'named':>10}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, noise, legs, pos in SCENARIOS:
            hits = sum(bool(named(dataclasses.replace(simulated(Path(tmp), s, noise), std_pos=pos * 1e-3), legs))
                       for s in seeds)
            print(f"{name:<58} {hits:>4} / {len(seeds)}")
        found = {"moved 5 mm": [0, 0], "turned 20 mrad": [0, 0]}  # named, named alone
        for s in seeds:
            obs = dataclasses.replace(simulated(Path(tmp), s, 0.015), std_pos=0.015e-3)  # the σ stated so
            xyz, R = obs.xyz.copy(), obs.R.copy()
            xyz[BAD, 0] += 5e-3
            R[BAD] = Rotation.from_rotvec([0.0, 0.02, 0.0]).as_matrix() @ R[BAD]
            for how, bad in (("moved 5 mm", dataclasses.replace(obs, xyz=xyz)), ("turned 20 mrad",
                                                                                 dataclasses.replace(obs, R=R))):
                rows = named(bad, None)
                found[how][0] += int(obs.rows[BAD]) in rows
                found[how][1] += rows == [int(obs.rows[BAD])]
    for how, (hit, alone) in found.items():
        print(f"{f'one pose {how} (0.015 mm stated): named, named alone':<58} {hit:>4} / {len(seeds)} {alone:>4}")


if __name__ == "__main__":
    main()
