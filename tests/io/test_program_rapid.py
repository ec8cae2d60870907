"""ABB RAPID reader/rewriter: every real module of the shared data read and written back byte for byte,
targets and listed moves checked against numbers read independently, a synthetic module from the RAPID
manual's forms (values against closed forms, a changed rewrite), and one broken module per failure."""
import functools
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_dataset, skeleton
from scipy.spatial.transform import Rotation

from kincal.errors import MeasurementError
from kincal.io import read_program
from kincal.io.program_rapid import declared_frames, parse, write

FOLDER = shared_dataset("robot_programs") / "rapid"
FILES = sorted(p for p in FOLDER.rglob("*") if p.suffix.lower() in (".mod", ".modx", ".sys", ".prg"))
EGM = FOLDER / "rparak__ABB_EGM_Python"
HANOI = FOLDER / "rparak__ABB-RobotStudio-YUMI-Tower-of_Hanoi" / "RAPID"
LIB = FOLDER / "ernell__ABB-RAPID-UTILITY-LIBRARY" / "Contributions"


def _rel(path: Path) -> str:
    return str(path.relative_to(FOLDER))


@functools.cache
def _read(path: Path):
    """A module of the data folder as read_program reads it, once for the tests below that only look at it (a
    Program is frozen)."""
    return read_program(str(path), "rapid")


def _rotvec(q_wxyz) -> np.ndarray:
    """Independent: scipy's rotation vector of a (w, x, y, z) quaternion."""
    w, x, y, z = q_wxyz
    return Rotation.from_quat([x, y, z, w]).as_rotvec()


@pytest.mark.parametrize("path", FILES, ids=_rel)
def test_every_file_is_read_and_written_back_byte_for_byte(path):
    prog = _read(path)
    out = prog.with_values({k: t.values for k, t in enumerate(prog.targets)}).encode(prog.encoding)
    assert out == path.read_bytes()


def test_the_data_folder_holds_31_modules_with_311_targets():
    assert len(FILES) == 31
    kinds = [t.kind for p in FILES for t in _read(p).targets]
    assert (kinds.count("pose"), kinds.count("joints")) == (300, 11)  # 12 before pRobHome, only compared, was one


DECLARED = re.compile(r"^\s*(?:(?:LOCAL|TASK)\s+)?(?:CONST|PERS|VAR)\s+(robtarget|jointtarget)\s+(\w+)\s*:=\s*\[\[",
                      re.I | re.M)
INLINE = re.compile(r"^\s*Move\w*\s+\[\[", re.I | re.M)
CHANGED_IN_FILE = {"RobertAndersson/lib_rob.sys": 6,  # VAR robtarget rx1 … then rx1.trans := … (read by eye)
                   "JohnFraser/Sys_Functions.sys": 1}  # pRobHome: only compared (IF …<>pRobHome.robax)


@pytest.mark.parametrize("path", FILES, ids=_rel)
def test_target_counts_match_a_regex_over_the_raw_text(path):
    raw = path.read_text(encoding="latin-1")
    expected = len(DECLARED.findall(raw)) + len(INLINE.findall(raw))
    expected -= next((n for k, n in CHANGED_IN_FILE.items() if _rel(path).endswith(k)), 0)
    assert len(_read(path).targets) == expected


@pytest.mark.parametrize("path", [EGM / "ABB/CRB15000/RAPID/T_ROB1/Module1.modx",
                                  EGM / "ABB/IRB12000/RAPID/T_ROB1/Module1.mod"])
def test_egm_targets_values_configs_and_frames(path):
    prog = read_program(str(path), "rapid")
    assert len(prog.targets) == 142 and all(t.move == "robtarget" for t in prog.targets)
    first_line = 28 if path.suffix == ".modx" else 3
    t = prog.targets[1]  # CONST robtarget Target_20 (line 29 of the .modx, 4 of the .mod)
    assert (t.variable, t.line, t.config, t.frames) == ("Target_20", first_line + 1, (-1, 0, -1, 0), ("tool0", "wobj0"))
    np.testing.assert_allclose(t.values[:3], [0.450673200019, 0.002107908887, 0.740247895004], atol=1e-12)
    np.testing.assert_allclose(t.values[3:], _rotvec([0.221935885, -0.567098394, 0.775814982, 0.165090848]), atol=1e-8)
    assert prog.text[t.fields[3][0]:t.fields[3][1]] == "0.221935885"
    last = prog.targets[-1]  # CONST robtarget Target_1420:=[[302.44061813,…],…,[0,-1,-1,0],…]
    assert last.variable == "Target_1420" and prog.text[last.start:last.end].startswith("[[302.44061813,")
    assert last.config == (0, -1, -1, 0)
    assert prog.text[last.at:last.at + 17] == "MoveJ Target_1420"  # the first move to it


