"""Batched kinematic chains of elementary motions, with analytic parameter Jacobians.

A chain is a sequence of elementary operations, each a rotation about or a translation along one
axis of the current frame, by a parameter value plus (optionally) a joint value. Any serial model
(DH, modified DH, Hayati β, base frame, tool point) is such a sequence, so one mechanism computes
the position and every Jacobian column:

* rotation about unit axis u through point o:  ∂p/∂angle = u × (p − o)
* translation along unit axis u:               ∂p/∂length = u

The ops are cut into segments: the ops before the first joint, then one segment per joint (its
joint op and the constant ops after it). Each segment's constant part is composed once per call
(scalar work, ~40 ops), so the batched work per joint is a mix of two frame axes by cos/sin of the
joint value and one small BLAS product. Arrays are laid out component-first, (3, N), so every
batched step is a contiguous vector operation; no Python loop runs over configurations.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from math import cos, prod, sin

import numpy as np

from ..errors import ModelError

ROT, TRANS = "R", "T"
AXES = {"x": 0, "y": 1, "z": 2}
BLOCK = 2048  # configurations per block of the parameter Jacobian (~3 MB of intermediates for a 6-axis arm)


@dataclass(frozen=True)
class Op:
    """One elementary motion of a chain: a rotation about, or a translation along, one local axis.

    The motion is by ``offset + values[param]``, plus ``q[:, joint]`` for a joint op.

    Parameters
    ----------
    motion : str
        "R" (a rotation, rad) or "T" (a translation, m).
    axis : int
        The axis of the current frame: 0 (x), 1 (y) or 2 (z).
    param : int
        Index of the parameter whose value the motion adds; -1 for a constant motion by ``offset`` alone
        (e.g. a URDF fixed joint, or the alignment of a joint axis).
    joint : int, optional
        Index of the joint whose value the motion adds (default -1: no joint).
    offset : float, optional
        A constant added to the motion, rad or m (default 0).

    Examples
    --------
    >>> from kincal.models import Op
    >>> Op("R", 2, 1, joint=0)  # about z by values[1] + q[:, 0]
    Op(motion='R', axis=2, param=1, joint=0, offset=0.0)
    """

    motion: str
    axis: int
    param: int
    joint: int = -1
    offset: float = 0.0


def cos_sin(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin from one tan(x/2): NumPy's float64 cos and sin are scalar libm calls on CPUs
    without AVX-512 and dominate FK time; one call instead of two. Accurate to a few ulp."""
    t = np.tan(0.5 * x)
    t2 = t * t
    inv = 1.0 / (1.0 + t2)
    return (1.0 - t2) * inv, (2.0 * inv) * t


def _carve(n: int, *shapes: tuple[int, ...]) -> list[np.ndarray]:
    """Views of shapes ``shape + (n,)`` cut from one block (one allocation instead of many)."""
    sizes = [prod(sh) * n for sh in shapes]
    parts = np.split(np.empty(sum(sizes)), np.cumsum(sizes)[:-1])
    return [part.reshape(*sh, n) for part, sh in zip(parts, shapes)]


@lru_cache(maxsize=64)
def compiled(ops: tuple[Op, ...], n_params: int, n_joints: int) -> "Chain":
    """The chain of ``ops``, compiled once per structure: a robot with new parameter values (every
    step of a fit) keeps its chain, which reads the values at each call and is never changed."""
    return Chain(ops, n_params, n_joints)


