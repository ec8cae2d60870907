"""Programs whose targets state their branch, compensated on it (kincal.compensate.branch): a KRL module of
E6POS (S/T) and E6AXIS targets written from a nominal arm's poses, compensated for a perturbed arm. Checked
independently of the module's own check: the text read again, each Cartesian target turned into joints on its
bits and moved through the perturbed arm, lands on the pose the original text meant."""
import dataclasses
import sys

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

import kincal
from kincal.compensate import command_models, tool_carry
from kincal.compensate.branch import compensate_branches, controller_inverse
from kincal.io import dialects, read_program

from conftest import skeleton
from test_taught_frames import _program


def config_of(robot, q):
    """A KUKA-like (S, T) for the UR10 of the test, naming each of its eight branches: S bit 0 the shoulder (the
    wrist behind the first axis, in the frame joint 1 turns), bit 1 the elbow (j3 < 0), bit 2 the wrist (j5 < 0);
    T bit i: joint i+1 negative (so whole turns are told apart)."""
    q = np.asarray(q, dtype=float)
    wrist = robot.link_points(q[None])[0, 4]  # (elbow and wrist as sin < 0: the UR10 turns them beyond 180 deg)
    behind = np.cos(q[0]) * wrist[0] + np.sin(q[0]) * wrist[1] < 0
    s = int(behind) + 2 * int(np.sin(q[2]) < 0) + 4 * int(np.sin(q[4]) < 0)
    return s, int(sum(1 << i for i in range(6) if q[i] < 0))


def rows(robot, q):
    """The test's bits of each row of q (N, 6)."""
    return [config_of(robot, qk) for qk in q]


TOOL = np.eye(4)
TOOL[:3, :3] = Rotation.from_euler("x", 30, degrees=True).as_matrix()
TOOL[:3, 3] = [0.01, -0.02, 0.15]  # a tool 150 mm long, turned 30 deg
BASE = np.eye(4)
BASE[:3, 3] = [0.3, -0.1, 0.05]


def _arms():
    nominal = kincal.load_robot("ur10")
    return nominal, kincal.perturb(nominal, seed=4)


def _module(nominal, q):
    """A .dat with one E6POS per joint vector (the TCP in BASE, mm and deg, its S/T) and one E6AXIS."""
    lines = ["DEFDAT  TEST PUBLIC"]
    for k, qk in enumerate(q, 1):
        p, R, _, _ = nominal.with_tool_point(np.zeros(3)).pose_and_jacobian(qk[None])
        flange = np.eye(4)
        flange[:3, :3], flange[:3, 3] = R[0], p[0]
        T = np.linalg.inv(BASE) @ flange @ TOOL
        a, b, c = Rotation.from_matrix(T[:3, :3]).as_euler("ZYX", degrees=True)
        s, t = config_of(nominal, qk)
        x, y, z = T[:3, 3] * 1e3
        lines += [f"DECL E6POS XP{k}={{X {x:.4f},Y {y:.4f},Z {z:.4f},A {a:.4f},B {b:.4f},C {c:.4f},S {s},T {t},"
                  f"E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}}",
                  f"DECL FDAT FP{k}={{TOOL_NO 1,BASE_NO 2,IPO_FRAME #BASE,POINT2[] \" \"}}"]
    axes = ",".join(f"A{i + 1} {v:.5f}" for i, v in enumerate(np.degrees(q[0])))
    lines += [f"DECL E6AXIS XHOME={{{axes},E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}}", "ENDDAT", ""]
    return "\r\n".join(lines)


