"""The Python snippets of the documentation run as written: every name a snippet uses is imported or assigned
before it on its page, or is one of the reader's own inputs the page speaks of (its joints, targets, test data),
docs/howto/python.md runs from top to bottom with those inputs made from the real UR5 data, and
docs/howto/compensate.md's program snippet runs on a KRL module."""
import ast
import builtins
import re
from pathlib import Path

import numpy as np
import pytest

import kincal
from kincal.io import read_program
from conftest import DATA, ROOT, UR5_COLS

FENCE = re.compile(r"```python\n(.*?)```", re.S)
PAGES = sorted(p.relative_to(ROOT).as_posix() for p in [ROOT / "README.md", *(ROOT / "docs").rglob("*.md")]
               if "```python" in p.read_text())
READER = {  # per page: the names its snippets take from the reader (data the page describes, not defines)
    "docs/howto/python.md": {"q", "q_of_use", "test_meas", "targets", "q_nominal", "use_q"},
}


def _blocks(page: str) -> list[str]:
    return FENCE.findall((ROOT / page).read_text())


def _names(node: ast.AST, ctx: type) -> set[str]:
    """The plain names a statement loads (ctx ast.Load) or binds (ast.Store: assignments, for and comprehension
    targets, imports, function and lambda arguments, function and class names)."""
    out = set()
    for n in ast.walk(node):
        if isinstance(n, ast.Name) and isinstance(n.ctx, ctx):
            out.add(n.id)
        elif ctx is ast.Store and isinstance(n, (ast.Import, ast.ImportFrom)):
            out.update((a.asname or a.name).split(".")[0] for a in n.names)
        elif ctx is ast.Store and isinstance(n, ast.arg):
            out.add(n.arg)
        elif ctx is ast.Store and isinstance(n, (ast.FunctionDef, ast.ClassDef)):
            out.add(n.name)
    return out


def undefined(page: str, reader: set[str]) -> list[str]:
    """The names the page's snippets use before any snippet of the page defines them (in page order), as
    'block k, line l: name'."""
    known, out = set(dir(builtins)) | reader, []
    for k, block in enumerate(_blocks(page), 1):
        for stmt in ast.parse(block).body:
            bound = _names(stmt, ast.Store)
            out += [f"block {k}, line {stmt.lineno}: {n}" for n in sorted(_names(stmt, ast.Load) - known - bound)]
            known |= bound
    return out


def test_the_check_finds_a_name_used_before_its_import():
    """The check itself: numpy used with only kincal imported (python.md's first snippet before) is found."""
    page = ROOT / "docs" / "howto" / "python.md"
    first = _blocks(page.relative_to(ROOT).as_posix())[0]
    assert "import numpy as np" in first
    broken = first.replace("import numpy as np\n", "")
    known, missing = set(dir(builtins)) | READER["docs/howto/python.md"], []
    for stmt in ast.parse(broken).body:
        missing += sorted(_names(stmt, ast.Load) - known - _names(stmt, ast.Store))
        known |= _names(stmt, ast.Store)
    assert missing == ["np"]


@pytest.mark.parametrize("page", PAGES)
def test_every_name_a_snippet_uses_is_defined_on_its_page(page):
    assert PAGES, "no Python snippet found in the documentation"
    assert not undefined(page, READER.get(page, set())), undefined(page, READER.get(page, set()))


