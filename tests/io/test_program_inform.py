"""Yaskawa INFORM (.JBI) jobs: every real job of the shared data read and written back byte for byte, what
is listed in them checked against the raw text, and jobs written from the format's documentation (DX100 /
NX100 "Job Data Format": //POS with ///NPOS, ///TOOL, ///USER, ///POSTYPE, ///PULSE, ///RECTAN, ///RCONF,
Cnnnnn=X,Y,Z,Rx,Ry,Rz[,Re] with R = Rz·Ry·Rx) with every kind of position, rewritten with new values."""
import dataclasses
import math
import re

import numpy as np
import pytest
from conftest import shared_dataset, skeleton
from scipy.spatial.transform import Rotation

from kincal.errors import MeasurementError
from kincal.io import read_program
from kincal.io.programs import dialects

DATA = shared_dataset("robot_programs") / "inform"
FILES = sorted(p for p in DATA.rglob("*") if p.suffix.lower() == ".jbi")


def _read(tmp_path, text: str, name: str = "TEST.JBI"):
    path = tmp_path / name
    path.write_bytes(text.encode("utf-8"))
    return read_program(str(path), "inform")


def _poses(prog):
    """The job's Cartesian targets only (its PULSE targets left out)."""
    return dataclasses.replace(prog, targets=tuple(t for t in prog.targets if t.kind == "pose"))


def _identity(prog) -> bytes:
    return prog.with_values({k: t.values for k, t in enumerate(prog.targets)}).encode(prog.encoding)


def test_the_data_folder_holds_the_inform_jobs():
    assert len(FILES) == 42
    assert dialects()["inform"].suffixes == (".jbi",) and dialects()["inform"].comment == ""  # none after a position line: refusals reported, not marked


@pytest.mark.parametrize("path", FILES, ids=[str(p.relative_to(DATA)) for p in FILES])
def test_every_real_job_reads_and_writes_back_byte_for_byte(path):
    prog = read_program(str(path), "inform")
    assert _identity(prog) == path.read_bytes()
    raw = path.read_text("latin-1")
    # independently: the C lines after ///RECTAN are the literal candidates; in this data every C is PULSE
    blocks = re.split(r"^///(RECTAN|PULSE)\s*$", raw.split("//INST")[0], flags=re.M)
    rectan_c = sum(len(re.findall(r"^C\d+=", body, re.M)) for kind, body in zip(blocks[1::2], blocks[2::2])
                   if kind == "RECTAN")
    inst = raw.split("//INST")[1]
    moves_to_c = re.findall(r"^\s*MOV[JLCS] C(\d+)", inst, re.M)
    p_uses = re.findall(r"^\s*(\w+) (P\d+)\b", inst, re.M)
    # every C a move goes to is a PULSE target (once), its counts those of its line
    assert rectan_c == 0 and all(t.kind == "pulses" for t in prog.targets)
    assert sorted(int(t.variable[1:]) for t in prog.targets) == sorted({int(c) for c in moves_to_c})
    for t in prog.targets:
        line = re.search(rf"^{t.variable}=([^\r\n]*)", raw, re.M).group(1)
        assert t.values.tolist() == [float(v) for v in line.split(",")] and len(t.fields) == len(t.values)
    assert [w for _, w, y in prog.not_literal if "global position variable" in y] == [f"{a} {b}" for a, b in p_uses]
    assert len(prog.not_literal) == len(p_uses)


def test_what_is_listed_in_real_jobs_with_the_lines_read_by_eye():
    prog = read_program(str(DATA / "AGSweeney__Motoman_EnIP_ToolChanger/MH180_Progs/FORMCUT.JBI"), "inform")
    assert [(line, what) for line, what, _ in prog.not_literal] == [(23, "FORMAPR P018"), (25, "MOVL P018")]
    assert [(t.move, t.variable, t.line) for t in prog.targets] == [("MOVJ", "C00000", 8), ("MOVJ", "C00001", 9)]
    assert "global position variable" in prog.not_literal[1][2]
    prog = read_program(str(DATA / "AGSweeney__Motoman_EnIP_ToolChanger/MH180_Progs/TC_HARDENED/TC_FULL_CHANGE.JBI"),
                        "inform")
    assert [(line, what) for line, what, _ in prog.not_literal] == [
        (65, "MOVJ P025"), (69, "MOVL P026"), (77, "MOVL P024"), (80, "MOVL P027"),
        (85, "MOVL P026"), (90, "MOVL P026"), (98, "MOVL P025"), (99, "MOVL P024")]
    assert [(t.move, t.variable) for t in prog.targets] == [("MOVJ", "C00000"), ("MOVJ", "C00001")]
    prog = read_program(str(DATA / "Yaskawa-Global__motoros2/robot_jobs/single_arm/INIT_ROS.JBI"), "inform")
    assert prog.targets == () and prog.not_literal == ()


