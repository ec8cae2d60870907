"""The KUKA KRL reader/rewriter: every real file of the shared data read and written back byte for byte,
targets counted against an independent reading of the raw text, a synthetic program with every kind of
target and the awkward text features, and broken programs."""
import dataclasses
import math
import re

import numpy as np
import pytest
from conftest import shared_dataset, skeleton

from kincal.errors import MeasurementError
from kincal.io import programs
from kincal.io.programs import read_program
from kincal.models.transforms import rot_zyx, rotvec_matrix

KRL = shared_dataset("robot_programs") / "krl"
FILES = sorted(p for p in KRL.rglob("*") if p.suffix.lower() in (".src", ".dat", ".sub"))


def _parse(text: str, source: str = "demo.src"):
    """The program as read_program gives it (its dialect named, so with_values writes KRL)."""
    return dataclasses.replace(programs.dialects()["krl"].parse(source, text), dialect="krl", comment=";")


def test_the_data_folder_has_every_krl_file():
    assert len(FILES) == 82


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(KRL)))
def test_every_real_file_is_read_and_written_back_byte_for_byte(path):
    prog = read_program(str(path), "krl")
    same = prog.with_values({k: t.values for k, t in enumerate(prog.targets)})
    assert same.encode(prog.encoding) == path.read_bytes()


# independent counts from the raw text: uncommented inline move literals, declarations of points with a
# literal (less, in a .dat, those its module's .src assigns at run time), typed point aggregates assigned in a .src
INLINE = re.compile(r"^[ \t]*(?:PTP|LIN|SPTP|SLIN|SPL)[ \t]*\{", re.M | re.I)
DECLARED = re.compile(r"^[ \t]*(?:(?:GLOBAL|DECL)[ \t]+)*(?:E6POS|POS|E6AXIS|AXIS)[ \t]+(\w+)[ \t]*=[ \t]*\{", re.M | re.I)
TYPED = re.compile(r"^[ \t]*\w+[ \t]*=[ \t]*\{[ \t]*(?:E6POS|POS|E6AXIS|AXIS)[ \t]*:", re.M | re.I)


@pytest.mark.parametrize("path", FILES, ids=lambda p: str(p.relative_to(KRL)))
def test_target_counts_match_an_independent_reading(path):
    raw = path.read_bytes().decode("latin-1")
    prog = read_program(str(path), "krl")
    src = path.with_suffix(".src")
    module = src.read_bytes().decode("latin-1") if path.suffix.lower() == ".dat" and src.exists() else None
    filled = [n for n in DECLARED.findall(raw)
              if re.search(rf"^[ \t]*{n}[ \t]*(\.[ \t]*\w+[ \t]*)?=(?!=)", module or "", re.M | re.I)]
    moves = "\n".join(re.findall(r"^[ \t]*(?:PTP|LIN|CIRC|SPTP|SLIN|SCIRC|SPL)\b[^\n;]*", module or "", re.M | re.I))
    local = [n for n in DECLARED.findall(raw) if n not in filled and module is not None
             and not re.search(rf"\b{n}\b", moves, re.I)
             and not re.search(rf"^[ \t]*(?:DECL[ \t]+)?GLOBAL\b[^\n]*\b{n}\b", raw, re.M | re.I)]
    found = sum(len(r.findall(raw)) for r in (INLINE, DECLARED, TYPED))
    assert len(prog.targets) == found - len(filled) - len(local)
    assert sum("at run time by its module" in why for _, _, why in prog.not_literal) == len(filled)
    assert sum("no move of its module" in why for _, _, why in prog.not_literal) == len(local)
    # every logged position inside other data is listed, not a target
    nested = len(re.findall(r"cmdPos \{", raw))
    assert sum("inside other data" in why for _, _, why in prog.not_literal) == nested


def test_the_data_folder_totals():
    progs = [read_program(str(p), "krl") for p in FILES]
    kinds = [t.kind for p in progs for t in p.targets]
    assert (kinds.count("pose"), kinds.count("joints")) == (0, 11)  # 8 .dat points their modules fill at run time,
    # 3 inline forms' points no move of their modules names any more: listed
    whys = [why for p in progs for _, _, why in p.not_literal]
    assert sum(w.startswith("a relative move") for w in whys) == 6
    assert sum("read at run time" in w and w.startswith("$") for w in whys) == 24


