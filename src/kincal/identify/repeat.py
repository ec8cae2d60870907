"""What a repeat calibration of the same, unchanged robot would differ by: the record that ``kincal compare`` and
``kincal check`` judge a change against.

Two calibrations of one unchanged robot on different poses differ by more than their noise σ: the part of what the
model cannot describe (an unmodelled harmonic, a warm-up) that each pose set pushes into the parameters is not the
same. The ordinary covariance σ̂²(JᵀJ)⁻¹ treats that part as white noise and is too small (on a simulated UR5 with a
0.1 mm harmonic, a test of the parameters on it called 18–25 % of unchanged pairs changed at a 5 % level). The
sandwich (robust) covariance A (Σ_s g_s g_sᵀ) A · n/(n − K), with A the fit's (JᵀJ + prior)⁻¹ and
g_s = Σ J_rowᵀ r_row over the rows of sample s, is what the parameters vary by when the poses are drawn anew from the
same region, whatever the residual's structure (White 1980; Freedman 2006): the same test on it called 3.5 % of 200
unchanged pairs changed at 5 %.

Beside it, what a prediction at a new pose of the region misses by (``sigma`` per axis, m, and ``joints``: the part
that acts like joint-angle errors, growing with the lever arm, correlated over poses whose joints stand at near
angles, ``length``) and how much heavier than Gaussian that miss is (``dispersion``: the variance of each sample's
squared whitened position residual over its Gaussian value, ≥ 1), so a check of a few poses states its false-alarm
probability honestly.
"""
from __future__ import annotations

import numpy as np

from ..analysis.changes import SAMPLES, Repeat, loo_scale, miss_from_parts, miss_parts
from ..models.robot import Robot
from ..ties import first_best
from .covariance import normal_inverse
from .judge import owners


LENGTHS = (0.0, 0.1, 0.2, 0.4, 0.8, 1.6)  # rad: the correlation lengths tried (0: a miss of its own at every pose)
MISS_SAMPLES = 2000  # samples the miss's variances are fitted on (a calibration of 10^5 poses: 0.25 s less)
LIKELIHOOD = 150  # samples the length is chosen on (its cost is cubic in them: 300 took 80 ms)
FLOOR = 0.01  # the position part of the miss is at least this share of the mean squared residual per axis


def repeat_of(robot: Robot, sets, free, J: np.ndarray, r: np.ndarray, posterior: np.ndarray | None,
              positions: np.ndarray, held: dict | None = None) -> Repeat:
    """The :class:`Repeat` record of a fit of the observation ``sets`` over the columns ``free`` of the calibrated
    ``robot``: J (M, K) and r (M,) whitened at the solution; ``posterior`` (K, K) the fit's (JᵀJ + prior)⁻¹ (None:
    least squares); ``positions`` (M,) the residual rows in m (the miss is read off the point and pose samples);
    ``held``: parameters kept nominal because the data determine them too weakly, name -> the σ the data gave them
    (m or rad): another calibration may fit them, so they join the covariance with that variance (a finite one)."""
    owner, n = owners(sets)
    lone = owner < 0  # a row of no sample (a known distance) is a sample of its own
    owner = np.where(lone, n + np.cumsum(lone) - 1, owner)
    groups = n + int(lone.sum())
    K = J.shape[1]
    g = np.zeros((groups, K))  # per sample (np.add.at: 10x slower); nothing fitted (a frame kept): no columns
    for k in range(K):
        g[:, k] = np.bincount(owner, J[:, k] * r, groups)
    A = normal_inverse(J) if posterior is None else posterior
    dof = max(groups - K, 1)
    cov = A @ (g.T @ g) @ A * (groups / dof)
    q, res = _position_samples(sets, positions)
    kept = _kept_samples(robot, q, res)
    taken = K * 3 * len(q) / max(r.size, 1)
    if len(q) > MISS_SAMPLES:  # two variances need no more: evenly by row, the degrees of freedom in proportion
        at = np.unique(np.linspace(0, len(q) - 1, MISS_SAMPLES).astype(int))
        q, res, taken = q[at], res[at], taken * len(at) / len(q)
    sigma, joints, dispersion = miss_model(robot, q, res, taken)
    length = miss_length(robot, q, res, sigma, joints) if sigma is not None else 0.0
    extra = {n: float(v) ** 2 for n, v in (held or {}).items() if np.isfinite(v) and n not in free}
    cov = np.block([[0.5 * (cov + cov.T), np.zeros((K, len(extra)))],
                    [np.zeros((len(extra), K)), np.diag(list(extra.values())).reshape(len(extra), len(extra))]])
    scale = 1.0
    if sigma is not None and len(kept[0]):
        rev = robot.revolute
        A = miss_from_parts(miss_parts(robot.joint_jacobian(kept[0])[:, :3, :], kept[0], rev, joints), sigma, length,
                            len(kept[0]))
        scale = loo_scale(A, kept[1])
    return Repeat((*free, *extra), cov, dof, sigma, joints, dispersion, length, *kept, scale)


