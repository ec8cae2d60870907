"""Batched kinematic chains of elementary motions, with analytic parameter Jacobians.

A chain is a sequence of elementary operations, each a rotation about or a translation along one
axis of the current frame, by a parameter value plus (optionally) a joint value. Any serial model
(DH, modified DH, Hayati β, base frame, tool point) is such a sequence, so one mechanism computes
the position and every Jacobian column:

* rotation about unit axis u through point o:  ∂p/∂angle = u × (p − o)
* translation along unit axis u:               ∂p/∂length = u

The ops are cut into segments: the ops before the first joint, then one segment per joint (its
joint op and the constant ops after it). Each segment's constant part is composed once per call
(scalar work), so the batched work per joint is a column mix and one small BLAS product. A
segment's Jacobian columns are affine in the tool position seen from the segment's end frame,
``G p_loc + h`` with constant G, h, and are turned to the world with that frame. Arrays are laid
out component-first, (3, N), so every batched step is a contiguous vector operation; no Python loop
runs over configurations.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import cos, sin

import numpy as np

from ..errors import ModelError

ROT, TRANS = "R", "T"
AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class Op:
    """One elementary motion: ``kind`` R/T about/along local ``axis`` (0,1,2) by
    ``values[param]`` (+ ``q[:, joint]`` if ``joint >= 0``)."""

    kind: str
    axis: int
    param: int
    joint: int = -1


def cos_sin(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin from one tan(x/2) (NumPy's float64 trig dominates FK time; this halves it).
    Accurate to a few ulp for every finite x."""
    t = np.tan(0.5 * x)
    t2 = t * t
    inv = 1.0 / (1.0 + t2)
    return (1.0 - t2) * inv, (2.0 * inv) * t


