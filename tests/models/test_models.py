"""Robot models: forward kinematics against independent computations, analytic Jacobians against
central differences, robot YAML files."""

import numpy as np
import pytest
from conftest import DATA, PANDA_URDF, ROOT, SOCKETS, UR5_COLS, UR5_URDF, central_jacobian

import kincal
from kincal import Joint, ModelError, SerialRobot


def dh_matrix(theta, d, a, alpha):
    """Craig's standard DH link transform, written out by hand."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct],
                     [st, ct * ca, -ct * sa, a * st],
                     [0, sa, ca, d],
                     [0, 0, 0, 1.0]])


UR5_D = [0.089159, 0, 0, 0.10915, 0.09465, 0.0823]
UR5_A = [0, -0.425, -0.39225, 0, 0, 0]
UR5_ALPHA = [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0]


def ur5_by_hand(q, tool):
    T = np.eye(4)
    for i in range(6):
        T = T @ dh_matrix(q[i], UR5_D[i], UR5_A[i], UR5_ALPHA[i])
    return (T @ np.append(tool, 1.0))[:3]


def test_ur5_forward_matches_hand_computation(ur5):
    q = ur5.sample_joints(25, seed=4)
    expected = np.array([ur5_by_hand(qi, [0, 0.09e-3, 31.0e-3]) for qi in q])
    np.testing.assert_allclose(ur5.forward(q), expected, atol=1e-12)


def test_ur5_zero_pose_closed_form(ur5):
    flange = ur5.with_params({"tool.y": 0.0, "tool.z": 0.0})
    # at q = 0 the UR5 flange sits at (a2 + a3, -(d4 + d6), d1 - d5)
    expected = [-0.425 - 0.39225, -(0.10915 + 0.0823), 0.089159 - 0.09465]
    np.testing.assert_allclose(flange.forward(np.zeros(6)), expected, atol=1e-12)


def test_ur5_matches_dataset_nominal_targets(ur5):
    d = np.genfromtxt(DATA / "ur5_grid.csv", delimiter=",", names=True)
    q = np.deg2rad(np.column_stack([d[c] for c in UR5_COLS]))
    target = np.column_stack([d["x_target"], d["y_target"], d["z_target"]]) * 1e-3
    assert np.abs(ur5.forward(q) - target).max() < 0.05e-3  # the README says 0.05 mm


def random_robot(convention, seed):
    """A random 6-joint chain with a prismatic joint, parallel axes (β) and non-zero base and tool."""
    rng = np.random.default_rng(seed)
    types = ["revolute", "revolute", "revolute", "prismatic", "revolute", "revolute"]
    joints, rows = [], []
    for k, t in enumerate(types):
        joints.append(Joint(f"j{k + 1}", t, beta=(k in (1, 4)), lower=-2.0, upper=2.0, velocity=1.0, effort=10.0))
        rows.append({"theta": rng.uniform(-1, 1), "d": rng.uniform(-0.3, 0.3), "a": rng.uniform(-0.5, 0.5),
                     "alpha": rng.uniform(-2, 2), "beta": rng.uniform(-0.1, 0.1)})
        if not joints[-1].beta:
            rows[-1].pop("beta")
    base = dict(zip(["x", "y", "z", "rx", "ry", "rz"], rng.uniform(-1, 1, 6)))
    tool = dict(zip("xyz", rng.uniform(-0.1, 0.1, 3)))
    return SerialRobot.build(f"random-{convention}", convention, joints, rows, base, tool)


@pytest.mark.parametrize("convention", ["dh", "mdh"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_param_jacobian_matches_central_differences(convention, seed):
    robot = random_robot(convention, seed)
    q = robot.sample_joints(30, seed=seed)
    J = robot.param_jacobian(q)
    Jn = central_jacobian(robot, q)
    assert J.shape == (30, 3, robot.n_params)
    assert np.abs(J - Jn).max() / np.abs(Jn).max() < 1e-6
    # every parameter column is exercised (none silently zero)
    assert np.all(np.linalg.norm(J, axis=(0, 1)) > 0)


@pytest.mark.parametrize("name", ["ur5", "ur10", "wam", "scara"])
def test_bundled_jacobians_match_central_differences(name):
    robot = kincal.perturb(kincal.load_robot(name), 1e-3, 1e-2, seed=5, include_base=True)
    q = robot.sample_joints(20, seed=1)
    Jn = central_jacobian(robot, q)
    assert np.abs(robot.param_jacobian(q) - Jn).max() / np.abs(Jn).max() < 1e-6


@pytest.mark.parametrize("name", ["ur5", "scara", "panda"])
def test_frame_rates_match_central_differences(name):
    """Robot.frame_and_rates (a chain reads the rotation rate off its ops' world axes) against central
    differences of the flange rotation, which comes from positions alone; over two blocks of configurations."""
    from kincal.models.chain import BLOCK
    from scipy.spatial.transform import Rotation
    base = (kincal.load_robot(PANDA_URDF, tip_link="ball_link")
            if name == "panda"
            else kincal.load_robot(name))
    robot = kincal.perturb(base.with_tool_point([0.05, -0.02, 0.1]), 1e-3, 1e-2, seed=5, include_base=True)
    q = robot.sample_joints(BLOCK + 7, seed=1)
    p, J, R, Jw = robot.frame_and_rates(q)
    p0, J0 = robot.forward_and_jacobian(q)
    assert np.array_equal(p, p0) and np.array_equal(J, J0)
    np.testing.assert_allclose(R, robot.flange_rotation(q), atol=1e-12)
    v, h = robot.params.values, 1e-6
    for k in range(robot.n_params):
        e = np.zeros_like(v)
        e[k] = h
        turn = robot.flange_rotation(q, v + e) @ robot.flange_rotation(q, v - e).transpose(0, 2, 1)
        np.testing.assert_allclose(Jw[:, :, k], Rotation.from_matrix(turn).as_rotvec() / (2 * h), atol=1e-7)


def test_joint_jacobian_matches_central_differences():
    robot = random_robot("dh", 3)
    q = robot.sample_joints(10, seed=2)
    h = 1e-6
    Jn = np.stack([(robot.forward(q + h * e) - robot.forward(q - h * e)) / (2 * h) for e in np.eye(6)], axis=2)
    np.testing.assert_allclose(robot.joint_jacobian(q), Jn, atol=1e-8)


def test_mdh_equals_dh_for_the_same_geometry():
    # a 2R planar arm: DH (a1, a2) and MDH (a on the following joint + tool offset) describe one machine
    dh = SerialRobot.build("p", "dh", [Joint("j1"), Joint("j2")], [{"a": 0.4}, {"a": 0.3}])
    mdh = SerialRobot.build("p", "mdh", [Joint("j1"), Joint("j2")], [{}, {"a": 0.4}], tool={"x": 0.3})
    q = dh.sample_joints(10, seed=0)
    np.testing.assert_allclose(dh.forward(q), mdh.forward(q), atol=1e-14)
    np.testing.assert_allclose(dh.forward(q)[:, 0], 0.4 * np.cos(q[:, 0]) + 0.3 * np.cos(q.sum(1)), atol=1e-14)


def test_prismatic_joint_moves_along_its_axis():
    scara = kincal.load_robot("scara")
    q = np.array([[0.3, -0.2, 0.05, 0.1], [0.3, -0.2, 0.15, 0.1]])
    p = scara.forward(q)
    # joint 3 points down (alpha2 = 180 deg): 100 mm more stroke is 100 mm lower
    np.testing.assert_allclose(p[1] - p[0], [0, 0, -0.1], atol=1e-14)


def test_beta_detected_on_parallel_axes(ur5):
    assert [j.beta for j in ur5.joints] == [False, True, True, False, False, False]
    assert "j2.beta" in ur5.params and "j6.beta" not in ur5.params
    assert ur5.structure_notes() == []
    no_beta = ur5.with_joints([Joint(j.name, j.type, False, j.lower, j.upper) for j in ur5.joints])
    notes = no_beta.structure_notes()
    assert len(notes) == 2 and "j2" in notes[0] and "beta" in notes[0]


def test_yaml_round_trip_is_exact(tmp_path, ur5):
    robot = kincal.perturb(ur5, seed=9, include_base=True)
    path = tmp_path / "r.yaml"
    kincal.save_robot(robot, path)
    back = kincal.load_robot(path)
    assert back.params == robot.params
    assert [(j.name, j.type, j.beta, j.lower, j.upper) for j in back.joints] == \
           [(j.name, j.type, j.beta, j.lower, j.upper) for j in robot.joints]
    assert back.convention == robot.convention and back.description == robot.description
    # and in engineering units it agrees to rounding
    kincal.save_robot(robot, path, "mm", "deg")
    np.testing.assert_allclose(kincal.load_robot(path).params.values, robot.params.values, rtol=1e-15, atol=1e-18)


def test_yaml_beta_override(tmp_path):
    text = """name: two
convention: dh
units: {length: mm, angle: deg}
joints:
  - {name: j1, a: 300, alpha: 0, beta: false}
  - {name: j2, a: 200, alpha: 0}
"""
    path = tmp_path / "two.yaml"
    path.write_text(text)
    r = kincal.load_robot(path)
    assert [j.beta for j in r.joints] == [False, False]  # j1 switched off explicitly; j2 has no successor
    assert len(r.structure_notes()) == 1
    path.write_text(text.replace("beta: false", "beta: 0.5"))
    r = kincal.load_robot(path)
    assert r.params["j1.beta"] == pytest.approx(np.deg2rad(0.5))
    path.write_text(text.replace("beta: false", "beta: 0"))  # zero is a value, not "off"
    assert kincal.load_robot(path).joints[0].beta


@pytest.mark.parametrize("text,fragment", [
    ("name: x\nconvention: dh\njoints: []\n", "non-empty list"),
    ("name: x\nconvention: xyz\njoints: [{a: 1}]\n", "convention"),
    ("name: x\nconvention: dh\njoints: [{a: 1, lenght: 2}]\n", "lenght"),
    ("name: x\nconvention: dh\njoints: [{a: one}]\n", "'a' must be a number"),
    ("name: x\nconvention: dh\nunits: {length: inch}\njoints: [{a: 1}]\n", "unknown length unit"),
    ("name: x\nconvention: dh\njoints: [{a: 1, limits: [1, -1]}]\n", "lower < upper"),
])
def test_bad_robot_files_name_the_problem(tmp_path, text, fragment):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ModelError, match=fragment) as exc:
        kincal.load_robot(path)
    assert "bad.yaml" in str(exc.value) or "joint" in str(exc.value)


def test_unknown_robot_and_parameter_names(ur5):
    with pytest.raises(ModelError, match="bundled robot"):
        kincal.load_robot("ur55")
    with pytest.raises(ModelError, match="unknown parameter 'j9.a'"):
        ur5.with_params({"j9.a": 1.0})
    with pytest.raises(ModelError, match=r"expected \(N, 6\)"):
        ur5.forward(np.zeros((3, 5)))


def test_models_are_immutable(ur5):
    with pytest.raises(ValueError):
        ur5.params.values[0] = 1.0
    moved = ur5.with_params({"j2.a": -0.43})
    assert ur5.params["j2.a"] == -0.425 and moved.params["j2.a"] == -0.43


def test_cos_sin_matches_numpy_everywhere():
    from kincal.models.chain import cos_sin
    x = np.concatenate([np.linspace(-50, 50, 200001), np.pi * np.arange(-8, 9) / 2, [0.0, -0.0, 1e-300]])
    c, s = cos_sin(x)
    assert np.abs(c - np.cos(x)).max() < 1e-15 and np.abs(s - np.sin(x)).max() < 1e-15


def test_rotation_helpers_against_scipy():
    """skew(v) @ u is v × u, and rotvec_matrix is scipy's rotation of the same vector (small and large)."""
    from scipy.spatial.transform import Rotation
    from kincal.models.transforms import rotvec_matrix, skew
    rng = np.random.default_rng(5)
    v, u = rng.normal(size=(7, 3)), rng.normal(size=(7, 3))
    np.testing.assert_allclose(np.einsum("nij,nj->ni", skew(v), u), np.cross(v, u), atol=1e-14)
    for w in (rng.normal(size=3), 1e-13 * rng.normal(size=3), np.array([0.0, 0.0, np.pi - 1e-9])):
        np.testing.assert_allclose(rotvec_matrix(w), Rotation.from_rotvec(w).as_matrix(), atol=1e-12)


def test_a_robot_file_states_its_controllers_language_and_keeps_it(tmp_path):
    """language: the bundled vendor arms say theirs (the languages kincal.io reads, and URScript); a calibrated
    robot saved and loaded keeps it, an error model's wrapper reports its inner robot's, and a language kincal does
    not read is refused naming the ones it does."""
    from kincal.io import dialects
    from kincal.models.yaml_io import LANGUAGES
    assert set(LANGUAGES) == {"ur", *dialects()}
    said = {n: kincal.load_robot(n).program_language() for n in ("ur5", "ur10", "kuka_kr6r900sixx", "abb_irb120",
                                                                 "fanuc_lrmate200id", "motoman_gp7", "wam")}
    assert said == {"ur5": "ur", "ur10": "ur", "kuka_kr6r900sixx": "krl", "abb_irb120": "rapid",
                    "fanuc_lrmate200id": "fanuc", "motoman_gp7": "inform", "wam": ""}
    robot = kincal.perturb(kincal.load_robot("kuka_kr6r900sixx"), seed=1)
    kincal.save_robot(robot, tmp_path / "k.yaml", "mm", "deg")
    assert kincal.load_robot(tmp_path / "k.yaml").program_language() == "krl"
    from kincal.models.terms import extend
    assert extend(robot, "harmonics:1", robot.sample_joints(20, seed=1)).program_language() == "krl"
    text = (tmp_path / "k.yaml").read_text().replace("language: krl", "language: karel")
    (tmp_path / "bad.yaml").write_text(text)
    with pytest.raises(kincal.ModelError, match="language 'karel' is not one of ur, krl, rapid, fanuc, inform"):
        kincal.load_robot(tmp_path / "bad.yaml")


@pytest.mark.parametrize("angle, advice", [("rad", "units: {length: mm, angle: rad}"),
                                           ("deg", "units: {length: mm, angle: deg}")])
def test_a_robot_file_without_units_is_told_the_units_it_is_in(tmp_path, angle, advice):
    """A UR5 file with its lengths in mm and no units line: the advice names mm for the lengths and, for angles
    written in radians, keeps radians (it said 'angle: deg', which loaded the arm with 0.785 deg twists); the
    file with the advised line is the UR5."""
    ur5 = kincal.load_robot("ur5")
    path = tmp_path / "arm.yaml"
    kincal.save_robot(ur5, path, length_unit="mm", angle_unit=angle)
    text = "".join(line for line in path.read_text().splitlines(True) if not line.startswith("units:"))
    path.write_text(text)
    with pytest.raises(ModelError) as e:
        kincal.load_robot(path)
    assert f"add '{advice}'" in str(e.value)
    path.write_text(text.replace("joints:", advice + "\njoints:", 1))
    again = kincal.load_robot(path)
    assert np.allclose(again.params.values, ur5.params.values, rtol=1e-12, atol=1e-12)


def _ur5_file(tmp_path, length="m", angle="rad", edit=lambda text: text):
    """The bundled UR5 saved in ``length``/``angle`` units, its text changed by ``edit``; the path."""
    path = tmp_path / f"ur5_{length}_{angle}.yaml"
    kincal.save_robot(kincal.load_robot("ur5"), path, length_unit=length, angle_unit=angle)
    path.write_text(edit(path.read_text()))
    return path


def test_joint_limits_in_the_other_angle_unit_are_refused_naming_the_joint(tmp_path):
    """A UR5 file in m and rad with its limits written in degrees (±360, the elbow ±180) loaded as ±57.3 turns
    and designed a URScript program whose elbow went to 153 rad; the converse (±2π written in a deg file) kept
    every joint within ±6.3 deg. Both are refused, naming the joint, the limits as written and the same limits in
    the file's unit (360 deg = 2π rad = 6.28319; 2π rad = 360 deg)."""
    two_pi = f"{2 * np.pi!r}"
    degrees = _ur5_file(tmp_path, edit=lambda t: t.replace(f"[-{two_pi}, {two_pi}]", "[-360, 360]")
                        .replace(f"[-{np.pi!r}, {np.pi!r}]", "[-180, 180]"))
    with pytest.raises(ModelError) as e:
        kincal.load_robot(degrees)
    said = str(e.value)
    assert f"joint j1's limits [-360, 360] rad reach {360 / (2 * np.pi):.3g} turns" in said
    assert "look like degrees" in said and f"write them in rad ([-{2 * np.pi:.6g}, {2 * np.pi:.6g}])" in said
    radians = _ur5_file(tmp_path, angle="deg", edit=lambda t: t.replace("[-360.0, 360.0]", "[-6.2832, 6.2832]")
                        .replace("[-180.0, 180.0]", "[-3.1416, 3.1416]"))
    with pytest.raises(ModelError) as e:
        kincal.load_robot(radians)
    said = str(e.value)
    assert "every revolute joint's limits lie within ±6.283 deg (joint j1: [-6.2832, 6.2832] deg)" in said
    assert "look like radians" in said and f"write them in deg ([-{6.2832 * 180 / np.pi:.6g}," in said
    no_units = _ur5_file(tmp_path, edit=lambda t: t.replace(f"[-{two_pi}, {two_pi}]", "[-360, 360]")
                         .replace("units: {length: m, angle: rad}\n", ""))
    with pytest.raises(ModelError, match=r"the default: the file has no 'units' key.*add 'units: \{angle: deg\}'"):
        kincal.load_robot(no_units)
    wide = kincal.load_robot("abb_irb120")  # axis 6 turns ±400 deg: 1.11 turns, within 2
    assert wide.upper[5] == pytest.approx(np.radians(400))


def test_prismatic_limits_in_the_other_length_unit_are_refused(tmp_path):
    """The SCARA's quill (0..200 mm) written in mm in an m file reaches 200 m; written in m in a mm file it
    travels 0.2 mm: both refused, naming the joint and its limits in the file's unit."""
    scara = tmp_path / "scara.yaml"
    kincal.save_robot(kincal.load_robot("scara"), scara)  # m, rad
    text = scara.read_text()
    assert "limits: [0.0, 0.2]" in text
    scara.write_text(text.replace("limits: [0.0, 0.2]", "limits: [0.0, 200]"))
    with pytest.raises(ModelError, match=r"joint j3's limits \[0, 200\] m reach 200 m from zero; .* look like mm .*"
                                         r"write them in m \(\[0, 0\.2\]\)"):
        kincal.load_robot(scara)
    kincal.save_robot(kincal.load_robot("scara"), scara, length_unit="mm", angle_unit="deg")
    text = scara.read_text()
    assert "limits: [0.0, 200.0]" in text
    scara.write_text(text.replace("limits: [0.0, 200.0]", "limits: [0.0, 0.2]"))
    with pytest.raises(ModelError, match=r"every prismatic joint's limits lie within ±0\.2 mm .* look like metres"
                                         r".*write them in mm \(\[0, 200\]\)"):
        kincal.load_robot(scara)


UR5_REACH = sum(UR5_D) + sum(map(abs, UR5_A))  # m: UR's DH table, the links from the base frame to the flange


def test_a_tool_point_written_in_mm_in_an_m_file_is_refused(tmp_path):
    """The UR5's reflector written in mm (0, 0.09, 31) in an m file loaded as a probe 31 m long (`show` printed
    tool.z 31000 mm), while `--tool 0,0.09,31` was refused as mm: the file is refused alike, with the same bound
    (2 m from the flange), the arm's reach beside it and the values to write."""
    path = _ur5_file(tmp_path, edit=lambda t: t.replace("tool: {x: 0.0, y: 8.999999999999999e-05, z: 0.031}",
                                                        "tool: {x: 0, y: 0.09, z: 31.0}"))
    with pytest.raises(ModelError) as e:
        kincal.load_robot(path)
    said = str(e.value)
    assert f"the tool point (0, 0.09, 31) m lies {np.hypot(0.09, 31):.4g} m from the flange" in said
    assert f"the reach of the robot itself is {UR5_REACH:.3g} m" in said
    assert "these look like mm: write them in m (0, 9e-05, 0.031)" in said


@pytest.mark.parametrize("written, declared, looks, advice", [
    (1.0, "mm", "m", "set 'length: m' in its 'units'"),  # metres read as mm: a 1.19 mm UR5
    (100.0, "m", "cm", "write the lengths in mm (x10) and set 'length: mm'"),  # cm read as m: 42.5 m links
    (1000.0, "m", "mm", "set 'length: mm' in its 'units'")])
def test_a_robot_file_in_another_length_unit_is_refused_by_its_reach(tmp_path, written, declared, looks, advice):
    """The UR5's lengths written in m (cm, mm) in a file declared mm (m): its reach, the DH lengths added up
    (1.1925 m), is 1.19 mm (119 m, 1193 m); the m-as-mm file designed poses whose note blamed the joint terms.
    Refused, naming the reach as read, the unit that makes it 1.19 m and how to write it."""
    ur5 = kincal.load_robot("ur5")
    scaled = ur5.with_params({n: v * written for n, v, k in zip(ur5.params.names, ur5.params.values,
                                                                 ur5.params.kinds) if k == "length"})
    path = tmp_path / "arm.yaml"
    text = kincal.models.yaml_io.robot_to_yaml(scaled)  # in m (save_robot refuses to write 119 m links)
    path.write_text(text.replace("units: {length: m,", f"units: {{length: {declared},"))
    with pytest.raises(ModelError) as e:
        kincal.load_robot(path)
    said = str(e.value)
    read = UR5_REACH * written * kincal.units.LENGTH_UNITS[declared]
    assert f"the arm's reach is {read:.4g} m as read in {declared}, implausible for a robot (5 mm to 20 m)" in said
    assert f"the lengths look like {looks} (a reach of {UR5_REACH:.3g} m)" in said and advice in said


def _robot_files():
    """Every robot kincal ships or reads in its data: the bundled ones, the examples' files, the datasets'
    URDFs (with the tip link their tests use)."""
    return ([(name, {}) for name in kincal.bundled_robots()]
            + [(p, {}) for p in sorted((ROOT / "examples").glob("*.yaml"))]
            + [(UR5_URDF, {"tip_link": "tool0"}), (PANDA_URDF, {"tip_link": "ball_link"}),
               (SOCKETS / "panda_2_calibrated_by_authors.urdf", {"tip_link": "ball_link"})])


@pytest.mark.parametrize("source, links", _robot_files(), ids=lambda v: str(v).rsplit("/", 1)[-1] if v else "")
def test_every_shipped_robot_is_plausible_in_any_units(tmp_path, source, links):
    """Every bundled robot, example robot file and dataset URDF loads, passes the size, tool and limit checks, and
    loads back when saved in mm and deg and in m and rad (the checks judge each file in its own units)."""
    from kincal.models.plausible import MAX_REACH, MAX_TOOL, MIN_REACH, arm_size, check_limits, check_size
    robot = kincal.load_robot(source, **links)
    check_size(robot, "r"), check_limits(robot, "r")
    size, _ = arm_size(robot)
    assert MIN_REACH <= size <= MAX_REACH
    assert not robot.has_tool_point or np.linalg.norm(robot.tool_point()) <= MAX_TOOL
    if "tip_link" in links:
        return  # a URDF is saved as a reference to its file
    for length, angle in (("mm", "deg"), ("m", "rad")):
        kincal.save_robot(robot, tmp_path / "r.yaml", length_unit=length, angle_unit=angle)
        assert np.allclose(kincal.load_robot(tmp_path / "r.yaml").params.values, robot.params.values, atol=1e-9)
