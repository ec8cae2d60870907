"""A corpus of bad input for every command that reads a file: never a traceback, never a confident
wrong answer. Each case asserts the exit code, words of the message, and that no input file was
changed and no output was left behind where the command refused."""
import hashlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

import kincal
from conftest import UR5_URDF, default_sigint

from kincal.cli import main

MMDEG = ["--length-unit", "mm", "--angle-unit", "deg"]
UR5_YAML = """name: myarm
convention: dh
units: {length: mm, angle: deg}
joints:
  - {name: j1, theta: 0, d: 89.159, a: 0, alpha: 90, limits: [-360, 360]}
  - {name: j2, theta: 0, d: 0, a: -425, alpha: 0, limits: [-360, 360]}
  - {name: j3, theta: 0, d: 0, a: -392.25, alpha: 0, limits: [-360, 360]}
  - {name: j4, theta: 0, d: 109.15, a: 0, alpha: 90, limits: [-360, 360]}
  - {name: j5, theta: 0, d: 94.65, a: 0, alpha: -90, limits: [-360, 360]}
  - {name: j6, theta: 0, d: 82.3, a: 0, alpha: 0, limits: [-360, 360]}
tool: {x: 0, y: 0, z: 0}
"""
PUU3_YAML = "name: p\ntype: puu3\nunits: {length: mm, angle: deg}\nparameters: {r: 100, R: 200, L1: 350, L2: 350, L3: 350}\n"


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """Good files: UR5 measurements (mm, deg), their lines, a targets file with nominal joints."""
    d = tmp_path_factory.mktemp("base")
    ur5 = kincal.load_robot("ur5")
    true = kincal.perturb(ur5, seed=4)
    q = ur5.sample_joints(60, seed=4)
    kincal.write_measurements(d / "good.csv", kincal.simulate(true, q, 15e-6, seed=1), ur5.joint_types, "mm", "deg")
    qt = ur5.sample_joints(5, seed=8)
    xyz = ur5.forward(qt) * 1e3
    body = "\n".join(",".join(f"{v:.9f}" for v in (*np.rad2deg(a), *b)) for a, b in zip(qt, xyz))
    (d / "targets.csv").write_text("j1,j2,j3,j4,j5,j6,x,y,z\n" + body + "\n")
    kincal.calibrate(ur5, kincal.read_measurements(d / "good.csv", ur5, length_unit="mm", angle_unit="deg"))
    return d


def good_lines(base):
    return (base / "good.csv").read_text().splitlines()


def edit(base, f):
    """good.csv with f applied to its data lines (list of lists of cells)."""
    lines = good_lines(base)
    rows = [line.split(",") for line in lines[1:]]
    header, rows = f(lines[0].split(","), rows)
    return "\n".join(",".join(r) for r in [header] + rows) + "\n"


def scaled_xyz(factor):
    return lambda h, rows: (h, [r[:6] + [repr(float(v) * factor) for v in r[6:]] for r in rows])


def robot_yaml(**changes):
    """UR5_YAML with lines replaced (key: old substring -> new)."""
    text = UR5_YAML
    for old, new in changes.values():
        text = text.replace(old, new)
    return text


def csv_case(name, content, code, words, extra=(), robot="ur5", cmd="calibrate"):
    """A command on one data file with MMDEG's units, those ``extra`` gives replaced (a flag is given once)."""
    units = [x for k in range(0, len(MMDEG), 2) if MMDEG[k] not in extra for x in MMDEG[k:k + 2]]
    return pytest.param({"files": {"data.csv": content}, "argv": [cmd, robot, "{d}/data.csv", *units, *extra],
                         "code": code, "words": words}, id=name)


def yaml_case(name, text, code, words, cmd=("show",)):
    return pytest.param({"files": {"robot.yaml": text}, "argv": [*cmd, "{d}/robot.yaml"], "code": code,
                         "words": words}, id=name)


def case(name, argv, code, words, files=None, marks=()):
    return pytest.param({"files": files or {}, "argv": argv, "code": code, "words": words}, id=name, marks=marks)


CSV = [
    csv_case("empty", "", 1, ["empty"]),
    csv_case("header-only", "j1,j2,j3,j4,j5,j6,x,y,z\n", 1, ["no data rows"]),
    csv_case("blank-lines-only", "\n\n  \n", 1, ["empty"]),
    csv_case("comments-only", "# a\n# b\n", 1, ["empty"]),
    csv_case("missing-column", lambda b: edit(b, lambda h, r: (h[:-1] + ["zz"], r)), 1, ["not found", "z"]),
    csv_case("non-numeric", lambda b: edit(b, lambda h, r: (h, [r[0], r[1][:1] + ["abc"] + r[1][2:]] + r[2:])), 1,
             ["row 3", "'j2'", "abc"]),
    csv_case("empty-cell", lambda b: edit(b, lambda h, r: (h, [r[0][:3] + [""] + r[0][4:]] + r[1:])), 1,
             ["row 2", "'j4'", "not a number"]),
    csv_case("nan", lambda b: edit(b, lambda h, r: (h, r[:4] + [r[4][:7] + ["nan"] + r[4][8:]] + r[5:])), 1,
             ["NaN", "6"]),
    csv_case("inf", lambda b: edit(b, lambda h, r: (h, r[:9] + [r[9][:2] + ["inf"] + r[9][3:]] + r[10:])), 1,
             ["infinite", "11"]),
    csv_case("fewer-fields", lambda b: edit(b, lambda h, r: (h, r[:2] + [r[2][:5]] + r[3:])), 1,
             ["row 4", "5 fields"]),
    csv_case("decimal-commas-in-comma-file",
             lambda b: edit(b, lambda h, r: (h, [[c.replace(".", ",") for c in row] for row in r])), 1,
             ["decimal commas", "';'"]),
    csv_case("no-separator", "j1 j2 j3\n1 2 3\n", 1, ["separator"]),
    csv_case("utf16", lambda b: (b / "good.csv").read_text().encode("utf-16"), 1, ["not a text file", "UTF-8"]),
    csv_case("degrees-declared-rad", lambda b: (b / "good.csv").read_text(), 1, ["look like degrees", "deg"],
             extra=["--angle-unit", "rad"]),
    csv_case("mm-declared-m", lambda b: (b / "good.csv").read_text(), 1, ["look like mm", "--length-unit mm"],
             extra=["--length-unit", "m"]),
    csv_case("m-declared-mm", lambda b: edit(b, scaled_xyz(1e-3)), 1, ["look like m;", "--length-unit m)"]),
    csv_case("cm-declared-mm", lambda b: edit(b, scaled_xyz(0.1)), 1, ["look like cm", "x10"]),
    csv_case("inches-declared-mm", lambda b: edit(b, scaled_xyz(1 / 25.4)), 1, ["look like inch", "x25.4"]),
    csv_case("tenfold-too-large", lambda b: edit(b, scaled_xyz(10.0)), 1, ["x more than", "no length unit explains"]),
    csv_case("wrong-joint-count", lambda b: (b / "good.csv").read_text(), 1, ["5 joint columns", "6 joints"],
             extra=["--joint-cols", "j1,j2,j3,j4,j5"]),
    csv_case("joint-columns-unknown", lambda b: (b / "good.csv").read_text(), 1, ["not found", "joint_1"],
             extra=["--joint-cols", "joint_1,joint_2,joint_3,joint_4,joint_5,joint_6"]),
    csv_case("xyz-two-columns", lambda b: (b / "good.csv").read_text(), 1, ["three position columns"],
             extra=["--xyz-cols", "x,y"]),
    csv_case("too-few-poses", lambda b: "\n".join(good_lines(b)[:5]) + "\n", 1, ["4 poses", "measure at least"]),
    csv_case("one-pose-repeated", lambda b: "\n".join(good_lines(b)[:1] + good_lines(b)[1:2] * 80) + "\n", 1,
             ["3 distinct poses", "1 (80 rows)"]),
    csv_case("swapped-joint-columns", lambda b: edit(b, lambda h, r: (h, [[x[0], x[2], x[1], *x[3:]] for x in r])), 4,
             ["refused", "implausible"]),
    csv_case("duplicated-joint-column", lambda b: edit(b, lambda h, r: (h, [[x[0], x[0], *x[2:]] for x in r])), 4,
             ["refused"]),
    csv_case("wrong-robot", lambda b: (b / "good.csv").read_text(), 1, ["j7", "not found"], robot="wam"),
    csv_case("wrong-robot-same-joints", lambda b: (b / "good.csv").read_text(), 4, ["implausible", "robot file"],
             robot="ur10"),
    csv_case("exclude-unknown-row", lambda b: (b / "good.csv").read_text(), 1, ["row(s) 999", "not data rows"],
             extra=["--exclude", "999"]),
    csv_case("exclude-bad-syntax", lambda b: (b / "good.csv").read_text(), 2, ["row number"],
             extra=["--exclude", "x-y"]),
    csv_case("exclude-header", lambda b: (b / "good.csv").read_text(), 2, ["from 2"], extra=["--exclude", "1"]),
    csv_case("unknown-param", lambda b: (b / "good.csv").read_text(), 1, ["j9.a"], extra=["--params", "j2.a,j9.a"]),
    csv_case("base-param-with-fixed-base", lambda b: (b / "good.csv").read_text(), 1, ["base='fixed'"],
             extra=["--base", "fixed", "--params", "base.x,j2.a"]),
    csv_case("unidentifiable-params", lambda b: (b / "good.csv").read_text(), 1, ["cannot all be identified"],
             extra=["--params", "j2.d,j3.d,j4.d"]),
    csv_case("max-iter-zero", lambda b: (b / "good.csv").read_text(), 2, ["at least 1"], extra=["--max-iter", "0"]),
    csv_case("tracker-noise-in-metres", lambda b: (b / "good.csv").read_text(), 2,
             ["'0.000015' mm is 15 nm, below any instrument's noise: metres?"], extra=["--tracker-noise", "0.000015"]),
    csv_case("length-limits-one-number", lambda b: (b / "good.csv").read_text(), 2, ["two numbers"],
             extra=["--length-limits", "5"]),
    csv_case("limits-reversed", lambda b: (b / "good.csv").read_text(), 2, ["SUSPECT <= REFUSE"],
             extra=["--angle-limits", "10,2"]),
    csv_case("tracker-noise-negative", lambda b: (b / "good.csv").read_text(), 2, ["'-1': give a positive noise"],
             extra=["--tracker-noise", "-1"]),
    csv_case("pso-with-huber", lambda b: (b / "good.csv").read_text(), 1, ["huber", "pso"],
             extra=["--method", "pso", "--loss", "huber"]),
    csv_case("joint-residual-serial", lambda b: (b / "good.csv").read_text(), 1, ["joint", "closed-form"],
             extra=["--residual", "joint"]),
    csv_case("evaluate-nan", lambda b: edit(b, lambda h, r: (h, r[:1] + [r[1][:8] + ["nan"]] + r[2:])), 1, ["NaN", "3"],
             cmd="evaluate"),
    csv_case("evaluate-empty", "", 1, ["empty"], cmd="evaluate"),
    csv_case("identifiability-nan", lambda b: edit(b, lambda h, r: (h, [["nan"] + r[0][1:]] + r[1:])), 1,
             ["NaN", "joint values", "2"], cmd="identifiability"),
]
for _p in CSV:  # identifiability reads poses with --data: their joints alone (the UR5's: no length unit)
    if _p.values[0]["argv"][0] == "identifiability":
        _p.values[0]["argv"][2:5] = ["--data", "{d}/data.csv"]

