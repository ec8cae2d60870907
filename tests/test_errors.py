"""Bad input: every error names what is wrong and what to do, through the API and the CLI."""
import numpy as np
import pytest
from conftest import DATA, UR5_COLS

import kincal
from kincal import MeasurementError
from kincal.cli import main

MMDEG = ["--length-unit", "mm", "--angle-unit", "deg", "--joint-cols", ",".join(UR5_COLS)]


def write_csv(path, ur5, q, xyz, length="m", angle="rad"):
    kincal.write_measurements(path, kincal.Measurements(q, xyz, ur5.joint_names), ur5.joint_types, length, angle)


@pytest.fixture
def good(tmp_path, ur5):
    q = ur5.sample_joints(30, seed=0)
    xyz = kincal.perturb(ur5).forward(q)
    path = tmp_path / "good.csv"
    write_csv(path, ur5, q, xyz)
    return path, q, xyz


def run_cli(capsys, *argv):
    code = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_nan_rows_are_named(tmp_path, ur5, good, capsys):
    good_path, _, _ = good
    lines = good_path.read_text().splitlines()
    for row in (5, 9):  # file lines (header = 1)
        lines[row - 1] = lines[row - 1].rsplit(",", 1)[0] + ",nan"
    path = tmp_path / "nan.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(MeasurementError, match=r"nan.csv: NaN or infinite values in row\(s\) 5, 9"):
        kincal.read_measurements(path, ur5)
    code, _, err = run_cli(capsys, "calibrate", "ur5", path)
    assert code == 1 and "row(s) 5, 9" in err and err.count("\n") == 1


def test_non_numeric_cell_is_located(tmp_path, ur5, good):
    path, _, _ = good
    lines = path.read_text().splitlines()
    cells = lines[4].split(",")
    cells[2] = "abc"
    lines[4] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(MeasurementError, match="row 5, column 'j3': 'abc' is not a number"):
        kincal.read_measurements(path, ur5)


def test_missing_columns_list_the_header(ur5, good, capsys):
    path, _, _ = good
    with pytest.raises(MeasurementError, match="column.*joint_1.*the header has: j1"):
        kincal.read_measurements(path, ur5, joint_cols=UR5_COLS)
    code, _, err = run_cli(capsys, "evaluate", "ur5", path, "--joint-cols", ",".join(UR5_COLS))
    assert code == 1 and "joint_1" in err


def test_joint_count_mismatch(ur5, good, capsys):
    path, q, xyz = good
    with pytest.raises(MeasurementError, match="5 joint columns given.*6 joints"):
        kincal.read_measurements(path, ur5, joint_cols=["j1", "j2", "j3", "j4", "j5"])
    wam = kincal.load_robot("wam")
    with pytest.raises(MeasurementError, match="6 joint columns but robot 'wam' has 7"):
        kincal.calibrate(wam, kincal.Measurements(q, xyz, ur5.joint_names))
    code, _, err = run_cli(capsys, "calibrate", "wam", path)
    assert code == 1 and "j7 not found" in err


def test_mm_read_as_metres_and_the_reverse(ur5, capsys):
    path = DATA / "ur5_grid.csv"
    with pytest.raises(MeasurementError, match="look like mm; use length unit 'mm' .CLI: --length-unit mm"):
        kincal.read_measurements(path, ur5, joint_cols=UR5_COLS, angle_unit="deg")
    code, _, err = run_cli(capsys, "calibrate", "ur5", path, "--angle-unit", "deg", "--joint-cols", ",".join(UR5_COLS))
    assert code == 1 and "--length-unit mm" in err


def test_metres_read_as_mm(tmp_path, ur5, good):
    path, _, _ = good
    with pytest.raises(MeasurementError, match="look like m; use length unit 'm'"):
        kincal.read_measurements(path, ur5, length_unit="mm")


def test_degrees_read_as_radians(ur5, capsys):
    with pytest.raises(MeasurementError, match="look like degrees.*--angle-unit deg"):
        kincal.read_measurements(DATA / "ur5_grid.csv", ur5, joint_cols=UR5_COLS, length_unit="mm")
    code, _, err = run_cli(capsys, "evaluate", "ur5", DATA / "ur5_grid.csv", "--length-unit", "mm",
                           "--joint-cols", ",".join(UR5_COLS))
    assert code == 1 and "degrees" in err


