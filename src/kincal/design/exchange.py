"""Greedy start and modified Fedorov exchange with low-rank updates (no factorisation per candidate).

Each pose contributes a 3-row block Jᵢ, so adding it changes M = Σ JᵀJ by a rank-3 term and an
exchange (add i, remove j) by a rank-6 term. With Vᵢ = Jᵢ M⁻¹ Jᵢᵀ and Cᵢⱼ = Jᵢ M⁻¹ Jⱼᵀ (3×3):

* add i:           det M'/det M = det(I + Vᵢ)
* exchange j → i:  det M'/det M = det(I + Vᵢ) · det(I − Vⱼ + Cᵢⱼᵀ (I + Vᵢ)⁻¹ Cᵢⱼ)
* I-criterion:     tr(M'⁻¹B) = tr(M⁻¹B) − tr(K⁻¹ U H Uᵀ), U = [Jᵢ; Jⱼ], H = M⁻¹BM⁻¹,
                   K = diag(I, −I) + U M⁻¹ Uᵀ   (Woodbury)

For one design point j, all N candidates cost one (3N×k)·(k×3) product plus 3×3 algebra; M⁻¹ and
every Vᵢ are then updated by the same Woodbury identity (rank 6). The exchange visits the design
points in turn and swaps each with its best candidate while that improves the criterion (Cook and
Nachtsheim's modified Fedorov algorithm). Candidates whose gains tie (:mod:`kincal.ties`) are taken
in pool order, so the design does not depend on round-off.
"""
from __future__ import annotations

import numpy as np

from ..ties import first_best
from .problem import DesignProblem

IMPROVE = 1e-10  # relative improvement an exchange must bring

# Small matrices are stored component-first, (3, 3, N): every batched step is then a contiguous
# vector operation, several times faster than NumPy's stacked (N, 3, 3) matmul.


def det3(A: np.ndarray) -> np.ndarray:
    """Determinants of (3, 3, ...) matrices in closed form."""
    return (A[0, 0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1])
            - A[0, 1] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
            + A[0, 2] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]))


def inv3(A: np.ndarray) -> np.ndarray:
    """Inverses of (3, 3, ...) matrices in closed form (adjugate / determinant)."""
    adj = np.empty_like(A)
    for i in range(3):
        for j in range(3):
            r = [x for x in range(3) if x != j]
            c = [x for x in range(3) if x != i]
            minor = A[r[0], c[0]] * A[r[1], c[1]] - A[r[0], c[1]] * A[r[1], c[0]]
            adj[i, j] = minor if (i + j) % 2 == 0 else -minor
    return adj / det3(A)