def _intended(nominal, values):
    """The flange pose (p (3,), R (3, 3)) a Cartesian target means: BASE · T · TOOL⁻¹."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_rotvec(values[3:]).as_matrix(), values[:3]
    F = BASE @ T @ np.linalg.inv(TOOL)
    return F[:3, 3], F[:3, :3]


def test_cartesian_and_joint_targets_land_where_the_program_meant_on_their_own_branch(tmp_path):
    nominal, true = _arms()
    rng = np.random.default_rng(2)
    q = rng.uniform(-2.5, 2.5, (6, 6)) * [1, 0.6, 0.8, 1, 1, 1]
    path = tmp_path / "test.dat"
    path.write_bytes(_module(nominal, q).encode())
    prog = read_program(str(path), "krl")
    assert [t.kind for t in prog.targets] == ["pose"] * 6 + ["joints"]
    frames = {"TOOL_NO 1": TOOL, "BASE_NO 2": BASE}
    res = compensate_branches(true, nominal, prog, rows, frames=frames, q_start=q[0])
    assert not res.problems and len(res.texts) == 7
    out = tmp_path / "test_cal.dat"
    kincal.io.write_program(str(out), prog, res.texts)
    again = read_program(str(out), "krl")
    flange = [m.with_tool_point(np.zeros(3)) for m in (nominal, true)]
    for old, new, qk in zip(prog.targets[:6], again.targets[:6], q):
        assert new.config == old.config  # the bits as written, and the corrected joints have them too
        p, R = _intended(nominal, old.values)
        pn, Rn = _intended(nominal, new.values)
        q_ctrl = controller_inverse(flange[0], pn[None], Rn[None], qk, new.config, config_of)
        assert not isinstance(q_ctrl, str) and config_of(nominal, q_ctrl) == old.config
        pt, Rt, _, _ = flange[1].pose_and_jacobian(q_ctrl[None])
        assert np.linalg.norm(pt[0] - p) < 1e-9  # m: within 1e-6 mm
        assert np.linalg.norm(Rotation.from_matrix(Rt[0] @ R.T).as_rotvec()) < 1e-9
        assert 1e-5 < np.linalg.norm(pn - p) < 0.02  # the target moved, by a calibration's few mm
    home = again.targets[6].values  # the joint target: the true arm's pose there is the nominal one at the old joints
    pa, Ra, _, _ = flange[1].pose_and_jacobian(home[None])
    pb, Rb, _, _ = flange[0].pose_and_jacobian(prog.targets[6].values[None])
    assert np.linalg.norm(pa - pb) < 1e-9 and np.abs(Ra - Rb).max() < 1e-9
    # every byte outside the targets' numbers is the same
    assert skeleton(again.text, again.targets) == skeleton(prog.text, prog.targets)


def test_a_missing_frame_or_an_unreachable_branch_is_refused_by_line(tmp_path):
    nominal, true = _arms()
    q = np.array([[0.3, -1.2, 1.4, -0.5, 1.1, 0.4]])
    path = tmp_path / "test.dat"
    path.write_bytes(_module(nominal, q).encode())
    prog = read_program(str(path), "krl")
    res = compensate_branches(true, nominal, prog, rows, frames={"TOOL_NO 1": TOOL}, q_start=q[0])
    assert res.refused[0].startswith("its base frame 'BASE_NO 2' is not given")
    assert "line 2" in res.problems[0] and 1 in res.texts  # the joint target needs no frame
    unnamed = dataclasses.replace(prog, targets=tuple(dataclasses.replace(t, frames=("", "")) for t in prog.targets))
    res = compensate_branches(true, nominal, unnamed, rows, frames={"TOOL_NO 1": TOOL}, q_start=q[0])
    assert res.refused[0] == "the program names no tool frame here: give the one in force (frames: 'default tool')"
    res = compensate_branches(true, nominal, unnamed, rows, frames={"default tool": TOOL, "default base": BASE},
                              q_start=q[0])
    assert not res.refused
    wrong = lambda robot, qq: [(config_of(robot, x)[0], 63) for x in qq]  # noqa: E731  (every joint negative: none)
    res = compensate_branches(true, nominal, prog, wrong, frames={"TOOL_NO 1": TOOL, "BASE_NO 2": BASE}, q_start=q[0])
    assert "reaches this pose, but on no branch with the target's bits (1, 10)" in res.refused[0]


def _kincal(capsys, argv):
    from kincal.cli import main

    code = main(argv)
    out = capsys.readouterr()
    return code, out.err + out.out


def test_a_kuka_program_through_the_command_line(tmp_path, capsys):
    """kincal compensate cal.yaml pick.dat --program krl --frames frames.yaml -o pick_cal.dat, on the bundled KR 6
    R900 sixx with its own S/T rule: the written E6POS, turned into joints on its bits by the nominal arm, lands
    on the pose the original meant on the calibrated arm; a forgotten --frames is refused by line, a flag that
    does not apply is refused, and the output never replaces the input."""
    from kincal.io import BITS

    nominal = kincal.load_robot("kuka_kr6r900sixx").with_tool_point([0.0, 0.0, 0.05])  # a reflector on the flange
    measured = kincal.simulate(kincal.perturb(nominal, seed=3), nominal.sample_joints(60, seed=1), noise=0.0)
    res = kincal.calibrate(nominal, measured)
    cal = tmp_path / "cal.yaml"
    kincal.save_robot(res.robot, cal, calibration=res.record())
    true = command_models(res.robot, res.record()["nominal"])[0]  # the calibrated arm in its base frame
    shift = tool_carry(res.robot.tool_point(), nominal.tool_point())[0]  # carried over to the TCP (a link's error)
    assert 0 < np.linalg.norm(shift) <= 1e-3
    q = np.radians([[10, -80, 100, 20, 40, 30], [-25, -100, 110, -30, -50, 60], [40, -60, 80, 90, 30, -120]])
    flange = nominal.with_tool_point(np.zeros(3))
    dat = tmp_path / "pick.dat"
    _program(dat, nominal, flange, BASE, TOOL, q)  # E6POS in TOOL_NO 1 / BASE_NO 2, with their S/T
    frames = tmp_path / "frames.yaml"
    tool_rpy = Rotation.from_matrix(TOOL[:3, :3]).as_euler("ZYX", degrees=True)
    frames.write_text(f"TOOL_NO 1: {{x: 10, y: -20, z: 150, rz: {tool_rpy[0]}, ry: {tool_rpy[1]}, rx: {tool_rpy[2]}}}\n"
                      f"BASE_NO 2: {{x: 300, y: -100, z: 50}}\n")
    out = tmp_path / "pick_cal.dat"
    code, said = _kincal(capsys, ["compensate", str(cal), str(dat), "--program", "krl", "-o", str(out)])
    assert code != 0 and "line 2 (E6POS XP1): its tool frame 'TOOL_NO 1' is not given" in said and not out.exists()
    code, said = _kincal(capsys, ["compensate", str(cal), str(dat), "--program", "rapid", "-o", str(out)])
    assert code != 0 and "its suffix is a krl program's, not rapid's; give --program krl" in said
    code, said = _kincal(capsys, ["compensate", str(cal), str(dat), "--program", "krl", "--frames", str(frames),
                                  "--tcp", "0,0,100mm", "-o", str(out)])
    assert code != 0 and "--tcp: not for a krl program" in said
    code, said = _kincal(capsys, ["compensate", str(cal), str(dat), "--program", "krl", "--frames", str(frames),
                                  "-o", str(out)])
    assert code == 0 and "3 of 3 literal targets compensated on their own branch" in said
    old, new = read_program(str(dat), "krl"), read_program(str(out), "krl")
    for t_old, t_new, qk in zip(old.targets, new.targets, q):
        assert t_new.config == t_old.config
        p, R = _intended(nominal, t_old.values)
        pn, Rn = _intended(nominal, t_new.values)
        q_ctrl = controller_inverse(flange, pn[None], Rn[None], qk, t_new.config, BITS["krl"])
        pt, Rt, _, _ = true.with_tool_point(np.zeros(3)).pose_and_jacobian(q_ctrl[None])
        assert np.linalg.norm(Rotation.from_matrix(Rt[0] @ R.T).as_rotvec()) < 1e-9
        # the TCP: TOOL's origin, moved on the calibrated arm by what the calibration moved the reflector
        assert np.linalg.norm(pt[0] + Rt[0] @ (TOOL[:3, 3] + shift) - p - R @ TOOL[:3, 3]) < 1e-9


def test_where_the_tracker_stood_does_not_change_the_program(tmp_path, capsys):
    """The same arm calibrated from a tracker at its base and from one 1.26 m away and turned 34°: the
    program and the folder written from each are the same to 1e-9 (the commands are in the robot's base frame,
    the controller's world, never the tracker's), and land on the poses the program meant (the first test's
    check)."""
    nominal = kincal.load_robot("kuka_kr6r900sixx").with_tool_point([0.0, 0.0, 0.05])
    arm = kincal.perturb(nominal, seed=3)
    q = nominal.sample_joints(60, seed=1)
    flange = nominal.with_tool_point(np.zeros(3))
    _program(tmp_path / "pick.dat", nominal, flange, BASE, TOOL, np.radians([[10, -80, 100, 20, 40, 30],
                                                                             [-25, -100, 110, -30, -50, 60]]))
    tool_rpy = Rotation.from_matrix(TOOL[:3, :3]).as_euler("ZYX", degrees=True)
    (tmp_path / "frames.yaml").write_text(f"TOOL_NO 1: {{x: 10, y: -20, z: 150, rz: {tool_rpy[0]}, ry: "
                                          f"{tool_rpy[1]}, rx: {tool_rpy[2]}}}\nBASE_NO 2: {{x: 300, y: -100, z: 50}}\n")
    (tmp_path / "cell").mkdir()
    (tmp_path / "cell" / "pick.dat").write_bytes((tmp_path / "pick.dat").read_bytes())
    written = []
    for k, where in enumerate(({}, {"base.x": 1.2, "base.y": -0.3, "base.z": 0.1, "base.rz": 0.6})):
        res = kincal.calibrate(nominal, kincal.simulate(arm.with_params(where), q, noise=0.0))
        kincal.save_robot(res.robot, tmp_path / f"cal{k}.yaml", calibration=res.record())
        out = tmp_path / f"pick{k}.dat"
        code, said = _kincal(capsys, ["compensate", str(tmp_path / f"cal{k}.yaml"), str(tmp_path / "pick.dat"),
                                      "--program", "krl", "--frames", str(tmp_path / "frames.yaml"), "-o", str(out)])
        assert code == 0 and "2 of 2 literal targets compensated" in said, said
        code, said = _kincal(capsys, ["compensate", str(tmp_path / f"cal{k}.yaml"), str(tmp_path / "cell"), "--program",
                                      "krl", "--frames", str(tmp_path / "frames.yaml"), "-o", str(tmp_path / f"out{k}")])
        assert code == 0, said
        assert (tmp_path / f"out{k}" / "pick.dat").read_bytes() == out.read_bytes()
        written.append(np.array([t.values for t in read_program(str(out), "krl").targets]))
    assert np.abs(written[0] - written[1]).max() < 1e-9
    assert np.abs(written[0] - np.array([t.values for t in read_program(str(tmp_path / "pick.dat"), "krl").targets])
                  ).max() > 1e-5  # compensated: the arm's errors moved them


@pytest.mark.parametrize("language, arm", [("krl", "kuka_kr6r900sixx"), ("fanuc", "fanuc_lrmate200id")])
def test_every_real_target_is_compensated_and_checked_or_refused_by_line(language, arm):
    """The data folder's KRL and FANUC programs with a calibration of the vendor's bundled arm: each literal target
    is compensated (its text read again reaches the meant pose on the calibrated arm, which the module checks) or
    refused with its line and why; nothing else happens to it."""
    from conftest import shared_dataset
    from kincal.io import ROWS, dialect_of

    nominal = kincal.load_robot(arm)
    cal = kincal.perturb(nominal, seed=1)
    compensated = refused = 0
    for path in sorted((shared_dataset("robot_programs") / language).rglob("*")):
        if not path.is_file() or dialect_of(str(path)) != language:
            continue
        prog = read_program(str(path), language)
        res = compensate_branches(cal, nominal, prog, ROWS[language])
        kept = {k for k, t in enumerate(prog.targets) if t.line in {line for line, _, _ in res.kept}}
        assert set(res.texts) | set(res.refused) | kept == set(range(len(prog.targets)))
        assert not set(res.texts) & set(res.refused) and not kept & (set(res.texts) | set(res.refused))
        assert all(res.refused.values())
        assert all(f"line {prog.targets[k].line} " in p for k, p in zip(sorted(res.refused), res.problems))
        again = dialects()[language].parse(str(path), prog.with_targets(res.texts)).targets
        half = dialects()[language].step[1] / 2  # the controller's angle step (FANUC: 0.001 deg), half of it
        for k in res.texts:  # a joint target: the calibrated arm at the new joints is where the nominal one was
            if prog.targets[k].kind == "joints":  # to the rounding of each joint, through its lever on the flange
                pa = cal.with_tool_point(np.zeros(3)).pose_and_jacobian(again[k].values[None])[0]
                pb, _, jp, _ = nominal.with_tool_point(np.zeros(3)).pose_and_jacobian(prog.targets[k].values[None])
                bound = 1e-9 + half * np.linalg.norm(jp[0], axis=0).sum()
                assert np.linalg.norm(pa - pb) <= bound and not np.allclose(again[k].values, prog.targets[k].values)
        compensated, refused = compensated + len(res.texts), refused + len(res.refused) + len(kept)
    assert compensated >= 1 and compensated + refused == {"krl": 11, "fanuc": 2}[language]


def test_a_redundant_arms_pose_targets_are_refused_with_the_reason(tmp_path):
    """A 7-joint arm (the bundled WAM): the controller picks the redundancy of a Cartesian target (KRL E1, RAPID
    eax_a), so its pose targets are refused with that reason, by line; an E6AXIS (A1..A6, six values) is refused
    for the count, and neither is written."""
    from kincal.compensate.branch import REDUNDANT

    nominal = kincal.load_robot("wam")
    true = kincal.perturb(nominal, seed=2)
    text = ("DEFDAT  SEVEN\r\nDECL E6POS XP1={X 400.0,Y 0.0,Z 500.0,A 0.0,B 90.0,C 0.0,S 2,T 10,E1 12.5}\r\n"
            "DECL E6AXIS XP2={A1 0,A2 10,A3 0,A4 90,A5 0,A6 0,E1 12.5}\r\nENDDAT\r\n")
    path = tmp_path / "seven.dat"
    path.write_bytes(text.encode())
    prog = read_program(str(path), "krl")
    res = compensate_branches(true, nominal, prog, lambda robot, qq: [(0, 0)] * len(qq),
                              frames={"default tool": np.eye(4), "default base": np.eye(4)})
    assert res.refused == {0: REDUNDANT, 1: "6 joint values for a 7-joint robot"} and not res.texts
    assert "line 2" in res.problems[0] and "E1" in res.problems[0] and "line 3" in res.problems[1]


def test_a_joint_taught_at_zero_and_written_to_three_decimals_is_named_as_such(tmp_path):
    """E6POS written to 3 decimals (mm, deg) from joints with A6 at 0° or A1 at 0°: the pose's own inverse puts that
    joint at about -0.001°, across the sign bit from the target's T. Refused naming the joint, its angle and why
    (it said only 'on no branch with the target's bits'); the same pose with A6 at 0.5° is compensated."""
    from kincal.io import ROWS
    from kincal.models.transforms import zyx_from_matrix
    nominal = kincal.load_robot("kuka_kr6r900sixx").with_tool_point([0.0, 0.0, 0.15])
    qs = np.radians([[10, -80, 100, 5, 30, 0], [0, -90, 90, 0.5, 45, 0.5], [10, -80, 100, 5, 30, 0.5]])
    lines = ["DEFDAT EDGE PUBLIC"]
    for k, q in enumerate(qs):
        P, R = nominal.forward(q[None])[0] * 1e3, nominal.flange_rotation(q[None])[0]
        (a, b, c), (s, t) = np.degrees(zyx_from_matrix(R)), ROWS["krl"](nominal, q[None])[0]
        lines.append(f"DECL E6POS XP{k + 1}={{X {P[0]:.3f},Y {P[1]:.3f},Z {P[2]:.3f},A {a:.3f},B {b:.3f},C {c:.3f},"
                     f"S {s},T {t}}}")
    (tmp_path / "edge.dat").write_text("\n".join(lines + ["ENDDAT", ""]))
    program = read_program(str(tmp_path / "edge.dat"), "krl")
    tool = np.eye(4)
    tool[2, 3] = 0.15
    res = compensate_branches(kincal.perturb(nominal, seed=1), nominal, program, ROWS["krl"],
                              {"default tool": tool, "default base": np.eye(4)})
    assert sorted(res.refused) == [0, 1] and 2 in res.texts
    for k, joint in ((0, "a6"), (1, "a1")):
        why = res.refused[k]
        assert why.startswith(f"the pose puts {joint} at -") and "on the other side of 0" in why, why
        assert -0.01 < float(why.split(" at ")[1].split("°")[0]) < 0


def test_a_correction_that_moves_a_joint_across_0_names_it(tmp_path):
    """A KRL pose taught with A6 at 0 (written to 3 decimals: +0.001° on the controller's side of the T bit); the
    real robot needs A6 at -0.45° there, across the sign bit, so the target is refused as before, but the reason
    now names A6 and both angles (it said only that the bits differ)."""
    from kincal.io import ROWS
    from kincal.models.transforms import zyx_from_matrix
    nominal = kincal.load_robot("kuka_kr6r900sixx")
    q = np.radians([10, -80, 100, 25, 30, 0])
    P, R = nominal.forward(q[None])[0] * 1e3, nominal.flange_rotation(q[None])[0]
    (a, b, c), (s, t) = np.degrees(zyx_from_matrix(R)), ROWS["krl"](nominal, q[None])[0]
    (tmp_path / "x.src").write_text(f"DEF x()\nPTP {{X {P[0]:.3f}, Y {P[1]:.3f}, Z {P[2]:.3f}, A {a:.3f}, B {b:.3f}, "
                                    f"C {c:.3f}, S {s}, T {t}}}\nEND\n")
    res = compensate_branches(kincal.perturb(nominal, seed=1), nominal, read_program(str(tmp_path / "x.src"), "krl"),
                              ROWS["krl"], {"default tool": np.eye(4), "default base": np.eye(4)})
    why = res.refused[0]
    assert why.startswith("the corrected joints' configuration bits (2, 34) differ from the target's (2, 2)")
    assert "(a6 moves from +0.00" in why and "to -0.4" in why and "across 0" in why, why


def test_a_joint_target_at_a_singularity_is_kept_and_said(tmp_path, capsys):
    """KUKA's home (A5 = 0: the wrist's axes in line) has no corrected joints near it: kept as it is and said, with
    how far the calibrated arm's flange lands from the nominal one there (recomputed here); the same move 0.3 rad
    off the singularity is compensated, and a URScript home pose is kept alike."""
    from kincal.compensate import compensate_program
    from kincal.io import ROWS

    nominal = kincal.load_robot("kuka_kr6r900sixx")
    real = kincal.perturb(nominal, seed=1)
    path = tmp_path / "home.src"
    path.write_text("DEF home()\nPTP {A1 0, A2 -90, A3 90, A4 0, A5 0, A6 0}\n"
                    "PTP {A1 0, A2 -90, A3 90, A4 0, A5 17.2, A6 0}\nEND\n")
    prog = read_program(str(path), "krl")
    res = compensate_branches(real, nominal, prog, ROWS["krl"])
    assert sorted(res.texts) == [1] and not res.refused and [line for line, _, _ in res.kept] == [2]
    q = prog.targets[0].values
    miss = np.linalg.norm(real.with_tool_point(np.zeros(3)).forward(q[None]) - nominal.with_tool_point(
        np.zeros(3)).forward(q[None]))
    assert f"the TCP lands {miss * 1e3:.3f} mm from the nominal model's point" in res.kept[0][2] and miss > 1e-4
    assert prog.with_targets(res.texts).splitlines()[1] == "PTP {A1 0, A2 -90, A3 90, A4 0, A5 0, A6 0}"
    ur, ur_real = kincal.load_robot("ur5"), kincal.perturb(kincal.load_robot("ur5"), seed=1)
    script = tmp_path / "home.script"
    script.write_text("def p():\n  movej([0, -1.5708, 0, -1.5708, 0, 0])\n  movej([0, -1.5708, 1.2, -1.5708, 0.3, 0])\n"
                      "end\n")
    res = compensate_program(ur_real, ur, read_program(str(script), "ur"))
    assert sorted(res.texts) == [1] and not res.problems and [line for line, _, _ in res.kept] == [2]



def test_fanuc_user_frame_0_is_the_world(tmp_path):
    """A FANUC position in UF : 0 (the world frame, by FANUC's definition) with its tool given: compensated, where
    it was refused until a frame 'UF 0' was given; the written position, read back and turned into joints on its
    CONFIG by the nominal arm, lands on the meant pose on the calibrated arm."""
    from kincal.io import BITS, ROWS, frame_numbers

    nominal = kincal.load_robot("fanuc_lrmate200id")
    real = kincal.perturb(nominal, seed=2)
    flange = nominal.with_tool_point(np.zeros(3))
    q = np.radians([10.0, 20.0, -10.0, 30.0, -40.0, 50.0])
    p, R, _, _ = flange.pose_and_jacobian(q[None])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R[0], p[0]
    x, y, z, a, b, c = frame_numbers(T)
    (bits,) = ROWS["fanuc"](flange, q[None])
    text = ("/PROG  UF0\n/ATTR\n/MN\n   1:L P[1] 100mm/sec FINE ;\n/POS\nP[1]{\n   GP1:\n"
            f"\tUF : 0, UT : 1,\t\tCONFIG : '{bits[0]}, {bits[1]}, {bits[2]}, {bits[3]}',\n"
            f"\tX = {x:.4f} mm,\tY = {y:.4f} mm,\tZ = {z:.4f} mm,\n\tW = {c:.4f} deg,\tP = {b:.4f} deg,\tR = {a:.4f} deg\n"
            "};\n/END\n")
    path = tmp_path / "uf0.ls"
    path.write_text(text)
    prog = read_program(str(path), "fanuc")
    res = compensate_branches(real, nominal, prog, ROWS["fanuc"], {"UT 1": np.eye(4)})
    assert not res.refused and sorted(res.texts) == [0]
    new = dialects()["fanuc"].parse(str(path), prog.with_targets(res.texts)).targets[0]
    Tn = np.eye(4)
    Tn[:3, :3], Tn[:3, 3] = Rotation.from_rotvec(new.values[3:]).as_matrix(), new.values[:3]
    q_ctrl = controller_inverse(flange, Tn[None, :3, 3], Tn[None, :3, :3], q, new.config, BITS["fanuc"])
    reached, Rr, _, _ = real.with_tool_point(np.zeros(3)).pose_and_jacobian(q_ctrl[None])
    meant = prog.targets[0].values  # the pose as the text wrote it (to 1e-4 mm and deg)
    length, angle = dialects()["fanuc"].step  # written to the controller's 0.001 mm and deg: half of it on each
    assert np.linalg.norm(reached[0] - meant[:3]) <= 1e-9 + np.sqrt(3) * length / 2
    turn = Rotation.from_matrix(Rr[0]).inv() * Rotation.from_rotvec(meant[3:])
    assert turn.magnitude() <= 1e-9 + 3 * angle / 2


def test_a_program_and_a_targets_file_carry_the_calibrations_move_of_the_declared_point_alike(tmp_path, capsys):
    """An LR Mate calibrated from points on a probe declared at (0, 0, 100) mm that sits 0.54 mm off it: the
    calibration moves the declared point by 0.706 mm (with the last link's errors), and a TCP at (0, 0, 100) mm
    carries that move over (the last link's error, at most --link-error-max). Three Cartesian targets for that TCP,
    as a FANUC program (UT 1) and as a CSV with --pose --tcp: the calibrated model's TCP at both routes' commands is
    one point, the true robot's TCP there (the probe) is on the targets. Before, the program carried nothing over:
    its commands were up to 0.12 deg off the CSV's, the routes' TCPs 0.706 mm apart, the program's missing the true
    robot by as much (0.4 µm and 1 µm after)."""
    import json
    from kincal.cli import main
    from kincal.io import BITS, ROWS, frame_numbers
    from kincal.observe import from_matrices

    nominal = kincal.load_robot("fanuc_lrmate200id").with_tool_point(np.array([0.0, 0.0, 0.1]))
    true = kincal.perturb(nominal, seed=3)
    true = true.with_params({n: nominal.params[n] for n in [*nominal.base_params(), "j1.theta", "j1.d"]})
    true = true.with_tool_point(np.array([0.0002, -0.0003, 0.1004]))  # where the probe really is, 0.54 mm off
    fit = kincal.calibrate(nominal, kincal.simulate(true, nominal.sample_joints(150, seed=4), 1e-6, seed=5))
    kincal.save_robot(fit.robot, tmp_path / "cal.yaml", calibration=fit.record())
    shift, _ = tool_carry(fit.robot.tool_point(), nominal.tool_point())
    assert 0.3e-3 < np.linalg.norm(shift) < 1e-3  # carried over (a link's error)
    flange = nominal.with_tool_point(np.zeros(3))
    q = np.radians([[10.0, 20.0, -10.0, 30.0, -40.0, 50.0], [-15, 10, 5, -20, -50, 10], [30, -5, -20, 40, -30, -60]])
    p, R, _, _ = flange.pose_and_jacobian(q)
    T = np.zeros((3, 4, 4))
    T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = R, p + R[:, :, 2] * 0.1, 1.0  # the TCP (0, 0, 100) mm's poses
    pos = ""
    for k, (Tk, bits) in enumerate(zip(T, ROWS["fanuc"](flange, q)), 1):
        x, y, z, a, b, c = frame_numbers(Tk)
        pos += (f"P[{k}]{{\n   GP1:\n\tUF : 0, UT : 1,\t\tCONFIG : '{', '.join(map(str, bits))}',\n\tX = {x:.3f} mm,"
                f"\tY = {y:.3f} mm,\tZ = {z:.3f} mm,\n\tW = {c:.3f} deg,\tP = {b:.3f} deg,\tR = {a:.3f} deg\n}};\n")
    (tmp_path / "t.ls").write_text("/PROG  T\n/ATTR\n/MN\n" + "".join(f"   {k}:L P[{k}] 100mm/sec FINE ;\n"
                                                                      for k in (1, 2, 3)) + "/POS\n" + pos + "/END\n")
    (tmp_path / "frames.yaml").write_text("UT 1: {x: 0, y: 0, z: 100}\n")
    prog = read_program(str(tmp_path / "t.ls"), "fanuc")
    goal = np.array([t.values for t in prog.targets])  # m and rotation vectors, as the program writes them
    np.savetxt(tmp_path / "t.csv", np.column_stack([np.degrees(q), goal[:, :3] * 1e3, from_matrices(
        Rotation.from_rotvec(goal[:, 3:]).as_matrix(), "euler-zyx-intrinsic-deg")]), delimiter=",", comments="",
        header="J1,J2,J3,J4,J5,J6,x,y,z,e1,e2,e3", fmt="%.15g")
    capsys.readouterr()
    assert main(["compensate", str(tmp_path / "cal.yaml"), str(tmp_path / "t.csv"), "--pose", "--tcp", "0,0,100mm",
                 "--length-unit", "mm", "--angle-unit", "deg", "--orientation", "euler-zyx-intrinsic-deg",
                 "-o", str(tmp_path / "cmd.csv")]) == 0
    csv = np.radians(np.loadtxt(tmp_path / "cmd.csv", delimiter=",", skiprows=1)[:, 1:7])
    capsys.readouterr()
    assert main(["compensate", str(tmp_path / "cal.yaml"), str(tmp_path / "t.ls"), "--program", "fanuc", "--frames",
                 str(tmp_path / "frames.yaml"), "-o", str(tmp_path / "out.ls"), "--json"]) == 0
    assert "carried over to the TCP" in json.loads(capsys.readouterr().out)["tool_carry"]
    again = read_program(str(tmp_path / "out.ls"), "fanuc").targets
    tcp = np.array([0.0, 0.0, 0.1])
    ctrl = []  # the controller's joints of the written program: its pose at UT 1 turned into joints on its CONFIG
    for t, qk in zip(again, csv):
        F = np.eye(4)
        F[:3, :3], F[:3, 3] = Rotation.from_rotvec(t.values[3:]).as_matrix(), t.values[:3]
        F[:3, 3] -= F[:3, :3] @ tcp
        ctrl.append(controller_inverse(flange, F[None, :3, 3], F[None, :3, :3], qk, t.config, BITS["fanuc"]))
    model, _ = command_models(fit.robot, fit.record()["nominal"], tcp)
    assert np.allclose(model.tool_point(), tcp + shift, atol=1e-12)
    written = 0.5e-3 * 1e-3 * np.sqrt(3) + 3 * np.radians(0.5e-3) * 0.1  # m: the text's 0.001 mm and deg, halved
    assert np.linalg.norm(model.forward(np.array(ctrl)) - model.forward(csv), axis=1).max() < written  # was 0.706 mm
    assert np.linalg.norm(model.forward(csv) - goal[:, :3], axis=1).max() < 1e-9
    assert np.linalg.norm(true.forward(np.array(ctrl)) - goal[:, :3], axis=1).max() < 0.01e-3  # was 0.706 mm
    # the library: the program's corrected joints (unrounded) are the targets file's commands
    ut1 = np.eye(4)
    ut1[:3, 3] = tcp
    res = compensate_branches(*command_models(fit.robot, fit.record()["nominal"]), prog, ROWS["fanuc"], {"UT 1": ut1},
                              carry=shift)
    assert not res.problems
    assert np.linalg.norm(model.forward(res.q) - model.forward(csv), axis=1).max() < 1e-6


def _kabsch(P, Q):
    """R (3, 3), t (3,) putting the points P (N, 3) on Q (N, 3) by least squares (a rigid move)."""
    pc, qc = P.mean(axis=0), Q.mean(axis=0)
    U, _, Vt = np.linalg.svd((P - pc).T @ (Q - qc))
    R = Vt.T @ np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))]) @ U.T
    return R, qc - R @ pc


