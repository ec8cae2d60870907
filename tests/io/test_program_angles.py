"""Orientation angles a KRL, FANUC or INFORM target is written with are in the controller's range: each in
[-180, 180] (KRL A and C, FANUC W, P, R, INFORM Rx, Ry, Rz) and KUKA's B in [-90, 90], while the rotation stays
the one given. The written numbers are read with a regular expression of this test and turned into a rotation by
scipy (fixed axes x, y, z: intrinsic "ZYX" of (rz, ry, rx)), and by kincal's own reader; both against the rotation
the writer was given, to 1e-9 rad."""
import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kincal.io import read_program

# (old numbers written (rz, ry, rx) deg, the new rotation as (rz, ry, rx) deg): each new one is a few hundredths of a
# degree from the old, across ±180° (rows 1, 2) or across the Euler lock at ry = 90° (row 3), where the triple nearest
# the old numbers is out of range; row 4 is well inside (its angles are the given ones).
CASES = [((179.99, 10.0, -179.99), (180.04, 10.02, -180.03)),
         ((-179.995, -30.0, 179.98), (-180.02, -29.97, 180.05)),
         ((30.0, 89.95, 20.0), (30.0, 90.05, 20.0)),
         ((45.0, -20.0, 60.0), (45.01, -20.02, 60.03))]


def _krl(old):
    lines = [f"DECL E6POS XP{k}={{X 500.0,Y 0.0,Z 400.0,A {a:.3f},B {b:.3f},C {c:.3f},S 2,T 2}}"
             for k, (a, b, c) in enumerate(old, 1)]
    return "\r\n".join(["DEFDAT  T PUBLIC"] + lines + ["ENDDAT", ""])


def _fanuc(old):
    mn = [f"   {k}:L P[{k}] 100mm/sec FINE    ;" for k in range(1, len(old) + 1)]
    pos = [f"P[{k}]{{\n   GP1:\n\tUF : 0, UT : 1,\t\tCONFIG : 'N U T, 0, 0, 0',\n\tX = 500.000  mm,\tY = 0.000  mm,"
           f"\tZ = 400.000  mm,\n\tW = {rx:.3f} deg,\tP = {ry:.3f} deg,\tR = {rz:.3f} deg\n}};"
           for k, (rz, ry, rx) in enumerate(old, 1)]
    return "\n".join(["/PROG  T", "/ATTR", "/MN"] + mn + ["/POS"] + pos + ["/END", ""])


def _inform(old):
    pos = [f"C{k:05d}=500.000,0.000,400.000,{rx:.3f},{ry:.3f},{rz:.3f}" for k, (rz, ry, rx) in enumerate(old)]
    inst = [f"MOVL C{k:05d} V=100.0" for k in range(len(old))]
    return "\n".join(["/JOB", "//NAME T", "//POS", f"///NPOS {len(old)},0,0,0,0,0", "///TOOL 1", "///POSTYPE ROBOT",
                      "///RECTAN"] + pos + ["//INST", "///ATTR SC,RW", "NOP"] + inst + ["END", ""])


# each language: its program, a pattern of its written angles and their order, and the range of the middle angle
SUFFIX = {"krl": ".dat", "fanuc": ".ls", "inform": ".JBI"}
LANGUAGES = {"krl": (_krl, r",A ([^,]+),B ([^,]+),C ([^,]+),", (0, 1, 2), 90.0),
             "fanuc": (_fanuc, r"W = (\S+) deg,\tP = (\S+) deg,\tR = (\S+) deg", (2, 1, 0), 180.0),
             "inform": (_inform, r"C\d+=[^,]+,[^,]+,[^,]+,([^,]+),([^,]+),([^,\n]+)", (2, 1, 0), 180.0)}


@pytest.mark.parametrize("language", LANGUAGES)
def test_written_angles_are_in_the_controllers_range_and_keep_the_rotation(tmp_path, language):
    make, pattern, order, middle = LANGUAGES[language]
    path = tmp_path / f"t{SUFFIX[language]}"
    path.write_bytes(make([old for old, _ in CASES]).encode())
    prog = read_program(str(path), language)
    given = Rotation.from_euler("ZYX", [new for _, new in CASES], degrees=True)
    values = {k: np.concatenate([t.values[:3], given[k].as_rotvec()]) for k, t in enumerate(prog.targets)}
    written = prog.with_values(values)
    found = np.array(re.findall(pattern, written), dtype=float)[:, order]  # (rz, ry, rx) as written
    assert found.shape == (len(CASES), 3)
    assert np.abs(found).max() <= 180.0 and np.abs(found[:, 1]).max() <= middle
    turn = Rotation.from_euler("ZYX", found, degrees=True) * given.inv()
    assert turn.magnitude().max() < 1e-9  # the written numbers are the given rotation (to their 1e-8 deg)
    (tmp_path / f"new{SUFFIX[language]}").write_bytes(written.encode())
    again = read_program(str(tmp_path / f"new{SUFFIX[language]}"), language)
    for t, v in zip(again.targets, values.values()):
        assert np.abs(Rotation.from_rotvec(t.values[3:]).as_matrix() - Rotation.from_rotvec(v[3:]).as_matrix()).max() \
            < 1e-9
    # rows 1, 2 cross ±180: the angle past it is written past the other end; row 4 is written as given
    assert np.all(np.abs(found[:2] - [new for _, new in CASES[:2]]) % 360.0 < 1e-6)
    assert (np.sign(found[:2, [0, 2]]) == -np.sign([[180.04, -180.03], [-180.02, 180.05]])).all()
    assert np.abs(found[3] - CASES[3][1]).max() < 1e-6
    expected = (-150.0, 89.95, -160.0) if middle == 90.0 else (30.0, 90.05, 20.0)  # B past 90: A and C turned 180
    assert np.abs(found[2] - expected).max() < 1e-6
