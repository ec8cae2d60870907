"""Pose commands after a calibration from positions alone: the flange follows the calibrated model where the
data's lever determined its turn, else the nominal model; the same in targets files and in robot programs
(URScript, and KRL with a tool frame whose TCP is off the flange). Checked against the true robot of each
simulation."""
import json
import os

import numpy as np
import pytest

import kincal
from kincal.compensate import (command_models, compensate_branches, compensate_poses, compensate_program, flange_turn,
                               tool_carry)
from kincal.io import ROWS, read_program
from kincal.models.transforms import rotation_log, zyx_from_matrix

from conftest import DATA, UR5_COLS


def _turn(A, B):
    return np.linalg.norm(rotation_log(A @ np.swapaxes(B, 1, 2)), axis=1)


def _case(name, tool, seed=2):
    """A nominal robot with the measured point at ``tool``, its true robot, and a calibration from 200 points."""
    nominal = kincal.load_robot(name).with_tool_point(tool)
    true = kincal.perturb(nominal, seed=seed)
    fit = kincal.calibrate(nominal, kincal.simulate(true, nominal.sample_joints(200, seed=1), 15e-6, 1),
                           kincal.FitOptions(diagnose=False))
    return nominal, true, fit


def _walk(robot, start_deg, n=20, seed=7):
    """Joints (n, 6) of a program: a random walk of 0.1 rad steps from ``start_deg`` inside the limits."""
    rng = np.random.default_rng(seed)
    q = [np.radians(start_deg)]
    for _ in range(n - 1):
        q.append(np.clip(q[-1] + rng.normal(0, 0.1, robot.n_joints), robot.lower, robot.upper))
    return np.array(q)


def test_the_turns_sigma_is_the_spread_of_calibrations_drawn_from_the_covariance():
    """σ of the turn (finite differences through the covariance, the base frame left out) against the RMS turn of
    400 parameter vectors drawn from the same covariance (a Monte-Carlo reference), within 10 %."""
    from kincal.compensate.turn import _relative, _sigma, poses_in
    nominal, _, fit = _case("ur5", [0.03, -0.02, 0.12])
    unc = fit.uncertainty()
    q = poses_in(fit.robot, nominal.lower, nominal.upper)[:50]
    keep = [k for k, n in enumerate(unc.names) if n not in set(fit.robot.base_params())]
    idx = fit.robot.params.indices([unc.names[k] for k in keep])
    draws = np.random.default_rng(3).multivariate_normal(np.zeros(len(keep)), unc.covariance[np.ix_(keep, keep)], 400)
    spread = []
    for d in draws:
        v = fit.robot.param_values(None).copy()
        v[idx] += d
        spread.append(np.sum(_relative(fit.robot, q, v, fit.robot) ** 2, axis=1))
    assert len(keep) < len(unc.names)  # the tracker's frame was in the fit
    assert abs(_sigma(fit.robot, q, unc.covariance, tuple(unc.names)) / np.sqrt(np.mean(spread)) - 1) < 0.1


@pytest.mark.slow
@pytest.mark.parametrize("tool, determined", [([0.0, 0.0, 0.031], False), ([0.03, -0.02, 0.12], True)])
def test_the_orientation_followed_is_the_one_nearer_the_true_robot(tool, determined):
    """A UR5 measured 31 mm out on the flange's axis: the calibrated turn is noise (undetermined) and following
    it turns the true flange further from the targets than the nominal commands; measured 120 mm out and off the
    axis the turn is determined and following it brings the true flange nearer the targets. Either way the
    decision picks the better one, and the positions are corrected."""
    nominal, true, fit = _case("ur5", tool)
    unc = fit.uncertainty()
    turn = flange_turn(fit.robot, nominal, unc.covariance, unc.names, nominal.lower, nominal.upper)
    assert turn.determined is determined
    model, nominal = command_models(fit.robot, nominal.params.as_dict(), frame="measurement")  # the tracker's frame
    qt = nominal.sample_joints(30, seed=7)
    p, R = nominal.forward(qt), nominal.flange_rotation(qt)
    own = compensate_poses(model, p, R, qt, nominal=nominal)
    kept = compensate_poses(model, p, R, qt, nominal=nominal, orientation=nominal)
    ok = own.ok & kept.ok
    errors = {k: _turn(true.flange_rotation(c.q[ok]), R[ok]).mean() for k, c in (("own", own), ("kept", kept))}
    chosen, other = ("own", "kept") if determined else ("kept", "own")
    assert errors[chosen] < 0.8 * errors[other], errors
    for c in (own, kept):
        assert np.linalg.norm(true.forward(c.q[ok]) - p[ok], axis=1).max() < 0.05 * np.linalg.norm(
            true.forward(qt[ok]) - p[ok], axis=1).mean()


def _urscript(q, robot):
    p, R = robot.forward(q), robot.flange_rotation(q)
    lines = ["def demo():", "  movej([" + ", ".join(f"{v:.12f}" for v in q[0]) + "])"]
    lines += ["  movel(p[" + ", ".join(f"{v:.12f}" for v in np.concatenate([p[k], rotation_log(R[k:k + 1])[0]]))
              + "])" for k in range(1, len(q))]
    return "\n".join(lines + ["end", ""])


