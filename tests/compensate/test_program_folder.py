"""Every one of the 185 real robot programs in ``../shared/datasets/robot_programs`` (its MANIFEST: KRL, RAPID,
FANUC TP, INFORM) is read by the dialect its suffix names, and written back from its own targets byte for byte
(each target's numbers converted to SI and back and written in their own style), whatever its encoding, byte-order
mark or line endings; the sha256 of each file is the manifest's, so the files read are the ones listed."""
import csv
import hashlib

import pytest

from kincal.io import dialect_of, read_program

from conftest import shared_dataset

FOLDER = shared_dataset("robot_programs")
MANIFEST = list(csv.DictReader((FOLDER / "MANIFEST.csv").open(newline="", encoding="utf-8")))
LANGUAGE = {"krl": "krl", "rapid": "rapid", "fanuc": "fanuc", "inform": "inform"}  # the manifest's dialect column


def test_the_manifest_lists_every_program_once():
    assert len(MANIFEST) == 185 and len({row["local_path"] for row in MANIFEST}) == 185
    assert {row["dialect"] for row in MANIFEST} == set(LANGUAGE)


@pytest.mark.parametrize("row", MANIFEST, ids=[row["local_path"] for row in MANIFEST])
def test_every_program_is_read_and_written_back_byte_for_byte(row):
    path = FOLDER / row["local_path"]
    raw = path.read_bytes()
    assert hashlib.sha256(raw).hexdigest() == row["sha256"]
    dialect = dialect_of(str(path))
    assert dialect == LANGUAGE[row["dialect"]]
    prog = read_program(str(path), dialect)
    again = prog.with_values({k: t.values for k, t in enumerate(prog.targets)})
    assert again.encode(prog.encoding) == raw
    for t in prog.targets:  # every field of a target is a number inside its span
        assert all(t.start <= a < b <= t.end and prog.text[a:b].strip() for a, b in t.fields)


def test_a_suffix_kincal_does_not_read_is_named():
    with pytest.raises(ValueError, match=r"\.src \(krl\).*\.mod \(rapid\).*\.ls \(fanuc\).*\.jbi \(inform\)"):
        dialect_of("cell/program.txt")
    assert dialect_of("A/B/JOB.JBI") == "inform" and dialect_of("x.LS") == "fanuc" and dialect_of("m.modx") == "rapid"


def test_angles_written_again_are_the_rotation_nearest_the_old_numbers():
    """kincal.models.transforms.zyx_nearest, shared by the KRL, FANUC and INFORM writers: it gives the rotation
    (against scipy's), the one of its equivalent triples nearest the old angles, and the old ones when unchanged."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    from kincal.models.transforms import zyx_nearest

    rng = np.random.default_rng(0)
    for _ in range(200):
        old = rng.uniform(-np.pi, np.pi, 3) * [1, 0.5, 1]
        R = Rotation.from_euler("ZYX", old).as_matrix()
        assert np.array_equal(zyx_nearest(R, old), old)  # unchanged: the old numbers exactly
        turned = Rotation.from_rotvec(rng.normal(0, 1e-3, 3)).as_matrix() @ R
        written = old + 2 * np.pi * rng.integers(-1, 2, 3)  # the old angles as written, with whole turns
        new = zyx_nearest(turned, written)
        assert np.abs(Rotation.from_euler("ZYX", new).as_matrix() - turned).max() < 1e-12
        assert np.abs(new - written).max() < 0.05 or abs(abs(old[1]) - np.pi / 2) < 0.05  # beside the old numbers
        other = np.array([new[0] + np.pi, np.pi - new[1], new[2] + np.pi])  # the same rotation, the other triple
        assert np.abs(Rotation.from_euler("ZYX", other).as_matrix() - turned).max() < 1e-12
    # at ry = 90 deg only rz - rx is defined: the old rx is kept, rz follows
    R = Rotation.from_euler("ZYX", [0.7, np.pi / 2, 0.2]).as_matrix()
    got = zyx_nearest(R, np.array([0.0, 1.5, 0.3]))
    assert abs(got[1] - np.pi / 2) < 1e-15 and got[2] == 0.3 and abs(got[0] - 0.8) < 1e-9
