"""Frames taught on the robot, corrected as measurements (kincal.compensate.taught): a tool taught by four flange
poses on one point and a base taught by three points, on a 'true' arm (the calibrated model), give the controller
frames its nominal model computes and the physical ones; a program in them, compensated, lands on the true arm
where it means (the controller's frames and the landing computed here by other formulas: the tool from pairwise
differences, the base by Gram-Schmidt); a frame written in the file that its joints contradict is refused."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kincal
from kincal.compensate import solve_poses
from kincal.compensate.branch import compensate_branches, controller_inverse
from kincal.io import BITS, ROWS, read_frames, read_program

TOOL = np.array([0.012, -0.004, 0.18])  # the real TCP in the flange
BASE = np.eye(4)
BASE[:3, :3], BASE[:3, 3] = Rotation.from_euler("ZYX", [25, 2, -1], degrees=True).as_matrix(), [0.55, -0.1, 0.2]
START = np.radians([0, -80, 100, 0, 60, 0])


def _arms():
    nominal = kincal.load_robot("kuka_kr6r900sixx").with_tool_point(np.zeros(3))
    return nominal, kincal.perturb(nominal, seed=11).with_tool_point(np.zeros(3))


def _reach(robot, p_tcp, R):
    """Joints putting the flange at R with the real TCP on p_tcp (Newton from START)."""
    sol = solve_poses(robot, (p_tcp - R @ TOOL)[None], R[None], START[None], max_iter=200, max_travel=20.0)
    assert sol.converged[0]
    return sol.q[0]


def _teach(true):
    """The teach poses, reached by the true arm: four flange turns on one point (the tool), then the base's
    origin, a point on its +x and one in its xy plane, the tool pointing down."""
    down = Rotation.from_euler("y", 180, degrees=True)
    turns = [down * Rotation.from_euler("xyz", a, degrees=True) for a in ([0, 0, 0], [25, 0, 0], [0, 30, 40],
                                                                           [-20, -15, 90])]
    tool = [_reach(true, np.array([0.5, 0.05, 0.25]), r.as_matrix()) for r in turns]
    points = [BASE[:3, :3] @ v + BASE[:3, 3] for v in ([0, 0, 0], [0.25, 0, 0], [0.15, 0.2, 0])]
    base = [_reach(true, p, down.as_matrix()) for p in points]
    return np.array(tool), np.array(base)


def _frames_file(path, tool_q, base_q, declared=""):
    """The frames file: the tool as the controller shows it (its own fit of the four poses: here the pairwise
    differences of _controller_frames) and how it was taught; the base taught with it."""
    rows = lambda q: "[" + ", ".join("[" + ", ".join(f"{v:.12f}" for v in np.degrees(x)) + "]" for x in q) + "]"  # noqa: E731
    t = _controller_frames(_arms()[0], tool_q, base_q)[0][:3, 3] * 1e3
    path.write_text(f"TOOL_NO 1: {{x: {t[0]:.9f}, y: {t[1]:.9f}, z: {t[2]:.9f}, "
                    f"taught: {{rule: fixed-point, joints: {rows(tool_q)}}}}}\n"
                    f"BASE_NO 2: {{{declared}taught: {{rule: origin-x-xy, tool: TOOL_NO 1, joints: {rows(base_q)}}}}}\n")


def _flange(robot, q):
    p, R, _, _ = robot.pose_and_jacobian(np.atleast_2d(q))
    return p, R


def _controller_frames(nominal, tool_q, base_q):
    """The controller's tool and base, computed here: the TCP from (R_i - R_0) t = p_0 - p_i, the base by
    Gram-Schmidt on the three TCP positions."""
    p, R = _flange(nominal, tool_q)
    t = np.linalg.lstsq((R[1:] - R[0]).reshape(-1, 3), (p[0] - p[1:]).reshape(-1), rcond=None)[0]
    U = np.eye(4)
    U[:3, 3] = t
    p, R = _flange(nominal, base_q)
    P = p + R @ t
    x = (P[1] - P[0]) / np.linalg.norm(P[1] - P[0])
    y = (P[2] - P[0]) - ((P[2] - P[0]) @ x) * x
    y /= np.linalg.norm(y)
    B = np.eye(4)
    B[:3, :3], B[:3, 3] = np.column_stack([x, y, np.cross(x, y)]), P[0]
    return U, B


def test_a_program_in_taught_frames_lands_where_it_means(tmp_path):
    nominal, true = _arms()
    tool_q, base_q = _teach(true)
    _frames_file(tmp_path / "frames.yaml", tool_q, base_q)
    frames = read_frames(str(tmp_path / "frames.yaml"))
    U_c, B_c = _controller_frames(nominal, tool_q, base_q)
    U_true = np.eye(4)
    U_true[:3, 3] = TOOL
    q = np.radians([[10, -80, 100, 20, 40, 30], [-25, -100, 110, -30, -50, 60], [30, -70, 90, 60, 45, -100]])
    _program(tmp_path / "taught.dat", nominal, true, BASE, U_true, q)  # meant in the real fixture, for the real tool
    prog = read_program(str(tmp_path / "taught.dat"), "krl")
    res = compensate_branches(true, nominal, prog, ROWS["krl"], frames)
    assert not res.problems and len(res.texts) == 3
    (tmp_path / "out.dat").write_text(prog.with_targets(res.texts))
    for old, new, qk in zip(prog.targets, read_program(str(tmp_path / "out.dat"), "krl").targets, q):
        meant = BASE @ _pose(old.values) @ np.linalg.inv(U_true)  # the real flange pose the target means
        sent = B_c @ _pose(new.values) @ np.linalg.inv(U_c)  # what the controller turns the written target into
        q_ctrl = controller_inverse(nominal, sent[None, :3, 3], sent[None, :3, :3], qk, new.config, BITS["krl"])
        p, R = _flange(true, q_ctrl)
        assert np.linalg.norm(p[0] - meant[:3, 3]) < 1e-8
        assert np.linalg.norm(Rotation.from_matrix(R[0] @ meant[:3, :3].T).as_rotvec()) < 1e-8
    # the controller's frames taken as the real ones (nothing taught): the flange would be sent this far off
    miss = [np.linalg.norm((B_c @ _pose(t.values) @ np.linalg.inv(U_c) - BASE @ _pose(t.values)
                            @ np.linalg.inv(U_true))[:3, 3]) for t in prog.targets]
    assert min(miss) > 1e-4  # a tenth of a millimetre and more: what the correction of the taught frames is worth


def _pose(v):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_rotvec(v[3:]).as_matrix(), v[:3]
    return T


def test_a_written_frame_its_joints_contradict_is_refused(tmp_path):
    nominal, true = _arms()
    tool_q, base_q = _teach(true)
    U_c, B_c = _controller_frames(nominal, tool_q, base_q)
    v = np.concatenate([B_c[:3, 3] * 1e3, Rotation.from_matrix(B_c[:3, :3]).as_euler("ZYX", degrees=True)])
    good = f"x: {v[0]:.4f}, y: {v[1]:.4f}, z: {v[2]:.4f}, rz: {v[3]:.5f}, ry: {v[4]:.5f}, rx: {v[5]:.5f}, "
    wrong = f"x: {v[0] + 0.5:.4f}, y: {v[1]:.4f}, z: {v[2]:.4f}, rz: {v[3]:.5f}, ry: {v[4]:.5f}, rx: {v[5]:.5f}, "
    _program(tmp_path / "one.dat", nominal, nominal, B_c, U_c, np.radians([[10, -80, 100, 20, 40, 30]]))
    prog = read_program(str(tmp_path / "one.dat"), "krl")
    for declared, ok in ((good, True), (wrong, False)):
        _frames_file(tmp_path / "frames.yaml", tool_q, base_q, declared)
        res = compensate_branches(true, nominal, prog, ROWS["krl"], read_frames(str(tmp_path / "frames.yaml")))
        if ok:
            assert not res.problems
        else:
            assert res.refused[0].startswith("its base frame 'BASE_NO 2' is not known: as written it is 0.500 mm")


def _program(path, nominal, robot, B, U, q):
    """A .dat of E6POS targets in TOOL_NO 1 / BASE_NO 2: where ``robot`` puts the TCP U at joints q (N, 6), in B,
    with the nominal arm's S/T at q."""
    lines = ["DEFDAT  TAUGHT"]
    for k, qk in enumerate(q, 1):
        p, R = _flange(robot, qk)
        F = np.eye(4)
        F[:3, :3], F[:3, 3] = R[0], p[0]
        T = np.linalg.inv(B) @ F @ U
        a, b, c = Rotation.from_matrix(T[:3, :3]).as_euler("ZYX", degrees=True)
        s, t = BITS["krl"](nominal, qk)
        x, y, z = T[:3, 3] * 1e3
        lines += [f"DECL E6POS XP{k}={{X {x:.6f},Y {y:.6f},Z {z:.6f},A {a:.7f},B {b:.7f},C {c:.7f},S {s},T {t}}}",
                  f"DECL FDAT FP{k}={{TOOL_NO 1,BASE_NO 2}}"]
    path.write_text("\n".join(lines + ["ENDDAT", ""]))


