"""The Stewart–Gough platform (6-D implicit model): kinematics against independent references (finite
differences, closed-form leg lengths, the robot file read back), recovery of simulated parameters, sampling that
only gives poses that exist, and the real Jugglebot hexapod (``../shared/datasets/stewart_jugglebot``)."""
import csv
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.linalg import block_diag
from scipy.spatial.transform import Rotation

import kincal
from kincal.compensate import command_models, compensate
from kincal.errors import ModelError
from kincal.identify.calibrate import fit_observations
from kincal.models.stewart import StewartRobot
from kincal.observe import in_joint_space
from kincal.simulate import simulate_poses

from conftest import shared_dataset

ROOT = Path(__file__).resolve().parents[2]
JUGGLEBOT = shared_dataset("stewart_jugglebot")


@pytest.fixture(scope="module")
def hexapod():
    return kincal.load_robot("hexapod")


def _perturbed(robot, seed=3, size=2e-3):
    """``robot`` with every parameter off by up to ``size`` (m; scales by up to 0.2 %, rotations 2 mrad)."""
    rng = np.random.default_rng(seed)
    kinds = np.array(robot.params.kinds)
    step = np.where(kinds == "length", size, np.where(kinds == "ratio", 2e-3, 2e-3))
    return robot.with_params(robot.params.values + rng.uniform(-1, 1, robot.n_params) * step)


def _leg_lengths(robot, R, t):
    """Each leg's length (N, 6) from the platform pose (world R (N, 3, 3), tool point t (N, 3)) written out
    from the definition: base and platform points through the base frame and the tool point."""
    v = robot.params.as_dict()
    Rb = Rotation.from_euler("ZYX", [v["base.rz"], v["base.ry"], v["base.rx"]]).as_matrix()
    tb = np.array([v["base.x"], v["base.y"], v["base.z"]])
    tool = np.array([v["tool.x"], v["tool.y"], v["tool.z"]])
    out = np.zeros((len(t), 6))
    for i in range(6):
        b = Rb @ np.array([v[f"leg{i + 1}.b{c}"] for c in "xyz"]) + tb
        p = np.array([v[f"leg{i + 1}.p{c}"] for c in "xyz"])
        out[:, i] = np.linalg.norm(np.einsum("nij,j->ni", R, p - tool) + t - b, axis=1)
    return out


def test_forward_kinematics_closes_every_leg(hexapod):
    true = _perturbed(hexapod)
    q = true.sample_joints(50, seed=1)
    p, _, R, _ = true.frame_and_rates(q)
    v = true.params.as_dict()
    lead = true.lead
    expected = np.array([v[f"leg{i}.zero"] for i in range(1, 7)]) + np.array(
        [v[f"leg{i}.scale"] for i in range(1, 7)]) * lead * q
    assert np.abs(_leg_lengths(true, R, p) - expected).max() < 1e-12
    assert np.abs(true.inverse_pose(R, p) - q).max() < 1e-9


def _fd(fun, x, h):
    return np.stack([(fun(x + h * e) - fun(x - h * e)) / (2 * h) for e in np.eye(x.size)], axis=-1)


def _compliant(hexapod, give=10e-3):
    """The hexapod with its legs giving ``give`` (m) under the platform's weight, the base frame turned well away
    from the measurement frame's (so the loads' dependence on gravity's direction in the robot frame shows)."""
    robot = hexapod.with_load_compliance()
    return robot.with_params({"legs.compliance": give, "base.rx": 0.05, "base.ry": -0.08, "base.rz": 0.3})


@pytest.mark.parametrize("compliance", [False, True])
def test_jacobians_match_finite_differences(hexapod, compliance):
    robot = _perturbed(_compliant(hexapod) if compliance else hexapod)
    q = robot.sample_joints(4, seed=2)
    p, J, R, W = robot.frame_and_rates(q)
    v0 = robot.params.values
    assert np.abs(J - _fd(lambda v: robot.forward(q, v), v0, 1e-7)).max() < 1e-7
    turn = lambda v: Rotation.from_matrix(robot.frame_and_rates(q, v)[2] @ R.transpose(0, 2, 1)).as_rotvec()  # noqa: E731
    assert np.abs(W - _fd(turn, v0, 1e-7)).max() < 1e-7
    _, _, Jq, Wq = robot.pose_and_jacobian(q)
    for k in range(6):
        e = np.zeros(6)
        e[k] = 1e-6
        assert np.abs(Jq[:, :, k] - (robot.forward(q + e) - robot.forward(q - e)) / 2e-6).max() < 1e-7
        dR = robot.pose_and_jacobian(q + e)[1] @ robot.pose_and_jacobian(q - e)[1].transpose(0, 2, 1)
        assert np.abs(Wq[:, :, k] - Rotation.from_matrix(dR).as_rotvec() / 2e-6).max() < 1e-7
    qq, dq, dw = robot.inverse_pose_and_jacobian(R, p)
    assert np.abs(dq - _fd(lambda v: robot.inverse_pose(R, p, v), v0, 1e-7)).max() < 1e-6
    for k in range(3):
        w = np.zeros(3)
        w[k] = 1e-7
        turned = [Rotation.from_rotvec(s * w).as_matrix() @ R for s in (1, -1)]
        assert np.abs(dw[:, :, k] - (robot.inverse_pose(turned[0], p) - robot.inverse_pose(turned[1], p)) / 2e-7
                      ).max() < 1e-6
    # by the measured pose: a world translation of the tool point, then the turn above (how its noise reaches the legs)
    moved = robot.inverse_rates(p, None, R)
    assert np.abs(moved[:, :, :3] - _fd(lambda x: robot.inverse_pose(R, p + x), np.zeros(3), 1e-7)).max() < 1e-6
    assert np.array_equal(moved[:, :, 3:], dw) and np.abs(moved).max() > 10  # rad per m: a leg's lead of ~12 mm


@pytest.mark.parametrize("compliance", [False, True])
def test_robot_file_round_trip_and_units(hexapod, tmp_path, compliance):
    robot = _perturbed(_compliant(hexapod) if compliance else hexapod)
    for units in (("m", "rad"), ("mm", "deg")):
        path = tmp_path / f"hexapod-{units[0]}.yaml"
        kincal.save_robot(robot, path, *units)
        back = kincal.load_robot(path)
        tol = 0.0 if units == ("m", "rad") else 1e-15
        assert back.params.names == robot.params.names
        assert np.abs(back.params.values - robot.params.values).max() <= tol
        assert np.abs(back.lead - robot.lead).max() <= 1e-15 and np.array_equal(back.joint_types, robot.joint_types)
    text = yaml.safe_load((tmp_path / "hexapod-mm.yaml").read_text())
    nominal = yaml.safe_load((JUGGLEBOT / "nominal.yaml").read_text())
    leads = [leg["lead"] for leg in yaml.safe_load((ROOT / "src/kincal/models/robots/hexapod.yaml").read_text())["legs"]]
    assert leads == nominal["mm_per_rev"] and text["reading"] == {"unit": "rev"}
    assert np.allclose(hexapod.lead * 2 * np.pi * 1e3, nominal["mm_per_rev"], rtol=1e-15)


def test_the_legs_carry_the_platforms_weight(hexapod):
    """A symmetric hexapod (three-fold, mirrored pairs) level and centred: its six legs lean alike, so each carries
    a sixth of the weight along gravity, f = 1 / (6 u_z), and is shorter by the compliance times that load."""
    ang = np.radians([a + s for a in (0, 120, 240) for s in (-10, 10)])
    pang = np.radians([a + s for a in (0, 120, 240) for s in (-50, 50)])
    b = np.column_stack([0.41 * np.cos(ang), 0.41 * np.sin(ang), np.zeros(6)])
    p = np.column_stack([0.22 * np.cos(pang), 0.22 * np.sin(pang), np.zeros(6)])
    rigid = StewartRobot.build("sym", b, p, np.full(6, 0.6), (np.zeros(6), np.full(6, 0.3)))
    robot = rigid.with_load_compliance().with_params({"legs.compliance": 10e-3})
    home = np.concatenate([np.eye(3), [[0.0], [0.0], [0.55]]], axis=1)[None]  # platform 0.55 m above the base
    d = p + [0.0, 0.0, 0.55] - b
    uz = d[:, 2] / np.linalg.norm(d, axis=1)
    assert np.ptp(uz) < 1e-15 and uz[0] < 0.99  # every leg leans alike
    dq = robot.inverse_local(home, robot.params.values) - rigid.inverse_local(home, rigid.params.values)
    assert np.allclose(dq[0], 10e-3 / (6 * uz), rtol=1e-12, atol=0)  # a longer reading for the same pose
    robot, v = _compliant(hexapod), _compliant(hexapod).params.values
    # the loads hold the weight (up: the measurement frame's z) and no moment, whatever the pose
    x = robot._solve_local(robot.sample_joints(20, seed=3), v)[0]
    d, length, _ = robot._vectors(x, v)
    f, JT, m, up = robot._loads(x, d / length[..., None], v)
    u = d / length[..., None]
    up = Rotation.from_euler("ZYX", [0.3, -0.08, 0.05]).as_matrix().T @ [0.0, 0.0, 1.0]  # the base frame turned
    assert np.abs(np.einsum("nk,nki->ni", f, u) - up).max() < 1e-12
    assert np.abs(np.einsum("nk,nki->ni", f, np.cross(m, u))).max() < 1e-12