@pytest.mark.parametrize("arm, language, suffix", [("kuka_kr6r900sixx", "krl", "src"),
                                                   ("fanuc_lrmate200id", "fanuc", "ls")])
def test_joint_targets_take_the_calibrations_move_of_the_measured_point_as_the_carry(tmp_path, capsys, arm,
                                                                                     language, suffix):
    """An arm measured at a point 30 mm out on the flange whose every link but the base's is off: the noise-free
    calibration moves the declared point by less than 1 mm (the last link's error, carried over to the TCP). A
    program's joint targets (KRL PTP {A1 ...}, FANUC J1 = ... deg) mean where the nominal model puts the declared
    point there; the true arm (moved onto the calibrated model's frame by a rigid fit of its points) puts its
    measured point at the written joints on that point (to the text's rounding: KRL full precision, FANUC 0.001 deg).
    Before, the joint targets aimed the nominal flange's pose plus the fitted point: off by the move (0.89, 0.73 mm)."""
    from kincal.cli import main
    from kincal.io import ROWS

    nominal = kincal.load_robot(arm).with_tool_point(np.array([0.0, 0.0, 0.03]))
    true = kincal.perturb(nominal, seed=2, names=[n for n in nominal.params.names if n not in nominal.base_params()])
    fit = kincal.calibrate(nominal, kincal.simulate(true, nominal.sample_joints(200, seed=1), 0.0),
                           kincal.FitOptions(diagnose=False))
    kincal.save_robot(fit.robot, tmp_path / "cal.yaml", calibration=fit.record())
    model, _ = command_models(fit.robot, fit.record()["nominal"])
    carry, _ = tool_carry(model.tool_point(), nominal.tool_point())
    assert 0.3e-3 < np.linalg.norm(carry) < 1e-3  # carried over: the last link's error
    q = np.radians([[10.0, -80, 100, 20, 40, 30], [-25, -100, 110, -30, -50, 60], [30, -70, 90, 60, 45, -100]])
    if language == "fanuc":
        q = np.radians([[10.0, 20, -10, 30, -40, 50], [-15, 10, 5, -20, -50, 10], [30, -5, -20, 40, -30, -60]])
        text = "/PROG  J\n/ATTR\n/MN\n" + "".join(f"   {k}:J P[{k}] 100% FINE ;\n" for k in (1, 2, 3)) + "/POS\n" \
            + "".join(f"P[{k}]{{\n   GP1:\n\tUF : 0, UT : 1,\n\t" + ",\t".join(
                f"J{j} = {v:.3f} deg" for j, v in enumerate(np.degrees(qk), 1)) + "\n};\n"
                for k, qk in enumerate(q, 1)) + "/END\n"
    else:
        text = "DEF j()\n" + "".join("PTP {" + ", ".join(f"A{j} {v:.6f}" for j, v in enumerate(np.degrees(qk), 1))
                                     + "}\n" for qk in q) + "END\n"
    (tmp_path / f"j.{suffix}").write_text(text)
    q = np.array([t.values for t in read_program(str(tmp_path / f"j.{suffix}"), language).targets])  # as written
    capsys.readouterr()
    assert main(["compensate", str(tmp_path / "cal.yaml"), str(tmp_path / f"j.{suffix}"), "--program", language,
                 "-o", str(tmp_path / f"out.{suffix}")]) == 0
    assert "carried over to the TCP" in capsys.readouterr().out
    written = np.array([t.values for t in read_program(str(tmp_path / f"out.{suffix}"), language).targets])
    spread = nominal.sample_joints(300, seed=5)
    Rt, tt = _kabsch(true.forward(spread), model.forward(spread))  # the true arm onto the calibrated frame
    reached = true.forward(written) @ Rt.T + tt  # the true measured point, in the calibrated model's frame
    meant = nominal.forward(q)  # the declared point where the nominal model puts it at the program's joints
    _, _, Jp, _ = true.pose_and_jacobian(written)
    rounding = np.einsum("nij->n", np.abs(Jp)) * np.radians(0.0005) if language == "fanuc" else np.zeros(3)
    assert (np.linalg.norm(reached - meant, axis=1) < 1e-6 + rounding).all(), np.linalg.norm(reached - meant, axis=1)
    assert np.linalg.norm(true.forward(q) @ Rt.T + tt - meant, axis=1).min() > 0.1e-3  # the calibration's worth


