"""The bundled ABB IRB 120 (abb_irb120.yaml) against ROS-Industrial's published description, and RAPID's
configuration data (cf1, cf4, cf6, cfx) from joint values (kincal.io.branches.abb_confdata)."""

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from conftest import shared_dataset

from kincal.io import program_rapid
from kincal.errors import ModelError
from kincal.io.branches import abb_confdata as config_of, quadrant
from kincal.models.arm import six_axes
from kincal.models import load_robot

RAPID = shared_dataset("robot_programs") / "rapid"

# github.com/ros-industrial/abb_experimental @ 20b9cf86ad274e4f98540b9c9efe59f94245d2d1,
# abb_irb120_support/urdf/irb120_3_58_macro.xacro (last changed in 0ae97e142ea6828c1f928f8525b6a9abc5635782):
# joint origin xyz (m), rpy (rad), axis; joint_1 … joint_6, then the fixed joints to flange and tool0.
URDF_JOINTS = [
    ((0, 0, 0), (0, 0, 0), (0, 0, 1)),
    ((0, 0, 0.29), (0, 0, 0), (0, 1, 0)),
    ((0, 0, 0.27), (0, 0, 0), (0, 1, 0)),
    ((0, 0, 0.07), (0, 0, 0), (1, 0, 0)),
    ((0.302, 0, 0), (0, 0, 0), (0, 1, 0)),
    ((0.072, 0, 0), (0, 0, 0), (1, 0, 0)),
]
URDF_FIXED = [((0, 0, 0), (0, 0, 0)),              # link_6 -> flange
              ((0, 0, 0), (0, np.pi / 2, 0))]     # flange -> tool0
LIMITS_DEG = [(-165, 165), (-110, 110), (-110, 70), (-160, 160), (-120, 120), (-400, 400)]
# Controller convention (ROS-Industrial abb_driver @ f3068b92, rapid/ROS_messages.sys: rax_i = URDF joint i in
# deg; J23_coupled false for the IRB 120): the URDF joint vector is the jointtarget's, in rad.
URDF_FROM_RAX = np.eye(6)


def urdf_frames(q):
    """The URDF's link frames (R, p) of joint_1 … joint_6 and tool0 at URDF joints q (rad), composed
    with scipy rotations: origin (xyz, rpy: fixed-axis roll, pitch, yaw), then the turn about the axis."""
    R, p, frames = np.eye(3), np.zeros(3), []
    for (xyz, rpy, axis), qk in zip(URDF_JOINTS, q):
        p = p + R @ np.array(xyz, dtype=float)
        R = R @ Rotation.from_euler("xyz", rpy).as_matrix() @ Rotation.from_rotvec(np.array(axis) * qk).as_matrix()
        frames.append((R, p))
    for xyz, rpy in URDF_FIXED:
        p = p + R @ np.array(xyz, dtype=float)
        R = R @ Rotation.from_euler("xyz", rpy).as_matrix()
    frames.append((R, p))
    return frames


@pytest.fixture(scope="module")
def irb120():
    return load_robot("abb_irb120")


def random_joints(n, seed, widen=1.0):
    rng = np.random.default_rng(seed)
    lo, hi = np.radians(np.array(LIMITS_DEG, dtype=float)).T * widen
    return rng.uniform(lo, hi, size=(n, 6))


def test_forward_kinematics_equal_the_urdf_at_1000_joint_vectors(irb120):
    q = random_joints(1000, seed=120)
    tool0 = [urdf_frames(URDF_FROM_RAX @ qi)[-1] for qi in q]
    p_ref = np.array([p for _, p in tool0])
    R_ref = np.array([R for R, _ in tool0])
    dp = np.abs(irb120.forward(q) - p_ref).max()
    dR = np.abs(irb120.flange_rotation(q) - R_ref).max()
    assert dp < 1e-9, dp  # m
    assert dR < 1e-9, dR  # the flange frame is ABB's tool0 too
    # beyond the limits as well: the chain is the chain
    q = random_joints(200, seed=121, widen=1.5)
    assert np.abs(irb120.forward(q) - np.array([urdf_frames(qi)[-1][1] for qi in q])).max() < 1e-9


def test_limits_and_names_are_the_urdfs(irb120):
    np.testing.assert_allclose(np.degrees(np.column_stack([irb120.lower, irb120.upper])), LIMITS_DEG)
    assert irb120.stack_names == tuple(f"joint_{k}" for k in range(1, 7))