def test_hanoi_targets_offs_moves_and_the_jointtarget_of_moveabsj():
    prog = read_program(str(HANOI / "Real_World/Method_1/T_ROB_L/Module1.mod"), "rapid")
    init, grasp, home = prog.targets
    assert (init.variable, init.line, init.config, init.frames) == ("Target_INIT", 70, (0, 0, 2, 4), ("Servo", "wobj0"))
    assert (grasp.variable, grasp.line, grasp.config) == ("Target_GRASP", 71, (0, 1, 1, 4))
    np.testing.assert_allclose(grasp.values[3:], _rotvec([-0.000000157, 0, 0.870355756, -0.492423455]), atol=1e-8)
    assert (home.move, home.kind, home.line, home.frames, home.config) == ("MoveAbsJ", "joints", 181, ("tool0", ""), ())
    np.testing.assert_allclose(home.values, np.radians([0, -130, 30, 0, 40, 0]))
    assert len(home.fields) == 6  # eax_a (the arm angle, 135) stays as written
    assert len(prog.not_literal) == 11
    assert all(why == "Offs() displaces Target_GRASP at run time: the move goes with Target_GRASP's compensation (a "
               "literal target of its own, line 71); the offset itself is not corrected" for _, _, why in prog.not_literal)
    assert [n for n, _, _ in prog.not_literal][:3] == [109, 128, 132]


def test_library_modules_list_run_time_targets():
    prog = read_program(str(LIB / "RobertAndersson/lib_robmove.sys"), "rapid")
    assert prog.targets == ()
    reasons = {(n, why.split(" ")[0]) for n, _, why in prog.not_literal}
    assert len(prog.not_literal) == 18
    assert {(70, "RelTool()"), (292, "MidPos()"), (154, "pEndPoint"), (222, "p_endpos")} <= reasons
    assert (158, "SearchL pStart", "pStart is assigned at run time (line 151)") in prog.not_literal
    rob = read_program(str(LIB / "RobertAndersson/lib_rob.sys"), "rapid")
    assert [(n, w) for n, w, _ in rob.not_literal] == [(395, "robtarget rx1"), (396, "robtarget rx2"),
                                                      (397, "robtarget ry1"), (411, "robtarget rx1"),
                                                      (412, "robtarget rx2"), (413, "robtarget ry1")]
    leer = read_program(str(LIB / "LeeJustice/LEERULZ.mod"), "rapid")
    assert [n for n, _, _ in leer.not_literal] == [104, 106, 108, 169, 171, 173]
    assert all("parameter" in why for _, _, why in leer.not_literal)


def test_tooldata_and_wobjdata_are_exposed_not_targets():
    prog = read_program(str(LIB / "JohnFraser/Sys_Functions.sys"), "rapid")
    assert prog.targets == ()  # its one jointtarget, pRobHome, is only compared: test_a_point_only_compared_...
    frames = declared_frames(prog)
    tool, wobj = frames["yourtool"], frames["yourwobj"]
    assert (tool.kind, tool.line, tool.robhold, tool.oframe) == ("tooldata", 19, True, None)
    np.testing.assert_allclose(tool.frame[:3], [0.0452505, -0.00289384, 0.357831])
    np.testing.assert_allclose(tool.frame[3:], _rotvec([0.870472, 0.00718865, 0.492121, -0.00657274]), atol=1e-9)
    assert (wobj.kind, wobj.line, wobj.robhold) == ("wobjdata", 20, False)
    np.testing.assert_allclose(wobj.frame[:3], [3.69883, -1.55043, 0.702404])
    np.testing.assert_allclose(wobj.oframe[:3], [-2.63968, -0.450586, -0.245961])