CSV_GOOD = [  # variants real tools produce: read correctly, never misread
    csv_case("bom", lambda b: "\ufeff" + (b / "good.csv").read_text(), 0, []),
    csv_case("semicolon-decimal-commas",
             lambda b: (b / "good.csv").read_text().replace(",", ";").replace(".", ","), 0, []),
    csv_case("tabs", lambda b: (b / "good.csv").read_text().replace(",", "\t"), 0, []),
    csv_case("comments-and-blank-lines",
             lambda b: "# exported by the tracker\n" + "\n".join(good_lines(b)[:10]) + "\n\n# pause\n" +
             "\n".join(good_lines(b)[10:]) + "\n", 0, []),
    csv_case("latin1-extra-column",
             lambda b: edit(b, lambda h, r: (h + ["opérateur"], [x + ["José"] for x in r])).encode("latin-1"), 0, []),
    csv_case("crlf", lambda b: (b / "good.csv").read_text().replace("\n", "\r\n"), 0, []),
    csv_case("extra-columns-reordered",
             lambda b: edit(b, lambda h, r: (["t"] + h[::-1], [["0"] + x[::-1] for x in r])), 0, []),
]

YAML = [
    yaml_case("not-yaml", "name: [unclosed\n", 1, ["not valid YAML"]),
    yaml_case("empty-file", "", 1, ["expected a mapping"]),
    yaml_case("top-level-list", "- a\n- b\n", 1, ["expected a mapping"]),
    yaml_case("unknown-key", UR5_YAML + "colour: red\n", 1, ["unknown key", "colour"]),
    yaml_case("missing-convention", UR5_YAML.replace("convention: dh\n", ""), 1, ["missing required key", "convention"]),
    yaml_case("bad-convention", UR5_YAML.replace("convention: dh", "convention: xyz"), 1, ["convention", "xyz"]),
    yaml_case("units-string", UR5_YAML.replace("units: {length: mm, angle: deg}", "units: mm"), 1,
              ["'units' must be a mapping", "length: mm"]),
    yaml_case("units-inch", UR5_YAML.replace("length: mm", "length: inch"), 1, ["unknown length unit", "inch"]),
    yaml_case("units-extra-key", UR5_YAML.replace("angle: deg}", "angle: deg, time: s}"), 1, ["takes only"]),
    yaml_case("base-list", UR5_YAML + "base: [1, 2, 3]\n", 1, ["'base' must be a mapping"]),
    yaml_case("tool-string", UR5_YAML.replace("tool: {x: 0, y: 0, z: 0}", "tool: flange"), 1,
              ["'tool' must be a mapping", "flange"]),
    yaml_case("base-unknown-key", UR5_YAML + "base: {q: 1}\n", 1, ["unknown parameter", "base.q"]),
    yaml_case("joints-empty", UR5_YAML.split("joints:")[0] + "joints: []\n", 1, ["non-empty list"]),
    yaml_case("joints-number", UR5_YAML.split("joints:")[0] + "joints: 5\n", 1, ["non-empty list"]),
    yaml_case("joint-not-mapping", UR5_YAML.replace("  - {name: j6, theta: 0, d: 82.3, a: 0, alpha: 0, limits: "
                                                    "[-360, 360]}", "  - j6"), 1, ["joint 6", "mapping"]),
    yaml_case("joint-unknown-key", UR5_YAML.replace("name: j2,", "name: j2, offset: 3,"), 1, ["joint 2", "offset"]),
    yaml_case("joint-bad-type", UR5_YAML.replace("name: j3,", "name: j3, type: spherical,"), 1, ["spherical"]),
    yaml_case("limits-three", UR5_YAML.replace("limits: [-360, 360]}", "limits: [-360, 0, 360]}", 1), 1,
              ["'limits' must be [lower, upper]"]),
    yaml_case("limits-reversed", UR5_YAML.replace("limits: [-360, 360]}", "limits: [360, -360]}", 1), 1,
              ["lower < upper"]),
    yaml_case("value-text", UR5_YAML.replace("d: 89.159", "d: abc"), 1, ["'d' must be a number", "abc"]),
    yaml_case("value-nan", UR5_YAML.replace("d: 89.159", "d: .nan"), 1, ["must be finite"]),
    yaml_case("value-bool", UR5_YAML.replace("d: 89.159", "d: yes"), 1, ["must be a number"]),
    yaml_case("duplicate-key", UR5_YAML.replace("d: 89.159,", "d: 89.159, d: 90,"), 1, ["given twice", "'d'"]),
    yaml_case("duplicate-top-key", UR5_YAML + "name: other\n", 1, ["given twice", "'name'"]),
    yaml_case("duplicate-joint-names", UR5_YAML.replace("name: j2,", "name: j1,"), 1,
              ["robot.yaml", "duplicate joint names", "j1"]),
    yaml_case("dot-in-joint-name", UR5_YAML.replace("name: j2,", "name: j.2,"), 1, ["contain no '.'"]),
    yaml_case("degrees-without-units", UR5_YAML.replace("units: {length: mm, angle: deg}\n", "").replace(
        "89.159", "0.089159").replace("-425", "-0.425").replace("-392.25", "-0.39225").replace("109.15", "0.10915")
        .replace("94.65", "0.09465").replace("82.3", "0.0823"), 1, ["look like degrees", "units"]),
    yaml_case("mm-without-units", UR5_YAML.replace("units: {length: mm, angle: deg}\n", "").replace(
        "alpha: 90", "alpha: 1.5707963").replace("alpha: -90", "alpha: -1.5707963").replace(
        "limits: [-360, 360]", "limits: [-6.28, 6.28]"), 1, ["look like mm", "units"]),
    yaml_case("absurd-length", UR5_YAML.replace("a: -425", "a: 1e300"), 1, ["implausible"]),
    yaml_case("negative-mass", UR5_YAML.replace("name: j2,", "name: j2, mass: -8.4,"), 1,
              ["joint 2", "'mass'", "negative", "kg"]),
    yaml_case("com-two-numbers", UR5_YAML.replace("name: j2,", "name: j2, mass: 8.4, com: [1, 2],"), 1,
              ["joint 2", "'com'"]),
    yaml_case("error-model-unknown-term", UR5_YAML + "error_model: {terms: [{type: spline}], values: {}}\n", 1,
              ["error_model", "term 1", "harmonics|compliance|gravity-regressor"]),
    yaml_case("error-model-no-reference", UR5_YAML + "error_model: {terms: [{type: compliance, joints: [j2]}], "
              "values: {}}\n", 1, ["error_model", "term 1", "reference"]),
    yaml_case("puu3-parameters-list", PUU3_YAML.replace("parameters: {r: 100, R: 200, L1: 350, L2: 350, L3: 350}",
                                                        "parameters: [100, 200]"), 1,
              ["'parameters' must be a mapping"]),
    yaml_case("puu3-unknown-parameter", PUU3_YAML.replace("r: 100", "rr: 100"), 1, ["unknown 3-PUU parameter", "rr"]),
    yaml_case("puu3-slider-limits", PUU3_YAML + "slider_limits: 380\n", 1, ["slider_limits"]),
    yaml_case("puu3-base-unknown", PUU3_YAML + "base: {w: 1}\n", 1, ["unknown base key", "w"]),
    yaml_case("unknown-type", UR5_YAML.replace("convention: dh", "convention: dh\ntype: cable"), 1,
              ["unknown robot type", "cable", "stewart", "delta"]),
    yaml_case("actuators-alone", UR5_YAML + "actuators: [{name: m1, limits: [0, 1]}]\n", 1, ["go together"]),
    yaml_case("transmission-malformed", UR5_YAML + "actuators: [{name: m1, limits: [0, 1]}]\ntransmission: "
              "{parameters: {sx: 10}, maps: [5]}\n", 1, ["robot.yaml", "malformed"]),
    yaml_case("binary", "\x00\x01\x02", 1, ["robot.yaml"]),
    pytest.param({"files": {"robot.yaml": "name: [unclosed\n"}, "argv": ["calibrate", "{d}/robot.yaml",
                                                                          "{base}/good.csv", *MMDEG],
                  "code": 1, "words": ["robot.yaml", "not valid YAML"]}, id="calibrate-with-bad-robot"),
    pytest.param({"files": {"robot.yaml": UR5_YAML + "calibration: 5\n"},
                  "argv": ["evaluate", "{d}/robot.yaml", "{base}/good.csv", *MMDEG], "code": 1,
                  "words": ["calibration", "mapping"]}, id="evaluate-bad-calibration-section"),
]
YAML_GOOD = [
    yaml_case("exponent-without-dot", UR5_YAML.replace("d: 89.159", "d: 89159e-3"), 0, []),
    yaml_case("bom-robot", "\ufeff" + UR5_YAML, 0, []),
]

PATHS = [
    case("calibrate-output-is-data", ["calibrate", "ur5", "{base}/good.csv", *MMDEG, "-o", "{base}/good.csv"], 1,
         ["would overwrite"]),
    case("calibrate-output-is-robot", ["calibrate", "{d}/r.yaml", "{base}/good.csv", *MMDEG, "-o", "{d}/r.yaml"], 1,
         ["would overwrite"], files={"r.yaml": UR5_YAML}),
    case("calibrate-residuals-is-output", ["calibrate", "ur5", "{base}/good.csv", *MMDEG, "-o", "{d}/c.yaml",
                                           "--residuals", "{d}/c.yaml"], 1, ["would overwrite"]),
    case("calibrate-output-folder-missing", ["calibrate", "ur5", "{base}/good.csv", *MMDEG, "-o", "{d}/no/c.yaml"], 1,
         ["does not exist"]),
    case("calibrate-output-is-folder", ["calibrate", "ur5", "{base}/good.csv", *MMDEG, "-o", "{d}"], 1,
         ["is a folder"]),
    case("calibrate-data-missing", ["calibrate", "ur5", "{d}/nothing.csv", *MMDEG], 1, ["cannot read"]),
    case("calibrate-data-is-folder", ["calibrate", "ur5", "{d}", *MMDEG], 1, ["cannot read"]),
    case("compensate-output-is-targets", ["compensate", "ur5", "{base}/targets.csv", *MMDEG, "-o",
                                          "{base}/targets.csv"], 1, ["would overwrite"]),
    case("compensate-output-is-robot", ["compensate", "{d}/r.yaml", "{base}/targets.csv", *MMDEG, "-o", "{d}/r.yaml"],
         1, ["would overwrite"], files={"r.yaml": UR5_YAML}),
    case("design-output-is-candidates", ["design", "ur5", "-m", "10", "--candidates", "{d}/c.csv", "-o", "{d}/c.csv"],
         1, ["would overwrite"], files={"c.csv": "j1,j2,j3,j4,j5,j6\n0,0,0,0,0,0\n"}),
    case("simulate-output-is-save-true", ["simulate", "ur5", "-o", "{d}/x.yaml", "--save-true", "{d}/x.yaml"], 1,
         ["would overwrite"]),
    case("simulate-output-is-joints", ["simulate", "ur5", "--poses-file", "{d}/j.csv", "-o", "{d}/j.csv"], 1,
         ["would overwrite"], files={"j.csv": "j1,j2,j3,j4,j5,j6\n0,0,0,0,0,0\n"}),
    case("simulate-output-folder-missing", ["simulate", "ur5", "-o", "{d}/none/x.csv"], 1, ["does not exist"]),
    case("sensitivity-plot-folder-missing", ["sensitivity", "ur5", "--plot", "{d}/none/s.png"], 1, ["does not exist"]),
    case("verify-output-is-plan", ["verify", "puu3", "--plan", "{d}/p.csv", "-o", "{d}/p.csv"], 1,
         ["would overwrite"], files={"p.csv": "x\n"}),
    case("export-output-is-robot", ["export", "{d}/r.yaml", "{d}/r.yaml"], 1, ["would overwrite"],
         files={"r.yaml": UR5_YAML}),
    case("export-output-is-source-urdf", ["export", "{d}/r.urdf", "{d}/r.urdf", "--tip-link", "b"], 1,
         ["would overwrite"], files={"r.urdf": "<robot name='r'><link name='a'/><link name='b'/><joint name='j' "
                                               "type='revolute'><parent link='a'/><child link='b'/><limit "
                                               "lower='-1' upper='1'/></joint></robot>"}),
    case("export-ur-of-a-parallel-robot", ["export", "puu3", "{d}/u.yaml", "--format", "ur"], 1,
         ["not a serial chain"]),
    case("urdf-flags-on-yaml-robot", ["show", "ur5", "--tip-link", "tool0"], 1, ["apply to URDF files only"]),
    case("robot-missing", ["show", "{d}/none.yaml"], 1, ["robot file", "none.yaml' not found"]),
    case("robot-is-folder", ["show", "{d}"], 1, ["is a folder"]),
    case("unknown-bundled-name", ["show", "ur55"], 1, ["neither a bundled robot", "ur5"]),
]

