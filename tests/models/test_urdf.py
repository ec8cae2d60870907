"""URDF robots in, calibrated kinematics out (URDF, Universal Robots' kinematics file, kincal YAML)."""
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import DATA, PANDA_URDF, SOCKETS, UR5_COLS, UR5_URDF, central_jacobian

import yourdfpy  # an independent URDF parser, test-time only (the dev extra installs it)

import kincal
from kincal.analysis import stacked_jacobian
from kincal.cli import main


SMR = (0.0, 0.09e-3, 31.0e-3)  # the data set's reflector in the flange (tool0) frame, m
UNITS = ["--length-unit", "mm", "--angle-unit", "deg", "--joint-cols", ",".join(UR5_COLS)]

TESTBOT = """<?xml version="1.0"?>
<!-- fixed joints inside the chain, a continuous joint, a prismatic joint, tilted and negative axes -->
<robot name="testbot">
  <link name="world"/><link name="base"/><link name="l1"/><link name="l1b"/><link name="l2"/>
  <link name="l3"/><link name="l4"/><link name="tip"/><link name="camera"/>
  <joint name="mount" type="fixed"><parent link="world"/><child link="base"/>
    <origin xyz="0.1 0 0.05" rpy="0 0 0.3"/></joint>
  <joint name="j1" type="continuous"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/></joint>
  <joint name="bracket" type="fixed"><parent link="l1"/><child link="l1b"/>
    <origin xyz="0.05 0 0.1" rpy="0.2 -0.1 0"/></joint>
  <joint name="j2" type="revolute"><parent link="l1b"/><child link="l2"/>
    <origin xyz="0 0.1 0" rpy="1.5707963 0 0"/><axis xyz="0 0.6 0.8"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.4 0 0" rpy="0 0.3 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.3" effort="1" velocity="1"/></joint>
  <joint name="j4" type="revolute"><parent link="l3"/><child link="l4"/>
    <origin xyz="0.1 0 0.05"/><axis xyz="0 -1 0"/><limit lower="-2.5" upper="2.5" effort="1" velocity="1"/></joint>
  <joint name="j5" type="revolute"><parent link="l4"/><child link="tip"/>
    <origin xyz="0.08 0 0" rpy="0 1.2 0"/><axis xyz="1 0 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="cam" type="fixed"><parent link="l1"/><child link="camera"/><origin xyz="0 0 0.2"/></joint>
  <transmission name="t1"><type>SimpleTransmission</type></transmission>
</robot>
"""


@pytest.fixture(scope="module")
def ur5u():
    return kincal.load_robot(UR5_URDF, base_link="base_link", tip_link="tool0", tool=SMR)


@pytest.fixture(scope="module")
def testbot(tmp_path_factory):
    path = tmp_path_factory.mktemp("urdf") / "testbot.urdf"
    path.write_text(TESTBOT)
    return path, kincal.load_robot(path, tip_link="tip", tool=(0.02, 0.01, 0.05))


def reference(path, robot, q, tip):
    """Tool positions by yourdfpy (base frame of the model removed: its base is the chain's base)."""
    u = yourdfpy.URDF.load(str(path), load_meshes=False, build_collision_scene_graph=False)
    tool = np.append([robot.params[f"tool.{c}"] for c in "xyz"], 1.0)
    out = []
    for qi in q:
        u.update_cfg(dict(zip(robot.joint_names, qi)))
        out.append((u.get_transform(tip, robot.source.get("base_link", "base_link")) @ tool)[:3])
    return np.array(out)


def without_base(robot):
    return robot.with_params(dict.fromkeys(robot.base_params(), 0.0))


def test_ur5_urdf_equals_the_dh_model(ur5, ur5u):
    """base_link is the DH base turned 180° about z; tool0 is the DH flange; q_urdf = q_dh."""
    q = ur5.sample_joints(1000, seed=0)
    turned = ur5u.forward(q) * [-1.0, -1.0, 1.0]
    assert np.abs(turned - ur5.forward(q)).max() < 1e-9
    assert ur5u.joint_names[0] == "shoulder_pan_joint" and ur5u.n_params == 6 + 6 * 6 + 3


def test_jacobians_match_central_differences(ur5u, testbot):
    for robot in (kincal.perturb(ur5u, seed=3), kincal.perturb(testbot[1], seed=3)):
        q = robot.sample_joints(30, seed=1)
        J, Jn = robot.param_jacobian(q), central_jacobian(robot, q)
        assert np.abs(J - Jn).max() / np.abs(J).max() < 1e-6
        h, Jq = 1e-6, robot.joint_jacobian(q)
        Jqn = np.stack([(robot.forward(q + h * e) - robot.forward(q - h * e)) / (2 * h) for e in np.eye(robot.n_joints)],
                       axis=2)
        assert np.abs(Jq - Jqn).max() / np.abs(Jq).max() < 1e-6


def test_the_chain_is_read_as_written(testbot):
    path, robot = testbot
    assert robot.joint_names == ("j1", "j2", "slide", "j4", "j5")
    assert robot.joint_types == ("revolute", "revolute", "prismatic", "revolute", "revolute")
    assert np.isinf(robot.lower[0]) and robot.upper[2] == 0.3  # continuous = unlimited
    q = robot.sample_joints(200, seed=2)
    assert np.all(np.abs(q[:, 0]) <= np.pi)  # sampled within ±π when unlimited
    np.testing.assert_allclose(robot.forward(q), reference(path, robot, q, "tip"), atol=1e-12)


def test_kincal_yaml_round_trip_is_exact(ur5u, testbot, tmp_path):
    for robot in (kincal.perturb(ur5u, seed=5), kincal.perturb(testbot[1], seed=5, include_base=True)):
        path = tmp_path / f"{robot.name}.yaml"
        kincal.save_robot(robot, path)
        back = kincal.load_robot(path)
        assert back.params.names == robot.params.names and np.array_equal(back.params.values, robot.params.values)
        q = robot.sample_joints(50, seed=6)
        assert np.array_equal(back.forward(q), robot.forward(q))


def test_identifiability_as_for_dh(ur5, ur5u):
    q = ur5.sample_joints(100, seed=0)
    dh = kincal.analysis.free_parameters(ur5, q)
    urdf = kincal.analysis.free_parameters(ur5u, q)
    assert urdf.rank == dh.rank == 27
    # each dropped parameter is named with what it acts like
    assert urdf.confounds["shoulder_pan_joint.z"] == (("base.z", pytest.approx(1.0)),)


