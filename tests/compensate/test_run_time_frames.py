"""Frames a program sets at run time (FANUC ``UTOOL[n]=PR[i]``, ``UFRAME[n]=PR[i]``; Yaskawa ``MFRAME UF#(n)``,
``SETTOOL TL#(n)``; RAPID assignments to a tooldata or wobjdata): the targets in such a frame that the write may
reach, by the program's flow (its jumps back to a label, its loops), are refused and named with the write's line,
their text written back byte for byte; the others are compensated exactly as in the same program without the
writes."""
import re

import numpy as np
from scipy.spatial.transform import Rotation

import kincal
from kincal.compensate.branch import compensate_branches
from kincal.io import ROWS, frame_numbers, read_program


def _frame(x, y, z, rz=0.0, ry=0.0, rx=0.0):
    """A 4x4 frame from mm and deg (R = Rz·Ry·Rx)."""
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_euler("ZYX", [rz, ry, rx], degrees=True).as_matrix(), np.array([x, y, z]) / 1e3
    return T


def _targets(arm, q, frames, names, language):
    """The TCP poses (4x4, in its base frame, with its tool) of the flange at each q, and the arm's branch bits:
    T = B⁻¹ · F(q) · U for the (tool, base) names of each target."""
    flange = arm.with_tool_point(np.zeros(3))
    p, R, _, _ = flange.pose_and_jacobian(q)
    out = []
    for pk, Rk, (tool, base) in zip(p, R, names):
        F = np.eye(4)
        F[:3, :3], F[:3, 3] = Rk, pk
        out.append(np.linalg.inv(frames.get(base, np.eye(4))) @ F @ frames[tool])
    return out, ROWS[language](flange, q)


Q = np.radians([[10.0, 20.0, -10.0, 30.0, -40.0, 50.0], [-15, 10, 5, -20, -50, 10], [30, -5, -20, 40, -30, -60],
                [5, 25, -15, 10, -35, 20], [-25, 15, 0, -30, -45, 40], [20, 5, -5, 15, -55, -30],
                [0, 30, -25, 5, -40, 0]])


def _fanuc(frames, names, mn):
    nominal = kincal.load_robot("fanuc_lrmate200id")
    poses, bits = _targets(nominal, Q[:len(names)], frames, names, "fanuc")
    pos = ""
    for k, (T, b, (tool, base)) in enumerate(zip(poses, bits, names), 1):
        x, y, z, a, bb, c = frame_numbers(T)
        pos += (f"P[{k}]{{\n   GP1:\n\tUF : {base.split()[1]}, UT : {tool.split()[1]},\t\tCONFIG : "
                f"'{', '.join(map(str, b))}',\n\tX = {x:.3f} mm,\tY = {y:.3f} mm,\tZ = {z:.3f} mm,\n"
                f"\tW = {c:.3f} deg,\tP = {bb:.3f} deg,\tR = {a:.3f} deg\n}};\n")
    body = "".join(f"{k:4d}:  {s} ;\n" for k, s in enumerate(mn, 1))
    return "/PROG  RT\n/ATTR\n/MN\n" + body + "/POS\n" + pos + "/END\n"


def _compensated(tmp_path, name, text, language, arm, frames):
    path = tmp_path / name
    path.write_text(text)
    prog = read_program(str(path), language)
    nominal = kincal.load_robot(arm)
    real = kincal.perturb(nominal, seed=7)
    return prog, compensate_branches(real, nominal, prog, ROWS[language], frames, q_start=Q[0])


def _entry(text, k):
    """The text of /POS entry P[k] ({ … })."""
    return re.search(r"P\[%d\]\{[^}]*\}" % k, text).group()