@pytest.mark.slow
def test_a_urscript_program_turns_the_flange_as_the_nominal_model_when_the_turn_is_undetermined(tmp_path):
    """The program's pose targets with the nominal orientation: the true flange as far from the targets as with
    the nominal commands (within 2 %) while the calibrated one would turn it further; the positions corrected."""
    nominal, true, fit = _case("ur5", [0.0, 0.0, 0.031])
    q = _walk(nominal, [10, -80, 90, -90, 70, 20])
    (tmp_path / "p.script").write_text(_urscript(q, nominal))
    program = read_program(str(tmp_path / "p.script"), "ur")
    kept = compensate_program(fit.robot, nominal, program, orientation=nominal)
    own = compensate_program(fit.robot, nominal, program)
    assert not kept.problems and not own.problems and np.abs(kept.q - q).max() < 0.01  # the nominal branch
    R, p = nominal.flange_rotation(q), nominal.forward(q)
    before = _turn(true.flange_rotation(q), R).mean()
    assert abs(_turn(true.flange_rotation(kept.q), R).mean() / before - 1) < 0.02
    assert _turn(true.flange_rotation(own.q), R).mean() > 1.2 * before
    assert np.abs(nominal.flange_rotation(kept.q) - R).max() < 1e-6
    assert np.linalg.norm(true.forward(kept.q) - p, axis=1).max() < 0.05 * np.linalg.norm(
        true.forward(q) - p, axis=1).mean()


def _krl(q, robot, tool_lever):
    """A KRL module: a PTP to q[0], then LIN pose targets (mm, deg, S and T) of the TCP at ``tool_lever``."""
    tcp = robot.with_tool_point(tool_lever)
    P, R, bits = tcp.forward(q), tcp.flange_rotation(q), ROWS["krl"](robot, q)
    lines = ["DEF demo()", "PTP {" + ", ".join(f"A{j + 1} {v:.9f}" for j, v in enumerate(np.degrees(q[0]))) + "}"]
    for k in range(1, len(q)):
        a, b, c = np.degrees(zyx_from_matrix(R[k]))
        x, y, z = P[k] * 1e3
        lines.append(f"LIN {{X {x:.9f}, Y {y:.9f}, Z {z:.9f}, A {a:.9f}, B {b:.9f}, C {c:.9f}, "
                     f"S {bits[k][0]}, T {bits[k][1]}}}")
    return "\n".join(lines + ["END", ""])


@pytest.mark.slow
def test_a_krl_program_with_a_tool_off_the_flange_corrects_the_tcp_with_the_nominal_turn(tmp_path):
    """A KUKA measured at a point 150 mm out; its program's TCP is that point (the joint target's too). With the
    nominal turn, the corrected joints put the true TCP where the program means (the calibrated model's TCP, not
    its flange: the two turns differ) and the true flange as far from the targets' rotation as the nominal
    commands do; each written target passes the end-to-end check as read again."""
    nominal, true, fit = _case("kuka_kr6r900sixx", [0.02, -0.01, 0.15])
    flange = nominal.with_tool_point(np.zeros(3))
    q = _walk(nominal, [10, -80, 90, 20, 50, 10])
    (tmp_path / "demo.src").write_text(_krl(q, flange, fit.robot.tool_point()))
    program = read_program(str(tmp_path / "demo.src"), "krl")
    T = np.eye(4)
    T[:3, 3] = fit.robot.tool_point()
    res = compensate_branches(fit.robot, nominal, program, ROWS["krl"], {"default tool": T, "default base": np.eye(4)},
                              orientation=nominal)
    assert res.problems == () and len(res.texts) == len(q)
    R = flange.flange_rotation(q)
    goal = nominal.with_tool_point(fit.robot.tool_point()).forward(q)
    miss = np.linalg.norm(true.forward(res.q) - goal, axis=1)
    assert miss.max() < 0.01e-3 < 0.05 * np.linalg.norm(true.forward(q) - goal, axis=1).mean(), miss.max()
    assert np.abs(nominal.flange_rotation(res.q) - R).max() < 1e-6
    before = _turn(true.flange_rotation(q), R).mean()
    assert abs(_turn(true.flange_rotation(res.q), R).mean() / before - 1) < 0.05


