"""The learned prior (relevance per joint origin): against the closed-form evidence of a linear
Gaussian model, and its effect on a plentiful and a scarce calibration."""
import numpy as np
import pytest
from scipy.optimize import minimize

import kincal
from kincal.identify.lm import levenberg_marquardt
from kincal.identify.relevance import prior_groups, relevance_fit
from kincal.identify import fit_observations
from kincal.observe.observations import PointObs

STATED = 1e-5  # m: the σ the "measurements" are whitened with


def _linear_problem(seed=0):
    """y = X·d + u·z + noise: two groups of 3 columns with a prior (one with real corrections, one
    without), one column without a prior (a set-up parameter)."""
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(40, 6)) * 0.3
    z = rng.normal(size=40)
    d_true = np.r_[rng.normal(0, 2e-4, 3), 1e-8 * rng.normal(size=3)]
    y = X @ d_true + 0.05 * z + rng.normal(0, 2.0 * STATED, 40)
    J = np.column_stack([X, z]) / STATED
    return J, y, ["a lengths"] * 3 + ["b lengths"] * 3 + [None]


def _log_evidence(log_params, J, y, groups):
    """The marginal likelihood of y, the prior columns integrated out with N(0, σ_g²), the set-up
    column with a flat prior (closed form); noise σ = STATED·exp(third parameter)."""
    s_a, s_b, s_n = np.exp(log_params)
    X, z = J[:, :6] * STATED, J[:, 6] * STATED
    var = np.array([s_a**2 if g == "a lengths" else s_b**2 for g in groups[:6]])
    S = (STATED * s_n) ** 2 * np.eye(len(y)) + X @ np.diag(var) @ X.T
    Si = np.linalg.inv(S)
    u = (z @ Si @ y) / (z @ Si @ z)
    r = y - z * u
    return -0.5 * (np.linalg.slogdet(S)[1] + r @ Si @ r + np.log(z @ Si @ z))


