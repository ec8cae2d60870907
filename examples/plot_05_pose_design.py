"""
Choose the measurement poses
============================

Every pose measured costs time on the robot and the tracker. Which poses to measure matters most when
there are few of them: some sets determine the parameters well, others leave directions the fit can
hardly see. ``kincal.select_poses`` picks them from a pool of candidates. Here a simulated UR5 is
calibrated from 15 poses, chosen by kincal or drawn at random from the same pool, and each calibrated
model is compared with the true robot where the robot will be used.
"""

# %%
# The pool and the designs
# ------------------------
#
# ``kincal.candidate_pool`` draws feasible random poses within the joint limits; in a real cell these
# would be the poses the robot can reach without hitting anything (``kincal.design.Cell`` describes
# floors, keep-out boxes and the tracker's line of sight). ``select_poses`` chooses ``m`` of them for
# the parameters position data identify. Two criteria are shown:
#
# * ``IMSE``, the default: the poses whose calibration predicts the tool best on average over the
#   region of use (``validation_q``, default the pool), counting also the bias of errors a geometric
#   model does not describe (gravity load, joint harmonics), and keeping one pose per region of joint
#   space so that the design covers the workspace;
# * ``D``: the classical D-optimal design, the largest determinant of the information matrix.
#
# ``certify=False`` skips the certified bound (a relaxation that tells how far from the best possible
# determinant a design is); it takes longer than the designs themselves.

import matplotlib.pyplot as plt
import numpy as np

import kincal

M = 15  # poses per calibration
robot = kincal.load_robot("ur5")
pool = kincal.candidate_pool(robot, 500, seed=0)
use = robot.sample_joints(300, seed=99)  # where the robot will work: the error is judged here

designs = {"IMSE (default)": kincal.select_poses(robot, pool, kincal.DesignOptions(m=M, certify=False),
                                                 validation_q=use),
           "D-optimal": kincal.select_poses(robot, pool, kincal.DesignOptions(m=M, criterion="D", certify=False))}
for name, design in designs.items():
    print(f"{name}: {design}")

# %%
# Calibrate from designed and from random poses
# ---------------------------------------------
#
# Six simulated robots (``kincal.perturb``: random errors of up to 0.5 mm and 0.05° on every kinematic
# parameter and the tool point, fixed seeds) are measured twice over:
#
# * **geometry only**: the true robot differs from the nominal one by its geometry alone, which a
#   geometric calibration can describe exactly;
# * **with compliance**: joints 2 to 4 also bend under the gravity load of the links, by 5 µrad per N·m
#   (``kincal.extend`` adds that term to the true robot), an error the geometric calibration leaves out.
#
# The tracker measures the designed poses with 15 µm of noise per axis, and also eight sets of 15 poses
# drawn at random from the same pool. Every set is calibrated the same way (geometry only), and the
# calibrated model is compared with the true robot at the 300 poses of use: the mean distance between
# where the model says the tool is and where it really is.


def workspace_error(true, q, seed):
    """Mean error (m) at the poses of use of the model calibrated from measurements of ``true`` at q."""
    fit = kincal.calibrate(robot, kincal.simulate(true, q, noise=15e-6, seed=seed), diagnose=False)
    return float(np.linalg.norm(fit.robot.forward(use) - true.forward(use), axis=1).mean())


def true_robots(compliance):
    """Six perturbed UR5s; with ``compliance`` (rad/(N·m)) joints 2-4 also bend under the links' weight."""
    for r in range(6):
        true = kincal.perturb(robot, seed=r)
        if compliance:
            true = kincal.extend(true, "compliance")  # the parameter is the deflection at 100 N·m
            true = true.with_params({n: compliance * 100.0 for n in true.params.names if n.endswith(".compliance")})
        yield true


draws = 8
results = {}
for scenario, compliance in (("geometry only", 0.0), ("with compliance", 5e-6)):
    designed = {name: [] for name in designs}
    random_sets = []
    for r, true in enumerate(true_robots(compliance)):
        for name, design in designs.items():
            designed[name].append(workspace_error(true, design.q, seed=1000 + r))
        rng = np.random.default_rng(r)
        random_sets.append([workspace_error(true, pool[rng.choice(len(pool), M, replace=False)],
                                            seed=2000 + 10 * r + k) for k in range(draws)])
    results[scenario] = designed, np.array(random_sets)

for scenario, (designed, random_sets) in results.items():
    print(f"== {scenario}: mean error at the poses of use (mm)")
    print(f"{'robot':>5} {'IMSE (default)':>15} {'D-optimal':>10} {'random: median':>15} {'best':>8} {'worst':>8}")
    for r in range(len(random_sets)):
        print(f"{r:>5} {designed['IMSE (default)'][r] * 1e3:15.4f} {designed['D-optimal'][r] * 1e3:10.4f} "
              f"{np.median(random_sets[r]) * 1e3:15.4f} {random_sets[r].min() * 1e3:8.4f} "
              f"{random_sets[r].max() * 1e3:8.4f}")
    for name, errs in designed.items():
        wins = sum(e < np.median(rs) for e, rs in zip(errs, random_sets))
        best = sum(e < rs.min() for e, rs in zip(errs, random_sets))
        print(f"  {name}: below the median random set for {wins} of {len(errs)} robots, below every random set "
              f"for {best}; mean error {np.mean(errs) * 1e3:.4f} mm against {np.mean(random_sets) * 1e3:.4f} mm "
              f"for random sets")
    lower = sum(a < b for a, b in zip(designed["IMSE (default)"], designed["D-optimal"]))
    print(f"  the IMSE design is below the D-optimal one for {lower} of {len(random_sets)} robots")

# %%
# Each column of the figure is one simulated robot: the grey dots are its eight random sets, the
# markers the two designs. Read the printed tables beside it.
#
# * With **geometry only**, the error left is the tracker's noise carried through the fit: the design
#   that determines the parameters best, D-optimal, is the one to beat, and both designs sit low in
#   the random sets' spread. What a design removes is the chance of a poor draw, a set that sees some
#   direction of the parameters badly.
# * **With compliance**, the error left is mostly the bending the model does not describe, and it is
#   largest where the arm reaches far out. D-optimality likes exactly those poses, because they
#   determine the parameters best; the default criterion counts that bias and chooses poses that
#   predict well over the region of use. Compare the printed counts: it is now the design to beat,
#   below the D-optimal one for most robots and on average.
#
# The gain shrinks as the number of poses grows: with many poses, any spread-out set identifies the
# robot well. The benchmarks of kincal measure the criteria on the real UR5 and WAM tracker data
# (``benchmarks/design_real.py``).

fig, axes = plt.subplots(1, 2, figsize=(12, 4.4))
for ax, (scenario, (designed, random_sets)) in zip(axes, results.items()):
    x = np.arange(len(random_sets))
    for r in x:
        ax.plot(np.full(draws, r), random_sets[r] * 1e3, "o", color="0.6", ms=5,
                label=f"random sets of {M}" if r == 0 else None)
    ax.plot(x - 0.12, np.array(designed["IMSE (default)"]) * 1e3, "D", color="C3", ms=8, label="IMSE design (default)")
    ax.plot(x + 0.12, np.array(designed["D-optimal"]) * 1e3, "s", color="C0", ms=7, label="D-optimal design")
    ax.set_xticks(x, [f"robot {r}" for r in x])
    ax.set(ylabel="mean error at the poses of use (mm)", title=f"{scenario}: UR5, {M} poses, 15 µm noise")
axes[0].legend()
fig.tight_layout()
plt.show()
