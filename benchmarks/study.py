"""The Monte-Carlo study of Guo et al. 2024's claim and how it scales: 200 trials on one worker, on two, and on a Dask
LocalCluster of two (when kincal[dask] is installed). Targets: 200 trials ≤ 5 min on 2 cores; two
workers ≥ 1.7× faster than one; Dask gives the same numbers as the process pool.

    python benchmarks/study.py [trials]
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from kincal.studies import runner, guo2024_mc


def main() -> None:
    trials = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    t0 = time.perf_counter()
    study = guo2024_mc.prepare()
    prep = time.perf_counter() - t0
    print(f"prepare (separation, DETMAX-IDE design, pools): {prep:.1f} s")
    print(f"{'executor':<22} {'trials':>6} {'time s':>8} {'speed-up':>9}  same results")
    results, base = {}, None
    runs = [("in-process (1)", {"workers": 1}), ("process pool (2)", {"workers": 2})]
    try:
        import distributed  # noqa: F401
        runs.append(("dask local:2", {"scheduler": "local:2"}))
    except ImportError:
        print("(dask not installed: pip install 'kincal[dask]')")
    with tempfile.TemporaryDirectory() as tmp:
        for label, kw in runs:
            t0 = time.perf_counter()
            with runner.make_executor(**kw) as ex:
                results[label] = runner.run_tasks(study.run, runner.tasks_for(trials), ex,
                                                  Path(tmp) / f"{len(results)}.jsonl", study.header)
            t = time.perf_counter() - t0
            base = base or t
            same = results[label] == results["in-process (1)"]
            print(f"{label:<22} {trials:>6} {t:8.1f} {base / t:8.2f}x  {same}")
    print(guo2024_mc.report(guo2024_mc.summarise(results["in-process (1)"])))
    print("targets: 200 trials <= 300 s on 2 cores; process pool (2) >= 1.7x; identical results")


if __name__ == "__main__":
    main()
