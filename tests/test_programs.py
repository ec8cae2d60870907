"""Robot programs compensated in place (URScript): every move kind, comments, variables and strings;
unchanged lines byte for byte, compensated literals equal to the pose-file route, non-literal targets
listed."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kincal
from kincal.cli import main
from kincal.compensate import compensate_program, solve_poses
from kincal.compensate.poses import rotation_log
from kincal.io import read_program, write_program


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
            "end\r\n")
    return nominal, true, home, qs, poses, text


def test_every_move_kind_is_found_and_only_literals(tmp_path, setting):
    nominal, true, home, qs, poses, text = setting
    (tmp_path / "prog.script").write_bytes(text.encode())
    prog = read_program(str(tmp_path / "prog.script"))
    assert [(t.move, t.kind, t.line) for t in prog.targets] == [
        ("movej", "joints", 3), ("movel", "pose", 6), ("movep", "pose", 7), ("movec", "pose", 8),
        ("movec", "pose", 8), ("servoj", "joints", 9)]
    assert prog.not_literal == ((5, "movel", "target"),)
    assert prog.with_targets({}) == text  # nothing replaced: the same bytes


def test_compensated_program_keeps_every_other_byte_and_matches_the_pose_route(tmp_path, setting):
    nominal, true, home, qs, poses, text = setting
    (tmp_path / "prog.script").write_bytes(text.encode())
    prog = read_program(str(tmp_path / "prog.script"))
    res = compensate_program(true, nominal, prog)
    assert res.problems == () and len(res.texts) == 6
    write_program(str(tmp_path / "out.script"), prog, res.texts)
    out = (tmp_path / "out.script").read_bytes().decode()
    old_lines, new_lines = text.split("\r\n"), out.split("\r\n")
    changed = {t.line for t in prog.targets}
    assert len(old_lines) == len(new_lines)
    for k, (a, b) in enumerate(zip(old_lines, new_lines), start=1):
        assert (a == b) != (k in changed), (k, a, b)  # unchanged lines byte for byte; target lines changed
    # joint targets: the same as compensating the pose the nominal model reaches there (the pose-file route)
    for k, q in ((0, home), (5, qs[4])):
        p, R, _, _ = nominal.pose_and_jacobian(q[None])
        comp = kincal.compensate(true, p, q[None], rotations=R, nominal=nominal)
        assert np.abs(res.q[k] - comp.q[0]).max() < 1e-9
    # pose targets: the controller's IK of the written pose gives joints at which the real robot is on target
    new = read_program(str(tmp_path / "out.script"))
    start = home
    for k in (1, 2, 3, 4):
        v = new.targets[k].values
        ik = solve_poses(nominal, v[None, :3], Rotation.from_rotvec(v[3:]).as_matrix()[None], start[None])
        pt, Rt, _, _ = true.pose_and_jacobian(ik.q)
        assert np.linalg.norm(pt[0] - poses[k][:3]) < 1e-6
        assert np.linalg.norm(rotation_log(Rt)[0] - poses[k][3:]) < 1e-6
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
    assert "6 of 6 literal targets compensated" in out and "line 5 movel(target, …)" in out
    new = read_program(str(tmp_path / "out.script"))
    assert 1e-5 < np.abs(new.targets[0].values - home).max() < np.deg2rad(5)  # corrected, same branch