def test_friccontrol_dat_points_with_their_fdat(tmp_path):
    real = KRL / "CentroEPiaggio__kuka-lwr/FRILibrary/KRL/FRIControl.dat"
    here = read_program(str(real), "krl")  # its module's .src moves to neither (the inline forms were deleted)
    assert here.targets == () and [(line, what) for line, what, why in here.not_literal
                                   if "no move of its module (FRIControl.src)" in why] == [(43, "XP1"), (46, "XP2")]
    (tmp_path / "FRIControl.dat").write_bytes(real.read_bytes())  # read alone, each point is a target
    prog = read_program(str(tmp_path / "FRIControl.dat"), "krl")
    xp1, xp2 = prog.targets
    # line 43: DECL E6POS XP1={X -525.592529,Y -0.0128466198,Z 659.265625,A 0.00409000413,B -45.2178993,
    #          C -0.00150612905,S 5,T 28,E1 -0.00314998603,...}; line 44: DECL FDAT FP1={TOOL_NO 1,BASE_NO 0,...}
    assert (xp1.line, xp1.variable, xp1.move, xp1.kind, xp1.config) == (43, "XP1", "E6POS", "pose", (5, 28))
    assert xp1.frames == ("TOOL_NO 1", "BASE_NO 0")
    np.testing.assert_allclose(xp1.values[:3], [-0.525592529, -0.0000128466198, 0.659265625], atol=1e-12)
    R = rot_zyx(*np.radians([0.00409000413, -45.2178993, -0.00150612905]))
    np.testing.assert_allclose(rotvec_matrix(xp1.values[3:]), R, atol=1e-12)
    assert xp2.line == 46 and xp2.values[1] == pytest.approx(-3.44777509e-08)  # -3.44777509E-05 mm


def test_kuka_ros_driver_dat(tmp_path):
    real = KRL / "ros-industrial__kuka_experimental/kuka_kss_hw_interface/krl/KSS_85/Program/ROS/kuka_ros_driver.dat"
    prog = read_program(str(real), "krl")
    names = [t.variable for t in prog.targets]
    assert names == ["g_joint_pos_empty"]  # GLOBAL: another module may move there. The measured position, velocity,
    # torque and the target the module's .src fills at run time (ROS_Meas_Vel = ROS_getVel(), line 149) are listed,
    # and so is Xdrop4, an inline form's point no move of the .src names any more
    filled = {(line, what): why for line, what, why in prog.not_literal if "by its module" in why}
    assert list(filled) == [(13, "ROS_Meas_Pos"), (14, "ROS_Meas_Vel"), (15, "ROS_Meas_Torque"),
                            (231, "ROS_joint_pos_tgt")]
    assert "kuka_ros_driver.src line 149" in filled[(14, "ROS_Meas_Vel")]
    assert any(line == 555 and "no move of its module" in why for line, _, why in prog.not_literal)
    empty = prog.targets[0]  # line 230: GLOBAL E6AXIS g_joint_pos_empty={A1 0.0, ...}: no assignment in the module
    assert empty.line == 230 and empty.config == () and empty.frames == ("", "")
    np.testing.assert_allclose(empty.values, 0.0)
    (tmp_path / "kuka_ros_driver.dat").write_bytes(real.read_bytes())  # read alone: every point a target
    prog = read_program(str(tmp_path / "kuka_ros_driver.dat"), "krl")
    drop = prog.targets[-1]  # line 555, its FDAT Fdrop4 on line 554 has TOOL_NO 10, BASE_NO 0
    assert (drop.line, drop.config, drop.frames) == (555, (0, 0), ("TOOL_NO 10", "BASE_NO 0"))
    assert drop.values[0] == pytest.approx(666.666688)