@pytest.mark.slow
def test_the_python_page_runs_as_written(tmp_path, monkeypatch):
    """docs/howto/python.md's snippets, one after the other in one namespace, with the reader's inputs: grid.csv
    the first 200 poses of the real UR5 grid (its joint columns for `joint_cols=[...]`), the 20 random poses as
    the test data and the poses of use, and targets the nominal model reaches at nominal joints. Each call does
    what its comment says: the calibration converges, the saved record reloads, the commands reach the
    targets."""
    rows = (DATA / "ur5_grid.csv").read_text().splitlines()
    (tmp_path / "grid.csv").write_text("\n".join(rows[:201]) + "\n")
    monkeypatch.chdir(tmp_path)
    robot = kincal.load_robot("ur5")
    test = kincal.read_measurements(DATA / "ur5_random.csv", robot, UR5_COLS, length_unit="mm", angle_unit="deg")
    q_nominal = robot.sample_joints(5, seed=3)
    ns = {"q": robot.sample_joints(20, seed=1), "q_of_use": test.q, "use_q": test.q, "test_meas": test,
          "q_nominal": q_nominal, "targets": robot.forward(q_nominal)}
    assert set(ns) == READER["docs/howto/python.md"]
    for k, block in enumerate(_blocks("docs/howto/python.md"), 1):
        assert "joint_cols=[...]" in block or k > 1
        exec(compile(block.replace("joint_cols=[...]", f"joint_cols={UR5_COLS!r}"), f"python.md block {k}", "exec"),
             ns)
    assert ns["res"].converged and ns["stats"].n == 20 and ns["stats"].mean < 1e-3
    saved = kincal.models.load_calibration_record("calibrated.yaml")
    assert saved is not None and np.shape(saved["covariance"]) == (len(ns["res"].names),) * 2
    assert bool(np.all(ns["cmd"].ok))
    assert np.abs(ns["model"].forward(ns["cmd"].q) - ns["targets"]).max() < 1e-9
    assert ns["d"].q.shape == (60, 6) and 0 < ns["d"].efficiency <= 1


KRL_SRC = """&ACCESS RVP
DEF PICK()
  PTP XHOME
  ;FOLD PTP P1 Vel=100 % PDAT1 Tool[1] Base[0];%{PE}
  FDAT_ACT=FP1
  PTP XP1
  ;ENDFOLD
  PTP XHOME
END
"""
KRL_DAT = """&ACCESS RVP
DEFDAT PICK
DECL E6POS XP1={X 658.901,Y -171.045,Z 854.246,A -28.700,B 46.708,C 0.581,S 2,T 34,E1 0.0,E2 0.0,E3 0.0}
DECL E6AXIS XHOME={A1 0.000,A2 -90.000,A3 90.000,A4 0.000,A5 45.000,A6 0.000,E1 0.0,E2 0.0,E3 0.0}
DECL FDAT FP1={TOOL_NO 1,BASE_NO 0,IPO_FRAME #BASE,POINT2[] " "}
ENDDAT
"""


def test_the_program_snippet_runs_on_a_krl_module(tmp_path, monkeypatch, capsys):
    """docs/howto/compensate.md's read_program snippet, as written, on a KRL module in the usual layout (the
    points in the .dat, the .src moving to them by name): it reads the .dat's two targets with their frames, and
    target 0 written again leaves the file as it was. Read from the .src, the module has no target (the snippet
    took prog.targets[0] there: IndexError)."""
    folder = tmp_path / "R1" / "Program"
    folder.mkdir(parents=True)
    (folder / "pick.src").write_text(KRL_SRC)
    (folder / "pick.dat").write_text(KRL_DAT)
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    for k, block in enumerate(_blocks("docs/howto/compensate.md"), 1):
        exec(compile(block, f"compensate.md block {k}", "exec"), ns)
    assert [(t.variable, t.kind) for t in ns["prog"].targets] == [("XP1", "pose"), ("XHOME", "joints")]
    assert ns["prog"].targets[0].frames == ("TOOL_NO 1", "BASE_NO 0")
    assert ns["text"] == KRL_DAT
    src = read_program(str(folder / "pick.src"), "krl")
    assert not src.targets and [what for _, what, _ in src.not_literal] == ["PTP XHOME", "PTP XP1", "PTP XHOME"]
    assert capsys.readouterr().out.splitlines()[0] == "3 E6POS XP1 pose (2, 34) ('TOOL_NO 1', 'BASE_NO 0')"


def _positioner_halves(tmp_path):
    """The positioner's even and odd data rows as two files (the pages' even.csv and odd.csv)."""
    from conftest import POSITIONER
    lines = (POSITIONER / "measurements.csv").read_text().splitlines()
    even, odd = tmp_path / "even.csv", tmp_path / "odd.csv"
    even.write_text("\n".join([lines[0], *lines[1::2]]) + "\n")
    odd.write_text("\n".join([lines[0], *lines[2::2]]) + "\n")
    return even, odd


