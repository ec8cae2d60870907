"""Full-pose compensation: commands that reproduce 6-D targets through the calibrated model, and
filtered targets that the controller's own inverse kinematics turn into the same commands; a UR5
(six joints), the Panda (seven: the controller's redundancy parameter is joint 7) and the 5-joint
hybrid of Guo et al. 2024 (it controls the position and two rotations; the third is reported)."""

import numpy as np
import pytest

import kincal
from kincal.compensate import solve_poses
from kincal.models.transforms import rotation_log
from conftest import PANDA_URDF

PANDA = PANDA_URDF


def _case(nominal, n=400, seed=3):
    """A program of nominal commands q0 and the poses the controller (the nominal model) reaches with
    them, away from the wrist singularity; the real robot is the nominal one with errors."""
    q0 = nominal.sample_joints(4 * n, seed=seed)
    _, _, Jp, Jw = nominal.pose_and_jacobian(q0)
    s = np.linalg.svd(np.concatenate([Jp, 0.1 * Jw], axis=1), compute_uv=False)
    q0 = q0[s[:, -1] > 0.2 * np.median(s[:, -1])][:n]  # well-conditioned poses only
    p, R, _, _ = nominal.pose_and_jacobian(q0)
    return kincal.perturb(nominal, seed=seed + 1), q0, p, R


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_pose_commands_reproduce_targets_and_filtered_targets_give_the_same_joints(name):
    nominal = (kincal.load_robot("ur5").with_tool_point([0.03, -0.02, 0.12]) if name == "ur5" else
               kincal.load_robot(PANDA, tip_link="ball_link"))
    true, q0, p, R = _case(nominal)
    comp = kincal.compensate(true, p, q0, rotations=R, nominal=nominal)
    assert comp.ok.mean() > 0.98, comp.problems[:3]
    ok = comp.ok
    pt, Rt, _, _ = true.pose_and_jacobian(comp.q[ok])  # the calibrated (true) model at the commands
    assert np.linalg.norm(pt - p[ok], axis=1).max() < 1e-6
    assert np.linalg.norm(rotation_log(R[ok] @ np.swapaxes(Rt, 1, 2)), axis=1).max() < 1e-6
    assert np.abs(comp.q[ok] - q0[ok]).max() > 1e-4  # the corrections are real, not the identity
    fp, fR = comp.filtered
    fixed = (6,) if nominal.n_joints == 7 else ()  # Franka: joint 7 is the inverse kinematics' parameter
    start = q0.copy()
    if fixed:
        start[:, 6] = comp.q[:, 6]
    back = solve_poses(nominal, fp[ok], fR[ok], start[ok], fixed=fixed)  # the controller's own IK
    assert back.converged.all() and np.abs(back.q - comp.q[ok]).max() < 1e-9


def test_a_five_joint_robot_reaches_position_and_the_rotations_it_controls():
    nominal = kincal.load_robot("guo3t2r")
    true, q0, p, R = _case(nominal, n=300)
    sol = solve_poses(true, p, R, q0)
    assert sol.converged.mean() > 0.98
    ok = sol.converged
    assert sol.position_error[ok].max() < 1e-6
    # the rotation left is the one five joints cannot control: orthogonal to every joint's rotation
    _, Rf, Jp, Jw = true.pose_and_jacobian(sol.q[ok])
    pt = true.forward(sol.q[ok])
    er = rotation_log(R[ok] @ np.swapaxes(Rf, 1, 2))
    J = np.concatenate([Jp, 1e-4 * Jw], axis=1)
    e = np.concatenate([p[ok] - pt, 1e-4 * er], axis=1)
    assert np.abs(np.einsum("nij,ni->nj", J, e)).max() < 1e-12  # the least-squares optimality condition
    assert np.median(np.linalg.norm(er, axis=1)) > 1e-5  # and some rotation is indeed left (not a 6-D reach)


def test_a_constant_rotation_of_the_targets_is_refused_as_a_set_up_mismatch():
    """Targets turned 90° about the flange z (another TCP orientation, or another convention): not
    'corrected' by moving joints; every row refused with the size and the axis."""
    from scipy.spatial.transform import Rotation
    nominal = kincal.load_robot("ur5").with_tool_point([0.03, -0.02, 0.12])
    true, q0, p, R = _case(nominal, n=50)
    turned = R @ Rotation.from_rotvec([0.0, 0.0, np.pi / 2]).as_matrix()
    comp = kincal.compensate(true, p, q0, rotations=turned, nominal=nominal)
    assert not comp.ok.any() and len(comp.problems) == 1
    assert "1570.8 mrad about the flange axis (0.00, 0.00, 1.00)" in comp.problems[0]
    assert np.array_equal(comp.q, q0)  # nothing moved


