"""The command line, end to end: real tracker data and a simulate → calibrate → evaluate round trip."""
import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import DATA, UR5_COLS, WAM_COLS

import kincal
from kincal.cli import main


def run_json(capsys, *argv):
    code = main([str(a) for a in argv] + ["--json"])
    cap = capsys.readouterr()
    assert code == 0, cap.err
    return json.loads(cap.out)


def units(cols):
    return ["--length-unit", "mm", "--angle-unit", "deg", "--joint-cols", ",".join(cols)]


def test_ur5_real_tracker_data(tmp_path, capsys):
    """Calibrate on the 1000-pose grid, evaluate on the 20 unseen random poses (same tracker set-up, data in the
    robot base frame: --same-frame): 2.57 mm -> <= 0.105 mm."""
    out = tmp_path / "ur5_cal.yaml"
    cal = run_json(capsys, "calibrate", "ur5", DATA / "ur5_grid.csv", "-o", out, *units(UR5_COLS))
    assert cal["converged"] and cal["n_poses"] == 1000
    before = run_json(capsys, "evaluate", "ur5", DATA / "ur5_random.csv", *units(UR5_COLS), "--same-frame")
    after = run_json(capsys, "evaluate", out, DATA / "ur5_random.csv", *units(UR5_COLS), "--same-frame")
    assert before["n"] == 20 and before["mean"] == pytest.approx(2.57e-3, abs=0.01e-3)
    assert after["mean"] <= 0.105e-3


@pytest.mark.slow
def test_wam_real_tracker_data(tmp_path, capsys):
    out = tmp_path / "wam_cal.yaml"
    run_json(capsys, "calibrate", "wam", DATA / "wam_grid.csv", "-o", out, *units(WAM_COLS))
    before = run_json(capsys, "evaluate", "wam", DATA / "wam_random.csv", *units(WAM_COLS), "--same-frame")
    after = run_json(capsys, "evaluate", out, DATA / "wam_random.csv", *units(WAM_COLS), "--same-frame")
    assert before["mean"] == pytest.approx(17.6e-3, abs=0.05e-3)
    assert after["mean"] < 3.5e-3  # a geometric model leaves the cable-driven WAM's ~3 mm


def test_simulate_calibrate_evaluate_round_trip(tmp_path, capsys):
    data, true = tmp_path / "sim.csv", tmp_path / "true.yaml"
    run_json(capsys, "simulate", "ur5", "-o", data, "--poses", "80", "--perturb", "--save-true", true,
             "--length-unit", "mm", "--angle-unit", "deg")
    cal_path = tmp_path / "cal.yaml"
    cal = run_json(capsys, "calibrate", "ur5", data, "-o", cal_path, "--length-unit", "mm", "--angle-unit", "deg")
    assert cal["after"]["rms"] < 40e-6  # residuals at the 15 µm noise level (3-D)
    val = tmp_path / "val.csv"
    run_json(capsys, "simulate", true, "-o", val, "--poses", "100", "--noise", "0", "--seed", "5")
    after = run_json(capsys, "evaluate", cal_path, val)
    before = run_json(capsys, "evaluate", "ur5", val)
    assert before["mean"] > 0.5e-3 and after["mean"] < 30e-6


def test_identifiability_and_show(capsys):
    ident = run_json(capsys, "identifiability", "ur5", "--poses", "60")
    assert ident["rank"] == 27 and "j6.d" in ident["dropped"]
    show = run_json(capsys, "show", "ur5")
    assert show["parameters"]["j2.a"] == pytest.approx(-0.425)
    robots = run_json(capsys, "robots")
    assert {r["name"] for r in robots["robots"]} >= {"ur5", "ur10", "wam", "scara"}


