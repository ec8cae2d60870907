"""Every flag of calibrate and evaluate, for every measurement kind: read by the command, or refused
with its reason (kincal.identify.SCOPES). None is silently ignored."""
import argparse
import json
import re

import numpy as np
import pytest

import kincal
from kincal.cli import build_parser, main, prepared
from kincal.identify import SCOPES
from kincal.identify.applies import KINDS

# a valid value other than the default, for every flag some kind refuses
SAMPLE = {"--loss": ["huber"], "--method": ["pso"], "--residual": ["joint"], "--error-model": ["compliance"],
          "--payload": ["1"], "--drift": [], "--exclude": ["3"], "--reject-outliers": [], "--residuals": ["r.csv"],
          "--plot": ["f.png"], "--tracker-noise": ["0.02"], "--std-cols": ["none"], "--base": ["fixed"],
          "--prior": ["none"], "--orientation": ["quat-xyzw"], "--rot-cols": ["a,b,c,d"], "--std-rot": ["1mrad"],
          "--std-pos": ["0.1mm"], "--markers": ["m1"], "--label-col": ["socket"], "--group-col": ["plate"],
          "--distance": ["0,1,50"], "--plane": ["t:0,0,1,0"], "--xyz-cols": ["a,b,c"], "--same-frame": [],
          "--refit-target": [], "--covariate-cols": ["temperature"]}
NOT_TYPED = {"help", "given", "func", "command"}


class Reads(argparse.Namespace):
    """A namespace that remembers which options the command read."""

    def __getattribute__(self, name):
        if not name.startswith("_"):
            object.__getattribute__(self, "_read").add(name)
        return object.__getattribute__(self, name)


def _parse(argv):
    parser = build_parser()
    ns = Reads()
    object.__setattr__(ns, "_read", set())
    args = parser.parse_args(argv, namespace=ns)
    object.__getattribute__(args, "_read").clear()
    return parser, prepared(parser, args)