def test_compensate_names_what_a_five_joint_robot_does_not_control():
    nominal = kincal.load_robot("guo3t2r")
    true, q0, p, R = _case(nominal, n=60)
    comp = kincal.compensate(true, p, q0, rotations=R, nominal=nominal)
    left = comp.rotation_residual[comp.ok].max()
    assert comp.ok.any() and left > 1e-5
    assert any(f"5 joints control the position and 2 rotation(s): the rest of the target orientation is not "
               f"controlled, up to {left * 1e3:.3f} mrad left" in w for w in comp.warnings)


@pytest.mark.slow
def test_pose_targets_through_the_command_line(tmp_path, capsys):
    """compensate --pose: KUKA-style A, B, C angles in, commands (or filtered poses) out; the commands
    reach every written target through the calibrated command model, the filtered poses are the
    nominal model's at the commands, and the other Euler order is named."""
    import json
    from kincal.cli import main
    from kincal.compensate import command_models
    from kincal.observe import from_matrices, to_matrices
    units = ["--length-unit", "mm", "--angle-unit", "deg"]
    assert main(["simulate", "ur5", "-o", str(tmp_path / "m.csv"), "--perturb", "--poses", "120", "--tool",
                 "0,0,100mm", *units]) == 0
    assert main(["calibrate", "ur5", str(tmp_path / "m.csv"), "--tool", "0,0,100mm", "-o", str(tmp_path / "cal.yaml"),
                 *units]) == 0
    tcp = np.array([0.03, -0.02, 0.12])
    cal = kincal.load_robot(tmp_path / "cal.yaml")
    model, nominal = command_models(cal, kincal.models.load_calibration_record(tmp_path / "cal.yaml")["nominal"], tcp)
    _, q0, p, R = _case(nominal, n=80)
    head = "j1,j2,j3,j4,j5,j6,x,y,z,e1,e2,e3"
    np.savetxt(tmp_path / "poses.csv", np.column_stack([np.rad2deg(q0), p * 1e3, from_matrices(R, "euler-zyx-intrinsic-deg")]),
               delimiter=",", header=head, comments="", fmt="%.15g")
    capsys.readouterr()
    base = ["compensate", str(tmp_path / "cal.yaml"), str(tmp_path / "poses.csv"), "--pose", "--tcp", "30,-20,120mm",
            *units, "--json", "--skip-unreachable"]
    assert main(base + ["-o", str(tmp_path / "cmd.csv"), "--orientation", "euler-zyx-intrinsic-deg"]) == 0
    out = json.loads(capsys.readouterr().out)
    cmd = np.loadtxt(tmp_path / "cmd.csv", delimiter=",", skiprows=1)
    rows = cmd[:, 0].astype(int) - 2
    assert len(rows) >= 76 and len(rows) + len(out["problems"]) == 80  # a refused row is named (limits, branch)
    assert out["max_rotation_residual"] < 1e-6 and out["written"] == len(rows) and out["targets"] == 80
    # calibrated from points: the flange is turned to the targets as the nominal model predicts, and said so; the
    # TCP is the calibrated measured point carried on by that turn (the TCP is 120 mm beyond it)
    assert out["orientation_from"] == "nominal"
    q = np.deg2rad(cmd[:, 1:7])
    tcp_at = model.with_tool_point(cal.tool_point()).forward(q) + nominal.flange_rotation(q) @ (
        model.tool_point() - cal.tool_point())
    assert np.abs(tcp_at - p[rows]).max() < 1e-6
    assert np.abs(nominal.pose_and_jacobian(np.deg2rad(cmd[:, 1:7]))[1] - R[rows]).max() < 1e-6
    assert main(base + ["-o", str(tmp_path / "f.csv"), "--orientation", "euler-zyx-intrinsic-deg",
                        "--output-kind", "cartesian"]) == 0
    capsys.readouterr()
    f = np.loadtxt(tmp_path / "f.csv", delimiter=",", skiprows=1)
    pn, Rn, _, _ = nominal.pose_and_jacobian(np.deg2rad(f[:, 7:13]))
    assert np.abs(pn * 1e3 - f[:, 1:4]).max() < 1e-6
    assert np.abs(Rn - to_matrices(f[:, 4:7], "euler-zyx-intrinsic-deg", "f", f[:, 0])).max() < 1e-9
    assert main(base + ["-o", str(tmp_path / "x.csv"), "--orientation", "euler-zyx-extrinsic-deg"]) == 1
    assert "the file looks like euler-zyx-intrinsic-deg" in capsys.readouterr().err
    # the axes relabelled (xzy: the same rotations turned by 120°, which a frame fitted to them alone absorbs)
    assert main(base + ["-o", str(tmp_path / "y.csv"), "--orientation", "euler-xzy-intrinsic-deg"]) == 1
    assert "the file looks like euler-zyx-intrinsic-deg" in capsys.readouterr().err


