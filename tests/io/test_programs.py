"""Robot programs compensated in place (URScript): every move kind, comments, variables and strings;
unchanged lines byte for byte, compensated literals equal to the pose-file route, non-literal targets
listed."""
import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

import kincal
from kincal.cli import main
from kincal.compensate import compensate_program, solve_poses
from kincal.models.transforms import rotation_log
from kincal.io import read_program, write_program
from kincal.io.program_ur import NOT_ONE_LITERAL


def _pose(robot, q):
    p, R, _, _ = robot.pose_and_jacobian(np.atleast_2d(q))
    return np.concatenate([p[0], rotation_log(R)[0]])


def _fmt(v, pose):
    return ("p[" if pose else "[") + ", ".join(f"{x:.12g}" for x in v) + "]"


@pytest.fixture(scope="module")
def setting():
    nominal = kincal.load_robot("ur5").with_tool_point([0.0, 0.0, 0.15])
    true = kincal.perturb(nominal, seed=7)
    home = np.array([0.2, -1.4, 1.5, -1.7, -1.4, 0.3])
    qs = [home + 0.05 * k * np.array([1.0, -0.5, 0.7, 0.4, -0.3, 0.8]) for k in range(1, 6)]
    poses = [_pose(nominal, q) for q in qs]
    text = ("def prog():\r\n"
            "  # go home first: movej([0, 0, 0, 0, 0, 0]) is only a comment\r\n"
            f"  movej({_fmt(home, False)}, a=1.4, v=1.05)\r\n"
            f"  global target = {_fmt(poses[0], True)}   # a variable\r\n"
            "  movel(target, a=1.2, v=0.25, r=0.01)\r\n"
            f"  movel( {_fmt(poses[1], True)} ,a=1.2,v=0.25)\r\n"
            f"  movep({_fmt(poses[2], True)}, a=1.2, v=0.25, r=0.005)\r\n"
            f"  movec({_fmt(poses[3], True)}, {_fmt(poses[4], True)}, a=1.2, v=0.25, r=0, mode=0)\r\n"
            f"  servoj({_fmt(qs[4], False)}, t=0.008, lookahead_time=0.1, gain=300)\r\n"
            '  textmsg("movel(p[1, 2, 3, 4, 5, 6])")\r\n'
            "  movel(pose_add(target, p[0, 0, 0.01, 0, 0, 0]), a=1.2)\r\n"
            "end\r\n")
    return nominal, true, home, qs, poses, text


def test_every_move_kind_is_found_and_only_literals(tmp_path, setting):
    nominal, true, home, qs, poses, text = setting
    (tmp_path / "prog.script").write_bytes(text.encode())
    prog = read_program(str(tmp_path / "prog.script"))
    assert [(t.move, t.kind, t.line, t.variable) for t in prog.targets] == [
        ("movej", "joints", 3, ""), ("movel", "pose", 4, "target"), ("movel", "pose", 6, ""), ("movep", "pose", 7, ""),
        ("movec", "pose", 8, ""), ("movec", "pose", 8, ""), ("servoj", "joints", 9, "")]
    assert prog.not_literal == ((11, "movel(pose_add(target, p[0, 0, 0.01, 0, 0, 0]))", NOT_ONE_LITERAL),)
    assert prog.with_targets({}) == text  # nothing replaced: the same bytes


