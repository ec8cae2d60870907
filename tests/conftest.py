"""Shared fixtures: bundled robots, the real datasets used in place (``../shared/datasets``), the Guo et al. 2024
demo."""
import contextlib
import io
import json
import os
import signal
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import kincal
from shared_data import POSITIONER_MODEL, ROOT, shared_dataset  # noqa: F401  (the tests import them from here)

DATA = shared_dataset("ur5_wam_gts3800")  # a UR5 and a WAM with a GTS3800 laser tracker
SOCKETS = shared_dataset("panda_sockets")  # a Panda's ball seated in plate sockets, with the Panda's URDF
POSITIONER = shared_dataset("positioner_6d")  # a two-axis positioner's target seen by a camera (6-D poses)
UR5_URDF = shared_dataset("urdf") / "ur5_robot.urdf"  # UR's UR5 description (example-robot-data)
PANDA_URDF = SOCKETS / "panda.urdf"
UR5_COLS = [f"joint_{i}" for i in range(1, 7)]
WAM_COLS = [f"joint_{i}" for i in range(1, 8)]


def pytest_configure(config):
    """One BLAS thread, here and in the commands the tests start: under pytest-xdist (make test: -n 2) each
    worker shares the two cores with the other, and alone (make test-fast) the tests share them with the rest
    of the machine. OpenBLAS threads that spin on a busy machine make the designs and separations that kincal
    does not limit itself 5-10x slower (a pose design 0.3 s -> 20 s) for matrices this small."""
    os.environ["OPENBLAS_NUM_THREADS"] = "1"  # libraries loaded later, and child processes
    threadpool_limits(1, user_api="blas")  # numpy's, loaded already


def skeleton(text: str, targets) -> list[str]:
    """The pieces of a program's text between its targets' fields: what a rewrite must leave as they were."""
    out, at = [], 0
    for a, b in sorted(f for t in targets for f in t.fields):
        out.append(text[at:a])
        at = b
    return out + [text[at:]]


@pytest.hookimpl(trylast=True)  # after pytest-xdist's own hook, which names each test's group
def pytest_collection_modifyitems(config, items):
    """The tests marked slow first, each group in collection order: make test's two workers then share the long
    ones from the start, and the short ones even out the end (the last long test no longer runs alone).

    Under ``--dist loadgroup`` each test of an ``xdist_group`` must reach the scheduler as ``<id>@<group>``:
    pytest-xdist 3.8 writes that suffix where pytest ≤ 9.1 kept the id, and pytest 9.2 no longer reads it from
    there, so every group was silently split over both workers (a shared session fixture computed twice). The
    suffix is set here where it is missing, and left alone where pytest-xdist set it."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
    if not os.environ.get("PYTEST_XDIST_WORKER") or not vars(config.option).get("loadgroup"):
        return
    for item in items:
        groups = sorted({str(m.args[0] if m.args else m.kwargs.get("name", "default"))
                         for m in item.iter_markers("xdist_group")})
        suffix = "@" + "_".join(groups)
        if groups and not item.nodeid.endswith(suffix):
            from _pytest.nodeid import NodeId  # pytest 9.2's structured id, only where the suffix did not hold

            item._id = NodeId.parse(item.nodeid + suffix)


@pytest.fixture(scope="session")
def ur5():
    return kincal.load_robot("ur5")


@pytest.fixture(scope="session")
def guo2024_demo() -> dict:
    """The JSON of ``kincal demo --repeats 1 --json`` (the whole study, ~8 s), run once for the tests
    that read it; they share the xdist group "guo2024-demo" so that make test's workers run it once."""
    from kincal.cli import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["demo", "--repeats", "1", "--json"]) == 0
    return json.loads(out.getvalue())