ARGS = [
    case("identifiability-zero-poses", ["identifiability", "ur5", "--poses", "0"], 2, ["at least 1"]),
    case("identifiability-tol-text", ["identifiability", "ur5", "--rank-tol", "small"], 2, ["not a number"]),
    case("simulate-negative-noise", ["simulate", "ur5", "-o", "{d}/x.csv", "--noise", "-1"], 2, [">= 0"]),
    case("simulate-zero-poses", ["simulate", "ur5", "-o", "{d}/x.csv", "--poses", "0"], 2, ["at least 1"]),
    case("simulate-nan-noise", ["simulate", "ur5", "-o", "{d}/x.csv", "--noise", "nan"], 2, ["finite"]),
    case("design-m-zero", ["design", "ur5", "-m", "0", "-o", "{d}/p.csv"], 2, ["at least 1"]),
    case("design-m-too-small", ["design", "ur5", "-m", "5", "--pool", "300", "-o", "{d}/p.csv"], 1, ["choose m"]),
    case("design-m-above-pool", ["design", "ur5", "-m", "40", "--pool", "30", "-o", "{d}/p.csv"], 1,
         ["distinct candidates"]),
    case("design-fedorov-criterion-A", ["design", "ur5", "-m", "20", "--pool", "300", "--criterion", "A", "-o",
                                        "{d}/p.csv"], 1, ["D and I"]),
    case("design-identical-candidates", ["design", "ur5", "-m", "10", "--candidates", "{d}/c.csv", "-o", "{d}/p.csv"],
         1, ["1 distinct pose"], files={"c.csv": "j1,j2,j3,j4,j5,j6\n" + "0.1,0.2,0.3,0.4,0.5,0.6\n" * 50}),
    case("design-candidates-beyond-limits", ["design", "guo3t2r", "-m", "10", "--candidates", "{d}/c.csv", "-o",
                                             "{d}/p.csv"], 1, ["joint phi1 holds 9e+04 to 9e+04 rad as written",
                                                                "far outside"],
         files={"c.csv": "phi1,phi2,phi3,phi4,phi5\n9e4,0,0,0,0\n"}),  # 1e6 rad: not physically possible
    case("design-negative-restarts", ["design", "ur5", "-o", "{d}/p.csv", "--restarts", "-1"], 2, ["at least 1"]),
    case("npose-max-zero", ["npose", "ur5", "--max", "0"], 2, ["at least 1"]),
    case("separate-zero-poses", ["separate", "guo3t2r", "--poses", "0"], 2, ["at least 1"]),
    case("separate-negative-threshold", ["separate", "guo3t2r", "--threshold", "-5"], 2, [">= 0"]),
    case("sensitivity-zero-samples", ["sensitivity", "ur5", "--samples", "0"], 2, ["at least 1"]),
    case("sensitivity-unknown-param", ["sensitivity", "ur5", "--params", "j9.a"], 1, ["j9.a"]),
    case("demo-zero-repeats", ["demo", "--repeats", "0"], 2, ["at least 1"]),
    case("demo-too-few-poses", ["demo", "--poses", "2", "--repeats", "1"], 1, ["choose m"],
         marks=pytest.mark.slow),  # the separation runs first (~1.3 s)
    case("verify-nothing-to-do", ["verify", "puu3"], 1, ["nothing to do", "-o FILE"]),
    case("verify-measured-without-plan", ["verify", "puu3", "--measured", "{base}/good.csv"], 1, ["needs --plan"]),
    case("verify-plan-not-a-plan", ["verify", "puu3", "--plan", "{base}/good.csv", "--measured", "{base}/good.csv"], 1,
         ["not a verification plan"]),
    case("verify-zero-samples", ["verify", "puu3", "--samples", "0", "-o", "{d}/p.csv"], 2, ["at least 1"]),
    case("verify-hexapod", ["verify", "hexapod", "-o", "{d}/p.csv"], 1,
         ["joints are set by the platform's whole pose", "no cases of 6-D poses", "calibrate --test"]),
    case("verify-plan-missing", ["verify", "puu3", "--plan", "{d}/none.csv", "--measured", "{base}/good.csv"], 1,
         ["none.csv: cannot read the file (No such file or directory)"]),
    case("verify-zero-tolerance", ["verify", "puu3", "-o", "{d}/p.csv", "--tolerance", "0"], 2, ["> 0"]),
    case("report-without-record", ["report", "{d}/r.yaml", "-o", "{d}/r.html"], 1, ["no calibration record"],
         files={"r.yaml": UR5_YAML}),
    case("report-record-options-a-list", ["report", "{d}/r.yaml", "--train", "{base}/good.csv", "-o", "{d}/r.html"],
         1, ["calibration options", "mapping"],
         files={"r.yaml": UR5_YAML + "calibration: {nominal: {}, options: [1, 2]}\n"}),
    case("report-record-thresholds-text", ["report", "{d}/r.yaml", "--train", "{base}/good.csv", "-o", "{d}/r.html"],
         1, ["thresholds"], files={"r.yaml": UR5_YAML + "calibration: {nominal: {}, options: {thresholds: "
                                                        "{tracker_noise: small}}}\n"}),
    case("report-record-data-a-number", ["report", "{d}/r.yaml", "-o", "{d}/r.html"], 1, ["'data' must be a mapping"],
         files={"r.yaml": UR5_YAML + "calibration: {nominal: {}, options: {}, data: 5}\n"}),
    case("report-record-use-q-text", ["report", "{d}/r.yaml", "--train", "{base}/good.csv", "-o", "{d}/r.html"], 1,
         ["'use_q' must be rows of 6 joint values"], files={"r.yaml": UR5_YAML + "calibration: {nominal: {}, options: "
                                                              "{}, use_q: [[1, 2], [x, y]]}\n"}),
    case("study-unknown-name", ["study", "seed3", "-o", "{d}/s.jsonl"], 2, ["the study is guo2024"]),
    case("study-zero-trials", ["study", "guo2024", "--trials", "0", "-o", "{d}/s.jsonl"], 2, ["at least 1"]),
    case("study-results-of-another-study", ["study", "guo2024", "--trials", "1", "--poses", "24", "--generations",
                                            "2", "--workers", "1", "-o", "{d}/s.jsonl"], 1, ["another study"],
         files={"s.jsonl": "not a results file\n"}),
    case("unknown-command", ["frobnicate"], 2, ["invalid choice"]),
    case("calibrate-missing-data-argument", ["calibrate", "ur5"], 2, ["required"]),
]

COMPENSATE = [
    case("compensate-targets-in-m-declared-mm", ["compensate", "ur5", "{d}/t.csv", *MMDEG, "-o", "{d}/c.csv"], 1,
         ["target positions spread 1e+03x more than the robot moves", "they look like um"], files={"t.csv": lambda b: _targets(b, xyz_factor=1e3)}),
    case("compensate-out-of-reach", ["compensate", "ur5", "{d}/t.csv", *MMDEG, "-o", "{d}/c.csv"], 4,
         ["row 4", "beyond the robot's reach"], files={"t.csv": lambda b: _targets(b, far_row=2)}),
    case("compensate-joints-and-targets-disagree", ["compensate", "ur5", "{d}/t.csv", *MMDEG, "-o", "{d}/c.csv"], 4,
         ["do not belong together"], files={"t.csv": lambda b: _targets(b, swap_joints=True)}),
    case("compensate-across-joint-limit", ["compensate", "{d}/r.yaml", "{d}/t.csv", *MMDEG, "-o", "{d}/c.csv"], 4,
         ["row 2", "joint limits"], files={"r.yaml": lambda b: _tight_calibrated(), "t.csv": lambda b: _limit_target()}),
    case("compensate-targets-without-joints", ["compensate", "ur5", "{d}/t.csv", *MMDEG, "-o", "{d}/c.csv"], 1,
         ["not found", "j1"], files={"t.csv": "x,y,z\n100,200,300\n"}),
    case("compensate-unknown-target-frame", ["compensate", "ur5", "{base}/targets.csv", *MMDEG, "-o", "{d}/c.csv",
                                             "--target-frame", "world"], 1, ["target frame 'world'", "base_link"]),
    case("compensate-tcp-without-tool-point", ["compensate", "puu3", "{d}/t.csv", "-o", "{d}/c.csv", "--tcp",
                                               "0,0,1mm"], 1, ["has no tool point"],
         files={"t.csv": "x,y,z\n0.02,-0.03,0.30\n"}),
    case("tool-without-unit-looks-like-mm", ["show", "ur5", "--tool", "0,0,93.2"], 2, ["look like mm", "93.2mm"]),
    case("calibrate-std-columns-missing", ["calibrate", "ur5", "{base}/good.csv", *MMDEG, "--std-cols", "a,b,c"], 1,
         ["column(s) a, b, c not found"]),
    case("robot-file-frame-with-unknown-key", ["show", "{d}/r.yaml"], 1, ["frame 'base_link'", "x, y, z, rx, ry, rz"],
         files={"r.yaml": UR5_YAML + "frames: {base_link: {rz: 180, w: 1}}\n"}),
    case("robot-file-names-unknown-joint", ["show", "{d}/r.yaml"], 1, ["'names' must map joint names"],
         files={"r.yaml": UR5_YAML + "names: {j9: shoulder_pan_joint}\n"}),
    case("compensate-puu3-out-of-reach", ["compensate", "puu3", "{d}/t.csv", "-o", "{d}/c.csv"], 4,
         ["row 3", "out of reach"], files={"t.csv": "x,y,z\n0.02,-0.03,0.30\n5.0,0.0,0.3\n"}),
]


def _targets(base, xyz_factor=1.0, far_row=None, swap_joints=False):
    lines = (base / "targets.csv").read_text().splitlines()
    rows = [line.split(",") for line in lines[1:]]
    for k, r in enumerate(rows):
        r[6:] = [repr(float(v) * xyz_factor) for v in r[6:]]
        if far_row == k:
            r[6:] = ["5000", "0", "0"]
        if swap_joints:
            r[0:6] = r[5::-1]
    return "\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n"


Q_LIMIT = np.array([10.0, -90.9, 40.0, 10.0, 60.0, 10.0])  # deg: the nominal command of the limit case


def _tight_robot():
    """The UR5 with every joint limited to ±0.01° around Q_LIMIT."""
    text = UR5_YAML
    for k, q in enumerate(Q_LIMIT):
        start = text.index(f"name: j{k + 1},")
        end = text.index("}", start)
        line = text[start:end]
        text = text[:start] + line[:line.index("limits:")] + f"limits: [{q - 0.01}, {q + 0.01}]" + text[end:]
    return text