def test_a_fanuc_tool_or_user_frame_set_at_run_time_refuses_the_targets_it_may_reach(tmp_path):
    """rt2.ls's case: 'UTOOL[2]=PR[9]' on line 5 of /MN, 'UFRAME[1]=PR[8]' on line 9, and 'IF …,JMP LBL[1]' on
    line 7 back to the LBL[1] of line 3. Before, every target was compensated with the frames' UT 2 and UF 1
    ('7 of 7'); now P[3] (UT 2, moved to between the label and the jump: the write reaches it the second time
    round), P[4] (UT 2, after the write) and P[6] (UF 1, after line 9) are refused naming the line and the write,
    their /POS entries written back byte for byte; P[1], P[2] (UT 2, before the write, outside the loop), P[5] (UT 1,
    which no line sets; 'PR[7]=UTOOL[1]' reads it) and P[7] (UF 0) are compensated, each exactly as in the same
    program without the writes."""
    frames = {"UT 1": _frame(0, 0, 100), "UT 2": _frame(5, -10, 120, ry=-30), "UF 1": _frame(400, 50, -100, rz=15)}
    names = [("UT 1", "UF 1"), ("UT 2", "UF 1"), ("UT 2", "UF 1"), ("UT 2", "UF 1"), ("UT 1", "UF 1"),
             ("UT 1", "UF 1"), ("UT 1", "UF 0")]
    mn = ["PR[7]=UTOOL[1]", "L P[1] 100mm/sec FINE", "L P[2] 100mm/sec FINE", "LBL[1]", "L P[3] 100mm/sec FINE",
          "UTOOL[2]=PR[9]", "L P[4] 100mm/sec FINE", "IF R[1]=1,JMP LBL[1]", "L P[5] 100mm/sec FINE",
          "UFRAME[1]=PR[8]", "L P[6] 100mm/sec FINE", "L P[7] 100mm/sec FINE", "! UTOOL[1]=PR[1]"]
    text = _fanuc(frames, names, mn)
    prog, res = _compensated(tmp_path, "rt.ls", text, "fanuc", "fanuc_lrmate200id", frames)
    variables = [t.variable for t in prog.targets]
    assert sorted(variables[k] for k in res.texts) == ["P[1]", "P[2]", "P[5]", "P[7]"]
    assert sorted(variables[k] for k in res.refused) == ["P[3]", "P[4]", "P[6]"]
    why = {variables[k]: w for k, w in res.refused.items()}
    assert why["P[3]"] == why["P[4]"] == (
        "its tool frame 'UT 2' may be the one the program sets at run time on line 9 (UTOOL[2]=PR[9]) at the moves "
        "to it: a value only the controller knows, not the one given with the frames; teach it in a frame the "
        "program does not set")
    assert why["P[6]"].startswith("its base frame 'UF 1' may be the one the program sets at run time on line 13 "
                                  "(UFRAME[1]=PR[8])")
    assert [text.splitlines()[n - 1].split(":", 1)[1].strip(" ;") for n in (9, 13)] == ["UTOOL[2]=PR[9]",
                                                                                        "UFRAME[1]=PR[8]"]
    out = prog.with_targets(res.texts)
    for k in (3, 4, 6):
        assert _entry(out, k) == _entry(text, k)
    for k in (1, 2, 5, 7):
        assert _entry(out, k) != _entry(text, k)
    # the same program without the writes: every target compensated, the same texts for those not refused here
    plain = text.replace("UTOOL[2]=PR[9]", "R[2]=9").replace("UFRAME[1]=PR[8]", "R[3]=8")
    prog0, res0 = _compensated(tmp_path, "plain.ls", plain, "fanuc", "fanuc_lrmate200id", frames)
    assert not res0.refused and sorted(res0.texts) == list(range(7))
    assert {k: res0.texts[k] for k in res.texts} == res.texts


def test_a_fanuc_write_with_no_jump_back_reaches_only_the_moves_after_it(tmp_path):
    """Without the jump, P[3] (UT 2, before 'UTOOL[2]=PR[9]') is compensated; a FOR … ENDFOR around the write and
    a move before it refuses that move; 'UTOOL[R[4]]=PR[9]' (a frame number chosen at run time) refuses every
    tool after it."""
    frames = {"UT 1": _frame(0, 0, 100), "UT 2": _frame(5, -10, 120, ry=-30)}
    names = [("UT 2", "UF 0"), ("UT 2", "UF 0"), ("UT 1", "UF 0"), ("UT 1", "UF 0")]
    mn = ["L P[1] 100mm/sec FINE", "UTOOL[2]=PR[9]", "L P[2] 100mm/sec FINE", "L P[3] 100mm/sec FINE",
          "UTOOL[R[4]]=PR[9]", "L P[4] 100mm/sec FINE"]
    prog, res = _compensated(tmp_path, "a.ls", _fanuc(frames, names, mn), "fanuc", "fanuc_lrmate200id", frames)
    assert sorted(res.texts) == [0, 2] and sorted(res.refused) == [1, 3]
    assert "on line 8 (UTOOL[R[4]]=PR[9])" in res.refused[3]
    looped = ["FOR R[1]=1 TO 3", "L P[1] 100mm/sec FINE", "UTOOL[2]=PR[9]", "ENDFOR", "L P[3] 100mm/sec FINE"]
    prog, res = _compensated(tmp_path, "b.ls", _fanuc(frames, names[:3], looped), "fanuc", "fanuc_lrmate200id",
                             frames)
    assert sorted(res.texts) == [2] and sorted(res.refused) == [0, 1]  # P[2] in UT 2: no move, set on line 6
    assert "where it is used (no move of the program goes to it)" in res.refused[1]


