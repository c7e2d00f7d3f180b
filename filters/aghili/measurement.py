"""Observation model and sensitivity matrix (Aghili eqs. (2), (7b), (10), (11)).

A landmark at world position ``rho`` is seen in the body frame as ``p = A^T (rho - r)``
(eq. (2)). The printed eq. (11) says ``p_hat = Abar (rho_hat - r_hat)``; eq. (2), (7b) and
the derivation of (10) all need ``Abar^T``, which is what we use (the sensitivity
``2 [p_hat x]`` of (10) is checked against finite differences of (7b) in
``tests/test_aghili_measurement.py``).

Error state layout: ``transition`` module (``[dq_v, dr, dr_dot, db_g, db_a, drho...]``).
"""

from __future__ import annotations

import numpy as np

from datasets.rotations import skew
from filters.aghili.transition import ATTITUDE, POSITION, VEHICLE_DIM


def predict(attitude: np.ndarray, position: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    """Aghili eqs. (7b), (11) (with ``A^T``): body-frame landmark positions (k, 3) [m].

    Args:
        attitude: ``Abar`` body-to-world (3, 3).
        position: ``r_hat`` world [m] (3,).
        landmarks: world positions ``rho`` (k, 3) [m].
    """
    return (np.asarray(landmarks, dtype=float) - position) @ attitude


def sensitivity(
    attitude: np.ndarray, predicted: np.ndarray, state_slots: np.ndarray, state_dim: int
) -> np.ndarray:
    """Aghili eq. (10): stacked ``H`` (3k, state_dim).

    Row block i: ``[2 [p_i x], -Abar^T, 0, 0, 0, ..., Abar^T (at landmark i's slot), ...]``;
    anchors (known landmarks, ``state_slots[i] < 0``) have no landmark column.

    Args:
        attitude: ``Abar`` (3, 3).
        predicted: ``p_hat`` (k, 3) from ``predict``.
        state_slots: (k,) index of each landmark among the estimated ones, -1 for anchors.
        state_dim: 15 + 3n.
    """
    count = len(predicted)
    H = np.zeros((3 * count, state_dim))
    attitude_t = attitude.T
    for i in range(count):
        rows = slice(3 * i, 3 * i + 3)
        H[rows, ATTITUDE] = 2.0 * skew(predicted[i])
        H[rows, POSITION] = -attitude_t
        slot = int(state_slots[i])
        if slot >= 0:
            start = VEHICLE_DIM + 3 * slot
            H[rows, start : start + 3] = attitude_t
    return H
