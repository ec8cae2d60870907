"""Yaskawa PULSE positions compensated with the robot file's pulses per degree (kincal.compensate.branch): a GP7
file given each joint's pulses_per_degree (saved and reloaded), a job of PULSE positions: the written counts are
whole, and turned into joints here (counts / pulses per degree) they put the calibrated arm where the nominal
arm was at the old counts, to what half a pulse on each joint moves the flange (bounded here by finite
differences); without pulses per degree each PULSE target is refused with the reason, by line."""
import numpy as np

import kincal
from kincal.compensate.branch import PULSES_WHY, compensate_branches
from kincal.io import ROWS, read_program

PPD = np.array([1456.356, -1450.212, 1165.089, 888.889, 888.889, 472.334])  # pulses per degree, signed (made up)
Q = np.array([[10.0, 20.0, -15.0, 30.0, -40.0, 60.0], [-35.0, 5.0, 25.0, -60.0, 50.0, -120.0]])  # deg


def _gp7_with_pulses(tmp_path):
    nominal = kincal.load_robot("motoman_gp7")
    path = tmp_path / "gp7.yaml"
    kincal.save_robot(nominal, path)
    text = path.read_text()
    for j, ppd in zip(("s", "l", "u", "r", "b", "t"), PPD):
        text = text.replace(f"{{name: {j}, ", f"{{name: {j}, pulses_per_degree: {ppd}, ", 1)
    path.write_text(text)
    return kincal.load_robot(str(path))


def _job(tmp_path, counts):
    lines = ["/JOB", "//NAME PULSES", "//POS", f"///NPOS {len(counts)},0,0,0,0,0", "///TOOL 0", "///POSTYPE PULSE",
             "///PULSE"] + [f"C{k:05d}=" + ",".join(str(int(c)) for c in row) for k, row in enumerate(counts)]
    lines += ["//INST", "///ATTR SC,RW", "NOP"] + [f"MOVJ C{k:05d} VJ=10.00" for k in range(len(counts))] + ["END"]
    path = tmp_path / "PULSES.JBI"
    path.write_text("\r\n".join(lines) + "\r\n")
    return read_program(str(path), "inform")


def _flange(robot, q_deg):
    return robot.with_tool_point(np.zeros(3)).pose_and_jacobian(np.radians(np.atleast_2d(q_deg)))[0][0]


def test_pulse_positions_compensated_with_pulses_per_degree(tmp_path):
    nominal = _gp7_with_pulses(tmp_path)
    again = tmp_path / "again.yaml"
    kincal.save_robot(nominal, again)  # pulses_per_degree saved and reloaded as given
    assert "pulses_per_degree: -1450.212" in again.read_text() and "pulses_per_degree" in again.read_text()
    true = kincal.perturb(nominal, seed=6)
    counts = np.round(Q * PPD)
    prog = _job(tmp_path, counts)
    assert [t.kind for t in prog.targets] == ["pulses", "pulses"]
    res = compensate_branches(true, nominal, prog, ROWS["inform"])
    assert not res.problems and sorted(res.texts) == [0, 1]
    (tmp_path / "OUT.JBI").write_text(prog.with_targets(res.texts))
    written = read_program(str(tmp_path / "OUT.JBI"), "inform")
    for old, new in zip(prog.targets, written.targets):
        assert np.array_equal(new.values, np.round(new.values)) and not np.array_equal(new.values, old.values)
        meant = _flange(nominal, old.values / PPD)
        q = new.values / PPD
        half = 0.5 / np.abs(PPD)  # deg: the most rounding to whole counts moves a joint
        bound = sum(np.linalg.norm(_flange(true, q + np.eye(6)[j] * half[j]) - _flange(true, q)) for j in range(6))
        assert np.linalg.norm(_flange(true, q) - meant) <= 1.01 * bound + 1e-9
        assert bound < 5e-5  # whole counts: tens of micrometres at most
    # every other byte as it was
    assert [line for line in (tmp_path / "OUT.JBI").read_text().splitlines() if not line.startswith("C0")] == \
        [line for line in (tmp_path / "PULSES.JBI").read_text().splitlines() if not line.startswith("C0")]


def test_without_pulses_per_degree_a_pulse_position_is_refused_by_line(tmp_path):
    nominal = kincal.load_robot("motoman_gp7")
    prog = _job(tmp_path, np.round(Q * PPD))
    res = compensate_branches(kincal.perturb(nominal, seed=6), nominal, prog, ROWS["inform"])
    assert res.refused == {0: PULSES_WHY, 1: PULSES_WHY} and not res.texts
    assert "line 8 (MOVJ C00000)" in res.problems[0] and "pulses_per_degree" in res.problems[0]