def test_sampled_configurations_exist_and_cover_the_legs(hexapod):
    q = hexapod.sample_joints(400, seed=4)
    assert q.shape == (400, 6) and hexapod.within_limits(q).all()
    x, ok = hexapod._solve_local(q, hexapod.params.values, strict=False)
    assert ok.all()
    stroke = hexapod.upper - hexapod.lower
    assert np.all(q.max(0) - q.min(0) > 0.5 * stroke)  # the draws reach across most of each leg's range
    assert np.array_equal(q, hexapod.sample_joints(400, seed=4))


def test_a_constraint_count_that_does_not_match_the_unknown_is_named():
    class Five(StewartRobot):
        def constraints(self, x, q, values):
            return super().constraints(x, q, values)[:, :5]
    robot = kincal.load_robot("hexapod")
    five = Five(robot.name, robot.params, robot.lower, robot.upper, robot.lead, robot.motor)
    with pytest.raises(ModelError, match="5 constraint.*pose unknown of 6 coordinates"):
        five.forward(robot.sample_joints(2))


@pytest.mark.parametrize("residual", ["cartesian", "joint"])
def test_simulated_hexapod_recovers_every_identifiable_parameter(hexapod, residual):
    true = _perturbed(hexapod, seed=5)
    q = hexapod.sample_joints(60, seed=6)
    target = Rotation.from_rotvec([0.01, -0.02, 0.03]).as_matrix()
    obs = dataclasses.replace(simulate_poses(true, q, target, std_pos=0.0, std_rot=0.0), std_pos=15e-6, std_rot=5e-5)
    obs = obs if residual == "cartesian" else in_joint_space(obs)
    res = fit_observations(hexapod, [obs], prior="none")
    gauge = res.identifiability.frames  # the design frames' 12 freedoms, named as such; nothing else dropped
    assert len(res.names) + len(res.nuisance) == 48 and len(gauge) == 12 and not res.identifiability.dropped
    assert "where the robot frame stands among the base points (6:" in str(res)
    # the 12 gauge freedoms leave the predictions alone: every pose of the true robot is reproduced
    q_test = hexapod.sample_joints(40, seed=7)
    p, _, R, _ = true.frame_and_rates(q_test)
    ph, _, Rh, _ = res.robot.frame_and_rates(q_test)
    fitted = res.observations[0]
    turn = Rh @ fitted.target(np.array([res.nuisance[f"target.r{c}"] for c in "xyz"])) @ (R @ target).transpose(0, 2, 1)
    assert np.abs(ph - p).max() < 1e-9 and np.abs(Rotation.from_matrix(turn).as_rotvec()).max() < 1e-9
    # started with the gauge parameters at their true values, the fit finds every other one
    start = hexapod.with_params({n: true.params[n] for n in gauge})
    again = fit_observations(start, [obs], prior="none")
    assert set(again.identifiability.frames) == set(gauge)
    for n in again.names:
        assert abs(again.robot.params[n] - true.params[n]) <= 1e-9 * max(abs(true.params[n]), 1e-3), n


def _judged_norms(res, obs):
    """Each sample's norm √(rᵢᵀ Vᵢ⁻¹ rᵢ) written out in numpy: rᵢ the legs that reach the measured pose − the read
    ones; Cᵢ = σ² I + D Σ Dᵀ, D the legs' central differences by the measured position and by a world turn of the
    measured rotation, Σ the poses' σ; V = (I − H) C (I − H)ᵀ over all rows at once, H the least-squares hat matrix
    of the fit's free columns (robot and target parameters) by central differences."""
    robot, v = res.robot, res.robot.params.values
    target = np.array([res.nuisance[f"target.r{c}"] for c in "xyz"])

    def legs(values=v, aim=target, move=np.zeros(3), turn=np.zeros(3)):
        R = Rotation.from_rotvec(turn).as_matrix() @ obs.R @ obs.target(aim).T
        return robot.inverse_pose(R, obs.xyz + move, values)
    n, zero, h = obs.q.shape[1], np.zeros(3), 1e-7
    D = np.concatenate([_fd(lambda x: legs(move=x), zero, h), _fd(lambda x: legs(turn=x), zero, h)], axis=2)
    C = obs.std**2 * np.eye(n) + D @ np.diag([obs.std_pos**2] * 3 + [obs.std_rot**2] * 3) @ D.transpose(0, 2, 1)
    cols = [_fd(lambda x: legs(values=v + x[0] * np.eye(v.size)[robot.params.index(f)]), np.zeros(1), h)
            if f in robot.params.names else _fd(lambda x: legs(aim=target + x[0] * np.eye(3)["xyz".index(f[-1])]),
                                                   np.zeros(1), h) for f in res.free]
    G = np.concatenate(cols, axis=2).reshape(obs.q.size, -1)  # (N·n, K), sample by sample
    I_H = np.eye(G.shape[0]) - G @ np.linalg.pinv(G.T @ G) @ G.T
    V = I_H @ block_diag(*C) @ I_H.T
    r = legs() - obs.q
    blocks = [V[i * n:(i + 1) * n, i * n:(i + 1) * n] for i in range(len(r))]
    return np.array([np.sqrt(ri @ np.linalg.solve(Vi, ri)) for ri, Vi in zip(r, blocks)])


def test_clean_poses_in_joint_space_are_judged_by_their_own_noise(hexapod, tmp_path, capsys):
    """A sample of the legs' residual (the legs that reach the measured pose − the read ones) carries the pose's
    noise through the inverse kinematics, C = σ² I + D Σ Dᵀ, not σ per leg: judged by σ alone, clean simulated poses
    (the 80 of seed 0, as `kincal simulate` writes them) had row 10 called an outlier (5.21 robust σ, limit 5).
    Judged by each sample's residual covariance after the fit, V = [(I − H) C (I − H)ᵀ]ᵢᵢ, checked here against the
    written-out numpy computation, it is not; a pose really 5 mm or 20 mrad off is found, alone."""
    from kincal.cli import main
    from kincal.identify.judge import sample_norms
    from kincal.observe import ObservationFormat, read_observations

    path = tmp_path / "l0.csv"
    assert main(["simulate", "hexapod", "--perturb", "--poses", "80", "--type", "pose", "-o", str(path)]) == 0
    capsys.readouterr()
    data = read_observations(str(path), hexapod, ObservationFormat("pose"))
    fit = lambda obs: fit_observations(hexapod, [obs], residual="joint", joint_std=0.006 * 2 * np.pi)  # noqa: E731
    res = fit(data)
    obs = res.observations[0]
    norms = sample_norms(res.observations, res.whitened_residual)[0]
    np.testing.assert_allclose(norms, _judged_norms(res, obs), rtol=1e-5)
    assert not any(len(found) for found in res.outliers) and res.verdict.status == "good"
    assert obs.rows[np.argmax(norms)] == 10  # still the largest, within the noise now
    moved = data.xyz.copy()
    moved[28, 0] += 5e-3
    turned = data.R.copy()
    turned[28] = Rotation.from_rotvec([0.0, 0.02, 0.0]).as_matrix() @ turned[28]
    for bad in (dataclasses.replace(data, xyz=moved), dataclasses.replace(data, R=turned)):
        found = fit(bad)
        assert [obs.rows[i] for i in found.outliers[0]] == [30] and found.verdict.status == "suspect"


def test_simulated_compliant_hexapod_keeps_its_gauge_and_recovers_the_compliance(hexapod):
    """Gravity along the measurement frame and the weight at the platform points' centre: the design frames stay
    gauge freedoms (12, named), and a fit with the error model 'compliance' finds the legs' give exactly."""
    true = _perturbed(_compliant(hexapod, 12e-3), seed=8)
    q = hexapod.sample_joints(60, seed=6)
    obs = dataclasses.replace(simulate_poses(true, q, np.eye(3), std_pos=0.0, std_rot=0.0), std_pos=15e-6,
                              std_rot=5e-5)
    res = fit_observations(hexapod, [in_joint_space(obs)], prior="none", error_model="compliance")
    assert len(res.identifiability.frames) == 12 and not res.identifiability.dropped
    assert abs(res.robot.params["legs.compliance"] - true.params["legs.compliance"]) < 1e-11
    q_test = hexapod.sample_joints(40, seed=7)
    assert np.abs(res.robot.forward(q_test) - true.forward(q_test)).max() < 1e-9


# ---- the delta robot ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def delta():
    return kincal.load_robot("delta")


def test_delta_closes_every_forearm_and_inverts_in_closed_form(delta):
    true = _perturbed(delta, seed=8)
    q = true.sample_joints(80, seed=9)
    p = true.forward(q)
    v = true.params.as_dict()
    Rb = Rotation.from_euler("ZYX", [v["base.rz"], v["base.ry"], v["base.rx"]]).as_matrix()
    local = (p - [v["base.x"], v["base.y"], v["base.z"]]) @ Rb
    for i in range(3):  # the definition written out: elbow from the motor angle, forearm length from the platform
        a = np.deg2rad(120.0 * i) + v[f"arm{i + 1}.phi"]
        e = np.array([np.cos(a), np.sin(a), 0.0])
        alpha = q[:, i] + v[f"arm{i + 1}.zero"]
        elbow = v[f"arm{i + 1}.R"] * e + v[f"arm{i + 1}.L"] * (np.cos(alpha)[:, None] * e
                                                                - np.sin(alpha)[:, None] * [0, 0, 1.0])
        reach = np.linalg.norm(local + v[f"arm{i + 1}.r"] * e - elbow, axis=1)
        assert np.abs(reach - v[f"arm{i + 1}.l"]).max() < 1e-12
        assert np.all(elbow[:, 2] > local[:, 2])  # the platform hangs below the elbows
    assert np.abs(true.inverse(p) - q).max() < 1e-9
    assert np.abs(true.inverse_rates(p[:5]) - _fd(lambda x: true.inverse(p[:5] + x), np.zeros(3), 1e-7)).max() < 1e-6
    J = true.param_jacobian(q[:5])
    assert np.abs(J - _fd(lambda x: true.forward(q[:5], x), true.params.values, 1e-7)).max() < 1e-7
    for k in range(3):
        assert np.abs(true.joint_jacobian(q[k]) - _fd(lambda x: true.forward(x), q[k], 1e-7)).max() < 1e-7


