"""KUKA's BAS calls set the tool and base along a KRL program's flow (kincal.io.krl_flow): ``BAS(#TOOL, n)`` and
``BAS(#BASE, n)`` set TOOL_DATA[n] and BASE_DATA[n] like the assignments, ``BAS(#FRAMES)`` and the inline forms'
``BAS(#PTP_PARAMS, v)`` the TOOL_NO and BASE_NO of the FDAT in FDAT_ACT, and a number known only at run time makes
the frame unknown after it (the moves refused, with the line). A module with its $config.dat and $machine.dat beside
it, compensated for a perturbed UR10; each written target checked by the test's own numpy: the frames built from
the numbers written in the files, the controller's inverse by the UR10's textbook DH product, the true arm there."""
import shutil

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

import kincal
from kincal.compensate.branch import compensate_branches
from kincal.io import read_program

from conftest import shared_dataset
from test_program_branches import _frame, _ur10_flange, config_of, rows

# the frames as written in $config.dat and $machine.dat: X, Y, Z (mm), A, B, C (deg; R = Rz(A)·Ry(B)·Rx(C))
TOOL1, TOOL2 = (10.0, -20.0, 150.0, 0.0, 0.0, 30.0), (-20.0, 30.0, 220.0, 15.0, 20.0, 0.0)
BASE2 = (650.0, 120.0, -40.0, 30.0, 0.0, 0.0)  # in the world
ROOT = (2000.0, -500.0, 300.0, 90.0, 0.0, 0.0)  # $ROBROOT_C: the robot's base in the world
Q = np.array([[0.3, -1.2, 1.4, -0.5, 1.1, 0.4], [-0.6, -1.0, 1.2, 0.7, -1.3, 2.0], [0.5, -1.4, 1.6, -0.2, 0.9, 1.0],
              [0.2, -1.1, 1.3, -0.4, 1.2, 0.3], [-0.3, -1.3, 1.5, 0.5, -1.0, 1.5], [0.1, -1.2, 1.5, 0.3, 1.0, -0.5]])
RAW = "{X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}"


