"""Identifiability: rank counts from theory, named confounds that hold exactly."""
import numpy as np
import pytest

import kincal
from kincal import Joint


def test_ur5_position_with_beta_has_27_identifiable(ur5):
    q = ur5.sample_joints(80, seed=3)
    ident = kincal.identifiability(ur5, q)
    assert ident.rank == 27 == len(ident.identifiable)  # 4*6 + 6 - 3
    assert len(ident.dropped) == ur5.n_params - 27
    assert ident.gap > 1e6  # a clear-cut rank
    # confounds read off the R factor are real: the dropped column equals the named combination
    J = ur5.param_jacobian(q)
    for name in ident.dropped:
        conf = ident.confounds[name]
        combo = sum(c * J[:, :, ur5.params.index(n)] for n, c in conf)
        np.testing.assert_allclose(J[:, :, ur5.params.index(name)], combo, atol=1e-9)
    # the obvious ones, in physical units
    conf = ident.confounds["j6.d"]  # one term, the tool's z, coefficient 1 (to round-off: 1 + 2e-16 here)
    assert [n for n, _ in conf] == ["tool.z"] and abs(conf[0][1] - 1) < 1e-9, conf
    assert abs(dict(ident.confounds["j1.d"])["base.z"] - 1) < 1e-9
    assert abs(dict(ident.confounds["j1.theta"])["base.rz"] - 1) < 1e-9
    text = str(ident)
    assert "27 of 35" in text and "j6.d" in text and "tool.z" in text


def test_ur5_without_beta_loses_rank_and_says_why(ur5):
    no_beta = ur5.with_joints([Joint(j.name, j.type, False, j.lower, j.upper) for j in ur5.joints])
    ident = kincal.identifiability(no_beta, no_beta.sample_joints(80, seed=3))
    assert ident.rank == 25
    # the d offsets along the three parallel axes act only through their sum
    parallel_d = {"j2.d", "j3.d", "j4.d"}
    assert len(parallel_d & set(ident.dropped)) == 2
    assert any("parallel" in n and "beta" in n for n in ident.notes)


def test_fixed_base_and_keep_change_the_choice(ur5):
    q = ur5.sample_joints(60, seed=1)
    fixed = kincal.identifiability(ur5, q, exclude=ur5.base_params())
    assert not set(ur5.base_params()) & set(fixed.candidates)
    assert {"j1.theta", "j1.d"} <= set(fixed.identifiable)
    kept = kincal.identifiability(ur5, q, keep=["j1.theta"])
    assert "j1.theta" in kept.identifiable and "base.rz" in kept.dropped


def test_parameter_without_effect_is_reported():
    wam = kincal.load_robot("wam")  # reflector on the last axis: joint 7's angle cannot be seen
    ident = kincal.identifiability(wam, wam.sample_joints(50, seed=0))
    assert "j7.theta" in ident.dropped and ident.confounds["j7.theta"] == ()
    assert "no effect" in str(ident)


def test_too_few_poses_limit_the_rank(ur5):
    """5 poses give 15 equations: the rank is 15, the rank numpy finds on the same scaled columns with its
    own tolerance (s_max·max(M, N)·eps, not kincal's RANK_TOL, so that the count is an independent one)."""
    q = ur5.sample_joints(5, seed=0)
    ident = kincal.identifiability(ur5, q)
    J = ur5.param_jacobian(q).reshape(15, -1)
    live = np.linalg.norm(J, axis=0) > 1e-12
    Js = J[:, live] / np.linalg.norm(J[:, live], axis=0)
    assert ident.rank == np.linalg.matrix_rank(Js) == 15
    assert len(ident.identifiable) == 15 and len(ident.dropped) == ur5.n_params - 15


@pytest.mark.parametrize("name, seed, dropped", [("guo3t2r", 0, "j5.theta"), ("guo3t2r", 0, "j5.alpha"),
                                                  ("puu3-extended", 1, "leg1.dR"), ("ur5", 2, "j6.alpha")])
def test_confound_coefficients_carry_their_units(name, seed, dropped):
    """A dropped parameter's combination gives each coefficient in the kept parameter's unit per the dropped one's
    (mm/mrad: 1 mrad of an angle moves the points like c mm of a length; same kinds none), its value the
    finite-difference ratio: on guo3t2r 1 mrad of j5.theta moves the points like +0.05 mm of tool.y."""
    import re

    robot = kincal.load_robot(name)
    q = robot.sample_joints(60 if name != "puu3-extended" else 80, seed=seed)
    ident = kincal.identifiability(robot, q)
    kinds = dict(zip(robot.params.names, robot.params.kinds))
    line = next(x for x in ident.confound_lines("") if x.startswith(f"{dropped}  ~  "))
    terms = re.findall(r"([-+][0-9.e+-]+)( mm/mrad| mrad/mm)?·(\S+)", line.split("  ~  ")[1])
    shown = {"length": "mm", "angle": "mrad"}  # both 1e-3 of the SI unit

    def moved(n):  # the points moved by 1e-3 (one mm or mrad) of parameter n, m: central differences
        h = 1e-7
        up, down = (robot.with_params({n: robot.params[n] + s}).forward(q) for s in (h, -h))
        return ((up - down) / (2 * h) * 1e-3).ravel()
    ratio = np.linalg.lstsq(np.stack([moved(k) for _, _, k in terms], axis=1), moved(dropped), rcond=None)[0]
    for (c, unit, kept), want in zip(terms, ratio):
        same = kinds[kept] == kinds[dropped]
        assert unit == ("" if same else f" {shown[kinds[kept]]}/{shown[kinds[dropped]]}"), line
        assert float(c) == pytest.approx(want, rel=6e-3, abs=1e-6), line  # 3 significant digits
    assert sum(bool(u) for _, u, _ in terms) >= 1
    if dropped == "j5.theta":
        assert line == "j5.theta  ~  +0.05 mm/mrad·tool.y"


def test_tall_r_factor_equals_one_householder_qr():
    """The blocked QR of a tall Jacobian has the same Gram matrix RᵀR = JᵀJ and singular values as
    NumPy's one QR, rank deficiency included (a column the sum of two others)."""
    from kincal.analysis.identifiability import QR_ROWS, r_factor

    rng = np.random.default_rng(3)
    J = rng.normal(size=(5 * QR_ROWS + 17, 12)) * np.logspace(-3, 2, 12)
    J[:, 5] = J[:, 3] + J[:, 4]
    R, R1 = r_factor(J), np.linalg.qr(J, mode="r")
    assert R.shape == (12, 12) and np.allclose(np.tril(R, -1), 0.0)
    np.testing.assert_allclose(R.T @ R, R1.T @ R1, rtol=1e-10, atol=1e-9 * np.abs(R1.T @ R1).max())
    s, s1 = np.linalg.svd(R, compute_uv=False), np.linalg.svd(R1, compute_uv=False)
    np.testing.assert_allclose(s[:-1], s1[:-1], rtol=1e-10)
    assert s[-1] < 1e-12 * s[0] and s1[-1] < 1e-12 * s1[0]


def test_a_name_to_prefer_that_the_robot_does_not_have_is_refused(ur5):
    """keep names parameters to prefer among confounded ones: a name the robot lacks was silently ignored."""
    with pytest.raises(kincal.ModelError, match="unknown parameter 'j9.d'"):
        kincal.identifiability(ur5, ur5.sample_joints(20, seed=1), keep=["j9.d"])
