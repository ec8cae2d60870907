"""Universal Robots' kinematics file out of a URDF calibration: where UR's flange and Base are, and which arm is UR's,
checked against an independent reading of the calibrated URDF (yourdfpy) and UR's own description chain."""
import json

import numpy as np
import pytest
import yaml
from conftest import UR5_URDF

import yourdfpy  # an independent URDF parser, test-time only (the dev extra installs it)

import kincal
from kincal.cli import main

SMR = (0.0, 0.09e-3, 31.0e-3)  # the data set's reflector in the flange (tool0) frame, m
ENTRIES = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
PROBE = ('<link name="probe"/><joint name="tool0-probe" type="fixed"><parent link="tool0"/><child link="probe"/>'
         '<origin xyz="0 0 0.02" rpy="0 0 0.7853981633974483"/></joint>\n</robot>')


def ur_frames(kin, q):
    """UR's description chain in UR's Base (ur_description's base_link_inertia, which is its link 'base'): per
    joint T(x, y, z) Rz(yaw) Ry(pitch) Rx(roll) Rz(q), by hand; wrist_3 -> flange -> tool0 is the identity, so the
    last frame is tool0. (N, 4, 4)."""
    def rot(axis, a):
        c, s = np.cos(a), np.sin(a)
        i, j = [(1, 2), (2, 0), (0, 1)][axis]
        R = np.eye(4)
        R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
        return R
    out = []
    for qi in q:
        T = np.eye(4)
        for name, angle in zip(ENTRIES, qi):
            e, M = kin[name], np.eye(4)
            M[:3, 3] = [e["x"], e["y"], e["z"]]
            T = T @ M @ rot(2, e["yaw"]) @ rot(1, e["pitch"]) @ rot(0, e["roll"]) @ rot(2, angle)
        out.append(T)
    return np.array(out)


