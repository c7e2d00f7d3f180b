"""Observation model and sensitivity matrix (Aghili eqs. (2), (7b), (10), (11)).

A landmark at world position ``rho`` is seen in the body frame as ``p = A^T (rho - r)``
(eq. (2)). The printed eq. (11) says ``p_hat = Abar (rho_hat - r_hat)``; eq. (2), (7b) and
the derivation of (10) all need ``Abar^T``, which is what we use (the sensitivity
``2 [p_hat x]`` of (10) is checked against finite differences of (7b) in
``tests/test_aghili_measurement.py``).

Error state layout: ``transition`` module (``[dq_v, dr, dr_dot, db_g, db_a, drho...]``);
where each estimated landmark sits is the filter's ``StateRegistry``'s to say. A landmark
the registry does not hold is an anchor (known, not estimated): no landmark column.
"""

from __future__ import annotations

import numpy as np

from filters.kalman import SparseJacobian
from filters.landmark_predictor import LandmarkMeasurement, LandmarkPredictor, stacked_jacobian
from filters.state_registry import StateRegistry

SEEN_VEHICLE_BLOCKS = ("attitude", "position")
"""The vehicle blocks a landmark observation depends on (eq. (10))."""


def predict(attitude: np.ndarray, position: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    """Aghili eqs. (7b), (11) (with ``A^T``): body-frame landmark positions (k, 3) [m].

    Args:
        attitude: ``Abar`` body-to-world (3, 3).
        position: ``r_hat`` world [m] (3,).
        landmarks: world positions ``rho`` (k, 3) [m].
    """
    return (np.asarray(landmarks, dtype=float) - position) @ attitude


def linearised(attitude: np.ndarray, predicted: np.ndarray, ids: np.ndarray) -> LandmarkMeasurement:
    """Aghili eq. (10) per landmark: row block i is ``[2 [p_i x], -Abar^T]`` on the attitude
    and position errors and ``Abar^T`` on landmark i's position (none for an anchor: a
    landmark the registry does not hold).

    Args:
        attitude: ``Abar`` (3, 3).
        predicted: ``p_hat`` (k, 3) from ``predict``.
        ids: (k,) map id of each landmark.
    """
    predicted = np.asarray(predicted, dtype=float)
    count = len(predicted)
    attitude_t = attitude.T
    x, y, z = predicted[:, 0], predicted[:, 1], predicted[:, 2]
    zero = np.zeros(count)
    skews = np.stack(
        [np.stack([zero, -z, y], 1), np.stack([z, zero, -x], 1), np.stack([-y, x, zero], 1)], 1
    )
    vehicle = np.zeros((count, 3, 6))
    vehicle[:, :, 0:3] = 2.0 * skews  # [p_i x]
    vehicle[:, :, 3:6] = -attitude_t
    return LandmarkMeasurement(
        predicted,
        np.asarray(ids, dtype=int),
        vehicle=SEEN_VEHICLE_BLOCKS,
        vehicle_jacobian=vehicle,
        landmark_jacobian=np.broadcast_to(attitude_t, (count, 3, 3)),
    )


def sparse_sensitivity(
    attitude: np.ndarray, predicted: np.ndarray, registry: StateRegistry, ids: np.ndarray
) -> SparseJacobian:
    """Aghili eq. (10): stacked ``H`` (3k rows) by its non-zero columns (``linearised``):
    the attitude and position errors and the observed estimated landmarks.

    Args:
        attitude: ``Abar`` (3, 3).
        predicted: ``p_hat`` (k, 3) from ``predict``.
        registry: where the state's blocks sit (``transition.state_registry``).
        ids: (k,) map id of each landmark.
    """
    return stacked_jacobian(registry, linearised(attitude, predicted, ids))


def sensitivity(
    attitude: np.ndarray, predicted: np.ndarray, registry: StateRegistry, ids: np.ndarray
) -> np.ndarray:
    """Aghili eq. (10) as the dense (3k, N) matrix (``sparse_sensitivity``)."""
    return sparse_sensitivity(attitude, predicted, registry, ids).dense(registry.size)


def map_predictor(
    attitude: np.ndarray,
    position: np.ndarray,
    covariance: np.ndarray,
    positions: np.ndarray,
    ids: np.ndarray,
    registry: StateRegistry,
) -> LandmarkPredictor:
    """The association ``Predictor`` (``filters.association``) of the Aghili map (the shared
    ``filters.landmark_predictor``): anchors and estimated landmarks seen from the nominal
    pose (eqs. (7b), (10)), with ``H P H^T`` from the error covariance; each candidate's
    block is read off the joint, as this filter's gates always were (``blocks_from_joint``:
    bit-identical estimates).

    Args:
        attitude: ``Abar`` (3, 3). position: ``r_hat`` (3,). covariance: P (15 + 3n, 15 + 3n).
        positions: world positions of the candidates (m, 3). ids: their map ids (m,).
        registry: where the state's blocks sit (anchors are not in it).
    """
    ids = np.asarray(ids, dtype=int)

    def measure(indices: np.ndarray) -> LandmarkMeasurement:
        predicted = predict(attitude, position, positions[indices])
        return linearised(attitude, predicted, ids[indices])

    return LandmarkPredictor(registry, covariance, measure, blocks_from_joint=True)
