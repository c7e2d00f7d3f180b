"""Observability (Aghili section 3): eq. (22) rank with 3 non-collinear, collinear and 1 anchor."""

from __future__ import annotations

import numpy as np

from datasets.rotations import so3_exp
from filters.aghili.observability import (
    observability_matrix,
    rank_report,
    segment_matrices,
    total_observability_matrix,
)

ATTITUDE = so3_exp(np.array([0.05, -0.02, 0.7]))
POSITION = np.array([1.0, 2.0, 0.3])
OMEGA = np.array([0.01, -0.02, 0.1])
A_BAR = np.array([0.2, 0.1, 9.81])
LANDMARKS = np.array([[8.0, -3.0, 1.0], [2.0, 9.0, 2.5]])


def report(anchors: np.ndarray):
    F, H = segment_matrices(ATTITUDE, POSITION, OMEGA, A_BAR, anchors, LANDMARKS)
    body = (anchors - POSITION) @ ATTITUDE
    return rank_report(observability_matrix(F, H), F.shape[0], anchors_body=body)


def test_three_non_collinear_anchors_give_full_rank() -> None:
    result = report(np.array([[5.0, 0.0, 0.0], [0.0, 6.0, 1.0], [-4.0, -2.0, 2.0]]))
    assert result.rank == result.size == 21
    assert result.anchors_collinear is False and result.pi_smallest_singular_value > 0.1


def test_collinear_anchors_are_rank_deficient() -> None:
    result = report(np.array([[5.0, 0.0, 0.0], [7.0, 1.0, 0.5], [9.0, 2.0, 1.0]]))
    assert result.rank < result.size
    assert result.anchors_collinear is True and result.pi_smallest_singular_value < 1e-9


def test_single_anchor_is_rank_deficient_per_segment() -> None:
    result = report(np.array([[5.0, 0.0, 0.0]]))
    assert result.rank <= result.size - 3


def test_stripped_matrix_over_moving_segments_reported() -> None:
    anchors = np.array([[5.0, 0.0, 0.0]])
    segments = [
        segment_matrices(
            so3_exp(np.array([0.0, 0.0, yaw])),
            POSITION + yaw,
            OMEGA * (1 + yaw),
            A_BAR + [yaw, 0, 0],
            anchors,
            LANDMARKS,
        )
        for yaw in (0.0, 0.8, 1.6)
    ]
    stripped = total_observability_matrix(segments, [1.0, 1.0], stripped=True)
    result = rank_report(stripped, 21)
    assert result.rank >= report(anchors).rank  # more segments never lose rank


def test_gauge_rotation_is_in_the_null_space_of_a_single_anchor_and_not_of_three() -> None:
    """Rotating vehicle, velocity and map about gravity through the one anchor leaves every
    predicted measurement unchanged (H u = 0), checked against H of eq. (10); finite
    differences of the nonlinear model (7b) agree; three non-collinear anchors see it."""
    from datasets.rotations import so3_exp as exp
    from filters.aghili.observability import gauge_rotation_direction

    velocity = np.array([0.4, -0.2, 0.05])
    anchor = np.array([[5.0, 0.0, 0.0]])
    u = gauge_rotation_direction(ATTITUDE, POSITION, velocity, LANDMARKS, anchor[0])
    _, H = segment_matrices(ATTITUDE, POSITION, OMEGA, A_BAR, anchor, LANDMARKS)
    assert np.abs(H @ u).max() < 1e-12
    psi = 1e-6  # the nonlinear rotation by psi, measured in body frame, does not move anything
    turn = exp(np.array([0.0, 0.0, psi]))
    rotated_attitude = turn @ ATTITUDE
    rotated_position = anchor[0] + turn @ (POSITION - anchor[0])
    world = np.vstack([anchor, anchor[0] + (LANDMARKS - anchor[0]) @ turn.T])
    before = (np.vstack([anchor, LANDMARKS]) - POSITION) @ ATTITUDE
    after = (world - rotated_position) @ rotated_attitude
    np.testing.assert_allclose(after, before, atol=1e-9)
    anchors3 = np.array([[5.0, 0.0, 0.0], [0.0, 6.0, 1.0], [-4.0, -2.0, 2.0]])
    _, H3 = segment_matrices(ATTITUDE, POSITION, OMEGA, A_BAR, anchors3, LANDMARKS)
    assert (
        np.abs(
            H3 @ gauge_rotation_direction(ATTITUDE, POSITION, velocity, LANDMARKS, anchors3[0])
        ).max()
        > 1.0
    )


def test_variance_along_a_direction_matches_the_scalar_estimator_variance() -> None:
    """(u^T P^-1 u)^-1 is the variance of the best linear estimate of psi from x ~ N(u psi, P):
    checked by Monte Carlo of that estimator."""
    from filters.aghili.observability import variance_along

    rng = np.random.default_rng(0)
    L = rng.normal(size=(5, 5))
    P = L @ L.T + 0.1 * np.eye(5)
    u = rng.normal(size=5)
    samples = rng.multivariate_normal(np.zeros(5), P, size=40000)
    weights = np.linalg.solve(P, u) / (u @ np.linalg.solve(P, u))
    np.testing.assert_allclose(np.var(samples @ weights), variance_along(P, u), rtol=0.03)