def test_zero_pose_is_abbs_calibration_position(irb120):
    """At rax = 0 the IRB 120 stands upright with the forearm horizontal: tool0 at (374, 0, 630) mm,
    pointing along +x (quaternion 0.7071, 0, 0.7071, 0); the wrist centre at (302, 0, 630) mm. ABB's
    product specification (3HAC035960-001, 1.4.3: J5 = mass·((Z + 0.072)² + L²)) puts the flange 72 mm
    from axis 5."""
    q0 = np.zeros(6)
    np.testing.assert_allclose(irb120.forward(q0), [0.374, 0, 0.630], atol=1e-12)
    quat = Rotation.from_matrix(irb120.flange_rotation(q0)[0]).as_quat()  # x, y, z, w
    np.testing.assert_allclose(quat[[3, 0, 1, 2]] * np.sign(quat[3]), [np.sqrt(0.5), 0, np.sqrt(0.5), 0], atol=1e-12)
    np.testing.assert_allclose(wrist_centre(irb120, q0), [0.302, 0, 0.630], atol=1e-12)
    for q in random_joints(20, seed=5):
        assert np.linalg.norm(irb120.forward(q) - wrist_centre(irb120, q)) == pytest.approx(0.072, abs=1e-12)


def test_the_irb120_program_of_the_data_folder_reads_as_controller_joints(irb120):
    path = RAPID / "rparak__ABB_EGM_Python/ABB_RobotStudio/ABB_IRB_120/T_ROB_1/Module1.mod"
    program = program_rapid.parse(path.name, path.read_text(encoding="utf-8"))
    (target,) = program.targets  # MoveAbsJ [[0,0,0,0,0,0],[9E9,…]]: the only target, a jointtarget
    q = np.asarray(target.values)
    np.testing.assert_allclose(irb120.forward(q), [0.374, 0, 0.630], atol=1e-12)
    assert config_of(irb120, q) == (0, 0, 0, 0)


# ---- configuration data ------------------------------------------------------------------------
@pytest.mark.parametrize("deg, expected", [(0, 0), (45, 0), (89.9, 0), (90, 1), (179.9, 1), (180, 2), (270, 3),
                                           (359.9, 3), (360, 4), (-0.1, -1), (-89.9, -1), (-90.1, -2),
                                           (-180.1, -3), (-270.1, -4), (-359.9, -4), (-360.1, -5)])
def test_quadrant_numbers(deg, expected):
    assert quadrant(np.radians(deg)) == expected


def reference_bits(q):
    """cfx from the URDF chain, independently: wrist centre = joint_5's origin; "behind axis 1" when it
    lies behind the vertical plane through axis 1 facing the arm's forward direction (Rz(q1)·x); "behind
    the lower arm" when it lies behind the line through joint_2 and joint_3 (forward = the way a positive
    axis-2 turn moves the lower arm); axis 5 negative."""
    frames = urdf_frames(q)
    wc, j2, j3 = frames[4][1], frames[1][1], frames[2][1]
    forward = np.array([np.cos(q[0]), np.sin(q[0]), 0.0])
    arm = j3 - j2
    lean = np.cross(frames[1][0] @ np.array([0, 1.0, 0]), arm)
    return 4 * int((wc - j2) @ forward < 0) + 2 * int((wc - j2) @ lean < 0) + int(q[4] < 0)


def test_config_of_matches_an_independent_reading_at_random_joints(irb120):
    for q in random_joints(400, seed=7):
        cf1, cf4, cf6, cfx = config_of(irb120, q)
        deg = np.degrees(q)
        assert (cf1, cf4, cf6) == tuple(int(np.floor(deg[k] / 90)) for k in (0, 3, 5))
        assert cfx == reference_bits(q), np.round(deg, 3)


def test_each_cfx_bit_flips_across_its_singularity(irb120):
    eps = np.radians(0.01)
    # lower arm: the wrist centre is in line with axes 2 and 3 where rax_3 = atan2(70, 302) - 90 deg
    q3_line = np.arctan2(0.07, 0.302) - np.pi / 2
    for q2 in np.radians([-30, 0, 40]):
        assert config_of(irb120, [0.3, q2, q3_line + eps, 0, 0.5, 0])[3] & 2 == 0
        assert config_of(irb120, [0.3, q2, q3_line - eps, 0, 0.5, 0])[3] & 2 == 2
    # axis 1: the wrist centre crosses the axis-1 line where 270 sin q2 + 70 sin(q2+q3) + 302 cos(q2+q3) = 0
    for q3 in np.radians([-60, 0, 60]):
        q2_line = brentq(lambda a: 0.27 * np.sin(a) + 0.07 * np.sin(a + q3) + 0.302 * np.cos(a + q3), -2.0, 0.0)
        assert config_of(irb120, [-1.0, q2_line + eps, q3, 1.0, 0.5, 0])[3] & 4 == 0
        assert config_of(irb120, [-1.0, q2_line - eps, q3, 1.0, 0.5, 0])[3] & 4 == 4
    # axis 5: its sign (0 counts as positive)
    assert config_of(irb120, [0, 0, 0, 0, eps, 0])[3] == 0
    assert config_of(irb120, [0, 0, 0, 0, 0, 0])[3] == 0
    assert config_of(irb120, [0, 0, 0, 0, -eps, 0])[3] == 1


