"""calibrate as problem + observation set + solver: option checks first, the base-mode rule, batched swarms."""
import importlib

import numpy as np
import pytest

import kincal
from kincal.design.ide import F_MIN, mutation_factor
from kincal.identify import FitOptions
from kincal.observe import JointObs, PointObs

calibrate_module = importlib.import_module("kincal.identify.calibrate")  # the module, not the function
select_module = importlib.import_module("kincal.design.select")
stacked_module = importlib.import_module("kincal.identify.stacked")


@pytest.fixture(scope="module")
def puu3_data():
    robot = kincal.load_robot("puu3")
    true = robot.with_params({"r": robot.params["r"] - 1e-3, "L1": robot.params["L1"] + 3.4e-3,
                              "L2": robot.params["L2"] - 2.8e-3, "L3": robot.params["L3"] + 2.2e-3})
    return robot, kincal.simulate(true, robot.sample_joints(30, seed=1), noise=0.0)


@pytest.mark.parametrize("kwargs, words", [
    (dict(method="pso", loss="huber"), ("pso", "huber")),
    (dict(method="pso+lm", loss="soft_l1"), ("pso+lm", "soft_l1")),
    (dict(pso={"particles": 10}), ("pso=", "method='lm'")),
    (dict(method="pso", pso={"swarm": 10}), ("swarm", "particles")),
    (dict(f_scale=-1.0), ("f_scale",)),
    (dict(max_iter=0), ("max_iter",)),
    (dict(names=["r", "nope"]), ("nope",)),
    (dict(residual="joint", robot="ur5"), ("joint", "ur5")),
    (dict(rank_tol=2.0), ("rank_tol",)),
    (dict(error_model="harmonics:9"), ("error model 'harmonics:9'",)),
    (dict(error_model={"name": "auto", "payload": -2.0}), ("payload",)),
    (dict(drift=True, residual="joint"), ("drift", "cartesian")),
    (dict(thresholds={"tracker_noise": -1.0}), ("tracker_noise",)),
    (dict(frobnicate=1), ("frobnicate", "the options are")),
])
def test_options_are_checked_before_any_work(puu3_data, monkeypatch, kwargs, words):
    robot, meas = puu3_data
    kwargs = dict(kwargs)  # the parameter is shared by every run of this test in a process
    if kwargs.pop("robot", None) == "ur5":
        robot = kincal.load_robot("ur5")
        meas = kincal.simulate(robot, robot.sample_joints(10, seed=0), noise=0.0)

    def no_work(*a, **k):
        raise AssertionError("work started before the options were checked")
    monkeypatch.setattr(calibrate_module, "fit_stack", no_work)
    monkeypatch.setattr(calibrate_module, "select_model", no_work)
    with pytest.raises((ValueError, kincal.ModelError)) as exc:
        kincal.calibrate(robot, meas, **kwargs)
    assert all(w in str(exc.value) for w in words), str(exc.value)


def _no_work(*a, **k):
    raise AssertionError("work started before the options were checked")


@pytest.mark.parametrize("changes, words", [
    (dict(method="fedorov", criterion="A"), ("fedorov", "D and I")),
    (dict(method="annealing"), ("method", "annealing")),
    (dict(criterion="X"), ("criterion", "X")),
    (dict(m=0), ("m=0",)),
    (dict(m=2000), ("m = 2000", "distinct")),
    (dict(generations=0), ("generations",)),
    (dict(restarts=-1), ("restarts",)),
    (dict(names=["j2.a", "j9.z"]), ("j9.z",)),
    (dict(units="inch"), ("units", "inch")),
    (dict(seed=-3), ("seed",)),
    (dict(frobnicate=1), ("frobnicate", "the options are")),
])
def test_design_options_are_checked_before_any_work(ur5, monkeypatch, changes, words):
    monkeypatch.setattr(select_module, "design_problem", _no_work)
    monkeypatch.setattr(select_module, "relaxed_bound", _no_work)
    with pytest.raises((ValueError, kincal.ModelError)) as exc:
        kincal.select_poses(ur5, ur5.sample_joints(300, seed=0), **changes)
    assert all(w in str(exc.value) for w in words), str(exc.value)


