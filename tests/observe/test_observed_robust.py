"""Robust losses and outlier rejection in the fit of observation sets: each sample's whitened block
(a 6-D pose's six rows, a marker sample's seen markers) reweighted or left out, against a fit of the
same data without the bad samples and against the true robot."""
import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kincal
from kincal.cli import main
from kincal.identify.robust import block_weights, chi_median
from kincal.identify import fit_observations
from kincal.observe import ObservationFormat, write_observations
from kincal.simulate.observations import simulate_markers, simulate_poses

BAD = np.array([7, 50, 91, 130, 177])  # samples given a 3 mm position error
TARGET = Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix()


@pytest.fixture(scope="module")
def case():
    ur5 = kincal.load_robot("ur5").with_tool_point([0.05, 0.02, 0.1])
    true = kincal.perturb(ur5, seed=3)
    clean = simulate_poses(true, ur5.sample_joints(200, seed=1), TARGET, 20e-6, 0.05e-3, seed=1)
    xyz = clean.xyz.copy()
    xyz[BAD, 0] += 3e-3
    q_test = ur5.sample_joints(200, seed=9)
    return ur5, true, clean, dataclasses.replace(clean, xyz=xyz), q_test


def _error(fit, true, q) -> float:
    """Mean distance (m) between the fitted and the true robot's tool point at held-out joints."""
    return float(np.mean(np.linalg.norm(fit.robot.forward(q) - true.forward(q), axis=1)))


def test_block_weights_by_hand():
    """Three samples of 2, 2 and 1 rows and a row of no sample; Huber against 3 robust σ."""
    r = np.array([0.3, 0.4, 3.0, 4.0, 0.6, 9.0])
    owner = np.array([0, 0, 1, 1, 2, -1])
    norms = np.array([0.5, 5.0, 0.6])
    sigma = np.median(norms / chi_median(np.array([2, 2, 1])))
    z = (norms / (3 * sigma)) ** 2
    w = np.where(z <= 1, 1.0, 1 / np.sqrt(z))
    np.testing.assert_allclose(block_weights(r, owner, 3, "huber"), np.sqrt(np.r_[w[0], w[0], w[1], w[1], w[2], 1.0]))
    assert w[1] < 1 and w[0] == w[2] == 1  # only the far sample is down-weighted
    # the median norm of d unit Gaussians, against a large sample
    g = np.random.default_rng(0).standard_normal((200_000, 6))
    for d in (1, 3, 6):
        assert chi_median(d) == pytest.approx(np.median(np.linalg.norm(g[:, :d], axis=1)), rel=0.02)


def test_robust_losses_resist_bad_poses(case):
    ur5, true, clean, dirty, q = case
    reference = fit_observations(ur5, [clean.subset(np.setdiff1d(np.arange(len(clean)), BAD))])
    ls = fit_observations(ur5, [dirty])
    assert np.array_equal(ls.outliers[0], BAD)  # named by the verdict, not left out
    assert any(r.code == "outliers" for r in ls.verdict.reasons)
    e_ref, e_ls = _error(reference, true, q), _error(ls, true, q)
    assert e_ls > 10 * e_ref
    for loss in ("huber", "soft_l1"):
        e = _error(fit_observations(ur5, [dirty], loss=loss), true, q)
        assert e < 2 * e_ref and e < e_ls / 5, (loss, e, e_ref, e_ls)


def test_outliers_left_out_give_the_fit_without_them(case):
    ur5, true, clean, dirty, q = case
    fit = fit_observations(ur5, [dirty], reject_outliers=True)
    assert fit.rejected == {dirty.source: tuple(int(r) for r in dirty.rows[BAD])}
    reference = fit_observations(ur5, [dirty.subset(np.setdiff1d(np.arange(len(dirty)), BAD))])
    np.testing.assert_allclose(fit.robot.params.values, reference.robot.params.values, rtol=0, atol=1e-12)
    assert fit.verdict.status == "good" and not any(len(b) for b in fit.outliers)
    assert "left out as outliers" in str(fit) and fit.to_dict()["rejected_rows"] == {dirty.source: list(dirty.rows[BAD])}
    # clean data: nothing left out, the same fit as without the option
    plain = fit_observations(ur5, [clean])
    again = fit_observations(ur5, [clean], reject_outliers=True)
    assert again.rejected == {} and np.array_equal(again.robot.params.values, plain.robot.params.values)


def test_marker_samples_are_judged_whole(case):
    """A sample whose one marker is 3 mm off is left out with all its markers."""
    ur5, true, *_ = case
    markers = np.array([[0.05, 0.0, 0.1], [-0.03, 0.05, 0.08], [0.0, -0.06, 0.12]])
    obs = simulate_markers(true, ur5.sample_joints(150, seed=4), markers, 20e-6, seed=2)
    xyz = obs.xyz.copy()
    xyz[[11, 90], 1, 2] += 3e-3
    fit = fit_observations(ur5, [dataclasses.replace(obs, xyz=xyz)], reject_outliers=True)
    assert fit.rejected == {obs.source: (int(obs.rows[11]), int(obs.rows[90]))}