# Real header and real numbers (SAMPLE_TC.JBI lines 5, 10-13: there a P variable) made a C position of a move
REAL_AS_C = ("/JOB\n//NAME SAMPLE_C\n//POS\n///NPOS 1,0,0,0,0,0\n///TOOL 1\n///POSTYPE BASE\n///RECTAN\n"
             "///RCONF 0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0\n"
             "C00000=755.000,1321.000,-446.500,-179.9988,-0.0019,-0.0019\n"
             "//INST\n///DATE 2026/05/06 11:28\n///ATTR SC,RW\n///GROUP1 RB1\nNOP\nMOVJ C00000 VJ=25.00 PL=0\nEND\n")


def test_a_real_cartesian_position_read_against_an_independent_conversion(tmp_path):
    prog = _read(tmp_path, REAL_AS_C)
    (t,) = prog.targets
    # ///POSTYPE BASE in a job with no base axis (///GROUP1 RB1): the robot frame; of RCONF's 24 digits the six
    # a six-axis arm's branch has (the others stay as written)
    assert (t.move, t.variable, t.kind, t.line, t.frames) == ("MOVJ", "C00000", "pose", 9, ("TOOL 1", "ROBOT"))
    assert t.config == (0,) * 6 and t.at == REAL_AS_C.index("MOVJ C00000")
    assert REAL_AS_C[t.start:t.end] == "755.000,1321.000,-446.500,-179.9988,-0.0019,-0.0019"
    assert [REAL_AS_C[a:b] for a, b in t.fields] == ["755.000", "1321.000", "-446.500", "-179.9988", "-0.0019",
                                                     "-0.0019"]
    np.testing.assert_allclose(t.values[:3], [0.755, 1.321, -0.4465], atol=1e-15)
    R = Rotation.from_euler("xyz", [-179.9988, -0.0019, -0.0019], degrees=True).as_matrix()  # fixed x, y, z
    np.testing.assert_allclose(Rotation.from_rotvec(t.values[3:]).as_matrix(), R, atol=1e-13)
    assert _identity(prog) == REAL_AS_C.encode()


LINES = [
    "\ufeff/JOB\r\n", "//NAME KINCAL_T\r\n", "//POS\n", "///NPOS 10,1,1,3,0,0\n", "///TOOL 1\n",
    "///POSTYPE PULSE\n", "///PULSE\n", "C00000=0,-1000,2000,0,0,0\n", "BC00000=1500\n", "EC00000=-2500,300\n",
    "///POSTYPE BASE\n", "///RECTAN\n",
    "C00001=500.000,0.000,300.000,0.0000,0.0000,90.0000\r\n",  # 13: no RCONF yet
    "///RCONF 1,0,0,0,0,0,0,0\n",
    "C00002=-.242,1.5E+02,+5.0,180.0000,0.0000,0.0000\n",  # 15
    "///USER 2\n", "///TOOL 3\n", "///POSTYPE USER\n", "///RCONF 0,1,1,0,0,1\n",
    "C00003=\t100.5,\t-20.25,\t30.125,\t0.0000,\t-90.0000,\t0.0000\t\n",  # 20: tabs, Ry = -90
    "C00004=10,20,30,10.5,-20.25,30.75,45.0000\n",  # 21: a 7-axis arm's Re
    "///POSTYPE ROBOT\n",
    "C00005=1e2,2.5e-1,-3E1,-179.9988,-0.0019,190.0000\n",  # 23
    "///POSTYPE TOOL\n", "C00006=0,0,10,0,0,0\n",  # 25
    "///postype base\n",
    "C00007=400,0,400,12.5,90.0000,-7.5\n",  # 27: Ry = 90 (only Rz - Rx is defined)
    "C00008=1,2,3,4,5,6\n", "C00009=1,2,3,4,5,6\n",  # 28, 29
    "P00010=1,2,3,0,0,0\n", "P00011=4,5,6,0,0,0\n", "P00012=7,8,9,0,0,0\n",
    "//INST\r\n", "///DATE 2024/01/01 00:00\n", "///ATTR SC,RW\n", "///GROUP1 RB1,BS1\n", "NOP\n",  # 37
    "'MOVL C00008 V=100.0: only a comment\n",
    "MOVJ C0000 BC00000 VJ=50.00\n",  # 39: another width, PULSE
    "MOVL C00001 V=100.0 PL=0\r\n", "movl c0002 v=100.0\n", "\tMOVC C00003 V=50.0\n", " MOVC C00004 V=50.0\n",
    "MOVS C00005 V=50.0 PL=3\n", "MOVL C00006 V=10.0\n", 'MSG "MOVL C00008"\n',  # 40-46
    "SMOVL C00009 V=10.0 +MOVJ C00007 VJ=10.00\n",  # 47
    "SETE P010 (1) D000\n", "MFRAME UF#(1) P010 P011\n", "SFTON P010 BF\n", "IMOV P010 V=10.0\n",  # 48-51
    "MOVL P010 V=100.0\n", "SFTOF\n", "MOVJ LP000 VJ=10.00\n", "CALL JOB:P001\n", "*P12\n", "JUMP *P12\n",  # 52-57
    "MOVL P[I000] V=10.0\n", "END",  # 58, 59: no final newline
]
TEXT = "".join(LINES)
PULSES_8 = "0,-1000,2000,0,0,0"  # C00000, line 8