def test_a_correction_past_a_joint_limit_is_named_as_such_not_as_an_unreached_branch(tmp_path):
    """A KRL pose taught with A6 at -349.95° (0.05° inside its -350° limit) with a 152 mm tool, whose TCP the
    calibration moves by 1 mm (the carry): the controller's joints of the target as written are those, inside the
    limits; the real robot needs A6 at -350.64° there (a least-squares solve of its flange pose, below). Before,
    the controller's joints were solved for the physical tool (the carried TCP), whose A6 is -350.17°, and the
    target was refused as 'the nominal model reaches this pose, but on no branch with the target's bits'; now the
    refusal names A6, its limit and the excess, as a targets file's does."""
    from scipy.optimize import least_squares
    from kincal.compensate import compensate_poses
    from kincal.io import ROWS
    from kincal.models.transforms import zyx_from_matrix
    nominal = kincal.load_robot("kuka_kr6r900sixx")
    true = kincal.perturb(nominal, seed=1)
    q = np.radians([20, -80, 100, 25, 30, -349.95])
    tool = np.eye(4)
    tool[:3, 3] = [0.0, 0.0, 0.152]
    carry = np.array([0.0, -1e-3, 0.0])  # m, flange frame: moves the flange goal so that A6 turns further back
    p, R, _, _ = nominal.with_tool_point(np.zeros(3)).pose_and_jacobian(q[None])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R[0], p[0]
    T = T @ tool
    P, (a, b, c), (s, t) = T[:3, 3] * 1e3, np.degrees(zyx_from_matrix(T[:3, :3])), ROWS["krl"](nominal, q[None])[0]
    (tmp_path / "x.src").write_text(f"DEF x()\nLIN {{X {P[0]:.4f}, Y {P[1]:.4f}, Z {P[2]:.4f}, A {a:.5f}, "
                                    f"B {b:.5f}, C {c:.5f}, S {s}, T {t}}}\nEND\n")
    phys = tool.copy()
    phys[:3, 3] += carry
    F = T @ np.linalg.inv(phys)  # where the real flange must be

    def off(x):
        pt, Rt, _, _ = true.with_tool_point(np.zeros(3)).pose_and_jacobian(x[None])
        return np.r_[pt[0] - F[:3, 3], Rotation.from_matrix(Rt[0] @ F[:3, :3].T).as_rotvec()]
    need = np.degrees(least_squares(off, q, xtol=1e-15, ftol=1e-15, gtol=1e-15).x[5])
    assert -350.7 < need < -350.6
    res = compensate_branches(true, nominal, read_program(str(tmp_path / "x.src"), "krl"), ROWS["krl"],
                              {"default tool": tool, "default base": np.eye(4)}, carry=carry)
    said = f"a6 at {need:.3f} deg, past its limit -350.000 deg by {-350 - need:.3f} deg"
    assert res.refused[0] == f"the corrected joints break the joint limits: {said}", res.refused
    assert "no branch" not in res.refused[0]
    csv = compensate_poses(true.with_tool_point(phys[:3, 3]), T[None, :3, 3], R, q[None])
    assert csv.problems == (f"row 1: the command breaks the joint limits: {said}",)


