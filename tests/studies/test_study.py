"""Monte-Carlo studies: the seed-1 trials, the runner (executors, resume), the CLI."""
import json
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import default_sigint

import kincal
from kincal.cli import main
from kincal.studies import guo2024_mc, runner

pytestmark = pytest.mark.slow  # whole studies and real-data calibrations: make test-fast leaves them out


@pytest.fixture(scope="module")
def small():
    """A small seed-1 study: 30 poses, a short optimisation."""
    return guo2024_mc.prepare(m=30, generations=10)


def records(path):
    lines = [json.loads(line) for line in open(path, encoding="utf-8")]
    return lines[0], sorted([r for t in lines[1:] for r in t["records"]], key=lambda r: r["trial"])


@pytest.mark.xdist_group("guo2024-small")
def test_grid_is_the_equally_spaced_one(small):
    q = small.robot.chain_q(small.grid)
    assert small.robot.feasible(small.grid).all() and len(q) == 60
    assert sorted(set(np.round(q[:, 0], 9))) == pytest.approx([0.1, 0.3, 0.5, 0.7, 0.9])
    assert sorted(set(np.round(np.rad2deg(q[:, 1]), 6))) == pytest.approx([-36, -12, 12, 36])
    assert sorted(set(np.round(q[:, 2], 9))) == pytest.approx([-0.45, -0.25, -0.05])
    part = small.robot.chain_q(small.pools["partial"])
    assert part[:, 0].max() <= 0.5 and part[:, 2].min() >= -0.25 and len(part) > 500


@pytest.mark.xdist_group("guo2024-small")
def test_quill_sag_is_quadratic_in_the_extension(small):
    q = small.grid[:6]
    ext = -small.robot.chain_q(q)[:, 2] / 0.5
    shift = small.positions(small.robot, q, 1e-4) - small.robot.forward(q)
    np.testing.assert_allclose(shift, np.outer(1e-4 * ext**2, [1, 0, 0]), atol=1e-15)


def test_trials_do_not_depend_on_how_they_are_batched(small, tmp_path):
    with runner.make_executor(1) as ex:
        a = runner.run_tasks(small.run, runner.tasks_for(4, 1), ex, tmp_path / "a.jsonl", small.header)
        b = runner.run_tasks(small.run, runner.tasks_for(4, 3), ex, tmp_path / "b.jsonl", small.header)
    assert a == b and [r["trial"] for r in a] == [0, 1, 2, 3]
    assert a[0] != a[1]  # every trial draws its own design, errors and noise


def test_summary_is_the_reduction_distribution():
    recs = []
    for t in range(20):
        r = {"trial": t}
        for truth in guo2024_mc.TRUTHS:
            for name in ("optimised", *guo2024_mc.RANDOM_SETS):
                for val in guo2024_mc.VALIDATIONS:
                    base = 1.0 if name != "optimised" else 0.5 + 0.01 * t  # reduction 50 … 31 %
                    r[f"{truth}/{name}/{val}"] = [base, 2 * base, 3 * base]
        recs.append(r)
    rows = guo2024_mc.summarise(recs)
    expected = 100 * (1 - (0.5 + 0.01 * np.arange(20)))
    assert len(rows) == 24 and all(row["trials"] == 20 for row in rows)
    assert rows[0]["median"] == pytest.approx(np.median(expected)) and rows[0]["p5"] == pytest.approx(
        np.percentile(expected, 5)) and rows[0]["at_least_paper"] == 0.0
    assert "median" in guo2024_mc.report(rows) and "62 %" in guo2024_mc.report(rows)


def test_dask_local_cluster_gives_the_process_pool_results_bit_for_bit(small, tmp_path):
    tasks = runner.tasks_for(4, 1)
    with runner.make_executor(2) as ex:
        pool = runner.run_tasks(small.run, tasks, ex, tmp_path / "p.jsonl", small.header)
    with runner.make_executor(scheduler="local:2") as ex:
        dask = runner.run_tasks(small.run, tasks, ex, tmp_path / "d.jsonl", small.header)
    assert pool == dask and len(pool) == 4
    assert records(tmp_path / "p.jsonl")[1] == records(tmp_path / "d.jsonl")[1]