def test_too_few_measurements(ur5, good, capsys):
    path, q, xyz = good
    few = kincal.Measurements(q[:4], xyz[:4], ur5.joint_names, source="few.csv")
    with pytest.raises(MeasurementError, match="4 poses give 12 equations.*measure at least"):
        kincal.calibrate(ur5, few)
    small = path.parent / "few.csv"
    small.write_text("\n".join(path.read_text().splitlines()[:5]) + "\n")
    code, _, err = run_cli(capsys, "calibrate", "ur5", small)
    assert code == 1 and "measure at least" in err


def test_not_converged_is_reported(ur5, good, tmp_path, capsys):
    path, q, xyz = good
    res = kincal.calibrate(ur5, kincal.Measurements(q, xyz, ur5.joint_names), max_iter=1)
    assert not res.converged and "without meeting the tolerances" in res.message
    assert "NOT CONVERGED" in str(res)
    code, out, err = run_cli(capsys, "calibrate", "ur5", path, "--max-iter", "1", "-o", tmp_path / "c.yaml")
    assert code == 3 and "did not converge" in err


def test_semicolon_separated_file(tmp_path, ur5, good):
    path, q, _ = good
    semi = tmp_path / "semi.csv"
    semi.write_text(path.read_text().replace(",", ";"))
    np.testing.assert_allclose(kincal.read_measurements(semi, ur5).q, q)


def test_bad_option_values(ur5, good):
    path, q, xyz = good
    meas = kincal.Measurements(q, xyz, ur5.joint_names)
    with pytest.raises(ValueError, match="base='tracker'"):
        kincal.calibrate(ur5, meas, base="tracker")
    with pytest.raises(ValueError, match="loss='cauchy'"):
        kincal.calibrate(ur5, meas, loss="cauchy")
    with pytest.raises(MeasurementError, match="unknown length unit 'inch'"):
        kincal.read_measurements(path, ur5, length_unit="inch")


def test_missing_file_and_unknown_robot(capsys, tmp_path):
    code, _, err = run_cli(capsys, "evaluate", "ur5", tmp_path / "nope.csv")
    assert code == 1 and "nope.csv" in err
    code, _, err = run_cli(capsys, "show", "ur55")
    assert code == 1 and "neither a bundled robot" in err


@pytest.mark.parametrize("tool", ["1,2", [1, 2], [1, 2, float("nan")], [1, "x", 2]])
def test_a_bad_tool_point_names_the_robot_once(tool):
    """A tool point that is not three finite numbers: a ModelError naming the robot once and the value."""
    with pytest.raises(kincal.ModelError) as err:
        kincal.load_robot("ur5", tool=tool)
    assert str(err.value) == f"bundled robot 'ur5': the tool point must be three finite numbers (m), got {tool!r}"


def test_python_calls_with_arguments_of_the_wrong_kind_say_what_to_give(ur5, good):
    """A file path where the data read from it belong, a loss name where the options record does, a result
    where its robot does: each a TypeError naming the argument and the call to make (they were a TypeError of
    str.replace, or an AttributeError from deep inside)."""
    path, q, xyz = good
    meas = kincal.Measurements(q, xyz, ur5.joint_names)
    with pytest.raises(TypeError, match=r"options: a FitOptions is wanted, got str: .*loss='huber'"):
        kincal.calibrate(ur5, meas, "huber")
    with pytest.raises(TypeError, match=r"meas: a Measurements is wanted, got PosixPath: .*read_measurements"):
        kincal.calibrate(ur5, path)
    res = kincal.calibrate(ur5, meas, diagnose=False)
    with pytest.raises(TypeError, match=r"robot: a Robot is wanted, got CalibrationResult: .*result\.robot"):
        kincal.evaluate(res, meas)
    with pytest.raises(TypeError, match=r"robot: a Robot is wanted, got str: .*load_robot\('ur5'\)"):
        kincal.read_measurements(path, "ur5")
    assert kincal.evaluate(res.robot, meas).n == 30  # the call it names works