def _kept_samples(robot: Robot, q: np.ndarray, res: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Up to ``SAMPLES`` samples evenly by row: their joints (S, n) and misses measured − predicted (S, 3) m in the
    robot's base frame (the residuals ``res`` are predicted − measured in the measurement frame)."""
    if len(q) == 0:
        return np.zeros((0, robot.n_joints)), np.zeros((0, 3))
    at = np.unique(np.linspace(0, len(q) - 1, min(len(q), SAMPLES)).astype(int))
    R = robot.base_transform()[0] if robot.base_params() else np.eye(3)
    return q[at].copy(), -res[at] @ R


def miss_length(robot: Robot, q: np.ndarray, res: np.ndarray, sigma: float, joints: tuple) -> float:
    """The joints' correlation length (rad, one of ``LENGTHS``; 0: none) under which the residuals res (N, 3) at q
    (N, n) are likeliest as a Gaussian with :func:`kincal.analysis.changes.miss_covariance` (at most ``LIKELIHOOD``
    samples, evenly by row; ties: the shortest, :mod:`kincal.ties`)."""
    at = np.unique(np.linspace(0, len(q) - 1, min(len(q), LIKELIHOOD)).astype(int))
    Jq, rev = robot.joint_jacobian(q[at])[:, :3, :], robot.revolute
    parts, values = miss_parts(Jq, q[at], rev, joints), []
    for length in LENGTHS:
        A = miss_from_parts(parts, sigma, length, len(at))
        try:
            L = np.linalg.cholesky(A)
        except np.linalg.LinAlgError:
            values.append(-np.inf)
            continue
        z = np.linalg.solve(L, res[at])
        values.append(-0.5 * float(np.sum(z**2)) - 3.0 * float(np.sum(np.log(np.diag(L)))))
    return LENGTHS[first_best(values)]


def _position_samples(sets, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The joints (N, n) and position residuals (N, 3) m of every point and pose sample of ``sets``."""
    qs, rs, at = [], [], 0
    for o in sets:
        m = o.sigma().size
        found = o.positions() if o.kind in ("point", "pose") else None  # None: a session in its own frame
        if found is not None:
            axes, sample = o.position_axes(), o.sample_rows()
            res, rows = np.zeros((len(o), 3)), axes >= 0
            res[sample[rows], axes[rows]] = positions[at:at + m][rows]
            qs.append(found[0])
            rs.append(res)
        at += m
    return (np.concatenate(qs), np.concatenate(rs)) if qs else (np.zeros((0, 0)), np.zeros((0, 3)))


def nonnegative_2(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """argmin ‖A x − b‖ over x ≥ 0 for A (N, 2), exactly: the unconstrained solution if it is non-negative, else the
    better of the two one-column solutions (each clipped at 0). (SciPy's nnls would cost every calibration the import
    of scipy.optimize: 0.3–1 s.)"""
    x, *_ = np.linalg.lstsq(A, b, rcond=None)
    if np.all(x >= 0):
        return x
    tries = [np.zeros(2)]
    for k in range(2):
        col = A[:, k]
        t = np.zeros(2)
        t[k] = max(float(col @ b) / float(col @ col), 0.0) if float(col @ col) > 0 else 0.0
        tries.append(t)
    return min(tries, key=lambda t: float(np.sum((A @ t - b) ** 2)))


def miss_model(robot: Robot, q: np.ndarray, res: np.ndarray, taken: float) -> tuple[float | None, tuple, float]:
    """What a prediction misses by at a new pose: σ_p (m per axis) and σ_q, one for every revolute joint's angle
    (rad; 0 for other joints), the miss per axis at joints q being σ_p² + σ_q² Σ_revolute |∂p/∂q_j|² / 3
    (isotropic: what the model leaves is not along the joints' motions alone, a geometric fit absorbs part of
    each), fitted to the residuals res (N, 3) at q (N, n) by non-negative least squares of their squared norms
    (``taken`` degrees of freedom given back). One σ_q, not one per joint: the residuals rarely tell the joints
    apart, and a σ of 0 for a joint they could not see made a check designed on it trust poses it should not.
    Also the dispersion of the whitened squared norms (their variance over 2·3, the Gaussian value; ≥ 1).
    None, (), 1 without enough samples."""
    if len(res) * 3 <= taken + robot.n_joints + 2:
        return None, (), 1.0
    Jq = robot.joint_jacobian(q)[:, :3, :]
    revolute = robot.revolute
    lever = np.sum(Jq**2, axis=1) * revolute  # (N, n): one σ for every revolute joint's angle
    A = np.stack([np.full(len(q), 3.0), lever.sum(axis=1)], axis=1)
    scale = np.where(A.max(axis=0) > 0, A.max(axis=0), 1.0)  # no revolute joint: 0
    x2 = nonnegative_2(A / scale, np.sum(res**2, axis=1))
    x2 = x2 / scale * (3 * len(q) / (3 * len(q) - taken))
    x = np.concatenate([x2[:1], np.where(revolute, x2[1], 0.0)])
    x[0] = max(x[0], FLOOR * float(np.mean(res**2)), 1e-18)  # never a pose without a miss (a singular whitening)
    w = np.sum(res**2, axis=1) / (x[0] + lever @ x[1:] / 3.0)
    disp = float(np.var(w) / 6.0) if len(w) > 2 else 1.0
    return float(np.sqrt(x[0])), tuple(float(v) for v in np.sqrt(x[1:])), max(1.0, disp)