def test_a_documented_job_every_position_kind(tmp_path):
    prog = _read(tmp_path, TEXT)
    pulse = [t for t in prog.targets if t.kind == "pulses"]  # MOVJ C0000 (line 39) goes to a PULSE position
    assert [(t.line, t.move, t.variable, TEXT[t.start:t.end]) for t in pulse] == [(8, "MOVJ", "C00000", PULSES_8)]
    prog = dataclasses.replace(prog, targets=tuple(t for t in prog.targets if t.kind != "pulses"))
    assert [(t.line, t.move, t.variable, t.frames, t.config) for t in prog.targets] == [
        (13, "MOVL", "C00001", ("TOOL 1", "BASE"), ()),
        (15, "MOVL", "C00002", ("TOOL 1", "BASE"), (1, 0, 0, 0, 0, 0)),  # BASE: the job has a base axis (BS1)
        (20, "MOVC", "C00003", ("TOOL 3", "USER 2"), (0, 1, 1, 0, 0, 1)),
        (21, "MOVC", "C00004", ("TOOL 3", "USER 2"), (0, 1, 1, 0, 0, 1)),
        (23, "MOVS", "C00005", ("TOOL 3", "ROBOT"), (0, 1, 1, 0, 0, 1)),
        (27, "MOVJ", "C00007", ("TOOL 3", "BASE"), (0, 1, 1, 0, 0, 1))]
    assert all(t.kind == "pose" and len(t.fields) == 6 for t in prog.targets)
    assert prog.targets[0].at == TEXT.index("MOVL C00001") and prog.targets[5].at == TEXT.index("MOVJ C00007")
    assert TEXT[prog.targets[3].start:prog.targets[3].end] == "10,20,30,10.5,-20.25,30.75,45.0000"  # Re in the span
    assert TEXT[slice(*prog.targets[3].fields[-1])] == "30.75"  # ... not a field
    assert [(line, what) for line, what, _ in prog.not_literal] == [
        (28, "C00008"), (32, "P00012"), (45, "MOVL C00006"), (47, "SMOVL C00009"),
        (48, "SETE P010"), (49, "MFRAME P010"), (49, "MFRAME P011"), (50, "SFTON P010"), (51, "IMOV P010"),
        (52, "MOVL P010"), (54, "MOVJ LP000"), (58, "MOVL P[I000]")]
    why = dict(((line, what), y) for line, what, y in prog.not_literal)
    assert "TOOL coordinates" in why[(45, "MOVL C00006")]
    assert "assigned at run time by SETE" in why[(48, "SETE P010")] and "user frame" in why[(49, "MFRAME P011")]
    assert "no instruction" in why[(28, "C00008")] and "does not use" in why[(32, "P00012")]
    assert "local" in why[(54, "MOVJ LP000")] and "indirect" in why[(58, "MOVL P[I000]")]


def _matrix(rx, ry, rz):
    return Rotation.from_euler("xyz", [rx, ry, rz], degrees=True).as_matrix()


