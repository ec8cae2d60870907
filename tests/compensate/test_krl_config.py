"""KUKA frames beside a program (kincal.io.krl_config): a controller's folders (KRC/R1/Program, R1/System/$config.dat,
STEU/Mada/$machine.dat) built from known frames; the program's targets compensated with the TOOL_DATA and BASE_DATA
found there land, on the calibrated arm, where the program meant (checked through an independent inverse with
the test's own frames); without $ROBROOT_C the bases are refused, never taken as in the robot's base."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kincal
from kincal.compensate.branch import compensate_branches, controller_inverse
from kincal.errors import MeasurementError
from kincal.io import BITS, ROWS, read_frames, read_program


def _frame(xyz_mm, zyx_deg):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_euler("ZYX", zyx_deg, degrees=True).as_matrix(), np.array(xyz_mm) * 1e-3
    return T


def _krl(T) -> str:
    a, b, c = Rotation.from_matrix(T[:3, :3]).as_euler("ZYX", degrees=True)
    x, y, z = T[:3, 3] * 1e3
    return f"X {x:.6f},Y {y:.6f},Z {z:.6f},A {a:.6f},B {b:.6f},C {c:.6f}"


TOOL = _frame([12, -5, 180], [0, 20, 0])
BASE = _frame([650, 120, -40], [30, 0, 0])  # in the robot's base
ROOT = _frame([2000, -500, 300], [90, 0, 0])  # the robot's base in the world ($ROBROOT_C)
Q = np.radians([[10, -80, 100, 20, 40, 30], [-25, -100, 110, -30, -50, 60], [40, -60, 80, 90, 30, -120]])


def _cell(tmp_path, nominal, machine=True):
    """KRC/R1/Program/pick.dat (three E6POS in BASE_NO 2 with TOOL_NO 1) and pick.src ($TOOL = $NULLFRAME,
    $BASE = BASE_DATA[2], a LIN to a flange pose), R1/System/$config.dat, STEU/Mada/$machine.dat."""
    flange = nominal.with_tool_point(np.zeros(3))
    program = tmp_path / "KRC" / "R1" / "Program"
    program.mkdir(parents=True)
    lines = ["DEFDAT  PICK"]
    for k, qk in enumerate(Q, 1):
        p, R, _, _ = flange.pose_and_jacobian(qk[None])
        F = np.eye(4)
        F[:3, :3], F[:3, 3] = R[0], p[0]
        s, t = BITS["krl"](nominal, qk)
        lines += [f"DECL E6POS XP{k}={{{_krl(np.linalg.inv(BASE) @ F @ TOOL)},S {s},T {t},E1 0.0}}",
                  f"DECL FDAT FP{k}={{TOOL_NO 1,BASE_NO 2,IPO_FRAME #BASE}}"]
    (program / "pick.dat").write_text("\r\n".join(lines + ["ENDDAT", ""]))
    p, R, _, _ = flange.pose_and_jacobian(Q[:1])
    F = np.eye(4)
    F[:3, :3], F[:3, 3] = R[0], p[0]
    (program / "move.src").write_text("DEF move()\n$TOOL = $NULLFRAME\n$BASE = BASE_DATA[2]\n"
                                      f"LIN {{{_krl(np.linalg.inv(BASE) @ F)}}}\nEND\n")
    system = tmp_path / "KRC" / "R1" / "System"
    system.mkdir()
    (system / "$config.dat").write_text(
        "&ACCESS RV\nDEFDAT  $CONFIG\nDECL FRAME TOOL_DATA[16]\n"
        f"TOOL_DATA[1]={{{_krl(TOOL)}}}\nTOOL_DATA[2]={{X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}}\n"
        f"DECL FRAME BASE_DATA[32]\nBASE_DATA[2]={{{_krl(ROOT @ BASE)}}}\nENDDAT\n")
    if machine:
        mada = tmp_path / "KRC" / "STEU" / "Mada"
        mada.mkdir(parents=True)
        (mada / "$machine.dat").write_text(f"DEFDAT  $MACHINE\nFRAME $ROBROOT_C={{{_krl(ROOT)}}}\nENDDAT\n")
    return program


def _lands(true, nominal, old, new, tool, base, q_near):
    """The written target, turned into joints on its bits by the nominal arm in the test's frames, puts the true
    arm's flange on the pose the original target meant."""
    flange = nominal.with_tool_point(np.zeros(3))

    def pose(values):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = Rotation.from_rotvec(values[3:]).as_matrix(), values[:3]
        F = base @ T @ np.linalg.inv(tool)
        return F[:3, 3], F[:3, :3]

    p, R = pose(old.values)
    pn, Rn = pose(new.values)
    q = controller_inverse(flange, pn[None], Rn[None], q_near, new.config or (), BITS["krl"])
    pt, Rt, _, _ = true.with_tool_point(np.zeros(3)).pose_and_jacobian(q[None])
    return np.linalg.norm(pt[0] - p), np.linalg.norm(Rotation.from_matrix(Rt[0] @ R.T).as_rotvec())