def test_delta_robot_file_round_trip(delta, tmp_path):
    robot = _perturbed(delta, seed=10)
    kincal.save_robot(robot, tmp_path / "d.yaml")
    back = kincal.load_robot(tmp_path / "d.yaml")
    assert np.array_equal(back.params.values, robot.params.values) and np.array_equal(back.lower, robot.lower)


def test_simulated_delta_recovers_every_identifiable_parameter(delta):
    true = _perturbed(delta, seed=11)
    q = delta.sample_joints(80, seed=12)
    meas = kincal.simulate(true, q, noise=0.0, seed=0)
    res = kincal.calibrate(delta, meas)
    start = delta.with_params({n: true.params[n] for n in res.identifiability.dropped})
    again = kincal.calibrate(start, meas)
    assert set(again.identifiability.dropped) == set(res.identifiability.dropped)
    for n in again.names:
        assert abs(again.robot.params[n] - true.params[n]) <= 1e-9 * max(abs(true.params[n]), 1e-3), n


# ---- the noise the fit predicts (Cramér–Rao) against what it does ---------------------------------------------


def _validation_ratio(robot, fit, bound, seeds=8):
    """RMS of the fitted model's position error at fresh poses over ``seeds`` draws of the noise, over the
    RMS the Cramér–Rao bound predicts there: σ² = trace(J C Jᵀ), ``bound(res)`` giving C over ``res.names``."""
    true = _perturbed(robot, seed=20)
    q_val = robot.sample_joints(50, seed=21)
    p_true = true.forward(q_val)
    err2, pred2 = [], []
    for seed in range(seeds):
        res = fit(true, seed)
        J = res.robot.param_jacobian(q_val)[:, :, res.robot.params.indices(res.names)]
        pred2.append(np.einsum("nip,pq,niq->n", J, bound(res), J).mean())
        err2.append(np.mean(np.sum((res.robot.forward(q_val) - p_true) ** 2, axis=1)))
    return np.sqrt(np.mean(err2) / np.mean(pred2))


@pytest.mark.slow
def test_hexapod_validation_error_matches_its_cramer_rao_prediction(hexapod):
    target = Rotation.from_rotvec([0.01, -0.02, 0.03]).as_matrix()
    q = hexapod.sample_joints(60, seed=22)

    def fit(true, seed):
        obs = simulate_poses(true, q, target, std_pos=15e-6, std_rot=0.05e-3, seed=seed)
        return fit_observations(hexapod, [obs], prior="none")

    def bound(res):  # the fit's covariance σ̂²(JᵀJ)⁻¹ (whitened by the stated σ) without its estimate σ̂²
        rows = 6 * len(q)
        at = [res.free.index(n) for n in res.names]
        return res.covariance[np.ix_(at, at)] * (rows - len(res.free)) / (res.whitened_rms**2 * rows)
    assert 0.80 <= _validation_ratio(hexapod, fit, bound) <= 1.10  # (below 1 only by the draws: 8 seeds spread ±8 %)


@pytest.mark.slow
def test_delta_validation_error_matches_its_cramer_rao_prediction(delta):
    q = delta.sample_joints(60, seed=23)

    def bound(res):  # σ²(JᵀJ)⁻¹ of the training poses' position Jacobian, from the model itself
        J = res.robot.param_jacobian(q)[:, :, res.robot.params.indices(res.names)].reshape(-1, len(res.names))
        return (15e-6) ** 2 * np.linalg.inv(J.T @ J)
    ratio = _validation_ratio(delta, lambda true, seed: kincal.calibrate(delta, kincal.simulate(true, q, noise=15e-6,
                                                                                                  seed=seed)), bound)
    assert 0.80 <= ratio <= 1.10


# ---- compensation: platform target poses -> leg commands ---------------------------------------------------


def test_pose_targets_become_leg_commands_that_reach_them(hexapod):
    true = _perturbed(hexapod, seed=30)
    q = hexapod.sample_joints(2000, seed=31)
    p, _, R, _ = hexapod.frame_and_rates(q)  # targets: where the nominal model puts the platform
    comp = compensate(true, p, rotations=R)
    assert comp.method == "closed-form inverse (poses)" and comp.ok.mean() > 0.95
    back_p, _, back_R, _ = true.frame_and_rates(comp.q[comp.ok])  # through the calibrated model, forward
    assert np.abs(back_p - p[comp.ok]).max() < 1e-9  # m: 1e-6 mm
    turn = Rotation.from_matrix(back_R @ R[comp.ok].transpose(0, 2, 1)).as_rotvec()
    assert np.abs(turn).max() < 1e-9
    refused = ~comp.ok  # only commands beyond a leg's range are refused, each named
    assert not true.within_limits(comp.q[refused]).any() and len(comp.problems) == refused.sum()
    with pytest.raises(ModelError, match="whole pose"):
        compensate(true, p[:3])


def test_a_pose_target_beyond_the_legs_is_refused_by_row_and_degrees_read_as_radians_are_named(hexapod, tmp_path,
                                                                                                capsys):
    """A row whose legs are past their range (one target's angles written in degrees, in a file declared in radians,
    all within 2π so the reader passes them) made the forward kinematics of the whole file fail ('did not converge
    for 1 configuration(s)', exit 1, nothing written, --skip-unreachable or not); now that row is refused with its
    leg in the file's unit, said to look like degrees where read so it is reached, and the others are written: the
    legs of the definition, |R p_i + t - b_i| = zero + lead · reading."""
    design = yaml.safe_load((ROOT / "src/kincal/models/robots/hexapod.yaml").read_text())["legs"]
    b, pl = np.array([leg["base"] for leg in design]), np.array([leg["platform"] for leg in design])  # mm
    zero, lead = np.array([leg["zero"] for leg in design]), np.array([leg["lead"] for leg in design])  # mm, mm/rev
    home = hexapod.frame_and_rates(np.full((1, 6), 2.1 * 2 * np.pi))[0][0] * 1e3  # mm: every leg at 2.1 rev
    rows = [(home, [0.02, 0.01, -0.03]), (home + [10, 0, 0], [1.6, -2.8, -5.5]),  # the second's angles in degrees
            (home + [0, -10, 0], [0.0, 0.03, 0.01]), (home + [0, 0, 600], [0.0, 0.0, 0.0])]  # the last out of reach
    targets = tmp_path / "targets.csv"
    targets.write_text("x,y,z,rz,ry,rx\n" + "".join(",".join(f"{v:.6f}" for v in (*p, *a)) + "\n" for p, a in rows))

    def legs(p, angles):  # rev: the definition, written out
        R = Rotation.from_euler("ZYX", angles).as_matrix()
        return (np.linalg.norm(pl @ R.T + p - b, axis=1) - zero) / lead

    flags = ["--pose", "--length-unit", "mm", "--angle-unit", "rev", "--orientation", "euler-zyx-intrinsic-rad",
             "--rot-cols", "rz,ry,rx", "-o", str(tmp_path / "legs.csv")]
    code, _, text = _kincal(capsys, ["compensate", "hexapod", str(targets), *flags])
    assert code == 4 and not (tmp_path / "legs.csv").exists() and "did not converge" not in text
    code, _, text = _kincal(capsys, ["compensate", "hexapod", str(targets), *flags, "--skip-unreachable"])
    assert code == 0 and "2 of 4 targets" in text
    as_read = legs(*rows[1])
    j = int(np.argmax(as_read - 4.2))
    assert as_read[j] > 4.2 and f"row 3: the command breaks the joint limits: leg{j + 1} at {as_read[j]:.3f} rev" in text
    assert "row 3" in text and "the angles look like degrees (orientation='euler-zyx-intrinsic-deg'; CLI: --orientation " \
                               "euler-zyx-intrinsic-deg)" in text
    assert np.all(legs(rows[1][0], np.radians(rows[1][1])) < 4.2)  # read as degrees: within the legs' range
    far = next(line for line in text.splitlines() if line.startswith("refused: row 5"))
    assert "look like degrees" not in far
    written = np.loadtxt(tmp_path / "legs.csv", delimiter=",", skiprows=1)
    assert written[:, 0].tolist() == [2, 4]
    assert np.abs(written[:, 1:7] - [legs(*rows[0]), legs(*rows[2])]).max() < 1e-6  # rev


