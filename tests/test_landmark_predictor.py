"""The shared landmark predictor (``filters.landmark_predictor``) against dense ``H P H^T``:
a world-frame map, a map with anchors (known landmarks, no state columns) and a selection
(a robocentric ``y_i = x_i``)."""

from __future__ import annotations

import numpy as np
import pytest

from filters.kalman import diagonal_blocks
from filters.landmark_predictor import LandmarkMeasurement, LandmarkPredictor, stacked_jacobian
from filters.state_registry import StateRegistry

SIZE = 13


def _state(rng: np.random.Generator) -> tuple[StateRegistry, np.ndarray]:
    """Vehicle [position 2 | heading 1 | velocity 2], landmarks 5, 6, 7 (a position each,
    landmark 6 also a direction): 5 + 2 + 4 + 2 = 13 entries, and a random P."""
    registry = StateRegistry([("position", 2), ("heading", 1), ("velocity", 2)])
    registry.augment(5, [("position", 2)])
    registry.augment(6, [("position", 2), ("direction", 2)])
    registry.augment(7, [("position", 2)])
    root = rng.normal(size=(SIZE, SIZE))
    return registry, root @ root.T


def _world_measurement(
    rng: np.random.Generator, registry: StateRegistry, ids: np.ndarray, vehicle: tuple[str, ...]
) -> tuple[LandmarkMeasurement, np.ndarray]:
    """A random linearised measurement (d = 2) of the landmarks ``ids`` through the named
    vehicle blocks and each landmark's position, and its dense H (2n, 13)."""
    n = len(ids)
    columns = registry.vehicle_indices(vehicle)
    vehicle_jac = rng.normal(size=(n, 2, columns.size))
    landmark_jac = rng.normal(size=(n, 2, 2))
    found = LandmarkMeasurement(
        rng.normal(size=(n, 2)), ids, vehicle, vehicle_jac, landmark_jac, block="position"
    )
    dense = np.zeros((2 * n, SIZE))
    for i, landmark_id in enumerate(ids):
        dense[2 * i : 2 * i + 2, columns] = vehicle_jac[i]
        if landmark_id in registry:
            own = registry.slice_of(int(landmark_id), "position")
            dense[2 * i : 2 * i + 2, own] = landmark_jac[i]
    return found, dense


def _selection(
    rng: np.random.Generator, registry: StateRegistry, ids: np.ndarray
) -> tuple[LandmarkMeasurement, np.ndarray]:
    """Each landmark's position itself, and the dense H (2n, 13) that selects it."""
    dense = np.zeros((2 * len(ids), SIZE))
    for i, landmark_id in enumerate(ids):
        own = registry.slice_of(int(landmark_id), "position")
        dense[2 * i : 2 * i + 2, own] = np.eye(2)
    found = LandmarkMeasurement(rng.normal(size=(len(ids), 2)), ids, block="position")
    return found, dense


CASES = {
    "world-frame map": lambda rng, registry: _world_measurement(
        rng, registry, np.array([7, 5, 6]), ("position", "heading")
    ),
    # 99: a known landmark (an anchor), not in the state; the vehicle blocks not contiguous
    "anchors": lambda rng, registry: _world_measurement(
        rng, registry, np.array([7, 99, 5]), ("position", "velocity")
    ),
    "selection": lambda rng, registry: _selection(rng, registry, np.array([6, 5])),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_individual_joint_and_jacobian_agree_with_the_dense_product(case: str) -> None:
    rng = np.random.default_rng(0)
    registry, P = _state(rng)
    found, dense = CASES[case](rng, registry)
    n = len(found.landmarks)
    np.testing.assert_array_equal(stacked_jacobian(registry, found).dense(SIZE), dense)
    predictor = LandmarkPredictor(registry, P, lambda indices: found)
    predicted, jacobian = predictor.jacobian(np.arange(n))
    np.testing.assert_array_equal(predicted, found.predicted)
    np.testing.assert_array_equal(jacobian.dense(SIZE), dense)
    expected = dense @ P @ dense.T
    _, joint = predictor.joint(np.arange(n))
    np.testing.assert_allclose(joint, expected, rtol=1e-12, atol=1e-12)
    _, blocks = predictor.individual(np.arange(n))
    np.testing.assert_allclose(blocks, diagonal_blocks(joint, 2), rtol=1e-12, atol=1e-12)
    # read off the joint: its diagonal blocks exactly
    from_joint = LandmarkPredictor(registry, P, lambda indices: found, blocks_from_joint=True)
    np.testing.assert_array_equal(from_joint.individual(np.arange(n))[1], diagonal_blocks(joint, 2))


def test_a_selection_gathers_the_blocks_of_p() -> None:
    """No products: the principal blocks of P as they are (even when P is not exactly
    symmetric)."""
    rng = np.random.default_rng(1)
    registry, P = _state(rng)
    P[5, 6] += 1e-15  # a P symmetric to round-off only
    found, _ = _selection(rng, registry, np.array([6, 5]))
    predictor = LandmarkPredictor(registry, P, lambda indices: found)
    rows = np.array([7, 8, 5, 6])
    np.testing.assert_array_equal(predictor.joint(np.arange(2))[1], P[np.ix_(rows, rows)])
    blocks = predictor.individual(np.arange(2))[1]
    np.testing.assert_array_equal(blocks[0], P[7:9, 7:9])
    np.testing.assert_array_equal(blocks[1], P[5:7, 5:7])
    np.testing.assert_array_equal(predictor.jacobian(np.arange(2))[1].columns, rows)