def test_frames_beside_the_program_compensate_it(tmp_path):
    nominal = kincal.load_robot("kuka_kr6r900sixx")
    true = kincal.perturb(nominal, seed=5)
    program = _cell(tmp_path, nominal)
    for name, tool, near in (("pick.dat", TOOL, Q), ("move.src", np.eye(4), Q[:1])):
        prog = read_program(str(program / name), "krl")
        res = compensate_branches(true, nominal, prog, ROWS["krl"])
        assert not res.problems and len(res.texts) == len(prog.targets) == len(near)
        again = read_program(str(program / name), "krl")
        text = prog.with_targets(res.texts)
        (tmp_path / name).write_text(text)
        written = read_program(str(tmp_path / name), "krl")
        for old, new, qk in zip(again.targets, written.targets, near):
            miss, turn = _lands(true, nominal, old, new, tool, BASE, qk)
            assert miss < 1e-9 and turn < 1e-9


def test_config_frames_against_their_closed_form_and_bases_need_robroot(tmp_path):
    nominal = kincal.load_robot("kuka_kr6r900sixx")
    program = _cell(tmp_path, nominal, machine=False)
    config = str(tmp_path / "KRC" / "R1" / "System" / "$config.dat")
    got = read_frames(config)
    assert {k for k, v in got.items() if not isinstance(v, str)} == {"TOOL_DATA[1]", "TOOL_NO 1", "TOOL_DATA[2]", "TOOL_NO 2"}
    assert np.abs(got["TOOL_NO 1"] - TOOL).max() < 1e-9
    prog = read_program(str(program / "pick.dat"), "krl")
    res = compensate_branches(kincal.perturb(nominal, seed=5), nominal, prog, ROWS["krl"])
    assert not res.texts and all(w.startswith("its base frame 'BASE_NO 2' is not known: ") and "$ROBROOT_C" in w
                                 and "BASE_DATA[2] in the world frame" in w for w in res.refused.values())
    assert isinstance(got["BASE_NO 2"], str)  # the reason, where a base cannot be placed
    mada = tmp_path / "KRC" / "STEU" / "Mada"
    mada.mkdir(parents=True)
    (mada / "$machine.dat").write_text(f"FRAME $ROBROOT_C={{{_krl(ROOT)}}}\n")
    got = read_frames(config)
    assert np.abs(got["BASE_NO 2"] - BASE).max() < 1e-9 and np.abs(got["BASE_DATA[2]"] - BASE).max() < 1e-9
    assert np.abs(got["$NULLFRAME"] @ ROOT - np.eye(4)).max() < 1e-12  # the world, in the robot's base


def test_a_broken_frame_is_named_by_file_line_and_column(tmp_path):
    bad = tmp_path / "$config.dat"
    bad.write_text("DEFDAT  $CONFIG\nTOOL_DATA[1]={X 0.0,Y 0.0,Z 100.0,A 0.0,B 0.0}\nENDDAT\n")
    with pytest.raises(MeasurementError, match=r"\$config.dat: line 2, column 14: a frame needs X, Y, Z, A, B and C "
                                               r"\(missing: C"):
        read_frames(str(bad))
    bad.write_text("DEFDAT  $CONFIG\nTOOL_DATA[1]={X 0.0,Y 0.0,Z 1OO.0,A 0.0,B 0.0,C 0.0}\nENDDAT\n")
    with pytest.raises(MeasurementError, match=r"line 2, column 29: '1OO.0' is not a number"):
        read_frames(str(bad))