def _flags(parser, command):
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {a.dest: a.option_strings[-1] for a in sub.choices[command]._actions
            if a.option_strings and a.dest not in NOT_TYPED and a.default is not argparse.SUPPRESS}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A simulated UR5 file of every kind, and the flags that read it back."""
    d = tmp_path_factory.mktemp("kinds")
    out = {}
    for kind in KINDS:
        path = d / f"{kind}.csv"
        count = [] if kind in ("same-point", "plane") else ["--poses", "40"]  # sockets and planes: the plan's count
        assert main(["simulate", "ur5", "--type", kind, "--perturb", *count, "-o", str(path)]) == 0
        out[kind] = path
    return out


READ_BACK = {"same-point": ["--label-col", "point", "--group-col", "placement", "--distance", "0,1,0.05"],
             "plane": None}  # planes: the simulated file's known planes, from simulate's printed flags


def _read_back(kind, path, capsys):
    if kind == "plane":
        main(["simulate", "ur5", "--type", "plane", "--perturb", "-o", str(path)])
        text = capsys.readouterr().out
        return re.findall(r"--plane \S+", text)[0].split() + re.findall(r"--plane \S+", text)[1].split()
    return READ_BACK.get(kind) or []


@pytest.mark.slow
@pytest.mark.parametrize("command", ["calibrate", "evaluate"])
@pytest.mark.parametrize("kind", KINDS)
def test_every_flag_is_read_or_refused(files, kind, command, capsys, tmp_path):
    extra = _read_back(kind, files[kind], capsys)
    head = [command, "ur5", str(files[kind]), "--type", kind, *extra]
    parser, args = _parse(head)
    code = args.func(args)
    capsys.readouterr()
    for dest in ("force", "rebase"):  # flags that only modify others: checked when given (kincal.cli.prepared)
        if dest in _flags(parser, command):
            assert main([*head, f"--{dest}", *(["--same-frame"] if dest == "rebase" else [])]) == 1
            assert "--same-frame" in capsys.readouterr().err or dest == "force"
            object.__getattribute__(args, "_read").add(dest)
    assert code in (0, 4), f"{command} {kind} failed"
    read = object.__getattribute__(args, "_read")
    for dest, flag in _flags(parser, command).items():
        scope = SCOPES.get(dest)
        applies = scope is None or (kind in scope.kinds)
        if applies:
            assert dest in read, f"{command} --type {kind}: {flag} is neither read nor refused"
            continue
        assert flag in SAMPLE, f"{flag}: give a sample value in SAMPLE"
        code = main([*head, flag, *SAMPLE[flag]])
        err = capsys.readouterr().err
        assert code == 1 and "does not apply to" in err and flag in err, (flag, kind, err)


def test_every_scoped_option_is_a_flag_or_an_option():
    """The table names only options that exist (a flag of calibrate or evaluate, or a FitOptions field)."""
    import dataclasses

    import kincal

    parser = build_parser()
    known = set(_flags(parser, "calibrate")) | set(_flags(parser, "evaluate"))
    known |= {f.name for f in dataclasses.fields(kincal.FitOptions)}
    assert set(SCOPES) <= known, set(SCOPES) - known


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_every_report_flag_is_read(files, kind, capsys, tmp_path):
    """kincal report on a file calibrated from each kind reads every one of its flags."""
    extra = _read_back(kind, files[kind], capsys)
    cal = tmp_path / "cal.yaml"
    assert main(["calibrate", "ur5", str(files[kind]), "--type", kind, *extra, "-o", str(cal), "--force"]) in (0, 4)
    parser, args = _parse(["report", str(cal), "-o", str(tmp_path / "r.html")])
    assert args.func(args) in (0, 4)
    capsys.readouterr()
    read = object.__getattribute__(args, "_read")
    missing = [flag for dest, flag in _flags(parser, "report").items() if dest not in read and dest != "rebase"]
    assert missing == [], f"report of {kind} data: {missing} neither read nor refused"


# a valid value other than the default, for every flag of simulate's own table (kincal.cli.model.SIMULATE_SCOPES)
SIMULATE_SAMPLE = {"--poses": ["7"], "--poses-file": ["{d}/q.csv"], "--orientation": ["quat-xyzw"],
                   "--rot-cols": ["a,b,c,d"], "--std-rot": ["5mrad"], "--label-col": ["socket"],
                   "--group-col": ["plate"], "--distance": ["0,1,0.04"], "--plane": ["t:0,0,1,-0.2"],
                   "--xyz-cols": ["a,b,c"], "--std-pos": ["1mm"], "--markers": ["m1"]}


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_every_simulate_flag_changes_the_file_or_is_refused(kind, tmp_path, capsys):
    """simulate: each flag its table scopes either changes the file written or is refused, naming it. --poses was
    ignored for sockets and planes (`--type plane --poses 200` wrote 60 samples, `--type same-point --poses 20`
    120), as were --std-pos (every kind) and --markers (the markers are always m1, m2, m3)."""
    from kincal.cli.model import SIMULATE_SCOPES
    from kincal.cli.observe import CONTACTS_PER_PLANE, SOCKETS_PER_POINT

    parser = build_parser()
    scoped = {flag: dest for dest, flag in _flags(parser, "simulate").items() if dest in SIMULATE_SCOPES}
    assert set(scoped) == set(SIMULATE_SAMPLE)
    (tmp_path / "q.csv").write_text("j1,j2,j3,j4,j5,j6\n" + "0.1,-1,1,-1,1,0.2\n" * 5)
    base = tmp_path / "base.csv"
    assert main(["simulate", "ur5", "--type", kind, "-o", str(base)]) == 0
    rows = base.read_text().splitlines()[1:]
    if kind in ("same-point", "plane"):  # the count the refusal states: the plan's, per socket or plane
        labels = [r.split(",")[0] + "/" + r.split(",")[1] * (kind == "same-point") for r in rows]  # placement/socket
        per = SOCKETS_PER_POINT if kind == "same-point" else CONTACTS_PER_PLANE
        assert {labels.count(lab) for lab in labels} == {per}
        assert len(rows) == {"same-point": 120, "plane": 60}[kind] == per * len(set(labels))
    capsys.readouterr()
    for flag, value in SIMULATE_SAMPLE.items():
        out = tmp_path / "f.csv"
        out.unlink(missing_ok=True)
        code = main(["simulate", "ur5", "--type", kind, "-o", str(out), flag, *[v.format(d=tmp_path) for v in value]])
        err = capsys.readouterr().err
        if kind in SIMULATE_SCOPES[scoped[flag]].kinds:
            assert code == 0 and out.read_bytes() != base.read_bytes(), (flag, kind, err)
        else:
            assert code == 1 and f"{flag} does not apply to {kind} data" in err and not out.exists(), (flag, kind, err)
    assert main(["simulate", "ur5", "--type", kind, "-o", str(tmp_path / "g.csv"), "--poses", "7", "--poses-file",
                 str(tmp_path / "q.csv")]) == 1  # --poses beside the file of poses: one of the two is not used


# a valid value other than the default, for every flag of identifiability a kind may refuse (the SCARA: revolute and
# prismatic joints, so that either unit reads a joint of a --data file)
IDENTIFIABILITY_SAMPLE = {
    "--poses": ["7"], "--seed": ["3"], "--base": ["fixed"], "--keep": ["j4.d"], "--rank-tol": ["0.01"],
    "--joint-cols": ["a1,a2,a3,a4"], "--xyz-cols": ["a,b,c"], "--length-unit": ["mm"], "--angle-unit": ["deg"],
    "--orientation": ["quat-xyzw"], "--rot-cols": ["a,b,c,d"], "--markers": ["m1"], "--label-col": ["socket"],
    "--group-col": ["plate"], "--distance": ["0,1,0.04"], "--plane": ["t:0,0,1,0.1", "--plane", "s:0,0,1,0.15"],
    "--std-pos": ["1mm"], "--std-rot": ["50mrad"], "--tool": ["0,0,0.3"]}
NOT_WALKED = {"json", "type", "data", "base_link", "tip_link"}  # the command's subject, and a URDF's chain


def _outcome(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.slow
@pytest.mark.parametrize("source", ["plan", "data"])
@pytest.mark.parametrize("kind", KINDS)
def test_every_identifiability_flag_changes_the_result_or_is_refused(kind, source, tmp_path, capsys):
    """identifiability, kincal's plan or a --data file: each flag either changes the result (the JSON, or the file's
    reading: a flag of the read-back given another value) or is refused by the command's table, naming it.
    --poses was ignored for sockets and planes (their count is the plan's, 120 and 60) and beside --data (its rows),
    --seed beside --data, the layout flags of a file that is not read, --std-pos for points, --base for poses and
    markers."""
    from kincal.cli.model import identifiability_scopes
    from kincal.identify.applies import Scope

    scara = kincal.load_robot("scara")
    data = tmp_path / f"{kind}.csv"
    code, out, _ = _outcome(["simulate", "scara", "--type", kind, "-o", str(data), "--json"], capsys)
    assert code == 0
    read_back = json.loads(out)["flags"].split() if kind in ("same-point", "plane") else []  # labels and planes
    head = ["identifiability", "scara", "--type", kind, "--json", *(["--data", str(data), *read_back] * (source == "data"))]
    base = _outcome(head, capsys)
    assert base[0] == 0, base[2]
    said = json.loads(base[1])
    planned = {"point": 100, "pose": 100, "markers": 100, "same-point": 120, "plane": 60}[kind]
    assert said["n_poses"] == (planned if source == "plan" else len(data.read_text().splitlines()) - 1)
    parser = build_parser()
    walked = {flag: dest for dest, flag in _flags(parser, "identifiability").items() if dest not in NOT_WALKED}
    assert set(walked) == set(IDENTIFIABILITY_SAMPLE)
    for flag, dest in walked.items():
        kept = [t for k, t in enumerate(head) if flag not in head[max(k - 1, 0):k + 1]]  # a read-back's flag: replaced
        argv = [*kept, flag, *IDENTIFIABILITY_SAMPLE[flag]]
        _, args = _parse(argv)
        code, out, err = _outcome(argv, capsys)
        scope = identifiability_scopes(args, scara).get(dest, Scope((kind,), ""))
        if kind in scope.kinds:  # it applies: the result moves
            moved = [(code, out)] + [_outcome(kept, capsys)[:2]] * (kept != head)  # a read-back's flag: or left out
            assert "does not apply" not in err and set(moved) != {base[:2]}, (flag, kind, source, err)
        else:
            assert code == 1 and f"{flag} does not apply to {kind} data" in err, (flag, kind, source, err)
    poses = _outcome([*head, "--poses", "7"], capsys)  # the finding: a count that is not the samples' is refused
    if source == "plan" and kind in ("point", "pose", "markers"):
        assert json.loads(poses[1])["n_poses"] == 7
    else:
        assert poses[0] == 1 and ("120 samples" in poses[2] and "30 contacts per plane" in poses[2]
                                  if source == "plan" else f"beside --data {data} its rows are the samples" in poses[2])


# a valid value other than the default for every flag of design (the UR5: revolute joints alone, so --length-unit reads
# no joint of its poses CSV); {d}: the test's folder, {kind}: the kind's candidates, {read_back}: the flags that read
# them (simulate's)
DESIGN_SAMPLE = {
    "--tool": ["0,0,0.3"], "-m": ["31"], "--program": ["ur"], "--settle": ["3"], "--pool": ["400"],
    "--candidates": ["{d}/{kind}.csv", "{read_back}"], "--floor": ["0mm"], "--keep-out": ["200,-300,0,600,300,400mm"],
    "--tracker": ["3000,0,500mm"], "--tracker-range": ["500,2900mm"], "--cone": ["10"], "--reflector-axis": ["1,0,0"],
    "--joint-margin": ["20"], "--link-radius": ["30mm"], "--method": ["random"], "--criterion": ["D"],
    "--use": ["{d}/q.csv"], "--no-coverage": [], "--weight": ["2"], "--params": ["j2.a,j3.a,j2.theta,j3.theta"],
    "--base": ["fixed"], "--restarts": ["10"], "--generations": ["3"], "--f0": ["0.5"], "--cr": ["0.5"],
    "--population": ["10"], "--no-bound": [], "--units": ["paper"], "--seed": ["3"],
    "--joint-cols": ["a1,a2,a3,a4,a5,a6"], "--xyz-cols": ["a,b,c"], "--length-unit": ["mm"], "--angle-unit": ["deg"],
    "--orientation": ["quat-xyzw"], "--rot-cols": ["a,b,c,d"], "--markers": ["m1"], "--label-col": ["socket"],
    "--group-col": ["plate"], "--distance": ["0,1,0.04"], "--plane": ["t:0,0,1,-0.2", "--plane", "s:0,0,1,-0.1"],
    "--std-pos": ["1mm"], "--std-rot": ["50mrad"]}
AS_GIVEN = {"--no-coverage": "--coverage"}  # an on/off flag walked in its 'on' spelling (off is the default)
# a flag that modifies another (kincal.cli.design.MODIFIERS): what it needs beside it to change the design, and what
# leaves it nothing to change (None: it asks what the default does); {pool}: a larger pool for the kinds that draw
# one (the greedy start wins over 10 random ones among 300 candidates)
DESIGN_NEEDS = {"--settle": (["--program", "ur"], []), "--link-radius": (["--floor", "0mm"], []),
                **{f: (["--tracker", "3000,0,500mm"], []) for f in ("--tracker-range", "--cone", "--reflector-axis")},
                **{f: (["--method", "ide", "--criterion", "D", "--generations", "2"], [])
                   for f in ("--generations", "--f0", "--cr", "--population")},
                "--restarts": (["--criterion", "D", "{pool}"], []), "--weight": ([], ["--criterion", "D"]),
                "--no-coverage": (["--criterion", "D"], None),
                **{f: (["{own_pool}"], None) for f in ("--pool", "--candidates")}}  # against the walk's own pool, not
# the default one (10x slower to design from)
DESIGN_NOT_WALKED = {"json", "type", "output", "check", "base_link", "tip_link"}  # its subject, a URDF's chain


def _design(argv, out, capsys):
    """design's exit code, its error line and what it wrote: the poses (or samples), the program, the JSON."""
    for f in (out, out.with_suffix(".script")):
        f.unlink(missing_ok=True)
    code = main(argv)
    text, err = capsys.readouterr()
    said = json.loads(text) if code == 0 else {}
    said.pop("time_s", None)
    wrote = [f.read_bytes() if f.exists() else None for f in (out, out.with_suffix(".script"))]
    return code, err, (wrote, json.dumps(said, sort_keys=True))


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_every_design_flag_changes_the_design_or_is_refused(kind, tmp_path, capsys):
    """design, for each kind: every flag changes what it writes (the poses or samples, the program, the JSON) or is
    refused, naming it: by design's table for a kind that does not use it, for a flag that modifies another without
    that one. 84 of the 42 × 5 were ignored (a byte-identical design): --xyz-cols, --orientation, --rot-cols,
    --markers for every kind, --length-unit for the UR5's poses, --std-pos and the socket and plane flags for points,
    --pool, --use, --cone and the like for sockets and planes, --base, --units, --weight for all but points,
    --settle without --program, --cone, --tracker-range and --reflector-axis without --tracker, --restarts beside
    IMSE's strata, --weight beside D."""
    from kincal.cli.design import design_scopes
    from kincal.identify.applies import Scope

    ur5 = kincal.load_robot("ur5")
    assert main(["simulate", "ur5", "--poses", "200", "-o", str(tmp_path / "q.csv")]) == 0
    capsys.readouterr()
    read_back = []
    if kind in ("same-point", "plane"):
        assert main(["simulate", "ur5", "--type", kind, "-o", str(tmp_path / f"{kind}.csv"), "--json"]) == 0
        read_back = json.loads(capsys.readouterr().out)["flags"].split()[2:]  # after --type KIND
    else:
        (tmp_path / f"{kind}.csv").write_bytes((tmp_path / "q.csv").read_bytes())
    capsys.readouterr()
    out = tmp_path / "p.csv"
    head = ["design", "ur5", "--type", kind, "-o", str(out), "--json", "-m", "12", "--pool", "300"]
    if kind in ("same-point", "plane"):
        head = head[:-4] + ["-m", "30"]
    parser = build_parser()
    walked = {flag: dest for dest, flag in _flags(parser, "design").items() if dest not in DESIGN_NOT_WALKED}
    assert set(walked) == set(DESIGN_SAMPLE)
    designed: dict = {}  # the design without the flag, by its command line: most flags share one
    for flag, dest in walked.items():
        gone = {flag, "--pool"} if flag == "--candidates" else {flag}  # -m, --pool: replaced; --pool: given anew
        kept = [t for k, t in enumerate(head) if not gone & set(head[max(k - 1, 0):k + 1])]
        tokens = {"{read_back}": read_back, "{pool}": ["--pool", "1000"] if "--pool" in head else [],
                  "{own_pool}": ["--pool", "300"] if "--pool" in head else []}
        value, (used, unused) = [AS_GIVEN.get(flag, flag)], DESIGN_NEEDS.get(flag, ([], None))
        for v in DESIGN_SAMPLE[flag]:
            value += tokens[v] if v in tokens else [v.format(d=tmp_path, kind=kind)]
        used = [t for v in used for t in tokens.get(v, [v])]
        _, args = _parse([*kept, *(unused or []), *value])
        if kind not in design_scopes(args, ur5).get(dest, Scope((kind,), "")).kinds:
            code, err, _ = _design([*kept, *(unused or []), *value], out, capsys)
            assert code == 1 and f"{flag if flag not in AS_GIVEN else AS_GIVEN[flag]} does not apply to {kind} " \
                                  f"data" in err, (flag, kind, err)
            continue
        if unused is not None and (used or unused):  # a modifier: alone (or beside what makes it idle), refused
            code, err, _ = _design([*kept, *unused, *value], out, capsys)
            assert code == 1 and flag in err and "leave it out" in err and "does not apply" not in err, (flag, err)
        if tuple([*kept, *used]) not in designed:  # what it needs: --generations 2 beside --generations 3
            designed[tuple([*kept, *used])] = _design([*kept, *used], out, capsys)
        before = designed[tuple([*kept, *used])]
        drop = gone if flag == "--candidates" else {flag}  # what the flag replaces: the pool, for candidates
        after = _design([*kept, *[t for k, t in enumerate(used) if not drop & set(used[max(k - 1, 0):k + 1])], *value],
                        out, capsys)
        if before[0] == 1:  # what it modifies is refused for the kind (the IDE leaves a plan's pool): so is it
            assert after[0] == 1, (flag, kind, after[1])
            continue
        assert before[0] == 0 and after[0] == 0 and after[2] != before[2], (flag, kind, before[1], after[1])


def test_a_unit_that_reads_no_joint_of_a_joints_file_is_refused(tmp_path, capsys):
    """--length-unit for a robot with no prismatic joint (--angle-unit with no revolute one), where the files hold
    joint values alone, is refused with the reason: design's poses CSV (and --check's), identifiability's --data.
    It was accepted and changed nothing; where it reads a joint, it converts it (the PUU3's legs: mm = 1000 × m)."""
    q, poses = tmp_path / "q.csv", tmp_path / "p.csv"
    assert main(["simulate", "ur5", "--poses", "40", "--perturb", "-o", str(q)]) == 0
    capsys.readouterr()
    for argv in (["design", "ur5", "-m", "12", "--pool", "300", "-o", str(poses), "--length-unit", "mm"],
                 ["identifiability", "ur5", "--data", str(q), "--length-unit", "mm"],
                 ["identifiability", "ur5", "--type", "same-point", "--data", str(q), "--length-unit", "mm"],
                 ["design", "puu3", "-m", "12", "--pool", "300", "-o", str(poses), "--angle-unit", "deg"]):
        code, _, err = _outcome(argv, capsys)
        unit, robot, other = ("angle", "puu3", "revolute") if "puu3" in argv else ("length", "ur5", "prismatic")
        assert code == 1 and f"--{unit}-unit does not apply" in err and f"{robot} has no {other} joint" in err, err
        assert "Traceback" not in err
    cal = tmp_path / "cal.yaml"
    assert main(["calibrate", "ur5", str(q), "-o", str(cal), "--force"]) in (0, 4)
    capsys.readouterr()
    code, _, err = _outcome(["design", str(cal), "--check", "-o", str(poses), "--length-unit", "mm"], capsys)
    assert code == 1 and "--length-unit does not apply" in err and "ur5 has no prismatic joint" in err, err
    # where it reads a value, it is accepted: a known distance's unit; the PUU3's legs
    sockets = tmp_path / "s.csv"
    assert main(["simulate", "ur5", "--type", "same-point", "-o", str(sockets)]) == 0
    capsys.readouterr()
    code, _, err = _outcome(["identifiability", "ur5", "--type", "same-point", "--data", str(sockets), "--label-col",
                             "point", "--group-col", "placement", "--distance", "0,1,50", "--length-unit", "mm"],
                            capsys)
    assert code == 0, err
    written = []
    for unit in ("m", "mm"):
        assert main(["design", "puu3", "-m", "12", "--pool", "300", "-o", str(poses), "--length-unit", unit]) == 0
        written.append(np.loadtxt(poses, delimiter=",", skiprows=1))
    capsys.readouterr()
    np.testing.assert_allclose(written[1], 1000.0 * written[0], rtol=1e-9)


# a valid value other than the default for every flag of show; {kind}: another kind than the walk's
SHOW_SAMPLE = {"--tool": ["0,0,0.3"], "--joint-cols": ["a1,a2,a3,a4,a5,a6"], "--xyz-cols": ["a,b,c"],
               "--length-unit": ["mm"], "--angle-unit": ["deg"], "--type": ["{kind}"], "--orientation": ["quat-xyzw"],
               "--rot-cols": ["a,b,c,d"], "--markers": ["m1"], "--label-col": ["socket"], "--group-col": ["plate"],
               "--distance": ["0,1,50"], "--plane": ["t:0,0,1,0"], "--std-pos": ["1mm"], "--std-rot": ["50mrad"]}
SHOW_NOT_WALKED = {"json", "base_link", "tip_link"}  # its output's form, a URDF's chain


@pytest.mark.parametrize("kind", [None, *KINDS])
def test_every_show_flag_changes_what_it_says_or_is_refused(kind, capsys):
    """show, without --type and with each kind: every flag changes what it prints (the robot, or the description of
    a file of that type) or is refused by show's table, naming it. Without --type all 13 file flags were ignored
    (show ur5 --length-unit mm printed the same), and with it --distance and --plane (and --markers: the columns
    named NAME whatever the markers)."""
    from kincal.cli.model import show_scopes
    from kincal.identify.applies import Scope

    ur5 = kincal.load_robot("ur5")
    head = ["show", "ur5", "--json", *(["--type", kind] if kind else [])]
    base = _outcome(head, capsys)
    assert base[0] == 0, base[2]
    walked = {flag: dest for dest, flag in _flags(build_parser(), "show").items() if dest not in SHOW_NOT_WALKED}
    assert set(walked) == set(SHOW_SAMPLE)
    other = "pose" if kind != "pose" else "point"
    for flag, dest in walked.items():
        kept = [t for k, t in enumerate(head) if flag not in head[max(k - 1, 0):k + 1]]  # --type: replaced
        argv = [*kept, flag, *(v.format(kind=other) for v in SHOW_SAMPLE[flag])]
        _, args = _parse(argv)
        code, out, err = _outcome(argv, capsys)
        if (kind or "point") in show_scopes(args, ur5).get(dest, Scope((kind or "point",), "")).kinds:
            assert code == 0 and out != base[1], (flag, kind, err)
        else:
            assert code == 1 and f"{flag} does not apply to {kind or 'point'} data" in err, (flag, kind, err)
            assert "without --type show describes no data file" in err if kind is None else "Traceback" not in err
    code, _, err = _outcome(["show", "puu3", "--type", "point", "--angle-unit", "deg"], capsys)  # no revolute joint
    assert code == 1 and "--angle-unit does not apply to point data: puu3 has no revolute joint" in err, err