@pytest.mark.slow
def test_command_line_leaves_out_bad_poses(case, tmp_path, capsys):
    ur5, true, clean, dirty, q = case
    path = tmp_path / "poses.csv"
    write_observations(path, dirty, ur5, ObservationFormat("pose", length_unit="mm"))
    cal = tmp_path / "cal.yaml"
    args = ["calibrate", "ur5", str(path), "--type", "pose", "--tool", "50,20,100mm", "--length-unit", "mm",
            "--std-pos", "0.02mm", "--std-rot", "0.05mrad", "-o", str(cal)]
    assert main([*args, "--reject-outliers"]) == 0
    out = capsys.readouterr().out
    assert f"row(s) {', '.join(str(r) for r in dirty.rows[BAD])}" in out and "verdict: GOOD" in out
    assert main(["report", str(cal), "-o", str(tmp_path / "r.html")]) == 0  # the record repeats the rejection
    assert "Left out as outliers" in (tmp_path / "r.html").read_text() and "verdict: GOOD" in capsys.readouterr().out
    assert main([*args[:-2], "--loss", "huber"]) == 0
    out = capsys.readouterr().out
    assert "outlier sample(s)" in out and "verdict: SUSPECT" in out  # still named, but down-weighted


@pytest.mark.slow
def test_residuals_file_per_sample(case, tmp_path, capsys):
    """--residuals for pose data: each sample's position and rotation error against the fitted model
    computed here from the written robot and set-up, the outliers flagged where the verdict names them."""
    import csv

    ur5, true, clean, dirty, q = case
    path, out, cal = tmp_path / "poses.csv", tmp_path / "res.csv", tmp_path / "cal.yaml"
    write_observations(path, dirty, ur5, ObservationFormat("pose", length_unit="mm"))
    assert main(["calibrate", "ur5", str(path), "--type", "pose", "--tool", "50,20,100mm", "--length-unit", "mm",
                 "--std-pos", "0.02mm", "--std-rot", "0.05mrad", "--residuals", str(out), "-o", str(cal),
                 "--force"]) in (0, 3)
    assert f"per-sample residuals written to {out}" in capsys.readouterr().out
    rows = list(csv.DictReader(open(out)))
    assert [int(r["row"]) for r in rows] == list(dirty.rows)
    assert [int(r["row"]) for r in rows if r["outlier"] == "yes"] == list(dirty.rows[BAD])
    fit = fit_observations(ur5, [dirty])
    robot = kincal.load_robot(str(cal))
    _, _, Rf = robot.frame_and_rates(dirty.q)[:3]
    target = fit.observations[0].target(np.array([fit.nuisance[f"target.r{a}"] for a in "xyz"]))
    pos = np.linalg.norm(robot.forward(dirty.q) - dirty.xyz, axis=1) * 1e3
    ang = Rotation.from_matrix(Rf @ target @ dirty.R.transpose(0, 2, 1)).magnitude() * 1e3
    np.testing.assert_allclose([float(r["position_error_mm"]) for r in rows], pos, rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose([float(r["rotation_error_mrad"]) for r in rows], ang, rtol=1e-5, atol=1e-9)


def test_label_swapped_marker_samples_are_named_before_the_residual(case):
    """Four samples whose first two markers were swapped (a label mix-up): the least-squares fit was refused with
    "data and model do not belong together" first, and under --loss huber (a fit as good as without them) still
    refused for residuals 119x their σ, counted over the down-weighted samples. The outliers come first and, once
    down-weighted, are the whole reason; an honest fit stays GOOD."""
    ur5, true, *_ = case
    markers = np.array([[0.05, 0.0, 0.1], [-0.03, 0.05, 0.08], [0.0, -0.06, 0.12]])
    q = ur5.sample_joints(80, seed=4)
    obs = simulate_markers(true, q, markers, 20e-6, seed=2)
    xyz = obs.xyz.copy()
    bad = [6, 16, 26, 36]
    xyz[bad, 0], xyz[bad, 1] = obs.xyz[bad, 1], obs.xyz[bad, 0]
    swapped = dataclasses.replace(obs, xyz=xyz)
    honest = fit_observations(ur5, [obs])
    assert honest.verdict.status == "good"
    linear = fit_observations(ur5, [swapped])
    codes = [r.code for r in linear.verdict.reasons]
    assert linear.verdict.status == "refused" and codes.index("outliers") < codes.index("residual")
    assert "outlier samples above" in linear.verdict.reasons[codes.index("residual")].message
    huber = fit_observations(ur5, [swapped], loss="huber")
    assert huber.verdict.status == "suspect" and "residual" not in [r.code for r in huber.verdict.reasons]
    assert set(obs.rows[bad]) <= set(obs.rows[huber.outliers[0]])
    assert _error(huber, honest.robot, q) < 0.1 * _error(linear, honest.robot, q)  # right: the samples were wrong