def test_compensated_program_keeps_every_other_byte_and_matches_the_pose_route(tmp_path, setting):
    nominal, true, home, qs, poses, text = setting
    (tmp_path / "prog.script").write_bytes(text.encode())
    prog = read_program(str(tmp_path / "prog.script"))
    res = compensate_program(true, nominal, prog)
    assert res.problems == () and len(res.texts) == 7
    write_program(str(tmp_path / "out.script"), prog, res.texts)
    out = (tmp_path / "out.script").read_bytes().decode()
    old_lines, new_lines = text.split("\r\n"), out.split("\r\n")
    changed = {t.line for t in prog.targets}
    assert len(old_lines) == len(new_lines)
    for k, (a, b) in enumerate(zip(old_lines, new_lines), start=1):
        assert (a == b) != (k in changed), (k, a, b)  # unchanged lines byte for byte; target lines changed
    # joint targets: the same as compensating the pose the nominal model reaches there (the pose-file route)
    for k, q in ((0, home), (6, qs[4])):
        p, R, _, _ = nominal.pose_and_jacobian(q[None])
        comp = kincal.compensate(true, p, q[None], rotations=R, nominal=nominal)
        assert np.abs(res.q[k] - comp.q[0]).max() < 1e-9
    # pose targets: the controller's IK of the written pose gives joints at which the real robot is on target
    new = read_program(str(tmp_path / "out.script"))
    start = home
    for k in (1, 2, 3, 4, 5):  # the variable's literal (its assignment compensated), then the literals
        v = new.targets[k].values
        ik = solve_poses(nominal, v[None, :3], Rotation.from_rotvec(v[3:]).as_matrix()[None], start[None])
        pt, Rt, _, _ = true.pose_and_jacobian(ik.q)
        assert np.linalg.norm(pt[0] - poses[k - 1][:3]) < 1e-6
        assert np.linalg.norm(rotation_log(Rt)[0] - poses[k - 1][3:]) < 1e-6
        assert np.abs(ik.q[0] - res.q[k]).max() < 1e-8
        start = ik.q[0]


@pytest.mark.slow
def test_program_through_the_command_line(tmp_path, capsys, setting):
    """A real calibration file (tracker data of a robot with errors): the program's joint targets change
    by the correction, the variable's move is listed, and the program is never written over."""
    nominal, true, home, qs, poses, text = setting
    (tmp_path / "prog.script").write_bytes(text.encode())
    units = ["--length-unit", "mm", "--angle-unit", "deg", "--tool", "0,0,150mm"]
    assert main(["simulate", "ur5", "-o", str(tmp_path / "m.csv"), "--perturb", "--poses", "120", "--seed", "7",
                 *units]) == 0
    assert main(["calibrate", "ur5", str(tmp_path / "m.csv"), "-o", str(tmp_path / "cal.yaml"), *units]) == 0
    capsys.readouterr()
    base = ["compensate", str(tmp_path / "cal.yaml"), str(tmp_path / "prog.script"), "--program", "ur"]
    assert main(base + ["-o", str(tmp_path / "prog.script")]) == 1
    assert "would overwrite" in capsys.readouterr().err  # never over the input
    assert main(base + ["-o", str(tmp_path / "out.script")]) == 0
    out = capsys.readouterr().out
    assert "7 of 7 literal targets compensated" in out and "line 11: movel(pose_add(target" in out
    new = read_program(str(tmp_path / "out.script"))
    assert 1e-5 < np.abs(new.targets[0].values - home).max() < np.deg2rad(5)  # corrected, same branch


def test_a_variable_changed_after_its_literal_is_listed_not_compensated():
    """Only a variable assigned once with a literal is compensated where it is written: one whose
    element is set or that is changed in place (b[0] = …, c += …) is a move to an expression, listed."""
    from kincal.io.program_ur import parse

    text = ("def p():\n  global a = p[0.1, 0.2, 0.3, 0, 0, 0]\n  b = [0, 0, 0, 0, 0, 0]\n  b[0] = 0.5\n"
            "  c = [1, 1, 1, 1, 1, 1]\n  c += 1\n  movel(a)\n  movej(b)\n  movej(c)\nend\n")
    prog = parse("p.script", text)
    assert [(t.variable, t.line, t.kind) for t in prog.targets] == [("a", 2, "pose")]
    assert prog.not_literal == ((8, "movej(b)", NOT_ONE_LITERAL), (9, "movej(c)", NOT_ONE_LITERAL))


def _ur10(seed=3):
    nominal = kincal.load_robot("ur10").with_tool_point([0.0, 0.0, 0.15]).with_params({"base.rz": 0.4, "base.x": 0.2})
    return nominal, kincal.perturb(nominal, seed=seed)


def _save_calibrated(true, nominal, path, n=60):
    """``true`` as a calibrated robot file of ``nominal`` (with the calibration record compensate reads), by a fit
    to noise-free positions of ``true`` at n poses."""
    q = nominal.sample_joints(n, seed=0)
    res = kincal.calibrate(nominal, kincal.simulate(true, q, 0.0, 0), kincal.FitOptions(diagnose=False))
    kincal.save_robot(res.robot, str(path), calibration=res.record())