def test_values_against_closed_forms(tmp_path):
    t = _poses(_read(tmp_path, TEXT)).targets
    np.testing.assert_allclose(t[0].values, [0.5, 0.0, 0.3, 0.0, 0.0, math.pi / 2], atol=1e-15)  # Rz = 90°
    np.testing.assert_allclose(t[1].values[:3], [-0.000242, 0.15, 0.005], atol=1e-15)  # -.242, 1.5E+02, +5.0 mm
    np.testing.assert_allclose(np.abs(t[1].values[3:]), [math.pi, 0.0, 0.0], atol=1e-12)  # Rx = 180°
    np.testing.assert_allclose(t[2].values, [0.1005, -0.02025, 0.030125, 0.0, -math.pi / 2, 0.0], atol=1e-15)
    np.testing.assert_allclose(t[3].values[:3], [0.01, 0.02, 0.03], atol=1e-15)
    np.testing.assert_allclose(t[4].values[:3], [0.1, 0.00025, -0.03], atol=1e-15)  # 1e2, 2.5e-1, -3E1
    for k, angles in ((3, (10.5, -20.25, 30.75)), (4, (-179.9988, -0.0019, 190.0)), (5, (12.5, 90.0, -7.5))):
        np.testing.assert_allclose(Rotation.from_rotvec(t[k].values[3:]).as_matrix(), _matrix(*angles), atol=1e-13)


def test_identity_is_byte_for_byte_with_bom_mixed_endings_and_no_final_newline(tmp_path):
    prog = _read(tmp_path, TEXT)
    assert prog.encoding == "utf-8" and _identity(prog) == TEXT.encode()
    prog = _read(tmp_path, TEXT.replace("\n", "\r\n").replace("\r\r", "\r"))
    assert len(prog.targets) == 7 and _identity(prog) == TEXT.replace("\n", "\r\n").replace("\r\r", "\r").encode()


def test_a_rewrite_with_new_values_reads_back_and_keeps_every_other_byte(tmp_path):
    prog = _poses(_read(tmp_path, TEXT))
    rng = np.random.default_rng(3)
    new = {}
    for k, t in enumerate(prog.targets):
        R = Rotation.from_rotvec(t.values[3:]) * Rotation.from_rotvec(rng.normal(0, 1e-3, 3))
        new[k] = np.concatenate([t.values[:3] + rng.normal(0, 1e-3, 3), R.as_rotvec()])
    written = prog.with_values(new)
    again = _poses(_read(tmp_path, written, "NEW.JBI"))
    assert skeleton(written, again.targets) == skeleton(TEXT, prog.targets)
    assert [(t.variable, t.frames, t.config) for t in again.targets] == [
        (t.variable, t.frames, t.config) for t in prog.targets]
    for k, t in enumerate(again.targets):  # to the controller's step, 0.001 mm and 0.0001 deg (1e2 style: to it)
        assert np.abs(t.values[:3] - new[k][:3]).max() <= 1e-6 + 1e-12
        turn = Rotation.from_rotvec(t.values[3:]).inv() * Rotation.from_rotvec(new[k][3:])
        assert turn.magnitude() <= 3 * np.radians(1e-4)
        fields = [written[a:b] for a, b in t.fields]
        decimals = [len(f.split(".")[1]) if "." in f and "e" not in f.lower() else 0 for f in fields]
        assert max(decimals[:3]) <= 3 and max(decimals[3:]) <= 4  # as the controller writes its own files
    assert written.startswith("\ufeff/JOB\r\n") and written.endswith("\nEND")


def test_the_angle_triple_nearest_the_old_one_is_written(tmp_path):
    prog = _poses(_read(tmp_path, TEXT))
    t = prog.targets[4]  # Rx -179.9988 (not 180.0012) is kept; Rz 190, outside INFORM's [-180, 180], becomes -170
    R = Rotation.from_rotvec(t.values[3:]) * Rotation.from_euler("z", 1e-4, degrees=True)
    text = prog.with_values({4: np.concatenate([t.values[:3], R.as_rotvec()])})
    fields = text.split("\n")[22].split("=")[1].split(",")
    assert fields[:3] == ["1e2", "2.5e-1", "-3E1"]
    np.testing.assert_allclose([float(f) for f in fields[3:]], [-179.9988, -0.0019, -170.0], atol=1e-3)
    t = prog.targets[5]  # Ry = 90°: only Rz - Rx is defined; a turn about the base z keeps Rx and Ry as written
    R = Rotation.from_euler("z", 0.5, degrees=True) * Rotation.from_rotvec(t.values[3:])
    text = prog.with_values({5: np.concatenate([t.values[:3], R.as_rotvec()])})
    assert text.split("\n")[26] == "C00007=400,0,400,12.5,90.0000,-7.0"