def test_a_frames_file_written_in_metres_is_refused_naming_the_unit(tmp_path):
    """A 150 mm tool written as z: 0.15 in a frames file read in mm (the default) was taken as a 0.15 mm tool; now
    refused as metres. Declared units are taken as they are, and a file of zero frames is fine."""
    from kincal.io import read_frames
    (tmp_path / "m.yaml").write_text("TOOL_NO 1: {z: 0.15}\nBASE_NO 0: {}\n")
    with pytest.raises(ValueError, match=r"within 0\.15 mm as read in mm \(the default\): they look like metres"):
        read_frames(str(tmp_path / "m.yaml"))
    (tmp_path / "ok.yaml").write_text("units: {length: m}\nTOOL_NO 1: {z: 0.15}\n")
    assert read_frames(str(tmp_path / "ok.yaml"))["TOOL_NO 1"][2, 3] == pytest.approx(0.15)
    (tmp_path / "small.yaml").write_text("units: {length: mm}\nTOOL_NO 1: {z: 0.15}\n")
    assert read_frames(str(tmp_path / "small.yaml"))["TOOL_NO 1"][2, 3] == pytest.approx(0.15e-3)
    (tmp_path / "zero.yaml").write_text("BASE_NO 0: {}\n")
    assert np.array_equal(read_frames(str(tmp_path / "zero.yaml"))["BASE_NO 0"], np.eye(4))


@pytest.mark.parametrize("output", ["R1/Program/pick.src", "R1/System/$config.dat", "STEU/Mada/$machine.dat"])
def test_compensate_refuses_to_write_over_a_file_its_reader_reads_beside_the_program(tmp_path, capsys, output):
    """compensate pick.dat reads pick.src (its module: what it does with the .dat's points), the controller's
    $config.dat and $machine.dat; -o on any of them is refused before any work, naming it, and the file is as it
    was (the .src was written over with the .dat's compensation, exit 0). A $config.dat given as the frames reads
    the $machine.dat beside it: refused alike."""
    from kincal.cli import main

    program = _cell(tmp_path, kincal.load_robot("kuka_kr6r900sixx"))
    (program / "pick.src").write_text("DEF pick()\nPTP XP1\nLIN XP2\nLIN XP3\nEND\n")
    target = tmp_path / "KRC" / output
    before = target.read_bytes()
    capsys.readouterr()
    assert main(["compensate", "kuka_kr6r900sixx", str(program / "pick.dat"), "--program", "krl",
                 "-o", str(target)]) == 1
    said = capsys.readouterr().err
    assert f"the output would overwrite {target}" in said and "which this command reads" in said, said
    assert target.read_bytes() == before
    if output.endswith("$machine.dat"):
        assert main(["compensate", "kuka_kr6r900sixx", str(program / "move.src"), "--program", "krl", "--frames",
                     str(tmp_path / "KRC" / "R1" / "System" / "$config.dat"), "-o", str(target)]) == 1
        assert f"the output would overwrite {target}" in capsys.readouterr().err


def test_one_frame_in_metres_among_frames_in_mm_is_refused_naming_it(tmp_path):
    """A frames file whose default tool was written in metres ({x: 0.02, y: 0.01, z: 0.12}: a 20, 10, 120 mm tool)
    beside TOOL_NO 2 in mm (z: 180): the tool was taken as 0.122 mm long without a word (only a file whose every frame
    is that small was refused; the real TCP then 0.27-0.29 mm off the targets). Each frame is judged on its own: the
    tool is named with its values and what they are in metres; one really that small is taken with 'units: {length:
    mm}', and frames at their origin (0) or far from it are as they were."""
    (tmp_path / "mix.yaml").write_text("default tool: {x: 0.02, y: 0.01, z: 0.12, rx: 0, ry: 0, rz: 0}\n"
                                       "default base: {x: 0, y: 0, z: 0}\nTOOL_NO 2: {z: 180}\n")
    with pytest.raises(ValueError) as err:
        read_frames(str(tmp_path / "mix.yaml"))
    said = str(err.value)
    assert "'default tool' {x: 0.02, y: 0.01, z: 0.12}, 0.122 mm from its origin" in said, said
    assert "in metres {x: 20, y: 10, z: 120} mm" in said and "beside 'TOOL_NO 2' 180 mm out" in said
    assert "'default base'" not in said and "units: {length: mm}" in said
    (tmp_path / "mm.yaml").write_text("units: {length: mm}\n" + (tmp_path / "mix.yaml").read_text())
    got = read_frames(str(tmp_path / "mm.yaml"))
    np.testing.assert_allclose(got["default tool"][:3, 3], [0.02e-3, 0.01e-3, 0.12e-3])
    (tmp_path / "ok.yaml").write_text("default tool: {x: 20, y: 10, z: 120}\ndefault base: {}\nTOOL_NO 2: {z: 180}\n")
    np.testing.assert_allclose(read_frames(str(tmp_path / "ok.yaml"))["default tool"][:3, 3], [0.02, 0.01, 0.12])


