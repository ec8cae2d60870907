"""Issue 34's speed target: a KRL program of many E6POS targets (the bundled KR 6 R900 sixx, a calibration of it)
compensated on each target's own branch, checked as written (target: 10^4 targets in 2 s). Prints a table.
Usage: python benchmarks/programs.py [N]"""
import sys
import time

import numpy as np

import kincal
from kincal.compensate import compensate_branches
from kincal.io import ROWS, read_program


def program(nominal, n: int, path: str) -> None:
    """A .dat with n E6POS targets along a smooth path (flange poses, mm and deg, their S and T)."""
    t = np.linspace(0, 1, n)[:, None]
    q = np.radians([10, -80, 100, 20, 40, 30]) + t * np.radians([60, 30, -40, 90, 30, 120])
    p, R, _, _ = nominal.with_tool_point(np.zeros(3)).pose_and_jacobian(q)
    lines = ["DEFDAT  BENCH"]
    bits = ROWS["krl"](nominal, q)
    for k in range(n):
        a, b, c = np.degrees(kincal.models.transforms.zyx_nearest(R[k], np.zeros(3)))
        s, tt = bits[k]
        x, y, z = p[k] * 1e3
        lines.append(f"DECL E6POS XP{k}={{X {x:.3f},Y {y:.3f},Z {z:.3f},A {a:.3f},B {b:.3f},C {c:.3f},S {s},T {tt}}}")
    open(path, "w").write("\n".join(lines + ["ENDDAT", ""]))


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 10_000
    nominal = kincal.load_robot("kuka_kr6r900sixx")
    cal = kincal.perturb(nominal, seed=1)
    program(nominal, n, "/tmp/kincal_bench.dat")
    prog = read_program("/tmp/kincal_bench.dat", "krl")
    t0 = time.perf_counter()
    res = compensate_branches(cal, nominal, prog, ROWS["krl"], {"default tool": np.eye(4), "default base": np.eye(4)})
    took = time.perf_counter() - t0
    print(f"{'case':<60} {'time':>9} {'target':>8}")
    print(f"{f'KRL program, {n} E6POS targets, compensated and checked':<60} {took:8.2f}s {f'{2 * n / 1e4:g} s':>8}")
    print(f"({len(res.texts)} of {len(prog.targets)} compensated)")


if __name__ == "__main__":
    main()