def test_human_output_uses_mm_and_deg(capsys):
    assert main(["show", "ur5"]) == 0
    text = capsys.readouterr().out
    assert "-425" in text and "mm" in text and "deg" in text
    assert main(["show", "hexapod"]) == 0  # the joints' limits with their unit (1512 of what? deg, the motor angle)
    leg = next(line for line in capsys.readouterr().out.splitlines() if line.strip("│ ").startswith("leg1 "))
    assert [c.strip() for c in leg.split("│")[1:-1]] == ["leg1", "revolute", "0", "1512", "deg"]


@pytest.mark.slow
@pytest.mark.xdist_group("guo2024-demo")
def test_demo_reproduces_guo2024(guo2024_demo):
    d = guo2024_demo  # demo --repeats 1 --json
    assert set(d["separation"]["subdomain_gcn"]) == {"theta", "alpha", "a", "d", "beta"}
    before = d["validation"]["before calibration"]["mean"]
    for name in ("random", "full-parameter optimised", "separated-parameter optimised"):
        assert d["validation"][name]["mean"] < 0.01 * before  # tens of mm -> about 0.1 mm
        # one repetition: its statistics are the first repetition's validation (the paper's e), with no spread
        e = np.asarray(d["validation_point_errors"][name]).mean(axis=1)
        assert d["repeated"][name]["mean_of_mean"] == pytest.approx(np.mean(np.abs(e)), rel=1e-12)
        assert d["repeated"][name]["mean_of_std"] == pytest.approx(np.std(e, ddof=1), rel=1e-12)
        assert d["repeated"][name]["sd_of_mean"] == 0.0 and d["repeats"] == 1
        table = d["validation_e"][name]  # the printed Table 8 analogue: e, not the 3-D norms of "validation"
        assert (table["max_abs"], table["mean_abs"], table["std"]) == pytest.approx(
            (np.max(np.abs(e)), np.mean(np.abs(e)), np.std(e, ddof=1)), rel=1e-12)
    assert d["design_values"]["separated-parameter optimised"] > d["design_values"]["random"]


def test_design_command(tmp_path, capsys):
    out = tmp_path / "poses.csv"
    d = run_json(capsys, "design", "ur5", "-m", "30", "--pool", "800", "-o", out, "--angle-unit", "deg")
    assert 0.85 < d["efficiency"] <= 1.0 and d["m"] == 30  # against the certified bound over the pool
    q = kincal.read_joints(out, kincal.load_robot("ur5"), angle_unit="deg")
    np.testing.assert_allclose(q, np.array(d["q"]), atol=1e-12)
    # the poses file feeds simulate, and a user's candidate list feeds design
    sim = tmp_path / "sim.csv"
    run_json(capsys, "simulate", "ur5", "--poses-file", out, "-o", sim, "--angle-unit", "deg")
    d2 = run_json(capsys, "design", "ur5", "-m", "10", "--candidates", out, "-o", tmp_path / "p2.csv",
                  "--angle-unit", "deg", "--params", "j2.a,j3.a,j2.theta,j3.theta")
    assert d2["m"] == 10 and d2["parameters"] == ["j2.a", "j3.a", "j2.theta", "j3.theta"]


@pytest.mark.slow
def test_separate_command(capsys):
    d = run_json(capsys, "separate", "guo3t2r")
    # exact dependences sit at the reproducible GCN floor; of j3.theta ≡ j4.theta the later one goes
    assert d["subdomain_gcn"]["a"] > 1e8 and "j4.theta" in d["separated"] and "j3.theta" not in d["separated"]


@pytest.mark.slow
def test_console_script_is_installed():
    proc = subprocess.run([sys.executable, "-m", "kincal.cli", "robots", "--json"], capture_output=True, text=True)
    assert proc.returncode == 0 and "ur5" in proc.stdout
    proc = subprocess.run([sys.executable, "-m", "kincal.cli", "show", "nope"], capture_output=True, text=True)
    assert proc.returncode == 1 and proc.stderr.startswith("kincal: error:")