def _world_module(tmp_path, nominal, machine: bool):
    """KRC/R1/Program/pick.dat: the three poses as E6POS in BASE_NO 0 (the world) with TOOL_NO 1, no $config.dat;
    STEU/Mada/$machine.dat with ROOT when ``machine``."""
    flange = nominal.with_tool_point(np.zeros(3))
    program = tmp_path / "KRC" / "R1" / "Program"
    program.mkdir(parents=True)
    lines = ["DEFDAT  PICK"]
    for k, qk in enumerate(Q, 1):
        p, R, _, _ = flange.pose_and_jacobian(qk[None])
        F = np.eye(4)
        F[:3, :3], F[:3, 3] = R[0], p[0]
        s, t = BITS["krl"](nominal, qk)
        lines += [f"DECL E6POS XP{k}={{{_krl(ROOT @ F @ TOOL)},S {s},T {t},E1 0.0}}",  # in the world: ROOT · base
                  f"DECL FDAT FP{k}={{TOOL_NO 1,BASE_NO 0,IPO_FRAME #BASE}}"]
    (program / "pick.dat").write_text("\r\n".join(lines + ["ENDDAT", ""]))
    if machine:
        mada = tmp_path / "KRC" / "STEU" / "Mada"
        mada.mkdir(parents=True)
        (mada / "$machine.dat").write_text(f"DEFDAT  $MACHINE\nFRAME $ROBROOT_C={{{_krl(ROOT)}}}\nENDDAT\n")
    return program / "pick.dat"


def test_base_0_is_the_world_placed_by_robroot_else_refused_with_why(tmp_path):
    """KRL's BASE_NO 0 ($NULLFRAME) is the world frame: with a $machine.dat beside the program (and no $config.dat)
    its $ROBROOT_C places it and the targets land where they meant (the test's own frames: the world is ROOT⁻¹ in
    the robot's base); without one, a frames file giving only the tool had the targets refused as 'not given (...
    not taken as the identity)', and now with why: base 0 is the world, the robot's base only where $ROBROOT_C is
    $NULLFRAME. BASE_NO 0 given with the frames is taken as given."""
    nominal = kincal.load_robot("kuka_kr6r900sixx")
    true = kincal.perturb(nominal, seed=5)
    path = _world_module(tmp_path / "placed", nominal, machine=True)
    prog = read_program(str(path), "krl")
    res = compensate_branches(true, nominal, prog, ROWS["krl"], {"TOOL_NO 1": TOOL})
    assert not res.problems and len(res.texts) == 3
    (tmp_path / "out.dat").write_text(prog.with_targets(res.texts))
    for old, new, qk in zip(prog.targets, read_program(str(tmp_path / "out.dat"), "krl").targets, Q):
        miss, turn = _lands(true, nominal, old, new, TOOL, np.linalg.inv(ROOT), qk)
        assert miss < 1e-9 and turn < 1e-9
    prog = read_program(str(_world_module(tmp_path / "bare", nominal, machine=False)), "krl")
    res = compensate_branches(true, nominal, prog, ROWS["krl"], {"TOOL_NO 1": TOOL})
    assert not res.texts and len(res.refused) == 3
    assert all(w.startswith("its base frame 'BASE_NO 0' is not known: KRL's base 0 ($BASE = $NULLFRAME) is the world "
                            "frame") and "$ROBROOT_C" in w and "give the controller's folders, or BASE_NO 0 with the "
               "frames" in w for w in res.refused.values())
    res = compensate_branches(true, nominal, prog, ROWS["krl"], {"TOOL_NO 1": TOOL, "BASE_NO 0": np.linalg.inv(ROOT)})
    assert not res.problems and len(res.texts) == 3
