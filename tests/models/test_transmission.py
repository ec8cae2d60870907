"""Robots driven through transmissions (the 3T2R robot of seed 1): kinematics, Jacobians, limits, files."""
import numpy as np
import pytest
from conftest import central_jacobian

import kincal
from kincal.design import candidate_pool


@pytest.fixture(scope="module")
def guo():
    return kincal.load_robot("guo3t2r")


def test_transmission_formulas(guo):
    sx, sz, L1 = 0.010, 0.010, 0.300
    phi = np.array([[300.0, 250.0, -100.0, 0.3, -0.4]])
    q = guo.chain_q(phi)[0]
    assert q[0] == pytest.approx(sx * 550.0 / (4 * np.pi))
    assert q[1] == pytest.approx(np.arctan(sx * 50.0 / (2 * np.pi * L1)))
    assert q[2] == pytest.approx(sz * -100.0 / (2 * np.pi))
    assert (q[3], q[4]) == (0.3, -0.4)


def test_21_kinematic_parameters_and_drive(guo):
    kin = [n for n in guo.params.names if n.split(".")[1] in ("theta", "alpha", "a", "d", "beta")]
    assert len(kin) == 21 and "j2.beta" in kin
    assert guo.drive.names == ("drive.sx", "drive.sz", "drive.L1")


def test_jacobians_match_central_differences(guo):
    robot = kincal.perturb(guo, 1e-3, 1e-2, seed=4, include_base=True)
    phi = candidate_pool(robot, 25, seed=3)
    Jn = central_jacobian(robot, phi)
    assert np.abs(robot.param_jacobian(phi) - Jn).max() / np.abs(Jn).max() < 1e-6
    h = 1e-6
    Jq = np.stack([(robot.forward(phi + h * e) - robot.forward(phi - h * e)) / (2 * h) for e in np.eye(5)], axis=2)
    np.testing.assert_allclose(robot.joint_jacobian(phi), Jq, atol=1e-8)


def test_psi_constraint_and_pool(guo):
    phi = candidate_pool(guo, 400, seed=1)
    q = guo.chain_q(phi)
    assert np.all(np.abs(q[:, 1]) <= np.pi / 4 + 1e-12) and np.all(guo.within_limits(phi))
    # a differential beyond 2*pi*L1/sx violates |psi| <= 45 deg
    bad = np.array([[400.0, 400.0 - 2 * np.pi * 0.3 / 0.01 - 1.0, -10.0, 0, 0]])
    assert not guo.feasible(bad)[0]


def test_round_trip_and_calibration(tmp_path, guo):
    true = kincal.perturb(guo, seed=5)
    path = tmp_path / "g.yaml"
    kincal.save_robot(true, path)
    back = kincal.load_robot(path)
    assert back.params == true.params and back.joint_names == guo.joint_names
    phi = candidate_pool(guo, 80, seed=2)
    res = kincal.calibrate(guo, kincal.simulate(true, phi, 15e-6, seed=1))
    val = kincal.simulate(true, candidate_pool(guo, 100, seed=9), 0.0)
    assert kincal.evaluate(guo, val).mean > 0.3e-3 and kincal.evaluate(res.robot, val).rms < 30e-6


def test_a_screw_motor_is_not_periodic(guo):
    """A whole turn of a screw's motor is 10 mm of travel, not the same pose: the route keeps the motors' values
    (turning them by whole turns moved the tool 30-40 mm) and the wrist's direct motors alone repeat."""
    from kincal.design import turned
    np.testing.assert_allclose(guo.motor_leads[:3] * 2 * np.pi * 1e3, [5.0, 5.0, 10.0])  # lead/2 per motor of a pair
    assert guo.periodic.tolist() == [False, False, False, True, True]
    q = guo.sample_joints(3, seed=1)
    np.testing.assert_array_equal(turned(guo, q)[:, :3], q[:, :3])