def test_simulate_at_given_joint_values(tmp_path, capsys):
    """Poses from a CSV without positions (e.g. a designed pose list), in degrees."""
    poses = tmp_path / "poses.csv"
    q_deg = np.array([[10, -80, 90, 0, 90, 0], [40, -60, 70, 20, 100, 30], [-20, -100, 120, -30, 60, 10]], float)
    poses.write_text("j1;j2;j3;j4;j5;j6\n" + "\n".join(";".join(str(v) for v in row) for row in q_deg) + "\n")
    out = tmp_path / "sim.csv"
    run_json(capsys, "simulate", "ur5", "--poses-file", poses, "--noise", "0", "-o", out, "--angle-unit", "deg")
    meas = kincal.read_measurements(out, kincal.load_robot("ur5"), angle_unit="deg")
    np.testing.assert_allclose(meas.q, np.deg2rad(q_deg), atol=1e-12)
    np.testing.assert_allclose(meas.xyz, kincal.load_robot("ur5").forward(np.deg2rad(q_deg)), atol=1e-12)


def test_npose_command(capsys):
    d = run_json(capsys, "npose", "ur5", "--criterion", "O1", "--max", "80")
    assert d["minimum_eq18"] == int(np.ceil(7 * d["parameters"] / 6)) and 1 <= d["chosen"] <= 80
    assert len(d["values"]) == 80


@pytest.mark.slow
def test_parallel_workflow_on_the_command_line(tmp_path, capsys):
    """simulate -> calibrate (joint residual) -> sensitivity -> verify -> compensate, for the 3-PUU robot."""
    true = tmp_path / "true.yaml"
    data = tmp_path / "data.csv"
    run_json(capsys, "simulate", "puu3-extended", "--perturb", "--poses", "80", "-o", data, "--save-true", true,
             "--length-error", "0.3", "--angle-error", "0.1")
    cal = tmp_path / "cal.yaml"
    c = run_json(capsys, "calibrate", "puu3-extended", data, "-o", cal, "--base", "fixed")
    assert c["after"]["rms"] < 40e-6
    s = run_json(capsys, "sensitivity", cal, "--params", "L1,L2", "--plot", tmp_path / "s.png")
    assert len(s["deltas"]) == 2 and (tmp_path / "s.png").stat().st_size > 1000
    v = run_json(capsys, "verify", cal, "--params", "L1,L2,L3", "--simulate", true, "-o", tmp_path / "plan.csv")
    assert set(v["cases"]) == {"L1", "L2", "L3"} and max(max(x["mean"]) for x in v["cases"].values()) < 40e-6
    assert v["pass"] and v["tolerance"] == pytest.approx(50e-6)
    targets = tmp_path / "targets.csv"
    targets.write_text("x,y,z\n0.02,-0.03,0.30\n-0.05,0.04,0.25\n")
    cmds = run_json(capsys, "compensate", cal, targets, "-o", tmp_path / "cmds.csv")
    assert cmds["max_residual"] < 1e-9 and cmds["written"] == 2