# A module written from the RAPID manual's forms, with the awkward text features: BOM, %%% header, CRLF
# and LF mixed, tabs, case variants, -.242, exponents, strings and comments that look like moves, no
# final newline.
ROB = "[[{x},{y},{z}],[{q}],[{cf}],[9E9,9E+09,9E9,9E9,9E9,9E9]]"
LINES = [
    "\ufeff%%%",                                                                              # 1
    "  VERSION:1",                                                                            # 2
    "%%%",                                                                                    # 3
    "MODULE Synth",                                                                           # 4
    "\tconst RobTarget pZ90 := " + ROB.format(x=100, y="-.242", z="1.5E+02", q="0.70710678,0,0,0.70710678",
                                              cf="0,0,-1,1") + ";  ! about z by 90 deg",      # 5
    "  LOCAL PERS robtarget pX180:=" + ROB.format(x="-0", y="+5.0", z="90.", q="0,1,0,0", cf="1,0,0,0") + ";",  # 6
    "  TASK PERS robtarget pNeg:=" + ROB.format(x=0, y=0, z=0, q="-0.70710678,0,0,-0.70710678",
                                                cf="0,0,0,0") + ";",                          # 7
    "  VAR robtarget pArr{2} := [" + ROB.format(x=1, y=2, z=3, q="2,0,0,0", cf="0,0,0,0") + ", "
    + ROB.format(x=4, y=5, z=6, q="1,0,0,0", cf="0,-1,0,0") + "];",                             # 8
    "  CONST jointtarget jHome:=[[0,-90,90.,0,1.5e1,-180],[9E9,9E9,9E9,9E9,9E9,9E9]];",        # 9
    "  PERS tooldata tGun:=[TRUE,[[0,0,200],[1,0,0,0]],[2,[0,0,100],[1,0,0,0],0,0,0]];",       # 10
    "  PERS wobjdata wTable:=[FALSE,TRUE,\"\",[[500,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];",    # 11
    "  VAR robtarget pRun := " + ROB.format(x=1, y=1, z=1, q="1,0,0,0", cf="0,0,0,0") + ";",    # 12
    "  VAR robtarget pEmpty;",                                                               # 13
    "  CONST num x0 := 5;",                                                                  # 14
    "  PROC main()",                                                                         # 15
    "    ! MoveL [[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;",  # 16
    '    TPWrite "MoveJ [[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]] ! not code";',  # 17
    "    MOVEJ pZ90, v1000, z50, tGun\\WObj:=wTable;",                                        # 18
    "\tmovel pX180,v100,fine,tool0;",                                                       # 19
    "    MoveL pArr{2}, v100, fine, tGun;",                                                   # 20
    "    MoveAbsJ jHome\\NoEOffs, v1000, fine, tool0;",                                       # 21
    "    MoveAbsJ [[10,20,30,40,50,60],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]], v100, z10, tool0;",  # 22
    "    MoveC " + ROB.format(x=1, y=0, z=0, q="1,0,0,0", cf="0,0,0,0") + ",",                 # 23
    "          " + ROB.format(x=0, y=1, z=0, q="1,0,0,0", cf="0,0,0,0") + ", v100, z10, tGun \\WObj:=wTable;",  # 24
    "    MoveL \\Conc, Offs(pZ90, 0, 0, 50), v100, z10, tGun\\WObj:=wTable;",                 # 25
    "    MoveJ RelTool(pZ90, 0, 0, -10 \\Rz:=45), v100, z10, tGun;",                          # 26
    "    pRun := CRobT(\\Tool:=tGun \\WObj:=wTable);",                                        # 27
    "    MoveL pRun, v100, fine, tGun;",                                                     # 28
    "    MoveAbsJ CJointT(), v100, fine, tool0;",                                            # 29
    "    MoveL pEmpty, v100, fine, tool0;",                                                  # 30
    "    MoveL pOther, v100, fine, tool0;",                                                  # 31
    "    MoveL [[x0,0,0],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;",  # 32
    "    MoveJDO pZ90, v100, fine, tool0, do1, 1;",                                           # 33
    "    TriggL " + ROB.format(x=7, y=8, z=9, q="1,0,0,0", cf="0,0,0,0") + ", v100, gunon, fine, tGun;",  # 34
    "    SearchL \\Stop, di1, pEmpty, pArr{1}, v100, tGun;",                                  # 35
    "    pEmpty := " + ROB.format(x=1, y=2, z=3, q="1,0,0,0", cf="0,0,0,0") + ";",            # 36
    "  ENDPROC",                                                                             # 37
    "  PROC go(robtarget pPar)",                                                             # 38
    "    VAR robtarget pZ90 := " + ROB.format(x=9, y=9, z=9, q="1,0,0,0", cf="0,0,0,0") + ";",  # 39
    "    MoveL pZ90, v100, fine, tool0;",                                                    # 40
    "    MoveL pPar, v100, fine, tool0;",                                                    # 41
    "  ENDPROC",                                                                             # 42
    "ENDMODULE",                                                                             # 43
]
SYNTH = "".join(line + ("\r\n" if k % 3 else "\n") for k, line in enumerate(LINES[:-1])) + LINES[-1]
H = np.sqrt(0.5)


