"""design --program ur: the measurement program's moves (movej: straight lines in joint space) stay inside the cell,
no joint turns a whole turn between two poses, the poses come in a short-travel order, the CSV holds the program's
poses; design CAL --check draws inside the cell. Every pose and move is checked with an independent forward
kinematics (the UR5's DH table multiplied out, test_design_cell._dh_origins; the arm as the segments from the
shoulder through every joint frame to the tool)."""
import re

import numpy as np
import pytest

import kincal
from kincal.cli import main
from kincal.design import Cell, plan_route, travel_order, turned

from test_design_cell import _dh_origins

UR5_DH = ([0.089159, 0, 0, 0.10915, 0.09465, 0.0823], [0, -0.425, -0.39225, 0, 0, 0],
          [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0], [0.0, 0.00009, 0.031])  # d, a, alpha, the UR5's tool point
LO, HI, RADIUS = np.array([0.2, -0.3, 0.0]), np.array([0.6, 0.3, 0.4]), 0.05  # the audit's box, m; link radius
AUDIT = ["design", "ur5", "-m", "30", "--floor", "0mm", "--tracker", "2000,0,500mm", "--keep-out",
         "200,-300,0,600,300,400mm", "--angle-unit", "deg", "--program", "ur"]
MOVEJ = re.compile(r"movej\(\[([^\]]*)\]")


def _outside(q: np.ndarray, box: bool = True, tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """(N,) bool: the pose puts the tool point below z = 0 or in the box, or a link (21 points along each segment
    between the DH frames and to the tool, 50 mm thick) below z = 0 or into the box, by more than ``tol`` (m); and
    (N,) the lowest link or tool height, m."""
    pts = _dh_origins(q, *UR5_DH)
    t = np.linspace(0.0, 1.0, 21)[None, None, :, None]
    seg = (pts[:, 1:-1, None] + t * (pts[:, 2:] - pts[:, 1:-1])[:, :, None]).reshape(len(q), -1, 3)
    tip = pts[:, -1]
    low = np.minimum(seg[:, :, 2].min(axis=1) - RADIUS, tip[:, 2])
    inside = (np.any(np.all((seg > LO - RADIUS + tol) & (seg < HI + RADIUS - tol), axis=2), axis=1)
              | np.all((tip > LO + tol) & (tip < HI - tol), axis=1)) if box else np.zeros(len(q), bool)
    return (low < -tol) | inside, low


def _leaving(a: np.ndarray, b: np.ndarray, box: bool = True) -> bool:
    """Whether the joint-space line a → b leaves the cell at any of its samples 0.5° apart (largest joint)."""
    n = int(np.ceil(np.degrees(np.abs(b - a).max()) / 0.5)) + 1
    return bool(_outside(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a), box)[0].any())


def _program(path) -> tuple[np.ndarray, np.ndarray]:
    """The program's joint targets (rad) in order, and which are vias (a '# via' comment before the movej)."""
    lines = path.read_text().splitlines()
    found = [(k, MOVEJ.search(s)) for k, s in enumerate(lines)]
    targets = [(np.array([float(x) for x in m.group(1).split(",")]), lines[k - 1].lstrip().startswith("# via"))
               for k, m in found if m]
    return np.array([t for t, _ in targets]), np.array([v for _, v in targets])


def _greedy_turning(q: np.ndarray, joint: int, lo: float, hi: float) -> float:
    """A joint's whole turning through q with each value at the equivalent (±2πk, within lo..hi) nearest the
    previous one, the first as given nearest 0: a route any least-turning choice must not exceed."""
    prev, total = None, 0.0
    for x in q[:, joint]:
        options = [x + 2 * np.pi * k for k in range(-3, 4) if lo <= x + 2 * np.pi * k <= hi]
        v = min(options, key=lambda c: abs(c - (0.0 if prev is None else prev)))
        total += 0.0 if prev is None else abs(v - prev)
        prev = v
    return total


def test_the_audit_program_keeps_every_move_inside_the_cell(tmp_path, capsys):
    """The audit's command: every movej of the program (vias included), sampled 0.5° apart, keeps the arm (50 mm
    thick) above the floor and out of the box, by an independent forward kinematics; the moves that got a via are
    those whose straight line would leave the cell, and the output says how many; the CSV holds the program's poses
    in its order; no joint moves a whole turn between two targets (the design's order had a 658° swing), a joint of
    ±360° turns no more in all than turning each move the short way allows, and the travel is a third of the
    design's order's (11104° then)."""
    out = tmp_path / "d1.csv"
    assert main(AUDIT + ["-o", str(out)]) == 0
    said = capsys.readouterr()
    robot = kincal.load_robot("ur5")
    q = kincal.read_joints(str(out), robot, angle_unit="deg")
    assert np.abs(_dh_origins(q, *UR5_DH)[:, -1] - robot.forward(q)).max() < 1e-12
    targets, via = _program(out.with_suffix(".script"))
    assert len(q) == 30 and np.abs(targets[~via] - q).max() < 1e-9  # the CSV's poses, in the program's order
    assert not _outside(q)[0].any()
    assert not any(_leaving(a, b) for a, b in zip(targets[:-1], targets[1:]))
    direct = [_leaving(a, b) for a, b in zip(q[:-1], q[1:])]
    assert direct == _vias_before(via) and f"{sum(direct)} of 29 needed a via pose" in said.out
    assert "warning" not in said.err
    assert np.degrees(np.abs(np.diff(targets, axis=0))).max() < 300.0
    wide = robot.upper - robot.lower > 2 * np.pi
    for j in np.flatnonzero(wide):
        turning = float(np.abs(np.diff(q[:, j])).sum())
        assert turning <= _greedy_turning(q, j, robot.lower[j], robot.upper[j]) + 1e-9, j
    travel = np.degrees(np.abs(np.diff(targets, axis=0)).max(axis=1)).sum()
    assert travel < 11104 / 3