def test_verify_with_measurements_file(tmp_path, capsys):
    """The plan is written in the user's units, read back from its file, and measured in its order."""
    plan_path = tmp_path / "plan.csv"
    run_json(capsys, "verify", "puu3", "--params", "L1,L2", "--samples", "4", "-o", plan_path, "--length-unit", "mm")
    rows = plan_path.read_text().splitlines()
    assert "length=mm" in rows[0] and rows[1].startswith("case,sample,h1,h2,h3") and len(rows) == 2 + 2 * 4
    # "measure" the plan with the model itself and 1 µm of noise: deviations are the noise
    robot = kincal.load_robot("puu3")
    body = [r.split(",") for r in rows[2:]]
    q = np.array([[float(x) for x in r[2:5]] for r in body]) / 1e3
    assert robot.within_limits(q).all()  # the commands were written in mm
    noise = np.random.default_rng(3).normal(0.0, 1e-6, (len(q), 3))
    p = robot.forward(q) + noise
    meas = tmp_path / "meas.csv"
    meas.write_text("h1,h2,h3,x,y,z\n" + "\n".join(",".join(repr(float(x)) for x in [*qi, *pi]) for qi, pi in zip(q, p)) + "\n")
    v = run_json(capsys, "verify", "puu3", "--plan", plan_path, "--measured", meas)
    largest = max(max(c["max"]) for c in v["cases"].values())
    assert 0.5 * np.linalg.norm(noise, axis=1).max() < largest < 1.01 * np.linalg.norm(noise, axis=1).max()
    assert v["pass"]
    # the plan itself is not measurements; nor its predicted columns copied into a file of their own
    code = main(["verify", "puu3", "--plan", str(plan_path), "--measured", str(plan_path), "--length-unit", "mm", "--xyz-cols",
                 "x_pred,y_pred,z_pred"])
    assert code == 1 and "a kincal verification plan (the commands to run" in capsys.readouterr().err
    copied = tmp_path / "copied.csv"
    copied.write_text("\n".join(plan_path.read_text().splitlines()[1:]) + "\n")
    code = main(["verify", "puu3", "--plan", str(plan_path), "--measured", str(copied), "--length-unit", "mm", "--xyz-cols",
                 "x_pred,y_pred,z_pred"])
    assert code == 1 and "predicted columns, not measurements" in capsys.readouterr().err
    # a plan rebuilt from another seed is not what was measured: the joints do not match and it says so
    other = tmp_path / "other.csv"
    run_json(capsys, "verify", "puu3", "--params", "L1,L2", "--samples", "4", "--seed", "5", "-o", other)
    code = main(["verify", "puu3", "--plan", str(other), "--measured", str(meas)])
    assert code == 1 and "not the plan's commands" in capsys.readouterr().err


def test_design_from_candidates_keeps_the_users_rows_and_columns(tmp_path, capsys):
    """A design from the user's candidate file writes the chosen rows themselves: their line numbers,
    their IDs and every other column as given (a comment and a blank line do not shift the rows);
    the choice is the one the library makes on the same pool."""
    robot = kincal.load_robot("ur5")
    pool = robot.sample_joints(150, seed=4)
    lines = ["pose_id;station;" + ";".join(f"j{k}" for k in range(1, 7)), "# reachable poses, exported", ""]
    lines += [f"P{100 + k};bay {k % 3};" + ";".join(repr(float(v)) for v in np.rad2deg(q)) for k, q in enumerate(pool)]
    src = tmp_path / "candidates.csv"
    src.write_text("\n".join(lines) + "\n")
    run_json(capsys, "design", "ur5", "--candidates", src, "-m", "12", "--method", "fedorov", "-o",
                   tmp_path / "d.csv", "--angle-unit", "deg", "--seed", "3")
    rows = [r.split(";") for r in (tmp_path / "d.csv").read_text().splitlines()]
    assert rows[0] == ["input_row", "pose_id", "station", "j1", "j2", "j3", "j4", "j5", "j6"] and len(rows) == 13
    ref = kincal.select_poses(robot, pool, kincal.DesignOptions(m=12, method="fedorov", seed=3))
    assert [r[1] for r in rows[1:]] == [f"P{100 + k}" for k in ref.indices]
    assert [int(r[0]) for r in rows[1:]] == [4 + k for k in ref.indices]  # the file's line numbers
    for r, k in zip(rows[1:], ref.indices):
        assert r[1:] == lines[3 + k].split(";")  # every cell as the user wrote it


def test_a_value_that_starts_with_a_minus_sign(capsys):
    """``--tool -1,-7,1.6mm``: argparse alone stops at "expected one argument"; the value is taken,
    in its unit, and a switch followed by such a token is still a switch (the token stays an error)."""
    shown = run_json(capsys, "show", "ur5", "--tool", "-1,-7,1.6mm")
    assert [shown["parameters"][f"tool.{a}"] for a in "xyz"] == pytest.approx([-1e-3, -7e-3, 1.6e-3], abs=1e-15)
    with pytest.raises(SystemExit) as stop:
        main(["evaluate", "ur5", str(DATA / "ur5_random.csv"), "--same-frame", "-5"])
    assert stop.value.code == 2 and "unrecognized arguments: -5" in capsys.readouterr().err