def test_a_parallel_robots_leg_columns_in_targets_are_said_not_to_be_read(hexapod, tmp_path):
    """A hexapod's legs follow from each target pose alone: leg columns in a targets file (all 0.5 rev here) were
    silently left unread, the commands byte for byte those of the file without them; now a warning names them."""
    from kincal.compensate import StreamJob, TargetsFormat, compensate_file

    q = hexapod.sample_joints(3, seed=4)
    p, _, R, _ = hexapod.frame_and_rates(q)
    quat = Rotation.from_matrix(R).as_quat()  # x, y, z, w
    body = "".join(",".join(f"{v:.9f}" for v in (*pi * 1e3, *qi)) + "\n" for pi, qi in zip(p, quat))
    bare, legs = tmp_path / "bare.csv", tmp_path / "legs.csv"
    bare.write_text("x,y,z,qx,qy,qz,qw\n" + body)
    legs.write_text("leg1,leg2,leg3,leg4,leg5,leg6,x,y,z,qx,qy,qz,qw\n" + "".join("0.5," * 6 + line + "\n"
                                                                                   for line in body.splitlines()))
    job = StreamJob(hexapod, None, TargetsFormat(pose=True, orientation="quat-xyzw", length_unit="mm",
                                                 angle_unit="rev"))
    without, with_legs = (compensate_file(job, str(f), str(tmp_path / f"out_{f.name}")) for f in (bare, legs))
    assert without.warnings == () and with_legs.all_ok
    assert with_legs.warnings[0].startswith("the file's joint columns leg1, leg2, leg3, leg4, leg5, leg6 are not read")
    commands = [np.loadtxt(tmp_path / f"out_{f.name}", delimiter=",", skiprows=1)[:, 1:7] for f in (bare, legs)]
    assert np.abs(commands[0] - commands[1]).max() == 0 and np.abs(commands[0] * 2 * np.pi - q).max() < 1e-6


def test_the_formats_reference_gives_the_parallel_robots_files():
    """docs/reference/formats.md gave serial robot files only: every key the hexapod's and the delta's readers take,
    and the rev unit, are now there, the example leg being the bundled hexapod's first."""
    import re

    from kincal.models.delta import ARM_NAMES
    from kincal.models.yaml_io import _TYPE_KEYS
    from kincal.models.yaml_kinds import LEG_KEYS

    page = (ROOT / "docs/reference/formats.md").read_text()
    assert "`type: stewart`" in page and "`type: delta`" in page and "`rev`" in page and "reading: {unit: rev}" in page
    for key in sorted(LEG_KEYS | _TYPE_KEYS["stewart"] | _TYPE_KEYS["delta"]):
        assert re.search(rf"\b{key}\b", page), key
    assert all(f".{name}`" in page for name in ARM_NAMES)
    leg = yaml.safe_load(re.search(r"  - (\{base: .*\})", page).group(1))
    assert leg == yaml.safe_load((ROOT / "src/kincal/models/robots/hexapod.yaml").read_text())["legs"][0]


# ---- the real Jugglebot hexapod through the command line ---------------------------------------------------


def _kincal(capsys, argv):
    from kincal.cli import main

    code = main(argv)
    out = capsys.readouterr()
    return code, (json.loads(out.out) if out.out.strip().startswith("{") else None), out.err + out.out


JUGGLE = ["--type", "pose", "--length-unit", "mm", "--angle-unit", "rev", "--orientation", "quat-xyzw"]


@pytest.mark.slow
def test_jugglebot_session_to_session_through_the_command_line(tmp_path, capsys):
    """Trained on one session, judged on the other with its measurement frame and the platform's rigid body
    re-fitted (the reference of the dataset's README: 0.610 mm / 0.112 deg and 1.268 mm, an independent
    least-squares implementation of the same 48-parameter leg model)."""
    s1, s2 = str(JUGGLEBOT / "S1.csv"), str(JUGGLEBOT / "S2.csv")
    common = ["--residual", "joint", "--refit-target", "--json"]
    code, out, _ = _kincal(capsys, ["calibrate", "hexapod", s1, "--test", s2, *JUGGLE, *common,
                                    "-o", str(tmp_path / "s1.yaml"), "--residuals", str(tmp_path / "res.csv")])
    # the per-sample file: the legs' misses in motor mrad (they were written as position errors in "mm", 100x the
    # fit's 0.84 mm); through the mean lead, 0.41 mm RMS per leg, the dataset README's fit of the same model
    rows = list(csv.DictReader(open(tmp_path / "res.csv")))
    assert rows[0]["position_error_mm"] == "" and len(rows) == len(open(s1).read().splitlines()) - 1
    legs = np.array([float(r["joint_error_mrad"]) for r in rows])
    lead = np.mean([leg["lead"] for leg in yaml.safe_load(
        (ROOT / "src/kincal/models/robots/hexapod.yaml").read_text())["legs"]])  # mm per rev
    assert abs(np.sqrt(np.mean(legs**2) / 6) * 1e-3 / (2 * np.pi) * lead - 0.41) < 0.01
    held = out["held_out"][0]
    assert code in (0, 4) and held["mean"] * 1e3 <= 0.611 and np.degrees(held["mean_rotation"]) <= 0.1120
    assert len(out["estimated"]) + len(out["nuisance"]) == 48 and len(out["identifiability"]["frames"]) == 12
    assert out["held_out_nominal"][0]["mean"] * 1e3 > 2.4  # the design geometry, frames fitted alike: 2.41 mm
    # leg 1's hand-measured lead (75.69 mm/rev) is 6 % off the others' and the data's: named as such
    said = " ".join(r["message"] for r in out["verdict"]["reasons"])
    assert "leg1.scale -6.1 %" in said and "leg1: the travel per reading unit (a leg's lead)" in said
    targets = tmp_path / "targets.csv"  # pose commands from the calibrated file: the orientation rule's poses are
    # drawn where the legs assemble (it drew each leg in its own range, and ended in a forward-kinematics error)
    targets.write_text("x,y,z,qx,qy,qz,qw\n0,0,700,0,0,0,1\n20,-10,720,0,0,0,1\n-15,25,690,0.0436,0,0,0.999\n")
    code, _, text = _kincal(capsys, ["compensate", str(tmp_path / "s1.yaml"), str(targets), "--pose",
                                     *JUGGLE[2:], "-o", str(tmp_path / "legs.csv")])
    assert code == 0 and "3 of 3 targets" in text and "orientation: from the calibrated model" in text
    cal = kincal.load_robot(str(tmp_path / "s1.yaml"))
    # the robot's own frame is far less certain than the motion capture's (the base and platform points and the
    # legs' zeros trade places): said, with the ratio of the record's σ over the training region (a UR5's is 1.5)
    unc = kincal.analysis.load_uncertainty(str(tmp_path / "s1.yaml"))
    ratio = unc.without(cal.base_params(), cal).envelope_sigma / unc.envelope_sigma
    assert ratio > 3 and f"the calibrated model is {ratio:.1f}x less certain than in the instrument's" in text
    nominal = kincal.models.load_calibration_record(str(tmp_path / "s1.yaml"))["nominal"]
    model, _ = command_models(cal, nominal)
    rows = np.loadtxt(tmp_path / "legs.csv", delimiter=",", skiprows=1)
    reached = model.forward(rows[:, 1:7] * 2 * np.pi)  # rev -> rad, the legs' reading unit
    assert np.abs(reached * 1e3 - np.loadtxt(targets, delimiter=",", skiprows=1)[:, :3]).max() < 1e-6
    # the calibrated model exported to a robot file: the base it writes is the nominal one (it wrote the motion
    # capture frame, 48 mm and 2.2° away, and its commands aimed there), so its commands are the calibrated file's
    code, _, text = _kincal(capsys, ["export", str(tmp_path / "s1.yaml"), str(tmp_path / "exported.yaml")])
    assert code == 0 and "the file keeps the nominal model's base" in text
    assert kincal.load_robot(str(tmp_path / "exported.yaml")).base_transform()[1].tolist() == [0.0, 0.0, 0.0]
    code, _, text = _kincal(capsys, ["compensate", str(tmp_path / "exported.yaml"), str(targets), "--pose",
                                     *JUGGLE[2:], "-o", str(tmp_path / "legs_exported.csv")])
    assert code == 0 and "has no calibration record" in text
    again = np.loadtxt(tmp_path / "legs_exported.csv", delimiter=",", skiprows=1)
    assert np.abs(again[:, 1:7] - rows[:, 1:7]).max() < 1e-9
    code, out, text = _kincal(capsys, ["calibrate", "hexapod", s2, "--test", s1, *JUGGLE, *common,
                                       "-o", str(tmp_path / "s2.yaml"), "--report", str(tmp_path / "s2.html")])
    assert code in (0, 4) and out["held_out"][0]["mean"] * 1e3 <= 1.268
    page = (tmp_path / "s2.html").read_text()  # a fit in joint space still has its positions' figures (it had none)
    assert page.count("<svg") >= 5 and "position error per pose" in page
    code, out, text = _kincal(capsys, ["evaluate", str(tmp_path / "s2.yaml"), s1, *JUGGLE, "--refit-target"])
    assert code == 0 and "lie outside the joint ranges the legs' zeros and scales were fitted on" in text
    assert "leg1 at 0.7..3.7 rev (calibrated on 1.2..3.3 rev)" in text  # S1 spreads the legs wider than S2


def test_jugglebot_legs_reading_noise_can_be_stated(tmp_path, capsys):
    """Every joint-space fit of the Jugglebot was SUSPECT for 'the joint residuals are 360x their stated σ (the
    joints' reading noise taken as 1e-4 rad or m; no flag states it yet)': --std-joint states it (0.006 rev, the fit's
    0.41 mm through the mean lead), the residual reason goes, the calibrated file keeps it for kincal report, and
    it is refused without the joint-space residual."""
    s1, cal = str(JUGGLEBOT / "S1.csv"), tmp_path / "s1.yaml"
    base = ["calibrate", "hexapod", s1, *JUGGLE, "--json"]
    code, out, _ = _kincal(capsys, [*base, "--residual", "joint"])
    assert any(r["code"] == "residual" for r in out["verdict"]["reasons"])
    code, out, _ = _kincal(capsys, [*base, "--residual", "joint", "--std-joint", "0.006rev", "-o", str(cal)])
    assert code in (0, 4) and not any(r["code"] == "residual" for r in out["verdict"]["reasons"])
    options = kincal.models.load_calibration_record(str(cal))["options"]
    assert options["joint_std"] == pytest.approx(0.006 * 2 * np.pi)
    code, _, err = _kincal(capsys, [*base, "--std-joint", "0.006rev"])
    assert code == 1 and "--std-joint" in err and "--residual joint" in err