def mm(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Products of (a, b, N) and (b, c, N) stacks, (a, c, N)."""
    return (X[:, :, None, :] * Y[None, :, :, :]).sum(axis=1)


def tr(X: np.ndarray) -> np.ndarray:
    return X.transpose(1, 0, 2)


class _State:
    """M⁻¹ of the current design and Vᵢ = Jᵢ M⁻¹ Jᵢᵀ for every candidate, (3, 3, N)."""

    def __init__(self, P: DesignProblem, M: np.ndarray) -> None:
        self.P = P
        self.rows = np.ascontiguousarray(P.J.transpose(1, 0, 2)).reshape(-1, P.k)  # (3N, k), axis-major
        self.Minv = np.linalg.inv(M)
        self._set_V(self.quad(self.Minv))

    def _set_V(self, V: np.ndarray) -> None:
        self.V = V
        A = np.eye(3)[:, :, None] + V
        self.A_det, self.A_inv = det3(A), inv3(A)  # reused by every exchange evaluation

    def quad(self, A: np.ndarray) -> np.ndarray:
        """Jᵢ A Jᵢᵀ for every candidate, (3, 3, N)."""
        N, k = self.P.N, self.P.k
        Y = (self.rows @ A).reshape(3, N, k)
        Jr = self.rows.reshape(3, N, k)
        return np.einsum("ank,bnk->abn", Y, Jr)

    def cross(self, j: int) -> np.ndarray:
        """Cᵢⱼ = Jᵢ M⁻¹ Jⱼᵀ for every candidate i, (3, 3, N)."""
        return (self.rows @ (self.Minv @ self.P.J[j].T)).reshape(3, self.P.N, 3).transpose(0, 2, 1)

    def update(self, U: np.ndarray, sign: np.ndarray, G: np.ndarray) -> None:
        """M += Uᵀ diag(sign) U, with G = J M⁻¹ Uᵀ for every candidate (3, r, N)."""
        MU = self.Minv @ U.T
        Kinv = np.linalg.inv(np.diag(sign) + U @ MU)
        self.Minv = self.Minv - MU @ Kinv @ MU.T
        GK = np.matmul(Kinv.T, G)  # (3, r, N)
        self._set_V(self.V - (GK[:, None] * G[None]).sum(axis=2))


def greedy(P: DesignProblem, m: int, ridge: float = 1e-8) -> list[int]:
    """Add, one at a time, the candidate that most increases det(M), from M = ridge·I."""
    st = _State(P, ridge * np.eye(P.k))
    chosen: list[int] = []
    taken = np.zeros(P.N, bool)
    for _ in range(m):
        gain = st.A_det.copy()
        gain[taken] = -np.inf
        i = first_best(gain)
        chosen.append(i)
        taken[i] = True
        st.update(P.J[i], np.ones(3), st.cross(i))
    return chosen


def fedorov(P: DesignProblem, start: list[int], criterion: str = "D", B: np.ndarray | None = None,
            max_passes: int = 50) -> tuple[list[int], int, int]:
    """Modified Fedorov exchange from ``start``; criterion "D" (max det M) or "I" (min tr M⁻¹B).

    Returns the design, the number of passes and of exchanges made.
    """
    design = list(start)
    in_design = np.zeros(P.N, bool)
    in_design[design] = True
    st = _State(P, P.information(design))
    eye, sign = np.eye(3)[:, :, None], np.array([1.0, 1, 1, -1, -1, -1])
    exchanges = passes = 0
    for passes in range(1, max_passes + 1):
        changed = False
        H = R = None
        for pos in range(len(design)):
            j = design[pos]
            C = st.cross(j)  # (3,3,N): Cᵢⱼ
            Vj = st.V[:, :, j:j + 1]
            if criterion == "D":
                E = (eye - Vj) + mm(tr(C), mm(st.A_inv, C))
                score = st.A_det * det3(E) - 1.0  # relative gain in det M
            else:
                if H is None:
                    H = st.Minv @ B @ st.Minv
                    R = st.quad(H)
                score = _i_gain(st, C, Vj, R, H, j, in_design) / max(np.trace(st.Minv @ B), 1e-300)
            score[in_design] = -np.inf
            score[~np.isfinite(score)] = -np.inf
            i = first_best(score + 1.0)  # ties judged on the ratio of the criteria
            if score[i] <= IMPROVE:
                continue
            U = np.vstack([P.J[i], P.J[j]])
            st.update(U, sign, np.concatenate([st.cross(i), C], axis=1))
            design[pos] = i
            in_design[i], in_design[j] = True, False
            exchanges += 1
            changed = True
            H = R = None
        if not changed:
            break
        st = _State(P, P.information(design))  # wash out rounding from the updates
    return design, passes, exchanges


def _i_gain(st: _State, C, Vj, R, H, j: int, in_design: np.ndarray) -> np.ndarray:
    """Decrease of tr(M⁻¹B) for exchanging j with each candidate: tr(K⁻¹ U H Uᵀ)."""
    P = st.P
    out = np.full(P.N, -np.inf)
    free = ~in_design
    to_n = lambda X: np.moveaxis(X, 2, 0)[free]  # noqa: E731  (3,3,N) -> (n_free,3,3)
    K = np.empty((int(free.sum()), 6, 6))
    K[:, :3, :3] = to_n(np.eye(3)[:, :, None] + st.V)
    K[:, :3, 3:] = to_n(C)
    K[:, 3:, :3] = np.swapaxes(K[:, :3, 3:], 1, 2)
    K[:, 3:, 3:] = Vj[:, :, 0] - np.eye(3)
    HJj = (st.rows @ (H @ P.J[j].T)).reshape(3, P.N, 3).transpose(0, 2, 1)
    Q = np.empty_like(K)
    Q[:, :3, :3] = to_n(R)
    Q[:, :3, 3:] = to_n(HJj)
    Q[:, 3:, :3] = np.swapaxes(Q[:, :3, 3:], 1, 2)
    Q[:, 3:, 3:] = R[:, :, j]
    with np.errstate(all="ignore"):
        out[free] = np.trace(np.linalg.solve(K, Q), axis1=1, axis2=2)
    return out
