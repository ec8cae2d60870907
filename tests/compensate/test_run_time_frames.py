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
