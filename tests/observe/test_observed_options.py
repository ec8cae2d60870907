"""Options of the position fit that the fit of observation sets now takes: --base fixed (data in the
robot's base frame) for 6-D poses, checked against the library's fit of the same parameters."""
import json

import numpy as np
import pytest
from conftest import DATA
from scipy.spatial.transform import Rotation

import kincal
from kincal.cli import main
from kincal.identify import fit_observations
from kincal.observe import ObservationFormat, write_observations
from kincal.simulate.observations import simulate_poses


def test_base_fixed_for_poses(tmp_path, capsys):
    ur5 = kincal.load_robot("ur5").with_tool_point([0.05, 0.02, 0.1])
    true = kincal.perturb(ur5, seed=3)  # the base frame as nominal: the data are in the robot's base frame
    assert np.allclose([true.params[n] for n in ur5.base_params()], [ur5.params[n] for n in ur5.base_params()])
    obs = simulate_poses(true, ur5.sample_joints(150, seed=1), Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix(),
                         20e-6, 0.05e-3, seed=1)
    path = tmp_path / "poses.csv"
    write_observations(path, obs, ur5, ObservationFormat("pose", length_unit="mm"))
    args = ["calibrate", "ur5", str(path), "--type", "pose", "--tool", "50,20,100mm", "--length-unit", "mm",
            "--std-pos", "0.02mm", "--std-rot", "0.05mrad", "--json"]
    assert main([*args, "--base", "fixed"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert not [n for n in out["estimated"] if n.startswith("base.")] and "j2.a" in out["estimated"]
    ref = fit_observations(ur5, [obs], base="fixed")
    assert out["estimated"] == list(ref.names)
    np.testing.assert_allclose([out["estimates"][n] for n in ref.names], [ref.robot.params[n] for n in ref.names],
                               rtol=0, atol=1e-12)
    assert main(args) == 0  # by default the base frame is fitted too
    assert any(n.startswith("base.") for n in json.loads(capsys.readouterr().out)["estimated"])
    assert main([*args, "--base", "fixed", "--params", "base.x,j2.a"]) == 1
    assert "the base frame is known" in capsys.readouterr().err


@pytest.mark.slow
def test_exclude_rows_of_a_pose_file(tmp_path, capsys):
    ur5 = kincal.load_robot("ur5").with_tool_point([0.05, 0.02, 0.1])
    obs = simulate_poses(kincal.perturb(ur5, seed=3), ur5.sample_joints(80, seed=1),
                         Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix(), 20e-6, 0.05e-3, seed=1)
    path, cal = tmp_path / "poses.csv", tmp_path / "cal.yaml"
    write_observations(path, obs, ur5, ObservationFormat("pose", length_unit="mm"))
    args = ["calibrate", "ur5", str(path), "--type", "pose", "--tool", "50,20,100mm", "--length-unit", "mm",
            "--std-pos", "0.02mm", "--std-rot", "0.05mrad", "--json"]
    rows = [int(obs.rows[5]), int(obs.rows[40])]
    assert main([*args, "--exclude", f"{rows[0]},{rows[1]}", "-o", str(cal)]) == 0
    out = json.loads(capsys.readouterr().out)
    ref = fit_observations(ur5, [obs.subset(np.setdiff1d(np.arange(len(obs)), [5, 40]))])
    assert out["sets"][0]["samples"] == 78
    np.testing.assert_allclose([out["estimates"][n] for n in ref.names], [ref.robot.params[n] for n in ref.names],
                               rtol=0, atol=1e-12)
    assert main(["report", str(cal), "-o", str(tmp_path / "r.html")]) == 0  # the record leaves them out again
    assert "differs from" not in capsys.readouterr().err
    assert main([*args, "--exclude", "999"]) == 1
    assert "row(s) 999 to exclude are not data rows" in capsys.readouterr().err
    (tmp_path / "copy.csv").write_bytes(path.read_bytes())
    assert main([*args[:3], str(tmp_path / "copy.csv"), *args[3:], "--exclude", str(rows[0])]) == 1
    assert "rows of one file" in capsys.readouterr().err


@pytest.mark.slow
def test_figures_for_poses(tmp_path, capsys):
    """--plot for pose data (calibrate and evaluate) writes the six figures (6-D data: the rotation error per pose
    too), the report embeds them, and
    the per-sample position errors of the same fit (its --residuals file) are the calibrated model's
    distances to the measured points, recomputed here."""
    import csv

    from kincal.report import observation_figures

    ur5 = kincal.load_robot("ur5").with_tool_point([0.05, 0.02, 0.1])
    obs = simulate_poses(kincal.perturb(ur5, seed=3), ur5.sample_joints(60, seed=1),
                         Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix(), 20e-6, 0.05e-3, seed=1)
    path, cal = tmp_path / "poses.csv", tmp_path / "cal.yaml"
    write_observations(path, obs, ur5, ObservationFormat("pose", length_unit="mm"))
    args = ["--type", "pose", "--length-unit", "mm", "--std-pos", "0.02mm", "--std-rot", "0.05mrad"]
    assert main(["calibrate", "ur5", str(path), *args, "--tool", "50,20,100mm", "-o", str(cal), "--plot",
                 str(tmp_path / "fig.png"), "--residuals", str(tmp_path / "res.csv"), "--report",
                 str(tmp_path / "r.html")]) == 0
    out = capsys.readouterr().out
    names = ("per_pose", "rotation", "histogram", "per_axis", "vs_joints", "workspace")
    for name in names:
        assert (tmp_path / f"fig-{name}.png").stat().st_size > 10_000 and name in out
    html = (tmp_path / "r.html").read_text()
    assert all(f'id="fig-{n}"' in html for n in names)
    fit = fit_observations(ur5, [obs])
    after = fit.robot.forward(obs.q) - obs.xyz
    written = [float(r["position_error_mm"]) for r in csv.DictReader(open(tmp_path / "res.csv"))]
    np.testing.assert_allclose(np.linalg.norm(after, axis=1) * 1e3, written, rtol=1e-5)
    assert set(observation_figures(fit)) == set(names)
    assert main(["evaluate", str(cal), str(path), *args, "--plot", str(tmp_path / "ev.svg")]) == 0
    assert (tmp_path / "ev-workspace.svg").read_text().startswith("<?xml")
    # markers have no one position per sample: --plot is refused for them with the reason
    assert main(["calibrate", "ur5", str(path), "--type", "markers", "--plot", str(tmp_path / "m.png")]) == 1
    assert "3-D position error" in capsys.readouterr().err


def test_learned_prior_for_points_is_the_one_fit_s():
    """calibrate(prior="relevance") on tracker points equals the fit of observation sets on the same
    points as a PointObs (two code paths, one answer), and the options refuse it where it cannot run."""
    import pytest

    from kincal.io.measurements import read_measurements
    from kincal.observe import PointObs

    r = kincal.load_robot("ur5")
    meas = read_measurements(DATA / "ur5_grid.csv", r, [f"joint_{i}" for i in range(1, 7)], length_unit="mm",
                             angle_unit="deg").subset(np.arange(0, 1000, 10))
    res = kincal.calibrate(r, meas, prior="relevance", diagnose=False)
    ref = fit_observations(r, [PointObs(meas.q, meas.rows, meas.source, xyz=meas.xyz, std=50e-6)], prior="relevance")
    assert set(res.names) == set(ref.names) and res.prior.keys() == ref.prior.keys()
    np.testing.assert_allclose([res.robot.params[n] for n in ref.names], [ref.robot.params[n] for n in ref.names],
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose([res.prior[g] for g in ref.prior], list(ref.prior.values()), rtol=1e-6, atol=1e-12)
    plain = kincal.calibrate(r, meas, diagnose=False)
    kinds = dict(zip(r.params.names, r.params.kinds))
    held = [n for n in res.names if res.prior.get(f"{n.rsplit('.', 1)[0]} {kinds[n]}s", 1.0) < 1e-6]
    assert held and all(abs(res.corrections[n]) < 0.1 * abs(plain.corrections[n]) + 1e-9 for n in held)
    assert "prior learned from the data" in str(res) and res.to_dict()["prior"] == res.prior
    with pytest.raises(ValueError, match="prior='relevance' refits a least-squares fit"):
        kincal.FitOptions(prior="relevance", method="pso")


@pytest.mark.slow
def test_diagnosis_of_poses_names_a_negated_joint():
    """6-D poses whose joint 2 column is negated: the fit doubts them, and the one diagnosis, run on
    their positions, names the joint; clean poses are not screened (nothing to explain)."""
    import dataclasses

    ur5 = kincal.load_robot("ur5").with_tool_point([0.05, 0.02, 0.1])
    obs = simulate_poses(kincal.perturb(ur5, seed=3), ur5.sample_joints(60, seed=1),
                         Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix(), 20e-6, 0.05e-3, seed=1)
    q = obs.q.copy()
    q[:, 1] *= -1
    fit = fit_observations(ur5, [dataclasses.replace(obs, q=q)], diagnose=True)
    first = fit.verdict.reasons[0]
    assert first.code == "cause-joint-sign" and "j2 counts the other way" in first.message
    assert fit.diagnosis is not None and fit.to_dict()["diagnosis"]["found"][0]["code"] == "joint-sign"
    clean = fit_observations(ur5, [obs], diagnose=True)
    assert clean.diagnosis is None and clean.verdict.status == "good"


@pytest.mark.slow
def test_diagnosis_of_poses_or_markers_given_one_frame_names_the_moved_camera():
    """Two 6-D pose files, or two markers files, fitted in one frame (--same-frame) though the camera turned 1 deg
    and moved 6 mm between them: the diagnosis tries each file in a frame of its own, as for position files, and
    names it with the σ before and after: after, the simulated noise per axis (20 µm for the poses' target; the
    centroid of 3 markers at 15 µm: 15/√3 µm), before, the fit of the same positions in one frame. It ran for one
    point or pose file only: none was named (the positioner: 55.6x the stated σ, no cause)."""
    import dataclasses

    from kincal.identify import calibrate, joined
    from kincal.io.measurements import Measurements
    from kincal.simulate.observations import simulate_markers

    ur5 = kincal.load_robot("ur5").with_tool_point([0.05, 0.02, 0.1])
    true = kincal.perturb(ur5, seed=3)
    turn, shift = Rotation.from_rotvec([0.0, 0.0, np.deg2rad(1.0)]).as_matrix(), np.array([6e-3, 0.0, 0.0])
    target = Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix()
    markers = np.array([[0.04, 0.0, 0.03], [0.0, 0.04, 0.03], [-0.03, -0.03, 0.05]])
    poses = [simulate_poses(true, ur5.sample_joints(60, seed=s), target, 20e-6, 0.05e-3, seed=s) for s in (1, 2)]
    seen = [simulate_markers(true, ur5.sample_joints(60, seed=s), markers, 15e-6, seed=s) for s in (1, 2)]
    moved = [[poses[0], dataclasses.replace(poses[1], xyz=poses[1].xyz @ turn.T + shift, R=turn @ poses[1].R)],
             [seen[0], dataclasses.replace(seen[1], xyz=seen[1].xyz @ turn.T + shift)]]
    for sets, noise in zip(moved, (20e-6, 15e-6 / np.sqrt(3))):
        fit = fit_observations(ur5, sets, diagnose=True)
        first = fit.verdict.reasons[0]
        assert first.code == "cause-same-frame" and "leave out --same-frame" in first.message
        best = fit.diagnosis.best
        assert best.sigma == pytest.approx(noise, rel=0.15) and best.status == "good"
        one = joined([Measurements(*o.positions(), ur5.joint_names, f"{k}.csv") for k, o in enumerate(sets)])
        assert fit.diagnosis.sigma == pytest.approx(calibrate(ur5, one, diagnose=False).sigma, rel=1e-6)
        assert fit.diagnosis.sigma > 50 * noise


def test_instrument_drift_over_a_pose_or_marker_file(tmp_path, capsys):
    """A camera creeping 0.3/-0.2/0.1 mm over a file: drift=True fits it as the file's set-up
    parameters (within 4 σ of the truth, for poses and for markers), and the model no longer absorbs
    it (held-out error against the true robot); sockets refuse it with the reason."""
    import dataclasses

    import pytest

    from kincal.observe.drifting import acquisition
    from kincal.simulate.observations import simulate_markers

    ur5 = kincal.load_robot("ur5").with_tool_point([0.05, 0.02, 0.1])
    true = kincal.perturb(ur5, seed=3)
    d = np.array([0.3e-3, -0.2e-3, 0.1e-3])
    poses = simulate_poses(true, ur5.sample_joints(150, seed=1), Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix(),
                           20e-6, 0.05e-3, seed=1)
    poses = dataclasses.replace(poses, xyz=poses.xyz + acquisition(poses.rows)[:, None] * d)
    markers = simulate_markers(true, ur5.sample_joints(150, seed=4), np.array([[0.05, 0, 0.1], [-0.03, 0.05, 0.08]]),
                               20e-6, seed=2)
    markers = dataclasses.replace(markers, xyz=markers.xyz + acquisition(markers.rows)[:, None, None] * d)
    qt = ur5.sample_joints(200, seed=9)
    for obs in (poses, markers):
        fit = fit_observations(ur5, [obs], drift=True)
        names = [f"drift[{obs.source}].{a}" for a in "xyz"]
        est, sd = np.array([fit.nuisance[n] for n in names]), np.array([fit.std[n] for n in names])
        assert np.all(np.abs(est - d) < 4 * sd) and np.all(sd < 0.02e-3), (obs.kind, est, sd)
    plain, drifting = fit_observations(ur5, [poses]), fit_observations(ur5, [poses], drift=True)
    error = [float(np.mean(np.linalg.norm(f.robot.forward(qt) - true.forward(qt), axis=1))) for f in (plain, drifting)]
    assert error[1] < 0.5 * error[0] and drifting.verdict.status == "good"
    assert "over the file (first to last sample): x +0.29" in str(drifting)
    from kincal.simulate.observations import simulate_same_point, socket_plan
    points, distances = socket_plan(ur5, 2, seed=1)
    sockets = simulate_same_point(true, points, 10, distances, seed=1)
    with pytest.raises(ValueError, match="no measuring instrument that could drift"):
        fit_observations(ur5, [sockets], drift=True)
    path = tmp_path / "poses.csv"
    write_observations(path, poses, ur5, ObservationFormat("pose", length_unit="mm"))
    assert main(["calibrate", "ur5", str(path), "--type", "pose", "--tool", "50,20,100mm", "--length-unit", "mm",
                 "--std-pos", "0.02mm", "--std-rot", "0.05mrad", "--drift"]) == 0
    out = capsys.readouterr().out
    assert "drift[poses.csv] over the file (first to last sample): x +0.2" in out and "verdict: GOOD" in out


def test_held_set_up_parameters_stay_as_given():
    """held=: a held-out file judged with the training probe's rotation: those set-up parameters keep
    the given values (σ undetermined), only the frame is fitted, and the error can only be larger than
    with the rotation fitted too."""
    ur5 = kincal.load_robot("ur5").with_tool_point([0.05, 0.02, 0.1])
    true = kincal.perturb(ur5, seed=3)
    target = Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix()
    train = simulate_poses(true, ur5.sample_joints(100, seed=1), target, 20e-6, 0.05e-3, seed=1)
    test = simulate_poses(true, ur5.sample_joints(50, seed=5), target, 20e-6, 0.05e-3, seed=2)
    fit = fit_observations(ur5, [train])
    anchors = fit.observations[0].anchors()
    trained = {n: fit.nuisance[n] for n in ("target.rx", "target.ry", "target.rz")}
    strict = fit_observations(fit.robot, [test.with_anchors(anchors)], names=ur5.base_params(), held=trained)
    loose = fit_observations(fit.robot, [test.with_anchors(anchors)], names=ur5.base_params())
    assert all(strict.nuisance[n] == v and strict.std[n] == np.inf for n, v in trained.items())
    assert any(abs(loose.nuisance[n] - v) > 1e-9 for n, v in trained.items())
    assert strict.per_set[0]["mean_rotation"] * 1e3 >= loose.per_set[0]["mean_rotation"] * 1e3 - 1e-9
    assert set(strict.names) == set(ur5.base_params())
