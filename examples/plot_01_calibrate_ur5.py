"""
Calibrate a UR5 from laser-tracker data
=======================================

A UR5 was measured by a laser tracker at 1000 poses on a grid over its workspace, and at 20 random poses
that the calibration never sees. kincal fits the robot's geometric parameters to the grid, says whether it
trusts the result (the verdict), and the random poses tell how well the calibrated model predicts where
the robot really goes. All figures are in millimetres and degrees; inside, kincal works in metres and
radians.
"""

# %%
# The robot and the data
# ----------------------
#
# ``kincal.load_robot("ur5")`` is the bundled UR5 with Universal Robots' published DH values; its tool
# point is the tracker's reflector on the flange, where the data set declares it. The measurement files
# have one row per pose: the six joint angles in degrees (columns ``joint_1`` … ``joint_6``) and the
# reflector's position in millimetres. ``read_measurements`` converts them to SI units and refuses data
# whose scale does not fit the robot (a wrong unit, a wrong column).

import os
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import kincal
from kincal.units import display

# the repository's root, relative to the working folder so that printed file names stay short
# (sphinx-gallery runs an example in its own folder, without __file__)
ROOT = Path(os.path.relpath(Path(__file__).resolve().parents[1])) if "__file__" in globals() else Path("..")
# the real datasets, used where they are: beside the checkout, or where KINCAL_SHARED_DATASETS points
DATASETS = Path(os.environ.get("KINCAL_SHARED_DATASETS", ROOT / ".." / "shared" / "datasets"))
DATA = DATASETS / "ur5_wam_gts3800"
if not DATA.is_dir():  # a copy of this example elsewhere: the datasets are not where it looks
    raise SystemExit(f"{DATA}: no such folder; set KINCAL_SHARED_DATASETS to the folder that holds kincal's datasets "
                     f"(shared/datasets beside the checkout)")
JOINTS = [f"joint_{k}" for k in range(1, 7)]

robot = kincal.load_robot("ur5")
grid = kincal.read_measurements(DATA / "ur5_grid.csv", robot, joint_cols=JOINTS, length_unit="mm", angle_unit="deg")
test = kincal.read_measurements(DATA / "ur5_random.csv", robot, joint_cols=JOINTS, length_unit="mm",
                                angle_unit="deg")
print(f"{robot.name}: {robot.n_joints} joints, {len(robot.params)} model parameters")
print(f"calibration poses: {len(grid)}, held-out poses: {len(test)}")

# %%
# Calibrate
# ---------
#
# ``kincal.calibrate`` registers the tracker's frame to the robot (the six ``base`` parameters), then
# fits the kinematics and the frame together. It estimates only what the poses can identify: for a UR5
# measured by positions some parameters act exactly like others (a joint offset along an axis like the
# tool point's height), so they are left at their nominal values and the ones kept carry their effect.
#
# The printed summary has one row per estimated parameter: its value, its correction from the nominal
# model and its standard deviation σ. Then come the training errors before and after, the residual σ
# per axis against the tracker's noise, the *mounting* line (where the data put the reflector against
# where it was declared: a set-up result, not a robot error) and the **verdict**. A verdict ``good``
# means no limit was crossed: the corrections are of a plausible size, the residual is of the order of
# the tracker's noise, no pose stands out.

result = kincal.calibrate(robot, grid)
print(result)

# %%
# Validate on poses the fit never saw
# -----------------------------------
#
# The random poses were measured in the same tracker set-up as the grid, so the calibrated model is
# judged in the training frame, as it is (``kincal.evaluate`` without ``rebase``). Three models are
# compared on them:
#
# * the nominal model as declared: it carries the reflector where the data set says it is;
# * "before": the nominal kinematics with the tracker frame and the reflector registered to the
#   training data (``result.before``), which is what the robot's own geometry is worth;
# * the calibrated model, with the model's predicted σ at these poses from the fit's covariance
#   (``result.uncertainty()``).
#
# The printed gap between the first two lines is mostly the mounting (the reflector sits away from where
# it was declared); the gap between the last two is what the calibration of the robot's geometry gains.