def _pose(numbers):
    """A KRL frame's 4x4 (m) from its numbers as written, by scipy: apart from kincal's reader."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("ZYX", numbers[3:], degrees=True).as_matrix()
    T[:3, 3] = np.array(numbers[:3]) * 1e-3
    return T


def _written(numbers) -> str:
    return "X {},Y {},Z {},A {},B {},C {}".format(*numbers)


U1, U2 = _pose(TOOL1), _pose(TOOL2)
WORLD = np.linalg.inv(_pose(ROOT))  # base 0 ($NULLFRAME): the world, in the robot's base
B2 = WORLD @ _pose(BASE2)


def _target(qk, tool, base, point=False):
    """The TCP pose the nominal UR10 reaches at qk, in base and tool, as KRL numbers with its S and T."""
    T = np.linalg.inv(base) @ _ur10_flange(qk) @ tool
    a, b, c = Rotation.from_matrix(T[:3, :3]).as_euler("ZYX", degrees=True)
    x, y, z = T[:3, 3] * 1e3
    s, t = config_of(kincal.load_robot("ur10"), qk)
    return f"{{X {x:.6f},Y {y:.6f},Z {z:.6f},A {a:.6f},B {b:.6f},C {c:.6f},S {s},T {t}{',E1 0.0' * point}}}"


def _controller(folder):
    (folder / "$config.dat").write_text(
        f"DEFDAT  $CONFIG\nDECL FRAME TOOL_DATA[16]\nTOOL_DATA[1]={{{_written(TOOL1)}}}\n"
        f"TOOL_DATA[2]={{{_written(TOOL2)}}}\nDECL FRAME BASE_DATA[32]\nBASE_DATA[1]={RAW}\n"
        f"BASE_DATA[2]={{{_written(BASE2)}}}\nENDDAT\n")
    (folder / "$machine.dat").write_text(f"DEFDAT  $MACHINE\nFRAME $ROBROOT_C={{{_written(ROOT)}}}\nENDDAT\n")


def _lands(true, res, old, new, tool, base, k):
    """Miss (mm) and turn (rad) of the true arm from the pose ``old`` meant, where the controller (the UR10's DH
    product, solved here from res.q[k]) takes ``new`` with the same frames."""
    goal = base @ _frame(new.values) @ np.linalg.inv(tool)
    ik = least_squares(lambda x: np.concatenate([(_ur10_flange(x) - goal)[:3, 3], Rotation.from_matrix(
        _ur10_flange(x)[:3, :3] @ goal[:3, :3].T).as_rotvec()]), res.q[k], xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    pt, Rt, _, _ = true.with_tool_point(np.zeros(3)).pose_and_jacobian(ik[None])
    meant = base @ _frame(old.values) @ np.linalg.inv(tool)
    return (np.linalg.norm(pt[0] - meant[:3, 3]) * 1e3,
            np.linalg.norm(Rotation.from_matrix(Rt[0] @ meant[:3, :3].T).as_rotvec()))


def test_bas_calls_set_the_tool_and_base_of_the_moves_after_them(tmp_path):
    """$TOOL = TOOL_DATA[1], BAS (#base, 2 ), LIN, BAS (#TOOL,2 ), LIN, an inline PTP fold (FDAT_ACT=FP1: TOOL_NO 1,
    BASE_NO 0), LIN, Bas( #Tool , nTool ), LIN, FDAT_ACT = FP2 (TOOL_NO 2, BASE_NO 2), BAS(#FRAMES), LIN. Before,
    the BAS calls were not read: every LIN was taken in TOOL_DATA[1] and in no base (refused: 'give the one in
    force'); with base 2 given as the default, the LIN after BAS (#TOOL,2 ) was compensated for tool 1 and landed
    0.431 mm and 0.74 mrad from the pose meant (1.25 mm uncompensated), every check passed. Now they are compensated
    in (tool 1, base 2), (2, 2), (1, world), (2, 2) and land where the text meant on the true arm to 1e-6 mm and
    1e-9 rad; the LIN after the variable nTool is refused, naming line 15; the fold's XP1 in the .dat with FP1's
    tool 1 in the world."""
    nominal, true = kincal.load_robot("ur10"), kincal.perturb(kincal.load_robot("ur10"), seed=4)
    _controller(tmp_path)
    src = ["DEF t()", "  $TOOL = TOOL_DATA[1]", "  BAS (#base, 2 )", f"  LIN {_target(Q[0], U1, B2)}",
           "  BAS (#TOOL,2 )", f"  LIN {_target(Q[1], U2, B2)}",
           ";FOLD PTP P1 Vel=100 % PDAT1 Tool[1] Base[0];%{PE}%R 8.3.31,%MKUKATPBASIS,%CMOVE,%VPTP,%P 1:PTP, 2:P1, "
           "3:, 5:100, 7:PDAT1", "  $BWDSTART=FALSE", "  PDAT_ACT=PPDAT1", "  FDAT_ACT=FP1", "  BAS(#PTP_PARAMS,100)",
           "  PTP XP1", ";ENDFOLD", f"  LIN {_target(Q[2], U1, WORLD)}", "  Bas( #Tool , nTool )",
           f"  LIN {_target(Q[3], U2, WORLD)}", "  FDAT_ACT = FP2", "  BAS(#FRAMES)", f"  LIN {_target(Q[4], U2, B2)}",
           "END", ""]
    (tmp_path / "t.src").write_text("\r\n".join(src))
    (tmp_path / "t.dat").write_text("\r\n".join([
        "DEFDAT  T", f"DECL E6POS XP1={_target(Q[5], U1, WORLD, point=True)}",
        "DECL FDAT FP1={TOOL_NO 1,BASE_NO 0,IPO_FRAME #BASE,POINT2[] \" \"}", "DECL PDAT PPDAT1={VEL 100,ACC 100}",
        "DECL FDAT FP2={TOOL_NO 2,BASE_NO 2,IPO_FRAME #BASE,POINT2[] \" \"}", "ENDDAT", ""]))
    prog = read_program(str(tmp_path / "t.src"), "krl")
    assert [t.line for t in prog.targets] == [4, 6, 14, 16, 19]
    assert [t.frames for t in prog.targets] == [("TOOL_DATA[1]", "BASE_DATA[2]"), ("TOOL_DATA[2]", "BASE_DATA[2]"),
                                                ("TOOL_DATA[1]", "$NULLFRAME"), ("", "$NULLFRAME"),
                                                ("TOOL_DATA[2]", "BASE_DATA[2]")]
    res = compensate_branches(true, nominal, prog, rows, q_start=Q[0])
    assert sorted(res.texts) == [0, 1, 2, 4] and list(res.refused) == [3]
    assert res.refused[3] == ("its $TOOL is known only at run time: line 15's Bas( #Tool , nTool ) sets the tool "
                              "numbered by nTool; give it with its number written out (BAS(#TOOL,2) or $TOOL = "
                              "TOOL_DATA[2]) on every path before this move")
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "t.src").write_text(prog.with_targets(res.texts))
    new = read_program(str(tmp_path / "out" / "t.src"), "krl")
    for k, tool, base in ((0, U1, B2), (1, U2, B2), (2, U1, WORLD), (4, U2, B2)):
        miss, turn = _lands(true, res, prog.targets[k], new.targets[k], tool, base, k)
        assert miss < 1e-6 and turn < 1e-9, (k, miss, turn)
    dat = read_program(str(tmp_path / "t.dat"), "krl")
    assert [t.frames for t in dat.targets] == [("TOOL_NO 1", "BASE_NO 0")]
    res = compensate_branches(true, nominal, dat, rows, q_start=Q[5])
    assert list(res.texts) == [0]
    (tmp_path / "out" / "t.dat").write_text(dat.with_targets(res.texts))
    miss, turn = _lands(true, res, dat.targets[0], read_program(str(tmp_path / "out" / "t.dat"), "krl").targets[0],
                        U1, WORLD, 0)
    assert miss < 1e-6 and turn < 1e-9


@pytest.mark.parametrize("lines, frames, why", [
    (["bas(#tool,1)"], ("TOOL_DATA[1]", ""), ""),
    (["BAS ( #BASE , 02 )", "BAS(#TOOL, 0)"], ("$NULLFRAME", "BASE_DATA[2]"), ""),
    (["BAS(#TOOL, 3.0)", "$TOOL.Z = 200"], ("", ""), "its $TOOL is known only at run time: line 3's $TOOL.Z = 200 "
                                                     "changes it"),
    (["IF $IN[1] THEN", "  BAS(#TOOL,1)", "ELSE", "  BAS(#TOOL,k+1)", "ENDIF"], ("", ""),
     "the $TOOL assignments on lines 3, 5 may be in force here"),
    (["BAS(#FRAMES)"], ("", ""), "its $TOOL is known only at run time: line 2's BAS(#FRAMES) sets it from FDAT_ACT, "
                                 "which no line of the module sets before it"),
    (["FDAT_ACT = FP7", "BAS(#FRAMES)"], ("", ""), "line 3's BAS(#FRAMES) sets it from FDAT_ACT = FP7 (line 2), which "
                                                   "no DECL FDAT of this file declares"),
    (["FDAT_ACT = {TOOL_NO 2, BASE_NO 0, IPO_FRAME #BASE}", "BAS(#CP_PARAMS,2)"], ("TOOL_DATA[2]", "$NULLFRAME"), ""),
])
def test_bas_calls_in_any_case_and_spacing_and_their_run_time_numbers(tmp_path, lines, frames, why):
    (tmp_path / "p.src").write_text("\n".join(["DEF p()", *lines, "LIN {X 500,Y 0,Z 600,A 0,B 90,C 0}", "END", ""]))
    prog = read_program(str(tmp_path / "p.src"), "krl")
    assert prog.targets[0].frames == frames
    said = prog.in_force_of(prog.targets[0])
    assert (why in said) if why else said == ()


def test_the_real_ros_control_src_and_a_move_after_its_bas_tool(tmp_path):
    """CentroEPiaggio's lwr_hw/krl/ros_control.src: its one move, PTP $AXIS_ACT_MES on line 81, is before its
    BAS (#tool,1 ) of line 95 and goes where the robot is: listed, not compensated, as before. The same text with a
    LIN written after line 95 (and one after line 81): the first was read with no tool (the 'default tool' asked
    for), now in TOOL_DATA[1]; the one before the BAS call still with none set."""
    real = shared_dataset("robot_programs") / "krl" / "CentroEPiaggio__kuka-lwr" / "lwr_hw" / "krl" / "ros_control.src"
    prog = read_program(str(real), "krl")
    assert prog.targets == () and prog.in_force == ()
    assert [x for x in prog.not_literal if x[1].startswith("PTP")] == [
        (81, "PTP $AXIS_ACT_MES", "$AXIS_ACT_MES is the robot's position when the move starts, read at run time")]
    lines = real.read_bytes().decode("latin-1").split("\n")
    assert lines[94] == "BAS (#tool,1 )"
    lines[95:95] = ["LIN {X 500,Y 0,Z 600,A 0,B 90,C 0}"]
    lines[81:81] = ["LIN {X 400,Y 0,Z 600,A 0,B 90,C 0}"]
    shutil.copy(real.with_suffix(".dat"), tmp_path / "ros_control.dat")
    (tmp_path / "ros_control.src").write_bytes("\n".join(lines).encode("latin-1"))
    copy = read_program(str(tmp_path / "ros_control.src"), "krl")
    assert [(t.line, t.frames) for t in copy.targets] == [(82, ("", "")), (97, ("TOOL_DATA[1]", ""))]
    assert copy.in_force == ()


def test_a_dat_point_takes_the_tool_and_base_in_force_at_its_moves_in_the_src(tmp_path):
    """A .dat's points with no FDAT of their own (DECL E6POS PA={…}), moved to by its module's .src after
    'BAS(#BASE,2)' and 'BAS(#TOOL,2)' (PA), '$TOOL = TOOL_DATA[1]' (PB; XP[2] by 'LIN XP[i]', an index chosen at
    run time), and PC, moved to on line 10 in tool 1 and on line 14 after an IF that may set tool 2. Before, the .dat
    was read without the .src's flow: every point in ('', ''), compensated with the default tool and base given (tool
    1, base 2), PA silently for tool 1 where the program moves it in tool 2. Now PA is compensated in (TOOL_DATA[2],
    BASE_DATA[2]), PB and XP[2] in (TOOL_DATA[1], BASE_DATA[2]), and land where the text meant on the true arm to
    1e-6 mm and 1e-9 rad; PC is refused naming m.src's lines 10, 14 and the assignments on lines 5, 12, its text
    left byte for byte; PD (GLOBAL, which no move of the .src uses) keeps the default tool and base as before."""
    nominal, true = kincal.load_robot("ur10"), kincal.perturb(kincal.load_robot("ur10"), seed=4)
    _controller(tmp_path)
    (tmp_path / "m.src").write_text("\n".join([
        "DEF m()", "  BAS(#BASE, 2)", "  BAS(#TOOL, 2)", "  LIN PA", "  $TOOL = TOOL_DATA[1]", "  LIN PB",
        "  FOR i = 1 TO 3", "    LIN XP[i]", "  ENDFOR", "  LIN PC", "  IF $IN[1] THEN", "    $TOOL = TOOL_DATA[2]",
        "  ENDIF", "  LIN PC", "END", ""]))
    (tmp_path / "m.dat").write_text("\n".join([
        "DEFDAT  M", f"DECL E6POS PA={_target(Q[0], U2, B2, point=True)}",
        f"DECL E6POS PB={_target(Q[1], U1, B2, point=True)}", f"DECL E6POS PC={_target(Q[2], U1, B2, point=True)}",
        f"GLOBAL DECL E6POS PD={_target(Q[3], U1, B2, point=True)}", "DECL E6POS XP[3]",
        f"XP[2]={_target(Q[4], U1, B2, point=True)}", "ENDDAT", ""]))
    dat = read_program(str(tmp_path / "m.dat"), "krl")
    assert [t.variable for t in dat.targets] == ["PA", "PB", "PC", "PD", "XP[2]"]
    assert [t.frames for t in dat.targets] == [("TOOL_DATA[2]", "BASE_DATA[2]"), ("TOOL_DATA[1]", "BASE_DATA[2]"),
                                               ("", "BASE_DATA[2]"), ("", ""), ("TOOL_DATA[1]", "BASE_DATA[2]")]
    res = compensate_branches(true, nominal, dat, rows, {"default tool": U1, "default base": B2}, q_start=Q[0])
    assert sorted(res.texts) == [0, 1, 3, 4] and list(res.refused) == [2]
    assert res.refused[2] == (
        "at the moves to it in m.src (lines 10, 14): its $TOOL is not known from the module's structure: the $TOOL "
        "assignments on lines 5, 12 may be in force at the moves to it, one literal for each; give each its own "
        "point, after a $TOOL assignment that every path to it runs")
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "m.dat").write_text(dat.with_targets(res.texts))
    new = read_program(str(tmp_path / "out" / "m.dat"), "krl")
    assert new.text.splitlines()[3] == dat.text.splitlines()[3]  # PC as it was
    for k, tool in ((0, U2), (1, U1), (3, U1), (4, U1)):
        miss, turn = _lands(true, res, dat.targets[k], new.targets[k], tool, B2, k)
        assert miss < 1e-6 and turn < 1e-9, (k, miss, turn)