def _beyond(angle, tmp_path):
    """A KR 6 measured 30 mm out on the flange's x axis (80 poses, 15 µm), true robot with angle errors up to
    ``angle`` rad; its TCP 120 mm beyond the measured point (controller's TCP 150, 0, 20 mm). The turn is left
    undetermined. Pose targets of the nominal TCP at 12 joint vectors in the tracker's frame, compensated with the
    nominal turn as a targets file, a KRL program (the tool given by its values) and a URScript program: each
    path's corrected joints (a list of (name, q)), the targets' nominal joints, p and R, the true TCP model, and the
    command models with the point measured."""
    nominal = kincal.load_robot("kuka_kr6r900sixx").with_tool_point([0.03, 0.0, 0.0])
    true = kincal.perturb(nominal, angle=angle, seed=3)
    fit = kincal.calibrate(nominal, kincal.simulate(true, nominal.sample_joints(80, seed=1), 15e-6, 1),
                           kincal.FitOptions(diagnose=False))
    unc = fit.uncertainty()
    assert not flange_turn(fit.robot, nominal, unc.covariance, unc.names, unc.lower, unc.upper).determined
    lever, tcp = np.array([0.12, 0.0, 0.02]), np.array([0.15, 0.0, 0.02])
    shift = tool_carry(fit.robot.tool_point(), nominal.tool_point())[0]
    assert np.linalg.norm(shift) > 0.3e-3  # the calibration's move of the point, carried over to the TCP
    values, measured = nominal.params.as_dict(), fit.robot.tool_point()
    model, nom = command_models(fit.robot, values, tcp, frame="measurement")
    q = _walk(nom, [30, -80, 100, 50, 50, 40], n=12)
    p, R = nom.forward(q), nom.flange_rotation(q)
    runs = [("file", compensate_poses(model, p, R, q, nominal=nom, orientation=nom, measured=measured).q)]
    point, nom_point = command_models(fit.robot, values, frame="measurement")
    (tmp_path / "demo.src").write_text(_krl(q, nom_point.with_tool_point(np.zeros(3)), tcp))
    T = np.eye(4)
    T[:3, 3] = tcp
    res = compensate_branches(point, nom_point, read_program(str(tmp_path / "demo.src"), "krl"), ROWS["krl"],
                              {"default tool": T, "default base": np.eye(4)}, orientation=nom_point, carry=shift)
    assert res.problems == ()
    runs.append(("krl", res.q))
    (tmp_path / "p.script").write_text(_urscript(q, nom))
    res = compensate_program(model, nom, read_program(str(tmp_path / "p.script"), "ur"), orientation=nom,
                             measured=measured)
    assert res.problems == ()
    runs.append(("ur", res.q[1:]))  # the first target is a joint target at q[0]
    return runs, (q, p, R), true.with_tool_point(true.tool_point() + lever), (model, nom, measured)


@pytest.mark.slow
def test_a_tcp_beyond_the_measured_point_is_carried_on_by_the_nominal_turn(tmp_path):
    """Where the commands keep the nominal turn, the calibrated model is trusted where it was measured: the TCP is
    the calibrated measured point plus the nominal flange's turn times the lever to the TCP, as the taught frames
    take it. A true robot with no angle errors turns its flange as the nominal model: its TCP at the corrected
    joints lands within 0.03 mm of every target, on all three paths (0.78 mm, the calibrated model's 6 mrad turn
    times the 122 mm lever, when the TCP was the calibrated model's own), the flange on the targets' rotation."""
    runs, (_, p, R), tcp, _ = _beyond(0.0, tmp_path)
    for name, q in runs:
        miss = np.linalg.norm(tcp.forward(q) - p[-len(q):], axis=1)
        assert miss.max() < 0.03e-3, (name, miss.max())
        assert _turn(tcp.flange_rotation(q), R[-len(q):]).max() < 0.02e-3, name  # the fitted frame's 4 µrad


@pytest.mark.slow
def test_with_angle_errors_a_tcp_beyond_the_measured_point_misses_by_the_nominal_turns_error_alone(tmp_path):
    """The same with angle errors up to 0.05° in the true robot: each path's TCP misses the targets by what the
    nominal turn's own error carries over the lever, no more (the hybrid model's error at the corrected joints,
    computed here: calibrated measured point plus nominal turn times the lever, against the true TCP; within
    1 µm), and by less than the commands following the calibrated model's turn miss."""
    runs, (q0, p, R), tcp, (model, nom, measured) = _beyond(np.deg2rad(0.05), tmp_path)
    own = compensate_poses(model, p, R, q0, nominal=nom).q  # the calibrated model's turn
    for name, q in runs:
        hybrid = model.with_tool_point(measured).forward(q) + nom.flange_rotation(q) @ (model.tool_point() - measured)
        miss = np.linalg.norm(tcp.forward(q) - p[-len(q):], axis=1)
        assert np.abs(miss - np.linalg.norm(tcp.forward(q) - hybrid, axis=1)).max() < 1e-6, name
    miss = np.linalg.norm(tcp.forward(runs[0][1]) - p, axis=1)
    assert np.sqrt(np.mean(miss**2)) < 0.5 * np.sqrt(np.mean(np.linalg.norm(tcp.forward(own) - p, axis=1) ** 2))