def _wrapped(q):
    return (q + np.pi) % (2 * np.pi) - np.pi


def test_ur10_closed_form_gives_the_eight_branches_a_numeric_search_finds():
    """The closed form's branches against an independent search: Newton from 400 spread starts finds
    the same solutions (joints modulo a turn), no more and no fewer."""
    from kincal.models.ur import ur_inverse

    nominal, _ = _ur10()
    q0 = np.array([0.3, -1.2, 1.4, -1.9, -1.5, 0.6])
    p, R, _, _ = nominal.pose_and_jacobian(q0[None])
    sols, ok = ur_inverse(nominal, p, R, q0[None])
    assert ok.sum() == 8
    starts = nominal.sample_joints(400, seed=11)
    found = solve_poses(nominal, np.repeat(p, 400, 0), np.repeat(R, 400, 0), starts, max_iter=300, max_travel=50.0)
    numeric = _wrapped(found.q[found.converged])
    distinct = [numeric[0]]
    for q in numeric[1:]:
        if min(np.abs(_wrapped(q - d)).max() for d in distinct) > 1e-6:
            distinct.append(q)
    closed = _wrapped(sols[0][ok[0]])
    assert len(distinct) == 8
    for q in distinct:  # every numeric solution is one of the closed form's, within 1e-8 rad
        assert min(np.abs(_wrapped(q - c)).max() for c in closed) < 1e-8


def _program(lines):
    return "def prog():\n" + "".join(f"  {line}\n" for line in lines) + "end\n"


def _checked_program(tmp_path, true, nominal, text, tcp=None):
    """The program compensated for ``true`` (the calibrated model), every target asserted on target
    through it within 1e-9 m and 1e-9 rad."""
    (tmp_path / "p.script").write_text(text)
    prog = read_program(str(tmp_path / "p.script"))
    models = (lambda t: (true.with_tool_point(t), nominal.with_tool_point(t))) if tcp is not None else None
    res = compensate_program(true, nominal, prog, models=models)
    assert res.problems == () and len(res.texts) == len(prog.targets)
    turn = np.eye(3) if tcp is None else Rotation.from_rotvec(tcp[3:]).as_matrix()
    model = true if tcp is None else true.with_tool_point(tcp[:3])
    for k, t in enumerate(prog.targets):
        p, R, _, _ = model.pose_and_jacobian(res.q[k][None])
        if t.kind == "pose":
            assert np.linalg.norm(p[0] - t.values[:3]) < 1e-9
            assert np.linalg.norm(rotation_log((R[0] @ turn)[None])[0] - t.values[3:]) < 1e-9
    return prog, res


def test_a_program_turning_joint_1_up_to_90_degrees_is_compensated_on_the_controllers_branch(tmp_path):
    """movej(q0) then movel to the nominal pose of q0 with joint 1 turned by 1 … 90 deg: every target
    compensated on the branch the controller takes (the nominal joints: q0 with joint 1 turned)."""
    nominal, true = _ur10()
    q0 = np.array([0.3, -1.2, 1.4, -1.9, -1.5, 0.6])
    turns = [1, 3, 5, 8, 12, 20, 40, 90]
    lines = []
    for deg in turns:
        q = q0 + np.deg2rad(deg) * np.eye(6)[0]
        lines += [f"movej({_fmt(q0, False)})", f"movel({_fmt(_pose(nominal, q), True)}, a=1.2, v=0.25)"]
    prog, res = _checked_program(tmp_path, true, nominal, _program(lines))
    from kincal.compensate.program import controller_inverse

    for k, deg in zip(range(1, 2 * len(turns), 2), turns):
        v = prog.targets[k].values
        q_nom = controller_inverse(nominal, v[None, :3], Rotation.from_rotvec(v[3:]).as_matrix()[None], q0)
        assert np.abs(q_nom - (q0 + np.deg2rad(deg) * np.eye(6)[0])).max() < 1e-9
        assert np.abs(res.q[k] - q_nom).max() < np.deg2rad(1)  # the correction stays on that branch