@pytest.mark.parametrize("kwargs, words", [
    (dict(damping=0.0), ("damping",)),
    (dict(damping=float("nan")), ("damping",)),
    (dict(rows=np.arange(3)), ("3 row numbers for 5 targets",)),
    (dict(q_start=None), ("starting point",)),
    (dict(q_start=np.zeros((4, 6))), ("5 targets but 4",)),
    (dict(targets=np.zeros((5, 2))), ("(N, 3)",)),
    (dict(targets=np.full((5, 3), np.nan)), ("finite",)),
])
def test_compensation_inputs_are_checked_before_any_work(ur5, monkeypatch, kwargs, words):
    compensate_module = importlib.import_module("kincal.compensate.commands")
    monkeypatch.setattr(compensate_module, "_checked", _no_work)
    q = ur5.sample_joints(5, seed=1)
    args = {"targets": ur5.forward(q), "q_start": q, **kwargs}
    with pytest.raises((ValueError, kincal.ModelError)) as exc:
        kincal.compensate(ur5, args.pop("targets"), args.pop("q_start"), **args)
    assert all(w in str(exc.value) for w in words), str(exc.value)


def test_base_mode_rule_has_one_home(ur5):
    q = ur5.sample_joints(60, seed=0)
    fixed = kincal.analysis.free_parameters(ur5, q, base="fixed")
    est = kincal.analysis.free_parameters(ur5, q, base="estimate")
    assert not set(fixed.candidates) & set(ur5.base_params())
    assert set(ur5.base_params()) <= set(est.identifiable)  # the base absorbs j1.theta and j1.d
    assert {"j1.theta", "j1.d"} <= set(est.dropped) and fixed.rank == est.rank - 4
    explicit = kincal.analysis.free_parameters(ur5, q, base="estimate", names=["j2.a", "j3.a"])
    assert explicit.candidates == (*ur5.base_params(), "j2.a", "j3.a")
    with pytest.raises(ValueError, match="base.x"):
        kincal.analysis.free_parameters(ur5, q, base="fixed", names=["base.x", "j2.a"])
    # calibrate, design and the CLI all use it: the same free parameters
    meas = kincal.simulate(ur5, q, noise=0.0)
    res = kincal.calibrate(ur5, meas)  # one rank rule: no tolerance to pass; then the weak hold, named
    assert res.names == tuple(n for n in est.identifiable if n not in res.weak)
    assert set(res.weak) == {"j5.theta", "j5.alpha"}  # the reflector 0.09 mm off the flange axis: ±6 deg
    assert kincal.design.design_problem(ur5, q).names == est.identifiable


def test_batched_kinematics_equal_one_vector_at_a_time():
    for name in ("puu3-extended", "ur5"):
        robot = kincal.load_robot(name)
        q = robot.sample_joints(25, seed=3)
        V = robot.params.values + np.random.default_rng(0).normal(0.0, 1e-3, (40, robot.n_params))
        ref = np.stack([robot.forward(q, v) for v in V])
        np.testing.assert_allclose(robot.forward_batch(q, V), ref, atol=1e-13)
        if name.startswith("puu3"):
            p = robot.forward(q)
            ref = np.stack([robot.inverse(p, v) for v in V])
            np.testing.assert_allclose(robot.inverse_batch(p, V), ref, atol=1e-13)


def test_swarm_costs_equal_the_residuals(puu3_data):
    robot, meas = puu3_data
    V = robot.params.values + np.random.default_rng(1).normal(0.0, 2e-3, (30, robot.n_params))
    V[0, robot.params.index("L1")] = 0.05  # a leg too short to reach: that particle is infinitely bad
    cols = np.arange(robot.n_params)
    for kind in (JointObs, PointObs):
        obs = kind(meas.q, meas.rows, meas.source, xyz=meas.xyz)
        costs = obs.batch_cost(robot, V)
        assert costs[0] == np.inf
        ref = [np.mean(obs.evaluate_cols(robot, v, cols)[0] ** 2) for v in V[1:]]
        np.testing.assert_allclose(costs[1:], ref, rtol=1e-12)