def test_a_path_through_a_wrist_near_singularity_keeps_its_branch_and_names_where_continuity_is_lost():
    """10⁴ consecutive UR5 poses whose wrist passes within 5 µrad of its singularity (j5 = 0): away
    from it the corrected commands stay on the nominal branch and as smooth as the nominal path;
    at it the rows where a correction would jump are refused and named, and only there."""
    from kincal.compensate import path_checked
    nominal = kincal.load_robot("ur5").with_tool_point([0.0, 0.0, 0.12])
    true = kincal.perturb(nominal, seed=5)
    t = np.linspace(0, 2 * np.pi, 10_000)
    q0 = np.array([0.3, -1.2, 1.5, -1.9, 0.0, 0.4]) + np.column_stack(
        [0.4 * np.cos(t), 0.2 * np.sin(t), 0.2 * np.cos(t), 0.3 * np.sin(t), 0.3 * np.sin(t) + 0.005, 0.2 * np.cos(t)])
    p, R, _, _ = nominal.pose_and_jacobian(q0)
    comp = path_checked(true, kincal.compensate(true, p, q0, rotations=R, nominal=nominal), q0)
    near = np.abs(q0[:, 4]) < 0.01  # within 0.6 deg of the singularity
    refused = ~comp.ok
    assert refused.any() and not (refused & ~near).any()  # refused only near the singularity
    assert any("continuity of the path is lost" in p for p in comp.problems)
    away = ~near
    assert np.abs(comp.q[away] - q0[away]).max() < np.deg2rad(5)  # the nominal branch: no flip
    steps = np.abs(np.diff(comp.q, axis=0))[away[1:] & away[:-1]]
    nominal_steps = np.abs(np.diff(q0, axis=0))[away[1:] & away[:-1]]
    assert (steps <= np.maximum(3 * nominal_steps, np.deg2rad(0.5))).all()


def test_a_six_d_calibration_commands_in_the_robots_base_frame(tmp_path, capsys):
    """A UR5 calibrated from 6-D poses measured by a camera 1.2 m away (rotated 0.4 rad): the file keeps
    the declared base as its nominal, so commands are computed in the robot's own base frame (it
    answered 'TCP/frame mismatch of 1.3 m' for every target, the registered camera frame standing in
    for the robot's base); through the true robot in its base frame they reach the targets."""
    from kincal.cli import main
    from kincal.identify import fit_observations
    from kincal.simulate.observations import simulate_poses

    ur5 = kincal.load_robot("ur5")
    unseen = [*ur5.base_params(), "j1.theta", "j1.d"]  # where the base sits: no tracker sees it, the file says
    true = kincal.perturb(ur5, 0.3e-3, 0.3e-3, seed=5)
    true = true.with_params({n: ur5.params[n] for n in unseen})
    base = {n: true.params[n] for n in ur5.base_params()}
    seen = true.with_params({"base.x": 1.2, "base.y": -0.3, "base.z": 0.4, "base.rz": 0.4})  # the camera's view
    obs = simulate_poses(seen, ur5.sample_joints(150, seed=6), np.eye(3), 20e-6, 0.2e-3, seed=7)
    fit = fit_observations(ur5, [obs])
    assert fit.nominal is ur5 and np.allclose(fit.registered.params["base.x"], 1.2, atol=0.01)
    cal = tmp_path / "cal.yaml"
    kincal.save_robot(fit.robot, cal, calibration=fit.record())
    robot_frame = true.with_params(base)
    q = ur5.sample_joints(20, seed=8)
    goals = kincal.Measurements(q, ur5.forward(q), ur5.joint_names)  # where the nominal model says it goes
    kincal.write_measurements(tmp_path / "goals.csv", goals, ur5.joint_types)
    out = tmp_path / "cmd.csv"
    code = main(["compensate", str(cal), str(tmp_path / "goals.csv"), "-o", str(out), "--skip-unreachable"])
    assert code == 0, capsys.readouterr().err
    rows = np.genfromtxt(out, delimiter=",", names=True)
    cmd = np.column_stack([rows[f"j{k}"] for k in range(1, 7)])
    done = (rows["row"] - 2).astype(int)
    assert len(done) >= 18
    miss = np.linalg.norm(robot_frame.forward(cmd) - goals.xyz[done], axis=1)
    assert miss.max() < 0.05e-3, miss.max()