def test_a_tool_and_base_are_one_frame_under_both_their_krl_names(tmp_path):
    """KRL names tool 1 ``TOOL_DATA[1]`` where a program sets ``$TOOL`` and ``TOOL_NO 1`` in an FDAT (base 2 likewise):
    given under either name, in any case, it is the frame of both; both names with two values are refused (the
    controller holds one tool 1, so one of them is not its). Before, a ``$TOOL = TOOL_DATA[1]`` program with
    the frames given as ``TOOL_NO 1`` refused every Cartesian target ("its tool frame 'TOOL_DATA[1]' is not
    given"); now each lands on the flange pose BASE · T · TOOL⁻¹ on the true arm, to 1e-9 m and rad."""
    nominal, true = _arms()
    q = np.array([[0.3, -1.2, 1.4, -0.5, 1.1, 0.4], [-0.6, -1.0, 1.2, 0.7, -1.3, 2.0]])
    (tmp_path / "test.dat").write_bytes(_module(nominal, q).encode())  # FDATs: TOOL_NO 1, BASE_NO 2
    dat = read_program(str(tmp_path / "test.dat"), "krl")
    same = compensate_branches(true, nominal, dat, rows, {"TOOL_NO 1": TOOL, "BASE_NO 2": BASE}, q_start=q[0])
    other = compensate_branches(true, nominal, dat, rows, {"tool_data[1]": TOOL, "BASE_DATA[2]": BASE}, q_start=q[0])
    assert not other.problems and other.texts == same.texts and len(same.texts) == 3
    src = ["DEF t()", "  $TOOL = TOOL_DATA[1]", "  $BASE = BASE_DATA[2]"]
    for t in dat.targets[:2]:
        src.append("  LIN " + dat.text[t.start:t.end] + " C_DIS")
    (tmp_path / "t.src").write_text("\n".join(src + ["END", ""]))
    prog = read_program(str(tmp_path / "t.src"), "krl")
    assert [t.frames for t in prog.targets] == [("TOOL_DATA[1]", "BASE_DATA[2]")] * 2
    res = compensate_branches(true, nominal, prog, rows, {"TOOL_NO 1": TOOL, "BASE_NO 2": BASE}, q_start=q[0])
    assert not res.problems and sorted(res.texts) == [0, 1]
    pt, Rt, _, _ = true.with_tool_point(np.zeros(3)).pose_and_jacobian(res.q)
    for k, t in enumerate(prog.targets):
        p, R = _intended(nominal, t.values)
        assert np.linalg.norm(pt[k] - p) < 1e-9 and np.linalg.norm(Rotation.from_matrix(Rt[k] @ R.T).as_rotvec()) < 1e-9
    both = compensate_branches(true, nominal, prog, rows, {"TOOL_NO 1": TOOL, "TOOL_DATA[1]": TOOL.copy(),
                                                           "BASE_NO 2": BASE}, q_start=q[0])
    assert both.texts == res.texts  # both names with one value: that frame
    with pytest.raises(ValueError, match=r"'TOOL_NO 1' and 'TOOL_DATA\[1\]', KRL's two names of tool 1, different"):
        compensate_branches(true, nominal, prog, rows, {"TOOL_NO 1": np.eye(4), "TOOL_DATA[1]": TOOL,
                                                        "BASE_NO 2": BASE}, q_start=q[0])