class Chain:
    """Compiled op sequence for ``n_params`` parameters and ``n_joints`` joints (each joint in exactly one op)."""

    def __init__(self, ops: tuple[Op, ...], n_params: int, n_joints: int) -> None:
        joint_ops = [k for k, op in enumerate(ops) if op.joint >= 0]
        joints = [ops[k].joint for k in joint_ops]
        if sorted(joints) != list(range(n_joints)):
            raise ModelError(f"chain: every joint must drive exactly one op, got joints {joints} for {n_joints}")
        bounds = [0] + joint_ops + [len(ops)]
        # segment 0: ops before the first joint; segment s: joint op and the constant ops after it
        self.segments = [tuple(ops[bounds[s]:bounds[s + 1]]) for s in range(len(bounds) - 1)]
        self.heads = [seg[0] if seg[0].joint >= 0 else None for seg in self.segments]
        self.ops = tuple(op for seg in self.segments for op in seg)
        self.seg_of_op = np.repeat(np.arange(len(self.segments)), [len(s) for s in self.segments])
        self.cols = np.array([op.param for op in self.ops])
        self.is_trans = np.array([op.kind == TRANS for op in self.ops])
        self.seg_slices = np.cumsum([0] + [len(s) for s in self.segments])
        self.n_params, self.n_joints = n_params, n_joints
        self.joint_param = np.array([ops[k].param for k in sorted(joint_ops, key=lambda k: ops[k].joint)])

    def _segment_frames(self, values: np.ndarray, record: bool):
        """Constant part of each segment as (R (3,3), t (3,)); with ``record`` also each op's axis
        and point in its segment's start coordinates, (n_ops, 3) each. Scalar Python: ~40 ops."""
        ends, axes, points = [], [], []
        for seg, head in zip(self.segments, self.heads):
            c0, c1, c2 = [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]
            cols = [c0, c1, c2]
            t = [0.0, 0.0, 0.0]
            for op in seg:
                if record:
                    axes.append(list(cols[op.axis]))
                    points.append(list(t))
                if op is head:
                    continue
                v = float(values[op.param])
                if v == 0.0:
                    continue
                u = cols[op.axis]
                if op.kind == TRANS:
                    t = [t[0] + v * u[0], t[1] + v * u[1], t[2] + v * u[2]]
                else:
                    c, s = cos(v), sin(v)
                    i, j = (op.axis + 1) % 3, (op.axis + 2) % 3
                    a, b = cols[i], cols[j]
                    cols[i] = [c * a[0] + s * b[0], c * a[1] + s * b[1], c * a[2] + s * b[2]]
                    cols[j] = [c * b[0] - s * a[0], c * b[1] - s * a[1], c * b[2] - s * a[2]]
            ends.append((np.array(cols).T, np.array(t)))
        return ends, np.array(axes), np.array(points)

    def forward(self, values: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Positions (N,3): the end point carried backwards through the chain."""
        n = q.shape[0]
        ends, _, _ = self._segment_frames(values, False)
        qt = q.T
        V = None  # (3, N) position in the current frame; None while it is the origin
        for (R, t), head in zip(reversed(ends), reversed(self.heads)):
            V = t[:, None] if V is None else R @ V + t[:, None]
            if head is None:
                continue
            x = qt[head.joint] + values[head.param]
            V = np.broadcast_to(V, (3, n))
            if head.kind == TRANS:
                V = V + np.outer(np.eye(3)[head.axis], x)
            else:
                c, s = cos_sin(x)
                i, j = (head.axis + 1) % 3, (head.axis + 2) % 3
                W = np.empty((3, n))
                W[i] = c * V[i] - s * V[j]
                W[j] = s * V[i] + c * V[j]
                W[head.axis] = V[head.axis]
                V = W
        return np.ascontiguousarray(np.broadcast_to(V, (3, n)).T)

    def forward_and_jacobian(self, values: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (N,3) and parameter Jacobian (N,3,P) by forward propagation of frames."""
        n = q.shape[0]
        ends, A, B = self._segment_frames(values, True)
        # each op's axis / point in its segment's END frame, then the affine column maps G p + h
        Rs = np.stack([R for R, _ in ends])[self.seg_of_op]  # (n_ops,3,3)
        ts = np.stack([t for _, t in ends])[self.seg_of_op]
        a = np.einsum("kj,kji->ki", A, Rs)
        b = np.einsum("kj,kji->ki", B - ts, Rs)
        G = np.zeros((len(self.ops), 3, 3))
        G[:, 0, 1], G[:, 0, 2], G[:, 1, 2] = -a[:, 2], a[:, 1], -a[:, 0]
        G[:, 1, 0], G[:, 2, 0], G[:, 2, 1] = a[:, 2], -a[:, 1], a[:, 0]
        h = -np.cross(a, b)
        G[self.is_trans] = 0.0
        h[self.is_trans] = a[self.is_trans]

        qt = q.T
        W = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, n))  # W[j] = world column j, (3, N)
        o = np.zeros((3, 1))
        frames = []
        for (R, t), head in zip(ends, self.heads):
            if head is not None:
                x = qt[head.joint] + values[head.param]
                if head.kind == TRANS:
                    o = o + W[head.axis] * x
                else:
                    c, s = cos_sin(x)
                    i, j = (head.axis + 1) % 3, (head.axis + 2) % 3
                    W2 = np.empty((3, 3, n))
                    W2[i] = c * W[i] + s * W[j]
                    W2[j] = c * W[j] - s * W[i]
                    W2[head.axis] = W[head.axis]
                    W = W2
            o = o + (t @ W.reshape(3, -1)).reshape(3, -1)
            W = (R.T @ W.reshape(3, -1)).reshape(3, 3, -1)
            frames.append((W, o))
        p = np.broadcast_to(o, (3, n))
        JT = np.zeros((3, self.n_params, n))
        for s, (W, o) in enumerate(frames):
            lo, hi = self.seg_slices[s], self.seg_slices[s + 1]
            d = p - o
            p_loc = (W * d[None]).sum(axis=1)  # (3, N): tool point in this segment's end frame
            L = (G[lo:hi].reshape(-1, 3) @ p_loc + h[lo:hi].reshape(-1, 1)).reshape(hi - lo, 3, -1)
            JT[:, self.cols[lo:hi], :] = W[0][:, None] * L[:, 0] + W[1][:, None] * L[:, 1] + W[2][:, None] * L[:, 2]
        return np.ascontiguousarray(p.T), JT.transpose(2, 0, 1)
