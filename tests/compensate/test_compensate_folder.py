"""A controller's programs compensated as a folder (kincal.compensate.folder, kincal compensate FOLDER): a KRC
backup built from known frames with an encrypted (binary) module, a broken one and a file of another kind: the
report names every target and item with its status and the unreadable files with their line; nothing is written
while something is refused or unreadable unless --skip-unreachable; the written folder holds each program
compensated exactly as one file at a time would be, the others byte for byte; an output that exists or lies in
the folder read is refused before any work."""
import csv
import json

import numpy as np
import pytest

import kincal
from kincal.cli import main
from kincal.compensate import command_models, compensate_folder, tool_carry
from kincal.compensate.branch import compensate_branches
from kincal.io import ROWS, read_program

from test_krl_config import _cell


def _backup(tmp_path):
    nominal = kincal.load_robot("kuka_kr6r900sixx")
    program = _cell(tmp_path, nominal)
    (program / "secret.src").write_bytes(b"DEF secret()\n\x00\x17\x9c\x00encrypted\n")
    (program / "broken.src").write_text("DEF broken()\nLIN {X 1, Y 2\nEND\n")
    (program / "notes.txt").write_text("not a program\n")
    measured = kincal.simulate(kincal.perturb(nominal.with_tool_point([0, 0, 0.05]), seed=3),
                               nominal.sample_joints(60, seed=1), noise=0.0)
    res = kincal.calibrate(nominal.with_tool_point([0, 0, 0.05]), measured)
    kincal.save_robot(res.robot, tmp_path / "cal.yaml", calibration=res.record())
    return command_models(res.robot, res.record()["nominal"])  # both in the robot's base frame, as compensate


def _run(capsys, *argv):
    code = main(["compensate", *argv])
    out = capsys.readouterr()
    return code, out.err + out.out


def test_a_backup_folder_compensated_with_its_report(tmp_path, capsys):
    cal, nominal = _backup(tmp_path)
    krc = tmp_path / "KRC"
    res = compensate_folder(cal, nominal, str(krc), "krl", ROWS["krl"])
    assert [f.path for f in res.files] == ["R1/Program/broken.src", "R1/Program/move.src", "R1/Program/pick.dat",
                                           "R1/Program/secret.src", "R1/System/$config.dat", "STEU/Mada/$machine.dat"]
    status = {f.path: [(r[0], r[2]) for r in f.rows] for f in res.files}
    assert status["R1/Program/broken.src"] == [(2, "unreadable")] and status["R1/Program/secret.src"] == [
        (0, "unreadable")]
    assert "binary data" in res.files[3].rows[0][3] and "line 2, column" in res.files[0].rows[0][3]
    assert status["R1/Program/pick.dat"] == [(2, "compensated"), (4, "compensated"), (6, "compensated")]
    out = tmp_path / "KRC_cal"
    code, said = _run(capsys, str(tmp_path / "cal.yaml"), str(krc), "--program", "krl", "-o", str(out))
    assert code == 4 and "2 files unreadable; nothing written" in said and not out.exists()
    code, said = _run(capsys, str(tmp_path / "cal.yaml"), str(krc), "--program", "krl", "-o", str(out),
                      "--skip-unreachable")
    assert code == 0 and "4 targets compensated" in said
    shift, carry = tool_carry(cal.tool_point(), nominal.tool_point())  # the tool frames' TCPs move as --tcp's would
    assert f"TCP: {carry}" in said and 0 < np.linalg.norm(shift) <= 1e-3
    one = read_program(str(krc / "R1/Program/pick.dat"), "krl")  # one file at a time gives the same text
    alone = compensate_branches(cal, nominal, one, ROWS["krl"], carry=shift)
    assert (out / "R1/Program/pick.dat").read_bytes() == one.with_targets(alone.texts).encode()
    for same in ("R1/Program/secret.src", "R1/Program/broken.src", "R1/System/$config.dat"):
        assert (out / same).read_bytes() == (krc / same).read_bytes()
    assert not (out / "R1/Program/notes.txt").exists()
    rows = list(csv.DictReader(open(out / "kincal_report.csv", encoding="utf-8")))
    assert sum(r["status"] == "compensated" for r in rows) == 4 and sum(r["status"] == "unreadable" for r in rows) == 2
    code, said = _run(capsys, str(tmp_path / "cal.yaml"), str(krc), "--program", "krl", "-o", str(out))
    assert code != 0 and "exists; kincal writes a compensated folder only where there is none" in said
    code, said = _run(capsys, str(tmp_path / "cal.yaml"), str(krc), "--program", "krl", "-o", str(krc / "new"))
    assert code != 0 and "inside the folder read" in said


