"""The bundled Yaskawa Motoman GP7 against ROS-Industrial's description of it, with the controller's joint
convention, and the INFORM ``///RCONF`` digits of ``config_of`` on both sides of every boundary.

The reference forward kinematics is written here from the description's joint table and composed with
scipy's rotations, not read through kincal's URDF reader."""
import math

import numpy as np
import pytest
from conftest import shared_dataset
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

import kincal
from kincal import ModelError
from kincal.io import read_program
from kincal.io.branches import yaskawa_rconf as config_of

# github.com/ros-industrial/motoman, commit 433be15f6a27cb9a5715cc3887b1cd15ff33a8cb (2023-12-20),
# motoman_gp7_support/urdf/gp7_macro.xacro (BSD): per joint the origin xyz (m) and rpy (rad) in the parent link,
# the axis in the child link, and the position limits (rad).
URDF_JOINTS = (
    ("joint_1_s", (0.0, 0.0, 0.330), (0.0, 0.0, 0.0), (0, 0, 1), (-2.9670, 2.9670)),
    ("joint_2_l", (0.040, 0.0, 0.0), (0.0, 0.0, 0.0), (0, 1, 0), (-1.1344, 2.5307)),
    ("joint_3_u", (0.0, 0.0, 0.445), (0.0, 0.0, 0.0), (0, -1, 0), (-1.2217, 3.3161)),
    ("joint_4_r", (0.440, 0.0, 0.040), (0.0, 0.0, 0.0), (-1, 0, 0), (-3.3161, 3.3161)),
    ("joint_5_b", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0, -1, 0), (-2.3561, 2.3561)),
    ("joint_6_t", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (-1, 0, 0), (-6.2944, 6.2944)),
)
URDF_TOOL0 = ((0.080, 0.0, 0.0), (3.1415926, -1.570796, 0.0))  # fixed joint joint_6_t-tool0 (rpy as written)
URDF_BASE = (0.0, 0.0, 0.330)  # fixed joint base_link-base: "ROS base_link to Robot Manufacturer World Coordinates"

# The controller's axis angles (S, L, U, R, B, T, deg) to the description's joint values (rad): MotoROS
# (same repository, motoman_driver/MotoPlus/CtrlGroup.c, Ros_CtrlGroup_ConvertToRosPos) divides each axis's
# pulse count by its pulses per radian: one to one, no sign change, no offset, no L/U coupling.
CONTROLLER_SIGN = (1, 1, 1, 1, 1, 1)
CONTROLLER_ZERO_DEG = (0, 0, 0, 0, 0, 0)


def _transform(xyz, rpy) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()  # URDF rpy: fixed axes x, then y, then z
    T[:3, 3] = xyz
    return T


def urdf_tool0(q_controller_deg) -> np.ndarray:
    """tool0's pose (4, 4) in Yaskawa's ROBOT frame (the description's link 'base') for controller angles (deg)."""
    q_ros = [s * math.radians(a - z) for s, a, z in zip(CONTROLLER_SIGN, q_controller_deg, CONTROLLER_ZERO_DEG)]
    T = _transform((-URDF_BASE[0], -URDF_BASE[1], -URDF_BASE[2]), (0, 0, 0))  # base_link seen from 'base'
    for (_, xyz, rpy, axis, _), angle in zip(URDF_JOINTS, q_ros):
        T = T @ _transform(xyz, rpy)
        T[:3, :3] = T[:3, :3] @ Rotation.from_rotvec(np.array(axis, float) * angle).as_matrix()
    return T @ _transform(*URDF_TOOL0)


def urdf_wrist_centre(q_controller_deg) -> np.ndarray:
    """The B axis' centre (where the R, B and T axes meet), m, in the ROBOT frame: tool0 80 mm back along its z."""
    T = urdf_tool0(q_controller_deg)
    return T[:3, 3] - URDF_TOOL0[0][0] * T[:3, 2]


@pytest.fixture(scope="module")
def gp7():
    return kincal.load_robot("motoman_gp7")


def _random_controller_deg(n: int, seed: int) -> np.ndarray:
    lo, hi = np.array([j[4] for j in URDF_JOINTS]).T
    return np.degrees(np.random.default_rng(seed).uniform(lo, hi, size=(n, 6)))