def test_learned_prior_maximises_the_closed_form_evidence():
    J, y, groups = _linear_problem()

    def fun(x):
        return (J @ x - y / STATED), J
    ls = levenberg_marquardt(fun, np.zeros(7))
    fit = relevance_fit(fun, ls, np.zeros(7), groups, ["length"] * 6 + [""])
    best = max((minimize(lambda p: -_log_evidence(p, J, y, groups), np.log(start), method="Nelder-Mead",
                         options={"xatol": 1e-8, "fatol": 1e-10, "maxiter": 4000})
                for start in ([1e-4, 1e-4, 1.0], [1e-3, 1e-6, 3.0])), key=lambda r: -r.fun)
    s_a, s_b, s_n = np.exp(best.x)
    assert fit.sigma["a lengths"] == pytest.approx(s_a, rel=1e-3)
    assert fit.noise2 == pytest.approx(s_n**2, rel=1e-3)
    assert fit.sigma["b lengths"] == pytest.approx(s_b, rel=1e-2)
    assert fit.sigma["b lengths"] < 0.2 * s_a  # the group without real corrections: a narrow prior
    # the fit is the posterior mean under the learned prior (closed form)
    prec = np.r_[np.full(3, fit.sigma["a lengths"] ** -2), np.full(3, fit.sigma["b lengths"] ** -2), 0.0]
    mean = np.linalg.solve(J.T @ J / fit.noise2 + np.diag(prec), J.T @ (y / STATED) / fit.noise2)
    np.testing.assert_allclose(fit.x, mean, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(fit.covariance, np.linalg.inv(J.T @ J / fit.noise2 + np.diag(prec)), rtol=1e-6,
                               atol=1e-30)


def test_groups_per_joint_origin_and_kind_the_base_and_set_up_without():
    kinds = {"j2.a": "length", "j2.d": "length", "j2.alpha": "angle", "base.x": "length", "tool.x": "length"}
    assert prior_groups(["j2.a", "j2.alpha", "j2.d", "base.x", "tool.x", "point[p].x"], kinds, ["base.x"]) == \
        ["j2 lengths", "j2 angles", "j2 lengths", None, "tool lengths", None]


def test_plentiful_data_well_determined_as_least_squares_weak_ones_nearer_the_truth():
    """200 tracker poses of a UR5 (errors 0.5 mm / 0.5 mrad on every parameter): what they determine
    to µm is fitted as by least squares (< 0.5 σ apart: one correlated with a weak one moves with it);
    what they hardly see (joint 5's confounded origin, σ 0.3 mm and 3 mrad) the prior pulls towards
    nominal, which is nearer the truth on the whole (five robots: one draw may go either way) and
    predicts no worse."""
    ur5 = kincal.load_robot("ur5")
    qv, misses = ur5.sample_joints(300, seed=9), np.zeros(2)
    for seed in range(4, 9):
        true = kincal.perturb(ur5, 0.5e-3, 0.5e-3, seed=seed)
        m = kincal.simulate(true, ur5.sample_joints(200, seed=seed), 15e-6, seed=seed)
        sets = [PointObs(m.q, m.rows, "sim", xyz=m.xyz, std=15e-6)]
        plain, learned = fit_observations(ur5, sets, prior="none"), fit_observations(ur5, sets, prior="relevance")
        assert learned.names == plain.names and learned.prior and not plain.prior
        sharp = [n for n in plain.names if plain.std[n] < 2e-5]
        weak = [n for n in plain.names if plain.std[n] > 1e-4]
        assert len(sharp) >= 20 and len(weak) >= 2
        assert max(abs(learned.robot.params[n] - plain.robot.params[n]) / plain.std[n] for n in sharp) < 0.5
        misses += [sum(abs(fit.robot.params[n] - true.params[n]) / plain.std[n] for n in weak) for fit in (plain, learned)]
        error = [np.mean(np.linalg.norm(fit.robot.forward(qv) - true.forward(qv), axis=1)) for fit in (plain, learned)]
        assert error[1] < 1.02 * error[0]
    assert misses[1] < 0.6 * misses[0]


def test_scarce_data_keep_what_they_cannot_confirm_near_nominal():
    """40 poses in a small joint region (±0.4 rad), a UR5 whose only errors are in joint 2's origin: least squares
    spreads the noise over every identifiable parameter and extrapolates it; the learned prior keeps the
    error-free joints near nominal, and predicts the whole workspace better."""
    ur5 = kincal.load_robot("ur5")
    true = ur5.with_params({"j2.a": ur5.params["j2.a"] + 1e-3, "j2.alpha": ur5.params["j2.alpha"] + 1e-3})
    q = ur5.sample_joints(1, seed=5) + np.random.default_rng(5).uniform(-0.4, 0.4, (40, 6))
    m = kincal.simulate(true, q, 15e-6, seed=5)
    sets = [PointObs(m.q, m.rows, "sim", xyz=m.xyz, std=15e-6)]
    plain, learned = fit_observations(ur5, sets, prior="none"), fit_observations(ur5, sets, prior="relevance")
    qv = ur5.sample_joints(300, seed=6)

    def error(robot):
        return float(np.sqrt(np.mean(np.sum((robot.forward(qv) - true.forward(qv)) ** 2, axis=1))))
    print(f"workspace RMS error: least squares {error(plain.robot) * 1e3:.4f} mm, learned prior "
          f"{error(learned.robot) * 1e3:.4f} mm; prior {learned.prior}")
    assert error(learned.robot) < 0.5 * error(plain.robot)
    held = [g for g, s in learned.prior.items() if s < 1e-6]
    assert "j2 lengths" not in held and len(held) >= 3



def test_the_learned_prior_keeps_to_its_iteration_limit():
    """relevance_fit's iterations (Gauss–Newton steps and its final Levenberg–Marquardt together) stay within
    max_iter, and a fit stopped by it says so (its Levenberg–Marquardt ran up to 100 whatever the limit)."""
    J, y, groups = _linear_problem()

    def fun(x):
        return (J @ x - y / STATED), J
    ls = levenberg_marquardt(fun, np.zeros(7))
    free = relevance_fit(fun, ls, np.zeros(7), groups, ["length"] * 6 + [""])
    assert free.converged and free.iterations > 1 and free.message == "prior learned"
    capped = relevance_fit(fun, ls, np.zeros(7), groups, ["length"] * 6 + [""], max_iter=1)
    assert capped.iterations == 1 and not capped.converged
    assert capped.message == "prior learned; stopped after 1 iterations without meeting the tolerances"


@pytest.mark.slow
def test_max_iter_caps_every_solver_run_and_the_count_sums_them(tmp_path, capsys, monkeypatch):
    """--max-iter caps each solver run, and the printed count is the sum over the runs it names: the Panda's
    front placement with --max-iter 5 printed "27 iterations" (6 Levenberg–Marquardt runs of at most 5, the
    learned prior's 3 left out), two files with a moved plate 9774 at the default 100."""
    import json

    import kincal.identify.rounds as rounds
    from conftest import PANDA_URDF, SOCKETS
    from kincal.cli import main

    runs, limits = [], []
    lm, prior = rounds.levenberg_marquardt, rounds.with_learned_prior

    def counted_lm(fun, x0, max_iter=100, **kw):
        fit = lm(fun, x0, max_iter=max_iter, **kw)
        runs.append(fit.iterations)
        limits.append(max_iter)
        return fit

    def counted_prior(fun, fit, nominal, free, robot, *limit):
        out = prior(fun, fit, nominal, free, robot, *limit)
        if out is not fit:
            runs.append(out.iterations)
            limits.extend(limit or [100])
        return out

    monkeypatch.setattr(rounds, "levenberg_marquardt", counted_lm)
    monkeypatch.setattr(rounds, "with_learned_prior", counted_prior)
    lines = (SOCKETS / "samples.csv").read_text().splitlines()
    front = tmp_path / "front.csv"
    front.write_text("\n".join([lines[0], *(x for x in lines if x.startswith("front_center,"))]) + "\n")
    args = ["calibrate", str(PANDA_URDF), "--tip-link", "ball_link", str(front), "--type", "same-point",
            "--joint-cols", "q1,q2,q3,q4,q5,q6,q7", "--label-col", "socket", "--group-col", "placement",
            "--length-unit", "mm", "--distance", "0,1,50", "--max-iter", "5"]
    assert main([*args, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["prior"] and len(runs) > 2 and set(limits) == {5} and max(runs) <= 5
    assert (out["iterations"], out["runs"]) == (sum(runs), len(runs))
    assert main(args) == 0
    assert f"in {out['iterations']} iterations over {out['runs']} solver runs" in capsys.readouterr().out
