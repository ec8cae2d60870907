"""Targets files of any length: compensated block by block (in worker processes when there are several
blocks), with the same commands, refusals and continuity checks as the whole file in one piece; a
Cartesian circle of 10⁴ UR5 poses past the wrist singularity; numbers written a table at a time."""
import numpy as np
import pytest

import kincal
from kincal._csv import open_stream
from kincal._numtext import fixed_lines
from kincal.compensate import (StreamJob, TargetsFormat, compensate, compensate_file, path_checked, solve_poses)
from kincal.errors import MeasurementError
from kincal.observe import from_matrices

NOMINAL = kincal.load_robot("ur5").with_tool_point([0.0, 0.0, 0.12])
Q_NEAR = np.array([0.3, -1.2, 1.5, -1.9, 1e-3, 0.4])  # the wrist 1 mrad from its singularity (j5 = 0)


def _circle(n: int = 10_000, radius: float = 0.05):
    """A horizontal circle of n TCP positions at the orientation of Q_NEAR, passing through its
    position, and the nominal commands along it (continued pose by pose on a coarse grid, then
    every pose from the interpolated commands): the controller's own smooth path."""
    p_near, R_near, Jp, Jw = NOMINAL.pose_and_jacobian(Q_NEAR[None])
    grad = np.linalg.solve(np.concatenate([Jp, Jw], axis=1)[0], np.eye(6))[4, :3]  # d j5 / d p, fixed orientation
    u = np.array([grad[0], grad[1], 0.0]) / np.hypot(grad[0], grad[1])
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    v = np.cross([0.0, 0.0, 1.0], u)
    p = p_near[0] + radius * (np.outer(1 - np.cos(t), u) + np.outer(np.sin(t), v))  # row 0: the near point
    R = np.repeat(R_near, n, axis=0)
    coarse = np.arange(0, n, max(1, n // 200))
    q, path = Q_NEAR[None], []
    for k in coarse:
        q = solve_poses(NOMINAL, p[k:k + 1], R[k:k + 1], q).q
        path.append(q[0])
    path = np.array(path + [path[0]])
    guess = np.column_stack([np.interp(np.arange(n), np.r_[coarse, n], path[:, j]) for j in range(6)])
    sol = solve_poses(NOMINAL, p, R, guess)
    assert sol.converged.all()
    return p, R, sol.q


def _write(path, q0, p, R, extra: str = "") -> None:
    quat = from_matrices(R, "quat-wxyz")
    lines = ["j1,j2,j3,j4,j5,j6,x,y,z,qw,qx,qy,qz"]
    lines += [",".join(repr(float(v)) for v in row) for row in np.column_stack([q0, p, quat])]
    path.write_text("\n".join(lines) + "\n" + extra)


def test_a_cartesian_circle_past_the_wrist_singularity_keeps_its_branch_and_refuses_only_there(tmp_path):
    """10⁴ poses on a circle whose TCP passes 1 mrad of j5 from the wrist singularity at constant
    orientation: away from it every corrected command reproduces its pose and follows the nominal
    path as smoothly; near it the corrections a real robot would need exceed the branch or
    continuity limits, and exactly those rows are refused and named. Streamed in 40 blocks by two
    processes, the file gives the same commands and the same refusals (the continuity check
    carries over block boundaries)."""
    p, R, q0 = _circle()
    assert np.rad2deg(np.abs(np.diff(q0, axis=0)).max()) < 0.5  # the nominal path is smooth ...
    assert np.abs(q0[:, 4]).min() < 2e-3  # ... and passes the singularity within 2 mrad
    true = kincal.perturb(NOMINAL, seed=5)
    comp = path_checked(true, compensate(true, p, q0, rotations=R, nominal=NOMINAL, rows=np.arange(2, 10_002)), q0)
    ok, near = comp.ok, np.abs(np.sin(q0[:, 4])) < 0.02
    assert 0 < (~ok).sum() < near.sum() and not (~ok & ~near).any()  # refused only near the singularity
    assert ok[np.abs(np.sin(q0[:, 4])) > 0.03].all()
    pt, Rt, _, _ = true.pose_and_jacobian(comp.q[ok])
    assert np.linalg.norm(pt - p[ok], axis=1).max() < 1e-6 and np.abs(Rt - R[ok]).max() < 1e-6
    assert np.rad2deg(np.abs(comp.q[ok] - q0[ok]).max()) < 5.0  # no branch flip
    steps, nominal_steps = np.abs(np.diff(comp.q[ok], axis=0)), np.abs(np.diff(q0[ok], axis=0))
    runs = np.diff(np.flatnonzero(ok)) == 1  # consecutive accepted rows
    assert (steps[runs] <= np.maximum(3 * nominal_steps[runs], np.deg2rad(0.5))).all()
    src, dst = tmp_path / "circle.csv", tmp_path / "cmd.csv"
    _write(src, q0, p, R)
    job = StreamJob(true, NOMINAL, TargetsFormat(pose=True), path=True)
    size = src.stat().st_size // 40
    res = compensate_file(job, str(src), str(dst), skip_unreachable=True, workers=2, block_bytes=size)
    table = np.loadtxt(dst, delimiter=",", skiprows=1)
    assert table[:, 0].astype(int).tolist() == comp.rows[ok].tolist() and res.accepted == ok.sum()
    assert np.abs(table[:, 1:7] - comp.q[ok]).max() < 1e-9
    assert sorted(res.problems) == sorted(comp.problems)


def test_streaming_does_not_depend_on_blocks_or_workers_and_keeps_row_numbers(tmp_path):
    """Comment and blank lines between blocks keep the file's line numbers as rows; one process and
    two give the same bytes; the progress callback ends at the file's size."""
    p, R, q0 = _circle(n=600)
    far = np.abs(np.sin(q0[:, 4])) > 0.05
    p, R, q0 = p[far], R[far], q0[far]
    src = tmp_path / "t.csv"
    _write(src, q0, p, R)
    lines = src.read_text().splitlines()
    lines[100:100] = ["# a comment", ""]
    src.write_text("\n".join(lines) + "\n")
    rows = np.r_[np.arange(2, 101), np.arange(103, 103 + len(q0) - 99)]  # lines 101-102: comment, blank
    true = kincal.perturb(NOMINAL, seed=2)
    job = StreamJob(true, NOMINAL, TargetsFormat(pose=True), path=True)
    seen = []
    out = {}
    for workers in (1, 2):
        out[workers] = tmp_path / f"c{workers}.csv"
        res = compensate_file(job, str(src), str(out[workers]), workers=workers, block_bytes=4000,
                              progress=lambda done, total: seen.append((done, total)))
        assert res.all_ok and res.written
    assert out[1].read_bytes() == out[2].read_bytes()
    table = np.loadtxt(out[1], delimiter=",", skiprows=1)
    assert table[:, 0].astype(int).tolist() == rows.tolist()
    ref = compensate(true, p, q0, rotations=R, nominal=NOMINAL)
    assert np.abs(table[:, 1:7] - ref.q).max() < 1e-9
    dones = [d for d, _ in seen[:len(seen) // 2]]
    assert dones == sorted(dones) and dones[-1] == src.stat().st_size and len(dones) > 10


def test_a_bad_cell_deep_in_a_long_file_is_named_and_nothing_is_written(tmp_path):
    p, R, q0 = _circle(n=1200)
    far = np.abs(np.sin(q0[:, 4])) > 0.05
    assert far.sum() > 500
    src, dst = tmp_path / "t.csv", tmp_path / "c.csv"
    _write(src, q0[far], p[far], R[far])
    lines = src.read_text().splitlines()
    cells = lines[400].split(",")
    cells[7] = "0,5"  # a decimal comma in a comma-separated file: one field too many
    lines[400] = ",".join(cells)
    src.write_text("\n".join(lines) + "\n")
    job = StreamJob(kincal.perturb(NOMINAL, seed=2), NOMINAL, TargetsFormat(pose=True))
    with pytest.raises(MeasurementError, match="row 401 has 14 fields, the header has 13"):
        compensate_file(job, str(src), str(dst), workers=2, block_bytes=3000)
    lines[400] = ",".join([*cells[:7], "abc", *cells[8:]])
    src.write_text("\n".join(lines) + "\n")
    with pytest.raises(MeasurementError, match="row 401, column 'y': 'abc' is not a finite number"):
        compensate_file(job, str(src), str(dst), workers=2, block_bytes=3000)
    assert sorted(x.name for x in tmp_path.iterdir()) == ["t.csv"]  # no output, no temporary file


def test_the_stream_reads_separators_and_decimal_commas_like_the_other_readers(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("\ufeff# exported\na;b;c\n1,5;2;3\n\n4;5,25;6\n")
    stream = open_stream(str(path), block_bytes=8)
    rows, values = zip(*(stream.numbers(b, ["c", "a"]) for b, _ in stream.blocks()))
    assert np.concatenate(rows).tolist() == [3, 5] and np.concatenate(values).tolist() == [[3, 1.5], [6, 4]]


def test_numbers_are_written_as_printf_would_with_ten_decimals():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(3000, 5)) * 10.0 ** rng.integers(-9, 6, size=(3000, 5))
    x[0] = [0.0, -0.0, 5.0, -1e-12, 99999.5]
    rows = np.arange(3000) * 7 + 2
    text = fixed_lines(rows, x, 10)
    ref = ["".join(",".join([str(r)] + [f"{v:.10f}".replace("-0.0000000000", "0.0000000000") for v in row]))
           for r, row in zip(rows, x)]
    got = text.splitlines()
    back, printf = np.loadtxt(got, delimiter=","), np.loadtxt(ref, delimiter=",")
    assert len(got) == 3000 and back[:, 0].tolist() == rows.tolist()
    assert (np.abs(back - printf) <= 1e-10 + 4 * np.spacing(np.abs(printf))).all()  # one unit in the 10th decimal ...
    assert (np.abs(back[:, 1:] - x) <= 0.5e-10 + 4 * np.spacing(np.abs(x))).all()  # ... where the scaled value sits at a half unit
    small = np.all(np.abs(x) < 10, axis=1)
    assert sum(a != b for a, b, s in zip(got, ref, small) if s) <= 1  # exact round-off there: printf's text
    assert fixed_lines(rows[:1], np.array([[1e6]]), 10) is None  # beyond exact integers: formatted otherwise


def test_a_unit_mistake_is_named_before_any_row_is_refused_for_it(tmp_path):
    """Targets in mm read as m, and joints in degrees read as radians: the file is refused with the
    unit the numbers are really in (not a TCP or convention mismatch, which they would also look like)."""
    p, R, q0 = _circle(n=400)
    job = StreamJob(kincal.perturb(NOMINAL, seed=2), NOMINAL, TargetsFormat(pose=True))
    src = tmp_path / "t.csv"
    _write(src, q0, p * 1e3, R)
    with pytest.raises(MeasurementError, match="target positions spread 1e\\+03x more .* they look like mm"):
        compensate_file(job, str(src), str(tmp_path / "c.csv"))
    _write(src, np.rad2deg(q0), p, R)
    with pytest.raises(MeasurementError, match="look like degrees"):
        compensate_file(job, str(src), str(tmp_path / "c.csv"))
    assert sorted(x.name for x in tmp_path.iterdir()) == ["t.csv"]


def test_refused_rows_are_listed_in_file_order():
    """Each check names its rows in turn (reach, then branch, then orientation), so the list came out as rows 7, 28,
    16; it is sorted by row, messages about every row first, ties kept in the order given."""
    from kincal.compensate.stream import _row_of
    given = ["row 28: b", "row 7: a", "the targets' frame: all", "row 16: c", "row 7: d"]
    assert sorted(given, key=_row_of) == ["the targets' frame: all", "row 7: a", "row 7: d", "row 16: c", "row 28: b"]


def test_the_commands_files_columns_are_those_the_guide_lists():
    """docs/howto/calibrate.md said every output had each joint's change and the tool orientation's: a hexapod's
    has neither (its legs follow from the pose, with no nominal legs), a serial robot's pose targets no orientation
    change; the guide now lists the three headers, and these are the ones written."""
    from pathlib import Path

    guide = " ".join((Path(__file__).resolve().parents[2] / "docs/howto/calibrate.md").read_text().split())
    ur5, hexapod = kincal.load_robot("ur5"), kincal.load_robot("hexapod")
    real = kincal.perturb(ur5, seed=1)
    for job in (StreamJob(real, ur5), StreamJob(real, ur5, TargetsFormat(pose=True)),
                StreamJob(hexapod, None, TargetsFormat(pose=True))):
        inner = {f"{d}{j}" for j in job.robot.joint_names[1:-1] for d in ("", "d_")}  # written as …
        cols = ["…" if c in inner else c for c in job.layout("commands.csv").header().strip().split(",")]
        short = ",".join(c for k, c in enumerate(cols) if not (c == "…" and cols[k - 1] == "…"))
        assert f"`{short}`" in guide, short