def test_the_real_krl_folder_report_counts_every_target_and_item(tmp_path):
    """The data folder's KRL programs: the report's rows are, file by file, the reader's targets (compensated
    or refused) and listed items."""
    from conftest import shared_dataset

    folder = shared_dataset("robot_programs") / "krl"
    nominal = kincal.load_robot("kuka_kr6r900sixx")
    res = compensate_folder(kincal.perturb(nominal, seed=1), nominal, str(folder), "krl", ROWS["krl"])
    assert len(res.files) == 82 and res.count("unreadable") == 0
    for f in res.files:
        prog = read_program(str(folder / f.path), "krl")
        assert f.count("compensated") + f.count("refused") + f.count("kept") == len(prog.targets) == f.targets
        assert f.count("listed") == len(prog.not_literal)
    assert res.count("compensated") + res.count("refused") + res.count("kept") == 11 and res.count("listed") == 322
    kept = [(f.path, line) for f in res.files for line, _, status, _ in f.rows if status == "kept"]
    assert len(kept) == res.count("kept") >= 1  # KUKA's home, A5 = 0: the wrist's axes in line
    for path, line in kept:
        q = next(t.values for t in read_program(str(folder / path), "krl").targets if t.line == line)
        assert abs(q[4]) < 1e-9


@pytest.mark.parametrize("flag", [["--program", "ur"], ["--program", "krl", "--tcp", "0,0,0.1"]])
def test_a_folder_with_what_does_not_apply_is_refused(tmp_path, capsys, flag):
    _backup(tmp_path)
    code, said = _run(capsys, str(tmp_path / "cal.yaml"), str(tmp_path / "KRC"), *flag, "-o", str(tmp_path / "o"))
    assert code != 0 and ("a folder of programs" in said or "--tcp: not for krl programs" in said)
    assert not (tmp_path / "o").exists()


def test_a_refused_folder_says_why_each_target_was_refused(tmp_path, capsys):
    """Nothing written without --skip-unreachable: the output lists each refused target with its file, line and
    reason (it gave only counts, and the report CSV is written only with the folder)."""
    nominal = kincal.load_robot("kuka_kr6r900sixx")
    q = nominal.sample_joints(60, seed=1)
    res = kincal.calibrate(nominal, kincal.simulate(kincal.perturb(nominal, seed=2), q, noise=0.0),
                           kincal.FitOptions(diagnose=False))
    kincal.save_robot(res.robot, tmp_path / "cal.yaml", calibration=res.record())
    folder = tmp_path / "KRC" / "R1" / "Program"
    folder.mkdir(parents=True)
    (folder / "a.src").write_text("DEF a()\nPTP {A1 10, A2 -80, A3 100, A4 5, A5 30, A6 10}\n"
                                  "PTP {A1 10, A2 -200, A3 100, A4 5, A5 30, A6 10}\nEND\n")
    code, said = _run(capsys, str(tmp_path / "cal.yaml"), str(tmp_path / "KRC"), "--program", "krl", "-o",
                      str(tmp_path / "out"))
    assert code == 4 and not (tmp_path / "out").exists()
    (line,) = [x for x in said.splitlines() if x.startswith("refused: ")]
    assert line.startswith("refused: R1/Program/a.src: line 3 (PTP): the target's own joints are outside the robot's "
                           "limits: a2 -200.000°")