def test_synthetic_module_targets_against_closed_forms():
    prog = parse("synth.mod", SYNTH)
    got = [(t.line, t.move, t.variable, t.kind) for t in prog.targets]
    assert got == [(5, "robtarget", "pZ90", "pose"), (6, "robtarget", "pX180", "pose"),
                   (7, "robtarget", "pNeg", "pose"), (8, "robtarget", "pArr{1}", "pose"),
                   (8, "robtarget", "pArr{2}", "pose"),
                   (9, "jointtarget", "jHome", "joints"), (22, "MoveAbsJ", "", "joints"), (23, "MoveC", "", "pose"),
                   (24, "MoveC", "", "pose"), (34, "TriggL", "", "pose"), (39, "robtarget", "pZ90", "pose")]
    z90, x180, neg, a1, a2, home, inline, via, to, trigg, local = prog.targets
    np.testing.assert_allclose(z90.values, [0.1, -0.000242, 0.15, 0, 0, np.pi / 2], atol=1e-8)
    np.testing.assert_allclose(x180.values, [0, 0.005, 0.09, np.pi, 0, 0], atol=1e-12)
    np.testing.assert_allclose(neg.values[3:], [0, 0, np.pi / 2], atol=1e-8)  # -q is the same rotation
    np.testing.assert_allclose(a1.values, [0.001, 0.002, 0.003, 0, 0, 0])  # [2,0,0,0]: norm 2, no rotation
    np.testing.assert_allclose(home.values, np.radians([0, -90, 90, 0, 15, -180]))
    np.testing.assert_allclose(inline.values, np.radians([10, 20, 30, 40, 50, 60]))
    np.testing.assert_allclose([via.values[0], to.values[1]], [0.001, 0.001])
    assert (z90.config, x180.config, a2.config, home.config) == ((0, 0, -1, 1), (1, 0, 0, 0), (0, -1, 0, 0), ())
    assert (z90.frames, x180.frames, a2.frames, home.frames) == (("tGun", "wTable"), ("tool0", ""), ("tGun", ""),
                                                                 ("tool0", ""))
    assert (via.frames, trigg.frames, a1.frames, local.frames) == (("tGun", "wTable"), ("tGun", ""), ("tGun", ""),
                                                                   ("tool0", ""))
    assert [SYNTH[a:b] for a, b in z90.fields] == ["100", "-.242", "1.5E+02", "0.70710678", "0", "0", "0.70710678"]
    assert SYNTH[z90.at:z90.at + 10] == "MOVEJ pZ90" and SYNTH[neg.at:neg.at + 14] == "PERS robtarget"  # no move
    assert SYNTH[z90.start:z90.end].startswith("[[100,") and SYNTH[z90.end - 1] == "]"


