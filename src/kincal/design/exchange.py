"""Greedy start and modified Fedorov exchange with low-rank updates (no factorisation per candidate).

Each pose contributes an r-row block Jᵢ (3 position rows for a tracker, 6 for a full pose, 3 per
marker), so adding it changes M = Σ JᵀJ by a rank-r term and an exchange (add i, remove j) by a
rank-2r term. With Vᵢ = Jᵢ M⁻¹ Jᵢᵀ and Cᵢⱼ = Jᵢ M⁻¹ Jⱼᵀ (r×r; closed forms for r = 3):

* add i:           det M'/det M = det(I + Vᵢ)
* exchange j → i:  det M'/det M = det(I + Vᵢ) · det(I − Vⱼ + Cᵢⱼᵀ (I + Vᵢ)⁻¹ Cᵢⱼ)
* I-criterion:     tr(M'⁻¹B) = tr(M⁻¹B) − tr(K⁻¹ U H Uᵀ), U = [Jᵢ; Jⱼ], H = M⁻¹BM⁻¹,
                   K = diag(I, −I) + U M⁻¹ Uᵀ   (Woodbury)

For one design point j, all N candidates cost one (rN×k)·(k×r) product plus r×r algebra; M⁻¹ and
every Vᵢ are then updated by the same Woodbury identity (rank 2r). The exchange visits the design
points in turn and swaps each with its best candidate while that improves the criterion (Cook and
Nachtsheim's modified Fedorov algorithm). Candidates whose gains tie (:mod:`kincal.ties`) are taken
in pool order, so the design does not depend on round-off.
"""
from __future__ import annotations

import numpy as np

from ..ties import first_best
from .problem import DesignProblem

IMPROVE = 1e-10  # relative improvement an exchange must bring
SINGULAR = 1e-10  # λmin/λmax of an information matrix at or below which it is singular; also the ridge, × λmax

# Small matrices are stored component-first, (3, 3, N): every batched step is then a contiguous
# vector operation, several times faster than NumPy's stacked (N, 3, 3) matmul.


def det3(A: np.ndarray) -> np.ndarray:
    """Determinants of (3, 3, ...) matrices in closed form."""
    return (A[0, 0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1])
            - A[0, 1] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
            + A[0, 2] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]))


def inv3(A: np.ndarray) -> np.ndarray:
    """Inverses of (3, 3, ...) matrices in closed form (adjugate / determinant): the cofactor of
    element (j, i) is A[j+1, i+1]·A[j+2, i+2] − A[j+2, i+1]·A[j+1, i+2], indices mod 3 (A tiled 2×2)."""
    T = np.tile(A, (2, 2) + (1,) * (A.ndim - 2))
    cof = T[1:4, 1:4] * T[2:5, 2:5] - T[2:5, 1:4] * T[1:4, 2:5]
    return cof.swapaxes(0, 1) / det3(A)


def det_blocks(A: np.ndarray) -> np.ndarray:
    """Determinants of (r, r, ...) matrices: closed form for r = 3 (a tracker's blocks), else LU."""
    return det3(A) if A.shape[0] == 3 else np.linalg.det(np.moveaxis(A, (0, 1), (-2, -1)))


def inv_blocks(A: np.ndarray) -> np.ndarray:
    """Inverses of (r, r, ...) matrices, same layout."""
    return inv3(A) if A.shape[0] == 3 else \
        np.moveaxis(np.linalg.inv(np.moveaxis(A, (0, 1), (-2, -1))), (-2, -1), (0, 1))


