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


def _dh_origins(q, d, a, alpha, tool):
    """Joint frame origins and the tool point of a standard-DH arm (an independent forward kinematics:
    4x4 matrices Rz(θ) Tz(d) Tx(a) Rx(α) multiplied out), (N, 7 + 1, 3) for six joints."""
    out = []
    for qi in q:
        T, pts = np.eye(4), [np.zeros(3)]
        for th, di, ai, al in zip(qi, d, a, alpha):
            c, s, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
            T = T @ np.array([[c, -s * ca, s * sa, ai * c], [s, c * ca, -c * sa, ai * s], [0, sa, ca, di], [0, 0, 0, 1]])
            pts.append(T[:3, 3].copy())
        pts.append((T @ np.append(tool, 1.0))[:3])
        out.append(pts)
    return np.array(out)


def test_designs_keep_the_whole_arm_above_the_floor_and_out_of_the_box(tmp_path, capsys):
    """design ur10 --floor 0mm --keep-out … --tracker …: none of the 60 poses puts any link (the
    segments between the DH joint frames and to the probe, thickened by 50 mm) below the floor or
    into the box — checked with an independent forward kinematics — or beyond UR's joint limits; a
    cell without the arm check lets the elbow through the floor in some of the same pool's poses."""

    from kincal.cli import main

    out = tmp_path / "poses.csv"
    assert main(["design", "ur10", "-m", "60", "--pool", "1500", "--tool", "0,0,100mm", "--floor", "0mm",
                 "--keep-out", "300,-300,0,700,300,400mm", "--tracker", "3000,0,500mm", "-o", str(out), "--json"]) == 0
    capsys.readouterr()
    robot = kincal.load_robot("ur10")
    q = kincal.read_joints(str(out), robot)
    pts = _dh_origins(q, [0.1273, 0, 0, 0.163941, 0.1157, 0.0922], [0, -0.612, -0.5723, 0, 0, 0],
                      [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0], [0.0, 0.0, 0.1])
    assert np.abs(pts[:, -1] - robot.with_tool_point([0, 0, 0.1]).forward(q)).max() < 1e-12
    seg = pts[:, 2:-1, None] + np.linspace(0, 1, 11)[None, None, :, None] * (pts[:, 3:] - pts[:, 2:-1])[:, :, None]
    seg = seg.reshape(len(q), -1, 3)
    assert len(q) == 60 and np.all(seg[:, :, 2] >= 0.05 - 1e-9)  # 50 mm of link radius above the floor
    inside = np.all((seg > np.array([0.3, -0.3, 0.0]) - 0.05) & (seg < np.array([0.7, 0.3, 0.4]) + 0.05), axis=2)
    assert not inside.any()
    assert _base_gap(pts).min() >= 0.1 - 1e-9  # nor into its own base
    assert np.abs(q[:, 2]).max() <= np.pi and np.abs(q).max() <= 2 * np.pi  # UR's limits: elbow ±180°, others ±360°
    bare = Cell(half_spaces=(((0.0, 0.0, 1.0), 0.0),), link_radius=0.0)
    pool = kincal.candidate_pool(robot, 1500, seed=0)
    tip_only = bare.violations(robot, pool)
    assert (tip_only["arm through half-space 1"] & ~tip_only["half-space 1"]).sum() > 50  # the elbow, not the tip


def _base_gap(pts):
    """(N,) m: how near the wrist (from the fourth joint's origin on) and the probe come to the base column, the
    segment from the base to the shoulder's axis point d1 above it (_dh_origins's points)."""
    column, wrist = pts[:, 1], pts[:, 3:]
    t = np.clip(wrist[..., 2] / column[:, None, 2], 0.0, 1.0)
    return np.linalg.norm(wrist - t[..., None] * column[:, None], axis=2).min(axis=1)


def test_a_pose_folded_into_the_robots_own_base_is_out_of_the_cell():
    """The audit's UR5 design had the tool 61 mm from the base's axis at 79 mm height, inside the base: with a floor
    (the arm checked) the wrist and the probe keep two link radii (100 mm) from the base column, the poses that do
    not are exactly those an independent forward kinematics finds nearer."""
    q = kincal.candidate_pool(UR10, 3000, seed=6)
    got = Cell(half_spaces=(((0.0, 0.0, 1.0), -10.0),)).violations(UR10.with_tool_point([0, 0, 0.1]), q)
    gap = _base_gap(_dh_origins(q, [0.1273, 0, 0, 0.163941, 0.1157, 0.0922], [0, -0.612, -0.5723, 0, 0, 0],
                                [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0], [0.0, 0.0, 0.1]))
    clear = np.abs(gap - 0.1) > 1e-9
    assert got["arm into its own base"].sum() > 50
    assert np.array_equal(got["arm into its own base"][clear], (gap < 0.1)[clear])