def test_real_src_moves():
    home = read_program(str(KRL / "ros-industrial__kuka_experimental/kuka_rsi_hw_interface/krl/KR_C2/ros_rsi.src"),
                        "krl")
    (t,) = home.targets  # line 68: HOME = {AXIS: A1 0, A2 -90, A3 90, A4 0, A5 90, A6 0}, line 71 PTP HOME
    assert (t.line, t.move, t.variable, t.kind) == (68, "PTP", "HOME", "joints")
    np.testing.assert_allclose(t.values, np.radians([0, -90, 90, 0, 90, 0]))
    assert any(line == 105 and "$AXIS_ACT" in what for line, what, _ in home.not_literal)
    eki = read_program(str(KRL / "tingelst__kuka_eki/kuka_eki/krl/ros_eki.src"), "krl")
    assert eki.targets == ()
    rel = [(line, what) for line, what, why in eki.not_literal if why.startswith("a relative move")]
    assert rel == [(90, "PTP_REL joint_pos_tgt"), (92, "LIN_REL cart_pos_tgt")]
    fri = read_program(str(KRL / "CentroEPiaggio__kuka-lwr/FRILibrary/KRL/FRIControl.src"), "krl")
    assert fri.targets == () and (76, "PTP $AXIS_ACT_MES") in [(ln, w) for ln, w, _ in fri.not_literal]
    raw = (KRL / "CentroEPiaggio__kuka-lwr/FRILibrary/KRL/FRIControl.src").read_text()
    settings = len(re.findall(r"^[ \t]*\$stiffness\.\w+[ \t]*=[ \t]*\{", raw, re.M))
    assert settings == 9 and sum("$stiffness" in w for _, w, _ in fri.not_literal) == settings  # listed, no target


SRC = ("\ufeffDEF demo( )\r\n"
       "DECL AXIS HOME\r\n"
       "decl e6pos P7\n"
       "DECL FRAME F1\n"
       "HOME = {AXIS: A1 0, A2 -90, A3 90, A4 0, A5 90, A6 0} ; home\r\n"
       "$TOOL = TOOL_DATA[2]\n"
       "$BASE = BASE_DATA[1]\n"
       "ptp HOME\n"
       "PTP {A1 10, A2 -.242, A3 1.5E1, A4 0, A5 30, A6 -45}\r\n"
       "LIN {X 100, Y -200.5, Z 3e2, A 90, B 0, C 0} C_DIS\n"
       "lin {x 1000.0,\ty 0,\tz 500, a 0, b 90, c 0, s 'B010', t 'B110', e1 5.0}\n"
       "CIRC {X 10, Y 0, Z 0, A 0, B 0, C 0}, {Y 10, X 0, Z 0, A 45, B 0, C 180}, CA 90\n"
       "SLIN {X 1, Y 2, Z 3, A -170, B 20, C 179.5, S 6, T 27}\n"
       "PTP {A1 10}\n"
       "PTP_REL {A1 5}\n"
       "LIN_REL {Z 10} #TOOL\n"
       "PTP $POS_ACT\n"
       "PTP $AXIS_ACT\n"
       "PTP XP1 C_PTP\n"
       "LIN F1:{X 1, Y 2, Z 3, A 0, B 0, C 0}\n"
       "F1 = {X 0, Y 0, Z 100, A 0, B 0, C 0}\n"
       "P7 = {X 1, Y 1, Z 1, A 0, B 0, C 0}\n"
       "P7.X = P7.X + 10\n"
       "LIN P7\n"
       "$stiffness.maxforce = {X 300.0, Y 300.0, Z 300.0, A 30.0, B 30.0, C 30.0}\n"
       "; PTP {A1 99, A2 0, A3 0, A4 0, A5 0, A6 0} commented out\n"
       "MSG = \"PTP {A1 1}\"\n"
       "END")
DAT = ("DEFDAT demo PUBLIC\r\n"
       "DECL E6POS XP1={X 500.0,Y 0.0,Z 800.0,A 0.0,B 90.0,C 0.0,S 2,T 10,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}\r\n"
       "DECL FDAT FP1={TOOL_NO 3,BASE_NO 2,IPO_FRAME #BASE,POINT2[] \" \"}\r\n"
       "GLOBAL E6AXIS XHOME1={A1 0.0,A2 -90.0,A3 90.0,A4 0.0,A5 0.0,A6 0.0,E1 0.0}\n"
       "E6AXIS bare={A1 1,A2 2,A3 3,A4 4,A5 5,A6 6}\n"
       "DECL POS XPT[3]\n"
       "XPT[1]={X 1,Y 2,Z 3,A 4,B 5,C 6,S 2,T 3}\n"
       "XPT[2]={X 10,Y 20,Z 30,A 40,B 50,C 60}\n"
       "DECL FRAME TOOL_X={X 0,Y 0,Z 120,A 0,B 0,C 0}\n"
       "DECL E6AXIS XPART={A1 10}\n"
       "ENDDAT")


