"""FANUC TP (.ls) programs: every real file of the data folder read and written back byte for byte,
targets and listed moves against numbers read independently, a program written from the format's
description (every kind of position, move and awkward text) with values against closed forms and a
rewrite that changes only the fields, and one broken program per failure kind."""
import re

import numpy as np
import pytest
from conftest import shared_dataset, skeleton

from kincal.errors import MeasurementError
from kincal.io import read_program
from kincal.io.program_fanuc import DIALECT
from kincal.io.programs import dialects
from kincal.models.transforms import rot_zyx, rotvec_matrix

FOLDER = shared_dataset("robot_programs") / "fanuc"
FILES = sorted(p for p in FOLDER.rglob("*") if p.suffix.lower() in DIALECT.suffixes)


def test_the_dialect_is_registered():
    assert dialects()["fanuc"] is DIALECT
    assert DIALECT.suffixes == (".ls",) and DIALECT.comment == ""  # TP has no comment after a /POS entry: refusals are reported, not marked
    assert len(FILES) == 30 and any(p.suffix == ".LS" for p in FILES)


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(FOLDER)))
def test_every_real_file_is_read_and_written_back_byte_for_byte(path):
    prog = read_program(str(path), "fanuc")
    again = prog.with_values({k: t.values for k, t in enumerate(prog.targets)})
    assert again.encode(prog.encoding) == path.read_bytes()
    raw = path.read_text(encoding="latin-1")
    # independently: the /POS entries that have a GP1 group, and the moves to a position register
    entries = re.findall(r"^P\[\d+[^\]\n]*\]\{\s*GP1:", raw, re.M)
    registers = re.findall(r"^[ \t]*(?:\d*[ \t]*:)?[ \t]*[JLCA][ \t]+PR\[", raw, re.M)
    circular = len(re.findall(r"^[ \t]*(?:\d*[ \t]*:)?[ \t]*C[ \t]+PR\[[^\]]*\][ \t]+PR\[", raw, re.M))
    assert len(prog.targets) == len(entries)
    assert sum(what.split()[1].startswith("PR[") for _, what, _ in prog.not_literal) == len(registers) + circular
    for line, what, why in prog.not_literal:
        assert what.split()[1].split("[")[0] in raw.splitlines()[line - 1] and why


def _one(name):
    return read_program(str(FOLDER / name), "fanuc")


def test_real_joint_positions_with_their_frames():
    prog = _one("KonstantynBely__karelCalibration/TCPCalibrator/Robot_1/temp/PRO_MOV2.LS")
    (t,) = prog.targets
    # line 26 "P[1]{", lines 28-30: UF : 0, UT : 5, J1 = -43.937 deg … J6 = -7.906 deg; line 24 "3: J P[1] 100% FINE ;"
    assert (t.line, t.move, t.variable, t.kind, t.config, t.frames) == (26, "J", "P[1]", "joints", (), ("UT 5", "UF 0"))
    assert np.allclose(t.values, np.deg2rad([-43.937, 55.411, -78.683, 0.0, -81.876, -7.906]), atol=1e-15)
    assert prog.text[t.start] == "{" and prog.text[t.end - 1] == "}" and prog.text[t.at:t.at + 4] == "J P["
    assert [prog.text[a:b] for a, b in t.fields] == ["-43.937", "55.411", "-78.683", "0.000", "-81.876", "-7.906"]
    assert prog.not_literal == ()
    home = _one("kobbled__rossum_example_ws/src/task-sync-test/src/move_to_home.ls")
    (h,) = home.targets  # line 25 P[1:""]{ … UF : 0, UT : 1, J1 = 127.834 … J6 = 54.899; used by "J P[1:home]"
    assert (h.line, h.move, h.frames) == (25, "J", ("UT 1", "UF 0"))
    assert np.allclose(np.rad2deg(h.values), [127.834, 24.311, -29.462, -110.295, 121.424, 54.899], atol=1e-12)