def _limit_target():
    """The nominal target of the nominal command at Q_LIMIT."""
    r = kincal.models.yaml_io.robot_from_dict(yaml.safe_load(_tight_robot()))
    xyz = r.forward(np.deg2rad(Q_LIMIT)[None]) * 1e3
    return "j1,j2,j3,j4,j5,j6,x,y,z\n" + ",".join(f"{v:.9f}" for v in (*Q_LIMIT, *xyz[0])) + "\n"


def _tight_calibrated():
    """The tight UR5 calibrated with j2.theta 0.05° off its nominal value: reaching the nominal target
    needs j2 0.05° from the nominal command, beyond its ±0.01° limits."""
    nominal = kincal.models.yaml_io.robot_from_dict(yaml.safe_load(_tight_robot()))
    cal = nominal.with_params({"j2.theta": np.deg2rad(0.05)})
    record = {"parameters": ["j2.theta"], "covariance": [[1e-12]], "training_median_sigma": 1e-5,
              "nominal": nominal.params.as_dict()}
    return kincal.models.yaml_io.robot_to_yaml(cal) + yaml.safe_dump({"calibration": record})


URDF = UR5_URDF
URDF_FLAGS = ["--tip-link", "tool0", "--joint-cols", "j1,j2,j3,j4,j5,j6"]
_CALIBRATED: dict = {}


def _calibrated_delta(base) -> str:
    """A calibrated delta robot file (YAML text), from simulated data of a perturbed delta."""
    delta = kincal.load_robot("delta")
    res = kincal.calibrate(delta, kincal.simulate(kincal.perturb(delta, seed=1), delta.sample_joints(40, seed=1), 0.0))
    out = base / "delta_cal.yaml"
    kincal.save_robot(res.robot, out, calibration=res.record())
    return out.read_text()


def _calibrated(base, **record):
    """A calibrated UR5 file (YAML text) from good.csv, its calibration record changed by ``record``
    (a key set to None is removed)."""
    if "text" not in _CALIBRATED:
        ur5 = kincal.load_robot("ur5")
        res = kincal.calibrate(ur5, kincal.read_measurements(base / "good.csv", ur5, length_unit="mm",
                                                             angle_unit="deg"))
        _CALIBRATED["robot"] = kincal.models.yaml_io.robot_to_yaml(res.robot)
        _CALIBRATED["record"] = {**res.record(), "data": {"file": str(base / "good.csv"), "length_unit": "mm",
                                                           "angle_unit": "deg"}}
        _CALIBRATED["text"] = True
    rec = {**_CALIBRATED["record"], **record}
    rec = {k: v for k, v in rec.items() if v is not None}
    return _CALIBRATED["robot"] + yaml.safe_dump({"calibration": rec})


def _header(base, f):
    lines = good_lines(base)
    return "\n".join([",".join(f(lines[0].split(",")))] + lines[1:]) + "\n"


def _joints_in_degrees_declared_rad(base):
    """Candidate poses in degrees (values up to 180), the file read as radians."""
    return "j1,j2,j3,j4,j5,j6\n" + "\n".join(",".join(line.split(",")[:6]) for line in good_lines(base)[1:]) + "\n"


def _mm_urdf():
    import re
    text = URDF.read_text()
    return re.sub(r'xyz="([^"]*)"', lambda m: 'xyz="' + " ".join(str(float(v) * 1000) for v in m.group(1).split())
                  + '"', text)


def _cal(cmd, extra=(), **record):
    """A command on a calibrated robot file whose record is changed."""
    return {"files": {"cal.yaml": lambda b: _calibrated(b, **record)}, "argv": [*cmd, *extra]}


def rcase(name, cmd, code, words, **record):
    spec = _cal(cmd, **record)
    return pytest.param({**spec, "code": code, "words": words}, id=name)


EVAL = ["evaluate", "{d}/cal.yaml", "{base}/good.csv", *MMDEG]
REPORT = ["report", "{d}/cal.yaml", "-o", "{d}/r.html"]
COMP = ["compensate", "{d}/cal.yaml", "{base}/targets.csv", *MMDEG, "-o", "{d}/c.csv"]
EXPORT = ["export", "{d}/cal.yaml", "{d}/out.urdf"]
STUDY = ["study", "guo2024", "--trials", "2", "--poses", "24", "--generations", "2", "--workers", "1", "-o",
         "{d}/s.jsonl"]
STUDY_HEAD = ('{"study":{"study":"guo2024","m":24,"generations":2,"seed":0,"exact_model":"identifiable errors",'
              '"per_task":100}}\n')