def _rot(values):
    return rotvec_matrix(np.asarray(values[3:6]))


def test_synthetic_src_targets_against_closed_forms():
    prog = _parse(SRC)
    moves = [(t.line, t.move, t.variable, t.kind) for t in prog.targets]
    assert moves == [(5, "PTP", "HOME", "joints"), (9, "PTP", "", "joints"), (10, "LIN", "", "pose"),
                     (11, "LIN", "", "pose"), (12, "CIRC", "", "pose"), (12, "CIRC", "", "pose"),
                     (13, "SLIN", "", "pose")]
    home, ptp, lin, lin2, aux, to, slin = prog.targets
    np.testing.assert_allclose(home.values, [0, -math.pi / 2, math.pi / 2, 0, math.pi / 2, 0])
    assert home.frames == ("TOOL_DATA[2]", "BASE_DATA[1]") and home.config == ()  # those in force at its move (line 8)
    np.testing.assert_allclose(ptp.values, np.radians([10, -0.242, 15, 0, 30, -45]))
    assert ptp.frames == ("TOOL_DATA[2]", "BASE_DATA[1]")
    np.testing.assert_allclose(lin.values, [0.1, -0.2005, 0.3, 0, 0, math.pi / 2], atol=1e-15)
    np.testing.assert_allclose(lin2.values, [1.0, 0, 0.5, 0, math.pi / 2, 0], atol=1e-15)
    assert lin2.config == (2, 6) and SRC[slice(*lin2.fields[0])] == "1000.0"
    np.testing.assert_allclose(aux.values, [0.01, 0, 0, 0, 0, 0], atol=1e-15)
    half = math.radians(22.5)  # Rz(45°)·Rx(180°): half a turn about (cos 22.5°, sin 22.5°, 0)
    assert abs(abs(to.values[3:] @ [math.cos(half), math.sin(half), 0]) - math.pi) < 1e-9
    assert [SRC[slice(*f)] for f in to.fields[:2]] == ["0", "10"]  # X, Y in KRL order, whatever the text order
    np.testing.assert_allclose(_rot(slin.values), rot_zyx(*np.radians([-170, 20, 179.5])), atol=1e-12)
    assert slin.config == (6, 27)


def test_synthetic_src_listed_items():
    listed = {line: why for line, _, why in _parse(SRC).not_literal}
    assert listed[14].startswith("a partial target: A2, A3, A4, A5, A6 not written")
    assert listed[15].startswith("a relative move") and listed[16].startswith("a relative move")
    assert "$POS_ACT is the robot's position" in listed[17] and "$AXIS_ACT is" in listed[18]
    assert "XP1 is not declared in this file" in listed[19] and "the module's .dat" in listed[19]
    assert "frame product" in listed[20]
    assert listed[21].startswith("a FRAME (tool or base data)")
    assert "P7 is assigned more than once" in listed[22] and "P7 is filled or changed" in listed[24]
    assert "controller setting" in listed[25]
    assert sorted(listed) == [14, 15, 16, 17, 18, 19, 20, 21, 22, 24, 25]  # comments and strings: nothing


def test_synthetic_dat_points_frames_and_arrays():
    prog = _parse(DAT, "demo.dat")
    got = [(t.line, t.move, t.variable, t.config, t.frames) for t in prog.targets]
    assert got == [(2, "E6POS", "XP1", (2, 10), ("TOOL_NO 3", "BASE_NO 2")),
                   (4, "E6AXIS", "XHOME1", (), ("", "")), (5, "E6AXIS", "bare", (), ("", "")),
                   (7, "POS", "XPT[1]", (2, 3), ("", "")), (8, "POS", "XPT[2]", (), ("", ""))]
    np.testing.assert_allclose(prog.targets[0].values, [0.5, 0, 0.8, 0, math.pi / 2, 0], atol=1e-15)
    np.testing.assert_allclose(prog.targets[2].values, np.radians([1, 2, 3, 4, 5, 6]))
    listed = {line: why for line, _, why in prog.not_literal}
    assert listed[9].startswith("a FRAME") and listed[10].startswith("a partial target")