# every layout flag simulate writes a file of the kind by (calibrate's defaults otherwise), and the header it gives
LAYOUT = {"point": (["--xyz-cols", "px,py,pz"], "q1,q2,q3,q4,q5,q6,px,py,pz"),
          "pose": (["--xyz-cols", "px,py,pz", "--orientation", "quat-xyzw", "--rot-cols", "A,B,C,D"],
                   "px,py,pz,A,B,C,D,q1,q2,q3,q4,q5,q6"),
          "markers": ([], "m1.x,m1.y,m1.z,m2.x,m2.y,m2.z,m3.x,m3.y,m3.z,q1,q2,q3,q4,q5,q6"),
          "same-point": (["--label-col", "sock", "--group-col", "plate"], "plate,sock,q1,q2,q3,q4,q5,q6"),
          "plane": (["--label-col", "surf"], "surf,q1,q2,q3,q4,q5,q6")}


@pytest.mark.parametrize("kind", [*LAYOUT])
def test_simulate_says_the_command_that_reads_its_file_back(tmp_path, capsys, kind):
    """The command simulate prints reads the file it wrote: run as printed, calibrate fits it (a verdict, not a read
    error), whatever columns and units the file was written in. It left out --xyz-cols and --rot-cols of a pose
    file, a plane file's --label-col and every non-point file's --joint-cols (calibrate said 'not found'); without
    the units the mm file is refused as a unit mistake."""
    import shlex

    path = tmp_path / "s p.csv"  # a space: the printed command quotes it
    count = [] if kind in ("same-point", "plane") else ["--poses", "40"]
    layout, header = LAYOUT[kind]
    assert main(["simulate", "ur5", "--type", kind, "-o", str(path), *count, "--perturb", "--joint-cols",
                 "q1,q2,q3,q4,q5,q6", *layout, "--length-unit", "mm", "--angle-unit", "deg", "--tool", "0,0,100mm"]) == 0
    assert path.read_text().splitlines()[0] == header
    command = shlex.split(capsys.readouterr().out.split("calibrate them with: ")[1])
    assert command[:4] == ["kincal", "calibrate", "ur5", str(path)]
    assert {"--length-unit", "--angle-unit", "--joint-cols", *layout[::2]} <= set(command)
    assert main(command[1:]) in (0, 4)
    err = capsys.readouterr().err
    assert "not found" not in err and "looks like" not in err, err
    assert main(["calibrate", "ur5", str(path), "--type", kind]) == 1


def test_simulate_says_the_urdf_chain_it_read(tmp_path, capsys):
    """A URDF robot's chain flags are part of the command that reads the simulated file back."""
    import shlex

    from conftest import PANDA_URDF

    path = tmp_path / "s.csv"
    assert main(["simulate", str(PANDA_URDF), "--tip-link", "ball_link", "-o", str(path), "--perturb"]) == 0
    command = shlex.split(capsys.readouterr().out.split("calibrate them with: ")[1])
    assert command == ["kincal", "calibrate", str(PANDA_URDF), str(path), "--tip-link", "ball_link"]
    assert main(command[1:]) in (0, 4)