def test_a_calibration_from_positions_does_not_turn_the_flange_it_never_saw():
    """Position data cannot see every turn of the flange their parameters imply (the reflector on the flange's
    axis): compensating pose targets with such a calibration turned the true flange further from the targets than
    the nominal commands did. With the nominal model's orientation the true flange is as far as with the nominal
    commands (no worse), and the positions are still corrected."""
    from kincal.compensate import command_models, compensate_poses
    from kincal.models.transforms import rotation_log

    nominal = kincal.load_robot("ur5")
    true = kincal.perturb(nominal, seed=2)
    q = nominal.sample_joints(200, seed=1)
    fit = kincal.calibrate(nominal, kincal.simulate(true, q, 15e-6, 1), kincal.FitOptions(diagnose=False)).robot
    cal, nominal = command_models(fit, nominal.params.as_dict(), frame="measurement")  # targets: the tracker's
    qt = nominal.sample_joints(30, seed=7)
    R, p = nominal.flange_rotation(qt), nominal.forward(qt)
    turn = lambda A, B: np.linalg.norm(rotation_log(A @ np.swapaxes(B, 1, 2)), axis=1)  # noqa: E731
    own = compensate_poses(cal, p, R, qt, nominal=nominal)
    kept = compensate_poses(cal, p, R, qt, nominal=nominal, orientation=nominal)
    ok = own.ok & kept.ok
    before = turn(true.flange_rotation(qt[ok]), R[ok]).mean()
    assert turn(true.flange_rotation(own.q[ok]), R[ok]).mean() > 1.4 * before  # the unseen turn, applied
    assert abs(turn(true.flange_rotation(kept.q[ok]), R[ok]).mean() - before) < 0.02 * before
    assert np.abs(nominal.flange_rotation(kept.q[ok]) - R[ok]).max() < 1e-6 and kept.rotation_residual[ok].max() < 1e-6
    assert np.linalg.norm(true.forward(kept.q[ok]) - p[ok], axis=1).max() < 0.05 * np.linalg.norm(
        true.forward(qt[ok]) - p[ok], axis=1).mean()


def test_a_hexapod_turned_as_its_nominal_model():
    """The legs of a pose follow in closed form; with the nominal model's orientation they put the calibrated
    platform's point at the target and the nominal platform's rotation at the target rotation."""
    from kincal.compensate import compensate_poses
    from kincal.models.transforms import rotation_log

    nominal = kincal.load_robot("hexapod")
    real = kincal.perturb(nominal, seed=3)
    q = nominal.sample_joints(5, seed=1)
    p, R = nominal.forward(q), nominal.flange_rotation(q)
    comp = compensate_poses(real, p, R, None, orientation=nominal)
    assert comp.all_ok and np.abs(real.forward(comp.q) - p).max() < 1e-9
    turn = np.linalg.norm(rotation_log(nominal.flange_rotation(comp.q) @ np.swapaxes(R, 1, 2)), axis=1)
    assert turn.max() < 1e-9 and np.allclose(comp.rotation_residual, turn)
    own = np.linalg.norm(rotation_log(real.flange_rotation(comp.q) @ np.swapaxes(R, 1, 2)), axis=1)
    assert own.min() > 1e-5  # the real platform's own rotation is not what was reached


def test_a_hexapods_tcp_beyond_the_measured_point_is_carried_on_by_the_nominal_turn():
    """A TCP 100 mm above the platform's measured point (its centre): the legs put the calibrated centre where the
    nominal platform's turn carries it to the TCP's target (computed here: centre + R_nominal · lever), not the
    calibrated platform's own TCP (0.2 mm away: its unseen turn times the lever)."""
    from kincal.compensate import compensate_poses

    nominal = kincal.load_robot("hexapod")
    centre, lever = nominal.tool_point(), np.array([0.02, -0.01, 0.1])
    nom, real = nominal.with_tool_point(centre + lever), kincal.perturb(nominal, seed=3).with_tool_point(centre + lever)
    q = nominal.sample_joints(5, seed=1)
    p, R = nom.forward(q), nom.flange_rotation(q)
    comp = compensate_poses(real, p, R, None, orientation=nom, measured=centre)
    hybrid = real.with_tool_point(centre).forward(comp.q) + nom.flange_rotation(comp.q) @ lever
    assert comp.all_ok and np.abs(hybrid - p).max() < 1e-9 and np.abs(real.forward(comp.q) - p).max() > 0.1e-3