ROUND2 = [
    # readers: columns named twice, units checked the same way in every command that reads joints
    csv_case("header-names-a-column-twice", lambda b: _header(b, lambda h: [h[0], h[0], *h[2:]]), 1,
             ["names column(s) j1 more than once", "columns 1, 2"]),
    csv_case("joint-cols-names-one-twice", lambda b: (b / "good.csv").read_text(), 1, ["j1 given more than once"],
             extra=["--joint-cols", "j1,j1,j3,j4,j5,j6"]),
    csv_case("xyz-col-also-a-joint", lambda b: (b / "good.csv").read_text(), 1, ["j6 given more than once"],
             extra=["--xyz-cols", "x,y,j6"]),
    csv_case("std-cols-repeat-x", lambda b: (b / "good.csv").read_text(), 1, ["given more than once"],
             extra=["--std-cols", "x,y,z"]),
    csv_case("evaluate-header-twice", lambda b: _header(b, lambda h: [*h[:6], "x", "x", "z"]), 1,
             ["names column(s) x more than once"], cmd="evaluate"),
    csv_case("rad-read-as-deg", lambda b: edit(b, lambda h, r: (h, [[repr(float(np.deg2rad(float(v)))) for v in x[:6]]
                                                                     + x[6:] for x in r])), 1,
             ["read as radians they match", "--angle-unit rad"]),
    csv_case("mm-read-as-um", lambda b: (b / "good.csv").read_text(), 1, ["look like mm", "--length-unit mm"],
             extra=["--length-unit", "um"]),
    case("design-candidates-in-degrees-read-as-rad", ["design", "ur5", "-m", "10", "--candidates", "{d}/c.csv", "-o",
                                                      "{d}/p.csv"], 1, ["look like degrees", "--angle-unit deg"],
         files={"c.csv": _joints_in_degrees_declared_rad}),
    case("simulate-poses-in-degrees-read-as-rad", ["simulate", "ur5", "--poses-file", "{d}/c.csv", "-o", "{d}/x.csv"],
         1, ["look like degrees"], files={"c.csv": _joints_in_degrees_declared_rad}),
    case("design-candidates-column-twice", ["design", "ur5", "-m", "10", "--candidates", "{d}/c.csv", "-o",
                                            "{d}/p.csv"], 1, ["more than once"],
         files={"c.csv": "j1,j1,j3,j4,j5,j6\n" + "0.1,0.2,0.3,0.4,0.5,0.6\n" * 20}),
    case("verify-plan-predictions-as-measurements", ["verify", "puu3", "--plan", "{d}/p.csv", "--measured",
                                                     "{d}/p.csv", "--xyz-cols", "x_pred,y_pred,z_pred"], 1,
         ["a kincal verification plan (the commands to run"], files={"p.csv": lambda b: _plan()}),
    # robot files: missing, a folder, xacro, URDF in mm or absurd, error-model values
    case("robot-file-missing-with-path", ["calibrate", "{d}/robots/arm.yaml", "{base}/good.csv", *MMDEG], 1,
         ["robot file", "not found", "does not exist either"]),
    case("robot-file-is-folder", ["evaluate", "{d}", "{base}/good.csv", *MMDEG], 1, ["is a folder"]),
    case("xacro-file", ["show", "{d}/arm.urdf.xacro"], 1, ["xacro file", "expand it first"],
         files={"arm.urdf.xacro": '<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro"><xacro:include '
                                  'filename="arm.xacro"/><xacro:arm prefix=""/></robot>'}),
    case("urdf-in-mm", ["show", "{d}/mm.urdf", "--tip-link", "tool0"], 1, ["look like mm", "metres"],
         files={"mm.urdf": lambda b: _mm_urdf()}),
    case("urdf-origin-1e300", ["show", "{d}/big.urdf", "--tip-link", "tool0"], 1, ["implausible", "shoulder_pan"],
         files={"big.urdf": lambda b: URDF.read_text().replace('xyz="0.0 0.0 0.089159"', 'xyz="0.0 0.0 1e300"', 1)}),
    yaml_case("error-model-payload-inf", UR5_YAML + "error_model: {terms: [{type: compliance, joints: [j2], payload: "
              ".inf}], reference: {}, values: {}}\n", 1, ["error_model"]),
    case("error-model-harmonic-3-rad", ["show", "{d}/h.yaml"], 1, ["harmonic amplitude", "j2.h1s = 3 rad",
                                                                     "implausible"],
         files={"h.yaml": UR5_YAML + "error_model: {terms: [{type: harmonics, order: 1, joints: [j2]}], values: "
                                     "{j2.h1s: 3.0}}\n"}),
    # URDF robots in every command that takes a robot
    case("urdf-evaluate", ["evaluate", str(URDF), "{base}/good.csv", *MMDEG, *URDF_FLAGS], 0, ["n=60"]),
    case("urdf-compensate-targets-in-dh-base", ["compensate", str(URDF), "{base}/targets.csv", *MMDEG, *URDF_FLAGS,
                                                "-o", "{d}/c.csv"], 4, ["do not belong together", "frame?"]),
    case("urdf-report-without-record", ["report", str(URDF), "--train", "{base}/good.csv", *MMDEG, *URDF_FLAGS, "-o",
                                        "{d}/r.html"], 1, ["not a calibrated robot file", "-o calibrated.yaml"]),
    case("separate-urdf", ["separate", str(URDF), "--tip-link", "tool0"], 1, ["no DH parameters"]),
    case("separate-puu3", ["separate", "puu3"], 1, ["no DH parameters", "identifiability"]),
    # calibration records that cannot be used: one line naming the file and the key
    rcase("evaluate-record-parameters-a-number", EVAL, 1, ["cal.yaml", "'parameters' is malformed"], parameters=5),
    rcase("evaluate-record-covariance-text", EVAL, 1, ["cal.yaml", "'covariance' is malformed"], covariance="text"),
    rcase("evaluate-record-envelope-a-number", EVAL, 1, ["cal.yaml", "'envelope' is malformed"], envelope=3),
    rcase("evaluate-record-without-sigma", EVAL, 1, ["'training_median_sigma' is missing"],
          training_median_sigma=None),
    rcase("compensate-record-covariance-text", COMP, 1, ["cal.yaml", "'covariance' is malformed"], covariance="x"),
    rcase("compensate-record-parameters-missing", COMP, 1, ["'parameters' is missing"], parameters=None),
    rcase("compensate-with-a-suspect-calibration", COMP, 0, ["calibrated with the verdict SUSPECT",
                                                             "these commands carry that doubt"], verdict="suspect"),
    rcase("report-record-options-a-list", [*REPORT], 1, ["options must be a mapping"], options=[1, 2]),
    rcase("report-record-data-a-number", [*REPORT], 1, ["'data' must be a mapping"], data=5),
    rcase("report-record-thresholds-text", [*REPORT], 1, ["thresholds"], options={"thresholds": "high"}),
    rcase("report-record-max-iter-text", [*REPORT], 1, ["max_iter"], options={"max_iter": "many"}),
    rcase("report-record-error-model-number", [*REPORT], 1, ["error model 5"], options={"error_model": 5}),
    rcase("report-record-unknown-option", [*REPORT], 1, ["unknown calibration option"], options={"colour": 1}),
    rcase("report-record-nominal-text", [*REPORT], 1, ["nominal value", "not a number"], nominal={"j2.a": "long"}),
    rcase("report-named-json", ["report", "{d}/cal.yaml", "-o", "{d}/r.json"], 1,
          ["r.json: the report is an HTML page: give it a .html name"]),
    rcase("report-test-is-the-training-file", [*REPORT, "--test", "{base}/good.csv"], 1,
          ["same data as the training file", "good.csv"]),
    rcase("evaluate-record-before-mounting-text", [*EVAL, "--same-frame"], 1, ["before mounting value of tool.z",
                                                                            "not a number"],
          before_mounting={"tool.z": "far"}),
    rcase("evaluate-record-before-mounting-unknown", [*EVAL, "--same-frame"], 1, ["before mounting value of j9.a"],
          before_mounting={"j9.a": 0.1}),
    rcase("report-record-data-file-a-number", [*REPORT], 1, ["--train"], data={"file": 5}),
    rcase("report-record-reject-outliers-text", [*REPORT], 1, ["reject_outliers"],
          options={"reject_outliers": "yes"}),
    # study results files
    case("study-line-not-a-record", STUDY, 1, ["line 2 is not a task record"], files={"s.jsonl": STUDY_HEAD + "[1]\n"}),
    # these three read the records after the study's preparation (~1.5 s each): slow
    case("study-empty-record-list", STUDY, 1, ["task 0", "one result per trial"],
         files={"s.jsonl": STUDY_HEAD + '{"task":0,"records":[]}\n'}, marks=pytest.mark.slow),
    case("study-records-without-results", STUDY, 1, ["lack the study's results"],
         files={"s.jsonl": STUDY_HEAD + '{"task":0,"records":[{"trial":0},{"trial":1}]}\n'}, marks=pytest.mark.slow),
    case("study-records-of-other-trials", STUDY, 1, ["task 0"],
         files={"s.jsonl": STUDY_HEAD + '{"task":0,"records":[{"trial":5},{"trial":6}]}\n'}, marks=pytest.mark.slow),
    case("study-header-a-number", STUDY, 1, ["another study"], files={"s.jsonl": "5\n"}),
    # exports: never over what the robot was read from; values checked before writing
    case("export-over-the-source-urdf", ["export", "{d}/cal.yaml", "arm.urdf"], 1, ["would overwrite", "arm.urdf"],
         files={"arm.urdf": lambda b: URDF.read_text(), "cal.yaml": lambda b: _urdf_calibrated(b)}),
    case("export-from-with-dh-robot", ["export", "ur5", "{d}/x.urdf", "--from", str(URDF)], 1,
         ["applies to robots read from a URDF"]),
    case("export-base-yaw-nan", ["export", "ur5", "{d}/u.yaml", "--format", "ur", "--base-yaw", "nan"], 2,
         ["finite number"]),
    case("export-base-yaw-inf", ["export", "ur5", "{d}/u.yaml", "--format", "ur", "--base-yaw", "inf"], 2,
         ["finite number"]),
    case("export-over-the-calibrated-file", [*EXPORT[:2], "{d}/cal.yaml"], 1, ["would overwrite"],
         files={"cal.yaml": lambda b: _calibrated(b)}),
    # options that were ignored or accepted without a word
    csv_case("payload-without-gravity-terms", lambda b: (b / "good.csv").read_text(), 1, ["--payload 5",
                                                                                         "gravity terms"],
             extra=["--payload", "5"]),
    csv_case("prior-with-a-swarm-alone", lambda b: (b / "good.csv").read_text(), 1,
             ["prior='relevance' refits a least-squares fit", "method 'lm' or 'pso+lm'"],
             extra=["--prior", "relevance", "--method", "pso"]),
    csv_case("payload-1e9", lambda b: (b / "good.csv").read_text(), 1, ["more than any robot carries"],
             extra=["--payload", "1e9", "--error-model", "compliance"]),
    csv_case("payload-with-harmonics-only", lambda b: (b / "good.csv").read_text(), 1, ["has none"],
             extra=["--payload", "2", "--error-model", "harmonics:1"]),
    csv_case("reject-outliers-with-pso", lambda b: (b / "good.csv").read_text(), 1, ["reject_outliers", "lm"],
             extra=["--reject-outliers", "--method", "pso"]),
    csv_case("tool-in-mm-without-unit", lambda b: (b / "good.csv").read_text(), 2, ["look like mm", "31mm"],
             extra=["--tool", "0,0.09,31"]),
    # outputs checked before any work
    csv_case("calibrate-plot-folder-missing", lambda b: (b / "good.csv").read_text(), 1, ["does not exist"],
             extra=["-o", "{d}/cal.yaml", "--report", "{d}/r.html", "--plot", "{d}/figs/f.png"]),
    csv_case("evaluate-plot-folder-missing", lambda b: (b / "good.csv").read_text(), 1, ["does not exist"],
             extra=["--plot", "{d}/figs/f.png"], cmd="evaluate"),
    csv_case("calibrate-report-folder-missing", lambda b: (b / "good.csv").read_text(), 1, ["does not exist"],
             extra=["-o", "{d}/cal.yaml", "--report", "{d}/none/r.html"]),
    csv_case("calibrate-plot-is-the-data", lambda b: (b / "good.csv").read_text(), 1, ["would overwrite"],
             extra=["--plot", "{d}/data.csv"]),
    case("demo-plot-folder-missing", ["demo", "--plot", "{d}/none/f.png"], 1, ["does not exist"]),
    case("report-output-is-training-data", ["report", "{d}/cal.yaml", "-o", "{base}/good.csv"], 1,
         ["would overwrite"], files={"cal.yaml": lambda b: _calibrated(b)}),
    case("compensate-output-is-calibrated-file", [*COMP[:-1], "{d}/cal.yaml"], 1, ["would overwrite"],
         files={"cal.yaml": lambda b: _calibrated(b)}),
    case("compensate-targets-header-twice", ["compensate", "ur5", "{d}/t.csv", *MMDEG, "-o", "{d}/c.csv"], 1,
         ["names column(s) x more than once"], files={"t.csv": "j1,j2,j3,j4,j5,j6,x,x,z\n0,0,0,0,0,0,1,2,3\n"}),
    case("identifiability-data-header-twice", ["identifiability", "ur5", "--data", "{d}/q.csv"], 1,
         ["names column(s) j3 more than once"], files={"q.csv": "j1,j2,j3,j3,j5,j6\n" + "0.1,0.2,0.3,0.4,0.5,0.6\n" * 9}),
    case("calibrate-urdf-in-mm", ["calibrate", "{d}/mm.urdf", "{base}/good.csv", *MMDEG, *URDF_FLAGS], 1,
         ["look like mm", "divide by 1000"], files={"mm.urdf": lambda b: _mm_urdf()}),
    case("export-joint-names-twice", ["export", "ur5", "{d}/x.urdf", "--joint-names", "a,a,c,d,e,f"], 1,
         ["give 6 distinct names"]),
    case("evaluate-xacro", ["evaluate", "{d}/arm.xacro", "{base}/good.csv", *MMDEG], 1, ["xacro file"],
         files={"arm.xacro": '<?xml version="1.0"?>\n<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">'
                             '<xacro:property name="a" value="1"/></robot>'}),
    csv_case("residuals-is-the-data", lambda b: (b / "good.csv").read_text(), 1, ["would overwrite"],
             extra=["--residuals", "{d}/data.csv"]),
    case("same-session-twice", ["calibrate", "ur5", "{d}/data.csv", "{d}/./data.csv", *MMDEG], 1,
         ["data.csv is given twice as a session", "give each session file once"],
         files={"data.csv": lambda b: (b / "good.csv").read_text()}),
]


def _plan():
    from kincal.compensate.verify import verification_plan
    r = kincal.load_robot("puu3")
    plan = verification_plan(r, r.sample_joints(4, seed=1), ["L1", "L2"])
    buf = Path(os.environ.get("TMPDIR", "/tmp")) / f"kincal-plan-{os.getpid()}.csv"
    plan.write_csv(buf, r)
    text = buf.read_text()
    buf.unlink()
    return text


def _urdf_calibrated(base):
    """A UR5 calibrated from the URDF 'arm.urdf' in the case's folder (the file it names as source)."""
    robot = kincal.load_robot(URDF, tip_link="tool0")
    text = kincal.models.yaml_io.robot_to_yaml(robot)
    return text.replace(str(URDF), "arm.urdf")  # relative: the case runs in its own folder


def _observations(kind, **change):
    """A UR5 file of the type (mm, deg) written by kincal; ``change``: cells to spoil (column -> f)."""
    def build(base):
        import dataclasses
        from kincal.observe import ObservationFormat, write_observations
        from kincal.simulate import simulate_poses
        ur5 = kincal.load_robot("ur5")
        obs = simulate_poses(ur5, ur5.sample_joints(30, seed=2), np.eye(3), 0.0, 0.0, 1)
        if kind == "same-point":  # every pose labelled as one socket: not one point
            from kincal.observe import SamePointObs
            obs = SamePointObs(obs.q, obs.rows, "x", labels=np.array(["0", "1"] * 15))
        path = Path(os.environ.get("TMPDIR", "/tmp")) / f"kincal-obs-{os.getpid()}.csv"
        write_observations(path, dataclasses.replace(obs), ur5, ObservationFormat(kind, length_unit="mm",
                                                                                 angle_unit="deg"))
        lines = [line.split(",") for line in path.read_text().splitlines()]
        path.unlink()
        for col, f in change.items():
            k = lines[0].index(col)
            for row in lines[1:]:
                row[k] = f(row[k])
        return "\n".join(",".join(r) for r in lines) + "\n"
    return build


def ocase(name, kind, code, words, extra=(), content=None, cmd="calibrate"):
    return pytest.param({"files": {"data.csv": content or _observations(kind)},
                         "argv": [cmd, "ur5", "{d}/data.csv", *MMDEG, "--type", kind, *extra], "code": code,
                         "words": words}, id=name)


