"""The bundled KUKA KR 6 R900 sixx (kuka_kr6r900sixx.yaml) against ROS-Industrial's published description, and
KRL's status and turn (S, T) from joint values (kincal.io.branches.kuka_status_turn)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import shared_dataset

from kincal.errors import ModelError
from kincal.io import program_krl
from kincal.io.branches import kuka_status_turn as config_of
from kincal.models.arm import axis_lines as joint_axes, nearest_point
from kincal.models import load_robot

KRL = shared_dataset("robot_programs") / "krl"

# github.com/ros-industrial/kuka_experimental @ e78bbd15edb2b39c9053ff3b963ef2947e10a531,
# kuka_kr6_support/urdf/kr6r900sixx_macro.xacro (last changed in 652600df1f2e0ec53988c84ebe77e9bf3446a52e):
# joint origin xyz (m), rpy (rad), axis of joint_a1 … joint_a6; then the fixed joints joint_a6-flange and
# flange-tool0 (origin xyz, rpy).
URDF_JOINTS = [
    ((0, 0, 0.400), (0, 0, 0), (0, 0, -1)),
    ((0.025, 0, 0), (0, 0, 0), (0, 1, 0)),
    ((0.455, 0, 0), (0, 0, 0), (0, 1, 0)),
    ((0, 0, 0.035), (0, 0, 0), (-1, 0, 0)),
    ((0.420, 0, 0), (0, 0, 0), (0, 1, 0)),
    ((0.080, 0, 0), (0, 0, 0), (-1, 0, 0)),
]
URDF_FLANGE = ((0, 0, 0), (0, 0, 0))
URDF_TOOL0 = ((0, 0, 0), (0, np.pi / 2, 0))
# Controller convention: KUKA's A1..A6 are the URDF's joint_a1..joint_a6 with no sign or offset (the xacro's axes
# are KUKA's directions and its zeros KUKA's; ROS-Industrial's RSI driver, kuka_rsi_hw_interface/src/
# kuka_hardware_interface.cpp, sets joint_position_[i] = DEG2RAD * the controller's axis value i).
URDF_SIGN = np.ones(6)
URDF_ZERO = np.zeros(6)
PHI = np.arctan2(0.035, 0.420)  # A3 of the stretched arm: the wrist centre on the line through A2 and A3


def urdf_from_controller(q):
    return URDF_SIGN * (np.asarray(q, dtype=float) - URDF_ZERO)


def urdf_frames(q):
    """(R, p) of link_1 … link_6, flange and tool0 at URDF joints q (rad), composed with scipy rotations:
    the origin (xyz, rpy as fixed-axis roll, pitch, yaw), then the turn about the joint axis."""
    R, p, frames = np.eye(3), np.zeros(3), []
    for (xyz, rpy, axis), qk in zip(URDF_JOINTS, q):
        p = p + R @ np.array(xyz, dtype=float)
        R = R @ Rotation.from_euler("xyz", rpy).as_matrix() @ Rotation.from_rotvec(np.array(axis) * qk).as_matrix()
        frames.append((R, p))
    for xyz, rpy in (URDF_FLANGE, URDF_TOOL0):
        R, p = frames[-1] if len(frames) == 6 else frames[5]
        frames.append((R @ Rotation.from_euler("xyz", rpy).as_matrix(), p + R @ np.array(xyz, dtype=float)))
    return frames


@pytest.fixture(scope="module")
def robot():
    return load_robot("kuka_kr6r900sixx")


def test_forward_kinematics_equal_the_published_description(robot):
    """1000 random joint vectors over two turns of every axis (limits play no part in the geometry): the tool
    point (the flange centre) and the flange frame equal the xacro's flange link within 1e-9."""
    q = np.random.default_rng(34).uniform(-2 * np.pi, 2 * np.pi, size=(1000, 6))
    ref = [urdf_frames(urdf_from_controller(qk)) for qk in q]
    p_ref = np.array([f[6][1] for f in ref])
    R_ref = np.array([f[6][0] for f in ref])
    dp = np.abs(robot.forward(q) - p_ref).max()
    dR = np.abs(robot.flange_rotation(q) - R_ref).max()
    assert dp < 1e-9 and dR < 1e-9, (dp, dR)
    tool = np.array([0.012, -0.034, 0.156])  # a probe on the flange: in KUKA's flange frame ($FLANGE)
    moved = robot.with_tool_point(tool).forward(q)
    np.testing.assert_allclose(moved, p_ref + R_ref @ tool, atol=1e-9, rtol=0)
    # tool0 is the flange frame turned +90 deg about y (ROS's z-out convention)
    R0 = np.array([f[7][0] for f in ref])
    np.testing.assert_allclose(R0, robot.flange_rotation(q) @ Rotation.from_euler("y", 90, degrees=True).as_matrix(),
                               atol=1e-12)


