"""Observation model and sensitivity matrix (Aghili eqs. (7b), (10), (11) with A^T)."""

from __future__ import annotations

import numpy as np

from datasets.rotations import so3_exp
from filters.aghili import quaternion_jpl as quat
from filters.aghili.measurement import predict, sensitivity
from filters.aghili.transition import LANDMARK_BLOCKS, state_registry


def test_prediction_uses_the_transpose_as_eq_2_says() -> None:
    rng = np.random.default_rng(0)
    attitude = so3_exp(rng.normal(size=3))
    r = rng.normal(size=3)
    rho = rng.normal(size=(4, 3)) * 5
    np.testing.assert_allclose(predict(attitude, r, rho), (attitude.T @ (rho - r).T).T, atol=1e-12)
    assert not np.allclose(
        predict(attitude, r, rho), (attitude @ (rho - r).T).T
    )  # eq. (11) as printed


def test_sensitivity_matches_finite_differences() -> None:
    rng = np.random.default_rng(1)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    r = rng.normal(size=3)
    anchors = rng.normal(size=(2, 3)) * 4
    landmarks = rng.normal(size=(2, 3)) * 4
    world = np.vstack([anchors, landmarks])
    registry = state_registry()
    for landmark_id in (0, 1):
        registry.augment(landmark_id, LANDMARK_BLOCKS)
    ids = np.array([-1, -2, 0, 1])  # the anchors are not in the state
    state_dim = 15 + 3 * 2

    def h(dx: np.ndarray) -> np.ndarray:
        q_perturbed = quat.apply_error(dx[0:3], q)
        moved = world.copy()
        moved[2:] += dx[15:].reshape(-1, 3)
        return predict(quat.rotation_matrix(q_perturbed), r + dx[3:6], moved).ravel()

    H = sensitivity(
        quat.rotation_matrix(q), predict(quat.rotation_matrix(q), r, world), registry, ids
    )
    step = 1e-6
    numeric = np.column_stack(
        [(h(step * e) - h(-step * e)) / (2 * step) for e in np.eye(state_dim)]
    )
    np.testing.assert_allclose(H, numeric, atol=1e-7)
    np.testing.assert_allclose(H[:, 6:15], 0.0)  # velocity and biases are not seen directly