def test_synthetic_module_lists_what_is_not_a_literal():
    listed = {n: (what, why) for n, what, why in parse("synth.mod", SYNTH).not_literal}
    assert sorted(listed) == [12, 25, 26, 28, 29, 30, 31, 32, 33, 36, 41]
    assert listed[12] == ("robtarget pRun", "declared with a literal but assigned at run time (line 27): the moves "
                                            "use the value set then")
    assert listed[25][1].startswith("Offs() displaces pZ90 at run time: the move goes with pZ90's compensation (a "
                                    "literal target of its own, line 5)")
    assert listed[26][1].startswith("RelTool() displaces pZ90")
    assert listed[28][1] == "pRun is assigned at run time (line 27)"
    assert listed[29][1].startswith("CJointT() reads the robot's joints")
    assert listed[30][1] == "pEmpty is assigned at run time (line 35)"  # the SearchPoint of SearchL
    assert listed[31][1].startswith("pOther is not declared in this file")
    assert listed[32][1] == "the robtarget is built from values computed at run time (x0)"
    assert listed[33][0] == "MoveJDO pZ90" and "compensated for tGun and wTable (line 18)" in listed[33][1]
    assert listed[36][0].startswith("robtarget literal [[1,2,3]") and "outside a move" in listed[36][1]
    assert listed[41][1].startswith("pPar is a parameter")
    frames = declared_frames(parse("synth.mod", SYNTH))
    np.testing.assert_allclose(frames["tgun"].frame, [0, 0, 0.2, 0, 0, 0])
    np.testing.assert_allclose(frames["wtable"].frame, [0.5, 0, 0, 0, 0, 0])


def test_a_changed_rewrite_reparses_to_the_new_values_and_keeps_every_other_byte():
    prog = parse("synth.mod", SYNTH)
    rng = np.random.default_rng(4)
    new = {}
    for k, t in enumerate(prog.targets):
        step = rng.normal(size=t.values.shape) * (1e-3 if t.kind == "pose" else 1e-2)
        new[k] = t.values + step
    text = prog.with_values(new)
    again = parse("synth.mod", text)
    assert len(again.targets) == len(prog.targets)
    for k, t in enumerate(again.targets):
        if t.kind == "joints":
            np.testing.assert_allclose(t.values, new[k], atol=2e-10)  # 1e-8 deg
            continue
        np.testing.assert_allclose(t.values[:3], new[k][:3], atol=2e-10)  # 1e-7 mm
        turn = Rotation.from_rotvec(t.values[3:]).inv() * Rotation.from_rotvec(new[k][3:])
        assert turn.magnitude() < 1e-9  # the same rotation (past pi it reads back as its shorter twin)
    assert skeleton(text, again.targets) == skeleton(SYNTH, prog.targets)
    neg = again.targets[2]  # pNeg keeps its hemisphere (w < 0) and arr{1} its norm 2
    assert text[neg.fields[3][0]] == "-"
    q = [float(text[a:b]) for a, b in again.targets[3].fields[3:]]
    assert np.linalg.norm(q) == pytest.approx(2.0, abs=1e-9)
    assert prog.with_values({k: t.values for k, t in enumerate(prog.targets)}) == SYNTH


def test_write_refuses_values_of_the_wrong_size():
    prog = parse("synth.mod", SYNTH)
    with pytest.raises(ValueError):
        write(SYNTH, [prog.targets[0]], [np.zeros(5)])
    with pytest.raises(ValueError):
        write(SYNTH, [prog.targets[5]], [np.zeros(7)])


