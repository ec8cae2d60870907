"""Calibration in simulation: statistical efficiency against the Cramér–Rao prediction, tracker-frame
registration, robust losses, covariance, evaluation."""
import numpy as np
import pytest

from conftest import DATA, UR5_COLS, central_jacobian

import kincal
from kincal.analysis import stacked_jacobian
from kincal.models.transforms import rot_zyx
from kincal.models.yaml_io import load_calibration_record

NOISE = 15e-6


def test_noise_free_calibration_recovers_positions_exactly(ur5):
    true = kincal.perturb(ur5, seed=1)
    meas = kincal.simulate(true, ur5.sample_joints(60, seed=1), noise=0.0)
    res = kincal.calibrate(ur5, meas)
    assert res.converged
    val = kincal.simulate(true, ur5.sample_joints(100, seed=2), noise=0.0)
    assert kincal.evaluate(res.robot, val).max < 1e-9
    # the link lengths and tilts come back to well under a micrometre / microradian
    for name in ("j2.a", "j3.a", "j2.beta", "j3.beta"):
        assert res.estimates[name] == pytest.approx(true.params[name], abs=1e-7)


def test_validation_rms_matches_cramer_rao(ur5):
    """Mean validation RMS over 20 seeds within 10 % of σ·sqrt(tr(J_v (JᵀJ)⁻¹ J_vᵀ)/n_v)."""
    rms, predicted = [], []
    for seed in range(20):
        true = kincal.perturb(ur5, seed=100 + seed)
        q = ur5.sample_joints(60, seed=200 + seed)
        qv = ur5.sample_joints(200, seed=300 + seed)
        res = kincal.calibrate(ur5, kincal.simulate(true, q, NOISE, seed=seed), base="fixed")
        rms.append(kincal.evaluate(res.robot, kincal.simulate(true, qv, 0.0)).rms)
        J = stacked_jacobian(res.robot, q, res.names)
        Jv = stacked_jacobian(res.robot, qv, res.names)
        cov = np.linalg.inv(J.T @ J)
        predicted.append(NOISE * np.sqrt(np.trace(Jv @ cov @ Jv.T) / len(qv)))
    ratio = np.mean(rms) / np.mean(predicted)
    assert abs(ratio - 1) < 0.10, ratio


def test_tracker_frame_is_registered(ur5):
    """Data in a frame rotated 30° and 3 m away: base='estimate' does as well as data in the base frame."""
    true = kincal.perturb(ur5, seed=7)
    q, qv = ur5.sample_joints(60, seed=7), ur5.sample_joints(200, seed=8)
    R, t = rot_zyx(np.deg2rad(30), np.deg2rad(10), np.deg2rad(-20)), np.array([3.0, -0.5, 0.8])
    moved = true.with_base_transform(R, t)
    meas = kincal.simulate(true, q, NOISE, seed=3)
    tracked = kincal.Measurements(q, meas.xyz @ R.T + t, meas.joint_names)  # the same data seen by the tracker
    in_base = kincal.calibrate(ur5, meas, base="estimate")
    in_tracker = kincal.calibrate(ur5, tracked, base="estimate")
    assert in_tracker.converged
    err_base = kincal.evaluate(in_base.robot, kincal.simulate(true, qv, 0.0)).rms
    err_tracker = kincal.evaluate(in_tracker.robot, kincal.simulate(moved, qv, 0.0)).rms
    # the same data in a rotated, shifted frame is the same problem: the same accuracy
    assert err_tracker == pytest.approx(err_base, rel=1e-4) and err_tracker < 30e-6
    Rb, tb = in_tracker.robot.base_transform()
    assert np.abs(Rb - R).max() < 1e-3 and np.abs(tb - t).max() < 1e-3
    # the nominal model in the wrong frame is metres off; rebasing alone fixes the frame
    assert kincal.evaluate(ur5, kincal.simulate(moved, qv, 0.0)).mean > 1.0
    assert kincal.evaluate(ur5, kincal.simulate(moved, qv, 0.0), rebase=True).mean < 2e-3


def test_standard_deviations_match_monte_carlo(ur5):
    q = ur5.sample_joints(40, seed=11)
    true = kincal.perturb(ur5, seed=11)
    runs = [kincal.calibrate(ur5, kincal.simulate(true, q, NOISE, seed=s), base="fixed") for s in range(40)]
    names = runs[0].names
    est = np.array([[r.estimates[n] for n in names] for r in runs])
    reported = np.array([[r.std[n] for n in names] for r in runs]).mean(axis=0)
    ratio = est.std(axis=0, ddof=1) / reported
    assert 0.7 < np.median(ratio) < 1.3, np.median(ratio)
    # the correlation matrix is that of (JᵀJ)⁻¹, J by central differences at the fitted values
    res = runs[0]
    Jn = central_jacobian(res.robot, q)[:, :, res.robot.params.indices(names)].reshape(-1, len(names))
    C = np.linalg.inv(Jn.T @ Jn)
    np.testing.assert_allclose(res.correlation, C / np.sqrt(np.outer(np.diag(C), np.diag(C))), atol=1e-5)
    assert np.abs(res.correlation - np.eye(len(names))).max() > 0.5  # strongly correlated pairs exist