def test_joint_residual_jacobian_is_its_derivative(puu3_data):
    """The joint-space observation's Jacobian against central differences, column by column, and its
    rows in the order of its samples (every pose's first joint, then the second, ...)."""
    robot, meas = puu3_data
    obs = JointObs(meas.q, meas.rows, meas.source, xyz=meas.xyz)
    v0, cols = robot.params.values, np.arange(robot.n_params)
    r, J = obs.evaluate_cols(robot, v0, cols)
    np.testing.assert_allclose(r.reshape(robot.n_joints, -1).T, robot.inverse(meas.xyz) - meas.q, atol=1e-15)
    assert np.array_equal(obs.sample_rows(), np.tile(np.arange(len(meas)), robot.n_joints))
    for k in cols:
        h = np.zeros_like(v0)
        h[k] = 1e-7
        fd = (obs.evaluate_cols(robot, v0 + h, cols)[0] - obs.evaluate_cols(robot, v0 - h, cols)[0]) / 2e-7
        np.testing.assert_allclose(J[:, k], fd, atol=1e-6)
    # each sample's noise: the joints' σ and the positions' σ through the inverse, D by central differences
    D = np.stack([(robot.inverse(meas.xyz + e) - robot.inverse(meas.xyz - e)) / 2e-7 for e in 1e-7 * np.eye(3)], -1)
    np.testing.assert_allclose(obs.covariance(robot, v0, np.zeros(0)), obs.std**2 * np.eye(3) + 15e-6**2 * D @
                               D.transpose(0, 2, 1), rtol=1e-6)


def test_pso_history_is_kept(puu3_data):
    robot, meas = puu3_data
    res = kincal.calibrate(robot, meas, base="fixed", residual="joint", method="pso",
                           names=["r", "R", "L1", "L2", "L3"], pso={"particles": 60, "iterations": 40})
    h = np.array(res.history)
    assert h.size == 40 and np.all(np.diff(h) <= 0) and h[-1] < h[0]
    # the last value is the mean squared joint residual of the returned model
    q_hat = res.robot.inverse(meas.xyz)
    assert h[-1] == pytest.approx(np.mean((q_hat - meas.q) ** 2), rel=1e-9)
    assert res.to_dict()["history"] == list(res.history)


def test_pso_sigma_of_a_parameter_in_an_undetermined_parameters_confound(puu3_data):
    """The swarm moves R, which only R - r determines, so r's value is where R was left: its sigma was 1.3 um (the
    pseudo-inverse's minimum-norm split, half of what LM gives with R held) while r sat 1.3 mm from the truth. Now
    its sigma holds R's search box (uniform +-8 mm, variance 64/3 mm^2): sqrt(sigma_LM^2 + 64e-6/3), and the model's
    predicted sigma, along that confound, stays the LM fit's."""
    robot, meas = puu3_data
    names = ["r", "R", "L1", "L2", "L3"]
    res = kincal.calibrate(robot, meas, base="fixed", residual="joint", method="pso", names=names,
                           pso={"particles": 60, "iterations": 40})
    assert res.identifiability.confounds["R"] == (("r", pytest.approx(-1.0, abs=1e-6)),)
    assert np.isinf(res.std["R"])
    cal = res.robot
    v0 = cal.params.as_dict()

    def residual(values):  # the joint-space residual, rad (one sigma for every row: it cancels below)
        return (cal.with_params(values).inverse(meas.xyz) - meas.q).ravel()
    r = residual(v0)
    J = np.stack([(residual({**v0, n: v0[n] + 1e-7}) - residual({**v0, n: v0[n] - 1e-7})) / 2e-7
                  for n in ("r", "L1", "L2", "L3")], axis=1)  # central differences; R held where it is: LM's rule
    held = np.linalg.inv(J.T @ J) * float(r @ r) / (r.size - len(names))
    assert res.std["r"] == pytest.approx(np.sqrt(held[0, 0] + 64e-6 / 3.0), rel=1e-9)
    assert res.std["L1"] == pytest.approx(np.sqrt(held[1, 1]), rel=1e-9)
    q = meas.q[:20]
    Jp = np.stack([(cal.with_params({**v0, n: v0[n] + 1e-7}).forward(q) - cal.with_params({**v0, n: v0[n] - 1e-7})
                    .forward(q)) / 2e-7 for n in ("r", "L1", "L2", "L3")], axis=2)  # (20, 3, 4) m per m
    expected = np.sqrt(np.einsum("nak,kl,nal->n", Jp, held, Jp))  # R held: the drift moves no prediction
    assert res.uncertainty().sigma(cal, q) == pytest.approx(expected, rel=1e-3)


