"""The noise model: stated σ plus the variance the model cannot describe (kincal.identify.noise)."""
import numpy as np
import pytest

import kincal
from kincal.identify.noise import extra_variance
from kincal.io.measurements import Measurements


def test_extra_variance_is_the_moment_estimate():
    r2 = np.random.default_rng(1).chisquare(1, 3000) * 4e-8
    var = np.full(3000, 1e-10)
    dof = 2900.0
    assert extra_variance(r2, var, dof) == pytest.approx(r2.sum() / dof - 1e-10, rel=1e-9)  # equal σ: closed form
    var = np.random.default_rng(2).uniform(1e-12, 4e-9, 3000)  # unequal: the equation holds at the estimate
    s2 = extra_variance(r2, var, dof)
    assert np.sum(r2 / (var + s2)) == pytest.approx(dof, rel=1e-9)
    assert extra_variance(r2, r2.sum() / dof * np.ones(3000) * 2, dof) == 0.0  # the stated σ explain it all


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