def test_a_fanuc_system_variable_write_of_a_tool_or_user_frame_refuses_as_utool_does(tmp_path):
    """'$MNUTOOL[1,2]=PR[9]' (group 1, tool 2), '$MNUFRAME [ 1 , 1 ].X = 500' (one number of user frame 1) and
    '$MNUTOOL[1,R[4]]=PR[9]' (a tool chosen at run time) were read as no write: P[2] (UT 2), P[3] (UF 1) and P[4]
    (UT 1) were compensated with the given frames ('5 of 5'). Now they are refused naming the line and the write,
    exactly as for 'UTOOL[2]=…', and P[5] (UT 3) too, by '$MNUTOOL[1,R[4]]' alone; P[1] (before the writes) is
    compensated exactly as in the program without them. '$MNUTOOL[2,3]=PR[9]' (group 2, a positioner's tool),
    '$MNUTOOLNUM[1]=2' (a selection) and 'PR[7]=$MNUTOOL[1,1]' (a read) write no frame of the robot: with only
    them, every target is compensated."""
    frames = {"UT 1": _frame(0, 0, 100), "UT 2": _frame(5, -10, 120, ry=-30), "UT 3": _frame(0, 30, 90, rx=20),
              "UF 1": _frame(400, 50, -100, rz=15)}
    names = [("UT 2", "UF 1"), ("UT 2", "UF 0"), ("UT 3", "UF 1"), ("UT 1", "UF 0"), ("UT 3", "UF 0")]
    mn = ["$MNUTOOLNUM[1]=2", "PR[7]=$MNUTOOL[1,1]", "L P[1] 100mm/sec FINE", "$MNUTOOL[1,2]=PR[9]",
          "L P[2] 100mm/sec FINE", "$MNUFRAME [ 1 , 1 ].X = 500", "L P[3] 100mm/sec FINE", "$MNUTOOL[2,3]=PR[9]",
          "$MNUTOOL[1,R[4]]=PR[9]", "L P[4] 100mm/sec FINE", "L P[5] 100mm/sec FINE"]
    text = _fanuc(frames, names, mn)
    prog, res = _compensated(tmp_path, "mn.ls", text, "fanuc", "fanuc_lrmate200id", frames)
    variables = [t.variable for t in prog.targets]
    assert sorted(variables[k] for k in res.texts) == ["P[1]"]
    assert sorted(variables[k] for k in res.refused) == ["P[2]", "P[3]", "P[4]", "P[5]"]
    why = {variables[k]: w for k, w in res.refused.items()}
    assert why["P[2]"] == (
        "its tool frame 'UT 2' may be the one the program sets at run time on line 7 ($MNUTOOL[1,2]=PR[9]) at the "
        "moves to it: a value only the controller knows, not the one given with the frames; teach it in a frame the "
        "program does not set")
    assert why["P[3]"].startswith("its base frame 'UF 1' may be the one the program sets at run time on line 9 "
                                  "($MNUFRAME [ 1 , 1 ].X = 500)")
    assert "on line 12 ($MNUTOOL[1,R[4]]=PR[9])" in why["P[4]"] and "line 11" not in why["P[4]"]
    assert "on line 12 ($MNUTOOL[1,R[4]]=PR[9])" in why["P[5]"] and "line 11" not in why["P[5]"]
    out = prog.with_targets(res.texts)
    for k in (2, 3, 4, 5):
        assert _entry(out, k) == _entry(text, k)
    # group 2's write alone leaves P[5] as it is; without the writes every target is compensated, the same texts
    plain = text.replace("$MNUTOOL[1,2]=PR[9]", "R[2]=9").replace("$MNUFRAME [ 1 , 1 ].X = 500", "R[3]=8")
    _, res2 = _compensated(tmp_path, "g2.ls", plain.replace("$MNUTOOL[1,R[4]]=PR[9]", "R[5]=1"), "fanuc",
                           "fanuc_lrmate200id", frames)
    assert not res2.refused and sorted(res2.texts) == list(range(5))
    assert {k: res2.texts[k] for k in res.texts} == res.texts


