"""The 3-PUU translational parallel robot of the 3-PUU paper of 2024
("Error analysis model of parallel robot based on parameters identification", eq. 7–10), with an
extended parameter set.

Leg i (nominal direction φᵢ = 0°, 120°, 240°): a slider moves along a rail through the base point
Rᵢ·e(φᵢ + aᵢ) in direction uᵢ = (txᵢ, tyᵢ, 1)/‖·‖, at height hᵢ + h0ᵢ; a link of length Lᵢ joins it to
the platform point p + rᵢ·e(φᵢ + bᵢ) (e(θ) = (cos θ, sin θ, 0)). The platform only translates. The
constraint of leg i is fᵢ = ‖p + rᵢe(φᵢ+bᵢ) − Rᵢe(φᵢ+aᵢ) − (hᵢ+h0ᵢ)uᵢ‖² − Lᵢ² = 0.

Parameters: the base frame, the paper's five ``r R L1 L2 L3`` (eq. 10), and with ``extended`` per
leg ``leg<i>.dR leg<i>.dr`` (radius offsets), ``leg<i>.a leg<i>.b`` (base / platform angle offsets),
``leg<i>.h0`` (slider zero offset) and ``leg<i>.tx leg<i>.ty`` (rail tilt). Rᵢ = R + dRᵢ, rᵢ = r + drᵢ.
Inverse kinematics is closed form (the slider above the platform, the nominal assembly mode).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..errors import ModelError
from .implicit import ImplicitRobot
from .parameters import Parameters
from .joint_space import JointSpace
from .serial import BASE_NAMES

LEG_PARAMS = ("dR", "dr", "a", "b", "h0", "tx", "ty")
LINK_RISE = 0.25  # sin of the smallest link elevation (about 14.5 deg) kept in sampled poses
LEG_KINDS = ("length", "length", "angle", "angle", "length", "angle", "angle")


def puu3_names(extended: bool) -> tuple[list[str], list[str]]:
    names = list(BASE_NAMES) + ["r", "R", "L1", "L2", "L3"]
    kinds = ["length"] * 3 + ["angle"] * 3 + ["length"] * 5
    if extended:
        for i in range(1, 4):
            names += [f"leg{i}.{p}" for p in LEG_PARAMS]
            kinds += list(LEG_KINDS)
    return names, kinds


@dataclass(frozen=True, eq=False, repr=False)
class PUU3Robot(ImplicitRobot):
    """The 3-PUU translational parallel robot; its joints are the three slider heights h1, h2, h3 (m).

    Three legs, each a slider on a rail and a link to the platform, which only translates; the measured point
    is the platform's position, found from the three leg constraints (see the module docstring). Build one with
    :meth:`PUU3Robot.build` or load "puu3" / "puu3-extended".

    Parameters
    ----------
    name : str
        The robot's name.
    params : Parameters
        The base frame, ``r R L1 L2 L3`` (platform radius, base radius, link lengths, m) and, when
        ``extended``, per leg ``leg<i>.dR .dr .a .b .h0 .tx .ty``, in that order; SI units.
    h_lower : float
        Lower limit of every slider height, m.
    h_upper : float
        Upper limit of every slider height, m, above ``h_lower``.
    extended : bool, optional
        Whether the parameters include each leg's radius, angle, zero and rail-tilt offsets (default False:
        the paper's five).
    description : str, optional
        Free text (default "").
    phi : tuple of 3 float, optional
        The legs' nominal directions φᵢ, rad (default 0°, 120°, 240°).

    Attributes
    ----------
    joint_space : JointSpace
        The three prismatic sliders h1, h2, h3 with the limits above.

    Raises
    ------
    ModelError
        When the parameters do not match the layout, or ``h_lower`` is not below ``h_upper``.

    Examples
    --------
    >>> import numpy as np
    >>> from kincal.models import PUU3Robot
    >>> robot = PUU3Robot.build()
    >>> robot.joint_names, robot.params.names[6:], robot.structure
    (('h1', 'h2', 'h3'), ('r', 'R', 'L1', 'L2', 'L3'), 'puu3 (implicit)')
    >>> q = robot.sample_joints(3, seed=1)
    >>> p = robot.forward(q)  # the platform's positions, m
    >>> bool(np.allclose(robot.inverse(p), q, atol=1e-9))  # the closed-form inverse gives the sliders back
    True
    >>> PUU3Robot.build(extended=True).n_params
    32
    """

    name: str
    params: Parameters
    h_lower: float
    h_upper: float
    extended: bool = False
    description: str = ""
    phi: tuple[float, float, float] = (0.0, 2 * np.pi / 3, 4 * np.pi / 3)
    joint_space: JointSpace = field(init=False, repr=False)
    has_inverse: ClassVar[bool] = True

    def __post_init__(self) -> None:
        names, kinds = puu3_names(self.extended)
        if self.params.names != tuple(names) or self.params.kinds != tuple(kinds):
            raise ModelError(f"{self.name}: parameters do not match the 3-PUU layout ({', '.join(names)})")
        if not self.h_lower < self.h_upper:
            raise ModelError(f"{self.name}: slider limits must have lower < upper")
        object.__setattr__(self, "joint_space", JointSpace(("h1", "h2", "h3"), ("prismatic",) * 3,
                                                           [self.h_lower] * 3, [self.h_upper] * 3))

    @classmethod
    def build(cls, name: str = "puu3", r: float = 0.1, R: float = 0.2, L: float = 0.35,
              h_range: tuple[float, float] = (0.380, 0.835), extended: bool = False,
              values: dict | None = None, description: str = "") -> "PUU3Robot":
        """Build a 3-PUU robot from its nominal dimensions.

        Parameters
        ----------
        name : str, optional
            The robot's name (default "puu3").
        r : float, optional
            Platform radius, m (default 0.1).
        R : float, optional
            Base radius, m (default 0.2).
        L : float, optional
            Length of every link, m (default 0.35).
        h_range : tuple of 2 float, optional
            Lower and upper slider limits, m (default (0.380, 0.835)).
        extended : bool, optional
            Include each leg's offsets (default False).
        values : dict, optional
            Other parameter values by name, SI units (default: all 0 but r, R and the link lengths).
        description : str, optional
            Free text (default "").

        Returns
        -------
        PUU3Robot
            The robot, its base frame at the origin.

        Raises
        ------
        ModelError
            When ``values`` names an unknown parameter, or the limits are not valid.
        """
        names, kinds = puu3_names(extended)
        v = dict.fromkeys(names, 0.0)
        v.update({"r": r, "R": R, "L1": L, "L2": L, "L3": L})
        v.update(values or {})
        unknown = set(v) - set(names)
        if unknown:
            raise ModelError(f"{name}: unknown parameter(s) {sorted(unknown)}; known: {', '.join(names)}")
        return cls(name, Parameters(names, [v[n] for n in names], kinds), h_range[0], h_range[1], extended,
                   description)

    @property
    def structure(self) -> str:
        return "puu3 (implicit)"

    # ---- geometry -------------------------------------------------------------------------------
    def _legs(self, values: np.ndarray):
        """Per leg: platform offset, base point, rail direction (..., 3, 3), h0 and L (..., 3), and the
        pieces needed for derivatives. ``values`` is (P,) or one parameter vector per row, (N, P)."""
        v = np.asarray(values, dtype=float)
        g = lambda n: v[..., self.params.index(n)]  # noqa: E731  () or (N,)
        r, R = g("r")[..., None], g("R")[..., None]
        L = np.stack([g("L1"), g("L2"), g("L3")], axis=-1)
        if self.extended:
            leg = np.stack([np.stack([g(f"leg{i}.{p}") for p in LEG_PARAMS], axis=-1) for i in range(1, 4)], axis=-2)
        else:
            leg = np.zeros(v.shape[:-1] + (3, len(LEG_PARAMS)))
        dR, dr, a, b, h0, tx, ty = np.moveaxis(leg, -1, 0)  # each (..., 3)
        phi = np.asarray(self.phi)
        vec = lambda x, y, z=np.zeros_like(a): np.stack([x, y, z], axis=-1)  # noqa: E731
        ea, eb = vec(np.cos(phi + a), np.sin(phi + a)), vec(np.cos(phi + b), np.sin(phi + b))
        va, vb = vec(-np.sin(phi + a), np.cos(phi + a)), vec(-np.sin(phi + b), np.cos(phi + b))  # d e(θ)/dθ
        w = vec(tx, ty, np.ones_like(a))
        nv = np.linalg.norm(w, axis=-1)[..., None]
        u = w / nv
        du_dtx, du_dty = ((np.eye(3)[k] - u * u[..., k:k + 1]) / nv for k in (0, 1))
        plat = (r + dr)[..., None] * eb
        base = (R + dR)[..., None] * ea
        return plat, base, u, h0, L, (ea, eb, va, vb, du_dtx, du_dty, r + dr, R + dR)

    def _d(self, p: np.ndarray, q: np.ndarray, values: np.ndarray):
        plat, base, u, h0, L, extra = self._legs(values)
        t = q + h0  # slider travel along the rail, (N, 3)
        d = p[:, None, :] + plat - base - t[:, :, None] * u  # (N, 3 legs, 3)
        return d, t, u, L, extra

    def constraints(self, p, q, values):
        d, _, _, L, _ = self._d(p, q, values)
        return np.einsum("nij,nij->ni", d, d) - L**2

    def constraint_derivatives(self, p, q, values):
        d, t, u, L, (ea, eb, va, vb, du_dtx, du_dty, ri, Ri) = self._d(p, q, values)
        n = p.shape[0]
        fp = 2.0 * d
        dot = lambda x: np.sum(d * x, axis=-1)  # noqa: E731  d·x per leg, (N, 3)
        du = dot(u)
        fq, legs = np.zeros((n, 3, 3)), [0, 1, 2]
        fq[:, legs, legs] = -2.0 * du
        fs = np.zeros((n, 3, self.n_params))
        ix = self.params.index
        d_eb, d_ea = dot(eb), dot(ea)
        fs[:, :, ix("r")] = 2.0 * d_eb
        fs[:, :, ix("R")] = -2.0 * d_ea
        fs[:, legs, self.params.indices(("L1", "L2", "L3"))] = -2.0 * L
        if self.extended:
            for name, x in (("dr", d_eb), ("dR", -d_ea), ("b", ri * dot(vb)), ("a", -Ri * dot(va)), ("h0", -du),
                            ("tx", -t * dot(du_dtx)), ("ty", -t * dot(du_dty))):
                fs[:, legs, self.params.indices(f"leg{i}.{name}" for i in (1, 2, 3))] = 2.0 * x
        return fp, fq, fs

    def start_point(self, q, values):
        plat, base, _, h0, L, _ = self._legs(values)
        rho = np.linalg.norm(base - plat, axis=-1).mean(axis=-1)
        z = (q + h0).mean(axis=1) - np.sqrt(np.maximum(L.mean(axis=-1) ** 2 - rho**2, 1e-12))
        return np.column_stack([np.zeros(q.shape[0]), np.zeros(q.shape[0]), z])

    def assembly_mode(self, p, q, values):
        """The platform hangs below its three sphere centres cᵢ = sliderᵢ − platform offsetᵢ; the other
        solution is the mirror image across their plane, so reflect any solution found above it."""
        plat, base, u, h0, _, _ = self._legs(values)
        c = base + (q + h0)[:, :, None] * u - plat  # (N, 3, 3) sphere centres
        n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        n *= np.sign(n[:, 2:3])  # upward normal
        h = np.einsum("ni,ni->n", p - c[:, 0], n)
        return p - 2.0 * np.maximum(h, 0.0)[:, None] * n

    def in_working_mode(self, p, q, values):
        """Every link rises from its platform point to its slider (the inverse's branch), at least
        ``LINK_RISE`` of its length: nearly horizontal links sit at the workspace boundary, where the
        inverse loses its solution under millimetre parameter changes."""
        d, _, u, L, _ = self._d(p, q, values)
        return np.all(-np.sum(d * u, axis=-1) > LINK_RISE * L, axis=1)

    def inverse_local(self, p, values, strict=True):
        """Slider heights for platform positions p (N, 3): the root with the slider above the platform."""
        plat, base, u, h0, L, _ = self._legs(values)
        w = np.asarray(p, float)[..., None, :] + plat - base  # (..., N, legs, 3)
        wu = np.sum(w * u, axis=-1)
        disc = wu**2 - np.einsum("...ij,...ij->...i", w, w) + L**2
        if not strict:
            with np.errstate(invalid="ignore"):
                return np.where(disc >= 0, wu + np.sqrt(np.maximum(disc, 0.0)), np.nan) - h0
        if np.any(disc < 0):
            k = int(np.flatnonzero(np.any(disc < 0, axis=1))[0])
            raise ModelError(f"{self.name}: position {np.array2string(np.asarray(p)[k], precision=6)} m is out of "
                             f"reach of the links (row {k}); check the targets and their units")
        return wu + np.sqrt(disc) - h0