def _vias_before(via: np.ndarray) -> list[bool]:
    """Per move between two consecutive poses: whether a via comes between them."""
    out, pending = [], False
    for k, v in enumerate(via):
        if v:
            pending = True
        elif k:
            out.append(pending)
            pending = False
    return out


def test_a_program_without_a_cell_warns_that_its_moves_were_not_checked(tmp_path, capsys):
    """design --program ur without --floor or --keep-out: written, the poses in a short-travel order and with no
    whole turn, and a warning (and a comment in the program) that the moves were not checked; some of them do go
    through the floor (so the warning is not idle)."""
    out = tmp_path / "free.csv"
    assert main(["design", "ur5", "-m", "20", "--pool", "600", "--program", "ur", "-o", str(out)]) == 0
    said = capsys.readouterr()
    assert "moves were not checked against any cell" in said.err and "give --floor" in said.err
    assert "NOT checked against any cell" in out.with_suffix(".script").read_text()
    targets, via = _program(out.with_suffix(".script"))
    robot = kincal.load_robot("ur5")
    assert not via.any() and np.abs(targets - kincal.read_joints(str(out), robot)).max() < 1e-9
    assert np.degrees(np.abs(np.diff(targets, axis=0))).max() < 360.0
    assert any(_leaving(a, b, box=False) for a, b in zip(targets[:-1], targets[1:]))


def test_a_move_no_via_keeps_inside_is_refused_naming_it():
    """Two floor poses whose straight joint move dips under the floor, with no pool to draw vias from: refused,
    naming the move, the constraint broken and the lowest point on the way — which the independent kinematics
    finds there too; with a pool, a via keeps both halves above the floor."""
    robot = kincal.load_robot("ur5")
    floor = Cell(half_spaces=(((0.0, 0.0, 1.0), 0.0),), labels=(("half-space 1", "--floor"),))
    q = floor.pool(robot, 400, seed=5)
    for a, b in zip(q[0::2], q[1::2]):
        try:
            plan_route(robot, np.array([a, b]), floor)
        except ValueError as exc:
            said = str(exc)
            break
    else:
        pytest.fail("no pair of the pool refused")
    first, second = turned(robot, np.array([a, b])[travel_order(robot, np.array([a, b]))], floor)  # as routed
    assert "the move from pose 1 to pose 2" in said and "arm through --floor" in said
    low = float(re.search(r"z = (-?\d+) mm", said).group(1))
    n = int(np.ceil(np.degrees(np.abs(second - first).max()))) + 1
    pts = _dh_origins(first + np.linspace(0, 1, n)[:, None] * (second - first), *UR5_DH)
    assert low < 0 and abs(pts[:, 2:, 2].min() * 1e3 - low) < 1.0
    route = plan_route(robot, np.array([a, b]), floor, vias=floor.pool(robot, 2000, seed=6))
    assert route.n_vias == 1
    assert not any(_leaving(s, t, box=False) for s, t in zip(route.targets()[:-1], route.targets()[1:]))


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """A UR5 calibrated with the tracker 1.2 m in front of it and 0.6 m below its base (the file keeps the
    measurement frame), as `kincal calibrate -o` writes it."""
    nominal = kincal.load_robot("ur5")
    true = kincal.perturb(nominal, seed=2).with_params({"base.x": 1.2, "base.z": 0.6})
    q = nominal.sample_joints(60, seed=0)
    res = kincal.calibrate(nominal, kincal.simulate(true, q, 0.0, 0), kincal.FitOptions(diagnose=False))
    path = tmp_path_factory.mktemp("cal") / "cal.yaml"
    kincal.save_robot(res.robot, str(path), calibration=res.record())
    return path


def test_the_check_design_draws_inside_the_cell(calibrated, tmp_path, capsys):
    """design CAL --check with the cell flags: the 10 poses keep the arm above the floor and out of the box in the
    robot's own base frame (not the tracker's, 0.6 m off); without them, most poses leave the cell, and as
--candidates with --floor they are refused, the first named by its row."""
    free, kept = tmp_path / "free.csv", tmp_path / "kept.csv"
    assert main(["design", str(calibrated), "--check", "-o", str(free)]) == 0
    assert main(["design", str(calibrated), "--check", "-o", str(kept), "--floor", "0mm", "--keep-out",
                 "200,-300,0,600,300,400mm", "--tracker", "2000,0,500mm"]) == 0
    assert "10 check poses" in capsys.readouterr().out
    robot = kincal.load_robot("ur5")
    assert _outside(kincal.read_joints(str(free), robot))[0].sum() >= 5
    below = _outside(kincal.read_joints(str(free), robot), box=False)[0]  # the floor alone
    assert main(["design", str(calibrated), "--check", "--candidates", str(free), "-m", "4", "--floor", "0mm", "-o",
                 str(tmp_path / "rows.csv")]) == 1  # the user's rows: those outside the cell refused by number
    assert f"leave the cell (first: row {int(np.flatnonzero(below)[0]) + 2}: " in capsys.readouterr().err
    bad, low = _outside(kincal.read_joints(str(kept), robot), tol=2e-3)  # the calibrated arm: mm from the nominal
    assert len(low) == 10 and not bad.any()