def test_a_value_error_of_numpy_is_an_internal_error_and_kincals_own_message_is_advice(monkeypatch, capsys, good):
    """A ValueError that numpy raises (shapes that do not broadcast, a singular matrix) is a bug in kincal: exit 70
    with the bug-report wording, not 'kincal: error:' advice (it printed 'operands could not be broadcast together
    with shapes (20,6) (7,)' as the user's error); a ValueError kincal raises itself stays advice, also from a
    worker process."""
    from concurrent.futures import ProcessPoolExecutor

    import kincal.cli.model
    from kincal.cli import EXIT_INTERNAL, raised_by_kincal

    def broadcast(args):
        return int((np.zeros((20, 6)) * np.zeros(7)).sum())

    def singular(args):
        return int(np.linalg.solve(np.zeros((2, 2)), np.ones(2)).sum())
    for bug in (broadcast, singular):
        monkeypatch.setattr(kincal.cli.model, "cmd_show", bug)
        code, _, err = run_cli(capsys, "show", "ur5")
        assert code == EXIT_INTERNAL == 70 and err.startswith("kincal: internal error (") and "please report" in err
    code, _, err = run_cli(capsys, "calibrate", "ur5", good[0], "--error-model", "harmonics:2", "--payload", "3")
    assert code == 1 and err.startswith("kincal: error: payload=3 kg: only the gravity terms")
    with ProcessPoolExecutor(1) as pool:
        own, numpy_s = (pool.submit(f, *a) for f, a in ((kincal.ErrorModel, ("harmonics:2", 3.0)),
                                                        (np.multiply, (np.zeros((2, 6)), np.zeros(7)))))
        with pytest.raises(ValueError) as a:
            own.result()
        with pytest.raises(ValueError) as b:
            numpy_s.result()
    assert type(a.value.__cause__).__name__ == "_RemoteTraceback"  # judged by the worker's traceback text
    assert raised_by_kincal(a.value) and not raised_by_kincal(b.value)


def test_python_calls_given_degrees_say_so(ur5):
    """select_poses on a pool in degrees designed 30 poses with |q| up to 137.8 rad, simulate and calibrate's use_q
    took degrees as radians, all without a word: each names the argument and that a Python call takes radians;
    the same calls in radians go through."""
    q = ur5.sample_joints(30, seed=1)
    pool = kincal.candidate_pool(ur5, 200, seed=0)
    meas = kincal.simulate(kincal.perturb(ur5, seed=2), q, seed=3)
    for call, what in ((lambda: kincal.select_poses(ur5, np.degrees(pool), m=30), "the candidate poses"),
                       (lambda: kincal.simulate(ur5, np.degrees(q)), "q"),
                       (lambda: kincal.calibrate(ur5, meas, use_q=np.degrees(q), diagnose=False), "use_q")):
        with pytest.raises(MeasurementError, match=rf"^{what}: revolute joint values reach [0-9.]+ rad, far beyond the "
                                                   r"joint limits: they look like degrees; a Python call takes radians"):
            call()
    assert len(kincal.select_poses(ur5, pool, m=30).q) == 30
    assert kincal.calibrate(ur5, meas, use_q=q, diagnose=False).converged


def test_degrees_read_in_the_default_radians_say_no_unit_was_given(ur5):
    """read_measurements with no angle unit read the UR5 grid's degrees as radians and said "('rad' was given)": the
    user gave none. The message says the default was used; a unit given is still named as given. The figure: the
    largest revolute value of the file as written (numpy on the columns)."""
    import csv
    with open(DATA / "ur5_grid.csv") as f:
        rows = list(csv.DictReader(f))
    largest = max(abs(float(r[c])) for r in rows for c in UR5_COLS)
    head = f"revolute joint values reach {largest:.4g} rad"
    with pytest.raises(MeasurementError) as err:
        kincal.read_measurements(DATA / "ur5_grid.csv", ur5, joint_cols=UR5_COLS, length_unit="mm")
    assert f"{head} (the default 'rad': no unit was given), far beyond the joint limits: they look like degrees; " \
           f"use angle unit 'deg'" in str(err.value)
    with pytest.raises(MeasurementError, match=r"\(the default 'rad': no unit was given\)"):
        kincal.io.read_joints(DATA / "ur5_grid.csv", ur5, joint_cols=UR5_COLS)
    with pytest.raises(MeasurementError) as err:
        kincal.read_measurements(DATA / "ur5_grid.csv", ur5, joint_cols=UR5_COLS, length_unit="mm", angle_unit="rad")
    assert f"{head} ('rad' was given)" in str(err.value)
    grid = kincal.read_measurements(DATA / "ur5_grid.csv", ur5, joint_cols=UR5_COLS, length_unit="mm",
                                    angle_unit="deg")
    assert np.degrees(np.abs(grid.q)).max() == pytest.approx(largest, rel=1e-12)