OBSERVE = [
    ocase("pose-type-on-point-file", "pose", 1, ["--type pose needs orientation columns qw, qx, qy, qz"],
          content=lambda b: (b / "good.csv").read_text()),
    ocase("markers-type-on-point-file", "markers", 1, ["NAME.x, NAME.y, NAME.z per marker"],
          content=lambda b: (b / "good.csv").read_text()),
    ocase("same-point-type-on-point-file", "same-point", 1, ["a label column ('point', --label-col)"],
          content=lambda b: (b / "good.csv").read_text()),
    ocase("quaternion-not-unit", "pose", 1, ["row 2: the orientation is not a unit quaternion"],
          content=_observations("pose", qw=lambda v: repr(2 * float(v)), qx=lambda v: repr(2 * float(v)),
                                qy=lambda v: repr(2 * float(v)), qz=lambda v: repr(2 * float(v)))),
    ocase("quaternion-x-first-declared-w-first", "pose", 1, ["the file looks like quat-xyzw"],
          extra=["--rot-cols", "qx,qy,qz,qw"]),
    ocase("pose-positions-in-m-declared-mm", "pose", 1, ["they look like m"],
          content=_observations("pose", x=lambda v: repr(float(v) / 1e3), y=lambda v: repr(float(v) / 1e3),
                                z=lambda v: repr(float(v) / 1e3))),
    ocase("sockets-of-many-places-one-label", "same-point", 1, ["are not one point", "--group-col"],
          extra=["--distance", "0,1,50"]),
    ocase("sockets-without-distance", "same-point", 1, ["scale is unobservable"]),
    ocase("distance-names-unknown-label", "same-point", 1, ["names label(s) 7"], extra=["--distance", "0,7,50"]),
    ocase("known-plane-not-in-file", "plane", 1, ["known plane(s) tabel not in column 'plane'"],
          content=lambda b: "plane,j1,j2,j3,j4,j5,j6\ntable,1,2,3,4,5,6\n", extra=["--plane", "tabel:0,0,1,0"]),
    ocase("types-for-two-of-one-file", "pose,markers", 1, ["give one type for all 1 files or one per file"],
          content=_observations("pose")),
    ocase("std-rot-without-unit", "pose", 2, ["give a number and an angle unit"], extra=["--std-rot", "1"]),
    ocase("pso-with-poses", "pose", 1, ["--method does not apply to pose data", "point data alone"],
          extra=["--method", "pso"]),
    ocase("error-model-auto-with-poses", "pose", 1, ["'auto' is chosen by blocked cross-validation of position data",
                                                    "name the model"], extra=["--error-model", "auto"]),
    ocase("exclude-unknown-row-of-poses", "pose", 1, ["row(s) 99 to exclude are not data rows"],
          extra=["--exclude", "99"]),
    ocase("pose-output-over-input", "pose", 1, ["would overwrite"], extra=["-o", "{d}/data.csv"]),
    ocase("empty-cell-in-pose-file", "pose", 1, ["row 2, column 'qw'", "is not a number (the cell is empty)"],
          content=_observations("pose", qw=lambda v: "")),
    case("design-tracker-in-mm-without-unit", ["design", "ur10", "-m", "30", "-o", "{d}/d.csv", "--tracker",
                                                "3000,0,500"], 2, ["looks like mm: give the unit (3000,0,500mm)"]),
    case("design-floor-in-mm-without-unit", ["design", "ur5", "-m", "30", "-o", "{d}/d.csv", "--floor", "-50"], 2,
         ["--floor", "-50 m without a unit looks like mm: give the unit (-50mm)"]),
    case("design-keep-out-in-mm-without-unit", ["design", "ur5", "-m", "30", "-o", "{d}/d.csv", "--keep-out",
                                                "200,-300,0,600,300,400"], 2, ["looks like mm", "400mm)"]),
    case("design-floor-the-arm-cannot-stand-above", ["design", "ur5", "-m", "30", "-o", "{d}/d.csv", "--floor",
                                                      "100mm", "--no-bound"], 1,
         ["the arm's own links sit below --floor (100 mm) at every pose", "at most 89 mm high",
          "50 mm link radius"]),
    case("design-tracker-out-of-range", ["design", "ur10", "-m", "30", "-o", "{d}/d.csv", "--tracker", "3000,0,500mm",
                                         "--tracker-range", "5,20m", "--no-bound"], 1,
         ["'tracker range' removes 100 %"]),
    case("compensate-pose-without-orientation", ["compensate", "ur5", "{base}/targets.csv", "-o", "{d}/c.csv", "--pose",
                                                 *MMDEG], 1, ["orientation columns qw, qx, qy, qz"]),
    case("compensate-cartesian-without-pose", ["compensate", "ur5", "{base}/targets.csv", "-o", "{d}/c.csv",
                                               "--output-kind", "cartesian", *MMDEG], 1, ["CLI: --pose"]),
    case("program-move-without-closing", ["compensate", "{d}/cal.yaml", "{d}/prog.script", "--program", "ur", "-o",
                                          "{d}/out.script"], 1, ["prog.script: line 2: a move call without its closing"],
         files={"prog.script": "def p():\n  movej([0, -1.5, 1.5, -1.5, -1.5, 0], a=1.4\nend\n",
                "cal.yaml": lambda b: _calibrated(b)}),
    case("program-pose-before-any-joints", ["compensate", "{d}/cal.yaml", "{d}/prog.script", "--program", "ur", "-o",
                                            "{d}/out.script"], 4, ["line 2 (movel): a pose target with no joints"],
         files={"prog.script": "def p():\n  movel(p[0.3, -0.2, 0.4, 0, 3.14, 0])\nend\n",
                "cal.yaml": lambda b: _calibrated(b)}),
    case("a-flag-given-twice", ["design", "ur5", "-m", "10", "--seed", "1", "--seed", "2", "-o", "{d}/p.csv"], 1,
         ["--seed is given twice, as 1 and 2 (only the last would count)"]),
    case("a-flag-given-twice-with-equals", ["design", "ur5", "-m", "10", "--seed=1", "--seed", "2", "-o", "{d}/p.csv"],
         1, ["--seed is given twice"]),
    case("simulate-sockets-with-a-poses-file", ["simulate", "ur5", "--type", "same-point", "--poses-file",
                                                "{d}/p.csv", "-o", "{d}/x.csv"], 1,
         ["--poses-file does not apply to same-point data: sockets and planes are touched where kincal's own plan"],
         files={"p.csv": "j1,j2,j3,j4,j5,j6\n0,0,0,0,0,0\n"}),
    case("design-candidates-in-degrees-read-as-radians", ["design", "ur5", "-m", "5", "--candidates", "{d}/c.csv",
                                                          "-o", "{d}/d.csv"], 1,
         ["candidate pose(s) break the joint limits", "read as deg, every pose is within them: give --angle-unit deg"],
         files={"c.csv": "j1,j2,j3,j4,j5,j6\n" + "".join(f"{a},{-a},{a + 0.5},{-a - 0.5},{a},{a}\n"
                                                        for a in (-5.5, -4.0, -3.5, 3.5, 4.0, 5.5, 2.0, 1.0))}),
    case("calibrate-a-design", ["calibrate", "ur5", "{d}/poses.csv"], 1,
         ["column(s) x, y, z not found", "it holds joint values only: a list of poses (a design, poses to run)?"],
         files={"poses.csv": "j1,j2,j3,j4,j5,j6\n" + "".join(f"{0.1 * k},0.2,0.3,0.4,0.5,0.6\n" for k in range(12))}),
    case("calibrate-a-verification-plan", ["calibrate", "ur5", "{d}/plan.csv", "--xyz-cols", "x_pred,y_pred,z_pred"],
         1, ["plan.csv: a kincal verification plan", "kincal verify ROBOT --plan"],
         files={"plan.csv": "# kincal verification plan for ur5; units: length=m angle=rad\ncase,sample,j1,j2,j3,j4,j5,"
                            "j6,x_pred,y_pred,z_pred\nj2.a,1,0,0,0,0,0,0,0.1,0.2,0.3\n"}),
    case("compensate-tcp-in-the-wrong-unit", ["compensate", "ur5", "{d}/t.csv", "--tcp", "0,0,0.109mm", "-o",
                                              "{d}/c.csv"], 1, ["--tcp is 0.109 mm from the flange"],
         files={"t.csv": "x,y,z\n0.4,0.1,0.3\n"}),
    case("frames-data-of-another-controller", ["export", "{d}/cal.yaml", "{d}/f.src", "--format", "frames-krl"], 1,
         ["robot 'ur5' runs ur programs", "give --format frames-urscript"], files={"cal.yaml": lambda b: _calibrated(b)}),
    case("frames-data-of-a-delta", ["export", "{d}/cal.yaml", "{d}/f.src", "--format", "frames-krl"], 1,
         ["frames data are a serial arm's base and tool; a parallel robot's controller takes its own"],
         files={"cal.yaml": lambda b: _calibrated_delta(b)}),
    case("an-on-off-flag-given-both-ways", ["design", "ur5", "-m", "10", "--coverage", "--no-coverage", "-o",
                                            "{d}/p.csv"], 1, ["--coverage and --no-coverage are both given"]),
    case("a-search-setting-of-another-method", ["design", "ur5", "-m", "10", "--method", "fedorov", "--generations",
                                                "50", "-o", "{d}/p.csv"], 1,
         ["--generations is for --method ide or detmax-ide, not fedorov"]),
    case("search-settings-of-another-method", ["design", "ur5", "-m", "10", "--method", "random", "--f0", "0.9",
                                               "--population", "7", "-o", "{d}/p.csv"], 1,
         ["--f0 is for --method ide or detmax-ide", "--population is for", "not random: leave them out"]),
    case("puu3-pool-in-mm-read-as-m", ["design", "puu3", "-m", "12", "--candidates", "{d}/pool.csv", "-o",
                                       "{d}/p.csv"], 1,
         ["the column read as joint h1 holds", "read as mm they lie within it", "--length-unit mm"],
         files={"pool.csv": lambda b: "h1,h2,h3\n" + "".join(f"{400 + 20 * k},{420 + 15 * k},{450 + 10 * k}\n"
                                                              for k in range(20))}),
    case("program-tcp-that-no-move-uses", ["compensate", "{d}/cal.yaml", "{d}/prog.script", "--program", "ur", "--tcp",
                                           "0,0,100mm", "-o", "{d}/out.script"], 1,
         ["--tcp is the TCP of the moves before the program's first set_tcp", "leave --tcp out"],
         files={"prog.script": "def p():\n  set_tcp(p[0, 0, 0.15, 0, 0, 0])\n"
                               "  movej([0, -1.5, 1.5, -1.5, -1.5, 0], a=1.4)\nend\n",
                "cal.yaml": lambda b: _calibrated(b)}),
    case("history-of-a-store-that-does-not-exist", ["history", "ur5", "--store", "{d}/none.db"], 1,
         ["no calibration store at", "none.db", "creates it"]),
    case("program-without-its-flag", ["compensate", "ur5", "{d}/prog.script", "-o", "{d}/out.script"], 1,
         ["prog.script looks like a ur program", "--program ur"],
         files={"prog.script": "def p():\n  movej([0, -1.5, 1.5, -1.5, -1.5, 0], a=1.4)\nend\n"}),
    case("program-with-an-uncalibrated-robot", ["compensate", "ur5", "{d}/prog.script", "--program", "ur", "-o",
                                                "{d}/out.script"], 1, ["ur5 holds one model and no calibration record",
                                                                       "nothing to correct"],
         files={"prog.script": "def p():\n  movej([0, -1.5, 1.5, -1.5, -1.5, 0], a=1.4)\nend\n"}),
    case("design-sockets-in-a-cell", ["design", "ur5", "-o", "{d}/poses.csv", "--type", "same-point", "--floor",
                                      "0mm"], 1, ["a same-point plan already says where the robot goes"]),
    case("design-sockets-with-ide", ["design", "ur5", "-o", "{d}/poses.csv", "--type", "same-point", "--method",
                                     "ide"], 1, ["use --method detmax or fedorov"]),
    case("design-pose-with-ide", ["design", "ur5", "-o", "{d}/poses.csv", "--type", "pose", "--method", "ide"], 1,
         ["use --method detmax or fedorov"]),
    case("identifiability-bad-type", ["identifiability", "ur5", "--type", "socket"], 1,
         ["--type: give one of point, pose"]),
    case("identifiability-sockets-plan-without-labels", ["identifiability", "ur5", "--type", "same-point", "--data",
                                                          "{base}/good.csv", "--angle-unit", "deg"], 1,
         ["a label column ('point', --label-col)"]),
]

_KIND_TEXT: dict = {}
KIND_FLAGS = {"same-point": ["--label-col", "point", "--group-col", "placement", "--distance", "0,1,50"]}


def _kind_text(kind):
    """A small exact UR5 file of the type (mm, deg) as `kincal simulate --type` writes it (12 poses;
    4 samples per socket, 6 contacts per plane)."""
    if kind not in _KIND_TEXT:
        from kincal.cli import build_parser
        from kincal.cli.observe import format_of, planned
        from kincal.observe import write_observations
        ur5 = kincal.load_robot("ur5")
        args = build_parser().parse_args(["simulate", "ur5", "-o", "x.csv", "--type", kind, *MMDEG])
        obs = planned(args, ur5, ur5, kind, ur5.sample_joints(12, seed=3), 0.0, 3, per=4 if kind == "same-point" else 6)
        path = Path(os.environ.get("TMPDIR", "/tmp")) / f"kincal-kind-{os.getpid()}.csv"
        write_observations(path, obs, ur5, format_of(args, kind))
        _KIND_TEXT[kind] = path.read_text()
        path.unlink()
    return _KIND_TEXT[kind]