@pytest.mark.slow
def test_the_segment_box_test_agrees_with_dense_sampling():
    """Segments against a box, 2000 random cases (a tenth parallel to a face): the slab test equals
    'some of 4001 points along the segment lie in the box' wherever that answer is the same for the
    box 2 mm smaller and 2 mm larger."""
    from kincal.design.cell import _crosses

    rng = np.random.default_rng(4)
    a, b = rng.uniform(-1, 1, (1, 2000, 3)), rng.uniform(-1, 1, (1, 2000, 3))
    b[0, :200, 0] = a[0, :200, 0]  # segments parallel to a face
    lo, hi = np.array([-0.3, -0.2, -0.4]), np.array([0.2, 0.3, 0.1])
    t = np.linspace(0, 1, 4001)[:, None, None]
    pts = a[0][None] + t * (b - a)[0][None]  # (4001, 2000, 3)
    def sampled(e):
        return np.any(np.all((pts >= lo - e) & (pts <= hi + e), axis=2), axis=0)
    small, big = sampled(-2e-3), sampled(2e-3)
    clear = small == big  # not grazing a face: the same answer for the box 2 mm smaller and larger
    assert clear.sum() > 1900 and 100 < small[clear].sum() < 1900
    assert np.array_equal(_crosses(a, b, lo, hi)[0][clear], small[clear])


def test_verification_plans_keep_to_the_cell(tmp_path, capsys):
    """verify ur10 -o plan.csv draws its samples over the whole joint range: commands under the mounting plane
    are counted on stderr (the count recomputed with an independent forward kinematics); with --floor 0mm and a
    keep-out box every command's arm (50 mm link radius) stays above the floor and out of the box; the cell flags
    with --plan (a plan already made) are refused."""
    from kincal.cli import main

    def commands(path):
        rows = [r.split(",") for r in path.read_text().splitlines()[2:]]
        return np.array([[float(x) for x in r[2:8]] for r in rows])  # m, rad: the plan's first line says so

    dh = ([0.1273, 0, 0, 0.163941, 0.1157, 0.0922], [0, -0.612, -0.5723, 0, 0, 0],
          [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0], [0.0, 0.0, 0.0])
    free, kept = tmp_path / "free.csv", tmp_path / "kept.csv"
    assert main(["verify", "ur10", "--params", "j2.a,j3.a", "-o", str(free)]) == 0
    below = int((_dh_origins(commands(free), *dh)[:, -1, 2] < 0).sum())
    assert below > 0 and f"warning: {below} of 20 commands put the tool point below" in capsys.readouterr().err
    assert main(["verify", "ur10", "--params", "j2.a,j3.a", "--samples", "15", "--floor", "0mm", "--keep-out",
                 "300,-300,0,700,300,400mm", "-o", str(kept)]) == 0
    assert "warning" not in capsys.readouterr().err
    pts = _dh_origins(commands(kept), *dh)
    seg = pts[:, 2:-1, None] + np.linspace(0, 1, 11)[None, None, :, None] * (pts[:, 3:] - pts[:, 2:-1])[:, :, None]
    seg = seg.reshape(len(pts), -1, 3)
    assert len(pts) == 30 and np.all(seg[:, :, 2] >= 0.05 - 1e-9)
    assert not np.all((seg > np.array([0.3, -0.3, 0.0]) - 0.05) & (seg < np.array([0.7, 0.3, 0.4]) + 0.05), axis=2).any()
    assert main(["verify", "ur10", "--plan", str(kept), "--floor", "0mm", "--simulate", "ur10"]) == 1
    assert "--plan" in capsys.readouterr().err


