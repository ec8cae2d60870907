"""The calibration report: same bytes for the same input, the page's numbers equal the JSON, bad
calibrations say so at the top, and figures for calibrate/evaluate --plot."""
import dataclasses
import json
import re

import numpy as np
import pytest
from conftest import DATA, UR5_COLS, shared_dataset

import kincal
from kincal.cli import main

pytestmark = pytest.mark.slow  # whole studies and real-data calibrations: make test-fast leaves them out

UNITS = ["--length-unit", "mm", "--angle-unit", "deg", "--joint-cols", ",".join(UR5_COLS)]


@pytest.fixture(autouse=True)
def fixed_date(monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1795000000")


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    """The real UR5 calibration with its report (calibrate --report), and the calibrated robot file; the tests
    that read it share the xdist group "report-real", so that make test's workers compute it once."""
    d = tmp_path_factory.mktemp("report")
    mp = pytest.MonkeyPatch()
    mp.setenv("SOURCE_DATE_EPOCH", "1795000000")
    code = main(["calibrate", "ur5", str(DATA / "ur5_grid.csv"), *UNITS, "-o", str(d / "cal.yaml"), "--test",
                 str(DATA / "ur5_random.csv"), "--same-frame", "--report", str(d / "report.html")])
    mp.undo()
    assert code == 0
    return d


def page_numbers(html: str) -> dict:
    return {k: float(v) for k, v in re.findall(r'data-key="([^"]+)\.mean">([-0-9.]+)<', html)}


@pytest.mark.xdist_group("report-real")
def test_report_content_matches_its_json(real):
    html = (real / "report.html").read_text()
    data = json.loads((real / "report.json").read_text())
    assert data["verdict"]["status"] == "good" and data["robot"] == "ur5"
    numbers = page_numbers(html)
    assert set(numbers) == {"training.before", "training.after", "held-out.before", "held-out.after"}
    for h in data["headline"]:
        assert numbers[h["key"]] == pytest.approx(h["mean"] * 1e3, abs=5e-5)  # the page shows 4 decimals in mm
    assert next(h for h in data["headline"] if h["key"] == "held-out.after")["mean"] == pytest.approx(0.1005e-3,
                                                                                                      abs=0.00005e-3)
    assert data["figures"] == ["per_pose", "histogram", "per_axis", "vs_joints", "workspace", "correlation"]
    assert html.count("<svg") == 6 and "<script" not in html  # self-contained: no JavaScript, nothing fetched
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//)""", html)
    assert len(html.encode()) < 1_000_000
    assert "sha256" in html and "ISO 9283" in html and "j1.d  ~  +1·base.z" in html


@pytest.mark.xdist_group("report-real")
def test_same_input_same_bytes(real, tmp_path, capsys):
    """calibrate --report twice gives the same bytes; kincal report of the saved file the same content."""
    code = main(["calibrate", "ur5", str(DATA / "ur5_grid.csv"), *UNITS, "--test", str(DATA / "ur5_random.csv"),
                 "--same-frame", "--report", str(tmp_path / "report.html")])
    assert code == 0
    assert (tmp_path / "report.html").read_bytes() == (real / "report.html").read_bytes()
    # the JSON too: it left the fit's time out (the only difference between two runs; the CLI's --json has it)
    assert (tmp_path / "report.json").read_bytes() == (real / "report.json").read_bytes()
    assert "time_s" not in json.loads((real / "report.json").read_text())["calibration"]
    assert main(["report", str(real / "cal.yaml"), "--test", str(DATA / "ur5_random.csv"), "--same-frame", "-o",
                 str(tmp_path / "again.html")]) == 0
    capsys.readouterr()
    first, again = (real / "report.html").read_text(), (tmp_path / "again.html").read_text()
    assert page_numbers(first) == page_numbers(again)
    strip = lambda t: re.sub(r"<table id=\"data\">.*?</table>|[\w.-]+\.json", "", t, flags=re.S)  # noqa: E731
    assert strip(first) == strip(again)


@pytest.mark.xdist_group("report-real")
def test_report_frame_as_recorded_or_turned_off(real, tmp_path, capsys):
    """The calibration was made with --same-frame: kincal report judges the held-out file in the training frame
    by default (0.1005 mm, the README's figure) and re-fits its frame with --no-same-frame (0.0922 mm), as
    calibrate without --same-frame does."""
    def held_after(*flags: str) -> float:
        assert main(["report", str(real / "cal.yaml"), "--test", str(DATA / "ur5_random.csv"), *flags, "-o",
                     str(tmp_path / "r.html"), "--json"]) == 0
        data = json.loads(capsys.readouterr().out)
        return next(h["mean"] for h in data["headline"] if h["key"] == "held-out.after")

    assert held_after() == pytest.approx(0.1005e-3, abs=0.00005e-3)
    assert held_after("--no-same-frame") == pytest.approx(0.0922e-3, abs=0.00005e-3)
    cal = kincal.load_robot(str(real / "cal.yaml"))
    meas = kincal.read_measurements(DATA / "ur5_random.csv", cal, UR5_COLS, length_unit="mm", angle_unit="deg")
    refit = kincal.identify.refit_frame(cal, meas)  # the frame alone, kinematics fixed
    independent = float(np.linalg.norm(refit.forward(meas.q) - meas.xyz, axis=1).mean())
    assert held_after("--no-same-frame") == pytest.approx(independent, abs=2e-6)


@pytest.mark.xdist_group("report-real")
def test_report_rebase_re_fits_the_frame_over_the_recorded_same_frame(real, tmp_path, capsys):
    """--rebase, the old spelling of --no-same-frame, was accepted and ignored over a calibration recorded with
    --same-frame (0.1005 mm, the training frame); it re-fits the held-out file's frame (the mean distance of the
    frame-alone re-fit computed here, 0.0922 mm), and beside --same-frame it is refused, naming both."""
    out = tmp_path / "r.html"
    assert main(["report", str(real / "cal.yaml"), "--test", str(DATA / "ur5_random.csv"), "--rebase", "-o",
                 str(out), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    cal = kincal.load_robot(str(real / "cal.yaml"))
    meas = kincal.read_measurements(DATA / "ur5_random.csv", cal, UR5_COLS, length_unit="mm", angle_unit="deg")
    refit = kincal.identify.refit_frame(cal, meas)
    independent = float(np.linalg.norm(refit.forward(meas.q) - meas.xyz, axis=1).mean())
    held = next(h["mean"] for h in data["headline"] if h["key"] == "held-out.after")
    assert held == pytest.approx(independent, abs=2e-6) and abs(held - 0.1005e-3) > 5e-6
    assert main(["report", str(real / "cal.yaml"), "--test", str(DATA / "ur5_random.csv"), "--rebase",
                 "--same-frame", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "--rebase" in err and "contradicts --same-frame" in err


def test_bad_calibration_says_so_at_the_top(ur5, tmp_path, capsys):
    true = kincal.perturb(ur5, seed=1)
    meas = kincal.simulate(true, ur5.sample_joints(80, seed=3), 15e-6, seed=0)
    xyz = meas.xyz.copy()
    xyz[37] += [0.03, 0.04, 0.0]  # a 50 mm outlier, input row 39
    path = tmp_path / "outlier.csv"
    kincal.write_measurements(path, kincal.Measurements(meas.q, xyz, meas.joint_names), ur5.joint_types, "mm", "deg")
    code = main(["calibrate", "ur5", str(path), "--length-unit", "mm", "--angle-unit", "deg", "--loss", "huber",
                 "--report", str(tmp_path / "outlier.html")])
    html = (tmp_path / "outlier.html").read_text()
    top = html[:html.index("<h2>")]
    assert code == 0 and "SUSPECT" in top and "row(s) 39" in top and 'id="outliers"' in top and ">39<" not in top
    assert "Outlier poses (input rows): 39" in top
    # data in cm declared as mm never reaches a fit: refused at the door, no report written
    scaled = tmp_path / "cm.csv"
    kincal.write_measurements(scaled, kincal.Measurements(meas.q, meas.xyz / 10, meas.joint_names), ur5.joint_types,
                              "mm", "deg")
    code = main(["calibrate", "ur5", str(scaled), "--length-unit", "mm", "--angle-unit", "deg", "--report",
                 str(tmp_path / "cm.html")])
    assert code == 1 and "cm" in capsys.readouterr().err and not (tmp_path / "cm.html").exists()
    # a fit that is refused still gets its report, which says why at the top
    swapped = tmp_path / "swapped.csv"
    kincal.write_measurements(swapped, kincal.Measurements(meas.q[:, [0, 2, 1, 3, 4, 5]], meas.xyz, meas.joint_names),
                              ur5.joint_types, "mm", "deg")
    code = main(["calibrate", "ur5", str(swapped), "--length-unit", "mm", "--angle-unit", "deg", "--report",
                 str(tmp_path / "swapped.html")])
    top = (tmp_path / "swapped.html").read_text().split("<h2>")[0]
    assert code == 4 and "REFUSED" in top and "implausible corrections" in top


def test_repeated_poses_get_iso9283(ur5, tmp_path):
    """Five visits of each of four poses: AP and RP by the ISO 9283 formulas, computed independently."""
    true = kincal.perturb(ur5, seed=2)
    q = np.vstack([ur5.sample_joints(60, seed=5), np.repeat(ur5.sample_joints(4, seed=6), 5, axis=0)])
    meas = kincal.simulate(true, q, 15e-6, seed=1)
    res = kincal.calibrate(ur5, meas)
    rep = kincal.build_report(res)
    groups = rep.data["iso"]["groups"]
    assert len(groups) == 4 and all(g["n"] == 5 for g in groups)
    pts = meas.xyz[60:65]
    mean = pts.mean(axis=0)
    ap = np.linalg.norm(mean - res.robot.forward(q[60]))
    d = np.linalg.norm(pts - mean, axis=1)
    assert groups[0]["ap"] == pytest.approx(ap * 1e3) and groups[0]["rp"] == pytest.approx((d.mean() + 3 * d.std(ddof=1)) * 1e3)
    assert groups[0]["rows"] == "62, 63, 64, 65, 66"
    (summary,) = rep.data["iso"]["summary"]  # one session: 4 repeated poses, their median and largest AP, RP
    aps, rps = [g["ap"] for g in groups], [g["rp"] for g in groups]
    assert summary["poses"] == 4 and summary["ap_median"] == pytest.approx(np.median(aps))
    assert summary["ap_max"] == max(aps) and summary["rp_median"] == pytest.approx(np.median(rps))
    assert 'id="iso9283-summary"' in rep.html and "<details open>" in rep.html  # 4 rows: shown open


@pytest.mark.xdist_group("report-real")
def test_plots_for_calibrate_and_evaluate(real, tmp_path, capsys):
    assert main(["evaluate", str(real / "cal.yaml"), str(DATA / "ur5_random.csv"), *UNITS, "--plot",
                 str(tmp_path / "ev.png")]) == 0
    capsys.readouterr()
    pngs = sorted(tmp_path.glob("ev-*.png"))
    assert [p.name for p in pngs] == ["ev-histogram.png", "ev-per_axis.png", "ev-per_pose.png", "ev-vs_joints.png",
                                      "ev-workspace.png"]
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 10_000 for p in pngs)
    assert main(["calibrate", "ur5", str(DATA / "ur5_grid.csv"), *UNITS, "--plot", str(tmp_path / "cal.svg")]) == 0
    svgs = sorted(tmp_path.glob("cal-*.svg"))
    assert len(svgs) == 6 and all("<svg" in p.read_text() for p in svgs)


def test_report_refits_from_the_record_the_file_keeps(tmp_path, capsys):
    """The record keeps FitOptions and the poses of use (calibrate --test with --error-model auto);
    kincal report refits from exactly those, whatever held-out file it is given to show."""
    cal = tmp_path / "cal.yaml"
    assert main(["calibrate", "ur5", str(DATA / "ur5_grid.csv"), *UNITS, "--error-model", "auto", "--test",
                 str(DATA / "ur5_random.csv"), "-o", str(cal), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    record = kincal.models.load_calibration_record(cal)
    assert kincal.FitOptions.from_dict(record["options"]).error_model == kincal.ErrorModel("auto")
    test = kincal.read_measurements(DATA / "ur5_random.csv", kincal.load_robot("ur5"), UR5_COLS, length_unit="mm",
                                    angle_unit="deg")
    np.testing.assert_array_equal(np.array(record["use_q"]), test.q)
    # shown against other poses (the grid's first 100; the grid itself is refused as a held-out file): the refit
    # still uses the recorded poses of use, so it is the file's fit
    (tmp_path / "part.csv").write_text("\n".join((DATA / "ur5_grid.csv").read_text().splitlines()[:101]) + "\n")
    assert main(["report", str(cal), "--test", str(tmp_path / "part.csv"), "-o", str(tmp_path / "r.html")]) == 0
    cap = capsys.readouterr()
    assert "differs from" not in cap.err
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["error_model_choice"]["chosen"] == res["error_model_choice"]["chosen"] == "harmonics:1"


def test_held_out_sessions_are_drawn_in_the_training_frame(ur5):
    """A held-out session measured from a tracker moved by 2 m and turned by 0.8 rad: the report's
    figures get its positions and error vectors in the training data's frame (equal to the truth
    there within the model's error), not in the session's own."""
    from kincal.models.transforms import rot_zyx
    from kincal.report import build

    true = kincal.perturb(ur5, seed=2)
    res = kincal.calibrate(ur5, kincal.simulate(true, ur5.sample_joints(80, seed=1), 15e-6, seed=1))
    q = ur5.sample_joints(30, seed=3)
    here = kincal.simulate(true, q, 0.0)
    R, t = rot_zyx(0.8, 0.0, 0.0), np.array([2.0, 1.0, 0.3])
    moved = kincal.Measurements(q, here.xyz @ R.T + t, ur5.joint_names, "moved.csv")
    models = build._held_out_models(res, [moved], False)
    _, held = build._sets(res, [moved], models, res.options.thresholds)
    assert np.abs(held.xyz - here.xyz).max() < 1e-3  # the session's own frame would be metres away
    assert np.abs(held.after - (here.xyz - res.robot.forward(q))).max() < 1e-4


@pytest.mark.slow
def test_a_pose_report_names_a_moved_camera_as_evaluate_does():
    """6-D poses held out with --same-frame while the camera moved 0.12 m and 0.05 rad: the report warns that the
    tracker moved (it printed GOOD with a 120 mm held-out error and no word of why), with the error re-registered
    near the training error; with the frame re-fitted there is nothing to warn."""
    from kincal.identify import fit_observations
    from kincal.simulate.observations import simulate_poses

    ur5 = kincal.load_robot("ur5")
    true = kincal.perturb(ur5, seed=5)
    fit = fit_observations(ur5, [simulate_poses(true, ur5.sample_joints(80, seed=6), np.eye(3), 20e-6, 0.2e-3,
                                                seed=7)])
    moved = simulate_poses(true.with_params({"base.x": 0.12, "base.rz": 0.05}), ur5.sample_joints(30, seed=8),
                           np.eye(3), 20e-6, 0.2e-3, seed=9)
    told = kincal.build_report(fit, [moved], same_frame=True)
    assert len(told.data["warnings"]) == 1 and "the tracker moved between sessions" in told.data["warnings"][0]
    assert told.data["warnings"][0] in told.html.replace("&#39;", "'") and "warning: " in told.summary
    assert kincal.build_report(fit, [moved]).data["warnings"] == []


def test_a_report_written_under_another_name_names_its_own_json(ur5, tmp_path):
    """Report.write('myrun.html') writes myrun.json beside it, but the page said its numbers were in report.json
    (the name it was built with)."""
    true = kincal.perturb(ur5, seed=1)
    res = kincal.calibrate(ur5, kincal.simulate(true, ur5.sample_joints(40, seed=2), seed=3), diagnose=False)
    written = kincal.build_report(res).write(tmp_path / "myrun.html")
    page = (tmp_path / "myrun.html").read_text()
    assert written == tmp_path / "myrun.json" and written.exists()
    assert "<code>myrun.json</code>" in page and "report.json" not in page


def _options_row(html: str) -> str:
    return re.search(r"<tr><th>options</th><td>(.*?)</td></tr>", html).group(1)


@pytest.mark.xdist_group("report-real")
def test_options_row_says_how_held_out_files_were_judged(real, tmp_path, capsys):
    """The Jugglebot hexapod trained on its first session, judged on its second: with --refit-target (the target's
    rigid body defined anew) 0.6107 mm held out, the dataset README's 0.610; without, 0.6491 mm. The options row
    names the flags that tell the two apart (and --residual joint), and the UR5's --same-frame; it named none."""
    juggle = shared_dataset("stewart_jugglebot")
    flags = ["--type", "pose", "--length-unit", "mm", "--angle-unit", "rev", "--orientation", "quat-xyzw",
             "--residual", "joint"]
    rows, held = {}, {}
    for name, extra in (("refit", ["--refit-target"]), ("kept", [])):
        page = tmp_path / f"{name}.html"
        main(["calibrate", "hexapod", str(juggle / "S1.csv"), "--test", str(juggle / "S2.csv"), *flags, *extra,
              "--report", str(page)])
        capsys.readouterr()
        rows[name] = _options_row(page.read_text())
        held[name] = json.loads(page.with_suffix(".json").read_text())["held_out"][0]["mean"] * 1e3
    assert held["refit"] == pytest.approx(0.610, abs=0.001) and held["kept"] == pytest.approx(0.6491, abs=0.0001)
    assert rows["refit"].endswith("--residual joint; held out: each file&#39;s frame re-fitted (kinematics fixed), "
                                  "its target re-fitted too (--refit-target)")
    assert "--residual joint" in rows["kept"] and "--refit-target" not in rows["kept"]
    assert _options_row((real / "report.html").read_text()).endswith("; held out: frame as calibrated (--same-frame)")


def test_parameter_table_says_what_the_cli_says(ur5):
    """The parameter table's σ and values with the CLI's digits (an angle's σ 0.0015 deg on the page, 0.00152 deg in
    the CLI's table), and its last column titled where a correction is flagged, absent where none is (it was an
    untitled, empty column)."""
    true = kincal.perturb(ur5, seed=1)
    meas = kincal.simulate(true, ur5.sample_joints(60, seed=2), 15e-6, seed=3)
    for bent in ({}, {"j3.a": true.params["j3.a"] + 0.02}):  # 20 mm: beyond the verdict's 10 mm
        res = kincal.calibrate(ur5, kincal.simulate(true.with_params(bent), meas.q, 15e-6, seed=3), diagnose=False)
        html = kincal.build_report(res).html
        table = re.search(r'<table id="parameters">(.*?)</table>', html, re.S).group(1)
        rows = re.findall(r"<tr><td><code>([^<]+)</code></td>(.*?)</tr>", table, re.S)
        cli = {line.split()[0]: line.split()[-2:] for line in str(res).splitlines()[2:2 + len(res.names)]}
        kinds = dict(zip(ur5.params.names, ur5.params.kinds))
        for name, cells in rows:
            sigma = re.findall(r'<td class="num">([^<]*)</td>', cells)[3]
            assert sigma.split() == cli[name]  # the CLI's σ column
            angle = kinds[name] == "angle"
            expected = np.degrees(res.std[name]) if angle else res.std[name] * 1e3
            assert sigma == (f"{expected:.5f} deg" if angle else f"{expected:.4f} mm")
        assert len(rows) == len(res.names) and "<th></th>" not in table
        flagged = [name for name, cells in rows if "large (beyond the verdict" in cells]
        assert flagged == (["j3.a"] if bent else []) and ("<th>note</th>" in table) == bool(flagged)


def test_header_names_the_hexapod_compliance(tmp_path, capsys):
    """A hexapod calibrated with --error-model compliance: its leg compliance is a parameter of its own (the model's
    structure does not name it, "stewart (implicit, 6-D)"), so the header names it beside the structure."""
    juggle = shared_dataset("stewart_jugglebot")
    page = tmp_path / "hc.html"
    main(["calibrate", "hexapod", str(juggle / "S1.csv"), "--type", "pose", "--length-unit", "mm", "--angle-unit",
          "rev", "--orientation", "quat-xyzw", "--residual", "joint", "--error-model", "compliance", "--report",
          str(page)])
    capsys.readouterr()
    html = page.read_text()
    assert "· stewart (implicit, 6-D) + compliance model ·" in html and "<code>legs.compliance</code>" in html
    assert ", --error-model compliance" in _options_row(html)


def test_a_good_verdict_states_the_residuals_against_their_limit():
    """A GOOD report said "residuals within the limits their stated noise allows (whitened RMS 2.11 ...)": 2.11 is
    twice the stated σ, no noise allows that; it names the ratio and the limit now. Poses with their noise twice the
    σ fit_observations is told: each kind's whitened RMS (numpy, from the whitened residual) within 3x; the real UR5
    grid: its σ per axis (numpy) against the 0.05 mm tracker noise, within 10x."""
    from kincal.identify import fit_observations
    from kincal.identify.judge import component_kinds
    from kincal.simulate.observations import simulate_poses

    ur5 = kincal.load_robot("ur5")
    noisy = simulate_poses(kincal.perturb(ur5, seed=5), ur5.sample_joints(80, seed=6), np.eye(3), 40e-6, 0.4e-3,
                           seed=7)
    fit = fit_observations(ur5, [dataclasses.replace(noisy, std_pos=20e-6, std_rot=0.2e-3)])
    labels, kinds = component_kinds(fit.observations)
    rms = [float(np.sqrt(np.mean(fit.whitened_residual[labels == k] ** 2))) for k in range(len(kinds))]
    assert fit.verdict.status == "good" and 1.5 < min(rms) and max(rms) < 3.0
    html = kincal.build_report(fit).html.replace("&#39;", "'")
    assert (f"whitened RMS {fit.whitened_rms:.2f} (1 when the stated σ are right): {kinds[0]} residuals {rms[0]:.1f}x"
            f", {kinds[1]} residuals {rms[1]:.1f}x their stated σ, each within the limit of 3x") in html
    assert "stated noise allows" not in html
    grid = kincal.read_measurements(DATA / "ur5_grid.csv", ur5, UR5_COLS, length_unit="mm", angle_unit="deg")
    res = kincal.calibrate(ur5, grid)
    sigma = np.sqrt(np.sum(res.residuals**2) / (res.residuals.size - len(res.names))) * 1e3
    assert (f"residual σ per axis {sigma:.4g} mm, {sigma / 0.05:.1f}x the tracker noise (0.05 mm), within the limit "
            f"of 10x") in kincal.build_report(res).html


def test_a_value_that_rounds_to_zero_is_written_without_a_sign(ur5):
    """A parameter held by a prior at -1e-9 m printed "-0.0000 mm" in the parameter table, and a tool point at
    y = -2e-6 m "(0.30, -0.00, 1.29) mm" (the Panda's report): every number that rounds to zero is written
    unsigned, whatever sign the value had; a value that does not round to zero keeps its sign."""
    from kincal.identify.verdict import mounting_line
    from kincal.units import display, fine, number

    assert [number(v, s) for v, s in ((-1e-9, ".4f"), (-1e-9, "+.4f"), (-0.0, "g"), (-0.00006, "+.4f"))] == \
        ["0.0000", "0.0000", "0", "-0.0001"]
    assert display(-1e-9, "length") == "0.0000 mm" and display(-1e-12, "angle", signed=False) == "0.00000 deg"
    assert fine(-1e-9, "angle", ".3f") == "0.000 mrad" and display(2e-7, "length") == "+0.0002 mm"
    line = mounting_line(np.zeros(3), np.array([0.30e-3, -2e-6, 1.29e-3]))
    assert line.startswith("the data put the target at (0.30, 0.00, 1.29) mm") and "-0.00" not in line
    res = kincal.calibrate(ur5, kincal.simulate(ur5, ur5.sample_joints(30, seed=2), 0.0, seed=3), diagnose=False)
    page = kincal.build_report(res).html
    assert not re.search(r"-0\.0+(?![0-9])", page)  # a perfect fit: every correction rounds to zero


def test_every_pose_set_is_drawn_training_sessions_and_held_out(tmp_path):
    """The Jugglebot's S1 (108 poses) and S2 (60) fitted in joint space: the figures drew S1 alone (S2, in a session
    frame of its own, was left out without a word) and never a held-out set. Now each is drawn, per pose in position
    (mm) and rotation (mrad), the held-out set too."""
    jug = shared_dataset("stewart_jugglebot")
    flags = ["--type", "pose", "--length-unit", "mm", "--angle-unit", "rev", "--orientation", "quat-xyzw",
             "--residual", "joint"]
    both = tmp_path / "both.html"
    assert main(["calibrate", "hexapod", str(jug / "S1.csv"), str(jug / "S2.csv"), *flags, "-o",
                 str(tmp_path / "both.yaml"), "--report", str(both)]) == 0
    html = both.read_text()
    for name, n in (("S1.csv", 108), ("S2.csv", 60)):
        assert html.count(f"training {name} poses ({n}): position error per pose") == 1
        assert html.count(f"training {name} poses ({n}): rotation error per pose") == 1
    held = tmp_path / "held.html"
    assert main(["calibrate", "hexapod", str(jug / "S1.csv"), *flags, "--test", str(jug / "S2.csv"),
                 "--refit-target", "-o", str(tmp_path / "s1.yaml"), "--report", str(held)]) == 0
    page = held.read_text()
    assert "held-out S2.csv poses (60): position error" in page and "held-out S2.csv poses (60): rotation" in page


@pytest.fixture(scope="module")
def jugglebot_pose(tmp_path_factory):
    """The Jugglebot hexapod's first session as 6-D poses (--residual joint): its report and its JSON."""
    juggle, d = shared_dataset("stewart_jugglebot"), tmp_path_factory.mktemp("jug")
    code = main(["calibrate", "hexapod", str(juggle / "S1.csv"), "--type", "pose", "--length-unit", "mm",
                 "--angle-unit", "rev", "--orientation", "quat-xyzw", "--residual", "joint", "-o", str(d / "j.yaml"),
                 "--report", str(d / "j.html")])
    assert code in (0, 1)
    return (d / "j.html").read_text(), json.loads((d / "j.json").read_text())


def _paragraph(html: str, pid: str) -> str:
    """The text of the page's <p id=pid> (unescaped), '' when there is none."""
    import html as h
    found = re.search(rf'<p id="{pid}">(.*?)</p>', html, re.S)
    return h.unescape(found.group(1)) if found else ""


@pytest.mark.xdist_group("report-real")
def test_a_hexapods_held_design_frames_are_said_and_an_undetermined_tool_point_not_called_a_mounting(
        jugglebot_pose, real):
    """The hexapod's "12 gauge freedoms of the design frames, held at ..." line, which the CLI prints, was missing
    from the page; and its mounting paragraph said the tool point "is not determined by these data", then "The tool
    point is where the target was mounted, not a robot error". The page now says the line as the calibration does,
    with as many parameters named as it counts, and the mounting sentence only for a determined tool point."""
    html, data = jugglebot_pose
    note = data["calibration"]["identifiability"]["frames_note"]
    frames = _paragraph(html, "frames")
    assert frames == note[0].upper() + note[1:] + "." and note.startswith("12 gauge freedoms")
    named = [n for group in re.findall(r"\(\d+: ([^)]*)\)", note) for n in group.split(", ")]
    assert len(named) == 12 == len(set(named)) and set(named) == set(data["calibration"]["identifiability"]["frames"])
    mounting = _paragraph(html, "mounting")
    assert "not determined by these data" in mounting and "not a robot error" not in mounting
    ur5 = (real / "report.html").read_text()  # a tool point the data determine: where the target was mounted
    assert _paragraph(ur5, "mounting").endswith("The tool point is where the target was mounted, not a robot error.")
    assert "not determined" not in _paragraph(ur5, "mounting") and not _paragraph(ur5, "frames")


def test_the_correlation_matrix_is_drawn_for_observation_sets_too(jugglebot_pose):
    """The parameters' correlation matrix was drawn for position data only; 6-D poses now have it too: one tick
    label per estimated parameter with a σ, on each axis."""
    html, data = jugglebot_pose
    assert "Residuals per measurement set" in html  # a page of observation sets, not of position data
    start = html.index('<figure id="fig-correlation">')
    labels = re.findall(r"<text[^>]*>([^<]*)</text>", html[start:html.index("</figure>", start)])
    sigma = data["calibration"]["std"]
    finite = [n for n in data["calibration"]["estimated"] if sigma.get(n) is not None and np.isfinite(sigma[n])]
    assert len(finite) > 40
    for name in finite:
        assert labels.count(name) == 2, name


def test_a_thermal_models_covariate_reference_and_range_are_on_the_page():
    """A thermal model's covariate reference (the training median) and fitted range, which the calibrated file keeps,
    appeared nowhere in the report; the error-model section says them, and the JSON has them (SI: as written)."""
    from kincal.models import with_covariates
    from kincal.report import build_report
    from kincal.simulate import simulate_thermal
    nominal = kincal.load_robot("ur5")
    q = nominal.sample_joints(60, seed=2)
    temperature = np.linspace(20.0, 24.0, 60)
    train = simulate_thermal(kincal.perturb(nominal, seed=1), q, temperature, reference=20.0)
    res = kincal.calibrate(with_covariates(nominal, ["temperature"]), train, error_model="thermal:temperature",
                           diagnose=False)
    report = build_report(res)
    mid, pad = np.median(temperature), 0.1 * (24.0 - 20.0)  # the accepted range: 10 % of the fitted one each side
    said = _paragraph(report.html, "covariates")
    assert f"'temperature' was fitted on [20, 24] (reference {mid:g}; accepted {20 - pad:.4g} to {24 + pad:.4g})" \
        in said and said.startswith("Covariates (in the column's unit")
    assert "<h3>Error model</h3>" in report.html
    assert report.data["covariates"] == [{"name": "temperature", "reference": pytest.approx(mid),
                                          "range": [20.0, 24.0]}]
    plain = build_report(kincal.calibrate(nominal, kincal.simulate(nominal, q, 15e-6, seed=3), diagnose=False))
    assert not _paragraph(plain.html, "covariates") and plain.data["covariates"] == []