def test_programs_of_other_languages_in_the_folder_are_reported_as_left_out(tmp_path, capsys):
    """A folder of mixed vendors compensated as KRL: the RAPID, FANUC, INFORM and URScript files were left out of the
    written folder without a word (exit 0). They are not read (another language) and are named as left out, on the
    terminal (how many, which, and the --program to use), in kincal_report.csv (one row each) and in --json; the exit
    code is as it was (0: nothing refused), and a folder with none of the language says what it holds."""
    import json

    _backup(tmp_path)
    krc = tmp_path / "KRC"
    others = {"R1/Program/Module1.mod": "rapid", "R1/Program/HOME.ls": "fanuc", "R1/FORMCUT.JBI": "inform",
              "prog.script": "ur"}
    for path in others:
        (krc / path).write_text("not read\n")
    (krc / "R1/Program/broken.src").unlink()
    (krc / "R1/Program/secret.src").unlink()
    out = tmp_path / "KRC_cal"
    code, said = _run(capsys, str(tmp_path / "cal.yaml"), str(krc), "--program", "krl", "-o", str(out))
    assert code == 0, said
    expected = sorted(others.items())
    named = ", ".join(f"{p} ({lang})" for p, lang in expected)
    assert (f"left out: 4 program(s) of other languages than krl, not read and not written: {named} (compensate "
            f"each with its own --program)") in said
    rows = [r for r in csv.DictReader(open(out / "kincal_report.csv", encoding="utf-8")) if r["status"] == "left out"]
    assert [(r["file"], r["line"]) for r in rows] == [(p, "0") for p, _ in expected]
    assert all(f"--program {lang}" in r["why"] for r, (_, lang) in zip(rows, expected))
    assert not any((out / p).exists() for p in others)
    code, said = _run(capsys, str(tmp_path / "cal.yaml"), str(krc), "--program", "krl", "-o", str(tmp_path / "j"),
                      "--json")
    got = json.loads(said)
    assert code == 0 and got["left out"] == 4
    assert [(f["path"], f["language"]) for f in got["left_out_files"]] == expected
    lone = tmp_path / "lone"
    lone.mkdir()
    (lone / "Module1.mod").write_text("not read\n")
    code, said = _run(capsys, str(tmp_path / "cal.yaml"), str(lone), "--program", "krl", "-o", str(tmp_path / "x"))
    assert code != 0 and "no krl program in this folder" in said and "Module1.mod (rapid)" in said


def test_a_program_for_another_robot_of_the_vendor_is_refused_whole(tmp_path, capsys):
    """An IRB 1200 module (rparak/ABB_EGM_Python, 142 robtargets in tool0 and wobj0) compensated with an IRB 120's
    calibration: 73 of its targets put the wrist centre (72 mm behind tool0, along its z) more than the IRB 120's
    270 + √(70² + 302²) = 580 mm from axis 2 (the test's own closed form), more than half of 142 on their own. The
    module looks written for another robot and says so; none of its targets is compensated, and --skip-unreachable
    writes it as it was, each target marked. Before, the 57 the IRB 120 reaches were written corrected with it."""
    from conftest import shared_dataset
    from scipy.spatial.transform import Rotation

    source = shared_dataset("robot_programs") / "rapid" / "rparak__ABB_EGM_Python/ABB/IRB12000/RAPID/T_ROB1/Module1.mod"
    folder = tmp_path / "HOME"
    folder.mkdir()
    (folder / "Module1.mod").write_bytes(source.read_bytes())
    prog = read_program(str(folder / "Module1.mod"), "rapid")
    v = np.array([t.values for t in prog.targets])
    wrist = v[:, :3] - 0.072 * Rotation.from_rotvec(v[:, 3:6]).as_matrix()[:, :, 2]
    beyond = np.linalg.norm(wrist - [0.0, 0.0, 0.29], axis=1) > 0.27 + np.hypot(0.07, 0.302)
    assert len(prog.targets) == 142 and beyond.sum() == 73 > 142 / 2
    nominal = kincal.load_robot("abb_irb120")
    res = kincal.calibrate(nominal, kincal.simulate(kincal.perturb(nominal, seed=3), nominal.sample_joints(60, seed=1),
                                                    noise=0.0), kincal.FitOptions(diagnose=False))
    kincal.save_robot(res.robot, tmp_path / "cal.yaml", calibration=res.record())
    code = main(["compensate", str(tmp_path / "cal.yaml"), str(folder), "--program", "rapid", "-o",
                 str(tmp_path / "out"), "--skip-unreachable", "--json"])
    said = json.loads(capsys.readouterr().out)
    (f,) = said["files"]
    assert code == 0 and said["compensated"] == 0 and said["refused"] == 142
    out = int(f["foreign"].split(" of its 142 ")[0].rsplit(" ", 1)[1])
    assert f["foreign"].startswith("the program looks written for another robot") and 73 <= out < 142
    lines = {t.line for t, far in zip(prog.targets, beyond) if far}
    assert all("does not reach this pose" in why for line, _, status, why in f["rows"] if line in lines)
    again = read_program(str(tmp_path / "out" / "Module1.mod"), "rapid")
    assert np.array_equal([t.values for t in again.targets], v)  # as it was
    assert all("kincal: not compensated" in line for line in again.text.splitlines()[2:144])