def test_jugglebot_gauge_and_mounting_do_not_depend_on_the_legs_unit(tmp_path, capsys):
    """S1 with the legs read in motor revolutions (the bundled file) and in mm of travel (the leads folded into the
    readings: a file without them) is one robot with one set of predictions. The design frames' gauge freedoms were
    held at other parameters (leg2.pz, leg5.pz, leg6.pz against leg3.pz, leg5.pz, leg6.pz: the whitened norms, in
    rad or in m), so the mounting line put the target at (0, 0, 14.46) mm against (0, 0, 15.24) mm; a tool point
    that trades with the platform points is no finding. Now the same parameters hold the gauge, and the line says
    the target's place is not determined by these data."""
    robot = yaml.safe_load((ROOT / "src/kincal/models/robots/hexapod.yaml").read_text())
    lead = np.array([leg.pop("lead") for leg in robot["legs"]])  # mm per rev
    for leg in robot["legs"]:
        leg["range"] = [0, 320]
    del robot["reading"]
    (tmp_path / "mm.yaml").write_text(yaml.safe_dump({**robot, "name": "hexapod_mm"}))
    s1 = np.genfromtxt(JUGGLEBOT / "S1.csv", delimiter=",", names=True)
    head = s1.dtype.names
    mm = np.column_stack([s1[c] * (lead[int(c[3:]) - 1] if c.startswith("leg") else 1.0) for c in head])
    np.savetxt(tmp_path / "S1_mm.csv", mm, delimiter=",", header=",".join(head), comments="", fmt="%.10g")
    outs = []
    for model, data, saved in (("hexapod", JUGGLEBOT / "S1.csv", "rev.yaml"), (tmp_path / "mm.yaml",
                                                                              tmp_path / "S1_mm.csv", "mm_cal.yaml")):
        code, out, text = _kincal(capsys, ["calibrate", str(model), str(data), *JUGGLE, "--residual", "joint",
                                           "--json", "-o", str(tmp_path / saved)])
        assert code in (0, 4)
        outs.append(out)
    rev, mm_out = outs
    held = rev["identifiability"]["frames"]
    assert len(held) == 12 and held == mm_out["identifiability"]["frames"]
    for n in ("tool.x", "tool.y", "tool.z", "leg1.px", "leg6.bz"):  # one parametrisation: the same values
        assert abs(rev["estimates"][n] - mm_out["estimates"][n]) < 1e-6, n
    platform = [n for n in held if ".p" in n]
    for out in outs:
        said = out["mounting"]["text"]
        assert out["mounting"]["tool_point"] is None and "not determined by these data" in said
        assert f"held here at {', '.join(platform)}" in said and "put the target at" not in said
        assert not any(r["code"] == "tool-point" for r in out["verdict"]["reasons"])
    # the reason, independently: the platform points and the tool point moved together 5 mm along z (a shift of the
    # platform frame among them) leave every pose the calibrated model predicts at S1's legs where it was
    cal = kincal.load_robot(tmp_path / "rev.yaml")
    shift = {n: cal.params[n] + 5e-3 for n in cal.params.names if n.endswith(".pz") or n == "tool.z"}
    q = np.column_stack([s1[f"leg{i}"] for i in range(1, 7)]) * 2 * np.pi
    p, _, R, _ = cal.frame_and_rates(q)
    p2, _, R2, _ = cal.with_params(shift).frame_and_rates(q)
    assert np.abs(p2 - p).max() < 1e-9 and np.abs(R2 - R).max() < 1e-9


def _platform_positions(robot, q, R, t):
    """The target's positions (N, 3) m that ``robot`` (a hexapod, legs in rad) predicts at joints ``q``, written out
    from the definition: each platform pose solved for the six leg lengths (scipy, from the measured pose (R, t) in
    the measurement frame), then the tool point carried to the measurement frame through the base frame."""
    from scipy.optimize import least_squares

    v = robot.params.as_dict()
    Rb = Rotation.from_euler("ZYX", [v["base.rz"], v["base.ry"], v["base.rx"]]).as_matrix()
    tb = np.array([v["base.x"], v["base.y"], v["base.z"]])
    tool = np.array([v["tool.x"], v["tool.y"], v["tool.z"]])
    b = np.array([[v[f"leg{i}.b{c}"] for c in "xyz"] for i in range(1, 7)])
    p = np.array([[v[f"leg{i}.p{c}"] for c in "xyz"] for i in range(1, 7)])
    zero, scale = (np.array([v[f"leg{i}.{k}"] for i in range(1, 7)]) for k in ("zero", "scale"))
    out = []
    for qk, Rk, tk in zip(q, R, t):
        length = zero + scale * robot.lead * qk
        R0, t0 = Rb.T @ Rk, Rb.T @ (tk - tb) - Rb.T @ Rk @ tool  # the platform's pose measured, in the robot frame

        def legs(x):
            Rp = Rotation.from_rotvec(x[:3]).as_matrix() @ R0
            return np.linalg.norm(p @ Rp.T + t0 + x[3:] - b, axis=1) - length
        x = least_squares(legs, np.zeros(6), xtol=1e-15, ftol=1e-15, gtol=1e-15).x
        out.append(Rb @ (Rotation.from_rotvec(x[:3]).as_matrix() @ R0 @ tool + t0 + x[3:]) + tb)
    return np.array(out)


@pytest.mark.slow
def test_jugglebot_nominal_figures_are_one_definition(tmp_path, capsys):
    """The nominal ("before") figure of a file is one definition: the nominal kinematics with the file's frame,
    target point and target rotation fitted to its poses. S1's read 4.6776 mm in calibrate --residual joint (the
    frame alone registered, the point as declared), 4.1092 mm in calibrate (frame and point on the positions),
    4.1285 mm in evaluate; S2's read 4.4968 mm held out without --refit-target (the calibrated target rotation).
    Now S1 4.1285 mm and S2 2.4066 mm everywhere (the dataset README fits the frames on the legs' residuals
    instead: 4.210 and 2.616 mm), and the figure is the target's forward-kinematics miss written out here."""
    s1, s2 = str(JUGGLEBOT / "S1.csv"), str(JUGGLEBOT / "S2.csv")
    said = {}
    for name, argv in (("joint", ["--residual", "joint", "--test", s2, "--refit-target"]),
                       ("cartesian", ["--test", s2])):
        code, out, text = _kincal(capsys, ["calibrate", "hexapod", s1, *JUGGLE, *argv, "--json", "-o",
                                           str(tmp_path / f"{name}.yaml")])
        assert code in (0, 4)
        said[name], said[f"{name} S2"] = out["sets_before"][0], out["held_out_nominal"][0]
    assert said["joint"]["type"] == "joint" and said["cartesian"]["type"] == "pose"
    code, out, _ = _kincal(capsys, ["calibrate", "hexapod", s2, *JUGGLE, "--residual", "joint", "--test", s1,
                                    "--json"])
    said["S2"], said["S2 S1"] = out["sets_before"][0], out["held_out_nominal"][0]
    for flags in ([], ["--refit-target"]):
        for data in (s1, s2):
            code, out, text = _kincal(capsys, ["evaluate", str(tmp_path / "joint.yaml"), data, *JUGGLE, *flags,
                                               "--json"])
            said[f"evaluate {Path(data).stem} {flags}"] = out["nominal"]
    code, _, text = _kincal(capsys, ["calibrate", "hexapod", s1, *JUGGLE, "--residual", "joint"])
    assert "before → after per file (before: nominal, frame, target point and target rotation fitted to each " \
           "file, kinematics fixed):" in text
    code, _, text = _kincal(capsys, ["evaluate", str(tmp_path / "joint.yaml"), s2, *JUGGLE])
    assert "(nominal, its frame, target point and target rotation fitted: mean 2.4066 mm, mean 8.5046 mrad)" in text
    one = {k: v for k, v in said.items() if "S1" in k or k in ("joint", "cartesian")}
    two = {k: v for k, v in said.items() if k not in one}
    for group, mm, mrad in ((one, 4.1285, 12.9774), (two, 2.4066, 8.5046)):
        for k, v in group.items():
            assert v["mean"] * 1e3 == pytest.approx(mm, abs=2e-4) and v["mean_rotation"] * 1e3 == pytest.approx(
                mrad, abs=2e-4), k
        assert max(v["mean"] for v in group.values()) - min(v["mean"] for v in group.values()) < 1e-8  # m
    # the figure, written out: the nominal robot with the frame and the point calibrate registered
    before = kincal.models.load_calibration_record(tmp_path / "joint.yaml")["before_mounting"]
    robot = kincal.load_robot("hexapod")
    robot = robot.with_params({k: float(v) for k, v in before.items()})
    rows = np.genfromtxt(s1, delimiter=",", names=True)
    q = np.column_stack([rows[f"leg{i}"] for i in range(1, 7)]) * 2 * np.pi
    xyz = np.column_stack([rows[c] for c in "xyz"]) * 1e-3
    R = Rotation.from_quat(np.column_stack([rows[c] for c in ("qx", "qy", "qz", "qw")])).as_matrix()
    miss = np.linalg.norm(_platform_positions(robot, q, R, xyz) - xyz, axis=1)
    assert miss.mean() == pytest.approx(said["joint"]["mean"], abs=1e-9)


