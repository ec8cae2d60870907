"""Same input, same answer: no verdict may depend on hash order or floating-point round-off."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import kincal
import kincal.analysis.separation as separation
from kincal.design import candidate_pool
from kincal.models.serial import SerialRobot
from kincal.models.transmission import TransmissionRobot
from kincal.ties import first_best, improves, order_with_ties

HASH_SEEDS = ("0", "123")


def _without_timing(obj):
    """A JSON result without wall-clock fields (the only thing allowed to differ between runs)."""
    if isinstance(obj, dict):
        return {k: _without_timing(v) for k, v in obj.items() if k != "time_s"}
    if isinstance(obj, list):
        return [_without_timing(v) for v in obj]
    return obj


def _run(argv, hash_seed, tmp_path):
    env = {**os.environ, "PYTHONHASHSEED": hash_seed}
    proc = subprocess.run([sys.executable, "-m", "kincal.cli", *argv], capture_output=True, text=True, env=env,
                          cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


@pytest.mark.slow
@pytest.mark.parametrize("argv", [
    ["separate", "guo3t2r", "--json"],
    ["demo", "--json"],
    ["design", "guo3t2r", "-m", "20", "--pool", "400", "--method", "detmax-ide", "--criterion", "comprehensive",
     "--generations", "40", "-o", "poses.csv", "--json"],
    ["design", "ur5", "-m", "30", "--pool", "1500", "--criterion", "D", "--restarts", "1", "-o", "poses.csv", "--json"],
], ids=["separate-json", "demo-json", "design-detmax-ide", "design-fedorov"])
def test_byte_identical_under_different_hash_seeds(argv, tmp_path):
    outs = [_run(argv, s, tmp_path) for s in HASH_SEEDS]
    if "--json" in argv:
        outs = [json.dumps(_without_timing(json.loads(o)), sort_keys=True) for o in outs]
    assert outs[0] == outs[1]


def _jitter(monkeypatch, seed):
    """Perturb every parameter Jacobian and every GCN by a relative 1e-13 in random directions, as a
    different BLAS kernel or summation order would."""
    rng = np.random.default_rng(seed)
    for cls in (SerialRobot, TransmissionRobot):
        def wrapped(self, q, values, jacobian, method=cls._forward_and_jacobian):
            p, J = method(self, q, values, jacobian)
            return p, (None if J is None else J * (1.0 + 1e-13 * rng.standard_normal(J.shape)))
        monkeypatch.setattr(cls, "_forward_and_jacobian", wrapped)
    exact_gcn = separation.gcn
    monkeypatch.setattr(separation, "gcn", lambda J, m: exact_gcn(J, m) * (1.0 + 1e-13 * rng.standard_normal()))


def _verdicts():
    robot = kincal.load_robot("guo3t2r")
    q = candidate_pool(robot, 100, seed=0)
    sep = separation.separate_ill_conditioned(robot, q)
    ur5 = kincal.load_robot("ur5")
    ident = kincal.identifiability(ur5, ur5.sample_joints(60, seed=0), keep=ur5.base_params())
    pool = candidate_pool(robot, 300, seed=1)
    designs = {m: kincal.select_poses(robot, pool, m=15, method=m, criterion="comprehensive" if m != "fedorov" else "D",
                                      seed=0,
                                      certify=False, generations=30)
               for m in ("detmax", "fedorov", "detmax-ide")}
    return (sep.separated, sep.paper_choice, sep.candidates, [r for r, _ in sep.models], ident.dropped,
            ident.confounds.keys(), {m: d.q.round(12).tolist() for m, d in designs.items()})


@pytest.mark.slow
def test_verdicts_survive_round_off(monkeypatch):
    """Separation, QR identifiability and the designs (DETMAX, Fedorov, DETMAX-IDE) give the same
    verdicts when every tie-prone input moves by round-off."""
    exact = _verdicts()
    # of the exactly equivalent θ3 ≡ θ4, the canonical rule removes the later one
    assert "j4.theta" in exact[0] and "j3.theta" not in exact[0]
    for seed in (1, 2):
        with monkeypatch.context() as m:
            _jitter(m, seed)
            assert _verdicts() == exact


def test_tie_rules():
    assert first_best([1.0, 3.0, 3.0 * (1 + 1e-12), 2.0]) == 1  # a tie goes to the earliest
    assert first_best([1.0, 3.0, 3.0 * (1 + 1e-6)]) == 2  # a real difference wins
    assert first_best([5.0, 2.0, 2.0 - 1e-15], maximize=False) == 1
    assert first_best([np.nan, -np.inf, 0.5]) == 2 and first_best([-np.inf, -np.inf]) == 0
    assert not improves(1.0 + 1e-12, 1.0) and improves(1.0 + 1e-6, 1.0) and not improves(np.nan, 1.0)
    assert improves(0.5, 1.0, maximize=False) and improves(1.0, -np.inf)
    assert order_with_ties([1.0, 3.0, 2.0, 3.0 * (1 - 1e-13)]) == [1, 3, 2, 0]
    assert order_with_ties([np.nan, 1.0, np.nan]) == [1, 0, 2]  # NaN last, in canonical order (no endless loop)


def _ordered_by_definition(v, descending):
    """order_with_ties as its docstring defines it: repeatedly the first best of what is left, then
    every value tied with it, in canonical order."""
    rest, out = list(range(len(v))), []
    while rest:
        k = rest[first_best(v[rest], maximize=descending)]
        tied = [i for i in rest if i == k or v[i] == v[k] or abs(v[i] - v[k]) <= 1e-9 * abs(v[k])]
        out += tied
        rest = [i for i in rest if i not in tied]
    return out


def test_order_with_ties_equals_its_definition():
    """The sorted fast path (no ties) and the tie loop agree with the definition, ties and NaN included."""
    rng = np.random.default_rng(7)
    pool = [0.0, -0.0, 1.0, 1 + 1e-10, 1 - 2e-9, -1.0, 3.0, 3 + 3e-9, np.inf, -np.inf, np.nan, 1e-300]
    for k in range(3000):
        n = int(rng.integers(0, 9))
        v = rng.choice(pool, n) if k % 2 else rng.normal(size=n) * 10.0 ** rng.integers(-5, 5)
        for descending in (True, False):
            assert order_with_ties(v, descending) == _ordered_by_definition(v, descending), (v, descending)


def test_zero_column_is_not_scaled_up():
    """A parameter with no effect must look unidentifiable, never 'well conditioned'."""
    from kincal.analysis.observability import column_scale

    J = np.zeros((30, 3))
    J[:, 0] = np.linspace(1, 2, 30)
    J[:, 1] = 1e-17 * np.linspace(-1, 1, 30)  # rounding noise
    J[:, 2] = np.cos(np.arange(30))
    scale = column_scale(J)
    assert scale[1] == 1.0 and np.linalg.norm(J[:, 1] * scale[1]) < 1e-15
    np.testing.assert_allclose(np.sqrt(np.sum((J[:, [0, 2]] * scale[[0, 2]]) ** 2, axis=0) / 10), 1.0)
    # the separation sees such a parameter as ill-conditioned
    assert separation.gcn(J * scale, 10) > 1e8
