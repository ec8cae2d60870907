"""House rules that keep kincal easy to read: short functions, no capability probes, a small public
face that imports fast, feasible random poses, papers cited by name, an architecture page that
describes every room."""
import ast
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import kincal
from kincal.cli import build_parser, main
from kincal.papers import GUO2024_TITLE, PUU3_2024_TITLE

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "kincal"
MAX_LINES = 60
LONG_FUNCTIONS: dict[str, str] = {}  # "file:function" -> why it may be longer; none today
HEAVY = ("scipy", "matplotlib", "jinja2", "threadpoolctl", "rich")
# "seed" is a random seed and nothing else: never a paper's nickname
PAPER_SEED = re.compile(r"(?<![-\w])(?<!random )seed[ _-]?[12](?![0-9])|\bseed(?:'s| paper| papers)\b|\bthe seed\b",
                        re.I)


def _sources():
    return sorted(SRC.rglob("*.py"))


def _functions():
    for path in _sources():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                yield path, node


def _code_lines(f) -> int:
    """A function's lines, its docstring left out (the numpydoc sections a reader needs are not code)."""
    lines = f.end_lineno - f.lineno + 1
    first = f.body[0]
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        lines -= first.end_lineno - first.lineno + 1
    return lines


def test_every_function_fits_on_a_screen():
    long = [f"{p.relative_to(SRC)}:{f.name} ({_code_lines(f)} lines)" for p, f in _functions()
            if _code_lines(f) > MAX_LINES and f"{p.relative_to(SRC)}:{f.name}" not in LONG_FUNCTIONS]
    assert not long, long


# The flow runs one way: a room imports only rooms of a lower rank (leaf modules are rank 0).
RANKS = {"errors": 0, "units": 0, "papers": 0, "ties": 0, "checks": 0, "_atomic": 0, "_threads": 0, "_memory": 0, "_numtext": 0, "_numstyle": 0, "_collector": 0, "_stats": 0, "_frozen": 0, "_csv": 1, "models": 1, "analysis": 2,
         "io": 2, "observe": 2, "design": 3, "identify": 3, "compensate": 3, "simulate": 3, "studies": 4, "report": 4, "history": 4,
         "cli": 5}