def test_real_moves_that_are_listed():
    test = _one("KonstantynBely__karelCalibration/src/tp/old/test.ls")
    assert test.targets == ()
    assert test.not_literal[0] == (33, "J P[3]", "P[3] has no entry in /POS")
    why = {line: w for line, _, w in test.not_literal}
    assert "INC" in why[35] and "VOFFSET, VR[1]" in why[36] and "OFFSET, PR[1]" in why[37]
    assert "TOOL_OFFSET, PR[1]" in why[38] and "tool frame" in why[38]
    assert [w for line, w, _ in test.not_literal if line == 39] == ["C PR[3]", "C PR[4]"]
    offset = _one("kobbled__rossum_example_ws/src/lib_a/src/foo_move.ls")
    ((line, what, why),) = offset.not_literal
    assert (line, what) == (26, "J PR[AR[1]]") and "Offset,PR[AR[2]]" in why and "position register" in why
    ros = _one("ros-industrial__fanuc/fanuc_driver/tpe/ros_movesm.ls")  # CRLF; register comments with blanks
    assert [(n, w) for n, w, _ in ros.not_literal] == [(43, "J PR[2:ROS-I p cache]")]


# A program written from the format's description: BOM, CRLF and LF mixed, tabs, no final newline,
# numbers like -.242, +5., 1.5e2; lower-case option names; comments, strings, MESSAGE text and a line
# commented out that name positions; positions of every kind.
LINES = [
    "\ufeff/PROG  SYNTH\r\n",
    "/ATTR\r\n",
    "OWNER\t\t= MNEDITOR;\r\n",
    'COMMENT\t\t= "J P[9] 100% FINE ;";\r\n',
    "LINE_COUNT\t= 14;\r\n",
    "DEFAULT_GROUP\t= 1,1,*,*,*;\r\n",
    "/MN\r\n",
    "   1:  UFRAME_NUM=1 ;\r\n",  # line 8
    "   2:  ! J P[9] 100% FINE ;\r\n",
    "   3:J P[1:home] 100% FINE    ;\n",  # line 10
    "   4:L P[2] 500mm/sec CNT100 ACC80    ; ! after: L P[9]\r\n",
    "   5:C P[3]    \r\n",  # line 12
    "    :  P[4] 200mm/sec FINE    ;\r\n",
    "   6:  //L P[9] 100mm/sec FINE ;\r\n",
    "   7:  MESSAGE[L P[9] here] ;\r\n",
    "   8:L P[5] 100mm/sec FINE tool_offset,PR[2:shift]    ;\r\n",  # line 16: P[5] only with an offset
    "   9:L P[6] 100mm/sec FINE inc    ;\r\n",  # line 17: P[6] also plainly below
    "  10:j P[6] 50% CNT50    ;\r\n",
    "  11:A P[10] 100mm/sec CNT100    ;\r\n",  # line 19
    "  12:J P[R[4]] 100% FINE    ;\r\n",
    "  13:J P[11] 100% FINE Offset    ;\r\n",  # line 21: no /POS entry, and Offset
    "  14:J P[12] 100% FINE    ;\r\n",  # line 22: not taught
    "/POS\r\n",
    'P[1:"home {x};"]{\r\n',  # line 24
    "   GP1:\r\n",
    "\tUF : 1, UT : 2,\t\tCONFIG : 'N U T, 0, 0, 0',\r\n",
    "\tX =   500.000  mm,\tY =  -.242  mm,\tZ =   1.5e2  mm,\r\n",  # line 27
    "\tW =     0.000 deg,\tP =     0.000 deg,\tR =    90.000 deg\r\n",
    "};\r\n",
    "P[2]{\n",  # line 30
    "   GP1:\n",
    "\tUF : 1, UT : 2,\t\tCONFIG : 'F D B, -1, 0, 1',\n",
    "\tX =  +5.  mm,\tY = 0 mm,\tZ = -10.5 mm,\n",
    "\tW =   180.000 deg,\tP =     0.000 deg,\tR =     0.000 deg,\n",
    "\tE1 =   250.000  mm\n",
    "   GP2:\n",
    "\tUF : 1, UT : 2,\n",
    "\tJ1=    45.000  deg,\tJ2 =  -10.000 deg\n",
    "};\n",
    "P[3]{\r\n",  # line 40
    "   GP1:\r\n",
    "\tUF : 0, UT : 1,\r\n",
    "\tJ1 =    10.000 deg,\tJ2 =   -20.000 deg,\tJ3 =    30.000 deg,\r\n",
    "\tJ4 =   -.500 deg,\tJ5 =    90.000 deg,\tJ6 =  -180.000 deg,\tE1 = 12.000 mm\r\n",
    "};\r\n",
    "P[4]{\r\n",  # line 46
    "   GP1:\r\n",
    "\tUF : 1, UT : 2,\t\tCONFIG : 'N U T, 0, 0, 0',\r\n",
    "\tX =  100.000  mm,\tY =  200.000  mm,\tZ =  300.000  mm,\r\n",
    "\tW =    30.000 deg,\tP =    90.000 deg,\tR =     0.000 deg\r\n",
    "};\r\n",
    "P[5]{\r\n",  # line 52: used only with Tool_Offset
    "   GP1:\r\n",
    "\tUF : 1, UT : 2,\t\tCONFIG : 'N U T, 0, 0, 0',\r\n",
    "\tX = 1 mm,\tY = 2 mm,\tZ = 3 mm,\tW = 0 deg,\tP = 0 deg,\tR = 0 deg\r\n",
    "};\r\n",
    "P[6]{\r\n",  # line 57: used with INC and plainly
    "   GP1:\r\n",
    "\tUF : 1, UT : 2,\r\n",
    "\tJ1 = 0 deg, J2 = 0 deg, J3 = 0 deg, J4 = 0 deg, J5 = 0 deg, J6 = 0 deg\r\n",
    "};\r\n",
    "P[7:\"spare\"]{\r\n",  # line 62: no move uses it
    "   GP1:\r\n",
    "\tUF : 1, UT : 2,\r\n",
    "\tJ1 = 1500.000 mm, J2 = 45.000 deg, J3 = 0.000 deg, J4 = 0.000 deg\r\n",
    "};\r\n",
    "P[8]{\r\n",  # line 67: only a positioner group, no move uses it
    "   GP2:\r\n",
    "\tUF : 1, UT : 2,\r\n",
    "\tJ1 = 10.000 deg\r\n",
    "};\r\n",
    "P[10]{\r\n",  # line 72
    "   GP1:\r\n",
    "\tUF : 1, UT : 2,\t\tCONFIG : 'N U T, 0, 0, 0',\r\n",
    "\tX = 0 mm,\tY = 0 mm,\tZ = 0 mm,\tW = 90 deg,\tP = 0 deg,\tR = 0 deg\r\n",
    "};\r\n",
    "P[12]{\r\n",  # line 77: not taught
    "   GP1:\r\n",
    "\tUF : *, UT : *,\t\tCONFIG : 'N U T, 0, 0, 0',\r\n",
    "\tX =  ********  mm,\tY =  ********  mm,\tZ =  ********  mm,\r\n",
    "\tW =  ******** deg,\tP =  ******** deg,\tR =  ******** deg\r\n",
    "};\r\n",
    "/END",
]
SYNTH = "".join(LINES)


