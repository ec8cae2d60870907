"""The bundled FANUC LR Mate 200iD: its forward kinematics against ROS-Industrial's description composed
here independently (with FANUC's J2/J3 coupling applied), FANUC's published reach, the 'coupled'
transmission map it is built with (analytic Jacobians against finite differences, its file round
trip), and FANUC's CONFIG letters and turn numbers (kincal.io.branches.fanuc_config) on either side of every
boundary, against closed forms of the published dimensions."""
import re

import numpy as np
import pytest
import yaml
from conftest import shared_dataset
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

import kincal
from kincal.errors import ModelError
from kincal.io import read_program
from kincal.io.branches import fanuc_config as config_of
from kincal.models.transmission import Map, build_transmission_robot
from kincal.models.yaml_io import robot_from_dict, robot_to_yaml

NAME = "fanuc_lrmate200id"
# github.com/ros-industrial/fanuc @ 8fee5e30e535378758ace26dfdffb8ab0403e23c,
# fanuc_lrmate200id_support/urdf/lrmate200id_macro.xacro: joint origins (xyz m, rpy rad) and axes
URDF = [("joint_1", (0, 0, 0.330), (0, 0, 0), (0, 0, 1)),
        ("joint_2", (0.050, 0, 0), (0, 0, 0), (0, 1, 0)),
        ("joint_3", (0, 0, 0.330), (0, 0, 0), (0, -1, 0)),
        ("joint_4", (0, 0, 0.035), (0, 0, 0), (-1, 0, 0)),
        ("joint_5", (0.335, 0, 0), (0, 0, 0), (0, -1, 0)),
        ("joint_6", (0.080, 0, 0), (0, 0, 0), (-1, 0, 0))]
BASE = ((0, 0, 0.330), (0, 0, 0))  # base_link -> base (FANUC World), fixed joint base_link-base
TOOL0 = ((0, 0, 0), (np.pi, -np.pi / 2, 0))  # link_6 -> flange (identity) -> tool0 (FANUC faceplate)
# ROS-Industrial fanuc_driver, src/fanuc_utils.cpp linkage_transform: joint_3 (ROS) = J3 + J23_factor·J2,
# J23_factor = 1 for the LR Mate 200iD (launch/robot_interface_streaming_lrmate200id.launch)
J23_FACTOR = 1.0


def _transform(xyz, rpy):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()  # URDF rpy: fixed axes x, y, z
    T[:3, 3] = xyz
    return T


def _reference(J: np.ndarray) -> np.ndarray:
    """tool0 in FANUC's World ('base') at controller joints J (rad), 4x4, from the table above."""
    q = np.array(J, dtype=float)
    q[2] += J23_FACTOR * q[1]
    T = np.linalg.inv(_transform(*BASE))  # World -> base_link
    for (_, xyz, rpy, axis), qi in zip(URDF, q):
        T = T @ _transform(xyz, rpy)
        R = np.eye(4)
        R[:3, :3] = Rotation.from_rotvec(np.asarray(axis, float) * qi).as_matrix()
        T = T @ R
    return T @ _transform(*TOOL0)


@pytest.fixture(scope="module")
def robot():
    return kincal.load_robot(NAME)


def test_forward_kinematics_equal_the_ros_industrial_description(robot):
    rng = np.random.default_rng(34)
    J = rng.uniform(robot.lower, robot.upper, size=(1000, 6))
    tool = np.array([0.03, -0.02, 0.15])  # a tool point off every axis checks the flange's orientation too
    ref = np.array([_reference(j) for j in J])
    assert np.abs(robot.forward(J) - ref[:, :3, 3]).max() < 1e-9
    assert np.abs(robot.flange_rotation(J) - ref[:, :3, :3]).max() < 1e-9
    assert np.abs(robot.with_tool_point(tool).forward(J) - (ref[:, :3, :3] @ tool + ref[:, :3, 3])).max() < 1e-9
    # beyond the limits too (the forward kinematics do not clip): the same map everywhere
    Jw = rng.uniform(-2 * np.pi, 2 * np.pi, size=(200, 6))
    assert np.abs(robot.forward(Jw) - np.array([_reference(j)[:3, 3] for j in Jw])).max() < 1e-9
    R, t = robot.named_frames()["base_link"]
    assert np.allclose(R, np.eye(3)) and np.allclose(t, [0, 0, -0.330])


def test_chain_is_the_urdf_and_j3_is_coupled(robot):
    J = np.radians([[10.0, 20.0, -30.0, 40.0, -50.0, 60.0]])
    assert np.allclose(np.degrees(robot.chain_q(J)), [[10, 20, -10, 40, -50, 60]])
    assert np.allclose(robot.actuator_q(robot.chain_q(J)), J)
    assert robot.joint_names == ("J1", "J2", "J3", "J4", "J5", "J6")
    assert robot.structure.endswith("transmission")


