"""
Calibrate a Panda with a ball in plate sockets
==============================================

No tracker, no camera: a ball on a Franka Panda's flange was seated by hand in the two sockets of a
printed plate, 50 mm apart, in many arm configurations, and the plate was put at 8 places on the table
(MUKCa, Franzese et al. 2025, "MUKCa: Accurate and Affordable Cobot Calibration Without External
Measurement Devices"). Nothing measures where the ball is. What the data say is that every configuration
of one socket puts the ball at the same unknown point, and that the two points of a placement are 50 mm
apart. kincal's ``same-point`` measurement turns that into a calibration; as the authors did, it is
trained on one placement and judged on the other seven.
"""

# %%
# The robot and the samples
# -------------------------
#
# The nominal model is the MUKCa authors' Panda URDF with the ball as link ``ball_link`` (a copy ships
# with kincal's test data); their own calibration of this robot is in the data folder, for comparison. The samples file
# has the seven joint angles in radians, the socket (0 or 1) and the placement of the plate. An
# :class:`~kincal.observe.ObservationFormat` says how to read it: the socket column labels the points,
# the placement groups them (a socket at another placement is another point), and the distance between
# sockets 0 and 1 is known inside every placement. ``describe`` prints what such a file holds and what
# the fit adds to the robot's parameters.

import dataclasses
import os
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import kincal
from kincal.identify import fit_observations
from kincal.observe import ObservationFormat, describe, read_observations

# the repository's root, relative to the working folder so that printed file names stay short
# (sphinx-gallery runs an example in its own folder, without __file__)
ROOT = Path(os.path.relpath(Path(__file__).resolve().parents[1])) if "__file__" in globals() else Path("..")
# the real datasets, used where they are: beside the checkout, or where KINCAL_SHARED_DATASETS points
DATASETS = Path(os.environ.get("KINCAL_SHARED_DATASETS", ROOT / ".." / "shared" / "datasets"))
DATA = DATASETS / "panda_sockets"
if not DATA.is_dir():  # a copy of this example elsewhere: the datasets are not where it looks
    raise SystemExit(f"{DATA}: no such folder; set KINCAL_SHARED_DATASETS to the folder that holds kincal's datasets "
                     f"(shared/datasets beside the checkout)")
URDF = DATA / "panda.urdf"

robot = kincal.load_robot(URDF, tip_link="ball_link")
authors = kincal.load_robot(DATA / "panda_2_calibrated_by_authors.urdf", tip_link="ball_link")
fmt = ObservationFormat(kind="same-point", joint_cols=tuple(f"q{k}" for k in range(1, 8)), length_unit="mm",
                        label_col="socket", group_col="placement", distances=(("0", "1", 50.0),))
samples = read_observations(DATA / "samples.csv", robot, fmt)
print("\n".join(describe(robot, fmt)))
placements = list(dict.fromkeys(samples.group.tolist()))
print(f"{len(samples)} samples at {len(placements)} placements:",
      ", ".join(f"{p} ({np.sum(samples.group == p)})" for p in placements))

# %%
# Train on one placement, test on the others
# ------------------------------------------
#
# The authors' protocol: fit on the plate's ``front_center`` placement, judge the model on the seven
# others, which it has never seen. A part of the samples is taken with ``subset``; the known distances
# of the placements left out go with them.


def placement_set(obs, keep):
    """The samples where ``keep`` holds, with the known distances of their own placements only."""
    part = obs.subset(np.flatnonzero(keep))
    have = set(part.labels.tolist())
    return dataclasses.replace(part, distances=tuple(d for d in part.distances if d[0] in have and d[1] in have))


front = samples.group == "front_center"
train, test = placement_set(samples, front), placement_set(samples, ~front)
print(f"training: {len(train)} samples at 1 placement; test: {len(test)} samples at {len(placements) - 1}")