@pytest.mark.slow
@pytest.mark.parametrize("loss", ["huber", "soft_l1"])
def test_robust_loss_resists_outliers(ur5, loss):
    true = kincal.perturb(ur5, seed=4)
    q, qv = ur5.sample_joints(120, seed=4), ur5.sample_joints(200, seed=5)
    meas = kincal.simulate(true, q, NOISE, seed=4)
    xyz = meas.xyz.copy()
    xyz[::15] += 3e-3  # 8 gross outliers of 5 mm
    bad = kincal.Measurements(q, xyz, meas.joint_names)
    val = kincal.simulate(true, qv, 0.0)
    plain = kincal.evaluate(kincal.calibrate(ur5, bad).robot, val).rms
    robust = kincal.evaluate(kincal.calibrate(ur5, bad, loss=loss).robot, val).rms
    assert robust < 0.2 * plain and robust < 50e-6


def test_explicit_parameter_list(ur5):
    true = kincal.perturb(ur5, seed=2)
    meas = kincal.simulate(true, ur5.sample_joints(40, seed=2), NOISE, seed=2)
    res = kincal.calibrate(ur5, meas, names=["j2.a", "j3.a"], base="fixed")
    assert res.names == ("j2.a", "j3.a")
    with pytest.raises(kincal.IdentifiabilityError, match="j6.d"):
        kincal.calibrate(ur5, meas, names=["j6.d", "tool.z"], base="fixed")


def test_result_round_trips_through_yaml_and_json(tmp_path, ur5):
    import json
    true = kincal.perturb(ur5, seed=3)
    res = kincal.calibrate(ur5, kincal.simulate(true, ur5.sample_joints(50, seed=3), NOISE, seed=3))
    d = json.loads(json.dumps(res.to_dict()))
    assert d["converged"] and set(d["estimates"]) == set(res.names)
    kincal.save_robot(res.robot, tmp_path / "cal.yaml")
    assert kincal.load_robot(tmp_path / "cal.yaml").params == res.robot.params
    assert "parameter" in str(res) and "mm" in str(res)


def test_residual_sigma_is_the_unbiased_per_axis_estimate(ur5):
    """σ̂ = sqrt(‖r‖² / (3N − K)) at the fit, written out (and near the simulated noise)."""
    true = kincal.perturb(ur5, seed=12)
    q = ur5.sample_joints(120, seed=12)
    res = kincal.calibrate(ur5, kincal.simulate(true, q, NOISE, seed=12), base="fixed")
    expected = np.sqrt(np.sum(res.residuals**2) / (res.residuals.size - len(res.names)))
    assert res.sigma == pytest.approx(expected, rel=1e-12) and 0.8 * NOISE < res.sigma < 1.2 * NOISE
    assert kincal.FitOptions(method="pso", pso={"seed": None}).pso.seed is None  # a fresh swarm each run


def test_parameters_the_data_hardly_determine_are_held_at_nominal(monkeypatch):
    """40 poses in a small region with 0.5 mm of noise (a motion-capture marker, its noise declared): a
    parameter the poses determine worse than the plausible correction limits is held at nominal and
    named, as the fit of observation sets does; over 4 robots the held-out error over a wider region is
    lower than when it is fitted."""
    import importlib

    calibrate_module = importlib.import_module("kincal.identify.rounds")
    from kincal.identify.registration import kabsch

    ur = kincal.load_robot("ur5")
    errors = {"held": [], "fitted": []}
    for seed in range(4):
        true = kincal.perturb(ur, 0.5e-3, 0.5e-3, seed=seed)
        q0 = ur.sample_joints(1, seed=5 + seed)[0]
        rng = np.random.default_rng(seed)
        q, q_test = q0 + rng.uniform(-0.3, 0.3, (40, 6)), q0 + rng.uniform(-0.5, 0.5, (200, 6))
        meas = kincal.simulate(true, q, 0.5e-3, seed=2)
        for name in ("held", "fitted"):
            if name == "fitted":
                monkeypatch.setattr(calibrate_module, "weakest", lambda *a, **k: None)
            res = kincal.calibrate(ur, meas, diagnose=False, thresholds=kincal.Thresholds(tracker_noise=0.5e-3))
            monkeypatch.undo()
            if name == "held":
                assert len(res.weak) >= 1 and not set(res.weak) & set(res.names)
                assert all(res.robot.params[n] == ur.params[n] for n in res.weak)
                assert "kept at nominal, determined worse than a real robot's error" in str(res)
                assert res.to_dict()["weakly_determined"] == res.weak
            p, t = res.robot.forward(q_test), true.forward(q_test)
            R, c = kabsch(p, t)
            errors[name].append(float(np.mean(np.linalg.norm(p @ R.T + c - t, axis=1))))
    print({k: np.round(np.array(v) * 1e3, 3) for k, v in errors.items()})
    assert np.mean(errors["held"]) < np.mean(errors["fitted"])