def _spoiled(kind, check):
    """The kind's file with one defect (``check``; "as-written": none), as text."""
    def build(base):
        head, *rows = [line.split(",") for line in _kind_text(kind).splitlines()]
        at = head.index
        positions = [k for k, h in enumerate(head) if h in ("x", "y", "z") or h[-2:] in (".x", ".y", ".z")]
        if check == "joint-column-twice":  # a second j2 with other values: never read as if it were the first
            head, rows = head + ["j2"], [r + [repr(float(r[at("j2")]) + 0.5)] for r in rows]
        elif check == "column-missing":
            head[at("j3")] = "j3_"
        elif check == "nan":
            rows[2][at("j4")] = "nan"
        elif check == "underscore-number":
            rows[1][at("j1")] = "0_5"
        elif check == "1e300":
            rows[2][(positions or [at("j2")])[0]] = "1e300"
        elif check == "positions-in-m-declared-mm":
            rows = [[repr(float(c) * 1e-3) if k in positions else c for k, c in enumerate(r)] for r in rows]
        elif check == "joints-in-rad-declared-deg":
            rows = [[repr(float(np.deg2rad(float(c)))) if h.startswith("j") else c for h, c in zip(head, r)]
                    for r in rows]
        return "\n".join(",".join(r) for r in [head] + rows) + "\n"
    return build


# every reader check on every kind's file (one shared mechanism, _csv.Table, reads them all): the words
# the message must hold; "{col}": the column spoiled (a coordinate, or a joint where the kind has none)
READER_CHECKS = {
    "joint-column-twice": ["names column(s) j2 more than once", "rename them"],
    "column-missing": ["j3 not found", "the header has"],
    "nan": ["NaN or infinite", "row 4, column 'j4'", "remove or fix"],
    "underscore-number": ["row 3, column 'j1'", "'0_5' is not a number", "not 0_5"],
    "1e300": ["row 4, column '{col}'", "1e+300", "not physically possible"],
    "positions-in-m-declared-mm": ["they look like m;", "--length-unit m"],
    "joints-in-rad-declared-deg": ["radians", "--angle-unit rad"],
}
BIG_COLUMN = {"point": "x", "pose": "x", "markers": "m1.x", "same-point": "j2", "plane": "j2"}


def _reader_cases():
    out = []
    for kind in ("point", "pose", "markers", "same-point", "plane"):
        for check, words in READER_CHECKS.items():
            extra = list(KIND_FLAGS.get(kind, []))
            if check == "positions-in-m-declared-mm" and kind == "plane":
                continue  # no positions in the file; a known plane's offset is a flag
            if check == "positions-in-m-declared-mm" and kind == "same-point":  # no positions: the distance in m
                extra[-1], words, check = "0,1,0.05", ["as if metres were stated in a file read in mm"], "as-written"
            out.append(pytest.param({"files": {"data.csv": _spoiled(kind, check)}, "code": 1,
                                     "argv": ["calibrate", "ur5", "{d}/data.csv", *MMDEG, "--type", kind, *extra],
                                     "words": [w.format(col=BIG_COLUMN[kind]) for w in words]},
                                    id=f"{kind}-{'distance-in-m' if check == 'as-written' else check}"))
    return out


def _verify_measured(base):
    """Measurements of the puu3 plan's commands (its predictions), one coordinate 1e300."""
    rows = [line.split(",") for line in _plan().splitlines() if not line.startswith("#")]
    at = rows[0].index
    body = [[r[at(c)] for c in ("h1", "h2", "h3", "x_pred", "y_pred", "z_pred")] for r in rows[1:]]
    body[2][4] = "1e300"
    return "\n".join(",".join(r) for r in [["h1", "h2", "h3", "x", "y", "z"]] + body) + "\n"


READERS = _reader_cases() + [
    pytest.param({"files": {"data.csv": _spoiled("pose", "1e300")}, "code": 1,
                  "argv": ["evaluate", "ur5", "{d}/data.csv", *MMDEG, "--type", "pose"],
                  "words": ["row 4, column 'x'", "not physically possible"]}, id="evaluate-pose-1e300"),
    pytest.param({"files": {"data.csv": _spoiled("point", "1e300")}, "code": 1,
                  "argv": ["evaluate", "ur5", "{d}/data.csv", *MMDEG], "words": ["row 4, column 'x'",
                                                                             "not physically possible"]},
                 id="evaluate-points-1e300"),
    case("verify-measured-1e300", ["verify", "puu3", "--plan", "{d}/p.csv", "--measured", "{d}/m.csv"], 1,
         ["m.csv: row 4, column 'y'", "not physically possible"], files={"p.csv": lambda b: _plan(),
                                                                         "m.csv": _verify_measured}),
    # flag values: the fields they have, and each thing given once
    ocase("distance-four-fields", "same-point", 2, ["'0,1,50,3'", "three fields"], extra=["--distance", "0,1,50,3"]),
    ocase("distance-underscore", "same-point", 2, ["'0,1,5_0'", "must be a number > 0"],
          extra=["--distance", "0,1,5_0"]),
    ocase("distance-twice-reversed", "same-point", 2, ["'1,0,60'", "already given as '0,1,50'", "give each once"],
          extra=["--distance", "0,1,50", "--distance", "1,0,60"]),
    ocase("plane-label-twice", "plane", 2, ["'table:0,0,1,5'", "plane 'table' is already given as 'table:0,0,1,0'"],
          extra=["--plane", "table:0,0,1,0", "--plane", "table:0,0,1,5"]),
    ocase("plane-five-numbers", "plane", 2, ["'table:0,0,1,0,5'", "four numbers"],
          extra=["--plane", "table:0,0,1,0,5"]),
    ocase("plane-offset-1e300", "plane", 1, ["plane table", "a robot can reach"],
          extra=["--plane", "table:0,0,1,1e300"]),
    ocase("marker-under-two-names", "markers", 1, ["the columns of marker m2 repeat those of m1 in every row"],
          content=lambda b: _markers_twice(b)),
]


def _markers_twice(base):
    """A markers file (mm, deg) of a UR5 whose second marker is the first one's columns again."""
    from kincal.observe import ObservationFormat, write_observations
    from kincal.simulate.observations import simulate_markers
    ur5 = kincal.load_robot("ur5")
    obs = simulate_markers(ur5, ur5.sample_joints(30, seed=2), np.array([[0.05, 0.0, 0.1], [0.05, 0.0, 0.1]]), 0.0)
    path = Path(os.environ.get("TMPDIR", "/tmp")) / f"kincal-markers-{os.getpid()}.csv"
    write_observations(path, obs, ur5, ObservationFormat("markers", length_unit="mm", angle_unit="deg"))
    text = path.read_text()
    path.unlink()
    return text


def _few(base):
    """good.csv's first three poses: too few for a check (its frame takes 6 of the 9 rows)."""
    return "\n".join(good_lines(base)[:4]) + "\n"


CHANGE = [  # compare, check, history: a robot's life
    pytest.param({**_cal(["compare", "ur5", "{d}/cal.yaml"]), "code": 1, "words": ["ur5: not a calibrated robot file"]},
                 id="compare-a-bundled-robot"),
    rcase("compare-without-repeat", ["compare", "{d}/cal.yaml", "{d}/cal.yaml"], 1,
          ["cal.yaml: the calibration keeps no repeat covariance", "calibrate again"], repeat=None),
    rcase("compare-malformed-repeat", ["compare", "{d}/cal.yaml", "{d}/cal.yaml"], 1,
          ["cal.yaml: the calibration's 'repeat' section is malformed"], repeat={"parameters": ["j2.a"]}),
    pytest.param({**_cal(["check", "{d}/cal.yaml", "{d}/few.csv", *MMDEG]), "code": 1,
                  "words": ["at least 4 poses", "3 given", "design CAL --check"]}, id="check-three-poses"),
    pytest.param({**_cal(["check", "{d}/cal.yaml", "{base}/good.csv", "--alpha", "0.7"]), "code": 2,
                  "words": ["--alpha", "below 0.5"]}, id="check-alpha-too-large"),
    pytest.param({**_cal(["check", "{d}/cal.yaml", "{base}/good.csv", "--angle-unit", "deg"]), "code": 1,
                  "words": ["good.csv", "look like mm", "--length-unit mm"]}, id="check-mm-read-as-m"),
    pytest.param({**_cal(["check", "{d}/cal.yaml", "{base}/good.csv", "--length-unit", "mm"]), "code": 1,
                  "words": ["good.csv", "look like degrees", "--angle-unit deg"]}, id="check-deg-read-as-rad"),
    pytest.param({**_cal(["design", "{d}/cal.yaml", "--check", "--criterion", "D", "-o", "{d}/p.csv"]), "code": 1,
                  "words": ["--criterion", "does not apply"]}, id="design-check-with-a-criterion"),
    pytest.param({**_cal(["design", "{d}/cal.yaml", "--check", "--link-radius", "20mm", "-o", "{d}/p.csv"]),
                  "code": 1, "words": ["--link-radius thickens the arm's links"]}, id="design-check-link-radius-alone"),
    pytest.param({**_cal(["design", "{d}/cal.yaml", "--check", "--floor", "2m", "-o", "{d}/p.csv"]), "code": 1,
                  "words": ["'--floor' removes 100 %"]}, id="design-check-floor-above-the-robot"),
    case("history-without-a-store", ["history", "ur5"], 1, ["no calibration store is set", "KINCAL_STORE"]),
    case("covariate-no-term-reads", ["calibrate", "ur5", "{base}/good.csv", "--covariate-cols", "temperature",
                                     "--error-model", "harmonics:1"], 1,
         ["--covariate-cols temperature: no term of --error-model harmonics:1 reads it",
          "--error-model harmonics:1+thermal:temperature or auto"]),
    case("check-serial-without-a-store", ["calibrate", "ur5", "{base}/good.csv", *MMDEG, "--serial", "7"], 1,
         ["--serial names the robot in the calibration store"]),
]
for _p in CHANGE[3:4]:
    _p.values[0]["files"]["few.csv"] = _few

ALL = CSV + CSV_GOOD + YAML + YAML_GOOD + PATHS + ARGS + COMPENSATE + ROUND2 + OBSERVE + READERS + CHANGE