def test_a_pick_program_across_the_workspace_with_its_own_tcp(tmp_path):
    """Seven targets across the workspace (joint 1 over 200 deg) after set_tcp(p[…]) with a rotated
    TCP: all compensated; the TCP's point and rotation are the program's."""
    nominal, true = _ur10(seed=5)
    tcp = np.array([0.01, -0.02, 0.12, 0.0, 0.0, 0.5])
    home = np.array([0.0, -1.5, 1.5, -1.5, -1.5, 0.0])
    qs = [home + np.array([a, 0.2 * np.sin(a), -0.3 * np.cos(a), 0.2, 0.1 * a, 0.3]) for a in np.linspace(-1.7, 1.8, 7)]
    tooled = nominal.with_tool_point(tcp[:3])
    poses = []
    for q in qs:
        p, R, _, _ = tooled.pose_and_jacobian(q[None])
        poses.append(np.concatenate([p[0], rotation_log((R[0] @ Rotation.from_rotvec(tcp[3:]).as_matrix())[None])[0]]))
    lines = [f"set_tcp({_fmt(tcp, True)})", f"movej({_fmt(home, False)})"]
    lines += [f"movel({_fmt(v, True)})" if k % 2 else f"movej({_fmt(v, True)})" for k, v in enumerate(poses)]
    _checked_program(tmp_path, true, nominal, _program(lines), tcp=tcp)


def test_skip_unreachable_marks_each_target_left_as_is(tmp_path, capsys):
    """A pose 3 m away cannot be reached: refused and nothing written; with --skip-unreachable the
    program is written with a comment naming why beside that target, the rest compensated."""
    nominal, true = _ur10()
    _save_calibrated(true, nominal, tmp_path / "cal.yaml")
    q0 = np.array([0.3, -1.2, 1.4, -1.9, -1.5, 0.6])
    far = np.concatenate([[3.0, 0.0, 0.5], _pose(nominal, q0)[3:]])
    text = _program([f"movej({_fmt(q0, False)})", f"movel({_fmt(far, True)})  # too far",
                     f"movel({_fmt(_pose(nominal, q0 + 0.1), True)})"])
    (tmp_path / "p.script").write_text(text)
    base = ["compensate", str(tmp_path / "cal.yaml"), str(tmp_path / "p.script"), "--program", "ur", "-o",
            str(tmp_path / "out.script")]
    assert main(base) == 4 and not (tmp_path / "out.script").exists()  # refused: nothing written
    assert "refused: " in capsys.readouterr().out
    assert main(base + ["--skip-unreachable"]) == 0
    out = (tmp_path / "out.script").read_text().splitlines()
    assert out[2].endswith("# too far  # kincal: not compensated: the nominal model does not reach this pose on "
                           "any branch within the joint limits")
    assert "kincal" not in out[1] + out[3] and out[1] != text.splitlines()[1] and out[3] != text.splitlines()[3]