class Chain:
    """A compiled sequence of elementary motions: positions and analytic Jacobians, batched.

    The ops are cut into segments, each joint op and the constant ops after it, so one call costs a few small
    products per joint (see the module docstring).

    Parameters
    ----------
    ops : tuple of Op
        The motions from the base to the end point. The chain starts with a constant segment: at least one op
        comes before the first joint op.
    n_params : int
        Length P of the value vectors the chain reads (parameters that no op uses get zero Jacobian columns).
    n_joints : int
        Number n of joints; each joint drives exactly one op.

    Raises
    ------
    ModelError
        When a joint drives no op or several, or a joint op has no parameter (its zero offset).

    Examples
    --------
    A lift of ``values[0]`` along z, a turn of ``values[1] + q`` about z, then an arm of ``values[2]`` along x:

    >>> import numpy as np
    >>> from kincal.models import Chain, Op
    >>> chain = Chain((Op("T", 2, 0), Op("R", 2, 1, joint=0), Op("T", 0, 2)), n_params=3, n_joints=1)
    >>> values, q = np.array([0.1, 0.0, 0.5]), np.array([[0.0], [np.pi / 2]])
    >>> np.round(chain.forward(values, q), 6) + 0.0
    array([[0.5, 0. , 0.1],
           [0. , 0.5, 0.1]])
    >>> p, J = chain.forward_and_jacobian(values, q)
    >>> np.round(J[1], 6) + 0.0  # rows x y z, columns the three values
    array([[ 0. , -0.5,  0. ],
           [ 0. ,  0. ,  1. ],
           [ 1. ,  0. ,  0. ]])
    """

    def __init__(self, ops: tuple[Op, ...], n_params: int, n_joints: int) -> None:
        joint_ops = [k for k, op in enumerate(ops) if op.joint >= 0]
        joints = [ops[k].joint for k in joint_ops]
        if sorted(joints) != list(range(n_joints)):
            raise ModelError(f"chain: every joint must drive exactly one op, got joints {joints} for {n_joints}")
        if any(ops[k].param < 0 for k in joint_ops):
            raise ModelError("chain: every joint op needs a parameter (its zero offset)")
        bounds = [0] + joint_ops + [len(ops)]
        # segment 0: ops before the first joint; segment s: joint op and the constant ops after it
        self.segments = [tuple(ops[bounds[s]:bounds[s + 1]]) for s in range(len(bounds) - 1)]
        self.heads = [seg[0] if seg[0].joint >= 0 else None for seg in self.segments]
        self.ops = tuple(ops)  # the segments in order
        self.cols = np.array([op.param for op in self.ops])
        self.is_trans = np.array([op.motion == TRANS for op in self.ops])
        self.n_params, self.n_joints = n_params, n_joints
        self.unused = np.setdiff1d(np.arange(n_params), self.cols)
        # Rows of the per-segment product, for segment s: the axes of its ops, the next frame's axes
        # (rows of Rᵀ), the points of its rotation ops, the next origin (t). Points and origin are
        # contiguous so one addition shifts them by the segment's origin. z_map picks the rows from
        # concat([A, B, ends]).
        n_ops = len(self.ops)
        self.rot_idx = np.flatnonzero(~self.is_trans)
        z_map: list[int] = []
        z_slices: list[tuple[int, int, int, int]] = []
        z_points: list[int] = []
        axis_row = np.empty(n_ops, dtype=int)  # the row of each op's axis
        for s, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
            lo, rot = len(z_map), [m for m in range(a, b) if not self.is_trans[m]]
            axis_row[a:b] = range(lo, lo + b - a)
            z_map += list(range(a, b)) + [2 * n_ops + 4 * s + r for r in range(3)]
            p0 = len(z_map)
            z_points += range(p0, p0 + len(rot))
            z_map += [n_ops + m for m in rot] + [2 * n_ops + 4 * s + 3]
            z_slices.append((lo, lo + b - a, p0, len(z_map)))
        self.z_map, self.z_slices, self.z_rows = np.array(z_map), z_slices, len(z_map)
        self.z_points = np.array(z_points, dtype=int)
        self.z_rot_axes, self.z_trans_axes = axis_row[self.rot_idx], axis_row[self.is_trans]
        self.cols_rot = self.cols[self.rot_idx]
        self.cols_trans = self.cols[self.is_trans]
        self.rot_keep = np.flatnonzero(self.cols_rot >= 0)  # constant ops have no column
        self.trans_keep = np.flatnonzero(self.cols_trans >= 0)
        self.all_ops_have_params = bool(np.all(self.cols >= 0))
        self.head_joint = np.array([h.joint for h in self.heads if h is not None])
        self.head_param = np.array([h.param for h in self.heads if h is not None])
        self.head_offset = np.array([h.offset for h in self.heads if h is not None])
        self.joint_param = np.array([ops[k].param for k in sorted(joint_ops, key=lambda k: ops[k].joint)])
        for value in vars(self).values():  # its index arrays read-only: an edit would move every position it gives
            if isinstance(value, np.ndarray):
                value.setflags(write=False)

    def _segment_frames(self, values: np.ndarray, record: bool):
        """Constant part of each segment as [Rᵀ; t] (4, 3); with ``record`` also each op's axis
        and point in its segment's start coordinates, (n_ops, 3) each. Scalar Python: ~40 ops."""
        ends, axes, points = [], [], []
        for seg, head in zip(self.segments, self.heads):
            cols = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]  # frame axes, start coordinates
            t = [0.0, 0.0, 0.0]
            for op in seg:
                if record:
                    axes.append(list(cols[op.axis]))
                    points.append(list(t))
                if op is head:
                    continue
                v = op.offset + (float(values[op.param]) if op.param >= 0 else 0.0)
                if v == 0.0:
                    continue
                u = cols[op.axis]
                if op.motion == TRANS:
                    t = [t[0] + v * u[0], t[1] + v * u[1], t[2] + v * u[2]]
                else:
                    c, s = cos(v), sin(v)
                    i, j = (op.axis + 1) % 3, (op.axis + 2) % 3
                    a, b = cols[i], cols[j]
                    cols[i] = [c * a[0] + s * b[0], c * a[1] + s * b[1], c * a[2] + s * b[2]]
                    cols[j] = [c * b[0] - s * a[0], c * b[1] - s * a[1], c * b[2] - s * a[2]]
            ends.append(np.array(cols + [t]))  # [Rᵀ; t], (4, 3): the segment's constant part
        return ends, np.array(axes), np.array(points)

    def forward(self, values: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Positions (N,3): the end point carried backwards through the chain."""
        n = q.shape[0]
        ends, _, _ = self._segment_frames(values, False)
        qt = q.T
        V: np.ndarray | None = None  # (3, N) position in the current frame; None while it is the origin
        for M, head in zip(reversed(ends), reversed(self.heads)):
            V = M[3][:, None] if V is None else M[:3].T @ V + M[3][:, None]
            if head is None:
                continue
            x = qt[head.joint] + (values[head.param] + head.offset)
            V = np.broadcast_to(V, (3, n))
            if head.motion == TRANS:
                V = V + np.outer(np.eye(3)[head.axis], x)
            else:
                c, s = cos_sin(x)
                i, j = (head.axis + 1) % 3, (head.axis + 2) % 3
                V = np.array(V)  # a copy, turned in place
                V[i], V[j] = c * V[i] - s * V[j], s * V[i] + c * V[j]
        assert V is not None  # a chain has at least one segment
        return np.ascontiguousarray(np.broadcast_to(V, (3, n)).T)

    def forward_and_jacobian(self, values: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (N,3) and parameter Jacobian (N,3,P) by forward propagation of frames.

        For each segment, one BLAS product of a stacked constant matrix with the frame just after
        its joint op gives the world axes of all its ops, the world points of its rotation ops and
        the next segment's frame and origin. Then one batched cross product u × (p − o) makes every
        rotation column; translation columns are the axes themselves. Intermediates live in one block
        written in place: many small temporaries make glibc return and re-fault heap pages on every
        call, which costs more than the arithmetic here.
        """
        return self.frame_and_rates(values, q, rates=False)[:2]

    def frame_and_rates(self, values: np.ndarray, q: np.ndarray, rates: bool = True
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Positions (N, 3), their parameter Jacobian (N, 3, P), the end frame's rotation (N, 3, 3:
        columns are its axes) and its world rotation rate per parameter (N, 3, P) (these two None
        without ``rates``): a rotation op turns the frame about its world axis, a translation op does
        not turn it. In blocks of ``BLOCK`` configurations: memory traffic, not arithmetic, limits, so
        a block fits the cache."""
        ends, A, B = self._segment_frames(values, True)
        G = np.concatenate([A, B, np.concatenate(ends)])[self.z_map]  # each segment's constant part, op axes and points
        n = q.shape[0]
        p, JT = np.empty((n, 3)), np.empty((self.n_params, 3, n))
        R, WT = (np.empty((n, 3, 3)), np.zeros((self.n_params, 3, n))) if rates else (None, None)
        for lo in range(0, n, BLOCK):
            at = slice(lo, lo + BLOCK)
            p[at], frame = self._block(values, q[at], G, JT[:, :, at], None if WT is None else WT[:, :, at])
            if R is not None:
                R[at] = frame
        return p, JT.transpose(2, 1, 0), R, None if WT is None else WT.transpose(2, 1, 0)

    def _block(self, values: np.ndarray, q: np.ndarray, G: np.ndarray, out: np.ndarray,
               rates: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """Positions and (with ``rates``, zeros (P, 3, n) to write the rotation rates to) the end
        frame's rotation of one block of configurations, ``G`` (z_rows, 3) from :meth:`frame_and_rates`;
        the Jacobian written to ``out`` (P, 3, n)."""
        n = q.shape[0]
        n_rot = self.rot_idx.size
        F, Z, o, Cx, tmp = _carve(n, (3, 3), (self.z_rows, 3), (3,), (n_rot, 3), (max(n_rot, 3),))
        X = q.T[self.head_joint] + (values[self.head_param] + self.head_offset)[:, None]  # joint-op values, (n_joints, N)
        C, Sn = cos_sin(X)
        W = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, n))  # W[k] = world axis k of the frame
        t3 = tmp[:3]
        o[...] = 0.0  # the frame's origin; at the end, the end point p
        k = 0
        for s, head in enumerate(self.heads):
            if head is None or head.motion == TRANS:  # F: the frame just after the joint op
                F[...] = W
                if head is not None:
                    np.multiply(W[head.axis], X[k], out=t3)
                    o += t3
            else:
                c, sn = C[k], Sn[k]
                i, j = (head.axis + 1) % 3, (head.axis + 2) % 3
                np.multiply(W[i], c, out=F[i])
                np.multiply(W[j], sn, out=t3)
                F[i] += t3
                np.multiply(W[j], c, out=F[j])
                np.multiply(W[i], sn, out=t3)
                F[j] -= t3
                F[head.axis] = W[head.axis]
            k += head is not None
            lo, w0, p0, hi = self.z_slices[s]
            np.matmul(G[lo:hi], F.reshape(3, -1), out=Z[lo:hi].reshape(hi - lo, -1))
            Z[p0:hi] += o  # world points of the rotation ops, and the next origin
            W, o = Z[w0:w0 + 3], Z[hi - 1]
        frame = None if rates is None else W.transpose(2, 1, 0).copy()  # (n, 3, 3): column k is axis k
        if rates is not None:
            rates[self.cols_rot[self.rot_keep]] = Z[self.z_rot_axes][self.rot_keep]
        D = Z[self.z_points]
        np.subtract(o, D, out=D)  # p − o for every rotation op
        Ur, tr = Z[self.z_rot_axes], tmp[:n_rot]
        for a, b, c_ in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
            np.multiply(Ur[:, b], D[:, c_], out=Cx[:, a])
            np.multiply(Ur[:, c_], D[:, b], out=tr)
            Cx[:, a] -= tr
        self._columns(Cx, Z[self.z_trans_axes], out)
        return np.ascontiguousarray(o.T), frame

    def pose_jacobian(self, values: np.ndarray, q: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """End point (N, 3), end frame orientation (N, 3, 3: columns are its axes in the world), the
        joint Jacobians of the position and of the frame's angular velocity, (N, 3, n) each, and the
        chain's start and the end of every segment (N, S + 1, 3: the frame after each joint's motion
        and the constants that follow it; the last is the end point): the frames carried forward only
        from joint to joint (the constant part of each segment is one 3×3 mix), so it costs a few
        forward passes, not a parameter Jacobian."""
        n = q.shape[0]
        ends, _, _ = self._segment_frames(values, False)
        W = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, n))  # W[k]: world axis k, (3, N)
        o = np.zeros((3, n))
        path = [o]  # the origin at the start and after every segment
        U, O = np.zeros((self.n_joints, 3, n)), np.zeros((self.n_joints, 3, n))
        revolute = np.zeros(self.n_joints, bool)
        for M, head in zip(ends, self.heads):
            F = W
            if head is not None:
                x = q[:, head.joint] + (values[head.param] + head.offset)
                U[head.joint] = W[head.axis]
                if head.motion == TRANS:
                    o = o + W[head.axis] * x
                else:
                    revolute[head.joint] = True
                    O[head.joint] = o
                    c, sn = cos_sin(x)
                    i, j = (head.axis + 1) % 3, (head.axis + 2) % 3
                    F = np.empty((3, 3, n))
                    F[i], F[j], F[head.axis] = W[i] * c + W[j] * sn, W[j] * c - W[i] * sn, W[head.axis]
            Ff = F.reshape(3, -1)
            o = o + (M[3] @ Ff).reshape(3, n)
            W = (M[:3] @ Ff).reshape(3, 3, n)
            path.append(o)
        rev = revolute[:, None, None]  # a revolute joint moves the point by u × (p − o) and turns the frame by u
        Jp, Jw = np.where(rev, np.cross(U, o - O, axis=1), U), np.where(rev, U, 0.0)  # (n_joints, 3, N)
        origins = np.stack(path).transpose(2, 0, 1)  # (N, S + 1, 3)
        return o.T, W.transpose(2, 1, 0), Jp.transpose(2, 1, 0), Jw.transpose(2, 1, 0), origins

    def _columns(self, rot: np.ndarray, trans: np.ndarray, JT: np.ndarray) -> None:
        """The Jacobian, written transposed to JT (P, 3, N), from the rotation columns u × (p − o) and
        the translation axes, each (ops, 3, N); constant ops have no column, parameters without an op get zeros."""
        if self.all_ops_have_params:
            JT[self.cols_rot] = rot
            JT[self.cols_trans] = trans
        else:
            JT[self.cols_rot[self.rot_keep]] = rot[self.rot_keep]
            JT[self.cols_trans[self.trans_keep]] = trans[self.trans_keep]
        if self.unused.size:
            JT[self.unused] = 0.0