def _job(frames, names, inst):
    """An INFORM job of C positions C00000… (in USER coordinates, or ROBOT for base 'ROBOT') and instructions."""
    nominal = kincal.load_robot("motoman_gp7")
    poses, bits = _targets(nominal, Q[:len(names)], frames, names, "inform")
    pos = ""
    for k, (T, b, (tool, base)) in enumerate(zip(poses, bits, names)):
        x, y, z, a, bb, c = frame_numbers(T)
        pos += (f"///TOOL {tool.split()[1]}\n" + (f"///USER {base.split()[1]}\n///POSTYPE USER\n" if base != "ROBOT"
                                                  else "///POSTYPE ROBOT\n")
                + f"///RECTAN\n///RCONF {','.join(map(str, b))},0,0\n"
                f"C{k:05d}={x:.3f},{y:.3f},{z:.3f},{c:.4f},{bb:.4f},{a:.4f}\n")
    return (f"/JOB\n//NAME RT\n//POS\n///NPOS {len(names)},0,0,0,0,0\n{pos}//INST\n///DATE 2024/01/01 00:00\n"
            "///ATTR SC,RW\n///GROUP1 RB1\nNOP\n" + "".join(s + "\n" for s in inst) + "END\n")


def _line(text, what):
    return text.splitlines().index(what) + 1


def test_an_inform_user_frame_or_tool_set_at_run_time_refuses_the_targets_it_may_reach(tmp_path):
    """MF.JBI's case: 'MFRAME UF#(1) P001 P002 P003' made user frame 1 at run time, yet a later MOVL in USER 1 was
    compensated with the frames' USER 1 ('3 of 3'). Now C00001 (USER 1, between the label *L1 and 'JUMP *L1') and
    C00002 (after the MFRAME) are refused naming its line, C00004 (TOOL 2, after 'SETTOOL TL#(2) P004') too; C00000
    (before the label) and C00003 (TOOL 2 before the SETTOOL, ROBOT coordinates) are compensated exactly as in the
    job without those lines; the refused position lines are written back byte for byte."""
    frames = {"TOOL 1": _frame(0, 0, 100), "TOOL 2": _frame(0, 20, 150, rx=30),
              "USER 1": _frame(500, -200, 50, rz=-30)}
    names = [("TOOL 1", "USER 1")] * 3 + [("TOOL 2", "ROBOT")] * 2
    inst = ["MOVL C00000 V=100.0", "*L1", "MOVL C00001 V=100.0", "MFRAME UF#(1) P001 P002 P003",
            "MOVL C00002 V=100.0 'after it", "JUMP *L1 IF IN#(1)=ON", "MOVL C00003 V=100.0", "SETTOOL TL#(2) P004",
            "MOVJ C00004 VJ=25.00"]
    text = _job(frames, names, inst)
    prog, res = _compensated(tmp_path, "rt.JBI", text, "inform", "motoman_gp7", frames)
    variables = [t.variable for t in prog.targets]
    assert sorted(variables[k] for k in res.texts) == ["C00000", "C00003"]
    assert sorted(variables[k] for k in res.refused) == ["C00001", "C00002", "C00004"]
    why = {variables[k]: w for k, w in res.refused.items()}
    mframe, settool = _line(text, inst[3]), _line(text, inst[7])
    assert why["C00001"] == why["C00002"] == (
        f"its base frame 'USER 1' may be the one the program sets at run time on line {mframe} (MFRAME UF#(1) P001 "
        "P002 P003) at the moves to it: a value only the controller knows, not the one given with the frames; "
        "teach it in a frame the program does not set")
    assert why["C00004"].startswith(f"its tool frame 'TOOL 2' may be the one the program sets at run time on line "
                                    f"{settool} (SETTOOL TL#(2) P004)")
    out = prog.with_targets(res.texts).splitlines()
    for k in (1, 2, 4):
        assert out[prog.targets[k].line - 1] == text.splitlines()[prog.targets[k].line - 1]
    plain = text.replace(inst[3], "NOP").replace(inst[7], "NOP")
    _, res0 = _compensated(tmp_path, "plain.JBI", plain, "inform", "motoman_gp7", frames)
    assert not res0.refused and {k: res0.texts[k] for k in res.texts} == res.texts