def test_joint_axes_are_the_controllers(robot):
    """At A1..A6 = 0 the axes are KUKA's: A1 about -z, A2, A3, A5 about +y, A4 and A6 about -x; the
    limits and joint names are the xacro's."""
    points, axes = joint_axes(robot, np.zeros(6))
    np.testing.assert_allclose(axes, [axis for *_, axis in URDF_JOINTS], atol=1e-15)
    origins = np.cumsum([xyz for xyz, *_ in URDF_JOINTS], axis=0)  # the URDF's joint origins at q = 0
    off = np.cross(points - origins, axes)  # each model point lies on the URDF's axis line
    assert np.abs(off).max() < 1e-15
    np.testing.assert_allclose(np.degrees(robot.lower), [-170, -190, -120, -185, -120, -350])
    np.testing.assert_allclose(np.degrees(robot.upper), [170, 45, 156, 185, 120, 350])
    assert [j.export_name for j in robot.moving] == [f"joint_a{k}" for k in range(1, 7)]


def test_published_poses(robot):
    """KUKA's mechanical zero {A1 0, A2 -90, A3 90, A4 0, A5 0, A6 0}: upper arm vertical, forearm horizontal,
    flange centre at X 525, Y 0, Z 890 mm (400 + 455 + 35 high, 25 + 420 + 80 ahead: the data sheet's
    dimensions) with the flange frame parallel to $ROBROOT; the maximum reach of the wrist centre, 901.5 mm on
    KUKA's data sheet, is the stretched arm (A2 0, A3 = atan(35/420)) at 25 + 455 + sqrt(420² + 35²) mm."""
    home = np.radians([0, -90, 90, 0, 0, 0])
    np.testing.assert_allclose(robot.forward(home) * 1e3, [525, 0, 890], atol=1e-9)
    np.testing.assert_allclose(robot.flange_rotation(home), np.eye(3)[None], atol=1e-12)
    np.testing.assert_allclose(robot.forward(np.radians([0, -90, 90, 0, 90, 0])) * 1e3, [445, 0, 810], atol=1e-9)
    stretched = np.array([0, 0, PHI, 0, 0, 0])
    w = wrist_root(*joint_axes(robot, stretched))
    assert abs(w[0] * 1e3 - 901.5) < 0.05 and abs(w[2] - 0.4) < 1e-12
    q = np.random.default_rng(1).uniform(robot.lower, robot.upper, size=(2000, 6))
    reach = max(np.hypot(*wrist_root(*joint_axes(robot, qk))[:2]) for qk in q)
    assert reach < w[0] + 1e-12


def expected_bits(q):
    """S and T from the published lengths alone (URDF table above), independently of the model: the wrist
    centre's x in the A1 frame, the A3 angle from the stretched arm, the A5 range, the axis signs."""
    a2, a3, a5 = q[1], q[2], q[4]
    x = 0.025 + 0.455 * np.cos(a2) + 0.420 * np.cos(a2 + a3) + 0.035 * np.sin(a2 + a3)
    flip = -np.pi <= a5 < 0 or a5 >= np.pi  # KUKA's A5 ranges, for -360 < A5 < 360 deg
    s = int(x < 0) | int(np.sin(a3 - PHI) >= 0) << 1 | int(flip) << 2
    return s, sum(1 << k for k in range(6) if q[k] < 0)


def test_status_and_turn_of_random_joint_vectors(robot):
    q = np.random.default_rng(7).uniform(robot.lower, robot.upper, size=(1000, 6))
    got = [config_of(robot, qk) for qk in q]
    assert got == [expected_bits(qk) for qk in q]
    assert {s for s, _ in got} == set(range(8))  # every branch met


def test_known_configurations(robot):
    # the ROS-Industrial RSI driver's HOME for its KR AGILUS (ros_rsi.src): the usual S 'B010', T 'B000010'
    assert config_of(robot, np.radians([0, -90, 90, 0, 90, 0])) == (2, 2)
    assert config_of(robot, np.radians([0, -90, 90, 0, 0, 0])) == (2, 2)
    # upper arm up, forearm bent back over the shoulder: overhead (bit 0), below the stretched arm (bit 1 clear)
    assert config_of(robot, np.radians([0, -90, -30, 0, 30, 0])) == (1, 4 | 2)
    # A5 negative: bit 2, and T's A5 bit
    assert config_of(robot, np.radians([-20, -45, 100, -10, -30, -5])) == (2 | 4, 1 | 2 | 8 | 16 | 32)


