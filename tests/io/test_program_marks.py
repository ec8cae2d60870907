"""A note kincal writes beside a target it leaves as it is (compensate --skip-unreachable) is ASCII in every
vendor language, whatever the reason says (°, …, —, σ, ×), and the file keeps its encoding and every other byte:
checked on the bytes written, line by line, against the bytes read. FANUC TP and INFORM have no comment beside a
position: their file is written byte for byte as it was."""
import numpy as np
import pytest

import kincal
from kincal.compensate.branch import compensate_branches
from kincal.io import ROWS, read_program, write_program
from kincal.models.transforms import zyx_from_matrix

REASON = "a6 moves from +0.091° to -0.876° (limits -350…350°) — 2σ × 3"

KRL = "DEF x()\r\n; Greifer öffnen\r\nPTP {A1 10, A2 -80, A3 100, A4 25, A5 30, A6 0}\r\nEND\r\n"
RAPID = ("MODULE MT\n    ! Schweißnaht\n    CONST robtarget p1:=[[374,0,630],[0.7071068,0,0.7071068,0],[0,0,0,0],"
         "[9E9,9E9,9E9,9E9,9E9,9E9]];\n    PROC main()\n        MoveL p1,v100,fine,tool0;\n    ENDPROC\nENDMODULE\n")
FANUC = ("/PROG  T\n/ATTR\n/MN\n   1:L P[1] 100mm/sec FINE    ;\n/POS\nP[1]{\n   GP1:\n\tUF : 0, UT : 1,\t\t"
         "CONFIG : 'N U T, 0, 0, 0',\n\tX = 500.000  mm,\tY = 0.000  mm,\tZ = 400.000  mm,\n\tW = 180.000 deg,\t"
         "P = 0.000 deg,\tR = 0.000 deg\n};\n/END\n")
INFORM = ("/JOB\r\n//NAME T\r\n//POS\r\n///NPOS 1,0,0,0,0,0\r\n///TOOL 1\r\n///POSTYPE ROBOT\r\n///RECTAN\r\n"
          "C00000=500.000,0.000,400.000,180.0000,0.0000,0.0000\r\n//INST\r\n///ATTR SC,RW\r\nNOP\r\n"
          "MOVL C00000 V=100.0\r\nEND\r\n")
# language: the file (its bytes: KRL and RAPID in Latin-1, as controllers write them), its suffix, the target's line
FILES = {"krl": (KRL.encode("latin-1"), ".src", 3), "rapid": (RAPID.encode("latin-1"), ".mod", 3),
         "fanuc": (FANUC.encode("ascii"), ".ls", 6), "inform": (INFORM.encode("ascii"), ".JBI", 8)}


def _inserted(before: bytes, after: bytes) -> dict[int, bytes]:
    """The bytes ``after`` has in addition to ``before``, by line (from 1): each line of ``after`` must be that of
    ``before`` with bytes added before its line ending, and nothing else may differ."""
    old, new = before.splitlines(keepends=True), after.splitlines(keepends=True)
    assert len(old) == len(new)
    out = {}
    for n, (a, b) in enumerate(zip(old, new), 1):
        body = a.rstrip(b"\r\n")
        ending = a[len(body):]
        assert b.startswith(body) and b.endswith(ending), (a, b)
        if a != b:
            out[n] = b[len(body):len(b) - len(ending)]
    return out


@pytest.mark.parametrize("language", FILES)
def test_a_mark_is_ascii_and_every_other_byte_stays(tmp_path, language):
    raw, suffix, line = FILES[language]
    path = tmp_path / f"t{suffix}"
    path.write_bytes(raw)
    prog = read_program(str(path), language)
    assert [t.line for t in prog.targets] == [line]
    assert prog.encoding == ("latin-1" if language in ("krl", "rapid") else "utf-8")
    out = tmp_path / f"out{suffix}"
    write_program(str(out), prog, {}, {0: REASON})
    added = _inserted(raw, out.read_bytes())
    if language in ("fanuc", "inform"):
        assert added == {}  # no comment beside a position: the file as it was
        return
    assert list(added) == [line]
    mark = added[line]
    assert mark.isascii() and all(32 <= b < 127 for b in mark)
    comment = {"krl": b";", "rapid": b"!"}[language]
    assert mark == (b"  " + comment + b" kincal: not compensated: a6 moves from +0.091 deg to -0.876 deg "
                    b"(limits -350...350 deg) - 2sigma x 3")


def test_a_real_refusal_of_a_latin1_krl_program_is_marked_in_ascii(tmp_path):
    """The reason kincal gives for a KRL pose whose correction moves A6 across 0 names both angles in degrees (°):
    written with --skip-unreachable into a Latin-1 file, the mark is ASCII and the umlaut of the comment stays."""
    nominal = kincal.load_robot("kuka_kr6r900sixx")
    q = np.radians([10, -80, 100, 25, 30, 0])
    p = nominal.forward(q[None])[0] * 1e3
    a, b, c = np.degrees(zyx_from_matrix(nominal.flange_rotation(q[None])[0]))
    s, t = ROWS["krl"](nominal, q[None])[0]
    text = (f"DEF x()\r\n; Greifer öffnen\r\nPTP {{X {p[0]:.3f}, Y {p[1]:.3f}, Z {p[2]:.3f}, A {a:.3f}, B {b:.3f}, "
            f"C {c:.3f}, S {s}, T {t}}}\r\nEND\r\n").encode("latin-1")
    (tmp_path / "x.src").write_bytes(text)
    prog = read_program(str(tmp_path / "x.src"), "krl")
    res = compensate_branches(kincal.perturb(nominal, seed=1), nominal, prog, ROWS["krl"],
                              {"default tool": np.eye(4), "default base": np.eye(4)})
    assert "°" in res.refused[0] and not res.texts
    write_program(str(tmp_path / "out.src"), prog, res.texts, res.refused)
    added = _inserted(text, (tmp_path / "out.src").read_bytes())
    assert list(added) == [3] and added[3].isascii() and b" deg to -0.4" in added[3]
    assert b"\xf6ffnen" in (tmp_path / "out.src").read_bytes()
