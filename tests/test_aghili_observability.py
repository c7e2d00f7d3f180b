"""Observability (Aghili section 3): eq. (22) rank with 3 non-collinear, collinear and 1 anchor."""

from __future__ import annotations

import numpy as np

from datasets.rotations import so3_exp
from filters.aghili.observability import observability_matrix, rank_report, segment_matrices, total_observability_matrix

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
        segment_matrices(so3_exp(np.array([0.0, 0.0, yaw])), POSITION + yaw, OMEGA * (1 + yaw), A_BAR + [yaw, 0, 0], anchors, LANDMARKS)
        for yaw in (0.0, 0.8, 1.6)
    ]
    stripped = total_observability_matrix(segments, [1.0, 1.0], stripped=True)
    result = rank_report(stripped, 21)
    assert result.rank >= report(anchors).rank  # more segments never lose rank
