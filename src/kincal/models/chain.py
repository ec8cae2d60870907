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
        self.unused = np.setdiff1d(np.arange(n_params), self.cols)
        # per segment: op slice, rotation mask (or None when it has no rotation op)
        self.seg_rot = []
        for a, b in zip(self.seg_slices[:-1], self.seg_slices[1:]):
            rot = ~self.is_trans[a:b]
            self.seg_rot.append(rot if rot.any() else None)
        self.head_joint = np.array([h.joint for h in self.heads if h is not None])
        self.head_param = np.array([h.param for h in self.heads if h is not None])
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
        """Positions (N,3) and parameter Jacobian (N,3,P) by forward propagation of frames.

        Pass 1 propagates the frames and keeps, per segment, the frame just after its joint op.
        Pass 2 turns each segment's op axes and points into world vectors with one BLAS product each
        and writes the columns: u × (p − o) for rotations, u for translations. Temporaries stay
        per segment (small), which matters more than op count for speed here.
        """
        n = q.shape[0]
        ends, A, B = self._segment_frames(values, True)
        JT = np.empty((self.n_params, 3, n))
        X = q.T[self.head_joint] + values[self.head_param][:, None]  # joint-op values, (n_joints, N)
        C, S = np.cos(X), np.sin(X)
        W = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, n))  # W[k] = world axis k of the frame, (3, N)
        o = np.zeros((3, n))
        starts = []
        k = 0
        for (R, t), head in zip(ends, self.heads):
            if head is not None:  # move to the frame just after the joint op
                if head.kind == TRANS:
                    o = o + W[head.axis] * X[k]
                else:
                    c, s = C[k], S[k]
                    i, j = (head.axis + 1) % 3, (head.axis + 2) % 3
                    W2 = np.empty((3, 3, n))
                    W2[i] = c * W[i] + s * W[j]
                    W2[j] = c * W[j] - s * W[i]
                    W2[head.axis] = W[head.axis]
                    W = W2
                k += 1
            Wf = W.reshape(3, -1)
            starts.append((Wf, o))
            o = o + (t @ Wf).reshape(3, n)
            W = (R.T @ Wf).reshape(3, 3, n)
        p = o
        for s, (Wf, o) in enumerate(starts):
            lo, hi = self.seg_slices[s], self.seg_slices[s + 1]
            U = (A[lo:hi] @ Wf).reshape(hi - lo, 3, n)
            rot = self.seg_rot[s]
            if rot is not None:
                D = p - o - (B[lo:hi][rot] @ Wf).reshape(-1, 3, n)
                Ur = U[rot]
                C = np.empty_like(D)
                C[:, 0] = Ur[:, 1] * D[:, 2] - Ur[:, 2] * D[:, 1]
                C[:, 1] = Ur[:, 2] * D[:, 0] - Ur[:, 0] * D[:, 2]
                C[:, 2] = Ur[:, 0] * D[:, 1] - Ur[:, 1] * D[:, 0]
                U[rot] = C
            JT[self.cols[lo:hi]] = U
        if self.unused.size:
            JT[self.unused] = 0.0
        return np.ascontiguousarray(p.T), JT.transpose(2, 1, 0)
