"""The demonstration: the seed-1 study on the 3T2R robot, in simulation."""
from __future__ import annotations

import kincal

from .common import emit, positive_int, progress


def cmd_demo(args) -> int:
    with progress("seed-1 study", args.json) as say:
        study = kincal.seed1_study(seeds=args.seeds, m=args.poses, progress=say)
    emit(args, study.to_dict(), str(study))
    return 0


def register(cmd) -> None:
    """Add the commands to the parser through ``cmd(name, func, help)``."""
    s = cmd("demo", cmd_demo, "the seed-1 study on the 3T2R robot (simulation)")
    s.add_argument("--poses", type=positive_int, default=60, help="poses per design (default 60)")
    s.add_argument("--seeds", type=positive_int, default=20, help="repetitions (default 20)")
