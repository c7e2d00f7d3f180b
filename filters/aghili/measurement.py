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


def sparse_sensitivity(
    attitude: np.ndarray, predicted: np.ndarray, registry: StateRegistry, ids: np.ndarray
) -> SparseJacobian:
    """Aghili eq. (10): stacked ``H`` (3k rows) by its non-zero columns.

    Row block i: ``[2 [p_i x], -Abar^T, 0, 0, 0, ..., Abar^T (at landmark i's entries), ...]``;
    anchors (known landmarks, not in ``registry``) have no landmark column. The non-zero
    columns are the attitude and position errors and the observed landmarks.

    Args:
        attitude: ``Abar`` (3, 3).
        predicted: ``p_hat`` (k, 3) from ``predict``.
        registry: where the state's blocks sit (``transition.state_registry``).
        ids: (k,) map id of each landmark.
    """
    predicted = np.asarray(predicted, dtype=float)
    ids = np.asarray(ids, dtype=int)
    count = len(predicted)
    estimated = np.flatnonzero([int(landmark_id) in registry for landmark_id in ids])
    columns = registry.columns(SEEN_VEHICLE_BLOCKS, ids[estimated])
    values = np.zeros((count, 3, columns.size))
    attitude_t = attitude.T
    x, y, z = predicted[:, 0], predicted[:, 1], predicted[:, 2]
    zero = np.zeros(count)
    skews = np.stack(
        [np.stack([zero, -z, y], 1), np.stack([z, zero, -x], 1), np.stack([-y, x, zero], 1)], 1
    )
    values[:, :, 0:3] = 2.0 * skews  # [p_i x]
    values[:, :, 3:6] = -attitude_t
    own = 6 + 3 * np.arange(estimated.size)[:, None] + np.arange(3)  # each landmark's columns
    values[estimated[:, None, None], np.arange(3)[None, :, None], own[:, None, :]] = attitude_t
    return SparseJacobian(columns, values.reshape(3 * count, columns.size))


def sensitivity(
    attitude: np.ndarray, predicted: np.ndarray, registry: StateRegistry, ids: np.ndarray
) -> np.ndarray:
    """Aghili eq. (10) as the dense (3k, N) matrix (``sparse_sensitivity``)."""
    return sparse_sensitivity(attitude, predicted, registry, ids).dense(registry.size)


def projected_blocks(jacobian: SparseJacobian, covariance: np.ndarray) -> np.ndarray:
    """Diagonal 3 x 3 blocks of ``H P H^T`` (m, 3, 3) (the eq. (42) window's ``H P H^T``
    per landmark), from the non-zero columns of H only."""
    columns, values = jacobian.columns, jacobian.values
    full = values @ covariance[np.ix_(columns, columns)] @ values.T
    count = full.shape[0] // 3
    return full.reshape(count, 3, count, 3)[np.arange(count), :, np.arange(count), :]


class MapPredictor:
    """The association ``Predictor`` (``filters.association``) of the Aghili map: anchors and
    estimated landmarks seen from the nominal pose (eqs. (7b), (10)), with ``H P H^T`` from
    the error covariance.

    Args:
        attitude: ``Abar`` (3, 3). position: ``r_hat`` (3,). covariance: P (15 + 3n, 15 + 3n).
        positions: world positions of the candidates (m, 3). ids: their map ids (m,).
        registry: where the state's blocks sit (anchors are not in it).
    """

    def __init__(
        self,
        attitude: np.ndarray,
        position: np.ndarray,
        covariance: np.ndarray,
        positions: np.ndarray,
        ids: np.ndarray,
        registry: StateRegistry,
    ) -> None:
        self.attitude = attitude
        self.position = position
        self.covariance = covariance
        self.positions = positions
        self.ids = np.asarray(ids, dtype=int)
        self.registry = registry

    def joint(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        predicted = predict(self.attitude, self.position, self.positions[indices])
        jacobian = sparse_sensitivity(self.attitude, predicted, self.registry, self.ids[indices])
        columns, values = jacobian.columns, jacobian.values
        joint = values @ self.covariance[np.ix_(columns, columns)] @ values.T
        return predicted, 0.5 * (joint + joint.T)

    def individual(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        predicted, joint = self.joint(indices)
        count = len(predicted)
        blocks = joint.reshape(count, 3, count, 3)[np.arange(count), :, np.arange(count), :]
        return predicted, blocks