def _parse(text=SYNTH):
    return DIALECT.parse("synth.ls", text)


def test_a_documented_program_is_read():
    prog = _parse()
    got = [(t.variable, t.line, t.move, t.kind, t.config, t.frames) for t in prog.targets]
    assert got == [("P[1]", 24, "J", "pose", ("N U T", 0, 0, 0), ("UT 2", "UF 1")),
                   ("P[2]", 30, "L", "pose", ("F D B", -1, 0, 1), ("UT 2", "UF 1")),
                   ("P[3]", 40, "C", "joints", (), ("UT 1", "UF 0")),
                   ("P[4]", 46, "C", "pose", ("N U T", 0, 0, 0), ("UT 2", "UF 1")),
                   ("P[6]", 57, "J", "joints", (), ("UT 2", "UF 1")),
                   ("P[7]", 62, "P[7]", "joints", (), ("UT 2", "UF 1")),
                   ("P[10]", 72, "A", "pose", ("N U T", 0, 0, 0), ("UT 2", "UF 1"))]
    t = {x.variable: x for x in prog.targets}
    assert SYNTH[t["P[1]"].at:t["P[1]"].at + 6] == "J P[1:" and SYNTH[t["P[4]"].at] == "C"
    assert SYNTH[t["P[6]"].at] == "j" and SYNTH[t["P[7]"].at:t["P[7]"].at + 5] == "P[7:\""
    assert np.allclose(t["P[1]"].values, [0.5, -0.000242, 0.15, 0.0, 0.0, np.pi / 2], atol=1e-15)
    assert np.allclose(t["P[2]"].values, [0.005, 0.0, -0.0105, np.pi, 0.0, 0.0], atol=1e-15)
    assert np.allclose(t["P[3]"].values, np.deg2rad([10, -20, 30, -0.5, 90, -180]), atol=1e-15)
    assert np.allclose(rotvec_matrix(t["P[4]"].values[3:]), rot_zyx(0.0, np.pi / 2, np.pi / 6), atol=1e-14)
    assert np.allclose(t["P[7]"].values, [1.5, np.pi / 4, 0.0, 0.0], atol=1e-15)
    assert np.allclose(t["P[10]"].values, [0, 0, 0, np.pi / 2, 0, 0], atol=1e-15)
    assert [SYNTH[a:b] for a, b in t["P[2]"].fields] == ["+5.", "0", "-10.5", "180.000", "0.000", "0.000"]
    assert [SYNTH[a:b] for a, b in t["P[1]"].fields][:3] == ["500.000", "-.242", "1.5e2"]
    assert SYNTH[t["P[1]"].start:t["P[1]"].end].startswith("{\r\n   GP1:") and SYNTH[t["P[1]"].end:][:2] == ";\r"