def test_zero_pose_and_published_reach(robot):
    # J1..J6 = 0: upper arm vertical, forearm horizontal (FANUC's zero); the faceplate 50 + 335 + 80 = 465 mm in
    # front and 330 + 35 = 365 mm above the World origin, its z forward and x up: W, P, R = 180, -90, 0 (deg)
    zero = np.zeros(6)
    assert np.allclose(robot.forward(zero), [0.465, 0, 0.365], atol=1e-12)
    R = Rotation.from_euler("ZYX", np.radians([0, -90, 180])).as_matrix()  # Rz(R) Ry(P) Rx(W)
    assert np.allclose(robot.flange_rotation(zero[None])[0], R, atol=1e-12)
    # the usual home with the tool down (J5 = -90): faceplate 80 mm below the wrist centre (385, 0, 365)
    assert np.allclose(robot.forward(np.radians([0, 0, 0, 0, -90, 0])), [0.385, 0, 0.285], atol=1e-12)
    # FANUC's data sheet: reach 717 mm (the wrist centre's farthest horizontal distance from the J1 axis)
    wrist = robot.with_tool_point([0, 0, -0.080])

    def minus_reach(j23):
        p = wrist.forward(np.array([0.0, *j23, 0.0, 0.0, 0.0]))
        return -np.hypot(p[0], p[1]) * 1e3

    best = minimize(minus_reach, np.radians([80.0, 0.0]), bounds=list(zip(robot.lower[1:3], robot.upper[1:3])))
    assert abs(-best.fun - 717.0) < 0.5 and abs(-best.fun - (50 + 330 + np.hypot(335, 35))) < 1e-6


# --- the 'coupled' transmission map ----------------------------------------------------------------

def _central(f, x, h=1e-6):
    cols = []
    for k in range(x.shape[-1]):
        e = np.zeros(x.shape[-1])
        e[k] = h
        cols.append((f(x + e) - f(x - e)) / (2 * h))
    return np.stack(cols, axis=-1)


def test_coupled_map_jacobians_match_central_differences(robot):
    perturbed = kincal.perturb(robot, 1e-3, 1e-2, seed=5, include_base=True)
    q = perturbed.sample_joints(20, seed=1)
    Jq = perturbed.joint_jacobian(q)
    Jq_num = _central(lambda x: perturbed.forward(x), q)
    assert np.abs(Jq - Jq_num).max() / np.abs(Jq_num).max() < 1e-7
    v = perturbed.params.values
    Jp_num = _central(lambda x: perturbed.forward(q, x), v)
    Jp = perturbed.param_jacobian(q)
    assert Jp.shape == (20, 3, perturbed.n_params)
    assert np.abs(Jp - Jp_num).max() / np.abs(Jp_num).max() < 1e-7


def test_coupled_map_with_other_factors_and_its_file():
    chain_only = kincal.load_robot(NAME).inner
    for k in (-1.0, 0.0, 0.5):
        maps = [Map("direct", (0,), (0,)), Map("coupled", (1, 2), (1, 2), factor=k),
                *(Map("direct", (i,), (i,)) for i in (3, 4, 5))]
        r = build_transmission_robot(chain_only, [(f"J{i}", -3.0, 3.0) for i in range(1, 7)], maps, {})
        q = np.radians([[5.0, 30.0, -20.0, 1.0, 2.0, 3.0]])
        assert np.allclose(r.chain_q(q)[0, 2], q[0, 2] + k * q[0, 1])
        assert np.allclose(r.joint_jacobian(q), _central(r.forward, q), atol=1e-8)
        again = robot_from_dict(yaml.safe_load(robot_to_yaml(r, "mm", "deg")), "again")
        assert again.maps[1].factor == k and np.allclose(again.forward(q), r.forward(q), atol=1e-12)
    with pytest.raises(ModelError, match="factor"):
        Map("direct", (0,), (0,), factor=2.0)
    with pytest.raises(ModelError, match="coupled"):
        Map("coupled", (0,), (0,))


def test_the_bundled_file_round_trips(robot):
    again = robot_from_dict(yaml.safe_load(robot_to_yaml(robot, "mm", "deg")), "again")
    q = robot.sample_joints(50, seed=2)
    assert np.allclose(again.forward(q), robot.forward(q), atol=1e-12)
    assert again.joint_names == robot.joint_names and again.maps[1].type == "coupled"


# --- CONFIG ------------------------------------------------------------------------------------------

def _closed_form(J: np.ndarray) -> tuple[str, str]:
    """Elbow and front letters from the published dimensions (mm) in the arm's plane: J3 axis at
    (50 + 330 sin J2, 330 cos J2); the wrist centre 335 along and 35 across the forearm, which is J3
    from the horizontal (deg)."""
    j2, j3 = np.radians(J[1]), np.radians(J[2])
    u = np.array([np.sin(j2), np.cos(j2)])  # upper arm, J2 axis -> J3 axis, in (forward, up)
    w = np.array([335 * np.cos(j3) - 35 * np.sin(j3), 335 * np.sin(j3) + 35 * np.cos(j3)])
    front = 50 + 330 * np.sin(j2) + w[0]
    return ("U" if u[1] * w[0] - u[0] * w[1] > 0 else "D"), ("T" if front >= 0 else "B")