def test_all_eight_cfx_codes(irb120):
    # (rax_2, rax_3, rax_5) deg; rax_3 = -90 is below the -76.95 deg lower-arm line, rax_2 = -80 leans back
    cases = {0: (0, 0, 10), 1: (0, 0, -10), 2: (30, -90, 10), 3: (30, -90, -10),
             4: (-80, 0, 10), 5: (-80, 0, -10), 6: (-80, -90, 10), 7: (-80, -90, -10)}
    for code, (q2, q3, q5) in cases.items():
        q = np.radians([20, q2, q3, 0, q5, 0])
        assert config_of(irb120, q)[3] == code == reference_bits(q), (code, q2, q3, q5)


def test_a_written_multiple_of_90_keeps_its_quadrant(irb120):
    q = np.radians([90, 0, 0, -90, 30, 180])
    assert config_of(irb120, q)[:3] == (1, -1, 2)


def test_config_of_wants_six_axes(irb120):
    with pytest.raises(ModelError, match="defined for six-axis arms; got 5 joint values"):
        config_of(irb120, np.zeros(5))


def test_calibrated_model_keeps_the_bits_away_from_singularities(irb120):
    rng = np.random.default_rng(3)
    v = irb120.params.values.copy()
    v[6:] += rng.normal(0, 1e-3, v.size - 6)  # 1 mm / 1 mrad errors on every link
    calibrated = irb120.with_params(v)
    for q in random_joints(100, seed=9):
        if abs(q[4]) > 0.05 and abs(q[2] - (np.arctan2(0.07, 0.302) - np.pi / 2)) > 0.05:
            wc = wrist_centre(irb120, q)
            if abs(wc @ np.array([np.cos(q[0]), np.sin(q[0]), 0])) > 0.02:
                assert config_of(calibrated, q) == config_of(irb120, q)


def test_cf1_of_real_robtargets_where_the_target_alone_fixes_axis_1():
    """The data folder has no IRB 120 robtarget and no robtarget with a jointtarget of the same pose.
    cf1 is the only bit that follows from one joint whose angle the target shows without the arm's
    lengths: on an arm with no sideways offset (the IRB 1200 of rparak/ABB_EGM_Python), with cfx < 4
    (wrist centre in front of axis 1), axis 1 points at the wrist centre, which lies on the tool0 z
    axis behind the flange. Where the quadrant of that direction is the same for every flange distance
    0..200 mm, it must be the written cf1."""
    path = RAPID / "rparak__ABB_EGM_Python/ABB/IRB12000/RAPID/T_ROB1/Module1.mod"
    program = program_rapid.parse(path.name, path.read_text(encoding="utf-8"))
    checked = 0
    for t in program.targets:
        assert t.kind == "pose" and t.frames == ("tool0", "wobj0") and t.config[3] < 4
        v = np.asarray(t.values)
        z = Rotation.from_rotvec(v[3:]).as_matrix()[:, 2]
        found = {quadrant(np.arctan2(*(v[:3] - d * z)[[1, 0]])) for d in np.linspace(0, 0.2, 41)}
        if len(found) == 1:
            assert found.pop() == t.config[0], t.variable
            checked += 1
    assert checked == 111  # of 142; the other 31 lie within 200 mm of the axis-1 quadrant boundary


def wrist_centre(robot, q):
    """The wrist centre: nearest the axes 4, 5 and 6."""
    return six_axes(robot, q, "the wrist centre")[3][0]


def test_one_joint_vector_of_the_wrong_shape_is_named_by_its_shape(irb120):
    """abb_confdata takes one joint vector (6,): given (1, 6) it said 'got 6 joint values for 6 joints'."""
    from kincal.io.branches import abb_confdata
    with pytest.raises(ModelError, match=r"takes one joint vector \(6,\), got shape \(1, 6\); abb_rows takes \(N, 6\)"):
        abb_confdata(irb120, np.zeros((1, 6)))
    assert abb_confdata(irb120, np.radians([10, 20, 30, 40, 50, 60])) == abb_confdata(irb120, np.radians(
        [10, 20, 30, 40, 50, 60]).tolist())