def test_another_study_or_a_torn_line(small, tmp_path, capsys):
    path = tmp_path / "r.jsonl"
    with runner.make_executor(1) as ex:
        full = runner.run_tasks(small.run, runner.tasks_for(3, 1), ex, path, small.header)
        lines = path.read_text().splitlines()
        path.write_text("\n".join(lines[:2]) + "\n" + lines[2][:25])  # stopped while writing task 1
        again = runner.run_tasks(small.run, runner.tasks_for(3, 1), ex, path, small.header)
        assert again == full
        with pytest.raises(ValueError, match="another study"):
            runner.run_tasks(small.run, runner.tasks_for(3, 1), ex, path, {**small.header, "m": 61})
    (tmp_path / "x.jsonl").write_text("hello\n")
    assert main(["study", "guo2024", "--trials", "2", "--poses", "30", "--generations", "10", "--workers", "1",
                 "-o", str(tmp_path / "x.jsonl")]) == 1
    assert "another study" in capsys.readouterr().err and (tmp_path / "x.jsonl").read_text() == "hello\n"
    empty = tmp_path / "empty.jsonl"  # made beforehand (touch): nothing in it is another study's
    empty.touch()
    with runner.make_executor(1) as ex:
        assert runner.run_tasks(small.run, runner.tasks_for(3, 1), ex, empty, small.header) == full
    assert empty.read_text() == path.read_text()  # the header first, then the tasks, as the other run's file