UR10_DH = ((0.1273, 0.0, np.pi / 2), (0.0, -0.612, 0.0), (0.0, -0.5723, 0.0), (0.163941, 0.0, np.pi / 2),
           (0.1157, 0.0, -np.pi / 2), (0.0922, 0.0, 0.0))  # the UR10's nominal DH (d, a, alpha), m and rad


def _ur10_flange(q):
    """The nominal UR10's flange (4x4) at joints q (6,): the textbook DH product, written here apart from kincal."""
    T = np.eye(4)
    for qj, (d, a, alpha) in zip(q, UR10_DH):
        ct, st, ca, sa = np.cos(qj), np.sin(qj), np.cos(alpha), np.sin(alpha)
        T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d],
                          [0, 0, 0, 1]])
    return T


def _frame(values):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_rotvec(values[3:6]).as_matrix(), values[:3]
    return T


def test_a_krl_tool_reaches_the_moves_its_flow_reaches_not_those_after_it_in_the_text(tmp_path):
    """$TOOL = TOOL_DATA[1], pick(), $TOOL = TOOL_DATA[2], place(), with pick and place defined after the main DEF:
    place's LIN runs with tool 2, but the last $TOOL before it in the text is the TOOL_DATA[1] of an IF further up,
    so it was compensated for tool 1; the LIN after that IF (tool 1 or 2) was compensated for tool 1. Now place's
    LIN is compensated for tool 2 and the one after the IF is refused, naming lines 5 and 8. Checked through the
    UR10's own DH product: the controller's inverse of each written target (BASE · T · TOOLk⁻¹), then the true arm
    there, on the pose the original text meant to 1e-6 mm and 1e-9 rad."""
    nominal, true = _arms()
    tool2 = TOOL.copy()
    tool2[:3, 3] = [-0.02, 0.03, 0.22]
    q = np.array([[0.3, -1.2, 1.4, -0.5, 1.1, 0.4], [-0.6, -1.0, 1.2, 0.7, -1.3, 2.0],
                  [0.5, -1.4, 1.6, -0.2, 0.9, 1.0]])
    assert np.abs(_ur10_flange(q[0]) - _poses_of(nominal, q[0])).max() < 1e-12
    lins = []
    for qk, tool in zip(q, (TOOL, tool2, TOOL)):
        T = np.linalg.inv(BASE) @ _ur10_flange(qk) @ tool
        a, b, c = Rotation.from_matrix(T[:3, :3]).as_euler("ZYX", degrees=True)
        x, y, z = T[:3, 3] * 1e3
        s, t = config_of(nominal, qk)
        lins.append(f"LIN {{X {x:.6f}, Y {y:.6f}, Z {z:.6f}, A {a:.6f}, B {b:.6f}, C {c:.6f}, S {s}, T {t}}}")
    src = ["DEF t()", "  $BASE = BASE_DATA[2]", "  $TOOL = TOOL_DATA[1]", "  pick()", "  $TOOL = TOOL_DATA[2]",
           "  place()", "  IF $IN[1] THEN", "    $TOOL = TOOL_DATA[1]", "  ENDIF", f"  {lins[2]}", "END", "",
           "DEF pick()", f"  {lins[0]}", "END", "", "DEF place()", f"  {lins[1]}", "END", ""]
    (tmp_path / "t.src").write_text("\r\n".join(src))
    prog = read_program(str(tmp_path / "t.src"), "krl")
    assert [t.line for t in prog.targets] == [10, 14, 18]
    frames = {"TOOL_DATA[1]": TOOL, "TOOL_DATA[2]": tool2, "BASE_DATA[2]": BASE}
    res = compensate_branches(true, nominal, prog, rows, frames, q_start=q[0])
    assert sorted(res.texts) == [1, 2] and list(res.refused) == [0]
    assert res.refused[0] == ("its $TOOL is not known from the module's structure: the $TOOL assignments on lines 5, "
                              "8 may be in force here, as a branch, loop or call decides at run time; give it one: a "
                              "$TOOL assignment that every path runs before this move")
    (tmp_path / "out.src").write_text(prog.with_targets(res.texts))
    new = read_program(str(tmp_path / "out.src"), "krl")
    assert [t.frames for t in new.targets] == [("", "BASE_DATA[2]"), ("TOOL_DATA[1]", "BASE_DATA[2]"),
                                               ("TOOL_DATA[2]", "BASE_DATA[2]")]
    for k, qk, tool in ((1, q[0], TOOL), (2, q[1], tool2)):
        goal = BASE @ _frame(new.targets[k].values) @ np.linalg.inv(tool)  # what the controller turns into joints
        ik = least_squares(lambda x: np.concatenate([(_ur10_flange(x) - goal)[:3, 3], Rotation.from_matrix(
            _ur10_flange(x)[:3, :3] @ goal[:3, :3].T).as_rotvec()]), res.q[k], xtol=1e-15, ftol=1e-15, gtol=1e-15).x
        pt, Rt, _, _ = true.with_tool_point(np.zeros(3)).pose_and_jacobian(ik[None])
        meant = BASE @ _frame(prog.targets[k].values) @ np.linalg.inv(tool)
        assert np.linalg.norm(pt[0] - meant[:3, 3]) * 1e3 < 1e-6
        assert np.linalg.norm(Rotation.from_matrix(Rt[0] @ meant[:3, :3].T).as_rotvec()) < 1e-9


