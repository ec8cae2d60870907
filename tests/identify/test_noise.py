"""The noise model: stated σ plus the variance the model cannot describe (kincal.identify.noise)."""
import numpy as np
import pytest

import kincal
from kincal.identify.noise import extra_variance
from kincal.io.measurements import Measurements


def test_extra_variance_is_the_robust_estimate():
    """median(r² / (σ² + s²)) = median of χ²₁ · dof / n: the closed form for equal σ, the equation itself
    for unequal σ, 0 when the stated σ explain the residuals, and 1 % of gross outliers barely move it
    (the mean-square estimate would grow 20-fold)."""
    n, dof = 3000, 2900.0
    r2 = np.random.default_rng(1).chisquare(1, n) * 4e-8
    t = 0.454936423119572 * dof / n  # the median of χ²₁ (scipy.stats.chi2(1).median())
    assert extra_variance(r2, np.full(n, 1e-10), dof) == pytest.approx(np.median(r2) / t - 1e-10, rel=1e-9)
    var = np.random.default_rng(2).uniform(1e-12, 4e-9, n)
    s2 = extra_variance(r2, var, dof)
    assert np.median(r2 / (var + s2)) == pytest.approx(t, rel=1e-6)
    assert extra_variance(r2, np.full(n, 1.0), dof) == 0.0
    gross = r2.copy()
    gross[:30] = 1e-4  # 30 components of 10 mm among errors of 0.2 mm
    assert extra_variance(gross, var, dof) == pytest.approx(s2, rel=0.05)
    assert np.mean(gross) / np.mean(r2) > 20


def _ur10_sets(seed: int, model_error: float):
    """UR10 poses with σ columns of 2–60 µm (noise drawn at them) and a smooth error the geometric
    model cannot describe (``model_error`` m per axis)."""
    ur = kincal.load_robot("ur10")
    true = kincal.perturb(ur, 0.5e-3, 0.5e-3, seed=seed)

    def data(n, s):
        q = ur.sample_joints(n, seed=s)
        bias = model_error * np.stack([np.sin(2 * q[:, 0] + q[:, 1]), np.cos(q[:, 2] - q[:, 1]),
                                       np.sin(q[:, 3] + q[:, 4])], 1)
        g = np.random.default_rng(s)
        std = np.exp(g.uniform(np.log(2e-6), np.log(60e-6), size=(n, 1))) * np.ones((1, 3))
        return q, true.forward(q) + bias + g.normal(size=(n, 3)) * std, std
    return ur, data(200, 100 + seed), data(200, 200 + seed)


@pytest.mark.slow
@pytest.mark.parametrize("model_error", [0.3e-3, 0.0])
def test_sigma_columns_cannot_make_a_fit_worse(model_error):
    """With 0.3 mm the model cannot describe, the σ columns leave the held-out error within 2 % of the
    fit without them (weighting by 1/σ² alone: 3.7 % worse here); with none, they still help."""
    ratios = []
    for seed in range(3):
        ur, (q, x, std), (qt, xt, _) = _ur10_sets(seed, model_error)
        err = []
        for s in (std, None):
            fit = kincal.calibrate(ur, Measurements(q, x, ur.joint_names, "sim", std=s), diagnose=False)
            err.append(np.linalg.norm(fit.robot.forward(qt) - xt, axis=1).mean())
        ratios.append(err[0] / err[1])
    print(f"model error {model_error * 1e3} mm: held-out with / without the σ columns {np.round(ratios, 4)}")
    assert max(ratios) <= 1.02
    if model_error == 0.0:
        assert np.mean(ratios) < 0.97  # the stated σ are right: weighting by them pays (0.94 here)