def test_gp7_is_bundled_with_the_description_names_and_limits(gp7):
    assert "motoman_gp7" in kincal.bundled_robots()
    assert gp7.stack_names == tuple(j[0] for j in URDF_JOINTS)
    np.testing.assert_allclose(gp7.lower, [j[4][0] for j in URDF_JOINTS], atol=1e-5)  # the file's 0.001°
    np.testing.assert_allclose(gp7.upper, [j[4][1] for j in URDF_JOINTS], atol=1e-5)
    R, t = gp7.named_frames()["base_link"]
    np.testing.assert_allclose(R, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(t, -np.array(URDF_BASE), atol=1e-15)


def test_gp7_forward_kinematics_equal_the_description_at_1000_joint_vectors(gp7):
    q_deg = _random_controller_deg(1000, seed=34)
    p, R, _, _ = gp7.pose_and_jacobian(np.radians(q_deg))
    ref = np.array([urdf_tool0(q) for q in q_deg])
    assert np.abs(p - ref[:, :3, 3]).max() < 1e-9  # m
    # the flange frame is tool0; the description writes its rpy as 3.1415926, -1.570796 (3.3e-7 rad short)
    assert np.abs(R - ref[:, :3, :3]).max() < 1e-6


def test_gp7_zero_pose_and_reach(gp7):
    # at zero: L arm up, U arm forward, wrist straight; flange centre 40 + 440 + 80 mm ahead of the S axis and
    # 445 + 40 mm above the L axis (the ROBOT frame's origin), tool0's z forward and x up
    p, R, _, _ = gp7.pose_and_jacobian(np.zeros(6))
    np.testing.assert_allclose(p, [0.560, 0.0, 0.485], atol=1e-12)
    np.testing.assert_allclose(R, [[0, 0, 1], [0, -1, 0], [1, 0, 0]], atol=1e-6)
    np.testing.assert_allclose(urdf_tool0(np.zeros(6))[:3, 3], p, atol=1e-12)
    # Yaskawa's GP7 data sheet: maximum reach 927 mm (the P point, i.e. the wrist centre, from the S axis):
    # the L arm horizontal forward and the U arm stretched along it
    stretched_u = math.degrees(math.atan2(0.440, 0.040))
    reach = np.hypot(*urdf_wrist_centre([0, 90, stretched_u, 0, 0, 0])[:2])
    assert round(reach * 1e3) == 927


# ---- ///RCONF digits ------------------------------------------------------------------------------------------
EPS = 1e-3  # deg: a configuration this far on either side of a boundary


def test_home_is_flip_upper_front_all_below_180(gp7):
    assert config_of(gp7, np.zeros(6)) == (0, 0, 0, 0, 0, 0)
    assert config_of(gp7, np.zeros(6), digits=8) == (0,) * 8  # jobs carry 8 or 24 digits; the rest are 0
    assert config_of(gp7, np.zeros(6), digits=24) == (0,) * 24


@pytest.mark.parametrize("b, flip", [(EPS, 0), (0.0, 0), (-EPS, 1), (120.0, 0), (-120.0, 1)])
def test_flip_is_the_sign_of_b(gp7, b, flip):
    for q in _random_controller_deg(20, seed=5):
        q[4] = b
        assert config_of(gp7, np.radians(q))[0] == flip


def test_upper_and_lower_arm_sit_either_side_of_the_stretched_elbow(gp7):
    # stretched: the U→wrist-centre line along the L arm, U = atan(440 / 40) from the description's lengths
    stretched = math.degrees(math.atan2(URDF_JOINTS[3][1][0], URDF_JOINTS[3][1][2]))
    for q in _random_controller_deg(50, seed=6):
        for u, lower in ((stretched - EPS, 0), (stretched + EPS, 1), (-60.0, 0), (170.0, 1)):
            q[2] = u
            assert config_of(gp7, np.radians(q))[1] == lower, q


def _on_s_axis(s: float, u: float) -> float:
    """L angle (deg) that puts the wrist centre on the S axis (its distance ahead of it along the arm's facing)."""
    def ahead(l_deg: float) -> float:
        w = urdf_wrist_centre([s, l_deg, u, 0, 0, 0])
        return float(w[0] * math.cos(math.radians(s)) + w[1] * math.sin(math.radians(s)))
    return brentq(ahead, -64.0, 0.0, xtol=1e-12)


@pytest.mark.parametrize("s, u", [(0.0, 30.0), (25.0, 60.0), (-140.0, 10.0)])
def test_front_and_rear_sit_either_side_of_the_s_axis(gp7, s, u):
    l_star = _on_s_axis(s, u)
    assert -64.0 < l_star < 0.0
    rng = np.random.default_rng(7)
    for r, b, t in rng.uniform(-120, 120, size=(10, 3)):
        front = config_of(gp7, np.radians([s, l_star + EPS, u, r, b, t]))
        rear = config_of(gp7, np.radians([s, l_star - EPS, u, r, b, t]))
        assert front[2] == 0 and rear[2] == 1
        assert front[:2] == rear[:2] and front[3:] == rear[3:]  # nothing else moves across this boundary


@pytest.mark.parametrize("angle, digit", [(180.0, 0), (180.0 + EPS, 1), (-180.0, 1), (-180.0 + EPS, 0),
                                          (0.0, 0), (189.0, 1), (-189.0, 1), (359.0, 1), (-359.0, 1)])
def test_r_t_s_digits_are_set_outside_minus_180_to_180(gp7, angle, digit):
    base = np.array([10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
    for k, place in ((3, 3), (5, 4), (0, 5)):  # R, T, S and where their digit is written
        q = base.copy()
        q[k] = angle  # the GP7's S stops at ±170°: its S digit is 0 on the real arm; the rule is tested anyway
        got = config_of(gp7, np.radians(q))
        assert got[place] == digit
        assert got[:3] == config_of(gp7, np.radians(base))[:3]


def test_the_wrist_twin_has_the_same_pose_and_the_other_flip(gp7):
    """(R, B, T) and (R ± 180°, −B, T ± 180°) reach the same flange pose: the flip digit tells them apart."""
    for q in _random_controller_deg(200, seed=8):
        twin = q.copy()
        twin[3] += -180.0 if q[3] > 0 else 180.0
        twin[4] = -q[4]
        twin[5] += -180.0 if q[5] > 0 else 180.0
        np.testing.assert_allclose(urdf_tool0(twin), urdf_tool0(q), atol=1e-9)
        a, b = config_of(gp7, np.radians(q)), config_of(gp7, np.radians(twin))
        assert a[0] + b[0] == 1 and a[1:3] == b[1:3]
        assert (b[3], b[4]) == tuple(int(not -180.0 < twin[k] <= 180.0) for k in (3, 5))


def test_digits_follow_the_models_own_geometry(gp7):
    """A calibrated model's elbow: with the U arm's 40 mm offset at 60 mm, the stretched elbow moves to atan(440/60)."""
    wider = gp7.with_params({"u.a": 0.060})
    old, new = (math.degrees(math.atan2(0.440, a)) for a in (0.040, 0.060))
    between = np.radians([0, 10, 0.5 * (old + new), 0, 30, 0])
    assert config_of(gp7, between)[1] == 0 and config_of(wider, between)[1] == 1
    assert config_of(wider, np.radians([0, 10, new - EPS, 0, 30, 0]))[1] == 0


def test_config_of_refuses_what_is_not_a_six_axis_arm(gp7):
    with pytest.raises(ModelError, match="defined for six-axis arms; got 5 joint values"):
        config_of(gp7, np.zeros(5))
    with pytest.raises(ValueError, match="at least 6 digits"):
        config_of(gp7, np.zeros(6), digits=4)
    with pytest.raises(ModelError, match="defined for six-axis arms; got 7 joint values for 7 joints"):
        config_of(kincal.load_robot("wam"), np.zeros(7))  # a 7-joint arm


def test_the_data_folders_jobs_carry_no_cartesian_c_target():
    """The shared INFORM jobs hold no RECTAN C position a move goes to (their RCONF lines stand before P
    variables of an MH180, listed, not compensated; their moves go to PULSE positions): config_of is checked on
    built configurations above."""
    folder = shared_dataset("robot_programs") / "inform"
    files = sorted(p for p in folder.rglob("*") if p.suffix.lower() == ".jbi")
    assert files
    kinds = [t.kind for p in files for t in read_program(str(p), "inform").targets]
    assert "pose" not in kinds and kinds.count("pulses") == len(kinds) == 8  # only PULSE positions: move targets