GOOD = "[[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]"
BROKEN = [  # (module, line, column, what the message says)
    ("MODULE m\n  CONST robtarget p := [[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9];\nENDMODULE",
     2, 24, "'[' not closed before the ';'"),
    ("MODULE m\n  VAR num a := 1];\nENDMODULE", 2, 17, "']' without its opening '['"),
    ("MODULE m\n  CONST robtarget p := [[1,2,3],[1,0,0,0],[0,0,0,0]];\nENDMODULE", 2, 24, "this one has 3 parts"),
    ("MODULE m\n  CONST robtarget p := [[1,2],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\nENDMODULE",
     2, 25, "this part has 2 values, not 3 numbers"),
    ("MODULE m\n  CONST jointtarget j := [[1,2,3,4,5],[9E9,9E9,9E9,9E9,9E9,9E9]];\nENDMODULE",
     2, 27, "this part has 5 values, not 6"),
    ("MODULE m\nPROC main()\n  MoveL [[1,2,1.2.3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v10, fine, tool0;\n"
     "ENDPROC\nENDMODULE", 3, 15, "'1.2.3' is not a number"),
    ("MODULE m\n  CONST robtarget p := [[1,,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\nENDMODULE",
     2, 28, "an empty field"),
    ('MODULE m\nPROC main()\n  TPWrite "not closed;\nENDPROC\nENDMODULE', 3, 11, "a string not closed on its line"),
    ("MODULE m\nPROC main()\n  MoveL p1, v10, fine, tool0\n  MoveL p2, v10, fine, tool0;\nENDPROC\nENDMODULE",
     3, 3, "MoveL without its closing ';' before the MoveL of line 4"),
    ("MODULE m\n  CONST robtarget p := [[1,2,3],[1,0,0,0],[0,0,1.5,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\nENDMODULE",
     2, 48, "must be whole numbers"),
    ("MODULE m\n  CONST robtarget p := [[1,2,3],[0,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\nENDMODULE",
     2, 34, "a quaternion of norm 0"),
    ("MODULE m\n  CONST robtarget p{3} := [" + GOOD + "," + GOOD + "];\nENDMODULE", 2, 27,
     "p is declared with 3 elements here; the value has 2"),
    ("MODULE m\n  CONST robtarget p " + GOOD + ";\nENDMODULE", 2, 21, "':=' or ';' expected after p"),
    ("MODULE m\n  PERS tooldata t := [TRUE,[[0,0,1],[1,0,0,0]]];\nENDMODULE", 2, 22, "a tooldata is"),
    ("MODULE m\nPROC main()\n  MoveL ;\nENDMODULE", 2, 1, "routine main without its END"),
    ("MODULE m\nPROC main()\n  MoveL \\Conc;\nENDPROC\nENDMODULE", 3, 3, "MoveL without its target argument"),
    ("MODULE m\nPROC main()\n  MoveL p1, , fine, tool0;\nENDPROC\nENDMODULE", 3, 13, "an empty argument of MoveL"),
    ("MODULE m\n  CONST robtarget p := " + GOOD + "\nENDMODULE", 2, 3, "the declaration of p without its closing ';'"),
    ("<?xml version=\"1.0\"?>\n<Module/>", 1, 1, "an XML file"),
]


@pytest.mark.parametrize("text, line, column, what", BROKEN, ids=[b[3][:30] for b in BROKEN])
def test_broken_modules_name_the_file_line_and_column(text, line, column, what):
    with pytest.raises(MeasurementError) as err:
        parse("bad.mod", text)
    message = str(err.value)
    assert message.startswith(f"bad.mod: line {line}, column {column}: "), message
    assert what in message and "\n" not in message


def test_a_point_the_module_uses_otherwise_than_as_a_moves_target_is_listed_not_compensated(tmp_path):
    """Sys_Functions.sys: LOCAL VAR jointtarget pRobHome:=[[0,0,0,0,35,0],…] (line 18) is compared with the robot's
    joints (line 92: IF jtPos.robax<>pRobHome.robax; line 113: a field of it as a limit) and its MoveAbsJ (line 142)
    is a comment: compensating it changed those comparisons. It is listed with the first such use, as KRL lists a
    module's point no move goes to (kincal.io.programs.used_otherwise); a point used by moves only, directly or as
    the base of Offs/RelTool, is still a target, and one of them compared too is listed."""
    from kincal.io.programs import used_otherwise

    prog = read_program(str(LIB / "JohnFraser/Sys_Functions.sys"), "rapid")
    raw = (LIB / "JohnFraser/Sys_Functions.sys").read_text(encoding="latin-1").splitlines()
    assert "pRobHome" in raw[91] and raw[141].lstrip().startswith("!!!MoveAbsJ pRobHome")  # lines 92, 142
    assert prog.targets == ()
    assert (18, "jointtarget pRobHome", used_otherwise("line 92 uses pRobHome otherwise than as a move's target (IF "
                                                       "jtPos.robax<>pRobHome.robax THEN)")) in prog.not_literal
    (tmp_path / "m.mod").write_text(
        "MODULE m\n  CONST robtarget pA:=[[500,0,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
        "  CONST robtarget pB:=[[500,100,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
        "  CONST jointtarget jH:=[[0,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
        "  PROC main()\n    MoveJ pA,v100,fine,tool0;\n    MoveL Offs(pA,0,0,50),v100,fine,tool0;\n"
        "    MoveL pB,v100,fine,tool0;\n    MoveAbsJ jH,v100,fine,tool0;\n"
        "    IF CRobT().trans.z > pB.trans.z THEN\n      Stop;\n    ENDIF\n  ENDPROC\nENDMODULE\n")
    m = read_program(str(tmp_path / "m.mod"), "rapid")
    assert [t.variable for t in m.targets] == ["pA", "jH"]
    assert (3, "robtarget pB", used_otherwise("line 10 uses pB otherwise than as a move's target (IF "
                                              "CRobT().trans.z > pB.trans.z THEN)")) in m.not_literal