@pytest.mark.parametrize("text,source", [(SRC, "demo.src"), (DAT, "demo.dat")])
def test_synthetic_identity_and_changed_rewrite(text, source):
    prog = _parse(text, source)
    assert prog.with_values({k: t.values for k, t in enumerate(prog.targets)}) == text
    rng = np.random.default_rng(7)
    new = {}
    for k, t in enumerate(prog.targets):
        step = np.r_[rng.normal(0, 1e-3, 3), rng.normal(0, 1e-2, 3)] if t.kind == "pose" else rng.normal(0, 1e-2, 6)
        new[k] = t.values + step
    out = prog.with_values(new)
    again = _parse(out, source)
    assert len(again.targets) == len(prog.targets) and skeleton(out, again.targets) == skeleton(text, prog.targets)
    for k, t in enumerate(again.targets):
        if t.kind == "joints":
            np.testing.assert_allclose(t.values, new[k], atol=math.radians(1e-8))
        else:
            np.testing.assert_allclose(t.values[:3], new[k][:3], atol=1e-10)  # 1e-7 mm
            np.testing.assert_allclose(_rot(t.values), _rot(new[k]), atol=1e-9)
        assert t.config == prog.targets[k].config and t.frames == prog.targets[k].frames


@pytest.mark.parametrize("text,line,column,what", [
    ("DEF a( )\nPTP {A1 0, A2 0\nEND", 2, 5, "never closed"),
    ("DEF a( )\n  x = 1 }\nEND", 2, 9, "no '{' open"),
    ("DEF a( )\nPTP {A1 0, A2 abc, A3 0, A4 0, A5 0, A6 0}\nEND", 2, 15, "'abc' is not a number"),
    ("DEFDAT a\nDECL E6POS P1={X 1,Y 2,Z}\nENDDAT", 2, 24, "component Z has no value"),
    ("DEF a( )\n\nCIRC {X 1, Y 2, Z 3, A 0, B 0, C 0} C_DIS\nEND", 3, 37, "auxiliary point and a target"),
    ("DEF a( )\n  LIN   \nEND", 2, 9, "LIN without its target"),
    ("DEFDAT a\r\nDECL E6AXIS J1={X 1,Y 2,Z 3,A 0,B 0,C 0}\r\nENDDAT", 2, 16, "J1 is E6AXIS"),
    ("DEF a( )\nPTP {VEL 100}\nEND", 2, 5, "PTP target is not a position"),
])
def test_broken_programs(text, line, column, what):
    with pytest.raises(MeasurementError) as err:
        _parse(text, "broken.src")
    message = str(err.value)
    assert message.startswith(f"broken.src: line {line}, column {column}: ") and what in message
    assert "\n" not in message


def test_flat_components_read_in_one_scan_as_part_by_part(monkeypatch):
    """The scanner's one-scan reading of flat aggregates and its one-scan number check give every real KRL
    file the same targets and listed items as reading each component on its own."""
    from kincal.io import krl_scan

    fast = [read_program(str(p), "krl") for p in FILES]
    monkeypatch.setattr(krl_scan, "_flat", lambda code, i, b: None)
    monkeypatch.setattr(krl_scan, "ALL_NUMBERS", re.compile(r"(?!)"))
    for path, f in zip(FILES, fast):
        s = read_program(str(path), "krl")
        assert [(t.start, t.end, t.fields, t.config, t.frames, t.variable) for t in f.targets] == \
               [(t.start, t.end, t.fields, t.config, t.frames, t.variable) for t in s.targets], path.name
        assert all(np.array_equal(a.values, b.values) for a, b in zip(f.targets, s.targets))
        assert f.not_literal == s.not_literal