@pytest.mark.parametrize("entry, says", [
    ("B: {taught: {rule: origin-x-xy, joints: [[0, 0, 0, 0, 0, 0]]}}", "takes 3 teach poses, not 1"),
    ("B: {taught: {rule: origin-x-xy, joints: [[0,0,0,0,0,0],[0,0,0,0,0,1],[0,0,0,0,1,0]]}}", "names the tool"),
    ("B: {taught: {rule: three-point, joints: [[0]]}}", "needs {rule: origin-x-xy | x1-x2-y1 | fixed-point"),
    ("B: {taught: {rule: x1-x2-y1, tool: T9, joints: [[0,0,0,0,0,0],[0,0,0,0,0,1],[0,0,0,0,1,0]]}}",
     "taught with tool 'T9', which the file does not give"),
    ("T: {z: 100, taught: {rule: fixed-point, joints: [[0, 0], [0, 1], [1, 0], [1]]}}", "each a list of joint values"),
    ("T: {taught: {rule: fixed-point, joints: [[0, 0], [0, 1], [1, 0], [1, 1]]}}", "a taught tool needs its x, y, z"),
])
def test_a_broken_taught_entry_is_named(tmp_path, entry, says):
    path = tmp_path / "frames.yaml"
    path.write_text(entry + "\n")
    with pytest.raises(ValueError, match=re_escape(says)):
        read_frames(str(path))


def re_escape(s):
    import re
    return re.escape(s)


def test_teach_poses_of_another_joint_count_refuse_the_frame_with_the_reason(tmp_path):
    nominal, true = _arms()
    tool_q, base_q = _teach(true)
    import yaml

    _frames_file(tmp_path / "frames.yaml", tool_q, base_q)
    entries = yaml.safe_load((tmp_path / "frames.yaml").read_text())
    entries["TOOL_NO 1"]["taught"]["joints"] = [q[:5] for q in entries["TOOL_NO 1"]["taught"]["joints"]]  # 5 of 6
    (tmp_path / "frames.yaml").write_text(yaml.safe_dump(entries))
    U_c, B_c = _controller_frames(nominal, tool_q, base_q)
    _program(tmp_path / "one.dat", nominal, nominal, B_c, U_c, np.radians([[10, -80, 100, 20, 40, 30]]))
    res = compensate_branches(true, nominal, read_program(str(tmp_path / "one.dat"), "krl"), ROWS["krl"],
                              read_frames(str(tmp_path / "frames.yaml")))
    assert res.refused[0].startswith("its tool frame 'TOOL_NO 1' is not known: its teach poses do not fit this robot")
