"""Pose commands after a calibration from positions alone: the flange follows the calibrated model where the
data's lever determined its turn, else the nominal model; the same in targets files and in robot programs
(URScript, and KRL with a tool frame whose TCP is off the flange). Checked against the true robot of each
simulation."""
import json
import os

import numpy as np
import pytest

import kincal
from kincal.compensate import command_models, compensate_branches, compensate_poses, compensate_program, flange_turn
from kincal.io import ROWS, read_program
from kincal.models.transforms import rotation_log, zyx_from_matrix


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


def test_parameters_held_at_nominal_count_in_the_turns_sigma():
    """An LR Mate point calibration kept j5.theta at nominal (determined to ±76 mrad): the flange's turn was
    'determined' to σ 0.039 mrad and followed, 23σ off on the true robot. A held parameter's σ now counts: a
    joint zero turns the flange by exactly its own angle, so σ² grows by its σ² (independent of the poses)."""
    nominal, true, fit = _case("ur5", [0.03, -0.02, 0.12])
    unc = fit.uncertainty()
    keep = [k for k, n in enumerate(unc.names) if n != "j5.theta"]
    names, cov = [unc.names[k] for k in keep], unc.covariance[np.ix_(keep, keep)]  # as if j5.theta had been held
    without = flange_turn(fit.robot, nominal, cov, names, nominal.lower, nominal.upper)
    held = flange_turn(fit.robot, nominal, cov, names, nominal.lower, nominal.upper, held={"j5.theta": 0.0759})
    assert without.determined and not held.determined
    assert held.sigma == pytest.approx(np.hypot(without.sigma, 0.0759), rel=1e-4)