def test_the_moves_that_are_listed_say_why():
    listed = _parse().not_literal
    assert [(n, what) for n, what, _ in listed] == [(16, "L P[5]"), (17, "L P[6]"), (20, "J P[R[4]]"), (21, "J P[11]"),
                                                    (22, "J P[12]"), (67, "P[8]")]
    why = [w for _, _, w in listed]
    assert "tool_offset,PR[2:shift]" in why[0] and "tool frame" in why[0]
    assert "INC" in why[1] and "P[6] itself is compensated for its plain moves" in why[1]
    assert "register at run time" in why[2]
    assert "P[11] has no entry in /POS" in why[3] and "OFFSET CONDITION" in why[3]
    assert "not taught" in why[4] and "no GP1" in why[5]


def test_identity_is_byte_for_byte_and_a_change_touches_only_the_fields():
    prog = _parse()
    assert prog.with_values({k: t.values for k, t in enumerate(prog.targets)}) == SYNTH
    delta = np.array([1e-3, -2e-3, 0.5e-3, 0.01, -0.02, 0.015])
    new = {}
    for k, t in enumerate(prog.targets):
        if t.kind == "pose":
            rot = rotvec_matrix(t.values[3:]) @ rotvec_matrix(delta[3:])
            new[k] = np.concatenate([t.values[:3] + delta[:3], _rotvec(rot)])
        else:
            new[k] = t.values + 0.01 * np.arange(1, t.values.size + 1)
    text = prog.with_values(new)
    again = _parse(text)
    assert [t.variable for t in again.targets] == [t.variable for t in prog.targets]
    for k, t in enumerate(again.targets):  # to the controller's step: 0.001 mm and 0.001 deg, half of it at most
        if t.kind == "pose":
            assert np.allclose(t.values[:3], new[k][:3], rtol=0, atol=0.5e-6 + 1e-12)
            turn = _rotvec(rotvec_matrix(t.values[3:]) @ rotvec_matrix(new[k][3:]).T)
            assert np.linalg.norm(turn) <= 3 * np.radians(0.5e-3)
        else:
            mm = np.array([text[b:b + 4].strip().startswith("mm") for _, b in t.fields])  # an axis in mm
            assert np.all(np.abs(t.values - new[k]) <= np.where(mm, 0.5e-6, np.radians(0.5e-3)) + 1e-12)
    fields = [text[a:b] for t in again.targets for a, b in t.fields]
    assert max(len(f.split(".")[1]) for f in fields if "." in f and "e" not in f.lower()) == 3  # the controller's
    assert skeleton(SYNTH, prog.targets) == skeleton(text, again.targets)
    assert text != SYNTH and len(text) > len(SYNTH)


def _rotvec(R):
    from kincal.models.transforms import rotation_log
    return rotation_log(R[None])[0]