def test_simulate_touches_the_planes_given_and_says_so(tmp_path, capsys):
    """simulate --type plane --plane: the contacts lie on the planes given (offsets in the file's mm), checked by the
    true robot's forward kinematics; the printed flags carry those planes and the --tool given, and calibrate reads
    the file back with them. (The planes were ignored: the contacts lay on kincal's own table, 150 mm lower.)"""
    import kincal

    path, true = tmp_path / "p.csv", tmp_path / "true.yaml"
    assert main(["simulate", "ur5", "--type", "plane", "--plane", "table:0,0,1,-200", "--plane", "step:0,0,1,-120",
                 "-o", str(path), "--perturb", "--noise", "0", "--length-unit", "mm", "--tool", "0,0,100mm",
                 "--save-true", str(true)]) == 0
    hint = capsys.readouterr().out.split("calibrate them with: ")[1].split()[4:]  # after kincal calibrate ROBOT FILE
    assert hint[hint.index("--tool") + 1] == "0,0,100mm"
    assert [hint[i + 1] for i, h in enumerate(hint) if h == "--plane"] == ["table:0,0,1,-200", "step:0,0,1,-120"]
    robot = kincal.load_robot(str(true))
    lines = path.read_text().splitlines()
    head, rows = lines[0].split(","), [line.split(",") for line in lines[1:]]
    q = np.array([[float(r[head.index(f"j{k}")]) for k in range(1, 7)] for r in rows])
    height = robot.forward(q)[:, 2]
    on = {lab: height[[r[head.index("plane")] == lab for r in rows]] for lab in ("table", "step")}
    assert len(on["table"]) == len(on["step"]) == 30
    assert on["table"] == pytest.approx(-0.200, abs=1e-8) and on["step"] == pytest.approx(-0.120, abs=1e-8)
    assert main(["calibrate", "ur5", str(path), *hint]) in (0, 4)
    assert "length scale" not in capsys.readouterr().err


def test_files_with_the_robot_stacks_joint_names_are_read_without_joint_cols(tmp_path):
    """A bundled UR's joints are j1..j6 in kincal and shoulder_pan_joint … in UR's ROS description (its
    robot file's names:): a file headed with either is read alike, points and 6-D poses; another
    header still names the columns it looks for."""
    import kincal
    from kincal.errors import MeasurementError
    from kincal.observe import ObservationFormat, read_observations

    robot = kincal.load_robot("ur10")
    m = kincal.simulate(robot, robot.sample_joints(20, seed=1), 0.0, seed=1)
    kincal.write_measurements(str(tmp_path / "own.csv"), m, robot.joint_types)
    lines = (tmp_path / "own.csv").read_text().splitlines()
    assert lines[0].startswith("j1,j2,j3,j4,j5,j6,")
    (tmp_path / "ros.csv").write_text("\n".join([lines[0].replace("j1,j2,j3,j4,j5,j6", ",".join(robot.stack_names)),
                                                 *lines[1:]]) + "\n")
    ros = kincal.read_measurements(str(tmp_path / "ros.csv"), robot)
    assert robot.stack_names[0] == "shoulder_pan_joint" and np.array_equal(ros.q, m.q)
    assert np.array_equal(read_observations(str(tmp_path / "ros.csv"), robot, ObservationFormat("point")).q, m.q)
    (tmp_path / "other.csv").write_text("\n".join([lines[0].replace("j1,", "a1,"), *lines[1:]]) + "\n")
    with pytest.raises(MeasurementError, match="j1"):
        kincal.read_measurements(str(tmp_path / "other.csv"), robot)


@pytest.mark.parametrize("command", [["compensate", "ur5", "targets.csv", "-o", "out.csv"], ["verify", "puu3", "-o", "plan.csv"],
                                     ["simulate", "ur5", "-o", "sim.csv"], ["design", "ur5", "-o", "poses.csv"],
                                     ["show", "ur5"], ["identifiability", "ur5"]])
def test_sigma_columns_are_refused_where_nothing_reads_them(command, capsys):
    """Targets, verification readings, simulated files, designs and joint-only analyses read no σ
    columns: --std-cols does not exist there (refused, not ignored)."""
    with pytest.raises(SystemExit) as stop:
        main([*command, "--std-cols", "sx,sy,sz"])
    assert stop.value.code == 2 and "unrecognized arguments: --std-cols" in capsys.readouterr().err