def _imports(path: Path):
    """(importing room, imported room) for every kincal import in a module."""
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    package = parts[:-1] if path.name != "__init__.py" else parts[:-1]
    here = parts[1] if len(parts) > 2 else parts[-1]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = list(package[:len(package) - node.level + 1])
            targets = [base + node.module.split(".")] if node.module else [base + [a.name] for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            targets = [(node.module or "").split(".")]
        elif isinstance(node, ast.Import):
            targets = [a.name.split(".") for a in node.names]
        else:
            continue
        for t in targets:
            if t[0] == "kincal" and len(t) > 1:
                yield here, t[1]


def test_the_flow_is_one_way():
    wrong = sorted({(a, b) for p in _sources() for a, b in _imports(p)
                    if a in RANKS and b in RANKS and a != b and RANKS[b] >= RANKS[a]})
    assert wrong == []
    assert set(RANKS) >= {p.stem if p.is_file() else p.name for p in SRC.iterdir()
                          if not p.name.startswith("__") and p.name != "py.typed"}


def test_no_capability_probes():
    """What a robot can do is declared on Robot: no hasattr/getattr anywhere in the package."""
    probes = [f"{p.relative_to(SRC)}:{node.lineno}" for p in _sources() for node in ast.walk(ast.parse(p.read_text()))
              if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("hasattr",
                                                                                                     "getattr")]
    assert probes == []


def test_type_ignores_are_few_and_explained():
    lines = [(p, line) for p in _sources() for line in p.read_text().splitlines() if "# type: ignore" in line]
    assert len(lines) <= 3, lines
    for p, line in lines:  # each names its error code and says why
        assert re.search(r"# type: ignore\[[\w-]+\]\s+#\s*\w+", line), (p, line)


def test_small_public_face():
    assert len(kincal.__all__) <= 40 and len(set(kincal.__all__)) == len(kincal.__all__)
    assert {"Robot", "ImplicitRobot", "calibrate", "select_poses", "compensate", "FitOptions"} <= set(kincal.__all__)
    for name in kincal.__all__:  # every name resolves (build_report loads the report room on first use)
        assert getattr(kincal, name) is not None


@pytest.mark.slow
def test_import_loads_no_heavy_library():
    code = f"import sys, kincal; print([m for m in sys.modules if m.split('.')[0] in {HEAVY!r}])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    code = "import sys, kincal; kincal.build_report; print('matplotlib' in sys.modules, 'jinja2' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["True", "True"]  # loaded when used


@pytest.mark.parametrize("name", kincal.bundled_robots())
def test_random_poses_are_feasible_on_every_bundled_robot(name):
    robot = kincal.load_robot(name)
    q = robot.sample_joints(400, seed=3)
    assert q.shape == (400, robot.n_joints) and robot.feasible(q).all()
    lo, hi = robot.sampling_limits()
    first = np.random.default_rng(3).uniform(lo, hi, size=(400, robot.n_joints))
    if robot.feasible(first).all():  # nothing rejected: exactly the generator's first draws
        np.testing.assert_array_equal(q, first)
    else:  # guo3t2r: |ψ| ≤ 45° and the carriage travel reject about 2 draws in 3; a hexapod's legs drawn
        # independently miss its workspace (about 1 in 14), so it draws platform poses instead
        assert robot.feasible(first).mean() < (0.5 if name == "guo3t2r" else 1.0)


def test_limits_cannot_be_changed_in_place():
    robot = kincal.load_robot("guo3t2r")
    for limits in (robot.lower, robot.upper, robot.inner.lower):
        with pytest.raises(ValueError):
            limits[0] = 0.0


def _json_keys(obj, out):
    if isinstance(obj, dict):
        for k, v in obj.items():
            out.add(str(k))
            _json_keys(v, out)
    elif isinstance(obj, list):
        for v in obj:
            _json_keys(v, out)
    return out


@pytest.mark.slow
@pytest.mark.xdist_group("guo2024-demo")
def test_papers_are_cited_not_nicknamed(tmp_path, capsys, guo2024_demo):
    """No user-visible "seed" meaning a paper: README, the documentation's pages and examples, --help of every
    command, bundled robot files, JSON keys of the results."""
    texts = {"README.md": (ROOT / "README.md").read_text()}
    for page in sorted([*(ROOT / "docs").rglob("*.md"), *(ROOT / "docs").rglob("*.rst"),
                        *(ROOT / "examples").glob("*.py")]):
        if "_build" not in page.parts:
            texts[str(page.relative_to(ROOT))] = page.read_text()
    parser = build_parser()
    texts["kincal --help"] = parser.format_help()
    subs = next(a for a in parser._actions if a.dest == "command")
    for name, sub in subs.choices.items():
        texts[f"kincal {name} --help"] = sub.format_help()
    for robot in kincal.bundled_robots():
        texts[robot] = kincal.load_robot(robot).description
    bad = {where: PAPER_SEED.findall(text) for where, text in texts.items() if PAPER_SEED.search(text)}
    assert bad == {}
    readme = " ".join(texts["README.md"].split())  # each paper by its authors or year and its own English title
    assert f'Guo et al. 2024, "{GUO2024_TITLE}"' in readme and f'2024, "{PUU3_2024_TITLE}"' in readme
    keys = _json_keys(guo2024_demo, set())  # demo --repeats 1 --json
    data = tmp_path / "d.csv"
    kincal.write_measurements(data, kincal.simulate(kincal.load_robot("puu3"),
                                                    kincal.load_robot("puu3").sample_joints(30, seed=1), 0.0))
    assert main(["calibrate", "puu3", str(data), "--base", "fixed", "--residual", "joint", "--method", "pso",
                 "--json"]) == 0
    _json_keys(json.loads(capsys.readouterr().out), keys)
    assert not [k for k in keys if PAPER_SEED.search(k) or "seed1" in k.lower()], sorted(keys)
    assert {"repeats", "error_model", "structure"} <= keys  # the renamed keys are there


def test_architecture_page_describes_every_room():
    page = (ROOT / "docs" / "architecture.md").read_text()
    rooms = sorted(p.name for p in SRC.iterdir() if p.is_dir() and not p.name.startswith("__"))
    assert rooms and [r for r in rooms if f"`{r}/`" not in page] == []
    for word in ("Glossary", "ImplicitRobot", "RANK_TOL", "FitOptions"):
        assert word in page