def test_design_writes_a_measurement_program_that_compensate_reads_whole(tmp_path, capsys):
    """design --program ur: movej through the designed poses (the CSV's joints to 1e-10 rad) with a
    wait at each, the predicted tool positions in the JSON (the forward kinematics at those joints);
    compensate --program ur reads every target as a literal and, with the nominal model as the
    calibrated one, writes the program back byte for byte."""
    import json

    out = tmp_path / "poses.csv"
    assert main(["design", "ur10", "-m", "12", "--pool", "400", "--tool", "0,0,100mm", "--settle", "1.5", "-o",
                 str(out), "--program", "ur", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    robot = kincal.load_robot("ur10").with_tool_point([0.0, 0.0, 0.1])
    q = kincal.read_joints(str(out), robot)
    prog = read_program(data["program"])
    assert prog.not_literal == () and [t.kind for t in prog.targets] == ["joints"] * 12
    assert np.abs(np.array([t.values for t in prog.targets]) - q).max() < 1e-10
    assert prog.text.count("sleep(1.5)") == 12
    assert np.abs(np.array(data["tool_positions"]) - robot.forward(q)).max() < 1e-12
    _save_calibrated(robot, robot, tmp_path / "ur10.yaml")  # its own nominal: corrections below the last digit
    assert main(["compensate", str(tmp_path / "ur10.yaml"), data["program"], "--program", "ur", "-o",
                 str(tmp_path / "again.script")]) == 0
    assert (tmp_path / "again.script").read_text() == prog.text


def test_a_program_written_in_millimetres_is_refused_with_that_cause(tmp_path):
    """URScript's set_tcp and poses are in metres: a TCP of p[0, 0, 109, …] and a pose of p[-572.3, …] are
    named as millimetres (not as a correction that did not converge, or a pose no branch reaches)."""
    nominal, true = _ur10()
    q0 = np.array([0.3, -1.2, 1.4, -1.9, -1.5, 0.6])
    pose = _pose(nominal, q0 + 0.1)
    in_mm = np.concatenate([pose[:3] * 1e3, pose[3:]])
    (tmp_path / "a.script").write_text(_program([f"movej({_fmt(q0, False)})", f"movel({_fmt(in_mm, True)})"]))
    res = compensate_program(true, nominal, read_program(str(tmp_path / "a.script"), "ur"))
    assert list(res.texts) == [0]
    assert res.refused[1] == (f"the pose is {np.linalg.norm(in_mm[:3]):g} m from the base: URScript's poses are in "
                              f"metres and radians")
    (tmp_path / "b.script").write_text(_program(["set_tcp(p[0, 0, 109, 0, 0, 0])", f"movej({_fmt(q0, False)})"]))
    res = compensate_program(true, nominal, read_program(str(tmp_path / "b.script"), "ur"),
                             models=lambda tcp: (true.with_tool_point(tcp), nominal.with_tool_point(tcp)))
    assert res.refused == {0: "the TCP set_tcp sets is 109 m from the flange: URScript's poses are in metres "
                              "(p[0, 0, 0.109, …] is 109 mm)"}


def test_a_program_for_another_robot_is_refused(tmp_path, capsys):
    """A KUKA calibration and a URScript program (or a folder of RAPID modules): refused, naming the robot's language
    from its robot file, nothing written; the UR program with a UR calibration is compensated."""
    kuka = kincal.load_robot("kuka_kr6r900sixx")
    _save_calibrated(kincal.perturb(kuka, seed=1), kuka, tmp_path / "kuka.yaml")
    ur = kincal.load_robot("ur5")
    _save_calibrated(kincal.perturb(ur, seed=1), ur, tmp_path / "ur.yaml")
    q0 = np.array([0.3, -1.2, 1.4, -1.9, -1.5, 0.6])
    (tmp_path / "p.script").write_text(_program([f"movej({_fmt(q0, False)})"]))
    base = [str(tmp_path / "p.script"), "--program", "ur", "-o", str(tmp_path / "out.script")]
    assert main(["compensate", str(tmp_path / "kuka.yaml"), *base]) == 1
    assert "robot 'kuka_kr6r900sixx' runs krl programs (its robot file says language: krl); this is a ur program" in \
        capsys.readouterr().err and not (tmp_path / "out.script").exists()
    (tmp_path / "rapid").mkdir()
    (tmp_path / "rapid" / "m.mod").write_text("MODULE m\nENDMODULE\n")
    assert main(["compensate", str(tmp_path / "kuka.yaml"), str(tmp_path / "rapid"), "--program", "rapid", "-o",
                 str(tmp_path / "new")]) == 1
    assert "this is a rapid program" in capsys.readouterr().err and not (tmp_path / "new").exists()
    assert main(["compensate", str(tmp_path / "ur.yaml"), *base]) == 0


def test_joint_targets_outside_the_limits_are_named_and_are_no_start(tmp_path):
    """A movej written in degrees: refused as outside the limits, looking like degrees (it said 'the corrected joints
    break the joint limits'), and it is no start for the pose moves after it, which are compensated (they were all
    refused as unreachable from joints of 91 rad)."""
    nominal, true = _ur10()
    q0 = np.array([0.3, -1.2, 1.4, -1.9, -1.5, 0.6])
    lines = [f"movej({_fmt(np.degrees(q0), False)})", f"movej({_fmt(q0, False)})"]
    lines += [f"movel({_fmt(_pose(nominal, q0 + 0.05 * k), True)})" for k in range(1, 4)]
    (tmp_path / "p.script").write_text(_program(lines))
    res = compensate_program(true, nominal, read_program(str(tmp_path / "p.script"), "ur"))
    assert list(res.refused) == [0] and sorted(res.texts) == [1, 2, 3, 4]
    why = res.refused[0]
    assert why.startswith("the target's own joints are outside the robot's limits: ")
    assert why.endswith("(URScript's joints are in radians; these look like degrees)")


def test_radians_just_beyond_a_limit_are_not_called_degrees(tmp_path):
    """movej with joint 6 at 7.0 rad (beyond ±2π): outside the limits, but read as degrees they would not be the
    joints the program means either way; no 'these look like degrees' (it said so whenever a value passed 2π)."""
    nominal, true = _ur10()
    q = np.array([0.1, -1.5, 1.4, -1.4, -1.57, 7.0])
    (tmp_path / "p.script").write_text(_program([f"movej({_fmt(q, False)})"]))
    why = compensate_program(true, nominal, read_program(str(tmp_path / "p.script"), "ur")).refused[0]
    assert why.startswith("the target's own joints are outside the robot's limits: ") and "degrees" not in why


def test_a_program_with_nothing_to_compensate_or_in_another_language(tmp_path, capsys):
    """A RAPID module read as KRL from a .txt (no move, no position found): refused naming the language; a KRL
    program whose only moves are to run-time variables: written as it was (it said '0 of 0' and exit 4 with no
    reason); a robtarget written in metres: its refusal asks whether it is; with --skip-unreachable a program whose
    every target is refused is written with each marked (it wrote nothing)."""
    abb, kuka = kincal.load_robot("abb_irb120"), kincal.load_robot("kuka_kr6r900sixx")
    _save_calibrated(kincal.perturb(abb, seed=1), abb, tmp_path / "abb.yaml")
    _save_calibrated(kincal.perturb(kuka, seed=1), kuka, tmp_path / "kuka.yaml")
    module = ("MODULE MT\n    CONST robtarget p1:=[[0.374,0.0,0.630],[0.7071068,0,0.7071068,0],[0,0,0,0],"
              "[9E9,9E9,9E9,9E9,9E9,9E9]];\n    PROC main()\n        MoveL p1,v100,fine,tool0;\n    ENDPROC\n"
              "ENDMODULE\n")
    (tmp_path / "sys.txt").write_text(module)
    assert main(["compensate", str(tmp_path / "kuka.yaml"), str(tmp_path / "sys.txt"), "--program", "krl", "-o",
                 str(tmp_path / "m.src")]) == 1
    assert "is it a krl program?" in capsys.readouterr().err and not (tmp_path / "m.src").exists()
    krl = "DEF run()\n  DECL E6POS goal\n  goal = $POS_ACT\n  LIN goal\nEND\n"
    (tmp_path / "run.src").write_text(krl)
    assert main(["compensate", str(tmp_path / "kuka.yaml"), str(tmp_path / "run.src"), "--program", "krl", "-o",
                 str(tmp_path / "run_cal.src")]) == 0
    said = capsys.readouterr().out
    assert "0 of 0 literal targets" in said and (tmp_path / "run_cal.src").read_text() == krl
    assert "TCP:" not in said and "orientation:" not in said  # no target: nothing was corrected, at no TCP
    (tmp_path / "mt.mod").write_text(module)
    base = ["compensate", str(tmp_path / "abb.yaml"), str(tmp_path / "mt.mod"), "--program", "rapid", "-o",
            str(tmp_path / "mt_cal.mod")]
    assert main(base) == 4 and not (tmp_path / "mt_cal.mod").exists()
    assert "(0.374, 0, 0.63 mm): written in metres?" in capsys.readouterr().out
    assert main(base + ["--skip-unreachable"]) == 0
    written = (tmp_path / "mt_cal.mod").read_text().splitlines()
    assert written[1].startswith(module.splitlines()[1]) and "not compensated" in written[1]


def test_a_pose_variable_moved_to_under_two_tcps_is_listed(tmp_path, capsys):
    """global home = p[…] moved to before set_tcp and again after it: one literal was corrected for the first TCP
    and the second move missed by 2.97 mm while '7 of 7 compensated' was printed; it is listed with why now, and
    a variable moved to under one TCP is compensated as before."""
    ur = kincal.load_robot("ur5")
    _save_calibrated(kincal.perturb(ur, seed=1), ur, tmp_path / "ur.yaml")
    q0 = np.array([0.3, -1.2, 1.4, -1.9, -1.5, 0.6])
    home = _fmt(_pose(ur, q0 + 0.05), True)
    two = _program([f"movej({_fmt(q0, False)})", f"global home = {home}", "movel(home)", "set_tcp(p[0, 0, 0.15, 0, 0, 0])",
                    "movej(home)"])
    (tmp_path / "two.script").write_text(two)
    prog = read_program(str(tmp_path / "two.script"))
    assert [t.variable for t in prog.targets] == [""]
    (line, what, why), = prog.not_literal
    assert what == "home" and "moved to under different TCPs (lines 4, 6" in why
    one = _program([f"movej({_fmt(q0, False)})", f"global home = {home}", "movel(home)", "movej(home)"])
    (tmp_path / "one.script").write_text(one)
    assert [t.variable for t in read_program(str(tmp_path / "one.script")).targets] == ["", "home"]


UR5_DH = ((0.089159, 0.0, np.pi / 2), (0.0, -0.425, 0.0), (0.0, -0.39225, 0.0), (0.10915, 0.0, np.pi / 2),
          (0.09465, 0.0, -np.pi / 2), (0.0823, 0.0, 0.0))  # the UR5's nominal DH (d, a, alpha), m and rad


def _ur5_tcp(q, tcp):
    """The nominal UR5's TCP frame (4x4) at joints q (6,) for a TCP (x, y, z) m on the flange: the textbook DH
    product, written here apart from kincal's models."""
    T = np.eye(4)
    for qj, (d, a, alpha) in zip(q, UR5_DH):
        ct, st, ca, sa = np.cos(qj), np.sin(qj), np.cos(alpha), np.sin(alpha)
        T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d],
                          [0, 0, 0, 1]])
    T[:3, 3] += T[:3, :3] @ np.asarray(tcp)
    return T