def test_problem_refuses_too_little_data_before_solving(puu3_data, monkeypatch):
    robot, meas = puu3_data
    few = meas.subset(np.arange(1))
    monkeypatch.setattr(stacked_module, "swarm", _no_work)
    with pytest.raises(kincal.MeasurementError, match="1 poses give 3 equations for 4 parameters"):
        kincal.calibrate(robot, few, FitOptions(names=["L1", "L2", "L3", "r"], base="fixed", residual="joint",
                                                method="pso"))


def test_ide_mutation_factor_stays_positive():
    G = 150
    F = np.array([mutation_factor(g, G, 1.1) for g in range(1, G + 1)])
    assert F[0] == pytest.approx(1.1) and np.all(np.diff(F) < 0) and 0.09 < F[-1] < 0.12
    # the seed's formula with F0 = 0.5 would turn negative at generation 64; the floor holds it
    assert 0.5 - np.log2(1 + 63 / G) < 0
    assert min(mutation_factor(g, G, 0.5) for g in range(1, G + 1)) == F_MIN


def test_ide_history_reaches_the_design(capsys):
    robot = kincal.load_robot("guo3t2r")
    pool = kincal.candidate_pool(robot, 200, seed=0)
    d = kincal.select_poses(robot, pool, m=12, method="detmax-ide", criterion="comprehensive", certify=False,
                            generations=25)
    h = np.array(d.history)
    assert h.size == 26 and np.all(np.diff(h) >= 0) and h[-1] == pytest.approx(d.value, rel=1e-12)
    start = kincal.select_poses(robot, pool, m=12, method="detmax", criterion="comprehensive", certify=False)
    assert h[0] == pytest.approx(start.value, rel=1e-12)  # generation 0: the DETMAX design IDE starts from


def test_fit_options_round_trip_and_the_records_of_0_1():
    o = FitOptions(names=["j2.a", "j3.a"], base="fixed", loss="huber", f_scale=2e-4, rank_tol=1e-6, max_iter=7,
                   error_model=kincal.ErrorModel("compliance+harmonics:2", payload=1.5), drift=True,
                   thresholds=kincal.Thresholds(tracker_noise=0.011e-3))
    assert FitOptions.from_dict(o.to_dict()) == o
    assert FitOptions.from_dict(__import__("json").loads(__import__("json").dumps(o.to_dict()))) == o
    old = {"params": "auto", "base": "estimate", "loss": "linear", "method": "pso", "f_scale": None, "keep": [],
           "tol": 3e-05, "max_iter": 100, "residual": "joint", "model": "harmonics:1", "payload": 0.0, "drift": False,
           "pso_options": {"particles": 60}, "thresholds": kincal.Thresholds().to_dict()}  # kincal 0.1's record
    new = FitOptions.from_dict(old)
    assert (new.names, new.rank_tol, new.method, new.pso.particles, new.error_model) == \
        ("auto", 3e-05, "pso", 60, kincal.ErrorModel("harmonics:1"))
    with pytest.raises(ValueError, match="calibration record: unknown calibration option.*colour"):
        FitOptions.from_dict({**old, "colour": "red"})


def test_ide_settings_are_options_checked_before_any_work():
    robot = kincal.load_robot("guo3t2r")
    pool = kincal.candidate_pool(robot, 200, seed=0)
    for bad in ({"f0": 0.0}, {"cr": 1.5}, {"population": 5}, {"f0": "1"}):
        with pytest.raises(ValueError, match=list(bad)[0]):
            kincal.DesignOptions(**bad)
    runs = {f0: kincal.select_poses(robot, pool, m=12, method="detmax-ide", criterion="comprehensive", certify=False,
                                    generations=15, f0=f0, cr=0.9, population=12).history for f0 in (0.5, 1.1)}
    assert runs[0.5][0] == runs[1.1][0] and runs[0.5] != runs[1.1]  # same start, another search
