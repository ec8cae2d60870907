"""The extension point as a user meets it: a new closed-loop robot written from the outside as an
ImplicitRobot works with every part of kincal (kinematics, identifiability, calibration, design)."""
from dataclasses import dataclass, field

import numpy as np
import pytest
from conftest import assert_jacobians

import kincal
from kincal.models import JointSpace

BASE = ("base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz")
ANCHORS = tuple(f"a{i}.{c}" for i in (1, 2, 3) for c in "xyz")


@dataclass(frozen=True, eq=False, repr=False)
class CableRobot(kincal.ImplicitRobot):
    """Three cables of lengths q from anchors aᵢ hold a point below them: ‖p − aᵢ‖² − qᵢ² = 0."""

    name: str = "cable3"
    description: str = "a point held by three cables (test robot)"
    params: kincal.Parameters = field(default_factory=lambda: kincal.Parameters(
        BASE + ANCHORS, [0.0] * 6 + [1.0, 0.0, 2.0, -0.5, 0.9, 2.0, -0.5, -0.9, 2.0], ["length"] * 3 + ["angle"] * 3 +
        ["length"] * 9))
    joint_space: JointSpace = field(default_factory=lambda: JointSpace(("c1", "c2", "c3"), ("prismatic",) * 3,
                                                                       [1.2] * 3, [2.4] * 3))

    def _anchors(self, values):
        return np.asarray(values)[..., 6:].reshape(*np.shape(values)[:-1], 3, 3)

    def constraints(self, p, q, values):
        d = p[:, None, :] - self._anchors(values)
        return np.sum(d * d, axis=-1) - q**2

    def constraint_derivatives(self, p, q, values):
        d = p[:, None, :] - self._anchors(values)  # (N, 3 cables, 3)
        fs = np.zeros((len(p), 3, self.n_params))
        for i in range(3):
            fs[:, i, 6 + 3 * i:9 + 3 * i] = -2.0 * d[:, i]
        return 2.0 * d, -2.0 * np.eye(3) * q[:, None, :], fs

    def start_point(self, q, values):
        a = self._anchors(values)
        return np.broadcast_to(a.mean(axis=-2) - [0.0, 0.0, 1.5], (len(q), 3)).copy()


def trilaterate(anchors, r):
    """The point below three anchors at distances r, in closed form (the independent reference)."""
    a1, a2, a3 = anchors
    ex = (a2 - a1) / np.linalg.norm(a2 - a1)
    i = ex @ (a3 - a1)
    ey = (a3 - a1 - i * ex) / np.linalg.norm(a3 - a1 - i * ex)
    ez = np.cross(ex, ey)
    d, j = np.linalg.norm(a2 - a1), ey @ (a3 - a1)
    x = (r[0] ** 2 - r[1] ** 2 + d**2) / (2 * d)
    y = (r[0] ** 2 - r[2] ** 2 + i**2 + j**2) / (2 * j) - i * x / j
    z = np.sqrt(r[0] ** 2 - x**2 - y**2)
    p = a1 + x * ex + y * ey
    return min((p + z * ez, p - z * ez), key=lambda c: c[2])


def test_a_user_written_implicit_robot_works_everywhere():
    robot = CableRobot()
    assert "ImplicitRobot" in kincal.__all__ and not robot.has_inverse
    q = robot.sample_joints(40, seed=1)
    assert robot.feasible(q).all()
    ref = np.array([trilaterate(robot.params.values[6:].reshape(3, 3), qi) for qi in q])
    np.testing.assert_allclose(robot.forward(q), ref, atol=1e-10)
    true = kincal.perturb(robot, length=2e-3, angle=0.0, seed=2)
    assert_jacobians(true, q, joint_tol=1e-6)
    with pytest.raises(kincal.ModelError, match="no closed-form inverse"):
        robot.inverse(ref)
    # identifiability names what position data cannot see (the frame and the anchors trade off)
    ident = kincal.identifiability(robot, q)
    assert ident.rank == 9 and len(ident.dropped) == 6
    res = kincal.calibrate(robot, kincal.simulate(true, q, 0.0), base="fixed")
    qv = robot.sample_joints(50, seed=3)
    assert res.converged and kincal.evaluate(res.robot, kincal.simulate(true, qv, 0.0)).max < 1e-9
    d = kincal.select_poses(robot, robot.sample_joints(300, seed=4), m=12, base="fixed", criterion="D")
    assert d.q.shape == (12, 3) and 0.9 < d.efficiency <= 1.0