def _as_pose(T):
    return np.concatenate([T[:3, 3], Rotation.from_matrix(T[:3, :3]).as_rotvec()])


def test_set_tcp_reaches_the_moves_its_flow_reaches_not_those_after_it_in_the_text(tmp_path):
    """A set_tcp in a def never called (0.25 m) does not reach the moves written after it for the 0.15 m TCP: they
    were compensated for 0.25 m and the real 0.15 m TCP missed by 1.15-1.41 mm while "10 of 10 compensated" was
    printed. After a call of that def its TCP is in force; after an if/else that sets 0.15 m or 0.25 m no one TCP
    is, and the move is refused naming both set_tcp lines; after one whose branches both set 0.25 m it is known.
    Checked through the nominal UR5's own DH product here: the controller's inverse of each written pose, then the
    calibrated model there, within 1e-6 mm of the target; a joint target's TCP likewise."""
    nominal = kincal.load_robot("ur5")
    true = kincal.perturb(nominal, seed=2)
    a, b = np.array([0.0, 0.0, 0.15]), np.array([0.0, 0.0, 0.25])
    home = np.array([0.30, -1.43, 1.54, 0.0, 1.63, 0.0])
    qs = [home + k * np.array([0.06, 0.04, -0.05, 0.07, 0.05, 0.08]) for k in range(1, 5)]
    assert np.abs(_ur5_tcp(home, a)[:3, 3] - nominal.with_tool_point(a).forward(home[None])[0]).max() < 1e-12
    meant = [(home, a), (qs[0], a), (qs[1], b), (qs[2], b), (qs[3], b)]  # each move's joints and real TCP
    p = [_fmt(_as_pose(_ur5_tcp(q, tcp)), True) for q, tcp in meant]
    text = _program(["set_tcp(p[0, 0, 0.15, 0, 0, 0])", f"movej({_fmt(home, False)})", "def tool_b():",
                     "  set_tcp(p[0, 0, 0.25, 0, 0, 0])", "end", f"movel({p[1]})", "tool_b()", f"movel({p[2]})",
                     "if get_digital_in(0):", "  set_tcp(p[0, 0, 0.15, 0, 0, 0])", "else:", "  tool_b()", "end",
                     f"movel({p[3]})", "if get_digital_in(1):", "  set_tcp(p[0, 0, 0.25, 0, 0, 0])", "else:",
                     "  tool_b()", "end", f"movel({p[4]})"]) + "prog()\n"
    (tmp_path / "p.script").write_text(text)
    prog = read_program(str(tmp_path / "p.script"))
    res = compensate_program(true, nominal, prog,
                             models=lambda t: (true.with_tool_point(t), nominal.with_tool_point(t)))
    assert sorted(res.texts) == [0, 1, 2, 4] and list(res.refused) == [3]
    assert res.refused[3].startswith("its TCP is not known from the program's structure: the set_tcp on lines 5, 11 "
                                     "may be in force here")
    assert "line 15 (movel)" in res.problems[0]
    write_program(str(tmp_path / "out.script"), prog, res.texts, res.refused)
    new = read_program(str(tmp_path / "out.script"))
    assert new.targets[3].values.tolist() == prog.targets[3].values.tolist()  # refused: as it was, and marked
    assert "kincal: not compensated: its TCP is not known" in new.text.splitlines()[14]
    for k, (q, tcp) in enumerate(meant):
        if k == 3:
            continue
        written = new.targets[k].values
        if k == 0:  # a joint target: the calibrated TCP at the new joints is the nominal one at the old
            got = true.with_tool_point(tcp).forward(written[None])[0]
            assert np.linalg.norm(got - _ur5_tcp(q, tcp)[:3, 3]) * 1e3 < 1e-6
            continue
        goal = np.eye(4)
        goal[:3, :3], goal[:3, 3] = Rotation.from_rotvec(written[3:]).as_matrix(), written[:3]
        ik = least_squares(lambda x: np.concatenate([(_ur5_tcp(x, tcp) - goal)[:3, 3], Rotation.from_matrix(
            _ur5_tcp(x, tcp)[:3, :3] @ goal[:3, :3].T).as_rotvec()]), q, xtol=1e-15, ftol=1e-15, gtol=1e-15).x
        p_true, R_true, _, _ = true.with_tool_point(tcp).pose_and_jacobian(ik[None])
        target = _ur5_tcp(q, tcp)
        assert np.linalg.norm(p_true[0] - target[:3, 3]) * 1e3 < 1e-6
        assert np.linalg.norm(Rotation.from_matrix(R_true[0] @ target[:3, :3].T).as_rotvec()) < 1e-9