def calibrated(tmp_path, capsys, text, tip, base_link=None, seed=31):
    """The URDF ``text`` (written to tmp_path) read to ``tip``, its joint origins perturbed as a calibration moves
    them (base frame left at zero), saved as cal.yaml and exported as a URDF and a UR file: the robot, the file's
    kinematics and the export's --json summary."""
    (tmp_path / "arm.urdf").write_text(text)
    nominal = kincal.load_robot(tmp_path / "arm.urdf", base_link=base_link, tip_link=tip, tool=SMR)
    true = kincal.perturb(nominal, seed=seed)
    robot = nominal.with_params({n: v for n, v in true.params.as_dict().items() if not n.startswith("base.")})
    kincal.save_robot(robot, tmp_path / "cal.yaml")
    assert main(["export", str(tmp_path / "cal.yaml"), str(tmp_path / "cal.urdf")]) == 0
    capsys.readouterr()
    assert main(["export", str(tmp_path / "cal.yaml"), str(tmp_path / "ur.yaml"), "--format", "ur", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    return robot, yaml.safe_load((tmp_path / "ur.yaml").read_text())["kinematics"], info


@pytest.mark.parametrize("tip", ["probe", "wrist_3_link", "tool0"])
def test_urs_flange_is_the_urdfs_tool0_whatever_the_tip_link(tip, tmp_path, capsys):
    """UR5 calibrated to a probe link 20 mm below tool0 turned 45°, to wrist_3_link (82.3 mm above tool0) or to
    tool0: the UR file's wrist-3 frame, rebuilt by UR's description rules, is the calibrated URDF's own tool0 in its
    link 'base' (read by yourdfpy) within 1e-9 m at random poses, and the TCP printed is the tool point in that
    tool0 (the probe's 20 mm and 45° turn, or the 82.3 mm, in it). Before, the file ended at the tip link: tool0 20 mm
    / 45° off (probe), 82.3 mm short (wrist_3_link), and its check passed."""
    robot, kin, info = calibrated(tmp_path, capsys, UR5_URDF.read_text().replace("</robot>", PROBE), tip)
    urdf = yourdfpy.URDF.load(str(tmp_path / "cal.urdf"), load_meshes=False, build_collision_scene_graph=False)
    q = robot.sample_joints(30, seed=32)
    for qi, ours in zip(q, ur_frames(kin, q)):
        urdf.update_cfg(dict(zip(robot.joint_names, qi)))
        np.testing.assert_allclose(ours, urdf.get_transform("tool0", "base"), atol=1e-9)
    x, y, z = t = robot.tool_point()
    tcp = urdf.get_transform(tip, "tool0") @ np.append(t, 1.0)
    np.testing.assert_allclose(info["tool_point"], tcp[:3], atol=1e-12)
    c = np.cos(np.pi / 4)  # by hand: tool0 -> probe is T(0, 0, 0.02) Rz(45°); tool0 -> wrist_3_link Rx(90°) T(0, -0.0823, 0)
    want = {"probe": [c * (x - y), c * (x + y), z + 0.02], "wrist_3_link": [x, -z, y - 0.0823], "tool0": t}[tip]
    np.testing.assert_allclose(info["tool_point"], want, atol=1e-12)


def test_a_tip_without_urs_flange_is_refused(tmp_path, capsys):
    """A URDF whose tool0 is renamed (and that has no 'flange'): UR's flange cannot be found, so nothing is written
    and the message says why and what to do."""
    text = UR5_URDF.read_text().replace('"tool0"', '"tool_plate"')
    (tmp_path / "arm.urdf").write_text(text)
    assert main(["export", str(tmp_path / "arm.urdf"), str(tmp_path / "ur.yaml"), "--format", "ur", "--base-link",
                 "base_link", "--tip-link", "tool_plate"]) == 1
    said = capsys.readouterr().err
    assert "link 'tool0' or 'flange', and neither is fixed to the chain's tip 'tool_plate'" in said
    assert "--tip-link tool0" in said and not (tmp_path / "ur.yaml").exists()


def test_a_mounted_arms_file_is_relative_to_urs_base(tmp_path, capsys):
    """The UR5 URDF calibrated from 'world' with the arm mounted at (300, 200, 800) mm, tilted 0.1 rad and turned 0.5
    rad: the UR file is written in the URDF's link 'base' wherever the mounting puts it (UR's calibration is
    relative to Base; the mounting is not the driver's business): its wrist-3 frame is the calibrated URDF's tool0 in
    'base' (yourdfpy) within 1e-9 m, and the same joint origins unmounted give the same file within 1e-9. It was
    refused ("not a turn about z of world") with no way out; --base-yaw beside it is refused, naming the mounting."""
    mount = ('<origin rpy="0.0 0.0 0.0" xyz="0.0 0.0 0.0"/>\n  </joint>\n</robot>',
             '<origin rpy="0 0.1 0.5" xyz="0.3 0.2 0.8"/>\n  </joint>\n</robot>')
    text = UR5_URDF.read_text()
    assert text.count(mount[0]) == 1
    robot, kin, _ = calibrated(tmp_path, capsys, text.replace(*mount), "tool0")
    assert robot.source.get("base_link") == "world"
    urdf = yourdfpy.URDF.load(str(tmp_path / "cal.urdf"), load_meshes=False, build_collision_scene_graph=False)
    q = robot.sample_joints(30, seed=33)
    for qi, ours in zip(q, ur_frames(kin, q)):
        urdf.update_cfg(dict(zip(robot.joint_names, qi)))
        np.testing.assert_allclose(ours, urdf.get_transform("tool0", "base"), atol=1e-9)
    flat = tmp_path / "flat"
    flat.mkdir()
    _, plain, _ = calibrated(flat, capsys, text, "tool0")  # the same seed: the same joint origins
    for entry in ENTRIES:
        np.testing.assert_allclose([kin[entry][k] for k in "xyz"], [plain[entry][k] for k in "xyz"], atol=1e-9)
    assert main(["export", str(tmp_path / "cal.yaml"), str(tmp_path / "x.yaml"), "--format", "ur", "--base-yaw",
                 "180"]) == 1
    assert "(at 300, 200, 800 mm: more than a turn about z, a mounting)" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["kuka_kr6r900sixx", "abb_irb120"])
def test_a_six_joint_arm_of_another_make_is_not_a_ur(name, tmp_path, capsys):
    """A 6R arm with a spherical wrist (joint 3 square to joint 4) is refused a UR file, naming its angles between
    neighbouring axes, the twists folded to [0°, 90°] by hand (standard DH: α of joints 1-5; modified DH, the KUKA:
    α of joints 2-6); it was written without comment (a Kinova Jaco calibration too, its root link being called
    'base'). UR's own pass (test_urdf)."""
    robot = kincal.load_robot(name)
    rows = robot.joint_names[1:] if name.startswith("kuka") else robot.joint_names[:5]
    twists = [np.degrees(robot.params[f"{j}.alpha"]) % 180.0 for j in rows]
    angles = ", ".join(f"{min(a, 180.0 - a):.1f}°" for a in twists)
    assert main(["export", name, str(tmp_path / "ur.yaml"), "--format", "ur"]) == 1
    said = capsys.readouterr().err
    assert f"robot '{name}' is not a Universal Robots arm" in said and f"this robot's are {angles};" in said
    assert "90.0°, 0.0°, 90.0°, 90.0°, 90.0°" in said and not (tmp_path / "ur.yaml").exists()


def test_urs_names_do_not_make_a_ur(tmp_path, capsys):
    """The UR5 URDF, its links 'base' and 'tool0' and UR's joint names kept, with wrist 1 turned about z instead of
    y (its axis square to the elbow's, parallel to wrist 2's): refused by its structure, angles 90, 0, 90, 0, 90."""
    text = UR5_URDF.read_text()
    wrist_1 = '<child link="wrist_1_link"/>\n    <origin rpy="0.0 1.57079632679 0.0" xyz="0.0 0.0 0.39225"/>\n    ' \
              '<axis xyz="0 1 0"/>'
    assert text.count(wrist_1) == 1
    (tmp_path / "arm.urdf").write_text(text.replace(wrist_1, wrist_1.replace("0 1 0", "0 0 1")))
    assert main(["export", str(tmp_path / "arm.urdf"), str(tmp_path / "ur.yaml"), "--format", "ur", "--base-link",
                 "base_link", "--tip-link", "tool0"]) == 1
    assert "this robot's are 90.0°, 0.0°, 90.0°, 0.0°, 90.0°;" in capsys.readouterr().err


def test_the_base_frame_printed_names_the_link_it_places(tmp_path, capsys):
    """A DH UR5 calibrated in a tracker's frame, exported as a URDF: the base frame printed places link
    base_link_inertia (the DH base), not the file's root base_link (180° about z from it), and says so. By yourdfpy:
    the calibrated positions are the base frame applied to tool_point in base_link_inertia within 1e-9 m, and miss
    by metres in base_link. A URDF robot's line names its chain's base link."""
    robot = kincal.perturb(kincal.load_robot("ur5"), seed=34).with_params({"base.x": 1.2, "base.y": -0.4,
                                                                            "base.rz": 0.7})
    kincal.save_robot(robot, tmp_path / "cal.yaml")
    assert main(["export", str(tmp_path / "cal.yaml"), str(tmp_path / "cal.urdf"), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["base_frame_link"], info["root_link"]) == ("base_link_inertia", "base_link")
    assert main(["export", str(tmp_path / "cal.yaml"), str(tmp_path / "cal.urdf")]) == 0
    assert "where the instrument saw link 'base_link_inertia', not the URDF's root 'base_link';" in \
        capsys.readouterr().out
    urdf = yourdfpy.URDF.load(str(tmp_path / "cal.urdf"), load_meshes=False, build_collision_scene_graph=False)
    R, t = robot.base_transform()
    q = robot.sample_joints(20, seed=35)
    for link, near in (("base_link_inertia", True), ("base_link", False)):
        placed = []
        for qi in q:
            urdf.update_cfg(dict(zip(robot.stack_names, qi)))
            placed.append(R @ urdf.get_transform("tool_point", link)[:3, 3] + t)
        gap = np.abs(np.array(placed) - robot.forward(q)).max()
        assert gap < 1e-9 if near else gap > 0.1
    assert main(["export", str(UR5_URDF), str(tmp_path / "u.urdf"), "--tip-link", "tool0", "--base-link",
                 "base_link", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["base_frame_link"] == "base_link"