def test_simulate_writes_the_position_columns_asked_for(tmp_path, capsys):
    """simulate --xyz-cols names the position columns it writes (it wrote x,y,z whatever was asked),
    and the hint it prints reads them back: the same positions as the true robot's within the noise."""
    out, true = tmp_path / "sim.csv", tmp_path / "true.yaml"
    d = run_json(capsys, "simulate", "ur5", "-o", out, "--xyz-cols", "px,py,pz", "--length-unit", "mm", "--noise", "0",
                 "--perturb", "--save-true", true)
    assert out.read_text().splitlines()[0] == "j1,j2,j3,j4,j5,j6,px,py,pz" and "--xyz-cols px,py,pz" in d["flags"]
    robot = kincal.load_robot(str(true))
    meas = kincal.read_measurements(out, robot, xyz_cols=["px", "py", "pz"], length_unit="mm")
    np.testing.assert_allclose(meas.xyz, robot.forward(meas.q), atol=1e-12)


def test_a_base_frame_near_gimbal_lock_says_its_outer_angles_mean_only_together(tmp_path, capsys):
    """guo3t2r's base stands at base.ry = 90°: a calibration moves base.rx and base.rz by about −90° each (σ 0.4°),
    a frame equal to the nominal one up to its small error, with its positions right; it printed those 'corrections'
    without a word. Now a note says they mean only together; a UR5 (base.ry 0) gets none."""
    data, true = tmp_path / "g.csv", tmp_path / "true.yaml"
    assert main(["simulate", "guo3t2r", "--perturb", "--poses", "80", "--seed", "3", "-o", str(data),
                 "--save-true", str(true)]) == 0
    capsys.readouterr()
    assert main(["calibrate", "guo3t2r", str(data), "-o", str(tmp_path / "cal.yaml")]) == 0
    said = capsys.readouterr().out
    assert "near ±90°: base.rx and base.rz then turn about nearly the same axis (gimbal lock)" in said
    q = kincal.load_robot("guo3t2r").sample_joints(50, seed=1)
    cal, truth = kincal.load_robot(str(tmp_path / "cal.yaml")), kincal.load_robot(str(true))
    assert np.abs(cal.forward(q) - truth.forward(q)).max() < 1e-4  # the frame it makes is right
    ur5 = kincal.simulate(kincal.perturb(kincal.load_robot("ur5"), seed=1), kincal.load_robot("ur5").sample_joints(60))
    assert "gimbal" not in str(kincal.calibrate(kincal.load_robot("ur5"), ur5))


def test_a_flag_of_another_command_is_named_with_its_commands(tmp_path, capsys):
    """report reads how the data were read from the calibration's record: --type and --orientation, calibrate's
    flags, ended in argparse's bare 'unrecognized arguments'; the error names the commands that have them and says
    where report takes them from."""
    with pytest.raises(SystemExit) as stop:
        main(["report", "cal.yaml", "--type", "pose", "-o", str(tmp_path / "r.html")])
    said = capsys.readouterr().err
    assert stop.value.code == 2 and "unrecognized arguments: --type pose" in said
    assert "--type is a flag of " in said and "calibrate" in said and "not of report" in said
    assert "from the calibration's record" in said


def test_verification_samples_are_commandable_and_the_simulated_noise_follows_the_seed(tmp_path, capsys):
    """A plan drawn over the 3-PUU's limits could hold a sample whose command is refused, and verify stopped
    ('choose sample inputs away from the joint limits', with no flag to choose them): such samples are passed
    over (commandable: exactly those verification_plan refuses). verify --simulate drew the same noise for every
    --seed; it follows the seed now."""
    from kincal.compensate import commandable, verification_plan

    robot = kincal.load_robot("puu3")
    q = robot.sample_joints(40, seed=1)
    ok = commandable(robot, q)
    assert 0 < (~ok).sum() < len(q)
    with pytest.raises(kincal.ModelError, match="were refused"):
        verification_plan(robot, q)
    assert verification_plan(robot, q[ok]).commands.shape == (5, int(ok.sum()), 3)
    largest = []
    for seed in (1, 2):
        v = run_json(capsys, "verify", "puu3", "--seed", seed, "--simulate", "puu3", "-o", tmp_path / f"p{seed}.csv")
        largest.append([max(c["max"]) for c in v["cases"].values()])
    assert largest[0] != largest[1]