HEAD = "/JOB\n//NAME BAD\n//POS\n///NPOS 1,0,0,0,0,0\n///TOOL 0\n///POSTYPE BASE\n///RECTAN\n"
TAIL = "//INST\n///ATTR SC,RW\nNOP\nMOVL C00000 V=10.0\nEND\n"
GOOD_C = "C00000=1,2,3,4,5,6\n"


@pytest.mark.parametrize("text, line, column, what", [
    (HEAD + "C00000=1,abc,3,4,5,6\n" + TAIL, 8, 10, "'abc' is not a number"),
    (HEAD + "C00000=1,2,,4,5,6\n" + TAIL, 8, 12, "a number is missing"),
    (HEAD + "C00000=1,2,3,4,5\n" + TAIL, 8, 17, "X,Y,Z,Rx,Ry,Rz[,Re]: 5 numbers"),
    (HEAD + GOOD_C + "C00001=1,2,3,4,5,6\n" + TAIL, 4, 4, "///NPOS declares 1 C positions, the //POS section has 2"),
    (HEAD.replace("1,0,0,0,0,0", "1,0,0,0,0") + GOOD_C + TAIL, 4, 9, "///NPOS needs 6 counts"),
    (HEAD + GOOD_C + TAIL.replace("C00000", "C00003"), 12, 6, "C00003: the job's //POS section holds no such C"),
    (HEAD.replace("BASE", "USER") + GOOD_C + TAIL, 8, 1, "a user frame with no ///USER"),
    (HEAD.replace("BASE", "WORLD") + GOOD_C + TAIL, 6, 12, "///POSTYPE 'WORLD' is not one of"),
    (HEAD + "///RCONF 0,1.5,0\n" + GOOD_C + TAIL, 8, 12, "///RCONF takes whole numbers, not '1.5'"),
    (HEAD.replace("1,0,0,0,0,0", "2,0,0,0,0,0") + GOOD_C + GOOD_C + TAIL, 9, 1, "C00000 is defined twice"),
    (HEAD + GOOD_C + TAIL.replace("NOP", 'MSG "OPEN'), 11, 5, "a string without its closing"),
    (HEAD + "C00000 1,2,3,4,5,6\n" + TAIL, 8, 1, "not a position line"),
    (HEAD.replace("BASE\n///RECTAN", "PULSE\n///RECTAN") + GOOD_C + TAIL, 8, 1, "no Cartesian ///POSTYPE"),
    (HEAD.replace("///POSTYPE BASE\n///RECTAN\n", "") + GOOD_C + TAIL, 6, 1, "a position before any ///POSTYPE"),
])
def test_broken_jobs_name_the_file_line_and_column(tmp_path, text, line, column, what):
    path = tmp_path / "BAD.JBI"
    path.write_text(text)
    with pytest.raises(MeasurementError) as err:
        read_program(str(path), "inform")
    message = str(err.value)
    assert message.startswith(f"{path}: line {line}, column {column}: ") and what in message
    assert "\n" not in message


@pytest.mark.parametrize("angles", ["-100.25,-89.99999,170.125", "10,89.9999999,20", "359.9,10,-359.9", "45,135,45",
                                    "-0.0000,-0.0000,-0.0000", "180.0000,0.0000,-180.0000", "1e-3,-9E1,2"])
def test_awkward_angle_triples_are_written_back_as_they_were(tmp_path, angles):
    """Near Ry = ±90° a triple is ill-conditioned, out-of-range and negative-zero ones are not what a matrix gives
    back: an unchanged rotation keeps its numbers."""
    text = HEAD + f"C00000=1.000,2.000,3.000,{angles}\n" + TAIL
    prog = _read(tmp_path, text)
    assert _identity(prog) == text.encode()
    rx, ry, rz = (float(a) for a in angles.split(","))
    np.testing.assert_allclose(Rotation.from_rotvec(prog.targets[0].values[3:]).as_matrix(), _matrix(rx, ry, rz),
                               atol=1e-13)