declared = kincal.evaluate(robot, test)
before = kincal.evaluate(result.before, test)
after = kincal.evaluate(result.robot, test, uncertainty=result.uncertainty())
print(f"nominal, as declared:                   mean {declared.mean * 1e3:.3f} mm, max {declared.max * 1e3:.3f} mm")
print(f"nominal, frame and reflector registered: mean {before.mean * 1e3:.3f} mm, max {before.max * 1e3:.3f} mm")
print(f"calibrated:                             mean {after.mean * 1e3:.3f} mm, max {after.max * 1e3:.3f} mm")
print(after)

# %%
# The calibrated model keeps its training error on unseen poses: compare the printed held-out mean with
# the training mean ("after") in the summary above. A held-out error many times the training error
# would mean the model learnt the grid rather than the robot.
#
# The last lines give the model's predicted σ at the held-out poses: what the uncertainty of the
# parameters alone makes of a prediction. It is far below the held-out error, which is set by what a
# geometric model cannot describe (the robot's repeatability, the joints' give under load, the
# tracker's noise), not by how well the grid determined the parameters.
#
# Where the errors lie
# --------------------
#
# Left: the 3-D position error of every training pose, before and after. Right: the held-out poses
# sorted by their error before calibration, with the calibrated model's error beside each. Before
# calibration the errors spread widely, because the geometry errors act differently in every pose;
# after calibration they shrink to a narrow band near the tracker's noise and the robot's
# repeatability, which no geometric model can remove.

train_before = np.linalg.norm(result.measurements.xyz - result.before.forward(result.measurements.q), axis=1)
train_after = np.linalg.norm(result.residuals, axis=1)
test_before = np.linalg.norm(test.xyz - result.before.forward(test.q), axis=1)
test_after = np.linalg.norm(test.xyz - result.robot.forward(test.q), axis=1)

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
bins = np.linspace(0.0, max(train_before.max(), train_after.max()) * 1e3, 50)
ax1.hist(train_before * 1e3, bins=bins, alpha=0.6, label="before (nominal, registered)")
ax1.hist(train_after * 1e3, bins=bins, alpha=0.8, label="after (calibrated)")
ax1.set(xlabel="position error (mm)", ylabel="poses", title=f"{len(grid)} training poses")
ax1.legend()
order = np.argsort(test_before)[::-1]
x = np.arange(len(order))
ax2.bar(x - 0.2, test_before[order] * 1e3, width=0.4, label="before (nominal, registered)")
ax2.bar(x + 0.2, test_after[order] * 1e3, width=0.4, label="after (calibrated)")
ax2.set(xlabel="held-out pose: its row in the file (sorted by the error before)", ylabel="position error (mm)",
        title=f"{len(test)} held-out poses, same tracker set-up")
ax2.set_xticks(x, [str(r) for r in test.rows[order]], fontsize=7)
ax2.legend()
fig.tight_layout()
plt.show()

# %%
# The result is a robot
# ---------------------
#
# ``result.robot`` is a robot like any other. Saved with the calibration's record,
# ``kincal.save_robot(result.robot, "ur5_cal.yaml", calibration=result.record())``, the file holds its
# covariance too (its ``calibration:`` section, as ``kincal calibrate -o`` writes it); saved without
# ``calibration=`` it holds the parameters only, and ``kincal evaluate`` then predicts no σ.
# ``kincal.export_robot`` turns it into a URDF or UR's kinematics file. The
# largest corrections of the arm itself (the tracker frame and the reflector left aside), lengths and
# angles apart, each with its σ:

kinds = dict(zip(robot.params.names, robot.params.kinds))
arm = {n: v for n, v in result.corrections.items() if not n.startswith(("base.", "tool."))}
for kind in ("length", "angle"):
    mine = sorted((n for n in arm if kinds[n] == kind), key=lambda n: -abs(arm[n]))
    for name in mine[:3]:
        print(f"{name:<10} {display(arm[name], kind):>14}  ± {display(result.std[name], kind, signed=False)}")