def test_calibrate_test_names_the_likely_cause_of_a_held_out_file_as_evaluate_does(tmp_path, capsys):
    """A held-out file of another robot (a UR10's positions under a UR5's joint names): calibrate --test printed
    '258 mm' and nothing else, while evaluate on the same file named a scale error or another robot's data. Now
    both say it; a held-out file of the same robot gets no cause."""
    ur5, ur10 = kincal.load_robot("ur5"), kincal.load_robot("ur10")
    true = kincal.perturb(ur5, seed=4)
    kincal.write_measurements(tmp_path / "train.csv", kincal.simulate(true, ur5.sample_joints(60, seed=1), seed=2),
                              ur5.joint_types)
    q = ur5.sample_joints(30, seed=3)
    kincal.write_measurements(tmp_path / "same.csv", kincal.simulate(true, q, seed=5), ur5.joint_types)
    kincal.write_measurements(tmp_path / "other.csv", kincal.Measurements(q, ur10.forward(q), ur5.joint_names),
                              ur5.joint_types)
    lines = {}
    for name in ("same", "other"):
        assert main(["calibrate", "ur5", str(tmp_path / "train.csv"), "--test", str(tmp_path / f"{name}.csv"),
                     "-o", str(tmp_path / f"{name}.yaml")]) == 0
        lines[name] = capsys.readouterr().out
    assert "likely cause" not in lines["same"]
    cause = next(x for x in lines["other"].splitlines() if "likely cause" in x)
    assert main(["evaluate", str(tmp_path / "other.yaml"), str(tmp_path / "other.csv")]) == 0
    assert cause in capsys.readouterr().out and "another robot's data" in cause


@pytest.mark.parametrize("argv, typed, si, rule", [
    (["design", "ur5", "-m", "10", "-o", "{d}/d.csv", "--tracker-range", "20000,500mm"], "20000,500mm",
     f"{20000 * 1e-3}..{500 * 1e-3} m", "give 0 ≤ min < max"),  # the record said 'tracker range 20.0..0.5 m'
    (["design", "ur5", "-m", "10", "-o", "{d}/d.csv", "--keep-out", "600,300,400,200,-300,0mm"],
     "600,300,400,200,-300,0mm", str(np.array([0.6, 0.3, 0.4])),  # 'keep-out box [0.6 0.3 0.4]..[ 0.2 -0.3 0. ]'
     "give the lower corner below the upper one on every axis"),
    (["calibrate", "ur5", str(DATA / "ur5_random.csv"), "--type", "pose", "--std-pos", "20000m"], "20000m",
     f"{20000 * 1e3:g} mm", "more than any instrument's σ (at most 10 km)"),  # 'std_pos 2e+07 mm'
    (["calibrate", "ur5", str(DATA / "ur5_random.csv"), "--tracker-noise", "1e-320m"], "1e-320m",
     "not finite", "below any instrument's noise")])  # passed as positive: 'the residual ... is not finite'
def test_a_unit_flag_refused_by_its_record_is_echoed_as_typed(argv, typed, si, rule, tmp_path, capsys):
    """A flag with a unit is converted to SI before its option record (the design's cell, the file's format) checks
    it: the refusal showed the SI number ('tracker range 20.0..0.5 m', 'keep-out box [0.6 0.3 0.4]..', 'std_pos
    2e+07 mm is more than any instrument's σ'), not the flag nor what was typed. Now the flag and its text, as
    --std-joint's refusals, and what to do, before any work."""
    flag = argv[-2]
    with pytest.raises(SystemExit) as stop:
        main([a.format(d=tmp_path) for a in argv])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and f"argument {flag}: '{typed}': {rule}" in err and si not in err, err
