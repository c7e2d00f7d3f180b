"""The shared Kalman core (``filters.kalman``) against the textbook dense forms."""

from __future__ import annotations

import numpy as np
import pytest

from filters import kalman


def _random_problem(seed: int, n: int = 30, columns: int = 12, rows: int = 6):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    P = a @ a.T / n + np.eye(n)
    chosen = np.sort(rng.choice(n, size=columns, replace=False))
    values = rng.normal(size=(rows, columns))
    b = rng.normal(size=(rows, rows))
    R = b @ b.T + np.eye(rows)
    residual = rng.normal(size=rows)
    return P, kalman.SparseJacobian(chosen, values), R, residual


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_update_equals_the_joseph_product_form_with_the_optimal_gain(seed: int) -> None:
    P, jacobian, R, residual = _random_problem(seed)
    n = P.shape[0]
    H = jacobian.dense(n)
    S = H @ P @ H.T + R
    gain = np.linalg.solve(S, H @ P).T
    product = (np.eye(n) - gain @ H) @ P @ (np.eye(n) - gain @ H).T + gain @ R @ gain.T
    posterior = P.copy()
    outcome = kalman.update(posterior, residual, jacobian, R, [np.arange(3), np.arange(3, 6)])
    np.testing.assert_allclose(posterior, product, atol=1e-9)
    np.testing.assert_allclose(outcome.correction, gain @ residual, atol=1e-12)
    assert np.abs(posterior - posterior.T).max() <= 1e-15 * np.abs(posterior).max()
    assert np.linalg.eigvalsh(posterior).min() > 0
    assert outcome.innovation.nis == pytest.approx(residual @ np.linalg.solve(S, residual))
    assert outcome.innovation.dof == 6
    first = residual[:3] @ np.linalg.solve(S[:3, :3], residual[:3])
    assert outcome.innovation.group_nis[0] == pytest.approx(first)
    assert list(outcome.innovation.group_dof) == [3, 3]


def test_update_refuses_a_non_positive_posterior_and_leaves_p_untouched() -> None:
    # a noise-free measurement of a state known exactly already: S is singular
    P = np.diag([1.0, 0.0, 2.0])
    prior = P.copy()
    outcome = kalman.update(
        P, np.array([0.1]), kalman.SparseJacobian.selection([1]), np.zeros((1, 1))
    )
    assert outcome.correction is None and "not positive definite" in outcome.refused
    assert np.array_equal(P, prior)


def test_block_noise_equals_the_stacked_matrix() -> None:
    P, jacobian, _, residual = _random_problem(3, rows=6)
    blocks = np.stack([np.diag([0.1, 0.2, 0.3]), np.diag([0.4, 0.5, 0.6])])
    first, second = P.copy(), P.copy()
    kalman.update(first, residual, jacobian, blocks)
    kalman.update(second, residual, jacobian, kalman.block_diagonal(blocks))
    assert np.array_equal(first, second)


def test_partitioned_propagation_equals_the_dense_product() -> None:
    rng = np.random.default_rng(4)
    n, v = 20, 5
    a = rng.normal(size=(n, n))
    P = a @ a.T + np.eye(n)
    F = np.eye(v) + 0.1 * rng.normal(size=(v, v))
    Q = np.diag(rng.uniform(0.1, 1.0, size=v))
    full_F = np.eye(n)
    full_F[:v, :v] = F
    full_Q = np.zeros((n, n))
    full_Q[:v, :v] = Q
    expected = full_F @ P @ full_F.T + full_Q
    kalman.propagate_vehicle(P, v, F, Q)
    np.testing.assert_allclose(P, expected, atol=1e-12)
    assert np.array_equal(P, P.T)


def test_augment_equals_the_dense_jacobian_form() -> None:
    rng = np.random.default_rng(5)
    n = 8
    a = rng.normal(size=(n, n))
    P = a @ a.T + np.eye(n)
    jacobian = kalman.SparseJacobian(np.array([0, 1, 2]), rng.normal(size=(2, 3)))
    added = np.diag([0.3, 0.4])
    grown = kalman.augment(P, jacobian, added)
    G = np.vstack([np.eye(n), jacobian.dense(n)])
    expected = G @ P @ G.T
    expected[n:, n:] += added
    np.testing.assert_allclose(grown, expected, atol=1e-12)
    uncorrelated = kalman.augment(
        P, kalman.SparseJacobian(np.zeros(0, int), np.zeros((2, 0))), added
    )
    assert np.array_equal(uncorrelated[n:, :n], np.zeros((2, n)))
    assert np.array_equal(uncorrelated[n:, n:], added)


def test_stacked_row_blocks_share_their_columns() -> None:
    first = (np.array([0, 1, 5]), np.arange(6.0).reshape(2, 3))
    second = (np.array([0, 1, 7]), np.arange(6.0, 12.0).reshape(2, 3))
    stacked = kalman.SparseJacobian.stacked([first, second])
    assert list(stacked.columns) == [0, 1, 5, 7]
    dense = stacked.dense(9)
    np.testing.assert_array_equal(dense[:2, [0, 1, 5]], first[1])
    np.testing.assert_array_equal(dense[2:, [0, 1, 7]], second[1])
    assert dense[:2, 7].tolist() == [0.0, 0.0] and dense[2:, 5].tolist() == [0.0, 0.0]