# %%
# The fit
# -------
#
# ``fit_observations`` fits the robot's joint origins together with the set-up parameters the data
# bring: the two socket points. Read the printed summary for three things the socket data imply.
#
# * **Gauge freedoms.** Sockets never say where the robot stands on the table, so its base frame is not
#   seen and is left where it is (named on the "not seen" line).
# * **The scale comes from the 50 mm.** Without a known distance a robot shrunk towards a point would
#   satisfy "the same point" just as well; kincal refuses such a fit.
# * **A learned prior.** One placement is a small region: it determines a full model, but with large
#   correlated corrections that extrapolate badly. kincal learns from the data how far each joint
#   origin's lengths and angles may move (MacKay's automatic relevance determination) and holds at
#   nominal the groups the data do not confirm; the summary names them (in the table they show a zero
#   correction and a zero σ) and gives the others' prior σ.
#   Parameters the data see worse than a real robot's error are kept nominal and named too.

fit = fit_observations(robot, [train])
print(fit)

# %%
# Judged on the seven other placements
# ------------------------------------
#
# The authors' two figures per placement: the *consistency* (mean distance of the predicted ball
# centres from their socket's mean, all samples of both sockets) and the *distance error* (how far the
# two socket means are from 50 mm). ``fit.held_out`` computes them for any model; the same numbers are
# printed for the nominal URDF, the authors' calibrated URDF, kincal's fit, and kincal's fit without the
# learned prior (plain least squares, ``prior="none"``).

plain = fit_observations(robot, [train], prior="none")
models = {"nominal URDF": robot, "authors' calibration": authors, "kincal": fit.robot,
          "kincal, least squares": plain.robot}
held = {name: fit.held_out(test, model) for name, model in models.items()}
print(f"{'model':<22} {'training consistency':>21} {'test consistency':>17} {'test distance error, mean / max':>33}")
for name, stats in held.items():
    trained = fit.held_out(train, models[name])["mean_abs"] * 1e3
    dist = np.array([g["distance_error"] for g in stats["groups"]]) * 1e3
    print(f"{name:<22} {trained:18.3f} mm {stats['mean_abs'] * 1e3:14.3f} mm {dist.mean():19.3f} / {dist.max():.3f} mm")

# %%
# The learned prior pays on the placements it did not see. Plain least squares fits the training
# placement at least as well (compare the training column), but it also moves the parameters that
# one placement cannot confirm, and those corrections extrapolate: its test consistency is the worse of
# the two. Read the consistency together with the distance error: consistency alone would reward a
# shrunk robot, the distance error shows that the scale carried over to the other placements.
#
# Per placement
# -------------
#
# Each test placement, for the nominal model and the three calibrations, on a logarithmic axis so that
# the nominal model's millimetres and the calibrations' tenths fit in one figure. The consistency of
# the calibrations is even over the placements, near and far from the training one; the distance
# error, a single number per placement, scatters more from one placement to the next.

test_places = [g["group"] for g in held["kincal"]["groups"]]
x = np.arange(len(test_places))
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
for k, (name, stats) in enumerate(held.items()):
    groups = {g["group"]: g for g in stats["groups"]}
    ax1.bar(x + (k - 1.5) * 0.2, [groups[p]["mean_abs"] * 1e3 for p in test_places], width=0.2, label=name)
    ax2.bar(x + (k - 1.5) * 0.2, [groups[p]["distance_error"] * 1e3 for p in test_places], width=0.2, label=name)
ax1.set(yscale="log", ylabel="consistency: mean |p − socket mean| (mm)", title="consistency per test placement")
ax2.set(yscale="log", ylabel="| socket distance − 50 mm | (mm)", title="distance error per test placement")
for ax in (ax1, ax2):
    ax.set_xticks(x, test_places, rotation=30, ha="right")
fig.legend(*ax1.get_legend_handles_labels(), loc="upper center", ncol=4)
fig.tight_layout(rect=(0, 0, 1, 0.92))
plt.show()