def _module(frames, names, body):
    """A RAPID module: tooldata t30 and wobjdata w1 declared, robtargets p0… and the routine ``body``."""
    nominal = kincal.load_robot("abb_irb120")
    poses, bits = _targets(nominal, Q[:len(names)], frames, names, "rapid")
    points = []
    for k, (T, b) in enumerate(zip(poses, bits)):
        x, y, z = T[:3, 3] * 1e3
        qx, qy, qz, qw = Rotation.from_matrix(T[:3, :3]).as_quat()
        points.append(f"    CONST robtarget p{k}:=[[{x:.6f},{y:.6f},{z:.6f}],[{qw:.9f},{qx:.9f},{qy:.9f},{qz:.9f}],"
                      f"[{','.join(map(str, b))}],[9E9,9E9,9E9,9E9,9E9,9E9]];")
    return "\n".join(["MODULE Rt", "    PERS tooldata t30:=[TRUE,[[0,0,30],[1,0,0,0]],[1,[0,0,10],[1,0,0,0],0,0,0]];",
                      "    PERS wobjdata w1:=[FALSE,TRUE,\"\",[[300,-100,50],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];",
                      *points, "    PROC main()", *body, "    ENDPROC", "ENDMODULE", ""])


def test_a_rapid_tool_or_work_object_set_at_run_time_refuses_its_targets(tmp_path):
    """'t30.tframe.trans := [0,0,80];' (line 10, after a move with t30: main runs again, and a PERS keeps its value)
    and 'MToolTCPCalib p4,p4,p4,p4,tLong,e1,e2;' (line 13) set the tools at run time; with t30 and tLong given in
    the frames, p0 and p1 (t30) and p2 (tLong) were compensated with the given values. Now they are refused naming
    the lines; p3 (tool0, wobj w1, which nothing sets) is compensated exactly as in the module without those lines,
    and the refused declarations are written back byte for byte."""
    frames = {"t30": _frame(0, 0, 30), "tLong": _frame(10, -5, 150, ry=30), "w1": _frame(300, -100, 50)}
    names = [("t30", "wobj0"), ("t30", "w1"), ("tLong", "wobj0"), ("tool0", "w1")]
    frames["tool0"] = np.eye(4)
    body = ["        MoveL p0,v100,fine,t30;", "        t30.tframe.trans := [0,0,80];",
            "        MoveL p1,v100,fine,t30\\WObj:=w1;", "        MoveJ p2,v100,fine,tLong;",
            "        MToolTCPCalib p4,p4,p4,p4,tLong,e1,e2;", "        MoveL p3,v100,fine,tool0\\WObj:=w1;"]
    text = _module(frames, names, body)
    given = {k: v for k, v in frames.items() if k != "tool0"}
    prog, res = _compensated(tmp_path, "rt.mod", text, "rapid", "abb_irb120", given)
    variables = [t.variable for t in prog.targets]
    assert sorted(variables[k] for k in res.texts) == ["p3"]
    assert sorted(variables[k] for k in res.refused) == ["p0", "p1", "p2"]
    why = {variables[k]: w for k, w in res.refused.items()}
    assert why["p0"] == why["p1"] == (
        "its tool frame 't30' may be the one the program sets at run time on line 10 (t30.tframe.trans := [0,0,80]) "
        "at the moves to it: a value only the controller knows, not the one given with the frames; teach it in a "
        "frame the program does not set")
    assert "on line 13 (MToolTCPCalib p4,p4,p4,p4,tLong,e1,e2)" in why["p2"]
    assert [_line(text, body[1]), _line(text, body[4])] == [10, 13]
    out = prog.with_targets(res.texts).splitlines()
    for k in range(3):
        assert out[prog.targets[k].line - 1] == text.splitlines()[prog.targets[k].line - 1]
    plain = text.replace(body[1], "").replace(body[4], "")
    _, res0 = _compensated(tmp_path, "plain.mod", plain, "rapid", "abb_irb120", given)
    assert not res0.refused and {k: res0.texts[k] for k in res.texts} == res.texts
