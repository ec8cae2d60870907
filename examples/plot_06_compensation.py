"""
Compensate targets and a robot program
======================================

A calibrated model is of no use to a controller that moves with its own nominal kinematics, unless the
commands change: ``kincal.compensate`` finds, for each target, the joint command at which the *real*
robot (the calibrated model) lands where the nominal model promised. Here a simulated UR5 stands in for
the real one, so the commands can be sent to the "true" robot and the errors that remain measured.
The last part compensates a short URScript program in place.
"""

# %%
# A robot, its calibration
# ------------------------
#
# The simulated tracker's reflector sits on an adapter 50 mm off the flange's axis and 100 mm out, so
# its positions also tell the flange's orientation. The true robot gets random errors of up to 0.5 mm
# and 0.05° on every parameter except joint 1's zero and height: tracker data cannot tell those from
# where the tracker stands (the calibration names them as acting like ``base.rz`` and ``base.z``), so
# in the robot's own base frame no calibration can correct them, and real targets are taught or
# defined relative to that frame anyway. Then 60 random poses are measured with 15 µm noise and
# calibrated.

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from scipy.spatial.transform import Rotation

import kincal
from kincal.compensate import command_models, compensate_program, solve_poses
from kincal.io import read_program, write_program

DEG = 180.0 / np.pi

nominal = kincal.load_robot("ur5").with_tool_point([0.05, 0.0, 0.10])
erred = [n for n in nominal.params.names if not n.startswith("base.") and n not in ("j1.theta", "j1.d")]
true = kincal.perturb(nominal, seed=7, names=erred)
result = kincal.calibrate(nominal, kincal.simulate(true, nominal.sample_joints(60, seed=1), seed=2))
print(result.verdict)
print("training error after calibration:", result.stats_after)

# %%
# The models for commands
# -----------------------
#
# The calibrated model lives in the tracker's frame. ``command_models`` returns the calibrated model
# and the controller's (nominal) model, both in the robot's own base frame, for the point the targets
# are given for (here the reflector; ``tcp=`` names the controller's TCP when it is another point).

model, controller = command_models(result.robot, nominal.params.as_dict())

# %%
# Targets: a pick grid
# --------------------
#
# Twenty-five targets on a horizontal 300 mm square, the tool's orientation the same at each: a pallet
# the robot is to visit. The controller's commands for them (``q_nominal``) are its inverse kinematics
# on the nominal model, found here by :func:`~kincal.compensate.solve_poses` from a home pose.

home = np.deg2rad([0.0, -100.0, 110.0, -100.0, -90.0, 0.0])
p_home, R_home, _, _ = controller.pose_and_jacobian(home[None])
dx, dy = np.meshgrid(np.linspace(-0.15, 0.15, 5), np.linspace(-0.15, 0.15, 5))
targets = p_home + np.column_stack([dx.ravel(), dy.ravel(), np.zeros(dx.size)])
rotations = np.repeat(R_home, len(targets), axis=0)
q_nominal = solve_poses(controller, targets, rotations, np.repeat(home[None], len(targets), axis=0),
                        max_travel=1.0).q

# %%
# Compensate
# ----------
#
# Given target poses (``rotations=``), ``kincal.compensate`` solves all six components on the
# calibrated model, starting from the nominal commands, and checks every command: within reach, inside
# the joint limits, on the nominal command's branch (no joint moving more than a few degrees), model
# residual under 1 µm. Refused rows would be named in ``problems``.

comp = kincal.compensate(model, targets, q_nominal, rotations=rotations, nominal=controller)
print(f"{comp.method}: {int(comp.ok.sum())} of {len(targets)} commands accepted; problems: {list(comp.problems)}")
print(f"largest joint change: {np.abs(comp.q - q_nominal).max() * DEG:.4f} deg")


def true_errors(q):
    """Position (mm) and orientation (deg) errors of the true robot at commands q against the targets."""
    p, R, _, _ = true.pose_and_jacobian(q)
    angle = np.linalg.norm(Rotation.from_matrix(R @ rotations.transpose(0, 2, 1)).as_rotvec(), axis=1)
    return np.linalg.norm(p - targets, axis=1) * 1e3, angle * DEG


pos_before, rot_before = true_errors(q_nominal)
pos_after, rot_after = true_errors(comp.q)
print(f"position error, nominal commands:     mean {pos_before.mean():.4f} mm, max {pos_before.max():.4f} mm")
print(f"position error, compensated commands: mean {pos_after.mean():.4f} mm, max {pos_after.max():.4f} mm")
print(f"orientation error, nominal commands:     mean {rot_before.mean():.4f} deg")
print(f"orientation error, compensated commands: mean {rot_after.mean():.4f} deg")