def test_jugglebot_legs_reading_noise_stated_far_too_large_is_suspect(tmp_path, capsys):
    """--std-joint 5rev (the legs read to 0.006 rev, the dataset README's 0.41 mm fit through the mean lead: about
    830x too large) held every leg parameter at nominal as 'determined worse than a real robot's error': training
    4.68 -> 4.77 mm, held out unchanged at 2.41 mm, whitened RMS 0.0056, and the verdict GOOD. Now suspect, naming
    --std-joint and how far off (at least the 1/0.0056 = 180x the residuals show); at 0.006 rev not said."""
    s1, s2 = str(JUGGLEBOT / "S1.csv"), str(JUGGLEBOT / "S2.csv")
    base = ["calibrate", "hexapod", s1, "--test", s2, *JUGGLE, "--residual", "joint", "--refit-target", "--json"]
    code, out, _ = _kincal(capsys, [*base, "--std-joint", "5rev"])
    held = out["held_out"][0]
    assert held["mean"] == pytest.approx(out["held_out_nominal"][0]["mean"], rel=1e-6)  # nothing was calibrated
    found = [r for r in out["verdict"]["reasons"] if r["code"] == "sigma-overstated"]
    assert code in (0, 4) and out["verdict"]["status"] == "suspect" and len(found) == 1
    factor = float(found[0]["message"].split("--std-joint looks about ")[1].split("x")[0])
    assert 150 <= factor <= 5 / 0.006 and "39 parameter(s) were kept at nominal" in found[0]["message"]
    code, out, _ = _kincal(capsys, [*base, "--std-joint", "0.006rev"])
    assert not any(r["code"] == "sigma-overstated" for r in out["verdict"]["reasons"])
    assert out["held_out"][0]["mean"] * 1e3 < 0.62  # the README's 0.610 mm


def test_same_frame_with_refit_target_refits_the_target_alone_in_every_command(tmp_path, capsys):
    """--same-frame --refit-target on S2 after S1: evaluate fitted the frame too ("frame_fitted": true, 0.6107 mm,
    the 12-parameter refit) while saying only the target was, and calibrate --test and report fitted nothing (1.9225
    mm). One meaning now: the frame as calibrated, the target's point and rotation fitted, 0.784 mm in all three,
    as a least-squares fit of those 6 numbers alone on the calibrated model's platform poses computes here (scipy,
    the poses' σ 0.1 mm and 1 mrad); the nominal model beside it judged the same way in all three."""
    from scipy.optimize import least_squares
    from scipy.spatial.transform import Rotation
    s1, s2, cal = str(JUGGLEBOT / "S1.csv"), str(JUGGLEBOT / "S2.csv"), tmp_path / "s1.yaml"
    both = ["--same-frame", "--refit-target", "--json"]
    code, fit, _ = _kincal(capsys, ["calibrate", "hexapod", s1, "--test", s2, *JUGGLE, "--residual", "joint", *both,
                                    "-o", str(cal)])
    code, ev, _ = _kincal(capsys, ["evaluate", str(cal), s2, *JUGGLE, *both])
    assert code == 0 and ev["frame_fitted"] is False
    code, rep, _ = _kincal(capsys, ["report", str(cal), "--test", s2, *both, "-o", str(tmp_path / "r.html")])
    assert code == 0
    mean = ev["mean"]
    assert fit["held_out"][0]["mean"] == pytest.approx(mean, rel=1e-6) == rep["held_out"][0]["mean"]
    nominal = ev["nominal"]["mean"]
    assert fit["held_out_nominal"][0]["mean"] == pytest.approx(nominal, rel=1e-6) == rep["held_out_nominal"][0]["mean"]
    table = np.genfromtxt(s2, delimiter=",", names=True)
    q = np.column_stack([table[f"leg{i}"] for i in range(1, 7)]) * 2 * np.pi
    xyz = np.column_stack([table["x"], table["y"], table["z"]]) * 1e-3
    Rm = Rotation.from_quat(np.column_stack([table[c] for c in ("qx", "qy", "qz", "qw")])).as_matrix()
    p, R, _, _ = kincal.load_robot(str(cal)).with_tool_point(np.zeros(3)).pose_and_jacobian(q)

    def residual(x):
        turn = np.einsum("kji,kjl->kil", Rm, R @ Rotation.from_rotvec(x[3:]).as_matrix())
        return np.concatenate([((p + R @ x[:3] - xyz) / 0.1e-3).ravel(),
                               (Rotation.from_matrix(turn).as_rotvec() / 1e-3).ravel()])
    x = least_squares(residual, np.zeros(6)).x
    assert mean == pytest.approx(np.linalg.norm(p + R @ x[:3] - xyz, axis=1).mean(), rel=2e-3)
    code, whole, _ = _kincal(capsys, ["evaluate", str(cal), s2, *JUGGLE, "--refit-target", "--json"])
    code, none, _ = _kincal(capsys, ["evaluate", str(cal), s2, *JUGGLE, "--same-frame", "--json"])
    assert whole["frame_fitted"] and whole["mean"] < mean < none["mean"]  # 0.611 < 0.784 < 1.92 mm


def _swapped(path, tmp_path, a: str, b: str, edit=None) -> str:
    """The Jugglebot file ``path`` with the columns ``a`` and ``b`` swapped (and ``edit`` applied to its rows), in
    ``tmp_path``."""
    rows = list(csv.reader(open(path)))
    i, j = rows[0].index(a), rows[0].index(b)
    for r in rows[1:]:
        r[i], r[j] = r[j], r[i]
    if edit is not None:
        edit(rows)
    out = tmp_path / f"{Path(path).stem}_{a}{b}.csv"
    csv.writer(open(out, "w", newline="")).writerows(rows)
    return str(out)


def test_jugglebot_legs_swapped_are_named_where_the_fit_and_the_held_out_errors_meet_them(tmp_path, capsys):
    """Legs 2 and 3 swapped. Held out with --refit-target: 37.6 mm against 0.84 mm in training, no likely cause
    (only looked for with the frame kept, and against a training set of the held-out file's kind, not the joint
    residual's); now the swap, with the error it leaves undone, the dataset README's 0.610 mm. In training: 'forward
    kinematics did not converge ... (first at index 60, q = [23.24 ...])' in rad; now the file's rows (62, 63, 64,
    86, 87, 88), row 62's values as written and the swap; a few rows that do not assemble are named by row and
    leave with --exclude."""
    s1, s2, cal = str(JUGGLEBOT / "S1.csv"), str(JUGGLEBOT / "S2.csv"), tmp_path / "s1.yaml"
    code, fit, _ = _kincal(capsys, ["calibrate", "hexapod", s1, *JUGGLE, "--residual", "joint", "--json",
                                    "-o", str(cal)])
    code, out, text = _kincal(capsys, ["evaluate", str(cal), _swapped(s2, tmp_path, "leg2", "leg3"), *JUGGLE,
                                       "--refit-target", "--json"])
    assert code == 0 and out["mean"] > 10 * fit["sets"][0]["mean"] and out["cause"] is not None
    assert "the columns of leg2 and leg3 are swapped (undone, the mean error is" in out["cause"]
    undone = float(out["cause"].split("undone, the mean error is ")[1].split(" mm")[0])
    assert abs(undone - 0.610) < 0.01
    swapped = _swapped(s1, tmp_path, "leg2", "leg3")
    code, _, err = _kincal(capsys, ["calibrate", "hexapod", swapped, *JUGGLE, "--residual", "joint"])
    assert code == 1 and "forward kinematics did not converge" not in err
    assert "row(s) 62, 63, 64, 86, 87, 88; row 62: leg1 " in err
    written = open(swapped).read().splitlines()[61].split(",")[1:7]  # line 62 of the file, its legs as written
    assert ", ".join(f"leg{k + 1} {float(v):.6g} rev" for k, v in enumerate(written)) + " as written" in err
    miss = float(err.split("fit it rigidly to ")[1].split(" mm")[0])  # the nominal model, its frame registered
    nominal = kincal.load_robot("hexapod")  # independently: the nominal positions at S1's legs, fitted rigidly (scipy)
    table = np.genfromtxt(s1, delimiter=",", names=True)
    p = nominal.forward(np.column_stack([table[f"leg{i}"] for i in range(1, 7)]) * 2 * np.pi)
    x = np.column_stack([table[c] for c in "xyz"]) * 1e-3
    turn = Rotation.align_vectors(x - x.mean(0), p - p.mean(0))[0]
    rigid = np.linalg.norm(turn.apply(p - p.mean(0)) - (x - x.mean(0)), axis=1).mean() * 1e3  # 4.678 mm
    assert "the columns of leg2 and leg3 are swapped" in err and miss == pytest.approx(rigid, abs=0.01)

    def stretched(rows):
        for r in (rows[10], rows[40]):
            r[1] = "12"
    bad = _swapped(s1, tmp_path, "leg1", "leg1", stretched)
    code, _, err = _kincal(capsys, ["calibrate", "hexapod", bad, *JUGGLE, "--residual", "joint"])
    assert code == 1 and "row(s) 11, 41; row 11: leg1 12 rev" in err and "--exclude 11,41" in err
    code, _, _ = _kincal(capsys, ["calibrate", "hexapod", bad, *JUGGLE, "--residual", "joint", "--exclude", "11,41"])
    assert code == 0