@pytest.mark.parametrize("spec", ALL)
def test_bad_input(spec, base, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for name, content in spec["files"].items():
        content = content(base) if callable(content) else content
        (tmp_path / name).write_bytes(content.encode() if isinstance(content, str) else content)
    argv = [a.format(d=tmp_path, base=base) for a in spec["argv"]]
    before = {p: _sha(p) for p in [*tmp_path.rglob("*"), *base.iterdir()] if p.is_file()}
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse
        code = exc.code
    cap = capsys.readouterr()
    assert code == spec["code"], cap.err + cap.out
    assert "Traceback" not in cap.err + cap.out and "internal error" not in cap.err
    for word in spec["words"]:
        assert word in cap.err + cap.out, (word, cap.err + cap.out)
    for p, h in before.items():  # no input damaged
        assert p.exists() and _sha(p) == h, f"{p} changed"
    if code not in (0,):
        created = [p for p in tmp_path.rglob("*") if p.is_file() and p not in before]
        assert not created, f"refused, but wrote {created}"


def test_every_command_that_reads_a_file_has_cases():
    """A new command that reads a file gets bad-input cases here, or this test names it."""
    from kincal.cli import build_parser
    subs = next(a for a in build_parser()._actions if a.dest == "command")
    covered = {spec.values[0]["argv"][0] for spec in ALL}
    assert [name for name in subs.choices if name not in covered | {"robots"}] == []


def test_outputs_get_normal_permissions(tmp_path, capsys):
    old = os.umask(0o022)
    try:
        assert main(["simulate", "ur5", "-o", str(tmp_path / "x.csv"), "--poses", "5", "--json"]) == 0
    finally:
        os.umask(old)
    capsys.readouterr()
    assert (tmp_path / "x.csv").stat().st_mode & 0o777 == 0o644


@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_signals_end_cleanly(tmp_path, sig, code, word):
    """Ctrl-C or SIGTERM during a long command: one line, the conventional exit code, no file left.
    The signal is sent once the command says (KINCAL_PROGRESS=1) that its work has started, so its
    handler is installed whatever the machine's speed."""
    out = tmp_path / "poses.csv"
    proc = subprocess.Popen([sys.executable, "-m", "kincal.cli", "design", "guo3t2r", "-m", "60", "--pool", "3000",
                             "--method", "detmax-ide", "--criterion", "comprehensive", "--generations", "100000",
                             "-o", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                            env={**os.environ, "KINCAL_PROGRESS": "1"}, preexec_fn=default_sigint)
    seen = [proc.stderr.readline() for _ in range(3)]
    assert [line.split(":")[1].strip() for line in seen] == ["design started", "designing poses", "detmax-ide on 3000 "
                                                             "candidates"], seen
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert word in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


@pytest.fixture
def cpu_hog():
    """One busy process per core: the machine a user's Ctrl-C meets when it is loaded."""
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(os.cpu_count() or 2)]
    yield
    for h in hogs:
        h.kill()
        h.wait()


STOP_ARGV = {"design": ["design", "guo3t2r", "-m", "60", "--pool", "3000", "--method", "detmax-ide", "--generations",
                        "100000"],
             "demo": ["demo", "--repeats", "50"]}


@pytest.mark.slow
@pytest.mark.parametrize("command", ["design", "demo"])
@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_signals_under_load_end_in_one_line(tmp_path, cpu_hog, command, sig, code, word):
    """Ctrl-C or SIGTERM while the command loads, parses or works on a busy machine: the conventional
    exit code, one line, no traceback, no file left; whenever the signal comes after the entry point
    runs (it says so with KINCAL_PROGRESS=1)."""
    kincal_cmd = str(Path(sys.executable).parent / "kincal")
    for delay in (0.0, 0.3, 2.5):  # while loading, while parsing or starting, while working
        out = tmp_path / f"{command}-{delay}"
        argv = STOP_ARGV[command] + (["-o", str(out)] if command == "design" else ["--plot", str(out) + ".png"])
        proc = subprocess.Popen([kincal_cmd, *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                cwd=tmp_path, env={**os.environ, "KINCAL_PROGRESS": "1"}, preexec_fn=default_sigint)
        assert proc.stderr.readline().strip() == "kincal: loading"
        time.sleep(delay)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
        lines = [x for x in err.splitlines() if x.strip()]
        assert proc.returncode == code, (delay, err)
        assert "Traceback" not in err and "Error" not in err, (delay, err)
        assert lines[-1] == f"kincal: {word}; nothing half-written" and sum(word in x for x in lines) == 1, (delay, err)
        assert not list(tmp_path.glob(f"{command}-{delay}*")), (delay, list(tmp_path.iterdir()))


@pytest.mark.parametrize("index", [-1, 3])
def test_a_row_index_outside_the_file_is_refused_and_nothing_written(tmp_path, index):
    """write_selected_rows: -1 would silently pick the last row, 3 is past the three data rows."""
    from kincal.io import write_selected_rows
    (tmp_path / "all.csv").write_text("id,j1\nP1,0.1\nP2,0.2\nP3,0.3\n")
    with pytest.raises(IndexError, match=f"data row index {index} is outside 0..2"):
        write_selected_rows(tmp_path / "chosen.csv", tmp_path / "all.csv", [0, index])
    assert not (tmp_path / "chosen.csv").exists()


def test_a_pose_number_column_given_as_a_joint_is_named_not_blamed_on_the_unit(tmp_path, capsys):
    """--joint-cols pose,joint_1,… with --angle-unit deg: the pose numbers (1…1000) read as joint 1's degrees reach
    999 deg. It said 'they look like degrees; use angle unit deg', which was already given; now it names the column
    read as that joint and the joint columns."""
    from conftest import DATA
    cols = "pose,joint_1,joint_2,joint_3,joint_4,joint_5"
    code = main(["calibrate", "ur5", str(DATA / "ur5_grid.csv"), "--length-unit", "mm",
                 "--angle-unit", "deg", "--joint-cols", cols, "-o", str(tmp_path / "c.yaml")])
    err = capsys.readouterr().err
    assert code == 1 and "the column read as joint j1 holds the whole numbers 0 to 999, counting up by 1" in err
    assert "--joint-cols" in err and "use angle unit" not in err and not (tmp_path / "c.yaml").exists()


@pytest.mark.parametrize("copy", [False, True])
def test_a_held_out_file_that_is_the_training_file_is_refused(tmp_path, capsys, copy):
    """--test given the training file, or a copy of it under another name (a sockets user did): its "held-out"
    figures were the training error, reported as held out under a GOOD verdict; now refused, nothing written."""
    from conftest import DATA
    test = DATA / "ur5_random.csv"
    if copy:
        test = tmp_path / "session2.csv"
        test.write_bytes((DATA / "ur5_random.csv").read_bytes())
    code = main(["calibrate", "ur5", str(DATA / "ur5_random.csv"), "--test", str(test), "--length-unit", "mm",
                 "--angle-unit", "deg", "--joint-cols", ",".join(f"joint_{i}" for i in range(1, 7)),
                 "-o", str(tmp_path / "c.yaml")])
    err = capsys.readouterr().err
    assert code == 1 and f"--test {test} holds the same data as the training file" in err
    assert not (tmp_path / "c.yaml").exists()


@pytest.mark.parametrize("same_frame", [[], ["--same-frame"]])
def test_a_held_out_file_of_two_poses_is_refused_before_the_fit(tmp_path, capsys, same_frame):
    """--test with 3 rows of 2 distinct poses (the third repeats the first): its frame cannot be registered (3
    needed). Found after the fit, the calibrated robot had been written (verdict good) with no figures printed;
    now refused before the fit, naming the file and its 2 poses, and nothing is written."""
    from conftest import DATA
    lines = (DATA / "ur5_grid.csv").read_text().splitlines()
    test = tmp_path / "two.csv"
    test.write_text("\n".join([lines[0], lines[1], lines[2], lines[1]]) + "\n")
    code = main(["calibrate", "ur5", str(DATA / "ur5_random.csv"), "--test", str(test), *same_frame, "--length-unit",
                 "mm", "--angle-unit", "deg", "--joint-cols", ",".join(f"joint_{i}" for i in range(1, 7)),
                 "-o", str(tmp_path / "c.yaml")])
    captured = capsys.readouterr()
    assert code == 1 and f"--test {test}: 2 distinct poses (3 rows)" in captured.err
    assert "calibration of ur5" not in captured.out and not (tmp_path / "c.yaml").exists()


def test_a_sample_number_column_given_as_a_joint_is_named(tmp_path, capsys):
    """--joint-cols sample,q2,… on the Panda's socket file (radians, as declared): the sample numbers 0…36, counting
    up within each placement, were called degrees ('use angle unit deg'); now the column is named a counter. A joint
    swept in degrees and read as radians is still degrees (its neighbours are degrees too)."""
    from conftest import PANDA_URDF, SOCKETS
    cols = "sample,q2,q3,q4,q5,q6,q7"
    code = main(["calibrate", str(PANDA_URDF), "--tip-link", "ball_link", str(SOCKETS / "samples.csv"), "--type",
                 "same-point", "--label-col", "socket", "--group-col", "placement", "--distance", "0,1,50",
                 "--length-unit", "mm", "--joint-cols", cols, "-o", str(tmp_path / "c.yaml")])
    err = capsys.readouterr().err
    assert code == 1 and "panda_joint1 holds the whole numbers 0 to 36, counting up by 1" in err
    assert "look like degrees" not in err and not (tmp_path / "c.yaml").exists()
    from kincal.io import check_degrees
    robot = kincal.load_robot("ur5")
    sweep = np.degrees(robot.sample_joints(40, seed=1))
    sweep[:, 0] = np.arange(40.0)  # joint 1 stepped 1° per row, every joint written in degrees
    with pytest.raises(kincal.errors.MeasurementError, match="they look like degrees"):
        check_degrees("sweep.csv", sweep, robot, "rad")


def test_another_robots_file_with_more_joints_is_named(tmp_path, capsys):
    """The WAM's grid calibrated as a UR5 on its first six joint columns: refused as before, and now the unread
    joint_7 column is named (it said only that no common mistake explains the data)."""
    from conftest import DATA
    code = main(["calibrate", "ur5", str(DATA / "wam_grid.csv"), "--length-unit", "mm", "--angle-unit", "deg",
                 "--joint-cols", ",".join(f"joint_{i}" for i in range(1, 7))])
    out = capsys.readouterr().out
    assert code == 4 and "also has the column(s) joint_7, which no joint of ur5 reads (6 joints)" in out
    assert main(["calibrate", "ur5", str(DATA / "ur5_grid.csv"), "--length-unit", "mm", "--angle-unit", "deg",
                 "--joint-cols", ",".join(f"joint_{i}" for i in range(1, 7))]) == 0
    assert "which no joint" not in capsys.readouterr().out


def test_a_store_that_cannot_be_written_is_refused_before_the_model_is(tmp_path, capsys):
    """--store in a folder that does not exist, or the same path as -o: the calibrated file was written, then the
    store failed ('file is not a database' for the second); both are refused before any work now."""
    from conftest import DATA
    units = ["--length-unit", "mm", "--angle-unit", "deg", "--joint-cols", ",".join(f"joint_{i}" for i in range(1, 7))]
    out = tmp_path / "cal.yaml"
    for store, said in ((tmp_path / "nodir" / "robots.db", "does not exist"), (out, "would overwrite")):
        assert main(["calibrate", "ur5", str(DATA / "ur5_random.csv"), *units, "-o", str(out), "--store",
                     str(store)]) == 1
        assert said in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("residual", ["joint", "cartesian"])
def test_a_3puu_file_in_mm_read_as_metres_is_named_a_unit(tmp_path, capsys, residual):
    """A 3-PUU file written in mm and read without --length-unit mm: the joint-space path said the positions in
    'row(s) 2 … 11' were out of reach (all 30 were) and 'use residual='cartesian'', the Cartesian one that the forward
    kinematics did not converge; both now name the unit, from the slides' values against their range."""
    robot = kincal.load_robot("puu3")
    q = robot.sample_joints(30, seed=1)
    kincal.write_measurements(tmp_path / "p30.csv", kincal.simulate(robot, q, 15e-6, seed=1), robot.joint_types, "mm")
    code = main(["calibrate", "puu3", str(tmp_path / "p30.csv"), "--base", "fixed", "--residual", residual,
                 "-o", str(tmp_path / "x.yaml")])
    err = capsys.readouterr().err
    lo, hi = (q[:, 0].min() * 1e3, q[:, 0].max() * 1e3)  # the first slide's values as written, mm
    assert code == 1 and f"the column read as joint h1 holds {lo:.4g} to {hi:.4g} m as written" in err
    assert "read as mm they lie within it" in err and "--length-unit mm" in err and "residual='cartesian'" not in err