def test_a_floor_the_arm_cannot_stand_above_names_the_flag_and_the_arm():
    """A UR5 under --floor 100mm: its fixed shoulder (89 mm up, DH d1) less the 50 mm link radius is below the floor
    at every pose, so nothing fits; the message names the flag and the arm's lowest link height (the shoulder, at
    most 89 mm high in every draw by an independent forward kinematics), not 'half-space 1' or the units."""
    import re

    ur5 = kincal.load_robot("ur5")
    cell = Cell(half_spaces=(((0.0, 0.0, 1.0), 0.1),), labels=(("half-space 1", "--floor"),))
    with pytest.raises(ValueError) as exc:
        cell.pool(ur5, 100)
    said = str(exc.value)
    assert "the arm's own links sit below --floor (100 mm) at every pose" in said
    assert "half-space" not in said and "units" not in said
    high = float(re.search(r"at most (\d+) mm high", said).group(1))
    pts = _dh_origins(ur5.sample_joints(2000, seed=0), [0.089159, 0, 0, 0.10915, 0.09465, 0.0823],
                      [0, -0.425, -0.39225, 0, 0, 0], [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0], ur5.tool_point())
    assert high == round(pts[:, 1:, 2].min(axis=1).max() * 1e3) == 89  # the shoulder is the arm's highest low point
    with pytest.raises(ValueError, match="'--floor' removes 100 %.*check its values and units"):
        Cell(half_spaces=(((0.0, 0.0, 1.0), 5.0),), labels=(("half-space 1", "--floor"),)).pool(ur5, 100)


def _with_tracker(tracker, n: int, seed: int, constraint: str, samples: int):
    """The UR10 (a 0.1 m probe) in a cell with a floor far below and a tracker: n candidate poses, which of them
    break ``constraint``, their independent link points (_dh_origins) and the links sampled ``samples`` times each
    (from the shoulder on, as the cell's arm)."""
    cell = Cell(half_spaces=(((0.0, 0.0, 1.0), -10.0),), tracker=tracker, cone=np.pi)
    q = kincal.candidate_pool(UR10, n, seed=seed)
    flagged = cell.violations(UR10.with_tool_point([0, 0, 0.1]), q)[constraint]
    pts = _dh_origins(q, [0.1273, 0, 0, 0.163941, 0.1157, 0.0922], [0, -0.612, -0.5723, 0, 0, 0],
                      [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0], [0.0, 0.0, 0.1])
    t = np.linspace(0, 1, samples)[None, None, :, None]
    links = (pts[:, 1:-1, None] + t * (pts[:, 2:] - pts[:, 1:-1])[:, :, None]).reshape(n, -1, 3)
    return q, flagged, pts, links


def test_the_arm_keeps_out_of_the_trackers_head():
    """A tracker set 0.5 m in front of the UR10 at shoulder height (inside its reach: the audit's arm passed 8 mm
    from one): with a floor (the arm checked), the arm's links keep out of a 0.3 m box around it grown by the link
    radius; the poses flagged are those whose links, sampled densely with an independent forward kinematics, enter
    the box (2 mm either way from its faces left out)."""
    tracker = np.array([0.5, 0.0, 0.3])
    q, flagged, pts, seg = _with_tracker(tracker, 1500, 8, "arm into the tracker", 201)
    def inside(grow):
        return np.any(np.all(np.abs(seg - tracker) < 0.15 + 0.05 + grow, axis=2), axis=1)
    small, big = inside(-2e-3), inside(2e-3)
    clear = small == big
    assert flagged.sum() > 50 and clear.sum() > 1400
    assert np.array_equal(flagged[clear], small[clear])


def test_a_link_across_the_trackers_line_of_sight_is_out_of_the_cell():
    """The arm between the reflector and the tracker blocks the beam (the audit's design with the tracker inside the
    reach: 10 of 20 poses): with a floor (the arm checked), a pose whose links come within the link radius of the
    beam (from 0.1 m out from the target to the tracker) is out; the poses flagged are those an independent forward
    kinematics and a dense sampling of the links and the beam find so (2 mm either way left out)."""
    tracker = np.array([1.2, 0.3, 0.2])
    q, flagged, pts, links = _with_tracker(tracker, 300, 9, "arm across the line of sight", 101)
    target = pts[:, -1]
    ray = tracker - target
    dist = np.linalg.norm(ray, axis=1)
    start = target + ray * (np.minimum(0.1, dist / 2) / dist)[:, None]
    beam = start[:, None] + np.linspace(0, 1, 801)[None, :, None] * (tracker - start)[:, None]
    gap = np.array([np.linalg.norm(links[k][:, None] - beam[k][None], axis=2).min() for k in range(len(q))])
    clear = np.abs(gap - 0.05) > 2e-3
    assert flagged.sum() > 10 and clear.sum() > 250
    assert np.array_equal(flagged[clear], (gap < 0.05)[clear])