def test_every_parameter_dropped_at_a_far_too_large_sigma_is_said(tmp_path, capsys):
    """puu3 positions with the legs' noise stated as 200 mm: every parameter is determined worse than a real robot's
    error (r ±42.8 mm at 20 poses, the σ √((JᵀJ)⁻¹) of the leg Jacobian, checked here), so nothing was left to fit
    and Levenberg–Marquardt ran on no column: an internal error. Now the file, the parameters and the flag."""
    puu3 = kincal.load_robot("puu3")
    meas = kincal.simulate(puu3, puu3.sample_joints(20, seed=1), 0.0)
    kincal.write_measurements(tmp_path / "p.csv", meas, puu3.joint_types)
    code, _, err = _kincal(capsys, ["calibrate", "puu3", str(tmp_path / "p.csv"), "--base", "fixed", "--residual",
                                    "joint", "--std-joint", "200mm"])
    assert code == 1 and "internal error" not in err
    assert "p.csv: no parameter is determined by these data at the stated σ" in err and "(--std-joint)" in err
    names = ["r", "L1", "L2", "L3"]
    J = puu3.inverse_and_jacobian(meas.xyz)[1][:, :, puu3.params.indices(names)].reshape(-1, len(names))
    sd = 0.2 * np.sqrt(np.diag(np.linalg.inv(J.T @ J)))
    assert f"{names[int(np.argmax(sd))]} ±{sd.max() * 1e3:.1f} mm" in err


@pytest.mark.parametrize("residual", [[], ["--residual", "joint"]], ids=["cartesian", "joint"])
def test_jugglebot_poses_in_the_measurement_frame_are_the_measured_bodys(tmp_path, capsys, residual):
    """The motion capture gives the poses of its rigid body, turned 6.9 mrad on the platform (the calibration's
    target_rotation): commands for S1's own first 20 poses in the measurement frame took them for the platform's
    and missed the legs that produced them by 1.06 mm RMS; turned by the body's rotation they miss by the fit's own
    residual (0.43 mm RMS through the legs' mean lead), and the output says how the rotations were taken. A fit in
    joint space (--residual joint) fits the body's rotation alike (16.8 mrad in its frames) but recorded none:
    its commands took the body's poses for the platform's, 2.17 mm RMS off the legs (0.32 mm now, within the fit's
    0.41 mm), and a file written so is refused for such targets."""
    s1 = JUGGLEBOT / "S1.csv"
    cal, targets, legs = tmp_path / "s1.yaml", tmp_path / "t.csv", tmp_path / "legs.csv"
    code, _, _ = _kincal(capsys, ["calibrate", "hexapod", str(s1), *JUGGLE, *residual, "-o", str(cal)])
    assert code in (0, 4)
    if residual:  # the recorded rotation: the chordal mean of flangeᵀ·measured under the calibrated model
        data = np.loadtxt(s1, delimiter=",", skiprows=1)
        flange = kincal.load_robot(cal).pose_and_jacobian(data[:, 1:7] * 2 * np.pi)[1]  # rev -> rad
        u, _, vt = np.linalg.svd(np.sum(flange.transpose(0, 2, 1) @ Rotation.from_quat(data[:, 10:14]).as_matrix(), 0))
        mean = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
        recorded = np.array(kincal.models.load_calibration_record(str(cal))["setup"]["target_rotation"])
        assert Rotation.from_matrix(mean.T @ recorded).magnitude() < 1e-4  # rad; 4.9e-6 here
    targets.write_text("\n".join(s1.read_text().splitlines()[:21]) + "\n")
    code, _, text = _kincal(capsys, ["compensate", str(cal), str(targets), "--pose", *JUGGLE[2:], "--target-frame",
                                     "measurement", "-o", str(legs)])
    assert code == 0 and "target rotations: the measured body's, as the instrument gives them" in text
    names = [f"leg{i}" for i in range(1, 7)]
    read = np.array([[float(r[n]) for n in names] for r in csv.DictReader(open(targets))])
    made = np.array([[float(r[n]) for n in names] for r in csv.DictReader(open(legs))])
    lead = np.mean([leg["lead"] for leg in yaml.safe_load(
        (ROOT / "src/kincal/models/robots/hexapod.yaml").read_text())["legs"]])  # mm per rev
    assert np.sqrt(np.mean(((made - read) * lead) ** 2)) < (0.45 if residual else 0.5)  # 0.32 mm, 0.43 mm
    if residual:  # a file from before the rotation was recorded: refused, not commanded 2.17 mm off
        record = yaml.safe_load(cal.read_text())
        del record["calibration"]["setup"]["target_rotation"]
        cal.write_text(yaml.safe_dump(record))
        code, _, text = _kincal(capsys, ["compensate", str(cal), str(targets), "--pose", *JUGGLE[2:],
                                         "--target-frame", "measurement", "-o", str(tmp_path / "again.csv")])
        assert code == 1 and "does not record it (setup.target_rotation)" in text and "calibrate again" in text


@pytest.mark.slow
def test_jugglebot_legs_give_under_the_platforms_weight(tmp_path, capsys):
    """The error model 'compliance' (one parameter: the legs' give per platform weight) on the real hexapod: better
    than the 48-parameter reference both ways (0.610 mm / 0.112 deg, 1.268 mm), the 12 gauge freedoms kept; the
    calibrated file keeps the term and gives the same figure when reloaded."""
    s1, s2 = str(JUGGLEBOT / "S1.csv"), str(JUGGLEBOT / "S2.csv")
    common = ["--residual", "joint", "--refit-target", "--error-model", "compliance", "--json"]
    code, out, _ = _kincal(capsys, ["calibrate", "hexapod", s1, "--test", s2, *JUGGLE, *common,
                                    "-o", str(tmp_path / "s1.yaml")])
    held = out["held_out"][0]
    assert code in (0, 4) and held["mean"] * 1e3 <= 0.60 and np.degrees(held["mean_rotation"]) <= 0.11
    assert len(out["estimated"]) + len(out["nuisance"]) == 49 and len(out["identifiability"]["frames"]) == 12
    assert 8e-3 < kincal.load_robot(tmp_path / "s1.yaml").params["legs.compliance"] < 13e-3  # 10.5 mm per weight
    code, again, _ = _kincal(capsys, ["evaluate", str(tmp_path / "s1.yaml"), s2, *JUGGLE, "--refit-target", "--json"])
    assert code == 0 and abs(again["mean"] - held["mean"]) < 1e-9
    code, out, text = _kincal(capsys, ["calibrate", "hexapod", s2, "--test", s1, *JUGGLE, *common])
    assert code in (0, 4) and out["held_out"][0]["mean"] * 1e3 <= 1.20


def test_jugglebot_mistakes_are_named(tmp_path, capsys):
    s1 = str(JUGGLEBOT / "S1.csv")
    out = ["-o", str(tmp_path / "x.yaml")]
    # the quaternion read scalar-first (upstream's mistake: 12.3 mm instead of 0.41 mm)
    code, _, err = _kincal(capsys, ["calibrate", "hexapod", s1, *JUGGLE[:-1], "quat-wxyz", "--rot-cols",
                                    "qx,qy,qz,qw", *out])
    assert code == 1 and "the file looks like quat-xyzw" in err
    # the motor revolutions read as radians, then as degrees
    for unit, said in (("rad", "read as radians"), ("deg", "read as degrees")):
        argv = ["calibrate", "hexapod", s1, *[unit if a == "rev" else a for a in JUGGLE], *out]
        code, _, err = _kincal(capsys, argv)
        assert code == 1 and said in err and "read as revolutions they match" in err and "--angle-unit rev" in err
    # the positions' x and y swapped: the fit drove the model where it no longer assembles, and the error blamed
    # the joint values; now the position columns are named first
    code, _, err = _kincal(capsys, ["calibrate", "hexapod", s1, *JUGGLE, "--xyz-cols", "y,x,z", *out])
    assert code == 1 and "no longer assembles" in err and "--xyz-cols" in err
    # ... and so with the fit in joint space, whose result did not assemble at the file's legs ("forward kinematics
    # did not converge ... check the joint values and their units")
    for cols in (["--xyz-cols", "y,x,z"], ["--rot-cols", "qy,qx,qz,qw"]):
        code, _, err = _kincal(capsys, ["calibrate", "hexapod", s1, *JUGGLE, "--residual", "joint", *cols, *out])
        assert code == 1 and "no longer assembles" in err and cols[0] in err and "did not converge" not in err, err
    # the legs written as mm of travel (rev × 71 mm) and declared rev: the column and its range, as written
    lines = open(s1).read().splitlines()
    head = lines[0].split(",")
    legs = [k for k, c in enumerate(head) if c.startswith("leg")]
    # the motor's degrees declared as revolutions: the legs do not assemble (it said '2.06e+299x less')
    deg = [",".join(f"{float(v) * 360:.4f}" if k in legs else v for k, v in enumerate(r.split(","))) for r in lines[1:]]
    (tmp_path / "S1_deg.csv").write_text("\n".join([lines[0], *deg]) + "\n")
    code, _, err = _kincal(capsys, ["calibrate", "hexapod", str(tmp_path / "S1_deg.csv"), *JUGGLE, *out])
    assert code == 1 and "do not even assemble the robot (hexapod), read as degrees they match" in err, err
    # the legs written as mm of travel (rev × 71.2 mm) and declared rev: it said 'read as deg they lie within it; use
    # angle unit deg', and with deg 'spread 6.08x more ... no length unit explains that factor'; now the travel is named
    # in both, the leads being the robot file's (75.69 mm/rev for leg1)
    mm = [",".join(f"{float(v) * 71.2:.4f}" if k in legs else v for k, v in enumerate(r.split(","))) for r in lines[1:]]
    (tmp_path / "S1_mm.csv").write_text("\n".join([lines[0], *mm]) + "\n")
    for unit, lead in (("rev", "75.69"), ("deg", f"{75.6921 / 360:.4g}")):  # mm per rev, per deg
        argv = ["calibrate", "hexapod", str(tmp_path / "S1_mm.csv"), *[unit if a == "rev" else a for a in JUGGLE], *out]
        code, _, err = _kincal(capsys, argv)
        assert code == 1 and f"read as mm of travel through each one's lead (leg1 {lead}," in err, err
        assert f"they look like lengths in mm: give them in {unit}" in err and "did not converge" not in err
        assert "angle unit 'deg'" not in err and "no length unit explains" not in err
    # the right readings with a robot file whose leads are 10 mm/rev: 'spread 8.86x more ... no length unit explains
    # that factor'; now the leads are named, with the factor the spreads give: the dataset's own leads (its README:
    # 70.62 to 75.69 mm/rev, mean 71.99) are 7.20x the file's
    design = yaml.safe_load((ROOT / "src/kincal/models/robots/hexapod.yaml").read_text())
    for leg in design["legs"]:
        leg["lead"] = 10.0
    (tmp_path / "lead10.yaml").write_text(yaml.safe_dump(design))
    code, _, err = _kincal(capsys, ["calibrate", str(tmp_path / "lead10.yaml"), s1, *JUGGLE, *out])
    said = err.split("the robot file's leads look ")[1]
    assert code == 1 and abs(float(said.split("x")[0]) / 7.199 - 1) < 0.02 and said.split("x ")[1].startswith("too small")
    assert "no length unit explains" not in err
    # legs 1 and 2 read in each other's columns: the fit relabels the legs (its held-out error unchanged), and the
    # file would command each by the other's column; refused with that cause (it named leg 1's lead), nothing written
    code, out, _ = _kincal(capsys, ["calibrate", "hexapod", s1, *JUGGLE, "--residual", "joint", "--joint-cols",
                                    "leg2,leg1,leg3,leg4,leg5,leg6", "--json", *out])
    said = " ".join(r["message"] for r in out["verdict"]["reasons"])
    assert out["verdict"]["status"] == "refused" and not (tmp_path / "x.yaml").exists()
    assert "put leg1 where leg2 is drawn, leg2 where leg1 is drawn" in said and "lead" not in said