# %%
# Sent to the true robot, the nominal commands miss every target by the robot's geometry errors, and
# differently at each: no constant offset could fix them. The compensated commands land within what
# the calibration left, at the level of its training error. The orientation error shrinks less than
# the position error: the tracker saw one point on the flange, so the fit knows the flange's
# orientation only through that point's lever, and what it could not determine stays.
#
# Left: the horizontal part of each target's position error, drawn 100 times larger; the compensated
# commands' arrows are too short to see at that scale. Right: each target's 3-D position error, on a
# logarithmic axis. The errors of the nominal commands change smoothly over the pallet: they are the
# robot's geometry, seen at neighbouring poses.

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.8), gridspec_kw={"width_ratios": [1, 1.4]})
tips = [targets[:, :2] * 1e3]
for q, color, label in ((q_nominal, "C0", "nominal commands"), (comp.q, "C3", "compensated")):
    err = (true.forward(q) - targets)[:, :2] * 1e3
    ax1.quiver(targets[:, 0] * 1e3, targets[:, 1] * 1e3, err[:, 0], err[:, 1], color=color, angles="xy",
               scale_units="xy", scale=0.01, width=0.006, label=label)
    tips.append(targets[:, :2] * 1e3 + 100.0 * err)
ax1.plot(targets[:, 0] * 1e3, targets[:, 1] * 1e3, "k.", ms=4)
lo, hi = np.vstack(tips).min(axis=0) - 20.0, np.vstack(tips).max(axis=0) + 20.0
ax1.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1] + 40.0), xlabel="x (mm)", ylabel="y (mm)",
        title="horizontal error × 100 (top view)", aspect="equal")
ax1.legend(loc="upper right", fontsize=8)
k = np.arange(len(targets))
ax2.bar(k - 0.2, pos_before, width=0.4, label="nominal commands")
ax2.bar(k + 0.2, pos_after, width=0.4, color="C3", label="compensated")
ax2.set(yscale="log", xlabel="target", ylabel="position error of the true robot (mm)",
        title="3-D error per target")
ax2.legend(loc="center right")
fig.tight_layout()
plt.show()

# %%
# A URScript program
# ------------------
#
# Programs are compensated in place: every literal target of ``movej``, ``movel``, ``movep``, ``movec``
# and ``servoj`` is replaced, every other byte (comments, speeds, blends) is kept. A pose target
# ``p[x, y, z, rx, ry, rz]`` (m, rotation vector in rad) becomes the pose the controller turns into the
# corrected joints. This program sets no TCP (``set_tcp``), so its poses are of the reflector's point,
# as the calibration's targets; a program that sets one needs ``models=`` to give the models for it.
# The program is printed as written, then as compensated: only the numbers of its targets change (a
# compensated number gets the decimals it needs). The tool points straight down, a turn of 180°, which a
# rotation vector can write with either sign: the compensated poses may show the other one.


def pose_literal(p, R):
    values = np.round([*p, *Rotation.from_matrix(R).as_rotvec()], 6) + 0.0  # + 0.0: no "-0.000000"
    return "p[" + ", ".join(f"{v:.6f}" for v in values) + "]"


corners = [0, 4, 24, 20]
lines = ["def pallet():", "  # visit the pallet's corners",
         "  movej([" + ", ".join(f"{v:.6f}" for v in home) + "], a=1.4, v=1.05)"]
lines += [f"  movel({pose_literal(targets[c], rotations[c])}, a=1.2, v=0.25, r=0.005)" for c in corners]
lines += ["end", ""]

with tempfile.TemporaryDirectory() as folder:
    source, written = Path(folder) / "pallet.script", Path(folder) / "pallet_compensated.script"
    source.write_text("\n".join(lines))
    print(source.read_text())
    program = read_program(str(source), "ur")
    compensated = compensate_program(model, controller, program)
    write_program(str(written), program, compensated.texts)
    print(f"{len(compensated.texts)} of {len(program.targets)} targets compensated; problems: "
          f"{list(compensated.problems)}")
    print(written.read_text())

# %%
# Through the true robot, the program's targets: the joint target's pose is where the nominal model
# puts the tool at those joints, each pose target its literal. ``compensated.q`` holds the joints the
# controller will now reach for each move.

intended = [controller.pose_and_jacobian(home[None])[0][0]] + [targets[c] for c in corners]
before = [home] + [q_nominal[c] for c in corners]
for move, goal, q_old, q_new in zip(program.targets, intended, before, compensated.q):
    old = np.linalg.norm(true.forward(q_old[None])[0] - goal) * 1e3
    new = np.linalg.norm(true.forward(q_new[None])[0] - goal) * 1e3
    print(f"line {move.line} {move.move:<6} true robot misses by {old:.4f} mm as written, {new:.4f} mm compensated")