def test_cli_tells_a_typed_angle_unit_from_its_default(ur5, tmp_path, capsys):
    """kincal calibrate with no --angle-unit said "reach 147 rad ('rad' was given)" of the UR5 grid's degrees: its
    default was 'rad' in the parser. The default is None now, read as rad: the message says no unit was given, as
    read_measurements does, and the same for a Python ObservationFormat with no angle unit; typed, 'rad' is named as
    given. The figure: the largest revolute value of the file as written (numpy on the columns)."""
    import csv

    from kincal.compensate import TargetsFormat
    from kincal.observe import ObservationFormat, read_observations
    with open(DATA / "ur5_grid.csv") as f:
        largest = max(abs(float(r[c])) for r in csv.DictReader(f) for c in UR5_COLS)
    head = f"revolute joint values reach {largest:.4g} rad"
    grid, cols, out = str(DATA / "ur5_grid.csv"), ",".join(UR5_COLS), str(tmp_path / "x.yaml")
    for argv in (["calibrate", "ur5", grid, "--length-unit", "mm", "--joint-cols", cols, "-o", out],
                 ["evaluate", "ur5", grid, "--length-unit", "mm", "--joint-cols", cols],
                 ["simulate", "ur5", "--poses-file", grid, "--joint-cols", cols, "-o", str(tmp_path / "s.csv")],
                 ["design", "ur5", "--candidates", grid, "--joint-cols", cols, "-m", "10", "-o", str(tmp_path / "d.csv")]):
        code, _, err = run_cli(capsys, *argv)
        assert code == 1 and f"{head} (the default 'rad': no unit was given), far beyond" in " ".join(err.split()), err
        code, _, err = run_cli(capsys, *argv, "--angle-unit", "rad")
        assert code == 1 and f"{head} ('rad' was given), far beyond" in " ".join(err.split()), err
    q = np.loadtxt(grid, delimiter=",", skiprows=1, usecols=range(1, 7))  # degrees, read as radians
    for fmt, said in ((ObservationFormat(), "(the default 'rad': no unit was given)"),
                      (ObservationFormat(angle_unit="rad"), "('rad' was given)"),
                      (TargetsFormat(), "(the default 'rad': no unit was given)"),
                      (TargetsFormat(angle_unit="rad"), "('rad' was given)")):
        assert fmt.angle_unit == "rad"
        with pytest.raises(MeasurementError) as err:
            kincal.io.check_joints(grid, q, ur5, "mm", fmt.angle_unit, angle_default=fmt.angle_default)
        assert f"{head} {said}, far beyond" in str(err.value)
    obs = read_observations(grid, ur5, ObservationFormat(joint_cols=tuple(UR5_COLS), length_unit="mm",
                                                         angle_unit="deg"))
    assert np.degrees(np.abs(obs.q)).max() == pytest.approx(largest, rel=1e-12)


def test_library_messages_name_the_python_argument_beside_the_flag(ur5):
    """frame_mismatch told a Python caller "say which with --target-frame" and "give the controller's TCP with --tcp",
    compensate of a hexapod "--pose", check_limits "(CLI: --joint-cols, --length-unit)": CLI flags alone. Each now
    names the argument first (command_models' frame= / tcp=, rotations=, joint_cols); the CLI flag stays beside it.
    The offsets are exact: a 2 mm shift along base y, 10 mm along the flange z, the base_link frame (x, y negated)."""
    from kincal.compensate import TargetsFormat, StreamJob, frame_mismatch
    q = ur5.sample_joints(5, seed=2)
    p = ur5.forward(q)
    said = frame_mismatch(ur5, q, p + [0.0, 0.002, 0.0])
    assert "mismatch of 2.0 mm along the base frame +y" in said
    assert "say which (command_models' frame=; CLI: --target-frame)" in said
    said = frame_mismatch(ur5, q, p + ur5.flange_rotation(q) @ np.array([0.0, 0.0, 0.01]))
    assert "mismatch of 10.0 mm along the flange +z" in said and "(command_models' tcp=; CLI: --tcp)" in said
    said = frame_mismatch(ur5, q, p * [-1.0, -1.0, 1.0])
    assert "(command_models' frame='base_link'; CLI: --target-frame base_link)" in said
    hexapod = kincal.load_robot("hexapod")
    with pytest.raises(kincal.ModelError, match=r"rotations=; CLI: --pose"):
        kincal.compensate(hexapod, hexapod.forward(hexapod.sample_joints(3, seed=0)))
    with pytest.raises(ValueError, match=r"TargetsFormat\(pose=True\); CLI: --pose"):
        StreamJob(ur5, ur5, TargetsFormat(), kind="cartesian")
    wide = ur5.sample_joints(20, seed=1)
    wide[:, 0] = 500.0  # rad: no angle unit puts joint 1 within ±2π
    with pytest.raises(MeasurementError, match=r"\(joint_cols, angle_unit; CLI: --joint-cols, --angle-unit\)"):
        kincal.io.check_limits("poses.csv", wide, ur5, "m", "rad")