def default_sigint() -> None:
    """For a child process (``preexec_fn``): Ctrl-C as at a terminal, even when the tests run where
    SIGINT is ignored (a shell's background job, some CI runners) — Python installs its
    KeyboardInterrupt handler only if SIGINT is not ignored at start."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def central_jacobian(robot, q, h=1e-6):
    """Central differences of forward() over every parameter, (N,3,P)."""
    v = robot.params.values
    cols = []
    for k in range(v.size):
        e = np.zeros_like(v)
        e[k] = h
        cols.append((robot.forward(q, v + e) - robot.forward(q, v - e)) / (2 * h))
    return np.stack(cols, axis=2)


def assert_jacobians(robot, q, param_tol=1e-6, joint_tol=1e-8, h=1e-6):
    """param_jacobian (relative) and joint_jacobian (absolute, m/rad) against central differences."""
    J, Jn = robot.param_jacobian(q), central_jacobian(robot, q)
    assert np.abs(J - Jn).max() / np.abs(J).max() < param_tol
    Jq = np.stack([(robot.forward(q + h * e) - robot.forward(q - h * e)) / (2 * h) for e in np.eye(q.shape[1])],
                  axis=2)
    assert np.abs(robot.joint_jacobian(q) - Jq).max() < joint_tol


def registered_markers(robot, sets, points=None):
    """Reference for the "before" of markers: the mean marker error (m) of ``robot``'s kinematics with each set's
    measurement frame and the markers' points (shared) registered by scipy's least squares, the points (k, 3) m
    (``points``: held at these) and each set's frame as (R (3, 3), t (3,)) taking the robot's frame to the set's."""
    from scipy.optimize import least_squares
    from scipy.spatial.transform import Rotation

    k, n = sets[0].xyz.shape[1], 6 * len(sets)

    def frames(x):
        return [(Rotation.from_rotvec(x[6 * s:6 * s + 3]).as_matrix(), x[6 * s + 3:6 * s + 6]) for s in range(len(sets))]

    def residual(x):
        pts = x[n:].reshape(k, 3) if points is None else points
        return np.concatenate([robot.with_tool_point(p).forward(obs.q) @ R.T + t - obs.xyz[:, m]
                               for obs, (R, t) in zip(sets, frames(x)) for m, p in enumerate(pts)])  # (N k, 3) m
    x = least_squares(lambda x: residual(x).ravel(), np.zeros(n + (3 * k if points is None else 0)), xtol=1e-14,
                      ftol=1e-14).x
    return float(np.linalg.norm(residual(x), axis=1).mean()), x[n:].reshape(k, 3) if points is None else points, \
        frames(x)


def z_limit(n: int, alpha: float = 0.01) -> float:
    """The bound on the largest |z| of n standard normal z-scores that a correct estimator exceeds with
    probability alpha (two-sided, Bonferroni): 3.0 is exceeded by one of 128 honest z-scores 29 % of the
    time, this bound (3.9 for 128) 1 % of the time."""
    from scipy.stats import norm

    return float(norm.isf(alpha / (2 * n)))


def postgres_binary(name: str) -> str:
    """PostgreSQL's program ``name`` (initdb, pg_ctl) on PATH or in /usr/lib/postgresql/*/bin (newest first); the
    test fails, saying how to install it, when there is none."""
    import glob
    import shutil

    found = shutil.which(name)
    if found:
        return found
    for folder in sorted(glob.glob("/usr/lib/postgresql/*/bin"), key=lambda p: int(p.split("/")[-2]), reverse=True):
        if os.access(os.path.join(folder, name), os.X_OK):
            return os.path.join(folder, name)
    pytest.fail(f"PostgreSQL's {name} is not installed (looked on PATH and in /usr/lib/postgresql/*/bin): the store's "
                f"tests run a real server; install Debian's postgresql (apt-get install postgresql; .ci/run does)")


@pytest.fixture(scope="session")
def postgres_url():
    """A real PostgreSQL server for the tests' session: initdb into a temporary folder, started with pg_ctl on a
    Unix socket in that folder (no TCP) and a free port number, as the postgres user when the tests run as root;
    stopped and removed at the end (fsync off: a throwaway server; a killed client, which the tests kill, is
    unaffected). The URL of its 'postgres' database (trust authentication)."""
    import pwd
    import shutil
    import socket
    import subprocess
    import tempfile

    initdb, pg_ctl = postgres_binary("initdb"), postgres_binary("pg_ctl")
    root = Path(tempfile.mkdtemp(prefix="kincal-pg-"))  # in /tmp: short enough for a socket path
    as_user: list[str] = []
    if os.geteuid() == 0:  # the server refuses to run as root
        shutil.chown(root, "postgres", pwd.getpwnam("postgres").pw_gid)
        as_user = ["runuser", "-u", "postgres", "--"]
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    data, log = root / "data", root / "server.log"

    def run(*cmd: str) -> None:
        done = subprocess.run([*as_user, *cmd], capture_output=True, text=True)
        if done.returncode:
            pytest.fail(f"{' '.join(cmd[:2])} failed ({done.returncode}): {done.stderr.strip() or done.stdout.strip()}"
                        + (f"\n{log.read_text()}" if log.exists() else ""))
    run(initdb, "-D", str(data), "-U", "postgres", "--auth=trust", "-E", "UTF8", "--no-sync")
    run(pg_ctl, "-D", str(data), "-l", str(log), "-w", "-o",
        f"-k {root} -p {port} -c listen_addresses='' -c max_connections=200 -c fsync=off", "start")
    try:
        yield f"postgresql://postgres@/postgres?host={root}&port={port}"
    finally:
        run(pg_ctl, "-D", str(data), "-m", "immediate", "-w", "stop")
        shutil.rmtree(root, ignore_errors=True)