def test_each_bit_changes_at_its_boundary(robot):
    rng = np.random.default_rng(3)
    eps = 1e-9
    for _ in range(20):
        q = rng.uniform(robot.lower, robot.upper)
        for k in range(6):  # T: the axis sign
            for a, bit in ((-eps, 1), (0.0, 0), (eps, 0)):
                assert config_of(robot, np.where(np.arange(6) == k, a, q))[1] >> k & 1 == bit
        for a3, bit in ((PHI - eps, 0), (PHI + eps, 1)):  # S bit 1: the stretched arm, whatever the other axes
            assert config_of(robot, np.r_[q[:2], a3, q[3:]])[0] >> 1 & 1 == bit
    for a5, bit in ((-np.pi - eps, 0), (-np.pi, 1), (-eps, 1), (0.0, 0), (np.pi - eps, 0), (np.pi, 1)):
        assert config_of(robot, [0, -np.pi / 2, np.pi / 2, 0, a5, 0])[0] >> 2 & 1 == bit
    # S bit 0 with the upper arm vertical: the wrist centre crosses A1's axis where 0.025 + 0.42 sin(A3)
    # - 0.035 cos(A3) = 0 (about A3 = 1.36 deg)
    from scipy.optimize import brentq
    a3 = brentq(lambda a: 0.025 + 0.42 * np.sin(a) - 0.035 * np.cos(a), -0.5, 0.5)
    for d, bit in ((-1e-7, 1), (1e-7, 0)):
        for a1 in (-2.0, 0.0, 1.0):  # the A1 frame turns with A1
            assert config_of(robot, [a1, -np.pi / 2, a3 + d, 0.3, 0.2, 0.1])[0] & 1 == bit


def test_bits_follow_the_calibrated_geometry(robot):
    """A calibrated model moves the wrist centre: the S bits are taken from its axes, not from the nominal
    lengths; the base frame (where the robot stands) changes nothing."""
    moved = robot.with_params({"base.x": 0.3, "base.rz": 1.0, "base.ry": 0.2})
    q = np.random.default_rng(5).uniform(robot.lower, robot.upper, size=(200, 6))
    assert [config_of(moved, qk) for qk in q] == [config_of(robot, qk) for qk in q]
    longer = robot.with_params({"a4.a": 0.0})  # A4 on A3's plane: the stretched arm is at A3 = 0
    assert config_of(longer, [0, 0, 0.01, 0, 0, 0])[0] & 2 and config_of(robot, [0, 0, 0.01, 0, 0, 0])[0] & 2 == 0


def test_refusals(robot):
    with pytest.raises(ModelError, match="defined for six-axis arms; got 5 joint values"):
        config_of(robot, np.zeros(5))
    with pytest.raises(ModelError, match="defined for six-axis arms; got 6 joint values for 3 joints"):
        config_of(load_robot("delta"), np.zeros(6))


def _krl_targets():
    """Every point of the folder's files, each file read alone (by its name only: a .dat's module .src lists the
    points it never moves to, and the bits are checked on every point written)."""
    for path in sorted(KRL.rglob("*")):
        if path.suffix.lower() in (".src", ".dat", ".sub"):
            for t in program_krl.parse(f"alone/{path.name}", path.read_bytes().decode("utf-8", "replace")).targets:
                yield path, t


def test_bits_written_in_the_data_folder(robot):
    """The folder's S/T-carrying targets are E6POS of other arms (a KUKA LWR 4+; the KSS ROS driver's dummy
    point) and no target carries both joints and bits, so only the length-free bits are checked: joints with
    the signs T encodes give back T, and S bit 2 (A5's range) agrees with T's A5 sign bit."""
    seen = 0
    for path, t in _krl_targets():
        if not t.config or t.config[1] is None:
            continue
        s, turn = t.config
        q = np.radians([-30.0 if turn >> k & 1 else 30.0 for k in range(6)])
        got = config_of(robot, q)
        assert got[1] == turn and got[0] >> 2 & 1 == s >> 2 & 1, (path.name, t.line, t.config, got)
        seen += 1
    assert seen >= 3


def test_joint_targets_of_the_data_folder(robot):
    """Every complete joint target of the folder (A1..A6 as written, deg) gets T from its signs."""
    for path, t in _krl_targets():
        if t.kind == "joints":
            s, turn = config_of(robot, t.values)
            assert turn == sum(1 << k for k in range(6) if t.values[k] < 0) and 0 <= s < 8


def wrist_root(points, axes):
    """KUKA's wrist root: where the A4, A5 and A6 axes meet."""
    return nearest_point(points[3:], axes[3:])
