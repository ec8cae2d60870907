"""The Stewart–Gough platform (6-UPS / 6-SPS hexapod): six legs of variable length join six base
points to six platform points; the unknown of its forward kinematics is the platform's whole pose.

Leg i (1..6) joins the base point bᵢ (robot frame) to the platform point pᵢ (platform frame). With the
platform pose (R, t) its length is ‖R pᵢ + t − bᵢ‖ = zeroᵢ + scaleᵢ · leadᵢ · qᵢ: qᵢ is the actuator's
reading, a length (m) for a prismatic actuator (lead 1) or a motor angle (rad; files may give
revolutions, ``rev``) for a revolute one, whose nominal travel per radian is leadᵢ (m/rad: the
robot file states it per revolution); ``zero`` is the leg's length at reading 0 and ``scale`` the
ratio of its true travel to the nominal one (1 nominal). The measured point is the tool point
``tool.x/y/z`` in the platform frame; a 6-D measurement sees the platform's frame.

Parameters: the base frame (the measurement frame's view of the robot frame), then per leg
``leg<i>.bx by bz`` and ``leg<i>.px py pz`` (m), ``leg<i>.zero`` (m) and ``leg<i>.scale`` (ratio),
with ``compliance`` also ``legs.compliance`` (m), then ``tool.x tool.y tool.z`` (m).

Compliance (the error model ``compliance``, or ``compliance:`` in the robot file): the legs give under
the platform's weight. The axial loads f (N, 6), in platform weights (compression positive), hold the
weight at the centre of the platform points p̄ against gravity along −z of the measurement frame (a
tracker or motion capture set up z up): Jᵀ f = (up, 0), J with the rows (uᵢ, R (pᵢ − p̄) × uᵢ). Neither
the design frames' choice (gauge freedoms) nor the base frame's changes the loads a pose puts on the legs.
A leg under load f is shorter by c·f,
c = ``legs.compliance`` (the give of a leg carrying the whole weight), so the constraint reads
‖R pᵢ + t − bᵢ‖ − Lᵢ(q) + c fᵢ = 0. On the Jugglebot hexapod (two sessions) this one parameter brings
the held-out error from 0.61 to 0.54 mm and from 1.23 to 0.94 mm the other way; a compliance per leg, a
centre of mass off the origin or offsets of the joints do worse on the other session.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar, Sequence

import numpy as np

from .._frozen import freeze_arrays
from ..errors import ModelError
from .implicit import ImplicitRobot, twist_exp
from .parameters import Parameters
from .joint_space import JointSpace
from .robot import TOOL_NAMES, Robot
from .serial import BASE_NAMES
from .transforms import kabsch

LEG_NAMES = ("bx", "by", "bz", "px", "py", "pz", "zero", "scale")
LEG_KINDS = ("length",) * 7 + ("ratio",)
N_LEGS = 6
RELABEL_MARGIN = 0.05  # m: a leg whose points lie this much nearer another leg's drawing than its own was relabelled
COMPLIANCE = "legs.compliance"  # m: a leg's give under the platform's whole weight


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b over the last axis (broadcast): np.cross without its axis handling, which dominates small batches."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def stewart_names(n_legs: int = N_LEGS, compliance: bool = False) -> tuple[list[str], list[str]]:
    """The parameter names and kinds of a platform with ``n_legs`` legs (and its legs' compliance)."""
    names, kinds = list(BASE_NAMES), ["length"] * 3 + ["angle"] * 3
    for i in range(1, n_legs + 1):
        names += [f"leg{i}.{p}" for p in LEG_NAMES]
        kinds += LEG_KINDS
    extra = [COMPLIANCE] if compliance else []
    return names + extra + list(TOOL_NAMES), kinds + ["length"] * (len(extra) + 3)


@dataclass(frozen=True, eq=False, repr=False)
class StewartRobot(ImplicitRobot):
    """A 6-UPS / 6-SPS hexapod; joints are the six legs' actuators (lengths, m, or motor angles, rad)."""

    name: str
    params: Parameters
    leg_lower: np.ndarray
    leg_upper: np.ndarray
    lead: np.ndarray  # (6,) nominal travel per joint unit: 1 (a length reading) or m/rad (a motor angle)
    motor: bool = False  # legs read as motor angles (revolute joints), else as lengths (prismatic)
    description: str = ""
    compliance: bool = False  # the legs give under the platform's weight (``legs.compliance``)
    joint_space: JointSpace = field(init=False, repr=False)
    UNKNOWN: ClassVar[str] = "pose"
    has_pose_inverse: ClassVar[bool] = True  # (not of positions: the legs need the platform's whole pose)
    has_load_compliance: ClassVar[bool] = True

    def __post_init__(self) -> None:
        names, kinds = stewart_names(compliance=self.compliance)
        if self.params.names != tuple(names) or self.params.kinds != tuple(kinds):
            raise ModelError(f"{self.name}: parameters do not match the hexapod layout ({', '.join(names[:14])}, …)")
        lead = np.array(self.lead, float).reshape(-1)
        if lead.shape != (N_LEGS,) or not np.all(np.isfinite(lead) & (lead > 0)):
            raise ModelError(f"{self.name}: each of the 6 legs needs a positive lead (travel per joint unit), got "
                             f"{self.lead!r}")
        lead.setflags(write=False)
        object.__setattr__(self, "lead", lead)
        if not self.motor and not np.all(lead == 1.0):
            raise ModelError(f"{self.name}: legs read as lengths have no lead (travel per unit 1); motor readings "
                             f"(motor=True) do")
        kind = "revolute" if self.motor else "prismatic"
        object.__setattr__(self, "joint_space", JointSpace([f"leg{i}" for i in range(1, N_LEGS + 1)],
                                                           (kind,) * N_LEGS, self.leg_lower, self.leg_upper))
        freeze_arrays(self)  # its arrays read-only: what it holds cannot be edited in place

    @classmethod
    def build(cls, name: str, base_points: Sequence, platform_points: Sequence, zero: Sequence[float],
              leg_range: tuple[Sequence[float], Sequence[float]], lead: Sequence[float] | None = None,
              description: str = "") -> "StewartRobot":
        """A hexapod from its design: base points (6, 3) m in the robot frame, platform points (6, 3) m
        in the platform frame, leg lengths at reading 0 (6,) m, the readings' range (lower, upper) (6,)
        each, and ``lead``: None for legs read as lengths (m), else each revolute actuator's nominal
        travel per radian (6,) m/rad; scales 1, tool point at the platform frame's origin."""
        b, p = np.asarray(base_points, float), np.asarray(platform_points, float)
        z = np.asarray(zero, float).reshape(-1)
        if b.shape != (N_LEGS, 3) or p.shape != (N_LEGS, 3) or z.shape != (N_LEGS,):
            raise ModelError(f"{name}: a hexapod needs 6 base points, 6 platform points (x, y, z each) and 6 leg "
                             f"lengths; got {b.shape}, {p.shape} and {z.shape}")
        names, kinds = stewart_names()
        v = dict.fromkeys(names, 0.0)
        for i in range(N_LEGS):
            v.update(zip((f"leg{i + 1}.{k}" for k in LEG_NAMES), (*b[i], *p[i], z[i], 1.0)))
        lo, hi = (np.asarray(x, float).reshape(-1) * np.ones(N_LEGS) for x in leg_range)
        return cls(name, Parameters(names, [v[n] for n in names], kinds), lo, hi,
                   np.ones(N_LEGS) if lead is None else np.asarray(lead, float), lead is not None, description)

    @property
    def structure(self) -> str:
        return "stewart (implicit, 6-D)"

    @property
    def motor_leads(self) -> np.ndarray:
        """(6,) m per rad: legs read as motor angles drive their travel through ``lead`` (NaN for lengths)."""
        return self.lead if self.motor else np.full(N_LEGS, np.nan)

    def reading_terms(self) -> str:
        return "the legs' zeros and scales"

    def correction_hint(self, calibrated: Robot) -> str:
        """Legs the calibration put where other legs are drawn (base and platform points each nearer another leg's
        than their own by more than ``RELABEL_MARGIN``, each set of points moved rigidly onto the drawing first: where
        the design frames stand among them is a gauge freedom, held where the fit chose): the joint columns in
        another order, a relabelling the fit follows (the model then commands each leg by another's column)."""
        mine, theirs = self._anchors(self.params.values), self._anchors(calibrated.params.values)
        for at in (slice(0, 3), slice(3, 6)):  # the base points, the platform points
            R, t = kabsch(theirs[:, at], mine[:, at])
            theirs[:, at] = theirs[:, at] @ R.T + t
        gap = np.linalg.norm(theirs[:, None] - mine[None], axis=2)  # (calibrated leg, drawn leg)
        moved = [(i, int(np.argmin(gap[i]))) for i in range(N_LEGS)
                 if gap[i].min() + RELABEL_MARGIN < gap[i, i]]
        if not moved:
            return ""
        pairs = ", ".join(f"leg{i + 1} where leg{j + 1} is drawn" for i, j in moved)
        return (f"; the calibration put {pairs}: the leg columns are read in another order than the robot file's "
                f"legs (--joint-cols names them in its order: leg1 … leg6)")

    def _anchors(self, values: np.ndarray) -> np.ndarray:
        """(6, 6) each leg's base and platform points, m."""
        names = [f"leg{i}.{k}" for i in range(1, N_LEGS + 1) for k in ("bx", "by", "bz", "px", "py", "pz")]
        return values[self.params.indices(names)].reshape(N_LEGS, 6)

    def frame_freedoms(self) -> tuple[tuple[str, tuple[str, ...], int], ...]:
        """The robot frame among the base points, and the platform frame among the platform points (with
        the tool point and a 6-D target's rotation): each may stand anywhere, the legs' lengths alike."""
        legs = range(1, N_LEGS + 1)
        return (("where the robot frame stands among the base points", BASE_NAMES + tuple(
                    f"leg{i}.b{c}" for i in legs for c in "xyz"), 6),
                ("where the platform frame stands among the platform points and the target", TOOL_NAMES + tuple(
                    f"leg{i}.p{c}" for i in legs for c in "xyz") + ("target.rx", "target.ry", "target.rz"), 6))

    def mounting_params(self) -> tuple[str, ...]:
        """The base and platform points and the legs' zero lengths: a hexapod's design frames are not the
        frames it is measured in, and a leg's length at reading 0 is set where its actuator is homed; and
        the legs' compliance, which is the drive's (belts, servo stiffness), not a small error of a drawing."""
        legs = tuple(f"leg{i}.{k}" for i in range(1, N_LEGS + 1) for k in LEG_NAMES[:7])
        return legs + ((COMPLIANCE,) if self.compliance else ())

    def with_load_compliance(self) -> "StewartRobot":
        """The hexapod with ``legs.compliance`` (0 to start; itself if it has it)."""
        if self.compliance:
            return self
        names = stewart_names(compliance=True)[0]
        values = {**self.params.as_dict(), COMPLIANCE: 0.0}
        return dataclasses.replace(self, compliance=True, params=Parameters(
            names, [values[n] for n in names], stewart_names(compliance=True)[1]))

    # ---- geometry ---------------------------------------------------------------------------------
    def _legs(self, values: np.ndarray):
        """Base points, platform points (…, 6, 3), zero lengths and scales (…, 6) of ``values`` (P,) or (N, P)."""
        v = np.asarray(values, dtype=float)
        leg = v[..., 6:6 + 8 * N_LEGS].reshape(v.shape[:-1] + (N_LEGS, 8))
        return leg[..., 0:3], leg[..., 3:6], leg[..., 6], leg[..., 7]

    def _vectors(self, x: np.ndarray, values: np.ndarray):
        """Leg vectors d = R p + t − b (N, 6, 3), their lengths (N, 6) and R p (N, 6, 3)."""
        b, p, _, _ = self._legs(values)
        Rp = p @ x[:, :, :3].transpose(0, 2, 1)  # (N, 6, 3): each platform point turned
        d = Rp + x[:, None, :, 3] - b
        return d, np.linalg.norm(d, axis=-1), Rp

    def _lengths(self, q: np.ndarray, values: np.ndarray) -> np.ndarray:
        _, _, zero, scale = self._legs(values)
        return zero + scale * self.lead * q

    def _give(self, values: np.ndarray) -> np.ndarray:
        """The legs' compliance c (m; (…, 1) for values (…, P)); 0 without the term."""
        v = np.asarray(values, dtype=float)
        return v[..., [self.params.index(COMPLIANCE)]] if self.compliance else np.zeros(v.shape[:-1] + (1,))

    def _up(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Up (+z of the measurement frame) in the robot frame, (…, 3), and its derivatives by the base
        rotations rx, ry, rz (…, 3, 3): each turns the robot frame about a world axis aₖ, so up moves by
        −R_bᵀ (aₖ × e_z)."""
        v = np.asarray(values, dtype=float)
        Rb = self._base(v)[0]
        ry, rz = v[..., self.params.index("base.ry")], v[..., self.params.index("base.rz")]
        axes = np.stack([np.stack([np.cos(rz) * np.cos(ry), np.sin(rz) * np.cos(ry), -np.sin(ry)], -1),
                         np.stack([-np.sin(rz), np.cos(rz), 0.0 * rz], -1), np.broadcast_to([0.0, 0.0, 1.0], ry.shape
                                                                                             + (3,))], -1)
        across = np.stack([axes[..., 1, :], -axes[..., 0, :], np.zeros_like(axes[..., 0, :])], -2)  # aₖ × e_z
        return Rb[..., 2, :], -np.swapaxes(Rb, -1, -2) @ across

    def _loads(self, x: np.ndarray, u: np.ndarray, values: np.ndarray):
        """The legs' axial loads f (N, 6) in platform weights (module docstring), with Jᵀ (N, 6, 6), the
        arms m = R (pᵢ − p̄) (N, 6, 3) about the platform points' centre (where the weight acts: no design
        frame's choice moves it) and up (N, 3) in the robot frame."""
        _, p, _, _ = self._legs(values)
        m = (p - p.mean(axis=-2, keepdims=True)) @ x[:, :, :3].transpose(0, 2, 1)
        JT = np.concatenate([u, _cross(m, u)], axis=2).transpose(0, 2, 1)
        up = np.broadcast_to(self._up(values)[0], (len(u), 3))
        return np.linalg.solve(JT, np.concatenate([up, np.zeros((len(u), 3))], axis=1)[..., None])[..., 0], JT, m, up

    def _load_rates(self, x, u, length, Rp, values, params: bool = True):
        """The loads f (N, 6) and their derivatives: by the twist (N, 6, 6) and, with ``params``, by each leg's
        base and platform point (N, 6, 6, 3) each (load j by leg i's coordinate a) and by the base rotations
        (N, 6, 3), from Jᵀ df = dw − Σᵢ fᵢ d(row i), the rows (uᵢ, mᵢ × uᵢ) and the wrench w = (up, 0)."""
        n = len(u)
        f, JT, m, up = self._loads(x, u, values)
        P = (np.eye(3) - u[..., :, None] * u[..., None, :]) / length[..., None, None]  # du = P dd
        E, zero = np.broadcast_to(np.eye(3), (n, N_LEGS, 3, 3)), np.zeros((n, N_LEGS, 3, 3))

        def rows(dd, dm):  # changes (N, 6, D, 6) of each leg's row, weighted by its load, for dd, dm (N, 6, D, 3)
            du = np.einsum("nkij,nkaj->nkai", P, dd)
            return f[:, :, None, None] * np.concatenate([du, _cross(dm, u[:, :, None]) + _cross(
                m[:, :, None], du)], axis=3)

        def turned(w):  # eₐ × wᵢ (N, 6, 3, 3)
            return _cross(np.eye(3)[None, None], w[:, :, None, :])

        def solve(g):  # −(Jᵀ)⁻¹ g for changes g (N, D, 6) → (N, 6, D)
            return -np.linalg.solve(JT, g.reshape(n, -1, 6).transpose(0, 2, 1))
        by_x = solve(rows(np.concatenate([E, turned(Rp)], 2), np.concatenate([zero, turned(m)], 2)).sum(1))
        if not params:  # what Newton's method needs
            return f, by_x
        R_e = np.moveaxis(x[:, :, :3], 1, 2)  # [n, a] = R eₐ
        dp = rows(np.broadcast_to(R_e[:, None], E.shape), np.broadcast_to(R_e[:, None], E.shape))
        dp[..., 3:] -= _cross(R_e, up[:, None])[:, None] / N_LEGS  # p̄ moves too: Σᵢ fᵢ uᵢ = up
        dw = np.zeros((n, 6, 3))
        dw[:, :3] = self._up(values)[1]

        return (f, by_x, solve(rows(-E, zero)).reshape(n, N_LEGS, N_LEGS, 3),
                solve(dp).reshape(n, N_LEGS, N_LEGS, 3), np.linalg.solve(JT, dw))

    def constraints(self, x, q, values):
        d, length, Rp = self._vectors(x, values)
        if not self.compliance:
            return length - self._lengths(q, values)
        return length - self._lengths(q, values) + self._give(values) * self._loads(x, d / length[..., None], values)[0]

    def constraint_jacobian(self, x, q, values):
        d, length, Rp = self._vectors(x, values)
        u = d / length[..., None]
        fx = np.concatenate([u, _cross(Rp, u)], axis=2)  # by (dt, δ): d moves by dt + δ × R p
        if not self.compliance:
            return fx
        return fx + self._give(values)[..., None] * self._load_rates(x, u, length, Rp, values, params=False)[1]

    def constraint_derivatives(self, x, q, values):
        d, length, Rp = self._vectors(x, values)
        u = d / length[..., None]
        n = x.shape[0]
        fx = np.concatenate([u, _cross(Rp, u)], axis=2)
        _, _, _, scale = self._legs(values)
        legs = np.arange(N_LEGS)
        fq = np.zeros((n, N_LEGS, N_LEGS))
        fq[:, legs, legs] = -np.broadcast_to(scale * self.lead, (n, N_LEGS))
        fs = np.zeros((n, N_LEGS, self.n_params))
        cols = 6 + 8 * legs[:, None] + np.arange(8)  # (6, 8): each leg's columns
        fs[:, legs[:, None], cols[:, 0:3]] = -u
        fs[:, legs[:, None], cols[:, 3:6]] = np.einsum("nkj,nji->nki", u, x[:, :, :3])  # uᵀ R
        fs[:, legs, cols[:, 6]] = -1.0
        fs[:, legs, cols[:, 7]] = -self.lead * q
        if self.compliance:
            c = self._give(values)[..., None]  # (…, 1, 1)
            f, fdx, fdb, fdp, fdr = self._load_rates(x, u, length, Rp, values)
            fx = fx + c * fdx
            fs[:, :, cols[:, 0:3]] += c[..., None] * fdb
            fs[:, :, cols[:, 3:6]] += c[..., None] * fdp
            fs[:, :, self.params.indices(BASE_NAMES[3:])] = c * fdr
            fs[:, :, self.params.index(COMPLIANCE)] = f
        return fx, fq, fs

    def start_point(self, q, values):
        """The platform parallel to the base, over the base points' centre, at the mean height the legs reach."""
        b, p, _, _ = self._legs(values)
        L = self._lengths(q, values)
        b, p = np.broadcast_to(b, L.shape + (3,)), np.broadcast_to(p, L.shape + (3,))
        xy = b[..., :2].mean(axis=-2) - p[..., :2].mean(axis=-2)  # (N, 2)
        flat = p[..., :2] + xy[:, None] - b[..., :2]
        h = np.sqrt(np.maximum(L**2 - np.sum(flat**2, axis=-1), 0.0)) - p[..., 2] + b[..., 2]
        t = np.column_stack([xy, h.mean(axis=1)])
        return np.concatenate([np.broadcast_to(np.eye(3), (len(t), 3, 3)), t[:, :, None]], axis=2)

    def in_working_mode(self, x, q, values):
        """The platform above the base (the legs' upper assembly, the one the start leads to), not turned over."""
        return (x[:, 2, 3] > 0.0) & (x[:, 2, 2] > 0.0)

    def inverse_local(self, x, values, strict=True):
        """Leg readings (N, 6) (m or rad) for platform poses x (N, 3, 4) in the robot frame: closed form,
        each leg's length through its zero, scale and lead."""
        _, _, zero, scale = self._legs(values)
        d, length, Rp = self._vectors(x, values)
        give = self._give(values) * self._loads(x, d / length[..., None], values)[0] if self.compliance else 0.0
        return (length + give - zero) / (scale * self.lead)

    def sample_joints(self, n: int, seed: int | None = 0, max_tries: int = 50) -> np.ndarray:
        """n leg readings (n, 6) of platform poses drawn uniformly around the pose at mid-range legs
        (translations within half a leg stroke, turns within the stroke over the platform's radius) and
        mapped to the legs in closed form, kept where every leg is inside its range and the platform
        assembles in the working mode: every sampled configuration exists."""
        rng = np.random.default_rng(seed)
        v = self.params.values
        mid = 0.5 * (self.lower + self.upper)[None]
        home = self._solve_local(mid, v)[0]
        _, p, zero, scale = self._legs(v)
        stroke = float(np.min(scale * self.lead * (self.upper - self.lower)))
        turn = stroke / max(float(np.max(np.linalg.norm(p, axis=1))), 1e-9)
        kept, have = [], 0
        for _ in range(max_tries):
            m = max(4 * (int(n) - have), 64)
            x = np.concatenate([twist_exp(rng.uniform(-0.5, 0.5, (m, 3)) * turn) @ home[:, :, :3],
                                (home[:, :, 3] + rng.uniform(-0.5, 0.5, (m, 3)) * stroke)[:, :, None]], axis=2)
            q = self.inverse_local(x, v)
            q = q[self.within_limits(q)]
            q = q[self.feasible(q)] if len(q) else q
            kept.append(q)
            have += len(q)
            if have >= n:
                return np.concatenate(kept)[:int(n)]
        raise ModelError(f"{self.name}: only {have} of {n} platform poses drawn around mid-range legs keep every leg "
                         f"inside its range; check the leg ranges and the geometry")