def test_set_tcp_in_a_loop_a_called_def_or_after_a_return_reaches_the_moves_its_paths_reach():
    """Each move's TCP by the program's paths: a loop's set_tcp reaches its start again (ambiguous there, known after
    it in the body); a def called under two TCPs has none known inside, and after its last call the caller's; a
    return before a def's set_tcp leaves its caller's TCP possible; a block never closed names its line."""
    from kincal.io.program_ur import parse

    a, b, j = "p[0, 0, 0.15, 0, 0, 0]", "p[0, 0, 0.25, 0, 0, 0]", "movej([0, -1.5, 1.5, -1.5, -1.5, 0])"

    def tcps(text):
        prog = parse("x.script", text)
        return [(t.line, v[2] if isinstance(v, np.ndarray) else v) for t in prog.targets for v in [prog.in_force_of(t)]]

    (l3, loop3), (l5, loop5), (l7, loop7) = tcps(f"set_tcp({a})\nwhile True:\n{j}\nset_tcp({b})\n{j}\nend\n{j}\n")
    assert "set_tcp on lines 1, 4 may be in force" in loop3 and loop5 == 0.25 and loop7 == loop3
    (_, inside), (_, after) = tcps(f"def mv():\n{j}\nend\nset_tcp({a})\nmv()\nset_tcp({b})\nmv()\n{j}\n")
    assert "set_tcp on lines 4, 6 may be in force" in inside and after == 0.25
    (_, back), = tcps(f"def f():\nif x:\nreturn\nend\nset_tcp({b})\nend\nset_tcp({a})\nf()\n{j}\n")
    assert "set_tcp on lines 5, 7 may be in force" in back
    (_, same), = tcps(f"if x:\nset_tcp({b})\nelif y:\nset_tcp({b})\nelse:\nset_tcp({b})\nend\n{j}\n")
    assert same == 0.25
    (_, before), = tcps(f"if x:\nset_tcp({b})\nend\n{j}\n")
    assert "set_tcp on line 2 or the TCP before any set_tcp may be in force" in before
    (_, broken), = tcps(f"set_tcp({a})\nif x:\n{j}\n")
    assert "line 2: this 'if' block is never closed with 'end'" in broken