LAB_HEXAPOD = """name: lab_hexapod
type: stewart
description: "a small precision hexapod, legs read as lengths by linear encoders"
units: {length: mm, angle: deg}
legs:
  - {base: [120.0, 20.0, 0.0], platform: [60.0, 45.0, 0.0], zero: 180.0, range: [0, 60]}
  - {base: [-42.7, 113.9, 0.0], platform: [8.97, 74.46, 0.0], zero: 180.0, range: [0, 60]}
  - {base: [-77.3, 93.9, 0.0], platform: [-68.97, 29.46, 0.0], zero: 180.0, range: [0, 60]}
  - {base: [-77.3, -93.9, 0.0], platform: [-68.97, -29.46, 0.0], zero: 180.0, range: [0, 60]}
  - {base: [-42.7, -113.9, 0.0], platform: [8.97, -74.46, 0.0], zero: 180.0, range: [0, 60]}
  - {base: [120.0, -20.0, 0.0], platform: [60.0, -45.0, 0.0], zero: 180.0, range: [0, 60]}
tool: {x: 0, y: 0, z: 20}
"""


@pytest.mark.slow
def test_a_users_hexapod_file_calibrates_saves_reloads_and_reports(tmp_path, capsys):
    """A hexapod of other dimensions written by hand, legs read as lengths: simulated, calibrated, reported
    from its record, reloaded, with no Python code (the command line only)."""
    robot_file, data, true_file = tmp_path / "lab.yaml", str(tmp_path / "sim.csv"), str(tmp_path / "true.yaml")
    robot_file.write_text(LAB_HEXAPOD)
    noise = ["--std-pos", "0.01mm", "--std-rot", "0.05mrad"]
    code, _, _ = _kincal(capsys, ["simulate", str(robot_file), "--poses", "80", "--perturb", "--type", "pose",
                                  "--length-unit", "mm", "--noise", "0.01", "--std-rot", "0.05mrad", "-o", data,
                                  "--save-true", true_file])  # simulated noise: --noise (mm), as σ for the fit
    assert code == 0
    cal = str(tmp_path / "cal.yaml")
    code, out, _ = _kincal(capsys, ["calibrate", str(robot_file), data, "--type", "pose", "--length-unit", "mm",
                                    *noise, "-o", cal, "--json"])
    assert code == 0 and out["verdict"]["status"] == "good" and len(out["identifiability"]["frames"]) == 12
    code, _, text = _kincal(capsys, ["report", cal, "-o", str(tmp_path / "again.html")])
    assert code == 0 and "calibrated): mean 0.0" in text
    back, true = kincal.load_robot(cal), kincal.load_robot(true_file)
    assert back.structure.startswith("stewart") and back.joint_types == ("prismatic",) * 6
    q = back.sample_joints(200, seed=40)  # the calibrated file predicts the true robot to the noise's level
    gap = np.linalg.norm(back.forward(q) - true.forward(q), axis=1)  # (simulated in the true robot's frame)
    assert gap.mean() < 0.02e-3 and gap.max() < 0.04e-3
    lengths = yaml.safe_load(robot_file.read_text())["legs"][0]
    assert lengths["zero"] == 180.0 and abs(back.params["leg1.zero"] - 0.18) < 2e-3  # mm in the file, m inside



def test_a_key_of_another_robot_type_is_refused(tmp_path):
    path = tmp_path / "d.yaml"
    path.write_text("name: d\ntype: delta\nunits: {length: mm, angle: deg}\narms: {R: 200, r: 50, L: 350, l: 800}\n"
                    "arm_limits: [-35, 80]\njoints: []\n")
    with pytest.raises(ModelError, match="joints do.es. not belong to a 'delta' robot .keys of serial, urdf."):
        kincal.load_robot(path)
    path.write_text(path.read_text().replace("joints: []\n", ""))
    assert kincal.load_robot(path).structure == "delta (implicit)"


@pytest.mark.slow
def test_a_hexapods_size_is_not_judged_from_its_leg_readings(capsys, tmp_path):
    """The Jugglebot's leg 1 lead is 6 % off in its file: named as that correction. Platform positions at given
    motor readings do not scale with the lengths (it was called 0.9 % larger 'as a whole'), so the size check is
    for arms of whole-turn joints only."""
    code, out, _ = _kincal(capsys, ["calibrate", "hexapod", str(JUGGLEBOT / "S1.csv"), *JUGGLE, "--residual", "joint",
                                    "--json", "-o", str(tmp_path / "s1.yaml")])
    codes = [r["code"] for r in out["verdict"]["reasons"]]
    assert "large-correction" in codes and "size" not in codes


def test_std_joint_is_judged_against_the_joints_kind(tmp_path, capsys):
    """--std-joint 0.4mm for the Jugglebot's legs read as motor turns was taken as 0.4 mrad of the motor (its
    whitened RMS 4.07 against 0.93 for the same noise as 0.0056 rev); now a length is turned into the motor turn
    through the legs' mean lead (computed here), and an angle for a slider read in metres (0.001 rev, taken as
    6.28 mm) is refused. mrad is an angle unit too (it printed leg noise in mrad and refused 5.6mrad)."""
    from kincal.cli import main
    hexapod = kincal.load_robot("hexapod")
    lead = float(np.mean(np.abs(hexapod.motor_leads)))  # m per rad
    taken = {}
    for given in ("0.4mm", "5.6mrad"):
        assert main(["calibrate", "hexapod", str(JUGGLEBOT / "S1.csv"), *JUGGLE, "--residual", "joint",
                     "--std-joint", given, "--json"]) in (0, 4)
        taken[given] = json.loads(capsys.readouterr().out)["options"]["joint_std"]
    assert taken == {"0.4mm": pytest.approx(0.4e-3 / lead, rel=1e-12), "5.6mrad": pytest.approx(5.6e-3, rel=1e-12)}
    puu3 = kincal.load_robot("puu3")
    kincal.write_measurements(tmp_path / "p.csv", kincal.simulate(puu3, puu3.sample_joints(20, seed=1), 0.0),
                              puu3.joint_types)
    assert main(["calibrate", "puu3", str(tmp_path / "p.csv"), "--base", "fixed", "--residual", "joint",
                 "--std-joint", "0.001rev"]) == 1
    assert "--std-joint 0.001rev is an angle, but puu3's joints are read as lengths" in capsys.readouterr().err
    # the flag's value is echoed as given: it said '0.00628 rad', '0.01 mm' and 'joint_std=0.006283185307179587'
    assert main(["calibrate", "ur5", str(tmp_path / "p.csv"), "--residual", "joint", "--std-joint", "10um"]) == 1
    assert "--std-joint 10um is a length, but ur5's joints are read as angles" in capsys.readouterr().err
    assert main(["calibrate", "hexapod", str(JUGGLEBOT / "S1.csv"), *JUGGLE, "--std-joint", "0.001rev"]) == 1
    err = capsys.readouterr().err
    assert "--std-joint 0.001rev:" in err and "--residual joint" in err and "0.00628" not in err