def _poses_of(robot, q):
    p, R, _, _ = robot.with_tool_point(np.zeros(3)).pose_and_jacobian(q[None])
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = R[0], p[0]
    return out


def _dh_point(params: dict, q: np.ndarray, point: np.ndarray) -> np.ndarray:
    """The test's own forward kinematics of a standard DH arm (N, 3) m: Rz(θ+q)·Tz(d)·Tx(a)·Rx(α)·Ry(β) per joint
    from the parameters by name (base at the identity), the point (3,) m in the flange frame."""
    def turn(axis: int, t: float) -> np.ndarray:
        M, (i, j) = np.eye(4), [(1, 2), (2, 0), (0, 1)][axis]  # about x, y, z
        M[[i, i, j, j], [i, j, i, j]] = [np.cos(t), -np.sin(t), np.sin(t), np.cos(t)]
        return M

    def move(x: float, z: float) -> np.ndarray:
        M = np.eye(4)
        M[0, 3], M[2, 3] = x, z
        return M
    out = []
    for qk in np.atleast_2d(q):
        M = np.eye(4)
        for j, v in enumerate(qk, 1):
            M = M @ turn(2, params[f"j{j}.theta"] + v) @ move(0.0, params[f"j{j}.d"]) @ move(params[f"j{j}.a"], 0.0) \
                @ turn(0, params[f"j{j}.alpha"]) @ turn(1, params.get(f"j{j}.beta", 0.0))
        out.append(M[:3, :3] @ point + M[:3, 3])
    return np.array(out)