@pytest.mark.parametrize("suffix", [".src", ".SRC"])
def test_a_dat_point_its_module_fills_at_run_time_is_listed_not_compensated(tmp_path, suffix):
    """A .dat alone cannot tell a taught point from a record its module fills at run time (a measured position,
    a velocity); the module's .src beside it can: an assignment there, whole, in part or through an index
    computed at run time, lists the point; a point the .src only moves to stays a target."""
    dat = ("DEFDAT demo\n"
           "DECL E6AXIS HOMEPOS={A1 0.0,A2 -90.0,A3 90.0,A4 0.0,A5 30.0,A6 0.0,E1 0.0}\n"
           "DECL E6AXIS VEL={A1 10.0,A2 20.0,A3 30.0,A4 40.0,A5 50.0,A6 60.0,E1 0.0}\n"
           "DECL E6POS XP[2]\n"
           "XP[1]={X 500.0,Y 0.0,Z 600.0,A 0.0,B 90.0,C 0.0,S 2,T 2}\n"
           "XP[2]={X 400.0,Y 0.0,Z 600.0,A 0.0,B 90.0,C 0.0,S 2,T 2}\n"
           "DECL E6POS XTOOL={X 450.0,Y 50.0,Z 500.0,A 0.0,B 90.0,C 0.0,S 2,T 2}\n"
           "ENDDAT\n")
    src = ("DEF demo()\n"
           "PTP HOMEPOS\n"
           "VEL = $VEL_AXIS_ACT  ; the record is a velocity\n"
           "FOR i = 1 TO 2\n"
           "  XP[i] = $POS_ACT\n"
           "ENDFOR\n"
           "XTOOL.Z = 480.0\n"
           "LIN XTOOL\n"
           "END\n")
    (tmp_path / "demo.dat").write_text(dat)
    prog = read_program(str(tmp_path / "demo.dat"), "krl")  # no .src beside it: every point is a target
    assert [t.variable for t in prog.targets] == ["HOMEPOS", "VEL", "XP[1]", "XP[2]", "XTOOL"]
    (tmp_path / f"demo{suffix}").write_text(src)
    prog = read_program(str(tmp_path / "demo.dat"), "krl")
    assert [t.variable for t in prog.targets] == ["HOMEPOS"]
    listed = {what: why for _, what, why in prog.not_literal}
    assert f"demo{suffix} line 3" in listed["VEL"] and f"demo{suffix} line 5" in listed["XP[1]"]
    assert f"demo{suffix} line 5" in listed["XP[2]"] and f"demo{suffix} line 7" in listed["XTOOL"]


def test_a_local_dat_point_no_move_of_its_module_names_is_listed(tmp_path):
    """A limit in an IF, a speed, a torque record, declared in the .dat without GLOBAL and named by no move of the
    module's .src: listed (a torque of {A4 1.0} was 'compensated' to 4.63). A GLOBAL point stays a target: other
    modules may move there."""
    (tmp_path / "m.dat").write_text(
        "DEFDAT m\n"
        "DECL E6AXIS XHOME={A1 0.0,A2 -90.0,A3 90.0,A4 10.0,A5 30.0,A6 0.0,E1 0.0}\n"
        "DECL E6AXIS XLIMIT={A1 45.0,A2 -60.0,A3 80.0,A4 20.0,A5 40.0,A6 10.0,E1 0.0}\n"
        "DECL AXIS XTORQUE={A1 12.5,A2 -40.0,A3 20.0,A4 1.0,A5 2.0,A6 0.5}\n"
        "DECL GLOBAL E6AXIS XSHARED={A1 5.0,A2 -80.0,A3 85.0,A4 0.0,A5 20.0,A6 0.0,E1 0.0}\n"
        "ENDDAT\n")
    (tmp_path / "m.src").write_text("DEF m()\n  PTP XHOME\n  IF $AXIS_ACT.A1 > XLIMIT.A1 THEN\n    HALT\n  ENDIF\n"
                                    "  ; PTP XTORQUE (a comment names it, no move does)\nEND\n")
    prog = read_program(str(tmp_path / "m.dat"), "krl")
    assert [t.variable for t in prog.targets] == ["XHOME", "XSHARED"]
    listed = {what: why for _, what, why in prog.not_literal}
    assert set(listed) == {"XLIMIT", "XTORQUE"} and all("no move of its module (m.src)" in w for w in listed.values())
