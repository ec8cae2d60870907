"""The demonstration (Guo et al. 2024 reproduced on the 3T2R robot) and Monte-Carlo studies that scale out."""
from __future__ import annotations

import argparse
import os
from pathlib import Path

import kincal.studies
from kincal.papers import GUO2024
from kincal.studies import guo2024, guo2024_mc, runner

from .common import EXIT_INTERRUPTED, check_paths, emit, hidden_alias, line, positive_int, progress, progress_bar
from .report import save_figures

STUDIES = {"guo2024": "guo2024", "seed1": "guo2024"}  # study names (and the 0.1 name, still accepted)


def cmd_demo(args) -> int:
    check_paths([], [args.plot])  # before the work: a figure folder that does not exist
    with progress(f"{GUO2024} reproduced", args.json) as say:
        study = kincal.studies.guo2024_study(repeats=args.repeats, m=args.poses, progress=say, protocol=args.protocol,
                                             units=args.units, robot=args.robot)
    text = str(study)
    if args.plot:
        from kincal.report import guo2024_figures

        text += "\n" + "\n".join(save_figures(guo2024_figures(study), args.plot))
    return emit(args, study.to_dict(), text)


def cmd_study(args) -> int:
    out = Path(args.output)
    if out.exists() and out.is_dir():
        raise ValueError(f"{out}: is a folder; give a results file (JSON lines)")
    if args.scheduler and "workers" in args.given:
        raise ValueError(f"--workers sets the worker processes on this machine; with --scheduler {args.scheduler} the "
                         f"Dask cluster's workers run the study (local:N gives N): give one of the two")
    header = {**guo2024_mc.settings(args.poses, args.generations, args.seed), "per_task": args.per_task}
    runner.check_results_file(out, header)  # another study's file is refused before the preparation
    with progress("preparing the study", args.json) as say:
        trials = guo2024_mc.prepare(m=args.poses, generations=args.generations, seed=args.seed, say=say)
    tasks = runner.tasks_for(args.trials, args.per_task)
    try:
        with runner.make_executor(args.workers or os.cpu_count() or 1, args.scheduler) as ex, progress_bar(args, "study", len(tasks)) as bar:
            records = runner.run_tasks(trials.run, tasks, ex, out, header, bar)
    except KeyboardInterrupt:
        line(f"kincal: interrupted; the finished tasks are kept in {out}: run the same command to resume"
             if out.exists() and out.stat().st_size else "kincal: interrupted before any task finished; nothing "
             "was kept: run the same command to start again")
        return EXIT_INTERRUPTED
    try:
        rows = guo2024_mc.summarise(records)
    except (KeyError, TypeError, ValueError, IndexError) as exc:  # records read back from the file
        raise ValueError(f"{out}: its trial records lack the study's results (key or value {exc} missing or "
                         f"malformed); the file was changed or written by another version; give a new output file "
                         f"or remove this one") from None
    return emit(args, {"results_file": str(out), "trials": len(records), "settings": header, "reduction": rows},
                guo2024_mc.report(rows) + f"\nper-trial results: {out}")


def _study(s: str) -> str:
    """argparse type: a study's name (its 0.1 name is still accepted)."""
    if s not in STUDIES:
        raise argparse.ArgumentTypeError(f"'{s}': the study is guo2024 ({GUO2024}'s 62 % claim)")
    return STUDIES[s]


def _scheduler(s: str) -> str:
    if s.startswith("local:"):
        positive_int(s.split(":", 1)[1])
    elif "://" not in s:
        raise argparse.ArgumentTypeError(f"'{s}': give a Dask scheduler address such as tcp://host:8786, or local:N")
    return s


def register(cmd) -> None:
    s = cmd("demo", cmd_demo, f"{GUO2024} (measurement-pose optimisation) reproduced on the 3T2R robot, in "
                              f"simulation", None)
    s.add_argument("--poses", type=positive_int, default=60, help="poses per design (default 60)")
    s.add_argument("--repeats", type=positive_int, default=20,
                   help="repetitions, each with new parameter errors (and, protocol kincal, new noise) from its "
                        "own random seed; the designs stay (default 20)")
    hidden_alias(s, "--seeds", "repeats", type=positive_int)
    s.add_argument("--robot", choices=["guo3t2r", "guo3t2r-paper"], default="guo3t2r",
                   help="the model: guo3t2r (tool point) or guo3t2r-paper (the paper's fixed A5 tool row)")
    s.add_argument("--plot", help="figures to write (Figs. 5-8, 10, 12-13): STEM.png or STEM.svg gives STEM-<figure>.png/.svg")
    s.add_argument("--protocol", choices=list(guo2024.PROTOCOLS), default="kincal",
                   help="kincal (default): errors only on the identifiable kinematic parameters, 0.015 mm tracker "
                        "noise, adaptive LM over them; paper: errors on every kinematic parameter (21 on guo3t2r, "
                        "25 on guo3t2r-paper), no noise, LM with a fixed mu = 1 over all of them")
    s.add_argument("--units", choices=["scaled", "paper"], default="scaled",
                   help="comprehensive index on scaled columns (default) or the raw Jacobian in mm and rad (paper)")
    s = cmd("study", cmd_study, f"Monte-Carlo study: {GUO2024}'s optimised against random poses, as a distribution",
            None)
    s.add_argument("name", type=_study, metavar="STUDY", help=f"the study: guo2024 ({GUO2024}'s 62 %% claim)")
    s.add_argument("--trials", type=positive_int, default=200,
                   help="trials, each a new random design, parameter errors and noise (default 200)")
    s.add_argument("--per-task", type=positive_int, default=runner.TRIALS_PER_TASK,
                   help=f"trials per task sent to a worker (default {runner.TRIALS_PER_TASK})")
    s.add_argument("--workers", type=positive_int, default=None,
                   help="worker processes on this machine (default: one per core; 1 runs in this process)")
    s.add_argument("--scheduler", type=_scheduler,
                   help="run on Dask: a scheduler address (tcp://host:8786) or local:N for a local cluster of N "
                        "workers (needs kincal[dask])")
    s.add_argument("--poses", type=positive_int, default=60, help="poses per design (default 60)")
    s.add_argument("--generations", type=positive_int, default=150, help="IDE generations of the optimised design")
    s.add_argument("--seed", type=int, default=0, help="the study's random seed (default 0)")
    s.add_argument("-o", "--output", default="guo2024_study.jsonl",
                   help="results file, one line per finished task; an existing one of the same study is resumed "
                        "(default guo2024_study.jsonl)")
