"""The cell around the robot: a floor at the mounting plane, a keep-out box and a laser tracker 3 m away
(range and the reflector's acceptance cone); pools, exchange designs and IDE all keep to them."""
import numpy as np
import pytest

import kincal
from kincal.design import Cell

UR10 = kincal.load_robot("ur10")
CELL = Cell(half_spaces=(((0.0, 0.0, 1.0), 0.0),), keep_out=((np.array([0.3, -0.3, 0.0]), np.array([0.7, 0.3, 0.4])),),
            tracker=np.array([3.0, 0.0, 0.5]), tracker_range=(1.0, 6.0), cone=np.deg2rad(30.0),
            joint_margin=np.deg2rad(2.0))


def _independent_violations(q: np.ndarray) -> np.ndarray:
    """Each constraint recomputed from its definition, pose by pose (no shared code with Cell)."""
    out = []
    for qi in q:
        p = UR10.forward(qi[None])[0]
        R = UR10.flange_rotation(qi[None])[0]
        ray = CELL.tracker - p
        angle = np.degrees(np.arccos(np.clip(R[:, 2] @ ray / np.linalg.norm(ray), -1, 1)))
        inside = 0.3 < p[0] < 0.7 and -0.3 < p[1] < 0.3 and 0.0 < p[2] < 0.4
        margin = np.degrees(np.minimum(qi - UR10.lower, UR10.upper - qi)).min()
        out.append(p[2] < 0 or inside or not 1.0 <= np.linalg.norm(ray) <= 6.0 or angle > 30.0 or margin < 2.0)
    return np.array(out)


def test_pools_and_designs_keep_to_the_cell():
    free = kincal.select_poses(UR10, kincal.candidate_pool(UR10, 3000, seed=1), m=40, method="fedorov",
                               criterion="D", certify=False)
    assert _independent_violations(free.q).sum() >= 20  # without the cell, most design poses break it
    pool = CELL.pool(UR10, 3000, seed=1)
    assert not _independent_violations(pool[:300]).any()
    for method in ("fedorov", "ide"):
        d = kincal.select_poses(UR10, pool, m=40, method=method, criterion="D", certify=False, generations=40,
                                cell=CELL)
        assert not _independent_violations(d.q).any(), method
        if method == "ide":
            assert np.abs(d.q[:, None, :] - pool[None]).max(axis=2).min(axis=1).max() > 1e-6  # IDE left the pool
            loose = kincal.select_poses(UR10, pool, m=40, method=method, criterion="D", certify=False, generations=40)
            assert _independent_violations(loose.q).sum() >= 10  # ... and without the cell it leaves the cell too


def test_candidates_that_break_the_cell_are_refused_with_the_first_one_named():
    pool = kincal.candidate_pool(UR10, 500, seed=2)
    with pytest.raises(ValueError, match=r"candidate poses break the cell's constraints \(first: candidate \d+, "):
        kincal.select_poses(UR10, pool, m=30, method="fedorov", certify=False, cell=CELL)
    with pytest.raises(ValueError, match="'half-space 1' removes"):
        Cell(half_spaces=(((0.0, 0.0, 1.0), 5.0),)).pool(UR10, 100)  # a floor 5 m up: nothing fits, named