def test_a_result_hands_out_read_only_arrays(ur5):
    """Edits in place of the arrays a result hands out raise, so what it prints stays what it computed: the mean
    error and σ of str(res) and to_dict() agree with numpy on a copy of the residuals (a copy is the user's own)."""
    true = kincal.perturb(ur5, seed=1)
    use_q = ur5.sample_joints(5, seed=3)
    res = kincal.calibrate(ur5, kincal.simulate(true, ur5.sample_joints(40, seed=1), NOISE, seed=2), use_q=use_q)
    assert use_q.flags.writeable  # the array given stays the caller's
    comp = kincal.compensate(res.robot, ur5.forward(ur5.sample_joints(3, seed=4)), ur5.sample_joints(3, seed=4))
    r = res.residuals
    with pytest.raises(ValueError, match="output array is read-only"):
        r *= 1e3
    for name, a in [("covariance", res.covariance), ("use_q", res.use_q), ("whitened_residual", res.whitened_residual),
                    ("comp.q", comp.q), ("comp.ok", comp.ok), ("comp.residual", comp.residual)]:
        with pytest.raises(ValueError, match="assignment destination is read-only"):
            a[...] = a
        assert not a.flags.writeable, name
    mine = np.array(res.residuals)
    mine *= 1e3  # the user's copy: free, and the result unchanged
    norms = np.linalg.norm(res.residuals, axis=1)
    sigma = np.sqrt(np.sum(res.residuals ** 2) / (res.residuals.size - len(res.names)))
    assert f"after:  n=40  mean {norms.mean() * 1e3:.4f} mm" in str(res)
    assert f"residual sigma per axis: {sigma * 1e3:.4f} mm" in str(res)
    d = res.to_dict()
    assert d["after"]["mean"] == pytest.approx(norms.mean(), rel=1e-12) and d["sigma"] == pytest.approx(sigma, rel=1e-12)
    before = res.std["j2.a"]
    with pytest.raises(TypeError, match="belongs to a frozen result"):  # res.std["j2.a"] *= 1000 printed 9.99 mm
        res.std["j2.a"] *= 1000
    assert res.std["j2.a"] == before and res.to_dict()["std"]["j2.a"] == before and dict(res.std) == res.std


def _writable(value, path: str, seen: set) -> list[str]:
    """The paths of the writable arrays ``value`` holds however deep: fields of kincal's records and objects, tuples,
    lists and dicts."""
    if id(value) in seen:
        return []
    seen.add(id(value))
    if isinstance(value, np.ndarray):
        return [path] if value.flags.writeable else []
    if isinstance(value, (tuple, list)):
        items = list(enumerate(value))
    elif isinstance(value, dict):
        items = list(value.items())
    elif type(value).__module__.startswith("kincal") and "__dict__" in dir(value):
        items = list(vars(value).items())
    else:
        return []
    return [p for k, v in items for p in _writable(v, f"{path}.{k}", seen)]


def test_every_array_a_calibration_holds_is_read_only(ur5, tmp_path):
    """Every array a result holds, however deep (its repeat record, observations, robots' compiled chains), is
    read-only: ``res.repeat.covariance[:] *= 100`` used to pass, and the calibration file then saved a repeat σ 10x
    the fit's, which compare judged by. The file keeps the covariance as computed, to the digit."""
    grid = kincal.read_measurements(DATA / "ur5_grid.csv", ur5, joint_cols=UR5_COLS, length_unit="mm",
                                    angle_unit="deg")
    res = kincal.calibrate(ur5, grid)
    assert res.repeat is not None and res.repeat.covariance.shape == (26, 26) and len(res.repeat.poses) > 0
    assert _writable(res, "res", set()) == []
    cov = np.array(res.repeat.covariance)
    for a in (res.repeat.covariance, res.repeat.poses, res.repeat.residuals):
        with pytest.raises(ValueError, match="read-only"):
            a[:] *= 100.0
    kincal.save_robot(res.robot, tmp_path / "cal.yaml", calibration=res.record())
    record = load_calibration_record(tmp_path / "cal.yaml")["repeat"]
    at = [res.repeat.names.index(n) for n in record["parameters"]]  # the robot's parameters of the fit's
    assert np.allclose(np.array(record["covariance"], dtype=float), cov[np.ix_(at, at)], rtol=1e-12, atol=0.0)
    comp = kincal.compensate(res.robot, res.robot.forward(grid.q[:5]), grid.q[:5])
    assert _writable(comp, "comp", set()) == [] and comp.ok.all()