def test_an_interrupted_study_resumes_to_the_same_results(tmp_path):
    argv = [sys.executable, "-m", "kincal.cli", "study", "guo2024", "--trials", "40", "--per-task", "2", "--poses",
            "30", "--generations", "10", "--workers", "2", "--json"]
    ref = subprocess.run(argv + ["-o", str(tmp_path / "ref.jsonl")], capture_output=True, text=True)
    assert ref.returncode == 0, ref.stderr
    part = tmp_path / "part.jsonl"
    proc = subprocess.Popen(argv + ["-o", str(part)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=default_sigint)
    deadline = time.time() + 60
    while time.time() < deadline and (not part.exists() or len(part.read_text().splitlines()) < 4):
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "run the same command to resume" in err and "Traceback" not in err
    done = len(part.read_text().splitlines()) - 1
    assert 3 <= done < 20  # stopped part-way
    again = subprocess.run(argv + ["-o", str(part)], capture_output=True, text=True)
    assert again.returncode == 0, again.stderr
    assert records(part)[1] == records(tmp_path / "ref.jsonl")[1]
    assert json.loads(again.stdout)["reduction"] == json.loads(ref.stdout)["reduction"]


def test_paper_units_give_the_paper_index_scale():
    """On the raw Jacobian in mm and rad the comprehensive index of the optimised designs lands near
    the paper's 1.833 (full) and 2.049 (separated), in the paper's order; scaled columns give < 1."""
    import kincal
    from kincal.design import candidate_pool, design_problem
    robot = kincal.load_robot("guo3t2r")
    pool = candidate_pool(robot, 400, seed=1)
    names = ("j1.theta", "j2.a", "j2.alpha", "j3.d", "j5.theta")
    P = design_problem(robot, pool, names, units="paper")
    raw = robot.param_jacobian(pool)[:, :, robot.params.indices(names)]
    np.testing.assert_array_equal(P.J, raw * [1e3, 1.0, 1e3, 1.0, 1e3])  # mm per rad; mm per mm
    with pytest.raises(ValueError, match="units"):
        design_problem(robot, pool, names, units="inch")
    study = kincal.studies.guo2024_study(repeats=1, units="paper", generations=60)
    v = study.design_values
    assert 1.4 < v["full-parameter optimised"] < v["separated-parameter optimised"] < 2.2
    assert "(paper: 2.049)" in str(study)


@pytest.mark.xdist_group("guo2024-demo")
def test_paper_protocol_splits_dependent_errors_and_names_the_combinations(capsys, guo2024_demo):
    """No noise, fixed μ = 1 over all 21 parameters: independent errors come back exactly; a group
    that acts through its sum (the d offsets along the vertical axis) is split but its sum is exact,
    as in the paper's Table 4 (d2 0.5097 + d3 0.4903 mm); the positions are matched exactly."""
    d = json.loads(_run(capsys, ["demo", "--protocol", "paper", "--repeats", "1", "--json"]))
    opt = d["identified_errors"]["separated-parameter optimised"]
    assert len(opt) == 21 and opt["j1.a"] == pytest.approx(0.5e-3, abs=1e-9)
    # the sum to 1 µm: with 0.05 rad errors the three axes are not exactly parallel any more
    assert opt["j2.d"] + opt["j3.d"] + opt["j4.d"] == pytest.approx(1.5e-3, abs=1e-6)
    assert abs(opt["j3.d"] - 0.5e-3) > 1e-6  # split, not recovered one by one
    combo = d["combinations"]["separated-parameter optimised"]["j2.d +1·j3.d +1·j4.d"]
    assert combo["eta"] == pytest.approx(100.0, abs=0.5)
    # kincal's own protocol judges a kept stand-in against the combination it carries
    k = guo2024_demo  # demo --repeats 1 --json
    combo = k["combinations"]["separated-parameter optimised"]
    assert all(c["eta"] > 75 for c in combo.values())  # first-order relations at 0.05 rad errors, with noise
    # its exact model sets no error on the dependent parameters: the stand-in j2.d carries its own error only
    assert k["eta_percent"]["separated-parameter optimised"]["j2.d"] == pytest.approx(
        combo["j2.d +1·j3.d +1·j4.d"]["eta"]) and combo["j2.d +1·j3.d +1·j4.d"]["eta"] > 90


def _run(capsys, argv):
    assert main(argv) == 0
    return capsys.readouterr().out


def test_seed_figures_show_the_study_numbers(tmp_path, capsys):
    """Figs. 5-8 and 12-13 of seed 1 from the demo, seed 2's Fig. 7 from a swarm; each figure's data
    are the study's own numbers."""
    import kincal
    from kincal.report import guo2024_figures
    study = kincal.studies.guo2024_study(repeats=1, generations=20)
    figs = guo2024_figures(study)
    assert set(figs) == {"ide-convergence", "pose-count", "eta", "validation-points", "validation-summary", "gcn",
                         "design-positions"}
    # Table 8 and Figs. 12-13 validate on the paper's grid with its error e, and show the same numbers
    robot = kincal.load_robot("guo3t2r")
    true = robot.with_params({n: robot.params[n] + e for n, e in study.true_errors.items()})  # first repetition
    grid = guo2024_mc.paper_grid(robot)
    np.testing.assert_allclose(study.point_errors["before calibration"], true.forward(grid) - robot.forward(grid),
                               atol=1e-12)
    summary = figs["validation-summary"].axes[0]
    heights = sorted(p.get_height() for p in summary.patches)
    table = sorted(v * 1e3 for row in kincal.identify.positions.e_statistics(study.point_errors).values() for v in row)
    np.testing.assert_allclose(heights, table, rtol=1e-12)
    for name, err in study.point_errors.items():
        e = np.asarray(err).mean(axis=1)
        text = str(study).split("Validation on the paper's 60-point grid")[1]
        row = next(line for line in text.splitlines() if line.strip().startswith(name))
        assert row.split()[-3:] == [f"{np.max(np.abs(e)) * 1e3:.4f}", f"{np.mean(np.abs(e)) * 1e3:.4f}",
                                    f"{np.std(e, ddof=1) * 1e3:.4f}"]
    # Fig. 5: cond/m of the separated model's Jacobian (mm, rad) on the first m pool poses
    from kincal.design import candidate_pool, design_problem
    names = study.gcn_curve["parameters"]
    J = design_problem(robot, candidate_pool(robot, 1000, seed=1)[:100], names, units="paper").J
    for m in (10, 60):
        k = study.gcn_curve["m"].index(m)
        assert study.gcn_curve["gcn"][k] == pytest.approx(np.linalg.cond(J[:m].reshape(-1, len(names))) / m, rel=1e-9)
    np.testing.assert_array_equal(figs["gcn"].axes[0].lines[0].get_ydata(), study.gcn_curve["gcn"])
    assert study.gcn_curve["gcn"][0] > 5 * study.gcn_curve["gcn"][-1]  # more poses, better conditioned
    # Fig. 10: the designs' tool positions
    for name, p in study.positions.items():
        assert np.asarray(p).shape == (study.m, 3)
    line = figs["pose-count"].axes[0].lines[0]
    np.testing.assert_array_equal(line.get_ydata(), study.curve["values"])
    bars = [p.get_height() for p in figs["eta"].axes[0].patches]
    expected = [max(study.eta[d].get(n, np.nan), -100.0) for d in ("random", "separated-parameter optimised")
                for n in study.true_errors]
    np.testing.assert_allclose(bars, expected, equal_nan=True)
    hatched = [p.get_hatch() for p in figs["eta"].axes[0].patches][:len(study.true_errors)]
    assert hatched[list(study.true_errors).index("j2.d")] == "///"  # the stand-in for d2 + d3 + d4
    ide = figs["ide-convergence"].axes[1].lines[0].get_ydata()
    np.testing.assert_array_equal(ide, study.histories["separated-parameter optimised"])
    # the command writes them (and refuses a missing folder before any work)
    assert main(["demo", "--repeats", "1", "--plot", str(tmp_path / "no" / "f.png")]) == 1
    assert "does not exist" in capsys.readouterr().err
    puu3 = kincal.load_robot("puu3")
    true = kincal.perturb(puu3, 1e-3, 0.0, seed=1)
    meas = kincal.simulate(true, puu3.sample_joints(30, seed=2), 0.0)
    res = kincal.calibrate(puu3, meas, base="fixed", residual="joint", method="pso",
                           pso={"particles": 40, "iterations": 30})
    fit = kincal.report.figure_set(res)["pso-fitness"].axes[0].lines[0].get_ydata()
    np.testing.assert_allclose(fit, np.sqrt(res.history) * 1e3)


def test_the_paper_row_structure_gives_the_papers_a4_a5_pair(capsys):
    """guo3t2r-paper: the same kinematics as guo3t2r (a fixed A5 row instead of a tool point), and
    the paper's a4/a5 dependence appears exactly (kincal's j5.a / a5.a)."""
    import kincal
    from kincal.analysis.identifiability import identifiability
    a, b = kincal.load_robot("guo3t2r"), kincal.load_robot("guo3t2r-paper")
    phi = a.sample_joints(50, seed=1)
    np.testing.assert_allclose(b.forward(phi), a.forward(phi), atol=1e-12)
    kin = [n for n in b.params.names if n.split(".")[1] in ("theta", "d", "a", "alpha", "beta")]
    ident = identifiability(b, kincal.candidate_pool(b, 500, seed=1), names=kin)
    assert dict(ident.confounds)["a5.a"] == (("j5.a", pytest.approx(1.0)),)
    assert ident.confounds["j4.d"][0][0] == "j2.d" and ident.confounds["a5.alpha"] == ()
    d = json.loads(_run(capsys, ["demo", "--robot", "guo3t2r-paper", "--repeats", "1", "--protocol", "paper",
                                 "--json"]))
    assert len(d["identified_errors"]["random"]) == len(kin) == 25


@pytest.mark.xdist_group("guo2024-small")
def test_the_exact_model_is_exact_without_noise(small):
    """Errors are drawn only where spread poses identify them, so every design's fit can equal the
    truth: < 1 µm training RMS with no noise (errors on dependent parameters left ~0.15 mm); with
    unmodelled errors the same fit cannot."""
    import dataclasses
    quiet = dataclasses.replace(small, noise=0.0)
    assert set(quiet.drawn) < set(quiet.kin) and len(quiet.drawn) >= 12
    for t in (0, 1):
        rec = quiet.trial(t)
        for name in ("optimised", *guo2024_mc.RANDOM_SETS):
            assert rec[f"exact/{name}/train_rms"] < 1e-6, (t, name)
            assert rec[f"unmodelled/{name}/train_rms"] > 5e-6, (t, name)
    every = dataclasses.replace(quiet, drawn=())  # the former truth: errors on every kinematic parameter
    assert max(every.trial(0)[f"exact/{n}/train_rms"] for n in ("optimised", "random")) > 1e-5


@pytest.mark.xdist_group("guo2024-small")
def test_a_file_of_more_trials_or_a_study_that_cannot_start_says_so(small, tmp_path, capsys):
    """A results file of 3 trials asked for 2 says it holds 3 and how to use them (it said the file was changed
    or written by another version); a study whose first task fails leaves no file (a header alone made every
    later run refuse it); too few poses for the study's parameters are refused before the preparation."""
    path = tmp_path / "r.jsonl"
    with runner.make_executor(1) as ex:
        runner.run_tasks(small.run, runner.tasks_for(3, 1), ex, path, small.header)
        with pytest.raises(ValueError, match=r"holds 3 trials of this study, more than the 2 asked; give --trials 3"):
            runner.run_tasks(small.run, runner.tasks_for(2, 1), ex, path, small.header)

        def broken(task):
            raise ValueError("the first task fails")
        with pytest.raises(ValueError, match="the first task fails"):
            runner.run_tasks(broken, runner.tasks_for(2, 1), ex, tmp_path / "new.jsonl", small.header)
    assert not (tmp_path / "new.jsonl").exists()
    k = len(kincal.identifiability(small.robot, kincal.candidate_pool(small.robot, 1000, seed=1),
                                   names=small.kin).identifiable)
    assert main(["study", "guo2024", "--poses", str(k // 3), "-o", str(tmp_path / "few.jsonl")]) == 1
    assert f"give --poses {k // 3 + 1} or more" in capsys.readouterr().err and not (tmp_path / "few.jsonl").exists()


@pytest.mark.xdist_group("guo2024-small")
def test_study_settings_that_do_not_apply_or_differ_are_named(small, tmp_path, capsys):
    """A file run with another --per-task was 'the results of another study'; --workers beside --scheduler was
    ignored; --poses 1000 ended in 'first_best of an empty sequence'. Each is said in the flags' words."""
    import os

    path = tmp_path / "r.jsonl"
    with runner.make_executor(1) as ex:
        runner.run_tasks(small.run, runner.tasks_for(2, 1), ex, path, {**small.header, "per_task": 1})
        with pytest.raises(ValueError, match=r"another study, run with --per-task 1 \(give the same to resume it\)"):
            runner.run_tasks(small.run, runner.tasks_for(2, 2), ex, path, {**small.header, "per_task": 2})
    workers = str((os.cpu_count() or 1) + 1)  # not the default, so given
    assert main(["study", "guo2024", "--workers", workers, "--scheduler", "local:1", "-o",
                 str(tmp_path / "w.jsonl")]) == 1
    assert "with --scheduler local:1 the Dask cluster's workers run the study" in capsys.readouterr().err
    assert main(["study", "guo2024", "--poses", "1000", "-o", str(tmp_path / "p.jsonl")]) == 1
    said = capsys.readouterr().err
    assert "the designs choose among 1000 candidates" in said and "give --poses 500 or fewer" in said
    assert not (tmp_path / "w.jsonl").exists() and not (tmp_path / "p.jsonl").exists()


@pytest.mark.xdist_group("guo2024-small")
def test_a_study_grows_shrinks_and_resumes_over_a_partial_last_task(small, tmp_path, capsys):
    """Tasks of 2 trials: a file of 3 trials (its last task holds one) extended to 4, and a file of 4 read for 3,
    were refused as 'changed or written by another version'; a line torn by an interruption was continued by the
    next record into a line no JSON reader takes. The trials are the fresh run's, and every line is JSON."""
    import os

    header = {**small.header, "per_task": 2}
    with runner.make_executor(1) as ex:
        fresh = runner.run_tasks(small.run, runner.tasks_for(4, 2), ex, tmp_path / "fresh.jsonl", header)
        runner.run_tasks(small.run, runner.tasks_for(3, 2), ex, tmp_path / "grow.jsonl", header)
        assert runner.run_tasks(small.run, runner.tasks_for(4, 2), ex, tmp_path / "grow.jsonl", header) == fresh
        assert runner.run_tasks(small.run, runner.tasks_for(3, 2), ex, tmp_path / "fresh.jsonl", header) == fresh[:3]
        torn = tmp_path / "torn.jsonl"
        torn.write_text((tmp_path / "fresh.jsonl").read_text()[:-40])  # stopped while writing the last task
        assert runner.run_tasks(small.run, runner.tasks_for(4, 2), ex, torn, header) == fresh
    assert all(json.loads(line) for line in torn.read_text().splitlines())
    workers = str(os.cpu_count() or 1)  # the default's value, given: still refused beside a scheduler
    assert main(["study", "guo2024", "--workers", workers, "--scheduler", "local:1", "-o",
                 str(tmp_path / "w.jsonl")]) == 1
    assert "the Dask cluster's workers run the study" in capsys.readouterr().err