def mm(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Products of (a, b, N) and (b, c, N) stacks, (a, c, N)."""
    return (X[:, :, None, :] * Y[None, :, :, :]).sum(axis=1)


def tr(X: np.ndarray) -> np.ndarray:
    return X.transpose(1, 0, 2)


class _State:
    """M⁻¹ of the current design and Vᵢ = Jᵢ M⁻¹ Jᵢᵀ for every candidate, (r, r, N).

    A singular M (a random start that leaves a parameter unseen, e.g. a socket with too few samples) is
    inverted as M + ε·λmax·I (ε = :data:`SINGULAR`; ``ridge`` holds the term added, else 0): the exchange
    then maximises det(M + ridge·I), which fills the unseen directions first, as the greedy start does.
    """

    def __init__(self, P: DesignProblem, M: np.ndarray) -> None:
        self.P = P
        self.rows = np.ascontiguousarray(P.J.transpose(1, 0, 2)).reshape(-1, P.k)  # (3N, k), axis-major
        w = np.linalg.eigvalsh(M)
        self.ridge = 0.0 if w[0] > SINGULAR * w[-1] else SINGULAR * (w[-1] if w[-1] > 0 else 1.0)
        self.Minv = np.linalg.inv(M + self.ridge * np.eye(P.k))
        self._set_V(self.quad(self.Minv))

    def _set_V(self, V: np.ndarray) -> None:
        self.V = V
        A = np.eye(self.P.r)[:, :, None] + V
        self.A_det, self.A_inv = det_blocks(A), inv_blocks(A)  # reused by every exchange evaluation

    def quad(self, A: np.ndarray) -> np.ndarray:
        """Jᵢ A Jᵢᵀ for every candidate, (r, r, N)."""
        shape = (self.P.r, self.P.N, self.P.k)
        return np.einsum("ank,bnk->abn", (self.rows @ A).reshape(shape), self.rows.reshape(shape))

    def cross(self, j: int, A: np.ndarray | None = None) -> np.ndarray:
        """Cᵢⱼ = Jᵢ A Jⱼᵀ (A: M⁻¹ unless given) for every candidate i, (r, r, N)."""
        A, r = self.Minv if A is None else A, self.P.r
        return (self.rows @ (A @ self.P.J[j].T)).reshape(r, self.P.N, r).transpose(0, 2, 1)

    def update(self, U: np.ndarray, sign: np.ndarray, G: np.ndarray) -> None:
        """M += Uᵀ diag(sign) U, with G = J M⁻¹ Uᵀ for every candidate (r, u, N)."""
        MU = self.Minv @ U.T
        Kinv = np.linalg.inv(np.diag(sign) + U @ MU)
        self.Minv = self.Minv - MU @ Kinv @ MU.T
        GK = np.matmul(Kinv.T, G)  # (r, u, N)
        self._set_V(self.V - (GK[:, None] * G[None]).sum(axis=2))


def greedy(P: DesignProblem, m: int, ridge: float = 1e-8) -> list[int]:
    """Add, one at a time, the candidate that most increases det(M), from M = ridge·I."""
    st = _State(P, ridge * np.eye(P.k))
    chosen: list[int] = []
    for _ in range(m):
        gain = st.A_det.copy()
        gain[chosen] = -np.inf
        chosen.append(i := first_best(gain))
        st.update(P.J[i], np.ones(P.r), st.cross(i))
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
    eye, sign = np.eye(P.r)[:, :, None], np.repeat([1.0, -1.0], P.r)
    exchanges = passes = 0
    for passes in range(1, max_passes + 1):
        before, H, R = exchanges, None, None
        for pos in range(len(design)):
            j = design[pos]
            C = st.cross(j)  # (r,r,N): Cᵢⱼ
            Vj = st.V[:, :, j:j + 1]
            ratio = st.A_det * det_blocks((eye - Vj) + mm(tr(C), mm(st.A_inv, C)))  # det M'/det M of each swap
            if criterion == "D":
                score = ratio - 1.0  # relative gain in det M
            else:
                assert B is not None  # criterion I weighs the region's information B
                if H is None:
                    H = st.Minv @ B @ st.Minv
                    R = st.quad(H)
                with np.errstate(over="ignore"):  # a gain beyond range is judged below, as not finite
                    score = _i_gain(st, C, Vj, R, H, j, in_design) / max(np.trace(st.Minv @ B), 1e-300)
            # a swap that leaves M singular has no finite criterion (its I gain is round-off): never taken
            score[in_design | ~np.isfinite(score) | ~(ratio > SINGULAR)] = -np.inf
            i = first_best(score + 1.0)  # ties judged on the ratio of the criteria
            if score[i] <= IMPROVE:
                continue
            st.update(np.vstack([P.J[i], P.J[j]]), sign, np.concatenate([st.cross(i), C], axis=1))
            design[pos] = i
            in_design[i], in_design[j] = True, False
            exchanges += 1
            H = R = None
        if exchanges == before:
            break
        st = _State(P, P.information(design))  # wash out rounding from the updates
    return design, passes, exchanges


def _i_gain(st: _State, C, Vj, R, H, j: int, in_design: np.ndarray) -> np.ndarray:
    """Decrease of tr(M⁻¹B) for exchanging j with each candidate: tr(K⁻¹ U H Uᵀ)."""
    P, r, free = st.P, st.P.r, ~in_design
    out = np.full(P.N, -np.inf)

    def sym(A: np.ndarray, X: np.ndarray, D: np.ndarray) -> np.ndarray:
        """[[A, X], [Xᵀ, D]] (n_free, 2r, 2r) of the free candidates from (r, r, N) stacks A, X and D (r, r)."""
        A, X = np.moveaxis(A, 2, 0)[free], np.moveaxis(X, 2, 0)[free]
        return np.block([[A, X], [np.swapaxes(X, 1, 2), np.broadcast_to(D, X.shape)]])

    K = sym(np.eye(r)[:, :, None] + st.V, C, Vj[:, :, 0] - np.eye(r))
    Q = sym(R, st.cross(j, H), R[:, :, j])  # Jᵢ H Jⱼᵀ off the diagonal
    with np.errstate(all="ignore"):
        out[free] = np.trace(np.linalg.solve(K, Q), axis1=1, axis2=2)
    return out