@pytest.mark.parametrize("arm, language, suffix", [("ur5", "ur", "script"), ("abb_irb120", "rapid", "mod")])
def test_joint_targets_take_a_move_of_the_measured_point_beyond_a_links_error_as_its_mounting(tmp_path, capsys, arm,
                                                                                               language, suffix):
    """The reflector mounted 2.4 mm from where it is declared: the calibration moves the declared point by more than
    a link's error (1 mm, --link-error-max), the target's mounting, carried over as nothing. A joint target (URScript
    movej, RAPID MoveAbsJ) then means where the nominal model puts the FITTED point at its joints: the written joints
    put the calibrated model's point there (the test's own DH kinematics, within 1e-6 m), in every language alike.
    Before, URScript's movej aimed the declared point: the real flange moved by the mounting's 2.4 mm."""
    from kincal.cli import main

    nominal = kincal.load_robot(arm).with_tool_point(np.array([0.0, 0.0, 0.03]))
    assert not np.any([nominal.params.as_dict()[n] for n in nominal.base_params()])  # the base at the identity
    true = kincal.perturb(nominal, seed=2, names=[n for n in nominal.params.names if n not in nominal.base_params()])
    true = true.with_tool_point(true.tool_point() + np.array([0.002, -0.001, 0.0008]))
    fit = kincal.calibrate(nominal, kincal.simulate(true, nominal.sample_joints(200, seed=1), 0.0),
                           kincal.FitOptions(diagnose=False))
    kincal.save_robot(fit.robot, tmp_path / "cal.yaml", calibration=fit.record())
    fitted = fit.robot.tool_point()
    assert np.linalg.norm(fitted - nominal.tool_point()) > 2e-3  # beyond a link's error: the mounting
    q = np.radians([[10.0, -80, 100, 20, 40, 30], [-25, -100, 110, -30, -50, 60]])
    if language == "ur":
        q = np.radians([[0.0, -100, 110, -100, -90, 0], [20, -80, 100, -110, -80, 10]])
        text = "def j():\n" + "".join(f"  movej([{', '.join(f'{v:.10f}' for v in qk)}])\n" for qk in q) + "end\n"
    else:
        q = np.radians([[10.0, 20, -10, 30, -40, 50], [-15, 10, 5, -20, -50, 10]])
        text = "MODULE j\n  PROC main()\n" + "".join(
            f"    MoveAbsJ [[{','.join(f'{v:.6f}' for v in np.degrees(qk))}],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, "
            f"tool0;\n" for qk in q) + "  ENDPROC\nENDMODULE\n"
    (tmp_path / f"j.{suffix}").write_text(text)
    q = np.array([t.values for t in read_program(str(tmp_path / f"j.{suffix}"), language).targets])  # as written
    capsys.readouterr()
    assert main(["compensate", str(tmp_path / "cal.yaml"), str(tmp_path / f"j.{suffix}"), "--program", language,
                 "-o", str(tmp_path / f"out.{suffix}")]) == 0
    said = capsys.readouterr().out
    written = np.array([t.values for t in read_program(str(tmp_path / f"out.{suffix}"), language).targets])
    calibrated = {**fit.robot.params.as_dict(), **{n: 0.0 for n in nominal.base_params()}}  # the controller's base
    reached = _dh_point(calibrated, written, fitted)
    meant = _dh_point(nominal.params.as_dict(), q, fitted)  # the nominal model's fitted point at the old joints
    assert (np.linalg.norm(reached - meant, axis=1) < 1e-6).all(), np.linalg.norm(reached - meant, axis=1)
    declared = _dh_point(nominal.params.as_dict(), q, nominal.tool_point())
    assert (np.linalg.norm(reached - declared, axis=1) > 2e-3).all()  # not the declared point's place
    assert "taken as the target's mounting" in said  # the note says so, for a program of joint targets too


def test_a_target_refused_by_the_written_text_check_has_nan_joints(tmp_path, monkeypatch):
    """A target whose written text check_written refuses kept its corrected joints in ProgramCompensation.q, which
    says NaN where refused (and its tcp was NaN): now NaN. The check is made to refuse the Cartesian target of a
    two-target KRL module; the joint target's joints stay those of the run without the refusal."""
    branch = sys.modules["kincal.compensate.branch"]  # kincal.compensate is also a function: no attribute path
    from kincal.io import ROWS
    nominal = kincal.load_robot("kuka_kr6r900sixx")
    real = kincal.perturb(nominal, seed=1)
    (tmp_path / "d.src").write_text("DEF d()\nPTP {A1 20, A2 -70, A3 80, A4 10, A5 40, A6 5}\nLIN {X 609.5, Y -231.3, "
                                    "Z 728.6, A -29.83, B 49.15, C -20.16, S 2, T 2}\nEND\n")
    program = read_program(str(tmp_path / "d.src"), "krl")
    frames = {"default tool": np.eye(4), "default base": np.eye(4)}
    free = compensate_branches(real, nominal, program, ROWS["krl"], frames)
    assert not free.refused and np.isfinite(free.q).all()
    monkeypatch.setattr(branch, "check_written", lambda *a, **k: {1: "the written text misses (test)"})
    res = compensate_branches(real, nominal, program, ROWS["krl"], frames)
    assert sorted(res.refused) == [1] and sorted(res.texts) == [0]
    assert np.isnan(res.q[1]).all() and np.isnan(res.tcp[1]).all()
    np.testing.assert_array_equal(res.q[0], free.q[0])


def test_the_wrong_robot_sentence_names_branch_bits_only_where_the_language_has_them():
    """foreign's sentence said "or on none of its branches with the target's bits" of a URScript program too, whose
    targets carry no branch bits; it says so only for the languages with bits (kincal.io.branches.BITS: KRL, RAPID,
    FANUC, INFORM). 2 of 3 targets unreached: more than half, so both sentences are given."""
    from kincal.compensate.program import Unreached, foreign
    from kincal.io.branches import BITS
    from kincal.io.programs import Program
    refused = {0: Unreached("a"), 1: Unreached("b")}
    bits = "on none of its branches with the target's bits"
    for dialect in ("ur", *BITS):
        said = foreign(kincal.load_robot("ur5"), Program("p", "", targets=(None,) * 3, dialect=dialect), refused)
        assert said.startswith("the program looks written for another robot: 2 of its 3 literal targets are out of "
                               "ur5's reach as written (beyond its reach or joint limits"), said
        assert (bits in said) == (dialect != "ur"), (dialect, said)