def test_the_orientation_written_is_the_triple_nearest_the_old_one():
    prog = _parse()
    t = {x.variable: x for x in prog.targets}
    k4 = prog.targets.index(t["P[4]"])  # P = 90: only R - W counts; W is kept
    turned = np.concatenate([t["P[4]"].values[:3], _rotvec(rot_zyx(np.deg2rad(-10.0), np.pi / 2, np.pi / 6))])
    text = prog.with_values({k4: turned})
    assert "\tW =    30.000 deg,\tP =    90.000 deg,\tR =     -10.000 deg\r\n" in text
    k2 = prog.targets.index(t["P[2]"])  # W = 180 stays 180 (not -180) after a small turn about z
    small = np.concatenate([t["P[2]"].values[:3], _rotvec(rot_zyx(np.deg2rad(1.0), 0.0, np.pi))])
    assert "\tW =   180.000 deg,\tP =     0.000 deg,\tR =     1.000 deg,\n" in prog.with_values({k2: small})
    flipped = np.concatenate([t["P[2]"].values[:3], _rotvec(rot_zyx(np.pi, np.deg2rad(179.0), 0.0))])
    assert "\tW =   180.000 deg,\tP =     1.000 deg,\tR =     0.000 deg,\n" in prog.with_values({k2: flipped})


def _broken(lines_changed: dict[int, str]) -> str:
    lines = list(LINES)
    for n, new in lines_changed.items():
        lines[n - 1] = new
    return "".join(lines)


@pytest.mark.parametrize("change, line, column, what", [
    ({26: "\tUF : 1, UT : 2,\r\n"}, 27, 8, "a Cartesian position without its CONFIG"),
    ({29: "\r\n"}, 24, 17, "P[1] has no closing '};'"),
    ({39: "}\n"}, 39, 1, "P[2]: '}' without its ';'"),
    ({27: "\tX =   500.000  mm,\tY =  -.2.42  mm,\tZ =   1.5e2  mm,\r\n"}, 27, 26, "Y = '-.2.42' is not a number"),
    ({43: "\tJ1 =    ten deg,\tJ2 =   -20.000 deg,\tJ3 =    30.000 deg,\r\n"}, 43, 10, "J1 = 'ten' is not a number"),
    ({28: "\tW =     0.000 deg,\tP =     0.000 deg\r\n"}, 27, 8, "needs X, Y, Z, W, P, R in this order"),
    ({32: "\tUF : 1, UT : 2,\t\tCONFIG : 'F D B, x, 0, 1',\n"}, 32, 28, "is not 'flip up top"),
    ({46: "P[3]{\r\n"}, 46, 1, "P[3] is in /POS twice"),
    ({47: "   GPX:\r\n"}, 47, 4, "expected a group GP1"),
    ({67: "Q[8]{\r\n"}, 67, 1, "expected a position P[n]"),
    ({33: "\tX =  +5.  deg,\tY = 0 mm,\tZ = -10.5 mm,\n"}, 33, 7, "X in deg; FANUC writes it in mm"),
    ({13: "    :  200mm/sec FINE    ;\r\n"}, 12, 6, "a circular move (C) without its end position"),
    ({44: "\tJ4 =   -.500 deg,\tJ5 =    90.000 deg,\tJ6 =  -180.000 deg,\tE1 = 12.000 mm ?\r\n"}, 44, 75,
     "expected 'name = number unit'"),
])
def test_a_broken_program_names_the_file_line_and_column(change, line, column, what):
    with pytest.raises(MeasurementError) as err:
        _parse(_broken(change))
    message = str(err.value)
    assert message.startswith(f"synth.ls: line {line}, column {column}: ") and what in message
    assert "\n" not in message


def test_a_file_read_from_disk_keeps_its_bom_and_line_endings(tmp_path):
    path = tmp_path / "SYNTH.LS"
    path.write_bytes(SYNTH.encode("utf-8"))
    prog = read_program(str(path), "fanuc")
    assert prog.dialect == "fanuc" and prog.comment == "" and len(prog.targets) == 7
    assert prog.with_values({k: t.values for k, t in enumerate(prog.targets)}).encode(prog.encoding) == path.read_bytes()