@pytest.mark.slow
def test_the_positioner_figures_of_the_measurements_page_are_those_printed(tmp_path, capsys):
    """docs/howto/measurements.md's held-out figures of the positioner, each as the command it names prints it:
    evaluate and calibrate --test with the frame refitted, with --same-frame, with --refit-target (it called the
    same-frame figures 0.3819 mm / 0.8465 mrad, the refitted frame's, and the refitted probe's 0.8433 mrad)."""
    from conftest import POSITIONER_MODEL
    from kincal.cli import main
    text = " ".join((ROOT / "docs" / "howto" / "measurements.md").read_text().split())
    said = re.search(r"On the positioner's odd rows.*?The report", text).group(0)
    pairs = re.findall(r"([\d.]+) mm / ([\d.]+) mrad", said)
    even, odd = _positioner_halves(tmp_path)
    flags, cal = ["--type", "pose", "--joint-cols", "q1,q2"], tmp_path / "cal.yaml"
    printed = []
    for extra in ([], ["--same-frame"], ["--refit-target"]):
        assert main(["calibrate", str(POSITIONER_MODEL), str(even), "--test", str(odd), *flags, *extra,
                     "-o", str(cal), "--force"]) == 0
        out = " ".join(capsys.readouterr().out.split())  # the lines as printed, however the terminal wraps them
        test = re.search(r"held out pose \([^)]*odd.csv\): [^→]*→ mean ([\d.]+) mm, mean ([\d.]+) mrad", out)
        assert main(["evaluate", str(cal), str(odd), *flags, *extra]) == 0
        judged = re.search(r"\): mean ([\d.]+) mm, mean ([\d.]+) mrad", " ".join(capsys.readouterr().out.split()))
        assert test.groups() == judged.groups(), extra  # both commands print the one figure
        printed.append(test.groups())
    assert pairs == printed


@pytest.mark.slow
def test_the_six_d_tutorial_states_the_fit_it_prints():
    """examples/plot_03's prose quotes the fit's "before" and "after" on the even rows as the fit prints them (it
    said the rotation "before" held the unknown target orientation; the target's turn is registered: 0.8244
    mrad, 14.8929 mrad before that)."""
    from conftest import POSITIONER, POSITIONER_MODEL
    from kincal.identify import fit_observations
    from kincal.observe import ObservationFormat, read_observations
    prose = " ".join(line.lstrip("# ") for line in (ROOT / "examples" / "plot_03_six_d_poses.py").read_text()
                     .splitlines() if line.startswith("#"))
    quoted = re.search(r"mean ([\d.]+) mm and ([\d.]+) mrad, the calibration's ([\d.]+) mm and ([\d.]+) mrad",
                       prose).groups()
    robot = kincal.load_robot(POSITIONER_MODEL)
    fmt = ObservationFormat(kind="pose", joint_cols=("q1", "q2"), std_pos=0.1e-3, std_rot=1e-3)
    poses = read_observations(POSITIONER / "measurements.csv", robot, fmt)
    fit = fit_observations(robot, [poses.subset(np.arange(0, len(poses), 2))])
    line = re.search(r"mean ([\d.]+) mm, mean ([\d.]+) mrad\s+→\s+mean ([\d.]+) mm, mean ([\d.]+) mrad", str(fit))
    assert quoted == line.groups()
    assert "unknown orientation" not in prose and "also contains" not in prose


@pytest.mark.parametrize("name", ["plot_01_calibrate_ur5.py", "plot_02_sockets.py", "plot_03_six_d_poses.py",
                                  "plot_04_sessions.py"])
def test_a_tutorial_copied_elsewhere_names_the_variable_that_finds_the_datasets(tmp_path, name):
    """A tutorial copied out of the checkout failed with "../../shared/datasets/...: cannot read the file": it says
    the folder it looked in is not there and names KINCAL_SHARED_DATASETS, in one line, before any work."""
    import os
    import subprocess
    import sys
    (tmp_path / name).write_text((ROOT / "examples" / name).read_text())
    env = {k: v for k, v in os.environ.items() if k != "KINCAL_SHARED_DATASETS"}
    env.update(MPLBACKEND="Agg", PYTHONPATH=str(ROOT / "src"))
    run = subprocess.run([sys.executable, name], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    folder = re.search(r'DATA = DATASETS / "(\w+)"', (ROOT / "examples" / name).read_text()).group(1)
    where = os.path.join(os.path.relpath(tmp_path.parent, tmp_path), "..", "shared", "datasets", folder)  # ROOT/../…
    assert run.returncode == 1 and "Traceback" not in run.stderr
    assert run.stderr.strip() == (f"{where}: no such folder; set KINCAL_SHARED_DATASETS to the folder that holds "
                                  f"kincal's datasets (shared/datasets beside the checkout)")
