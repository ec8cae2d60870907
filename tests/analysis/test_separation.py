"""GCN and the branch-and-bound separation of ill-conditioned parameters (seed 1, §3.1)."""
import numpy as np
import pytest

import kincal
from kincal.analysis.separation import GCN_FLOOR, averaged_gcn, gcn, separate_ill_conditioned
from kincal.design import candidate_pool


def test_gcn_by_hand():
    J = np.zeros((6, 3))
    J[0, 0], J[1, 1], J[2, 2] = 3.0, 2.0, 1.0
    assert gcn(J, 2) == pytest.approx(3.0 / 1.0 / 2)
    J[2, 2] = 0.0  # rank deficient: finite, enormous, and the same on every machine
    assert gcn(J, 2) == pytest.approx(1.0 / GCN_FLOOR / 2, rel=1e-15)
    J[2, 2] = 1e-14  # rounding noise of an exact dependence is floored to the same value
    assert gcn(J, 2) == pytest.approx(1.0 / GCN_FLOOR / 2, rel=1e-15)
    blocks = np.stack([np.eye(3) * 2.0, np.eye(3)])  # poses with orthogonal blocks
    assert averaged_gcn(blocks) == pytest.approx((1.0 / 1 + 1.0 / 2) / 2)


@pytest.mark.slow
def test_separation_on_the_3t2r_robot():
    robot = kincal.load_robot("guo3t2r")
    sep = separate_ill_conditioned(robot, candidate_pool(robot, 100, seed=0))
    assert len(sep.names) == 21
    big = {t for t, g in sep.subdomain_gcn.items() if g > 1e2}
    assert big == {"theta", "a", "d"}  # the paper found a and d; our wrist adds θ3 ≡ θ4
    assert sep.subdomain_gcn["alpha"] < 10 and sep.subdomain_gcn["beta"] < 10
    # equivalent pairs are found by backward elimination: removing either one fixes the subdomain
    rows = dict(sep.branches["a"])
    assert rows["j2.a"] < 1e2 and rows["j3.a"] < 1e2 and rows["j1.a"] > 1e8
    assert {"j3.theta", "j4.theta"} <= set(sep.candidates["theta"])
    assert set(sep.candidates["d"]) >= {"j3.d", "j4.d"}
    # one member of each dependent group is separated, like QR; step 4 also finds the dependence
    # across types (j5.alpha), so the reduced model has exactly QR's rank and is well conditioned
    for group in ({"j2.a", "j3.a"}, {"j3.theta", "j4.theta"}):
        assert len(group & set(sep.separated)) == 1 and len(group & set(sep.qr_dropped)) == 1
    assert "j5.alpha" in sep.separated and "j5.alpha" in sep.qr_dropped
    assert len(sep.names) - len(sep.separated) == len(sep.names) - len(sep.qr_dropped) == 16
    kept = [n for n in sep.names if n not in sep.separated]
    assert kincal.identifiability(robot, candidate_pool(robot, 100, seed=0), names=kept).full_rank
    assert sep.gcn_reduced < 1e2 < sep.gcn_full
    assert "kincal table S1" in sep.tables() and "the paper's Table 1" in sep.tables() and "QR" in sep.tables()
    # a GCN that comes from the floor (an exact dependence) is printed as such, never as a number: every such set
    # averaged the same 4.187e+08, which read as a measurement
    S3 = next(line for line in sep.tables().splitlines()[1:] if line.strip().startswith("-j1.a"))
    assert "-j1.a       dependent" in S3 and f"-j2.a      {rows['j2.a']:10.4g}" in S3 and "e+08" not in sep.tables()


def test_a_group_that_is_all_candidates_keeps_one_member():
    """Three parameters that act as one (the UR5's d offsets along parallel axes): every one is a candidate, and
    removing them all would leave no model; the separation keeps one, as QR does."""
    import kincal
    from kincal.analysis import separate_ill_conditioned

    ur5 = kincal.load_robot("ur5")
    sep = separate_ill_conditioned(ur5, ur5.sample_joints(50, seed=0), names=["j2.d", "j3.d", "j4.d"])
    assert len(sep.separated) == 2 and set(sep.separated) == set(sep.qr_dropped)


def test_a_model_with_fewer_rows_than_parameters_is_refused_not_called_well_conditioned():
    """Three guo3t2r poses give a 9 x 21 Jacobian of rank 9 (numpy's own rank, the independent count): its GCN over
    the 9 singular values was 4.16, under the threshold, so the whole rank-deficient model passed as verified.
    Refused now, naming the fewest poses with more rows than parameters (8); 8 poses are separated."""
    robot = kincal.load_robot("guo3t2r")
    q = candidate_pool(robot, 3, seed=0)
    names = [n for n in robot.params.names if n.split(".")[-1] in ("theta", "d", "a", "alpha", "beta")]
    J = robot.param_jacobian(q)[:, :, robot.params.indices(names)].reshape(-1, len(names))
    assert J.shape == (9, 21) and np.linalg.matrix_rank(J) == 9
    with pytest.raises(ValueError, match="3 poses give 9 rows for 21 parameters.*at least 8 poses"):
        separate_ill_conditioned(robot, q)
    assert separate_ill_conditioned(robot, candidate_pool(robot, 8, seed=0)).gcn_full > 0