def test_config_letters_against_closed_forms(robot):
    rng = np.random.default_rng(7)
    J = rng.uniform(np.degrees(robot.lower), np.degrees(robot.upper), size=(2000, 6))
    for j in J:
        letters, *_ = config_of(robot, np.radians(j))
        elbow, front = _closed_form(j)
        assert letters == f"{'F' if j[4] >= 0 else 'N'} {elbow} {front}"


def test_config_on_either_side_of_each_boundary(robot):
    eps = 1e-6  # deg
    home = np.array([0.0, 0.0, 0.0, 0.0, -90.0, 0.0])  # tool down in front: FANUC's usual 'N U T, 0, 0, 0'
    assert config_of(robot, np.radians(home)) == ("N U T", 0, 0, 0)
    cases = []
    # wrist flip: the sign of J5
    cases += [((0, 0, 0, 0, -eps, 0), "N U T"), ((0, 0, 0, 0, eps, 0), "F U T")]
    # elbow: J2 + J3 = atan2(335, 35) = 84.036 deg (arm folded up) and -95.964 deg
    up = np.degrees(np.arctan2(335, 35))
    for j2 in (-30.0, 0.0, 40.0):
        cases += [((0, j2, up - j2 - 1e-4, 0, -10, 0), "N U"), ((0, j2, up - j2 + 1e-4, 0, -10, 0), "N D")]
        cases += [((0, j2, up - 180 - j2 + 1e-4, 0, -10, 0), "N U"), ((0, j2, up - 180 - j2 - 1e-4, 0, -10, 0), "N D")]
    # front/back: the wrist centre crosses the plane of the J1 axis: 50 + 330 sin J2 + 335 cos J3 - 35 sin J3 = 0
    def ahead(j2, j3):  # mm
        return 50 + 330 * np.sin(np.radians(j2)) + 335 * np.cos(np.radians(j3)) - 35 * np.sin(np.radians(j3))

    for j2 in (-100.0, -60.0):
        lo, hi = 0.0, 180.0  # ahead > 0 at J3 = 0, < 0 at 180: bisect
        for _ in range(80):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if ahead(j2, mid) > 0 else (lo, mid)
        cases += [((30, j2, lo - 1e-4, 0, -10, 0), " T"), ((30, j2, hi + 1e-4, 0, -10, 0), " B")]
    for J, want in cases:
        letters = config_of(robot, np.radians(J))[0]
        assert letters.startswith(want) or letters.endswith(want), (J, letters, want)


def test_turn_numbers_and_the_other_wrist(robot):
    def turns(j1, j4, j6):
        return config_of(robot, np.radians([j1, 0, 0, j4, -30, j6]))[1:]
    assert turns(179.999, -179.999, 0) == (0, 0, 0)
    assert turns(180, -180, 539.999) == (1, -1, 1)
    assert turns(-180.001, 180.001, -540) == (-1, 1, -2)
    assert turns(540, 0, -539.999) == (2, 0, -1)
    # the same faceplate pose on the flipped wrist: J4 + 180, -J5, J6 - 180 (FANUC writes both, told by F/N and turns)
    J = np.radians([20.0, 10.0, -5.0, 30.0, -40.0, 50.0])
    other = J + np.radians([0, 0, 0, 180, 0, -180])
    other[4] = -J[4]
    assert np.allclose(robot.forward(other), robot.forward(J), atol=1e-12)
    assert np.allclose(robot.flange_rotation(other[None]), robot.flange_rotation(J[None]), atol=1e-12)
    assert config_of(robot, J) == ("N U T", 0, 0, 0) and config_of(robot, other) == ("F U T", 0, 1, 0)


def test_config_of_refuses_what_is_not_a_six_axis_arm(robot):
    with pytest.raises(ModelError, match="defined for six-axis arms; got 5 joint values"):
        config_of(robot, np.zeros(5))
    with pytest.raises(ModelError, match="defined for six-axis arms; got 4 joint values for 4 joints"):
        config_of(kincal.load_robot("scara"), np.zeros(4))


def test_real_fanuc_targets():
    """The data folder's FANUC programs carry no Cartesian position (no CONFIG to compare with): their only
    literal targets are joint positions of arms of unknown model. What does not depend on the arm's lengths
    (the flip letter, the turn numbers) is what the controller would write for them."""
    folder = shared_dataset("robot_programs") / "fanuc"
    configs = []
    for path in sorted(p for p in folder.rglob("*") if p.suffix.lower() == ".ls"):
        text = path.read_text(encoding="latin-1")
        assert not re.search(r"CONFIG\s*:", text), path
        for t in read_program(str(path), "fanuc").targets:
            assert t.kind == "joints" and t.config == ()
            configs.append((path.name, config_of(kincal.load_robot(NAME), t.values)))
    names = {n: (c[0][0], c[1:]) for n, c in configs}
    # PRO_MOV2.LS: J5 = -81.876, J1 = -43.937, J4 = 0, J6 = -7.906; move_to_home.ls: J5 = 121.424,
    # J1 = 127.834, J4 = -110.295, J6 = 54.899
    assert names == {"PRO_MOV2.LS": ("N", (0, 0, 0)), "move_to_home.ls": ("F", (0, 0, 0))}