@pytest.mark.slow
def test_a_programs_tcp_beyond_the_measured_point_is_carried_by_the_nominal_turn_and_its_sigma_said(tmp_path, capsys):
    """compensate --program krl after a KR 6 measured 30 mm out (turn undetermined), the program's tool 150, 0, 20
    mm: the controller's joints of each written target (the nominal model's inverse, from the nominal joints) put
    the calibrated measured point, carried on by the nominal turn to the TCP, on the target (1 nm; the calibrated
    model's own TCP 0.3 mm or more from it), the nominal flange on its rotation; the TCP's predicted σ through the
    undetermined turn is warned of as for a targets file, naming the lines."""
    from kincal.cli import main
    from kincal.compensate import solve_poses
    assert main(["simulate", "kuka_kr6r900sixx", "--tool", "30,0,0mm", "--poses", "80", "--perturb", "--angle-error",
                 "0", "--seed", "3", "-o", str(tmp_path / "m.csv")]) == 0
    assert main(["calibrate", "kuka_kr6r900sixx", str(tmp_path / "m.csv"), "--tool", "30,0,0mm", "-o",
                 str(tmp_path / "cal.yaml")]) == 0
    cal = kincal.load_robot(tmp_path / "cal.yaml")
    model, nom = command_models(cal, kincal.models.load_calibration_record(tmp_path / "cal.yaml")["nominal"])
    tcp = np.array([0.15, 0.0, 0.02])
    q = _walk(nom, [30, -80, 100, 50, 50, 40], n=8)
    (tmp_path / "demo.src").write_text(_krl(q, nom.with_tool_point(np.zeros(3)), tcp))
    (tmp_path / "frames.yaml").write_text("default tool: {x: 150, y: 0, z: 20}\ndefault base: {}\n")
    capsys.readouterr()
    assert main(["compensate", str(tmp_path / "cal.yaml"), str(tmp_path / "demo.src"), "--program", "krl", "--frames",
                 str(tmp_path / "frames.yaml"), "-o", str(tmp_path / "out.src"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["orientation_from"] == "nominal" and out["compensated"] == 8
    (warning,) = out["warnings"]
    assert "predicted σ at the TCP" in warning and "the TCP is 122 mm from that point" in warning
    v = np.array([t.values[:6] for t in read_program(str(tmp_path / "out.src"), "krl").targets[1:]])
    R = np.array([kincal.models.transforms.rotvec_matrix(r[None])[0] for r in v[:, 3:]])
    q_c = solve_poses(nom.with_tool_point(tcp), v[:, :3], R, q[1:]).q  # the controller turns them into these
    shift = tool_carry(cal.tool_point(), nom.tool_point())[0]
    lever = tcp + shift - cal.tool_point()  # the TCP from the measured point, both on the calibrated model
    p, Rn = nom.with_tool_point(tcp).forward(q[1:]), nom.flange_rotation(q_c)
    hybrid = model.forward(q_c) + Rn @ lever
    assert np.abs(hybrid - p).max() < 1e-9 and np.abs(Rn - nom.flange_rotation(q[1:])).max() < 1e-9
    assert np.linalg.norm(model.with_tool_point(tcp + shift).forward(q_c) - p, axis=1).min() > 0.3e-3


def test_the_tcps_jacobian_in_the_written_check_is_the_models_own_at_that_tcp():
    """The end-to-end check moves the flange's Jacobian to the TCP (v = v_flange + ω × arm): against the model
    built with that TCP as its tool point."""
    from kincal.compensate.branch import _misses
    robot = kincal.perturb(kincal.load_robot("kuka_kr6r900sixx"), seed=4)
    q = robot.sample_joints(5, seed=2)
    lever = np.array([[0.01, -0.02, 0.15]] * 5)
    tcp = robot.with_tool_point(lever[0])
    p, R, Jp, Jw = tcp.pose_and_jacobian(q)
    miss, turn, Jp_check, Jw_check = _misses(robot, robot, q, (p, R, lever))
    assert miss.max() < 1e-12 and turn.max() < 1e-9
    assert np.abs(Jp_check - Jp).max() < 1e-12 and np.abs(Jw_check - Jw).max() < 1e-12


@pytest.mark.slow
def test_the_command_line_says_whose_orientation_a_program_follows_and_why(tmp_path, capsys):
    """compensate --program after a calibration from points: the turn, its σ and the model followed, printed and
    in --json; the undetermined case turns the flange as the nominal model."""
    from kincal.cli import main
    units = ["--length-unit", "mm", "--angle-unit", "deg"]
    for tool, expected in (("0,0,31mm", "nominal"), ("30,-20,120mm", "calibrated")):
        folder = tmp_path / expected
        os.makedirs(folder)
        assert main(["simulate", "ur5", "-o", str(folder / "m.csv"), "--perturb", "--poses", "150", "--tool", tool,
                     *units]) == 0
        assert main(["calibrate", "ur5", str(folder / "m.csv"), "--tool", tool, "-o", str(folder / "cal.yaml"),
                     *units]) == 0
        cal = kincal.load_robot(folder / "cal.yaml")
        nominal = cal.with_params(kincal.models.load_calibration_record(folder / "cal.yaml")["nominal"])
        (folder / "p.script").write_text(_urscript(_walk(nominal, [10, -80, 90, -90, 70, 20], n=5), nominal))
        capsys.readouterr()
        assert main(["compensate", str(folder / "cal.yaml"), str(folder / "p.script"), "--program", "ur", "-o",
                     str(folder / "out.script"), "--json"]) == 0
        out = json.loads(capsys.readouterr().out)
        assert out["orientation_from"] == expected and out["compensated"] == 5
        turn = out["flange_turn"]
        assert turn["determined"] is (expected == "calibrated")
        assert (turn["change"] >= 3 * turn["sigma"]) is turn["determined"]
        assert main(["compensate", str(folder / "cal.yaml"), str(folder / "p.script"), "--program", "ur", "-o",
                     str(folder / "out2.script")]) == 0
        text = capsys.readouterr().out
        said = ("orientation: as the nominal model turns the flange" if expected == "nominal" else
                "orientation: from the calibrated model")
        assert said in text and f"σ {turn['sigma'] * 1e3:.3f} mrad" in text


def test_a_calibration_from_six_d_poses_determines_the_turn_and_a_single_marker_does_not():
    """6-D poses see the flange's turn directly: determined. One marker 31 mm out on the flange's axis is a point:
    the turn is not told apart from noise, as for the same point measured by a tracker."""
    from kincal.identify import fit_observations
    from kincal.simulate.observations import simulate_markers, simulate_poses

    ur5 = kincal.load_robot("ur5")
    true = kincal.perturb(ur5, seed=5)
    q = ur5.sample_joints(150, seed=6)
    for obs, determined in ((simulate_poses(true, q, np.eye(3), 20e-6, 0.2e-3, seed=7), True),
                            (simulate_markers(true, q, np.array([[0.0, 0.0, 0.031]]), 20e-6, seed=7), False)):
        fit = fit_observations(ur5, [obs])
        unc = fit.uncertainty()
        turn = flange_turn(fit.robot, fit.nominal, unc.covariance, unc.names, ur5.lower, ur5.upper)
        assert turn.determined is determined, turn


def test_a_taught_base_takes_the_nominal_turn_where_the_calibration_leaves_it_undetermined():
    """A UR5 measured 31 mm out on the flange's axis (its turn undetermined); bases taught by three points of a
    TCP 120 mm beyond the measured point. The physical base's origin from the calibrated model with the nominal
    turn is nearer the true one than with the calibrated turn, which the data never saw: the lever carries the
    turn's error."""
    from kincal.compensate import resolve_taught
    from kincal.io import TaughtFrame

    nominal, true, fit = _case("ur5", [0.0, 0.0, 0.031])
    lever = np.array([0.0, 0.0, 0.12])  # the TCP from the measured point, in the flange's axes
    tool = np.eye(4)
    tool[:3, 3] = fit.robot.tool_point() + lever
    errors = {"calibrated": [], "nominal": []}
    for k in range(10):
        q = nominal.sample_joints(3, seed=20 + k)
        taught = {"tcp": (tool, tool), "b": TaughtFrame("b", "origin-x-xy", q, "tcp", None)}
        true_origin = true.forward(q[:1])[0] + true.flange_rotation(q[:1])[0] @ lever
        flange = nominal.with_tool_point(np.zeros(3))
        for name, orientation in (("calibrated", None), ("nominal", nominal)):
            physical = resolve_taught(taught, flange, fit.robot, orientation)["b"][1]
            errors[name].append(np.linalg.norm(physical[:3, 3] - true_origin))
    assert np.mean(errors["nominal"]) < 0.7 * np.mean(errors["calibrated"]), errors


def test_a_tcp_far_from_the_measured_point_is_named_as_the_cause_of_its_sigma():
    """Targets for a TCP 120 mm beyond a point measured 31 mm out on the flange's axis: their σ is beyond the limit
    because of that lever (the turn the data leave undetermined), not because of where the poses are; the warning
    says so instead of 'measure calibration poses there too'. At the measured point the same targets draw no
    warning, and the file keeps the measured point."""
    from kincal.analysis.uncertainty import ModelUncertainty
    nominal, _, fit = _case("ur5", [0.0, 0.0, 0.031])
    unc = fit.uncertainty()
    assert np.allclose(unc.measured_point, fit.robot.tool_point())
    assert np.allclose(ModelUncertainty.from_dict(unc.to_dict()).measured_point, unc.measured_point)
    q = nominal.sample_joints(20, seed=3)
    tcp = fit.robot.with_tool_point(fit.robot.tool_point() + [0.0, 0.0, 0.12])
    far = kincal.compensate(tcp, nominal.with_tool_point(tcp.tool_point()).forward(q), q, uncertainty=unc)
    (warning,) = [w for w in far.warnings if "predicted σ" in w]
    assert "the TCP is 120 mm from that point" in warning and "measure at the TCP" in warning
    near = kincal.compensate(fit.robot, nominal.forward(q), q, uncertainty=unc)
    assert not [w for w in near.warnings if "predicted σ" in w]


def test_an_undetermined_turn_from_data_with_rotations_does_not_ask_for_them():
    """A turn left open by 6-D poses (the Jugglebot's S2 in its own frame: 44.6 mrad, σ 33.8 mrad) advised '6-D
    poses or several markers' to a user who had measured them; with rotations seen it advises what remains."""
    from kincal.compensate.turn import FlangeTurn

    plain, seen = FlangeTurn(0.0446, 0.0338, False), FlangeTurn(0.0446, 0.0338, False, rotations_seen=True)
    assert "6-D poses or several markers" in plain.note() and "6-D poses" not in seen.note()
    assert "the data saw rotations, yet in the robot's own frame they leave it open" in seen.note()


def _errors(fit, nominal, true, n=30):
    """The true flange's RMS rotation from 30 pose targets (rad) after commands that follow the calibrated turn, and
    after commands that keep the nominal one (targets in the tracker's frame, in the calibration's joint ranges)."""
    unc = fit.uncertainty()
    model, nom = command_models(fit.robot, nominal.params.as_dict(), frame="measurement")
    qt = unc.lower + np.random.default_rng(7).random((n, nominal.n_joints)) * (unc.upper - unc.lower)
    p, R = nom.forward(qt), nom.flange_rotation(qt)
    own = compensate_poses(model, p, R, qt, nominal=nom)
    kept = compensate_poses(model, p, R, qt, nominal=nom, orientation=nom)
    ok = own.ok & kept.ok
    return [float(np.sqrt(np.mean(_turn(true.flange_rotation(c.q[ok]), R[ok]) ** 2))) for c in (own, kept)]


@pytest.mark.slow
def test_the_readme_ur5s_turn_is_followed_as_its_simulation_shows_it_should():
    """The README's UR5 (reflector 34 mm out on the flange's axis) turns the flange 11.8 mrad from the nominal
    model, nearly all j3.alpha; its fit holds j5.theta at nominal (±87 mrad). Counting that σ as the turn's (the
    held angle's own turn, which the nominal commands share) called the turn undetermined (σ 87 mrad). A true robot
    with the README fit's estimates, the other parameters off nominal by up to 0.05° and 0.5 mm, measured at the
    README's 1000 joint vectors with 65 µm noise: the turn is determined (σ 0.3 mrad), and following it puts the
    true flange 1.5 mrad from the targets against 11.5 mrad with the nominal turn."""
    ur5 = kincal.load_robot("ur5")
    meas = kincal.read_measurements(DATA / "ur5_grid.csv", ur5, joint_cols=UR5_COLS, length_unit="mm",
                                    angle_unit="deg")
    real = kincal.calibrate(ur5, meas, kincal.FitOptions(diagnose=False))
    assert set(real.weak) == {"j5.theta"} and abs(real.robot.params["j3.alpha"] - 11.6e-3) < 0.1e-3
    rng = np.random.default_rng(0)
    true = real.robot.with_params({**{n: ur5.params[n] for n in ur5.base_params()}, **{
        n: ur5.params[n] + rng.uniform(-1, 1) * (0.5e-3 if k == "length" else np.deg2rad(0.05))
        for n, k in zip(ur5.params.names, ur5.params.kinds) if n not in real.names and n not in ur5.base_params()}})
    nominal = ur5.with_tool_point(real.robot.tool_point())
    fit = kincal.calibrate(nominal, kincal.simulate(true, meas.q, 65e-6, 0), kincal.FitOptions(diagnose=False))
    unc = fit.uncertainty()
    turn = flange_turn(fit.robot, nominal, unc.covariance, unc.names, unc.lower, unc.upper)
    assert fit.weak and turn.determined and turn.sigma < 0.5e-3 and abs(turn.change - 11.8e-3) < 0.3e-3, turn
    followed, kept = _errors(fit, nominal, true)
    assert followed < 0.2 * kept and abs(kept / turn.change - 1) < 0.1, (followed, kept)


@pytest.mark.slow
def test_the_readme_ur5s_program_follows_its_calibrated_turn(tmp_path, capsys):
    """The README's UR5 calibrated on the command line: its held j5.theta (±87 mrad) made σ 87.2 mrad and the
    commands kept the nominal turn; now σ 0.29 mrad (the doc's figure), the turn (11.8 mrad) followed, and the
    note names the turns neither model corrects."""
    from kincal.cli import main
    cal = tmp_path / "cal.yaml"
    assert main(["calibrate", "ur5", str(DATA / "ur5_grid.csv"), "--length-unit", "mm", "--angle-unit", "deg",
                 "--joint-cols", ",".join(UR5_COLS), "-o", str(cal)]) == 0
    nominal = kincal.load_robot("ur5")
    (tmp_path / "p.script").write_text(_urscript(_walk(nominal, [10, -80, 90, -90, 70, 20], n=5), nominal))
    capsys.readouterr()
    assert main(["compensate", str(cal), str(tmp_path / "p.script"), "--program", "ur", "-o",
                 str(tmp_path / "out.script"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    turn = out["flange_turn"]
    assert out["orientation_from"] == "calibrated" and turn["determined"], turn
    assert abs(turn["change"] - 11.82e-3) < 0.01e-3 and abs(turn["sigma"] - 0.29e-3) < 0.01e-3, turn
    assert turn["uncorrected"] == ["j5.theta", "j5.alpha", "j6.theta", "j6.alpha"]


def _lr_mate():
    """A FANUC LR Mate measured 30 mm out on the flange's axis at 100 poses within ±1 rad of (0, 10, 0, 0, -30, 0)°:
    the nominal robot, the true one and the calibration."""
    nominal = kincal.load_robot("fanuc_lrmate200id").with_tool_point([0.0, 0.0, 0.03])
    true = kincal.perturb(nominal, seed=3)
    rng = np.random.default_rng(13)
    q = np.clip(np.radians([0, 10, 0, 0, -30, 0]) + (rng.random((100, 6)) - 0.5) * 2.0, nominal.lower, nominal.upper)
    fit = kincal.calibrate(nominal, kincal.simulate(true, q, 15e-6, 3), kincal.FitOptions(diagnose=False))
    return nominal, true, fit


def test_a_turn_made_of_what_the_fit_took_up_of_an_unseen_length_is_not_followed():
    """A FANUC LR Mate measured 30 mm out on the flange's axis: j5.a is not identifiable, and the fit moves j5.theta
    to take up its position error (true +0.26 mrad, fitted -1.71). The covariance alone calls the turn determined
    (14σ), yet following it turns the true flange further from the targets than the nominal turn: with what the
    estimated parameters take up of a real robot's errors of those kept at nominal (10 mm, 2°), it is not."""
    from kincal.compensate.turn import _sigma, poses_in
    nominal, true, fit = _lr_mate()
    unc = fit.uncertainty()
    assert "j5.a" in fit.identifiability.dropped and "j5.theta" in unc.names
    turn = flange_turn(fit.robot, nominal, unc.covariance, unc.names, unc.lower, unc.upper)
    alone = _sigma(fit.robot, poses_in(fit.robot, unc.lower, unc.upper, nominal), unc.covariance, tuple(unc.names))
    assert turn.change > 10 * alone and not turn.determined, (turn, alone)
    followed, kept = _errors(fit, nominal, true)
    assert followed > 1.2 * kept, (followed, kept)


@pytest.mark.slow
def test_the_turns_sigma_counts_what_the_fit_took_up_of_the_parameters_kept_at_nominal():
    """The LR Mate above, sampled against flange_turn's σ (within 10 %, 1.6 % here). Per parameter kept at nominal,
    errors e at the 40 quantiles of a normal at the real robot's limits (10 mm, 2°): the true flange turns by e's
    own turn, the calibrated one by the estimated parameters moved as a least-squares fit of e's position effect at
    the measured point moves them; following adds the mean of |own − moved|² − |own|² (none where negative); to
    that the spread of 300 draws of the covariance. Nearly all of it is j5.theta taking up j5.a, which has no turn
    of its own."""
    from statistics import NormalDist

    from kincal.compensate.turn import _relative, _sigma, poses_in
    nominal, _, fit = _lr_mate()
    unc, robot = fit.uncertainty(), fit.robot
    q = poses_in(robot, unc.lower, unc.upper, nominal)
    kept = [n for n in robot.params.names if n not in unc.names and n not in robot.base_params()]
    P = robot.param_jacobian(q).reshape(-1, robot.n_params)
    est = robot.params.indices(list(unc.names))
    robot_part = np.array([n not in robot.base_params() for n in unc.names])  # the base frame's turn left out
    rng, v0, added = np.random.default_rng(5), robot.param_values(None), 0.0
    normal = np.array([NormalDist().inv_cdf((i + 0.5) / 40) for i in range(40)])  # the normal's 40 quantiles
    for name, kind in [(n, k) for n, k in zip(robot.params.names, robot.params.kinds) if n in kept]:
        k, excess = robot.params.index(name), []
        for e in (np.deg2rad(2.0) if kind == "angle" else 10e-3) * normal:
            own, moved = v0.copy(), v0.copy()
            own[k] += e
            moved[est] += np.linalg.lstsq(P[:, est], P[:, k] * e, rcond=None)[0] * robot_part
            t_own, t_moved = (_relative(robot, q, v, robot) for v in (own, moved))
            excess.append(np.mean(np.sum((t_own - t_moved) ** 2 - t_own**2, axis=1)))
        added += max(float(np.mean(excess)), 0.0)
    spread = []
    for d in rng.multivariate_normal(np.zeros(len(est)), unc.covariance, 300):
        v = v0.copy()
        v[est] += d * robot_part
        spread.append(np.sum(_relative(robot, q, v, robot) ** 2, axis=1))
    turn = flange_turn(robot, nominal, unc.covariance, unc.names, unc.lower, unc.upper)
    reference = np.sqrt(np.mean(spread) + added)
    assert abs(turn.sigma / reference - 1) < 0.1, (turn.sigma, reference)
    assert turn.sigma > 100 * _sigma(robot, q, unc.covariance, tuple(unc.names))  # nearly all from the kept ones


def test_the_turns_neither_model_corrects_are_named_not_hidden_in_sigma():
    """A KR 6 measured 50 mm out on the flange's axis: the turn is determined (σ 0.05 mrad) and followed, yet the
    true flange stays 0.75 mrad RMS from the targets. That is the turn of a6.theta, flange.theta and flange.alpha,
    kept at nominal: the point on the axis does not see them, so neither model corrects them. The note names them;
    their true errors turn the flange by as much as the commands miss (within 5 %)."""
    nominal = kincal.load_robot("kuka_kr6r900sixx").with_tool_point([0.0, 0.0, 0.05])
    true = kincal.perturb(nominal, seed=0)
    fit = kincal.calibrate(nominal, kincal.simulate(true, nominal.sample_joints(200, seed=100), 15e-6, 0),
                           kincal.FitOptions(diagnose=False))
    unc = fit.uncertainty()
    turn = flange_turn(fit.robot, nominal, unc.covariance, unc.names, unc.lower, unc.upper)
    assert turn.determined and turn.uncorrected == ("a6.theta", "flange.theta", "flange.alpha")
    assert "neither model corrects the flange's turns by a6.theta, flange.theta, flange.alpha" in turn.note()
    assert turn.to_dict()["uncorrected"] == ["a6.theta", "flange.theta", "flange.alpha"]
    model, nom = command_models(fit.robot, nominal.params.as_dict(), frame="measurement")
    qt = nominal.sample_joints(30, seed=7)
    R = nom.flange_rotation(qt)
    own = compensate_poses(model, nom.forward(qt), R, qt, nominal=nom)
    missed = np.sqrt(np.mean(_turn(true.flange_rotation(own.q), R) ** 2))
    unseen = true.with_params({n: nominal.params[n] for n in turn.uncorrected})
    theirs = np.sqrt(np.mean(_turn(true.flange_rotation(own.q), unseen.flange_rotation(own.q)) ** 2))
    assert missed > 10 * turn.sigma and abs(theirs / missed - 1) < 0.05, (missed, theirs, turn.sigma)


def test_a_compliance_kept_at_nominal_is_sized_at_the_datas_loads():
    """A compliance's value is its deflection at 100 N·m; kept at nominal, its error is sized as the verdict sizes a
    compliance, 2° at its joint's largest load at the poses (a UR5's j4: 3.5 N·m with 1 kg, so 57° at 100 N·m), not
    2° at 100 N·m (0.07° of deflection there: 800-fold too small in variance; σ 0.13 mrad, now 3.3 mrad, and the
    1.3 mrad turn no longer followed). Reference: what keeping j4's
    compliance adds to σ² (the fit's σ² less that of the same robot without the term), against the excess of
    |own − moved|² − |own|² over errors at 40 quantiles of a normal of that size, its load from the gravity model's
    torques at the poses, the moved parameters a least-squares fit of its position effect (as the test above)."""
    from statistics import NormalDist

    from kincal.compensate.turn import _relative, poses_in
    from kincal.models.gravity import GravityModel
    from kincal.models.terms import drop_terms
    em = kincal.ErrorModel("compliance", payload=1.0)
    nominal = kincal.load_robot("ur5").with_tool_point([0.03, -0.02, 0.12])
    true = kincal.perturb(kincal.extend(nominal, em), seed=2)
    true = true.with_params({n: 1e-3 for n in true.term_names})
    fit = kincal.calibrate(nominal, kincal.simulate(true, nominal.sample_joints(200, seed=1), 15e-6, 1),
                           kincal.FitOptions(diagnose=False, error_model=em))
    unc, robot = fit.uncertainty(), fit.robot
    names = [n for n in unc.names if n != "j4.compliance"]  # j4's compliance kept at nominal (0)
    cov = unc.covariance[np.ix_(*[[unc.names.index(n) for n in names]] * 2)]
    turns = [flange_turn(r, fit.nominal, cov, names, unc.lower, unc.upper)
             for r in (robot, drop_terms(robot, ["j4.compliance"]))]
    q = poses_in(robot, unc.lower, unc.upper, fit.nominal)
    load = np.abs(GravityModel(nominal, 1.0).torques(q)[:, 3]).max()  # N·m
    P = robot.param_jacobian(q).reshape(-1, robot.n_params)
    est, k, v0 = robot.params.indices(names), robot.params.index("j4.compliance"), robot.param_values(None)
    robot_part = np.array([n not in robot.base_params() for n in names])
    excess = []
    for e in np.deg2rad(2.0) * 100.0 / load * np.array([NormalDist().inv_cdf((i + 0.5) / 40) for i in range(40)]):
        own, moved = v0.copy(), v0.copy()
        own[k] += e
        moved[est] += np.linalg.lstsq(P[:, est], P[:, k] * e, rcond=None)[0] * robot_part
        t_own, t_moved = (_relative(robot, q, v, robot) for v in (own, moved))
        excess.append(np.mean(np.sum((t_own - t_moved) ** 2 - t_own**2, axis=1)))
    reference = max(float(np.mean(excess)), 0.0)
    assert 2.0 < load < 4.0 and reference > 0
    assert turns[0].sigma ** 2 - turns[1].sigma ** 2 == pytest.approx(reference, rel=0.05)
