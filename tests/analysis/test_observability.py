"""Observability indices against hand computations; entropy weights and the comprehensive index."""
import numpy as np
import pytest

from kincal.analysis.observability import (column_scale, comprehensive_index, entropy_weights, observability,
                                           indices_from_singular_values)


def test_indices_by_hand():
    # J with orthogonal columns of norms 3, 2, 1 (singular values 3, 2, 1), m = 2 poses (6 rows)
    J = np.zeros((6, 3))
    J[0, 0], J[1, 1], J[2, 2] = 3.0, 2.0, 1.0
    o = observability(J)
    assert o["O1"] == pytest.approx(6 ** (1 / 3) / np.sqrt(2))
    assert o["O2"] == pytest.approx(1 / 3)
    assert o["O3"] == pytest.approx(1.0)
    assert o["O4"] == pytest.approx(1 / 3)
    assert o["O5"] == pytest.approx(1 / (1 / 3 + 1 / 2 + 1))
    assert o["O6"] == pytest.approx(((1 / 9 + 1 / 4 + 1) / 3) ** -0.5)
    assert o["D"] == pytest.approx(np.log(36.0))
    assert o["A"] == pytest.approx(-(1 / 9 + 1 / 4 + 1))
    assert o["E"] == pytest.approx(1.0)


def test_indices_of_a_rotated_matrix_are_unchanged():
    rng = np.random.default_rng(0)
    J = rng.normal(size=(30, 5))
    Q = np.linalg.qr(rng.normal(size=(30, 30)))[0]
    a, b = observability(J), observability(Q @ J)
    for key in a:
        assert a[key] == pytest.approx(b[key])


def test_singular_design_scores_worst():
    J = np.zeros((6, 3))
    J[0, 0], J[1, 1] = 1.0, 1.0
    o = observability(J)
    assert o["O3"] == 0.0 and o["D"] == -np.inf and comprehensive_index(np.array([1.0, 1.0, 0.0]), 2) == 0.0


def test_entropy_weights_by_the_formula_and_scale_free():
    s = np.array([5.0, 2.0, 1.0, 0.3, 0.05])
    X = np.column_stack([s, 1 / s, 1 / s**2])
    P = X / X.sum(axis=0)
    d = 1 + (P * np.log(P)).sum(axis=0) / np.log(len(s))  # 1 − entropy per group (eq. 12–13)
    w = entropy_weights(s)
    np.testing.assert_allclose(w, d / d.sum(), rtol=1e-12)
    np.testing.assert_allclose(entropy_weights(7.3 * s), w, rtol=1e-12)


def test_entropy_weights_by_hand():
    s = np.array([1.0, 2.0])
    X = np.array([[1.0, 1.0, 1.0], [2.0, 0.5, 0.25]])
    P = X / X.sum(axis=0)
    S = -(P * np.log(P)).sum(axis=0) / np.log(2)
    np.testing.assert_allclose(entropy_weights(s), (1 - S) / (1 - S).sum())
    # the spread-out group (1/σ², proportions 0.8/0.2) carries the most weight
    assert np.argmax(entropy_weights(s)) == 2


def test_equal_singular_values_give_equal_weights():
    np.testing.assert_allclose(entropy_weights(np.ones(6)), np.full(3, 1 / 3))


def test_comprehensive_index_is_bounded_and_monotone():
    s = np.array([3.0, 1.0, 0.2, 0.05])
    values = [comprehensive_index(c * s, 10) for c in (0.1, 1.0, 10.0, 1e6)]
    assert all(0 <= v < 3 for v in values) and values == sorted(values)
    w = entropy_weights(s)
    ind = indices_from_singular_values(s, 10)
    expected = 2 / np.pi * (np.arctan(w[0] * ind["O1"]) + np.arctan(w[1] * ind["O5"]) + np.arctan(w[2] * ind["O6"]))
    assert comprehensive_index(s, 10) == pytest.approx(expected)


def test_column_scale_gives_unit_rms_columns():
    rng = np.random.default_rng(1)
    J = rng.normal(size=(60, 4)) * np.array([1e-3, 1.0, 50.0, 0.2])
    Js = J * column_scale(J)
    np.testing.assert_allclose(np.sqrt((Js**2).sum(axis=0) / 20), 1.0)


def test_batched_indices_match_single():
    rng = np.random.default_rng(3)
    S = np.abs(rng.normal(size=(5, 6))) + 0.01
    S[2, -1] = 0.0
    batch = indices_from_singular_values(S, 7)
    comp = comprehensive_index(S, 7)
    for i in range(5):
        one = indices_from_singular_values(S[i], 7)
        for key in one:
            assert batch[key][i] == pytest.approx(one[key])
        assert comp[i] == pytest.approx(comprehensive_index(S[i], 7))
    assert comp[2] == 0.0