def test_a_move_to_the_offs_of_a_compensated_target_says_it_goes_with_it(tmp_path, capsys):
    """MoveL Offs(pA,0,0,50) was listed "left as is" while pA itself is compensated, so the move changes at run time:
    Offs(pA, 0, 0, 50) is pA's new position plus 50 mm along the work object's z (RAPID's Offs), here 1.06 mm
    from the old one, as far as pA moved. It is listed as not rewritten, going with pA's compensation (the offset
    itself not corrected); a move to the Offs of a point the module uses otherwise (no target) says only literal
    targets are compensated."""
    import kincal
    from kincal.cli import main
    from kincal.io import ROWS

    nominal = kincal.load_robot("abb_irb120")
    res = kincal.calibrate(nominal, kincal.simulate(kincal.perturb(nominal, seed=3), nominal.sample_joints(60, seed=1),
                                                    noise=0.0), kincal.FitOptions(diagnose=False))
    kincal.save_robot(res.robot, tmp_path / "cal.yaml", calibration=res.record())
    q = np.radians([[10.0, 20, 10, 30, 50, 40]])
    x, y, z, w = Rotation.from_matrix(nominal.flange_rotation(q)[0]).as_quat()
    bits = ",".join(map(str, ROWS["rapid"](nominal, q)[0]))
    pose = ",".join(f"{v:.3f}" for v in nominal.forward(q)[0] * 1e3) + f"],[{w:.9f},{x:.9f},{y:.9f},{z:.9f}"
    (tmp_path / "m.mod").write_text(
        f"MODULE m\n  CONST robtarget pA:=[[{pose}],[{bits}],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
        "  CONST robtarget pB:=[[400,-50,450],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
        "  PROC main()\n    MoveJ pA,v100,fine,tool0;\n    MoveL Offs(pA,0,0,50),v100,fine,tool0;\n"
        "    MoveL Offs(pB,0,0,50),v100,fine,tool0;\n    IF CRobT().trans.z > pB.trans.z THEN\n      Stop;\n"
        "    ENDIF\n  ENDPROC\nENDMODULE\n")
    assert main(["compensate", str(tmp_path / "cal.yaml"), str(tmp_path / "m.mod"), "--program", "rapid", "-o",
                 str(tmp_path / "out.mod")]) == 0
    said = capsys.readouterr().out
    assert ("not rewritten: line 6: MoveL Offs(pA,0,0,50): Offs() displaces pA at run time: the move goes with pA's "
            "compensation (a literal target of its own, line 2); the offset itself is not corrected") in said
    assert "not rewritten: line 7: MoveL Offs(pB,0,0,50): Offs() displaces pB at run time; only literal targets are " \
           "compensated" in said and "left as is: line" not in said
    old, new = (re.search(r"pA:=\[\[([^\]]*)\]", (tmp_path / name).read_text()).group(1) for name in ("m.mod", "out.mod"))
    offset = np.array([0.0, 0.0, 50.0])  # Offs(pA, 0, 0, 50): pA's position plus the offset, the same frame
    before, after = np.array(old.split(","), float) + offset, np.array(new.split(","), float) + offset
    assert np.linalg.norm(after - before) > 0.5  # mm (1.06): the move to Offs(pA, ...) changed with pA