def test_real_ur5_grid_through_the_urdf(tmp_path, capsys):
    cal = tmp_path / "cal.yaml"
    flags = ["--base-link", "base_link", "--tip-link", "tool0", "--tool", ",".join(map(str, SMR))]
    assert main(["calibrate", str(UR5_URDF), str(DATA / "ur5_grid.csv"), *UNITS, *flags, "-o", str(cal)]) == 0
    text = capsys.readouterr().out
    assert "identifiable: 25 of 45 candidate parameters" in text and "shoulder_pan_joint.z  ~  +1·base.z" in text
    assert main(["evaluate", str(cal), str(DATA / "ur5_random.csv"), *UNITS, "--same-frame", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["mean"] == pytest.approx(0.1005e-3, abs=0.001e-3)


def test_exported_urdf_is_the_calibrated_model(ur5u, tmp_path, capsys):
    """Calibrated in simulation, exported, read by an independent parser: the same kinematics, the
    fitted tool point carried as a link (named, or 'tool_point' by default: never dropped); every
    line but the six joint origins and the added tool link is the original's."""
    true = kincal.perturb(ur5u, seed=11)
    res = kincal.calibrate(ur5u, kincal.simulate(true, ur5u.sample_joints(80, seed=11), 15e-6, seed=1))
    cal, out, plain = tmp_path / "cal.yaml", tmp_path / "cal.urdf", tmp_path / "plain.urdf"
    kincal.save_robot(res.robot, cal)
    assert main(["export", str(cal), str(out), "--tool-link", "smr", "--from", str(UR5_URDF)]) == 0
    assert main(["export", str(cal), str(plain), "--from", str(UR5_URDF)]) == 0
    capsys.readouterr()
    q = ur5u.sample_joints(100, seed=12)
    no_tool = without_base(res.robot).with_params({"tool.x": 0.0, "tool.y": 0.0, "tool.z": 0.0})
    np.testing.assert_allclose(reference(out, no_tool, q, "smr"), without_base(res.robot).forward(q), atol=1e-9)
    np.testing.assert_allclose(reference(plain, no_tool, q, "tool_point"), without_base(res.robot).forward(q), atol=1e-9)
    old, new = UR5_URDF.read_text().splitlines(), plain.read_text().splitlines()
    changed = [(a, b) for a, b in zip(old[:-1], new) if a != b]
    assert len(changed) == 6 and all("<origin" in a and "<origin" in b for a, b in changed)
    assert len(new) == len(old) + 6 and new[-7] == '  <link name="tool_point"/>' and new[-1] == old[-1]
    text = out.read_text()
    assert '<link name="smr"/>' in text and "<gazebo>" in text and "<transmission" in text and "<!-- measured" in text


def test_dh_robot_exports_to_urdf_and_ur_file(ur5, tmp_path, capsys):
    true = kincal.perturb(ur5, seed=13)
    res = kincal.calibrate(ur5, kincal.simulate(true, ur5.sample_joints(80, seed=13), 15e-6, seed=2))
    cal = tmp_path / "cal.yaml"
    kincal.save_robot(res.robot, cal)
    q = ur5.sample_joints(100, seed=14)
    model = without_base(res.robot).forward(q)
    # URDF, read by yourdfpy
    assert main(["export", str(cal), str(tmp_path / "cal.urdf"), "--tool-link", "smr"]) == 0
    capsys.readouterr()
    robot_for_ref = kincal.load_robot(tmp_path / "cal.urdf", base_link="base_link_inertia", tip_link="smr")
    np.testing.assert_allclose(reference(tmp_path / "cal.urdf", robot_for_ref, q, "smr"), model, atol=1e-9)
    # the root is ROS's base_link, the DH base turned 180° about z (as in UR's own URDF), and the joints
    # carry UR's names
    ros = kincal.load_robot(tmp_path / "cal.urdf", tip_link="smr")
    assert ros.joint_names == ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                               "wrist_2_joint", "wrist_3_joint")
    np.testing.assert_allclose(reference(tmp_path / "cal.urdf", ros, q, "smr"), model * [-1, -1, 1], atol=1e-9)
    # UR kinematics file, rebuilt by a few lines that follow the file format only
    assert main(["export", str(cal), str(tmp_path / "ur.yaml"), "--format", "ur", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    kin = yaml.safe_load((tmp_path / "ur.yaml").read_text())["kinematics"]
    assert kin["hash"].startswith("calib_") and list(kin)[:6] == ["shoulder", "upper_arm", "forearm", "wrist_1",
                                                                  "wrist_2", "wrist_3"]
    np.testing.assert_allclose(ur_file_forward(kin, q, info["tool_point"]), model, atol=1e-9)
    # the DH UR5's flange is UR's flange: the TCP is the tool point itself
    np.testing.assert_allclose(info["tool_point"], [res.robot.params[f"tool.{c}"] for c in "xyz"], atol=1e-12)


def ur_file_forward(kin, q, tcp):
    """UR's driver chain: per joint T(x, y, z) Rz(yaw) Ry(pitch) Rx(roll), then Rz(q); TCP in the last frame."""
    def rot(axis, a):
        c, s = np.cos(a), np.sin(a)
        i, j = [(1, 2), (2, 0), (0, 1)][axis]
        R = np.eye(4)
        R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
        return R
    out = []
    for qi in q:
        T = np.eye(4)
        for name, angle in zip(["shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"], qi):
            e = kin[name]
            M = np.eye(4)
            M[:3, 3] = [e["x"], e["y"], e["z"]]
            T = T @ M @ rot(2, e["yaw"]) @ rot(1, e["pitch"]) @ rot(0, e["roll"]) @ rot(2, angle)
        out.append((T @ np.append(tcp, 1.0))[:3])
    return np.array(out)


def test_complex_urdf_calibrates_to_the_cramer_rao_level(testbot, tmp_path):
    path, robot = testbot
    noise, rms, predicted = 15e-6, [], []
    for seed in range(20):
        true = kincal.perturb(robot, 0.5e-3, 2e-3, seed=100 + seed)
        q, qv = robot.sample_joints(60, seed=200 + seed), robot.sample_joints(200, seed=300 + seed)
        res = kincal.calibrate(robot, kincal.simulate(true, q, noise, seed=seed), base="fixed")
        assert res.converged and res.verdict.status == "good"
        rms.append(kincal.evaluate(res.robot, kincal.simulate(true, qv, 0.0)).rms)
        J, Jv = stacked_jacobian(res.robot, q, res.names), stacked_jacobian(res.robot, qv, res.names)
        predicted.append(noise * np.sqrt(np.trace(Jv @ np.linalg.inv(J.T @ J) @ Jv.T) / len(qv)))
    assert abs(np.mean(rms) / np.mean(predicted) - 1) < 0.10
    out = tmp_path / "cal.urdf"
    text = kincal.models.urdf_text(res.robot, path.read_text())
    out.write_text(text)
    q = robot.sample_joints(50, seed=7)
    no_tool = res.robot.with_params({"tool.x": 0.0, "tool.y": 0.0, "tool.z": 0.0})
    np.testing.assert_allclose(reference(out, no_tool, q, "tool_point"), res.robot.forward(q), atol=1e-9)
    assert text.count("<origin") == TESTBOT.count("<origin") + 1 and "camera" in text  # + the tool point's joint


BAD = {
    "not-xml": ("<robot><link name='a'>", "not valid XML"),
    "wrong-root": ("<model name='x'/>", "<model>"),
    "missing-link": ("<robot name='r'><link name='a'/><joint name='j' type='revolute'><parent link='a'/>"
                     "<child link='b'/><limit lower='-1' upper='1'/></joint></robot>", "joint 'j': child link 'b'"),
    "unknown-type": ("<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='spherical'>"
                     "<parent link='a'/><child link='b'/></joint></robot>", "joint 'j': unknown type 'spherical'"),
    "mimic": ("<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='revolute'><parent link='a'/>"
              "<child link='b'/><limit lower='-1' upper='1'/><mimic joint='k'/></joint></robot>", "'j' is a mimic"),
    "non-numeric-origin": ("<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='revolute'>"
                           "<parent link='a'/><child link='b'/><origin xyz='0 zero 0'/><limit lower='-1' upper='1'/>"
                           "</joint></robot>", "joint 'j': origin xyz='0 zero 0'"),
    "closed-loop": ("<robot name='r'><link name='a'/><link name='b'/><link name='c'/>"
                    "<joint name='j1' type='fixed'><parent link='a'/><child link='b'/></joint>"
                    "<joint name='j2' type='fixed'><parent link='c'/><child link='b'/></joint></robot>",
                    "closed loops"),
    "no-limit": ("<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='revolute'><parent link='a'/>"
                 "<child link='b'/></joint></robot>", "joint 'j': a revolute joint needs <limit"),
    "floating-in-chain": ("<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='floating'>"
                          "<parent link='a'/><child link='b'/></joint></robot>", "'j' is floating"),
    "no-moving-joint": ("<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='fixed'>"
                        "<parent link='a'/><child link='b'/></joint></robot>", "no moving joint"),
    "zero-axis": ("<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='revolute'><parent link='a'/>"
                  "<child link='b'/><axis xyz='0 0 0'/><limit lower='-1' upper='1'/></joint></robot>", "axis"),
    # xacro, by any of ROS's namespace URIs, undeclared, or by its ${...} expressions alone (it said "0 root links",
    # "child link 'base_link' is not defined" or "origin xyz='0 0 ${h}' is not 3 number(s)")
    "xacro-wiki-ns": ("<robot xmlns:xacro='http://wiki.ros.org/xacro' name='r'><xacro:include filename='ur.xacro'/>"
                      "<xacro:ur_robot prefix=''/></robot>", "a xacro file (<xacro:include>"),
    "xacro-undeclared": ("<robot name='r'><link name='world'/><xacro:ur_robot prefix=''/></robot>",
                         "a xacro file (<xacro:ur_robot>"),
    "xacro-expression": ("<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='revolute'>"
                         "<parent link='a'/><child link='b'/><origin xyz='0 0 ${h}'/><limit lower='-1' upper='1'/>"
                         "</joint></robot>", "a xacro file (<origin xyz='0 0 ${h}'>"),
    "dot-in-name": ("<robot name='r'><link name='a'/><link name='b'/><joint name='j.1' type='revolute'>"
                    "<parent link='a'/><child link='b'/><limit lower='-1' upper='1'/></joint></robot>", "'j.1'"),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_urdf_one_line_error(name, tmp_path, capsys):
    text, words = BAD[name]
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    assert main(["show", str(path)]) == 1
    err = capsys.readouterr().err
    assert words in err and "bad.urdf" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("old, new, words", [
    ('rpy="0.0 1.57079632679 0.0" xyz="0.0 0.13585 0.0"', 'rpy="0.0 90 0.0" xyz="0.0 0.13585 0.0"',
     f"joint 'shoulder_lift_joint': origin rpy='0 90 0' turns 90 rad (14.3 turns) about one axis; no origin turns "
     f"beyond 1.25 turns: the angles look like degrees; URDF angles are in radians: write rpy='0 "
     f"{np.pi / 2:.6g} 0'"),
    ('lower="-6.28318530718" upper="6.28318530718"', 'lower="-360" upper="360"',
     f"joint shoulder_pan_joint's limits [-360, 360] rad reach {360 / (2 * np.pi):.3g} turns from zero; no revolute "
     f"joint turns more than 2 turns each way: the limits look like degrees; URDF angles are in radians: write them "
     f"in rad ([{-2 * np.pi:.6g}, {2 * np.pi:.6g}])"),
], ids=["rpy", "limits"])
def test_degrees_in_a_urdf_are_refused_naming_the_joint(old, new, words, tmp_path, capsys):
    """UR's UR5 URDF with one rpy or every limit in degrees (it was read as 90 rad, ±360 rad = ±20626.5 deg, without
    a word, and calibrate blamed the length scale): refused, naming the joint and the radians meant."""
    path = tmp_path / "ur5_deg.urdf"
    assert old in UR5_URDF.read_text()
    path.write_text(UR5_URDF.read_text().replace(old, new))
    assert main(["show", str(path), "--tip-link", "tool0"]) == 1
    err = capsys.readouterr().err
    assert f"{path}: {words}" in err and len(err.strip().splitlines()) == 1


def test_real_urdfs_angles_are_read(tmp_path):
    """Angles real URDFs write stay readable: a continuous joint (no limits), a limit of ±9.25 rad (TIAGo's hand),
    ±2π (UR) and an rpy of 3π/2 (TALOS's wrist); the chain is the one yourdfpy reads."""
    text = (TESTBOT.replace('lower="-2.5" upper="2.5"', 'lower="-9.25" upper="9.25"')
            .replace('lower="-3" upper="3"', f'lower="{-2 * np.pi!r}" upper="{2 * np.pi!r}"')
            .replace('rpy="0.2 -0.1 0"', f'rpy="0.2 -0.1 {3 * np.pi / 2!r}"'))
    assert "9.25" in text and repr(3 * np.pi / 2) in text and repr(2 * np.pi) in text
    path = tmp_path / "angles.urdf"
    path.write_text(text)
    robot = kincal.load_robot(path, tip_link="tip", tool=(0.02, 0.01, 0.05))
    assert robot.joint_types[0] == "revolute" and np.isinf(robot.upper[0]) and robot.upper[3] == 9.25
    q = robot.sample_joints(5, seed=4)
    np.testing.assert_allclose(reference(path, without_base(robot), q, "tip"), robot.forward(q), atol=1e-12)


def test_non_unit_axes_are_noted_and_exported_as_unit_vectors(tmp_path, capsys):
    """Axes `1 2 2` (prismatic) and `1 1 1`: kincal reads their directions, as the URDF specification means, names
    the joints in a note, and the exported URDF holds the unit vectors (1, 2, 2)/3 and (1, 1, 1)/√3, so yourdfpy,
    which does not normalise a prismatic axis, reads the model (it read the exported file 0.3+ m off, the source's
    vectors kept)."""
    text = TESTBOT.replace('<axis xyz="1 0 0"/>\n    <limit lower="0"', '<axis xyz="1 2 2"/>\n    <limit lower="0"')
    text = text.replace('<axis xyz="0 -1 0"/>', '<axis xyz="1 1 1"/>')
    assert text.count('"1 2 2"') == 1 and text.count('"1 1 1"') == 1
    path = tmp_path / "axes.urdf"
    path.write_text(text)
    robot = kincal.load_robot(path, tip_link="tip", tool=(0.02, 0.01, 0.05))
    notes = robot.structure_notes()
    assert [n.split(":")[0] for n in notes] == ["joint 'slide'", "joint 'j4'"]
    assert "length 3)" in notes[0] and "yourdfpy: 3 times as far" in notes[0] and "length 1.73205)" in notes[1]
    assert main(["show", str(path), "--tip-link", "tip"]) == 0 and "note: joint 'slide'" in capsys.readouterr().out
    out = tmp_path / "out.urdf"
    kincal.export_robot(robot, out, tool_link="tool_point")
    axes = yourdfpy.URDF.load(str(out), load_meshes=False, build_collision_scene_graph=False).joint_map
    np.testing.assert_allclose(axes["slide"].axis, np.array([1.0, 2.0, 2.0]) / 3.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(axes["j4"].axis, np.ones(3) / np.sqrt(3.0), rtol=0, atol=1e-15)
    q = robot.sample_joints(20, seed=5)
    no_tool = without_base(robot).with_params({"tool.x": 0.0, "tool.y": 0.0, "tool.z": 0.0})
    np.testing.assert_allclose(reference(out, no_tool, q, "tool_point"), without_base(robot).forward(q), atol=1e-9)
    assert kincal.load_robot(out, tip_link="tool_point").structure_notes() == []


@pytest.mark.parametrize("flags, words", [
    (["--tool-link", "bad name<"], "tool link name 'bad name<' (--tool-link): a URDF name here holds no whitespace "
                                   "and none of < > & \" ' . (it has ' ', '<')"),
    (["--tool-link", "smr.1"], "tool link name 'smr.1' (--tool-link)"),  # its joint 'tool0-smr.1' would hold a dot
    (["--joint-names", "j1,j2,j3,j4,j5,a&b"], "joint name 'a&b' (--joint-names)"),
])
def test_a_name_a_urdf_cannot_hold_is_refused_naming_the_argument(flags, words, tmp_path, capsys):
    """A tool link or joint name that is no URDF name: refused naming the argument, nothing written (it said
    "exported URDF: not valid XML (line 337, column 22)")."""
    assert main(["export", "ur5", str(tmp_path / "ur5.urdf"), *flags]) == 1
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1 and not list(tmp_path.iterdir())


def test_a_urdf_that_xacro_wrote_is_read(tmp_path):
    """A URDF that xacro wrote keeps its root's xmlns:xacro, unused: read as a URDF, the chain yourdfpy reads."""
    path = tmp_path / "arm.urdf"
    path.write_text(TESTBOT.replace('<robot name="testbot">', '<robot name="testbot" '
                                    'xmlns:xacro="http://www.ros.org/wiki/xacro">'))
    robot = kincal.load_robot(path, tip_link="tip", tool=(0.02, 0.01, 0.05))
    q = robot.sample_joints(5, seed=2)
    np.testing.assert_allclose(reference(path, without_base(robot), q, "tip"), robot.forward(q), atol=1e-12)


@pytest.mark.parametrize("flags, words, expected", [  # 1: refused by the URDF reader, 2: by argparse
    (["--tip-link", "nowhere"], "tip_link 'nowhere' is not a link", 1),
    (["--base-link", "tool0", "--tip-link", "base_link"], "broken chain", 1),
    ([], "several end links", 1),
    (["--tip-link", "tool0", "--tool", "1,2"], "three", 2),
])
def test_chain_choice_errors(flags, words, expected, capsys):
    code = None
    try:
        code = main(["show", str(UR5_URDF), *flags])
    except SystemExit as exc:  # argparse
        code = exc.code
    err = capsys.readouterr().err
    assert code == expected and words in err and "Traceback" not in err


def test_export_refuses_what_it_cannot_write(tmp_path, capsys):
    assert main(["export", "guo3t2r", str(tmp_path / "g.urdf")]) == 1
    assert "not a serial chain" in capsys.readouterr().err
    assert main(["export", "wam", str(tmp_path / "w.yaml"), "--format", "ur"]) == 1
    assert "6 revolute joints" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("convention", ["dh", "mdh"])
def test_random_dh_and_mdh_chains_export(convention, tmp_path):
    """Random chains with a prismatic joint and β: the new URDF, read by yourdfpy, is the model."""
    from test_models import random_robot

    robot = random_robot(convention, 4)
    path = tmp_path / "r.urdf"
    path.write_text(kincal.models.urdf_text(robot, tool_link="tcp"))
    ref = kincal.load_robot(path, tip_link="tcp")
    q = robot.sample_joints(50, seed=3)
    np.testing.assert_allclose(reference(path, ref, q, "tcp"), without_base(robot).forward(q), atol=1e-9)
    assert "prismatic" in path.read_text()


FIXED_ROW = """name: fixedrow
convention: dh
units: {length: mm, angle: deg}
joints:
  - {name: j1, type: revolute, theta: 10, d: 300, a: 50, alpha: 90, limits: [-170, 170], velocity: 90, effort: 40}
  - {name: plate, type: fixed, theta: 30, d: 40, a: 120, alpha: -20}
  - {name: j2, type: prismatic, theta: 0, d: 100, a: 20, alpha: 0, limits: [0, 400], velocity: 250, effort: 300}
  - {name: j3, type: revolute, theta: 0, d: 10, a: 200, alpha: 0, limits: [-120, 120], velocity: 180, effort: 12}
  - {name: tcp, type: fixed, theta: 0, d: 80, a: 30, alpha: 0}
tool: {x: 5, y: 0, z: 0}
"""


def dh_matrix(theta, d, a, alpha):
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])


def test_fixed_rows_are_dh_rows_without_a_joint(tmp_path, capsys):
    """A fixed row (a DH row with no joint variable, such as seed 1's A5 tool row) composes as its
    matrix; it has parameters but no joint, round-trips through YAML and exports to URDF."""
    (tmp_path / "f.yaml").write_text(FIXED_ROW)
    robot = kincal.perturb(kincal.load_robot(tmp_path / "f.yaml"), 1e-3, 1e-3, seed=3)
    assert robot.joint_names == ("j1", "j2", "j3") and "plate.a" in robot.params and "tcp.alpha" in robot.params
    q = robot.sample_joints(20, seed=4)
    v = robot.params.as_dict()
    rows = [(n, t) for n, t in (("j1", "r"), ("plate", "f"), ("j2", "p"), ("j3", "r"), ("tcp", "f"))]
    expected = []
    for qi in q:
        T, k = np.eye(4), 0
        for name, t in rows:
            th, d = v[f"{name}.theta"], v[f"{name}.d"]
            if t != "f":
                th, d, k = (th + qi[k], d, k + 1) if t == "r" else (th, d + qi[k], k + 1)
            T = T @ dh_matrix(th, d, v[f"{name}.a"], v[f"{name}.alpha"])
        expected.append((T @ np.append([v["tool.x"], v["tool.y"], v["tool.z"]], 1.0))[:3])
    np.testing.assert_allclose(without_base(robot).forward(q), expected, atol=1e-12)
    kincal.save_robot(robot, tmp_path / "g.yaml", "mm", "deg")
    assert "{name: tcp, type: fixed" in (tmp_path / "g.yaml").read_text()
    back = kincal.load_robot(tmp_path / "g.yaml")
    np.testing.assert_allclose(back.forward(q), robot.forward(q), atol=1e-12)
    assert main(["export", str(tmp_path / "g.yaml"), str(tmp_path / "g.urdf"), "--tool-link", "tool"]) == 0
    capsys.readouterr()
    ref_robot = kincal.load_robot(tmp_path / "g.urdf", tip_link="tool")
    np.testing.assert_allclose(reference(tmp_path / "g.urdf", ref_robot, q, "tool"), without_base(robot).forward(q),
                               atol=1e-9)
    (tmp_path / "h.yaml").write_text(FIXED_ROW.replace("alpha: -20}", "alpha: -20, limits: [0, 1]}"))
    with pytest.raises(kincal.ModelError, match="fixed row has no joint"):
        kincal.load_robot(tmp_path / "h.yaml")


def test_a_socket_calibration_exports_the_fitted_ball(tmp_path, capsys):
    """Panda sockets (one plate placement) calibrated, then exported as URDF: the fitted ball point,
    millimetres from ball_link's origin, is the link 'tool_point'; an independent parser of the file
    reproduces the calibrated ball within 1e-9 m at random joints."""
    import csv as _csv

    rows = [r for r in _csv.DictReader(open(SOCKETS / "samples.csv"))
            if r["placement"] == "front_center"]
    with open(tmp_path / "train.csv", "w", newline="") as f:
        w = _csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    assert main(["calibrate", str(PANDA_URDF), str(tmp_path / "train.csv"),
                 "--tip-link", "ball_link", "--type", "same-point", "--joint-cols", ",".join(f"q{k}" for k in range(1, 8)),
                 "--label-col", "socket", "--group-col", "placement", "--distance", "0,1,50", "--length-unit", "mm",
                 "-o", str(tmp_path / "cal.yaml")]) == 0
    assert main(["export", str(tmp_path / "cal.yaml"), str(tmp_path / "cal.urdf")]) == 0
    said = capsys.readouterr().out  # sockets see no measurement frame: none is reported (it printed six zeros)
    assert "is the fixed link 'tool_point'" in said and "base frame found" not in said
    cal = kincal.load_robot(str(tmp_path / "cal.yaml"))
    assert np.linalg.norm(cal.tool_point()) > 1e-3  # the ball moved: dropping it would miss by millimetres
    q = cal.sample_joints(30, seed=4)
    no_tool = cal.with_params({"tool.x": 0.0, "tool.y": 0.0, "tool.z": 0.0})
    np.testing.assert_allclose(reference(tmp_path / "cal.urdf", no_tool, q, "tool_point"),
                               without_base(cal).forward(q), atol=1e-9)


UR10_KINEMATICS = {  # UR's ROS 2 description, config/ur10/default_kinematics.yaml: x y z (m), roll pitch yaw (rad)
    "shoulder_pan_joint": ((0, 0, 0.1273), (0, 0, 0)),
    "shoulder_lift_joint": ((0, 0, 0), (1.570796327, 0, 0)),
    "elbow_joint": ((-0.612, 0, 0), (0, 0, 0)),
    "wrist_1_joint": ((-0.5723, 0, 0.163941), (0, 0, 0)),
    "wrist_2_joint": ((0, -0.1157, -2.373046667922381e-11), (1.570796327, 0, 0)),
    "wrist_3_joint": ((0, 0.0922, -1.891053610911353e-11), (1.570796326589793, 3.141592653589793, 3.141592653589793)),
}


def _ur_description(kinematics: dict) -> str:
    """UR's description chain as its ur_macro.xacro writes it (base_link, base_link_inertia turned by π,
    the six joints at the kinematics' origins, wrist_3 → flange → tool0, base_link → base)."""
    pi = np.pi
    def fixed(parent, child, rpy):
        return (f'<link name="{child}"/><joint name="{parent}-{child}" type="fixed"><parent link="{parent}"/>'
                f'<child link="{child}"/><origin xyz="0 0 0" rpy="{" ".join(map(repr, rpy))}"/></joint>')
    parts = ['<robot name="ur10_reference">', '<link name="base_link"/>', fixed("base_link", "base_link_inertia",
                                                                              (0, 0, pi))]
    parent = "base_link_inertia"
    for joint, link in zip(kinematics, ("shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
                                        "wrist_2_link", "wrist_3_link")):
        xyz, rpy = kinematics[joint]
        parts.append(f'<link name="{link}"/><joint name="{joint}" type="revolute"><parent link="{parent}"/>'
                     f'<child link="{link}"/><origin xyz="{" ".join(map(repr, xyz))}" rpy="{" ".join(map(repr, rpy))}"/>'
                     f'<axis xyz="0 0 1"/><limit lower="-6.28" upper="6.28" effort="1" velocity="1"/></joint>')
        parent = link
    parts += [fixed("wrist_3_link", "flange", (0, -pi / 2, -pi / 2)), fixed("flange", "tool0", (pi / 2, 0, pi / 2)),
              fixed("base_link", "base", (0, 0, pi)), "</robot>"]
    return "".join(parts)


def test_the_ur10_urdf_has_urs_own_link_frames(tmp_path, capsys):
    """kincal export ur10 → URDF: every link of UR's description (base, base_link_inertia, shoulder_link …
    wrist_3_link, flange, tool0) sits where UR's own description chain (its ur_macro.xacro with the UR10's
    default kinematics) puts it, within 1e-9 m and 1e-9 rad at random joints; both read by yourdfpy."""
    assert main(["export", "ur10", str(tmp_path / "ur10.urdf")]) == 0
    capsys.readouterr()
    (tmp_path / "ref.urdf").write_text(_ur_description(UR10_KINEMATICS))
    ours = yourdfpy.URDF.load(str(tmp_path / "ur10.urdf"), load_meshes=False, build_collision_scene_graph=False)
    theirs = yourdfpy.URDF.load(str(tmp_path / "ref.urdf"), load_meshes=False, build_collision_scene_graph=False)
    links = ("base", "base_link_inertia", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
             "wrist_2_link", "wrist_3_link", "flange", "tool0")
    for qi in kincal.load_robot("ur10").sample_joints(20, seed=3):
        cfg = dict(zip(UR10_KINEMATICS, qi))
        ours.update_cfg(cfg)
        theirs.update_cfg(cfg)
        for link in links:
            np.testing.assert_allclose(ours.get_transform(link, "base_link"), theirs.get_transform(link, "base_link"),
                                       atol=1e-9, err_msg=link)


def test_the_ur10_calibration_file_has_urs_default_kinematics(tmp_path, capsys):
    """kincal export ur10 --format ur on the nominal UR10: the transforms of UR's own default_kinematics.yaml —
    each joint origin within 1e-9 m, its rotation within 1e-9 — but not its entries: wrist_3 is written roll
    -π/2, pitch 0, yaw 0 for UR's π/2, π, π, as docs/howto/export.md says."""
    from kincal.models.urdf import rpy_matrix

    assert main(["export", "ur10", str(tmp_path / "ur.yaml"), "--format", "ur"]) == 0
    capsys.readouterr()
    kin = yaml.safe_load((tmp_path / "ur.yaml").read_text())["kinematics"]
    for (joint, (xyz, rpy)), entry in zip(UR10_KINEMATICS.items(), ("shoulder", "upper_arm", "forearm", "wrist_1",
                                                                     "wrist_2", "wrist_3")):
        got = kin[entry]
        np.testing.assert_allclose([got["x"], got["y"], got["z"]], xyz, atol=1e-9, err_msg=joint)
        np.testing.assert_allclose(rpy_matrix(got["roll"], got["pitch"], got["yaw"]), rpy_matrix(*rpy), atol=1e-9,
                                   err_msg=joint)
    np.testing.assert_allclose([kin["wrist_3"][k] for k in ("roll", "pitch", "yaw")], [-np.pi / 2, 0.0, 0.0],
                               atol=1e-12)
    docs = " ".join((Path(__file__).parents[2] / "docs" / "howto" / "export.md").read_text().split())
    assert "wrist_3 comes out roll −π/2, pitch 0, yaw 0, UR's file has π/2, π, π" in docs


def test_a_tool_declared_in_another_links_axes_is_suspect(capsys):
    """The UR5 URDF calibrated at ee_link (turned 90° from tool0, the frame the reflector's 31 mm was declared in):
    the fitted point is as far out, along another axis, 46 mm from the declared one, under the 50 mm mounting limit;
    it was GOOD, now suspect naming --tip-link. At tool0 the same data are good."""
    grid = kincal.read_measurements(DATA / "ur5_grid.csv", kincal.load_robot(UR5_URDF, tip_link="tool0"), UR5_COLS,
                                    length_unit="mm", angle_unit="deg")
    for tip, status in (("ee_link", "suspect"), ("tool0", "good")):
        robot = kincal.load_robot(UR5_URDF, tip_link=tip).with_tool_point([0.0, 0.09e-3, 0.031])
        res = kincal.calibrate(robot, kincal.Measurements(grid.q, grid.xyz, robot.joint_names, "ur5_grid.csv"))
        said = " ".join(r.message for r in res.verdict.reasons)
        assert res.verdict.status == status and (("turned 90°" in said and "--tip-link" in said) == (tip == "ee_link"))


def test_a_urdf_needs_every_joints_velocity_and_effort(tmp_path, capsys):
    """ROS's URDF parser refuses a <limit> without effort and velocity: a DH file that does not give them for a
    joint is refused before anything is written, naming the joint; given, they are written in SI (90 deg/s is
    1.5708 rad/s, 250 mm/s is 0.25 m/s)."""
    import xml.etree.ElementTree as ET

    (tmp_path / "f.yaml").write_text(FIXED_ROW.replace(", velocity: 180, effort: 12", ""))
    assert main(["export", str(tmp_path / "f.yaml"), str(tmp_path / "f.urdf")]) == 1
    said = capsys.readouterr().err
    assert "gives none for j3: add 'velocity:'" in said and not (tmp_path / "f.urdf").exists()
    (tmp_path / "g.yaml").write_text(FIXED_ROW)
    assert main(["export", str(tmp_path / "g.yaml"), str(tmp_path / "g.urdf")]) == 0
    limits = {j.get("name"): j.find("limit").attrib for j in ET.parse(tmp_path / "g.urdf").getroot().iter("joint")
              if j.find("limit") is not None}
    assert float(limits["j1"]["velocity"]) == pytest.approx(np.pi / 2) and float(limits["j1"]["effort"]) == 40
    assert float(limits["j2"]["velocity"]) == pytest.approx(0.25) and float(limits["j2"]["effort"]) == 300
    docs = " ".join((Path(__file__).parents[2] / "docs" / "reference" / "formats.md").read_text().split())
    assert "refuses a file that lacks them for a moving joint" in docs and "leaves them out" not in docs



def test_the_ur5_urdf_exports_urs_layout_in_urs_base(tmp_path, capsys):
    """The UR5 read from ur_description's URDF (base_link, joint origins 136 mm along the shoulder's axis from UR's
    layout) exports the same UR kinematics file as kincal's DH ur5 (UR's default layout, the UR10 test's reference),
    entry by entry within 1e-9, in UR's Base: its link 'base' (base_link turned 180°) found without --base-yaw; a
    --base-yaw that disagrees is refused. Calibrated from the same measurements, the URDF and the DH robot give the
    same frames-only correction for the controller."""
    from kincal.models.urdf import rpy_matrix

    files = {}
    for name, robot in (("dh", ["ur5"]), ("urdf", [str(UR5_URDF), "--base-link", "base_link", "--tip-link", "tool0"])):
        assert main(["export", *robot, str(tmp_path / f"{name}.yaml"), "--format", "ur"]) == 0
        files[name] = yaml.safe_load((tmp_path / f"{name}.yaml").read_text())["kinematics"]
    for entry in ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"):
        a, b = files["dh"][entry], files["urdf"][entry]
        np.testing.assert_allclose([b[k] for k in "xyz"], [a[k] for k in "xyz"], atol=1e-9, err_msg=entry)
        np.testing.assert_allclose(rpy_matrix(b["roll"], b["pitch"], b["yaw"]), rpy_matrix(a["roll"], a["pitch"],
                                                                                             a["yaw"]), atol=1e-9)
    assert main(["export", str(UR5_URDF), str(tmp_path / "x.yaml"), "--format", "ur", "--base-link", "base_link",
                 "--tip-link", "tool0", "--base-yaw", "0"]) == 1
    assert "turned 180.000° about z from base_link; --base-yaw 0.000 disagrees" in capsys.readouterr().err
    dh = kincal.load_robot("ur5").with_tool_point([0.0, 0.0, 0.05])
    urdf = kincal.load_robot(UR5_URDF, base_link="base_link", tip_link="tool0").with_tool_point([0.0, 0.0, 0.05])
    q = dh.sample_joints(60, seed=5)
    true = kincal.perturb(dh, seed=5)
    meas = kincal.simulate(true.with_params({"base.x": 1.5, "base.rz": 0.4}), q, noise=0.0)  # the tracker's frame
    bases = []
    for name, robot in (("dh", dh), ("urdf", urdf)):
        res = kincal.calibrate(robot, kincal.Measurements(q, meas.xyz, robot.joint_names))
        kincal.save_robot(res.robot, tmp_path / f"{name}_cal.yaml", calibration=res.record())
        assert main(["export", str(tmp_path / f"{name}_cal.yaml"), str(tmp_path / f"{name}.script"), "--format",
                     "frames-urscript", "--json"]) == 0
        bases.append(np.array(json.loads(capsys.readouterr().out)["written_base"]))
    np.testing.assert_allclose(bases[1], bases[0], atol=1e-7)


UR_TOOL0_IN_WRIST_3 = (0.0, -np.pi / 2, -np.pi / 2), (np.pi / 2, 0.0, np.pi / 2)  # ur_description: flange, tool0 rpy


@pytest.mark.parametrize("base_link", [None, "base_link"])
def test_the_ur_file_of_a_urdf_is_in_urs_base_whatever_the_chains_base_link(base_link, tmp_path, capsys):
    """The UR5 URDF's chain from its root 'world' (world -> base_link -> base: link 'base' two fixed joints away) or
    from base_link: the written file, rebuilt by UR's rules (ur_file_forward, then ur_description's wrist_3 ->
    flange -> tool0, the identity), is the model in UR's Base, base_link turned 180° about z: x and y negated, within
    1e-9 m. It was 1.668 m off from 'world', with every x and y negated, and the check passed."""
    from kincal.models.urdf import rpy_matrix

    nominal = kincal.load_robot(UR5_URDF, base_link=base_link, tip_link="tool0", tool=SMR)
    true = kincal.perturb(kincal.load_robot(UR5_URDF, base_link="base_link", tip_link="tool0", tool=SMR), seed=21)
    robot = nominal.with_params({n: v for n, v in true.params.as_dict().items() if not n.startswith("base.")})
    kincal.save_robot(robot, tmp_path / "cal.yaml")
    assert main(["export", str(tmp_path / "cal.yaml"), str(tmp_path / "ur.yaml"), "--format", "ur"]) == 0
    kin = yaml.safe_load((tmp_path / "ur.yaml").read_text())["kinematics"]
    tcp = rpy_matrix(*UR_TOOL0_IN_WRIST_3[0]) @ rpy_matrix(*UR_TOOL0_IN_WRIST_3[1]) @ robot.tool_point()
    q = robot.sample_joints(40, seed=22)
    np.testing.assert_allclose(ur_file_forward(kin, q, tcp), robot.forward(q) * [-1, -1, 1], atol=1e-9)


def test_urs_base_is_found_through_fixed_joints_or_refused(tmp_path, capsys):
    """The link 'base' composed along fixed joints (a mounted world joint, then base_link's 180° turn: the pose by
    hand); a moving joint between refused by name; a URDF without link 'base' gets no guessed turn of 0: --base-yaw
    is asked for. A turn given beside the Base the description places is refused."""
    from kincal.models.export import ur_calibration
    from kincal.models.urdf import fixed_frame, rpy_matrix

    text = UR5_URDF.read_text().replace('<origin rpy="0.0 0.0 0.0" xyz="0.0 0.0 0.0"/>\n  </joint>\n</robot>',
                                        '<origin rpy="0 0 0.5" xyz="0.1 0.2 0.3"/>\n  </joint>\n</robot>')
    want = np.eye(4)
    want[:3, :3], want[:3, 3] = rpy_matrix(0.0, 0.0, 0.5) @ rpy_matrix(0.0, 0.0, -3.14159265359), [0.1, 0.2, 0.3]
    np.testing.assert_allclose(fixed_frame(text, "world", "base"), want, atol=1e-15)
    np.testing.assert_allclose(fixed_frame(text, "base", "world"), np.linalg.inv(want), atol=1e-15)
    with pytest.raises(kincal.ModelError, match="joint 'wrist_3_joint' \\(revolute\\) lies between"):
        fixed_frame(text, "tool0", "base")
    assert fixed_frame(text, "world", "no_such_link") is None
    bare = UR5_URDF.read_text().replace('<link name="base">', '<link name="base_x">').replace(
        '<child link="base"/>', '<child link="base_x"/>')
    (tmp_path / "bare.urdf").write_text(bare)
    flags = ["--base-link", "base_link", "--tip-link", "tool0"]
    assert main(["export", str(tmp_path / "bare.urdf"), str(tmp_path / "u.yaml"), "--format", "ur", *flags]) == 1
    assert "no link 'base' (UR's Base" in capsys.readouterr().err and not (tmp_path / "u.yaml").exists()
    assert main(["export", str(tmp_path / "bare.urdf"), str(tmp_path / "u.yaml"), "--format", "ur", *flags,
                 "--base-yaw", "180"]) == 0
    robot = kincal.load_robot(UR5_URDF, base_link="base_link", tip_link="tool0")
    with pytest.raises(kincal.ModelError, match="not both"):
        ur_calibration(robot, 0.0, driver_base=fixed_frame(UR5_URDF.read_text(), "base_link", "base"))


def test_the_source_urdf_is_the_calibrated_files_and_checked(tmp_path, monkeypatch, capsys):
    """A robot calibrated from 'mine.urdf' in its folder, exported from a sub-folder holding another mine.urdf
    (another robot's name, elbow limits ±1 rad): the export edits the calibrated file's (name 'ur5', elbow ±π, as
    the URDF says), resolved beside the robot file (saved elsewhere: '../mine.urdf'); the other one given as --from
    is refused naming both files and what differs, an old robot file (no sha256) too; the source changed after the
    calibration is refused unless given with --from."""
    import xml.etree.ElementTree as ET

    text = UR5_URDF.read_text()
    (tmp_path / "sub").mkdir()
    (tmp_path / "mine.urdf").write_text(text)
    (tmp_path / "sub" / "mine.urdf").write_text(text.replace('name="ur5"', 'name="cell7"').replace(
        'lower="-3.14159265359" upper="3.14159265359"', 'lower="-1.0" upper="1.0"'))
    monkeypatch.chdir(tmp_path)
    kincal.save_robot(kincal.load_robot("mine.urdf", tip_link="tool0"), "cal.yaml")
    kincal.save_robot(kincal.load_robot("mine.urdf", tip_link="tool0"), "sub/cal.yaml")
    assert 'file: "../mine.urdf"' in (tmp_path / "sub" / "cal.yaml").read_text()
    monkeypatch.chdir(tmp_path / "sub")
    for cal in ("../cal.yaml", "cal.yaml"):
        assert main(["export", cal, "out.urdf"]) == 0
        root = ET.parse("out.urdf").getroot()
        elbow = [j for j in root.findall("joint") if j.get("name") == "elbow_joint"][0].find("limit")
        assert root.get("name") == "ur5" and float(elbow.get("upper")) == pytest.approx(np.pi, abs=1e-10)
    capsys.readouterr()
    assert main(["export", "../cal.yaml", "out2.urdf", "--from", "mine.urdf"]) == 1
    said = capsys.readouterr().err
    assert said.startswith("kincal: error: mine.urdf: not the URDF robot 'ur5' was calibrated from (../mine.urdf)")
    assert "the robot is 'cell7', not 'ur5'" in said and "'elbow_joint' has limits [-1, 1]" in said
    old = "\n".join(line.split(", sha256")[0] + "}" if line.startswith("source:") else line
                    for line in (tmp_path / "cal.yaml").read_text().splitlines())
    (tmp_path / "old.yaml").write_text(old)
    assert main(["export", "../old.yaml", "out2.urdf", "--from", "mine.urdf"]) == 1
    assert "not the URDF robot 'ur5' was calibrated from" in capsys.readouterr().err
    assert not (tmp_path / "sub" / "out2.urdf").exists()
    assert main(["export", "../old.yaml", "out2.urdf"]) == 0
    (tmp_path / "mine.urdf").write_text(text + "<!-- edited -->\n")
    assert main(["export", "../cal.yaml", "out3.urdf"]) == 1
    assert "../mine.urdf: changed since robot 'ur5' was calibrated from it" in capsys.readouterr().err
    assert main(["export", "../cal.yaml", "out3.urdf", "--from", "../mine.urdf"]) == 0


def test_the_urdf_edit_changes_the_robots_joints_whatever_comes_first(ur5u, tmp_path, capsys):
    """ur_description's UR5 with its <transmission> blocks (each names a <joint>) before the joints, and the elbow's
    origin written <origin ...></origin>: the export edits the robot's own joints, one <origin> each, the
    transmissions unchanged, and the file read by yourdfpy is the calibrated model within 1e-9 m (it was refused:
    'would place the tool 4.05 mm', and the open origin came out twice)."""
    import re
    import xml.etree.ElementTree as ET

    text = UR5_URDF.read_text()
    blocks = re.findall(r"  <transmission.*?</transmission>\n", text, re.S)
    for block in blocks:
        text = text.replace(block, "")
    at = text.index('  <link name="base_link">')
    text = text[:at] + "".join(blocks) + text[at:]
    text = text.replace('xyz="0.0 -0.1197 0.425"/>', 'xyz="0.0 -0.1197 0.425">\n    </origin>')
    (tmp_path / "arm.urdf").write_text(text)
    robot = kincal.perturb(kincal.load_robot(tmp_path / "arm.urdf", base_link="base_link", tip_link="tool0",
                                             tool=SMR), seed=31)
    kincal.save_robot(robot, tmp_path / "cal.yaml")
    assert main(["export", str(tmp_path / "cal.yaml"), str(tmp_path / "out.urdf")]) == 0
    out = (tmp_path / "out.urdf").read_text()
    assert len(blocks) == 6 and out.index("".join(blocks)) == at
    joints = {j.get("name"): len(j.findall("origin")) for j in ET.fromstring(out).findall("joint")}
    assert set(joints.values()) == {1} and "</origin>" not in out
    assert out.count("<origin") == text.count("<origin") + 1  # and the tool point's
    q = robot.sample_joints(50, seed=32)
    no_tool = without_base(robot).with_params({"tool.x": 0.0, "tool.y": 0.0, "tool.z": 0.0})
    np.testing.assert_allclose(reference(tmp_path / "out.urdf", no_tool, q, "tool_point"),
                               without_base(robot).forward(q), atol=1e-9)


def test_a_robot_file_is_not_written_under_a_urdf_name(tmp_path, capsys):
    """calibrate -o cal.urdf wrote kincal YAML into a .urdf, which kincal itself then read as a URDF ('not valid XML'):
    refused before any work, as simulate --save-true t.xml and export --format yaml x.urdf, nothing written; the advice
    (cal.yaml, then kincal export cal.yaml cal.urdf) gives a URDF whose chain is the calibrated model."""
    import xml.etree.ElementTree as ET

    grid = ["ur5", str(DATA / "ur5_grid.csv"), *UNITS]
    assert main(["calibrate", *grid, "-o", str(tmp_path / "cal.urdf")]) == 1
    said = capsys.readouterr().err
    assert "cal.urdf: a kincal robot file is YAML, not .urdf" in said and f"'kincal export {tmp_path / 'cal.yaml'} " in said
    assert main(["simulate", "ur5", "-o", str(tmp_path / "s.csv"), "--save-true", str(tmp_path / "t.xml")]) == 1
    assert main(["export", "ur5", str(tmp_path / "x.urdf"), "--format", "yaml"]) == 1
    with pytest.raises(kincal.ModelError, match="YAML, not .URDF: a URDF or XML reader"):
        kincal.save_robot(kincal.load_robot("ur5"), tmp_path / "y.URDF")
    assert not list(tmp_path.iterdir())
    assert main(["calibrate", *grid, "-o", str(tmp_path / "cal.yaml")]) == 0
    assert main(["export", str(tmp_path / "cal.yaml"), str(tmp_path / "cal.urdf")]) == 0
    assert ET.parse(tmp_path / "cal.urdf").getroot().tag == "robot"
    cal = kincal.load_robot(tmp_path / "cal.yaml")
    back = kincal.load_robot(tmp_path / "cal.urdf", base_link="base_link_inertia", tip_link="tool_point")
    q = cal.sample_joints(20, seed=3)
    np.testing.assert_allclose(reference(tmp_path / "cal.urdf", back, q, "tool_point"), without_base(cal).forward(q),
                               atol=1e-9)
    # the advice for an XML name works as given: export to .xacro or .xml writes a URDF (it wrote YAML, refused,
    # so the advice named the very command refused)
    for name in ("cal.xacro", "cal.xml"):
        assert main(["export", str(tmp_path / "cal.yaml"), str(tmp_path / name)]) == 0
        assert (tmp_path / name).read_bytes() == (tmp_path / "cal.urdf").read_bytes()


def test_a_wrong_from_says_what_it_is(tmp_path, capsys):
    """--from a CSV or a README: 'not a URDF', naming it (it said the URDF had no joint 'shoulder_pan_joint'); a URDF
    with the same joints, its world joint 0.5 m up and every moving origin 1.5 times as far: not the URDF the
    calibration came from, its nominal geometry differing by the largest origin shift computed here from the two
    files (it ended in 'would place the tool ... mm (please report this)')."""
    import re
    import xml.etree.ElementTree as ET

    text = UR5_URDF.read_text()
    (tmp_path / "mine.urdf").write_text(text)
    kincal.save_robot(kincal.load_robot(tmp_path / "mine.urdf", tip_link="tool0"), tmp_path / "cal.yaml")
    for wrong in (DATA / "ur5_grid.csv", DATA / "README.md"):
        assert main(["export", str(tmp_path / "cal.yaml"), str(tmp_path / "o.urdf"), "--from", str(wrong)]) == 1
        said = capsys.readouterr().err
        assert said.startswith(f"kincal: error: {wrong}: not a URDF (not valid XML") and "--from takes the URDF " \
            f"robot 'ur5' was calibrated from ({tmp_path / 'mine.urdf'})" in said

    def scaled(m):
        xyz = [float(v) * 1.5 for v in m.group(2).split()]
        return f'{m.group(1)}{" ".join(map(repr, xyz))}"/>\n    <axis'
    other = re.sub(r'(<origin rpy="[^"]*" xyz=")([^"]*)"/>\n    <axis', scaled, text)
    other = other.replace('<child link="base_link"/>\n    <origin rpy="0.0 0.0 0.0" xyz="0.0 0.0 0.0"/>',
                          '<child link="base_link"/>\n    <origin rpy="0.0 0.0 0.0" xyz="0.0 0.0 0.5"/>')
    (tmp_path / "other.urdf").write_text(other)

    def origins(t):
        return {j.get("name"): np.array([float(v) for v in j.find("origin").get("xyz").split()])
                for j in ET.fromstring(t).findall("joint")}
    a, b = origins(text), origins(other)
    shift = max(np.linalg.norm(a[n] - b[n]) for n in a) * 1e3
    assert shift == pytest.approx(500.0)
    assert main(["export", str(tmp_path / "cal.yaml"), str(tmp_path / "o.urdf"), "--from",
                 str(tmp_path / "other.urdf")]) == 1
    said = capsys.readouterr().err
    assert "other.urdf: not the URDF robot 'ur5' was calibrated from" in said and "please report" not in said
    assert f"its nominal geometry differs by up to {shift:.4g} mm and 0°" in said
    assert "world_joint, shoulder_pan_joint, shoulder_lift_joint, elbow_joint" in said
    assert not (tmp_path / "o.urdf").exists()
