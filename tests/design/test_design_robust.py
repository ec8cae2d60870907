"""IMSE designs: the criterion against a direct computation and a Monte-Carlo of the linear model,
the exchange within strata, and the options and notes around it."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import kincal
from kincal.design import design_problem
from kincal.design.robust import design_imse, exchange_in_strata, medoids, robust_terms, strata
from conftest import DATA, PANDA_URDF



@pytest.fixture(scope="module")
def ur5_problem():
    ur5 = kincal.load_robot("ur5")
    pool = ur5.sample_joints(400, seed=11)
    return ur5, pool, design_problem(ur5, pool)


def _direct_imse(P, terms, design):
    """IMSE/σ² from its definition: prediction variance and bias row by row over the region (the pool)."""
    J, K = P.J[design].reshape(-1, P.k), terms.K[design].reshape(-1, terms.K.shape[2])
    Ju, Ku = P.J.reshape(-1, P.k), terms.K.reshape(-1, terms.K.shape[2])
    Minv = np.linalg.inv(J.T @ J)
    var = np.einsum("rk,kl,rl->", Ju, Minv, Ju) / P.N
    R = Ju @ Minv @ J.T @ K - Ku
    return var + np.sum(R ** 2) / P.N


def test_imse_matches_its_definition_the_woodbury_update_and_a_monte_carlo(ur5_problem):
    ur5, pool, P = ur5_problem
    terms, note = robust_terms(ur5, P, None, 0.3)
    assert len(terms.names) > 20 and "left-out error terms" in note
    rng = np.random.default_rng(0)
    design = sorted(rng.choice(P.N, 30, replace=False).tolist())
    J, K = P.J[design].reshape(-1, P.k), terms.K[design].reshape(-1, len(terms.names))
    direct = _direct_imse(P, terms, design)
    assert terms.imse((J.T @ J)[None], (J.T @ K)[None])[0] == pytest.approx(direct, rel=1e-9)
    rest, c = design[1:], np.array([design[0], 5, 17])
    Jr, Kr = P.J[rest].reshape(-1, P.k), terms.K[rest].reshape(-1, len(terms.names))
    added = terms.imse_added(Jr.T @ Jr, Jr.T @ Kr, P.J[c], terms.K[c])
    for v, extra in zip(added, c):
        assert v == pytest.approx(_direct_imse(P, terms, rest + [int(extra)]), rel=1e-8)
    # Monte-Carlo of the linear model: y = Jθ + Kδ + ε, δ ~ N(0, I) (weight folded into K), ε ~ N(0, 1)
    Ju, Ku = P.J.reshape(-1, P.k), terms.K.reshape(-1, len(terms.names))
    H = np.linalg.solve(J.T @ J, J.T)
    errs = []
    for _ in range(400):
        delta, eps = rng.standard_normal(len(terms.names)), rng.standard_normal(len(J))
        errs.append(np.sum((Ju @ (H @ (K @ delta + eps)) - Ku @ delta) ** 2) / P.N)
    assert np.mean(errs) == pytest.approx(direct, rel=0.1)


def test_the_stratified_exchange_keeps_one_pose_per_stratum_and_no_swap_improves(ur5_problem):
    ur5, pool, P = ur5_problem
    d = kincal.select_poses(ur5, pool, m=25, problem=P, certify=False, seed=4)
    again = kincal.select_poses(ur5, pool, m=25, problem=P, certify=False, seed=4)
    assert np.array_equal(d.indices, again.indices) and d.criterion == "IMSE"
    lab = strata(P.q, 25, np.random.default_rng(4))
    assert sorted(lab[d.indices].tolist()) == list(range(25))  # one pose per stratum
    terms, _ = robust_terms(ur5, P, None, 0.3)
    value = _direct_imse(P, terms, d.indices.tolist())
    assert d.value == pytest.approx(value, rel=1e-9)
    start = medoids(P.q, lab)
    assert value < _direct_imse(P, terms, start)
    for j in (0, 7, 19):  # no member of a stratum improves on the chosen pose by more than a tie
        members = np.flatnonzero(lab == lab[d.indices[j]])
        for c in members[:6]:
            swapped = d.indices.tolist()
            swapped[j] = int(c)
            assert _direct_imse(P, terms, swapped) >= value * (1 - 1e-9)
    randoms = [kincal.select_poses(ur5, pool, m=25, method="random", problem=P, certify=False, seed=s) for s in range(5)]
    assert all(r.value > d.value for r in randoms)  # a random design has larger IMSE (scored, not searched)
    exchanged = exchange_in_strata(P, lab, start, lambda M0, Q0, Jc, Kc: -terms.imse_added(M0, Q0, Jc, Kc), terms.K)
    assert sorted(exchanged) == sorted(d.indices.tolist())


def test_imse_options_and_notes(ur5_problem):
    ur5, pool, P = ur5_problem
    with pytest.raises(ValueError, match="with method 'detmax' choose a criterion such as D"):
        kincal.DesignOptions(method="detmax")
    with pytest.raises(ValueError, match="coverage is kept by the exchange within strata"):
        kincal.DesignOptions(method="detmax", criterion="D", coverage=True)
    with pytest.raises(ValueError, match="leave coverage on|and no coverage"):
        kincal.DesignOptions(coverage=False)
    with pytest.raises(ValueError, match="weight=-1"):
        kincal.DesignOptions(weight=-1)
    assert kincal.DesignOptions().stratified and not kincal.DesignOptions(criterion="D").stratified
    plain = kincal.select_poses(ur5, pool, m=20, problem=P, certify=False, weight=0.0)
    i_cov = kincal.select_poses(ur5, pool, m=20, problem=P, certify=False, criterion="I", coverage=True)
    assert np.array_equal(plain.indices, i_cov.indices)  # weight 0: IMSE is I-optimality within the strata
    assert "I-optimality here" in plain.note
    # the region of use moves the design: poses near the region's joints are favoured
    use = pool[np.argsort(pool[:, 1])[:60]]
    near = kincal.select_poses(ur5, pool, m=20, problem=P, certify=False, validation_q=use)
    terms_use, _ = robust_terms(ur5, P, use, 0.3)
    terms_pool, _ = robust_terms(ur5, P, None, 0.3)
    d_pool = kincal.select_poses(ur5, pool, m=20, problem=P, certify=False)
    imse_at_use = lambda idx: _direct_imse_region(P, terms_use, list(idx), ur5, use)  # noqa: E731
    assert imse_at_use(near.indices) < imse_at_use(d_pool.indices)
    assert not np.allclose(terms_pool.C, terms_use.C)  # the cross moments are the region's (D is fixed by the scaling)
    with pytest.raises(ValueError, match="steers the IMSE and I criteria only"):
        kincal.select_poses(ur5, pool, m=20, problem=P, certify=False, criterion="D", validation_q=use)


def _direct_imse_region(P, terms, design, robot, region):
    J, K = P.J[design].reshape(-1, P.k), terms.K[design].reshape(-1, terms.K.shape[2])
    M = J.T @ J
    val = terms.imse(M[None], (J.T @ K)[None])[0]
    Ju = robot.param_jacobian(region)[:, :, robot.params.indices(P.names)].reshape(-1, P.k) * P.scale
    assert np.trace(np.linalg.solve(M, Ju.T @ Ju / len(region))) <= val + 1e-12  # variance part alone
    return val


def test_a_pool_that_cannot_separate_two_parameters_is_designed_for_the_rest_and_says_which():
    ur5 = kincal.load_robot("ur5")
    pool = ur5.sample_joints(500, seed=3)
    pool[:, 5] = 0.3  # the last joint never moves: the wrist's last link and the tool point fold together
    d = kincal.select_poses(ur5, pool, m=30, certify=False)
    assert "identify 23 of the 27" in d.note and "no design from them can separate j5.theta ~" in d.note
    assert "j5.a ~ +0.955·tool.x" in d.note and "j5.a" not in d.names and len(d.names) == 23
    with pytest.raises(kincal.IdentifiabilityError, match="too alike"):
        kincal.select_poses(ur5, pool[:1] + np.linspace(0, 1e-3, 40)[:, None], m=30, certify=False)


def test_a_pools_confounds_carry_their_units_as_a_calibrations_do():
    """The real UR5 grid as candidates: its wrist cannot separate j5.theta from j5.a, nor j5.alpha from j5.d. The
    design's note gives each coefficient in the unit calibrate prints (an angle acting like a length: mm of the
    length per mrad of the angle, numerically m/rad), equal to the least-squares coefficient of the dropped
    parameter's Jacobian column on the designed ones' (numpy); it said '-0.113·j5.a', no unit."""
    ur5 = kincal.load_robot("ur5")
    q = np.radians(np.loadtxt(DATA / "ur5_grid.csv", delimiter=",", skiprows=1, usecols=range(1, 7)))
    d = kincal.select_poses(ur5, q, m=30, certify=False)
    J = ur5.param_jacobian(q).reshape(-1, len(ur5.params.names))
    kept = J[:, ur5.params.indices(list(d.names))]
    for dropped, like in (("j5.theta", "j5.a"), ("j5.alpha", "j5.d")):
        c = np.linalg.lstsq(kept, J[:, ur5.params.index(dropped)], rcond=None)[0][d.names.index(like)]  # m/rad
        assert f"{dropped} ~ {c:+.3g} mm/mrad·{like}" in d.note


def test_evaluating_on_no_poses_is_a_clear_error_not_a_traceback():
    ur5 = kincal.load_robot("ur5")
    meas = kincal.simulate(ur5, ur5.sample_joints(5, seed=0), 0.0)
    with pytest.raises(kincal.MeasurementError, match="no poses to evaluate on"):
        kincal.evaluate(ur5, meas.subset(np.array([], dtype=int)))


def _settle(true, q, targets):
    """The configurations near ``q`` where ``true`` puts its tool point at ``targets`` (Newton steps)."""
    x = q.copy()
    for _ in range(30):
        J = true.joint_jacobian(x)
        e = targets - true.forward(x)
        x = x + np.einsum("nji,nj->ni", J, np.linalg.solve(J @ J.transpose(0, 2, 1) + 1e-9 * np.eye(3), e[..., None])[..., 0])
    return x


@pytest.mark.slow
def test_socket_design_known_distance_as_exact_constraint_and_better_than_random():
    """Sockets: the known distances are eliminated as exact constraints (the reduced problem's
    information on the robot equals the full problem's as the distance σ goes to 0); the chosen 40
    seats of a 4-placement plan beat every one of 20 random choices on IMSE and calibrate a
    simulated Panda better over the workspace than random choices (median over 6 robots)."""
    from kincal.identify.registration import kabsch
    from kincal.identify import fit_observations
    from kincal.simulate.observations import simulate_same_point, socket_plan

    robot = kincal.load_robot(PANDA_URDF, tip_link="ball_link")
    pts, dist = socket_plan(robot, placements=4, seed=0)
    plan = dataclasses.replace(simulate_same_point(robot, pts, 40, dist, 0.0, 0.0, seed=0), std=50e-6,
                               std_distance=0.1e-3)
    P = kincal.design.observation_problem(robot, plan)
    tight = dataclasses.replace(plan, std_distance=1e-9).prepare(robot)
    names, start, _ = tight.nuisance(robot)
    _, Jr, Jn = tight.evaluate(robot, robot.params.values, start)
    full_names = list(robot.params.names) + list(names)

    def schur(J, cols, rob):
        a = [cols.index(n) for n in rob]
        b = [k for k, n in enumerate(cols) if n not in robot.params.names]
        M = J.T @ J
        return M[np.ix_(a, a)] - M[np.ix_(a, b)] @ np.linalg.pinv(M[np.ix_(b, b)]) @ M[np.ix_(b, a)]
    rob = [n for n in P.names if n in robot.params.names]
    full = schur(np.hstack([Jr, Jn]) / tight.sigma()[:, None], full_names, rob)
    reduced = schur(P.J.reshape(-1, P.k) / P.scale, list(P.names), rob)
    assert np.max(np.abs(full - reduced)) < 1e-6 * np.max(np.abs(full))
    assert len(P.names) == len(rob) + 3 * 8 - 4  # 8 socket points, one coordinate per distance eliminated

    d = kincal.select_poses(robot, plan.q, problem=P, m=40)
    rng = np.random.default_rng(0)
    random = [np.sort(rng.choice(len(plan), 40, replace=False)) for _ in range(20)]
    assert design_imse(robot, P, d.indices, None, 0.3)[0] < min(design_imse(robot, P, r, None, 0.3)[0] for r in random)
    qv = robot.sample_joints(300, seed=99)
    targets = np.array([pts[lab] for lab in plan.labels])
    errors = {"design": [], "random": []}
    for seed in range(6):
        true = kincal.perturb(robot, 0.5e-3, 0.5e-3, seed=seed)
        noise = np.random.default_rng(seed).standard_normal((40, 3)) * 50e-6
        for name, idx in (("design", d.indices), ("random", random[seed])):
            seats = dataclasses.replace(plan.subset(idx), q=_settle(true, plan.q[idx], targets[idx] + noise))
            p, t = fit_observations(robot, [seats]).robot.forward(qv), true.forward(qv)
            R, tt = kabsch(p, t)
            errors[name].append(float(np.sqrt(np.mean(np.sum((p @ R.T + tt - t) ** 2, axis=1)))))
    print({k: np.round(np.array(v) * 1e3, 3) for k, v in errors.items()})
    assert np.median(errors["design"]) < 0.9 * np.median(errors["random"])
