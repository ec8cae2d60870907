"""Helpers shared by the command-line modules: consoles, data flags, progress, output."""
from __future__ import annotations

import argparse
import json
import sys
from contextlib import contextmanager

import numpy as np
from rich.console import Console

import kincal

out = Console(highlight=False, soft_wrap=True)
err = Console(stderr=True, highlight=False, soft_wrap=True)
EXIT_ERROR, EXIT_NOT_CONVERGED = 1, 3
MM, DEG = 1e3, 180.0 / np.pi


def csv_list(s: str) -> list[str]:
    return [c.strip() for c in s.split(",") if c.strip()]


def add_data_flags(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("data columns and units")
    g.add_argument("--joint-cols", type=csv_list, default=None,
                   help="comma-separated joint columns (default: the robot's joint names)")
    g.add_argument("--xyz-cols", type=csv_list, default=["x", "y", "z"], help="position columns (default x,y,z)")
    g.add_argument("--length-unit", default="m", choices=["m", "mm", "um"], help="positions, prismatic joints")
    g.add_argument("--angle-unit", default="rad", choices=["rad", "deg"], help="revolute joints")


def read(args, robot, path):
    return kincal.read_measurements(path, robot, joint_cols=args.joint_cols, xyz_cols=args.xyz_cols,
                                    length_unit=args.length_unit, angle_unit=args.angle_unit)


@contextmanager
def progress(message: str, quiet: bool):
    """A spinner on stderr for work that may take over a second (off with --json)."""
    if quiet or not err.is_terminal:
        yield lambda msg: None
        return
    with err.status(message) as status:
        yield lambda msg: status.update(msg)


def emit(args, payload: dict, text) -> None:
    if args.json:
        sys.stdout.write(json.dumps(payload, indent=2, default=json_default) + "\n")
    elif isinstance(text, str):
        out.print(text, markup=False)
    else:
        out.print(text)


def json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
