"""Frames taught on the robot, corrected as measurements (kincal.compensate.taught): a tool taught by four flange
poses on one point and a base taught by three points, on a 'true' arm (the calibrated model), give the controller
frames its nominal model computes and the physical ones; a program in them, compensated, lands on the true arm
where it means (the controller's frames and the landing computed here by other formulas: the tool from pairwise
differences, the base by Gram-Schmidt); a frame written in the file that its joints contradict is refused."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kincal
from kincal.compensate import command_models, resolve_taught, solve_poses, tool_carry
from kincal.compensate.branch import compensate_branches, controller_inverse
from kincal.compensate.taught import tool_pair
from kincal.io import BITS, ROWS, TaughtFrame, read_frames, read_program

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


def _controller_frames(nominal, tool_q, base_q, U=None):
    """The controller's tool and base, computed here: the TCP from (R_i - R_0) t = p_0 - p_i (unless given: U),
    the base by Gram-Schmidt on the three TCP positions."""
    if U is None:
        p, R = _flange(nominal, tool_q)
        t = np.linalg.lstsq((R[1:] - R[0]).reshape(-1, 3), (p[0] - p[1:]).reshape(-1), rcond=None)[0]
        U = np.eye(4)
        U[:3, 3] = t
    t = U[:3, 3]
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


HELD = ("a1.theta", "a1.d", "a1.a", "a1.alpha", "a6.theta", "flange.theta", "flange.alpha")  # what a point on the
# flange's axis cannot tell from the base frame (the first four) or turns of the flange it does not see
POINT, LEVER = np.array([0.0, 0.0, 0.03]), np.array([0.01, -0.02, 0.12])  # the measured point; the TCP from it


def _carried_case():
    """A KR 6 measured at POINT (30 mm out on the flange's axis), calibrated from 200 noise-free points of a true
    arm whose HELD parameters are nominal: the calibrated model in the robot's base frame is the true arm's up to its
    flange, off by a translation (the last link's) that the fitted point takes up; the true TCP, LEVER beyond the
    point, shares it. Returns the nominal arm, the true one, the calibration, both models for commands and the carry
    (m)."""
    nominal = kincal.load_robot("kuka_kr6r900sixx").with_tool_point(POINT)
    true = kincal.perturb(nominal, seed=2, names=[n for n in nominal.params.names
                                                  if n not in HELD and n not in nominal.base_params()])
    fit = kincal.calibrate(nominal, kincal.simulate(true, nominal.sample_joints(200, seed=1), 0.0),
                           kincal.FitOptions(diagnose=False))
    model, nom = command_models(fit.robot, fit.record()["nominal"])
    return nominal, true, fit, (model, nom), tool_carry(model.tool_point(), nom.tool_point())[0]


def _true_teach(true, tool_tcp):
    """The true arm's joints putting the true TCP (``tool_tcp`` (3,) m in its flange) on the true fixture's origin,
    a point on its +x and one in its xy plane (the base's), and four times on one point (the tool's), pointing down."""
    flange = true.with_tool_point(np.zeros(3))

    def reach(p, R):
        sol = solve_poses(flange, (p - R @ tool_tcp)[None], R[None], START[None], max_iter=200, max_travel=20.0)
        assert sol.converged[0]
        return sol.q[0]

    down = Rotation.from_euler("y", 180, degrees=True)
    base_q = [reach(BASE[:3, :3] @ v + BASE[:3, 3], down.as_matrix()) for v in ([0, 0, 0], [0.25, 0, 0],
                                                                                  [0.15, 0.2, 0])]
    tool_q = [reach(np.array([0.5, 0.05, 0.25]), (down * Rotation.from_euler("xyz", a, degrees=True)).as_matrix())
              for a in ([0, 0, 0], [25, 0, 0], [0, 30, 40], [-20, -15, 90])]
    return np.array(base_q), np.array(tool_q)


@pytest.mark.parametrize("taught_tool", [False, True])
def test_a_taught_base_and_the_programs_tcp_take_the_calibrations_move_of_the_measured_point_alike(tmp_path,
                                                                                                   taught_tool):
    """A base taught with a TCP 150 mm out (LEVER beyond the measured point), given by its values or taught itself;
    a program in it for that TCP, meant in the true fixture. The calibration moved the measured point by 0.488 mm
    (the last link's error, carried over to the TCP). Each frame and program TCP now takes that move once: the
    physical base is the true one and the true arm's TCP at the written commands' controller joints is on the
    targets (to 1e-9 m). Before, a base taught with a given tool took none of it, or a taught tool took it twice
    (its physical frame, from the calibrated model, holds it already): the true TCP 0.488 mm off every target."""
    nominal, true, _, (model, nom), shift = _carried_case()
    assert 0.4e-3 < np.linalg.norm(shift) < 1e-3  # carried over (a link's error)
    flange, true_flange = nominal.with_tool_point(np.zeros(3)), true.with_tool_point(np.zeros(3))
    U_true = np.eye(4)
    U_true[:3, 3] = true.tool_point() + LEVER  # the TCP in the true flange
    base_q, tool_q = _true_teach(true, U_true[:3, 3])
    frames = {"BASE_NO 2": TaughtFrame("BASE_NO 2", "origin-x-xy", base_q, "TOOL_NO 1", None)}
    U_c = np.eye(4)
    U_c[:3, 3] = POINT + LEVER  # the controller's TCP, given by its values
    if taught_tool:
        U_c = _controller_frames(flange, tool_q, base_q)[0]  # the controller's own fit of the nominal poses
        frames["TOOL_NO 1"] = TaughtFrame("TOOL_NO 1", "fixed-point", tool_q, "", U_c)
    else:
        frames["TOOL_NO 1"] = U_c
    B_c = _controller_frames(flange, tool_q, base_q, U_c)[1]
    q = np.radians([[10, -80, 100, 20, 40, 30], [-25, -100, 110, -30, -50, 60], [30, -70, 90, 60, 45, -100]])
    _program(tmp_path / "t.dat", nominal, true_flange, BASE, U_true, q)  # meant in the true fixture, true TCP
    prog = read_program(str(tmp_path / "t.dat"), "krl")
    res = compensate_branches(model, nom, prog, ROWS["krl"], frames, carry=shift)
    assert not res.problems and len(res.texts) == 3
    (tmp_path / "out.dat").write_text(prog.with_targets(res.texts))
    for old, new, qk in zip(prog.targets, read_program(str(tmp_path / "out.dat"), "krl").targets, q):
        sent = B_c @ _pose(new.values) @ np.linalg.inv(U_c)  # what the controller turns the written target into
        q_ctrl = controller_inverse(flange, sent[None, :3, 3], sent[None, :3, :3], qk, new.config, BITS["krl"])
        p, R = _flange(true_flange, q_ctrl)
        assert np.linalg.norm(p[0] + R[0] @ U_true[:3, 3] - (BASE @ _pose(old.values))[:3, 3]) < 1e-9  # was 0.488 mm
    resolved = resolve_taught(frames, nom.with_tool_point(np.zeros(3)), model, carry=shift)
    tool, base = tool_pair(resolved["TOOL_NO 1"], shift)[1], resolved["BASE_NO 2"][1]  # the physical frames
    assert np.linalg.norm(base[:3, 3] - BASE[:3, 3]) < 1e-9  # the physical base is the true fixture (was 0.488 mm)
    assert np.linalg.norm(Rotation.from_matrix(base[:3, :3] @ BASE[:3, :3].T).as_rotvec()) < 1e-9
    p_cal, R_cal = _flange(model.with_tool_point(np.zeros(3)), q[:1])
    p_true, R_true = _flange(true_flange, q[:1])
    here = R_cal[0].T @ (p_true[0] + R_true[0] @ U_true[:3, 3] - p_cal[0])  # the true TCP in the calibrated flange
    assert np.linalg.norm(tool[:3, 3] - here) < 1e-9  # a taught tool's own, a given one's carried: the true TCP
    assert np.linalg.norm(here - (POINT + LEVER + shift)) < 1e-9  # the carry of a given tool is that move


def test_the_command_line_says_how_far_a_base_taught_with_a_given_tcp_really_is(tmp_path, capsys):
    """kincal compensate --program krl --frames after the calibration of _carried_case: a base taught with TOOL_NO 1
    given by its values (150 mm out). The line on the taught base names how far the true fixture is from the
    controller's base (0.759 mm; 0.727 before, the base computed without the carry the program's TCP takes), and
    the written program puts the true TCP on its targets to the text's rounding (0.488 mm off before)."""
    from kincal.cli import main

    nominal, true, fit, _, _ = _carried_case()
    kincal.save_robot(fit.robot, tmp_path / "cal.yaml", calibration=fit.record())
    flange, true_flange = nominal.with_tool_point(np.zeros(3)), true.with_tool_point(np.zeros(3))
    U_true, U_c = np.eye(4), np.eye(4)
    U_true[:3, 3], U_c[:3, 3] = true.tool_point() + LEVER, POINT + LEVER
    base_q, _ = _true_teach(true, U_true[:3, 3])
    rows = ", ".join("[" + ", ".join(f"{v:.12f}" for v in np.degrees(x)) + "]" for x in base_q)
    x, y, z = U_c[:3, 3] * 1e3
    (tmp_path / "frames.yaml").write_text(
        f"TOOL_NO 1: {{x: {x:.9f}, y: {y:.9f}, z: {z:.9f}}}\n"
        f"BASE_NO 2: {{taught: {{rule: origin-x-xy, tool: TOOL_NO 1, joints: [{rows}]}}}}\n")
    q = np.radians([[10, -80, 100, 20, 40, 30], [-25, -100, 110, -30, -50, 60], [30, -70, 90, 60, 45, -100]])
    _program(tmp_path / "t.dat", nominal, true_flange, BASE, U_true, q)
    capsys.readouterr()
    assert main(["compensate", str(tmp_path / "cal.yaml"), str(tmp_path / "t.dat"), "--program", "krl", "--frames",
                 str(tmp_path / "frames.yaml"), "-o", str(tmp_path / "out.dat")]) == 0
    said = capsys.readouterr().out
    B_c = _controller_frames(flange, None, base_q, U_c)[1]
    assert "orientation: from the calibrated model" in said
    assert (f"taught frame BASE_NO 2: corrected as a measurement: its origin really is "
            f"{np.linalg.norm(BASE[:3, 3] - B_c[:3, 3]) * 1e3:.3f} mm from the controller's") in said
    misses = []
    for old, new, qk in zip(read_program(str(tmp_path / "t.dat"), "krl").targets,
                            read_program(str(tmp_path / "out.dat"), "krl").targets, q):
        sent = B_c @ _pose(new.values) @ np.linalg.inv(U_c)
        q_ctrl = controller_inverse(flange, sent[None, :3, 3], sent[None, :3, :3], qk, new.config, BITS["krl"])
        p, R = _flange(true_flange, q_ctrl)
        misses.append(np.linalg.norm(p[0] + R[0] @ U_true[:3, 3] - (BASE @ _pose(old.values))[:3, 3]))
    assert max(misses) < 1e-9, misses  # was 0.488 mm


@pytest.mark.parametrize("in_radians", ["BASE_NO 2", "TOOL_NO 1"])
def test_teach_poses_written_in_radians_are_refused_naming_the_frame(tmp_path, in_radians):
    """The teach poses of a taught frame are in the file's angle unit (degrees unless it says otherwise). Written in
    radians, a base was taken as a measurement 1.6 mm off and its targets refused for 'no branch with the target's
    bits', a tool as '291 mm from ... not the joints, tool, rule or robot': now refused when read, by the readers'
    own check (every value within ±2π as written, kincal.models.unit_checks.radians_as_degrees), naming the frame; the
    same joints in degrees, or in radians with 'units: {angle: rad}', give the same frames."""
    nominal, true = _arms()
    tool_q, base_q = _teach(true)
    _frames_file(tmp_path / "deg.yaml", tool_q, base_q)
    text = (tmp_path / "deg.yaml").read_text().splitlines()
    k = 0 if in_radians == "TOOL_NO 1" else 1
    q = tool_q if k == 0 else base_q
    rows = "[" + ", ".join("[" + ", ".join(f"{v:.12f}" for v in x) + "]" for x in q) + "]"  # radians, as numbers
    text[k] = text[k].split("joints: ")[0] + f"joints: {rows}}}}}"
    (tmp_path / "mix.yaml").write_text("\n".join(text) + "\n")
    with pytest.raises(ValueError) as err:
        read_frames(str(tmp_path / "mix.yaml"))
    said = str(err.value)
    assert f"frame {in_radians!r}: the joints of its {len(q)} teach poses all lie within ±6.28 as written" in said
    assert f"(largest {np.abs(q).max():.4g})" in said and "they look like radians; write them in degrees" in said
    degrees = read_frames(str(tmp_path / "deg.yaml"))
    np.testing.assert_allclose(degrees[in_radians].joints, q, atol=1e-12)
    as_rad = lambda qq: "[" + ", ".join("[" + ", ".join(f"{v:.12f}" for v in x) + "]" for x in qq) + "]"  # noqa: E731
    both = [line.split("joints: ")[0] + f"joints: {as_rad(qq)}}}}}" for line, qq in zip(text, (tool_q, base_q))]
    (tmp_path / "rad.yaml").write_text("units: {angle: rad}\n" + "\n".join(both) + "\n")  # said so: the same frames
    rad = read_frames(str(tmp_path / "rad.yaml"))
    for name in ("TOOL_NO 1", "BASE_NO 2"):
        np.testing.assert_allclose(rad[name].joints, degrees[name].joints, atol=1e-11)
