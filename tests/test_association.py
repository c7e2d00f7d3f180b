"""Tests of ``filters.association``: gating, JCBB, the node cap, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from datasets.errors import InputError
from filters.association import (
    associate_jcbb,
    associate_nearest_neighbour,
    chi2_gate,
    individual_compatibility,
)


def _common_shift_map(
    landmark_count: int, common_sigma: float, own_sigma: float
) -> tuple[np.ndarray, np.ndarray]:
    """Landmarks on a line, predictions sharing one uncertain offset (a vehicle position error)."""
    predicted = np.stack([np.arange(landmark_count, dtype=float), np.zeros(landmark_count)], axis=1)
    joint = np.kron(np.full((landmark_count, landmark_count), common_sigma**2), np.eye(2))
    joint += own_sigma**2 * np.eye(2 * landmark_count)
    return predicted, joint


def _scan_cov(count: int, sigma: float) -> np.ndarray:
    return np.repeat((sigma**2 * np.eye(2))[None], count, axis=0)


def test_individual_distance_matches_direct_formula() -> None:
    rng = np.random.default_rng(0)
    predicted = rng.normal(size=(3, 2))
    a = rng.normal(size=(6, 6))
    joint = a @ a.T + np.eye(6)
    measured = rng.normal(size=(2, 2))
    r = _scan_cov(2, 0.3)
    cross = 0.1 * rng.normal(size=(4, 6))
    distances = individual_compatibility(measured, r, predicted, joint, cross)
    for j in range(2):
        for i in range(3):
            s = (
                r[j]
                + joint[2 * i : 2 * i + 2, 2 * i : 2 * i + 2]
                - cross[2 * j : 2 * j + 2, 2 * i : 2 * i + 2]
            )
            s = s - cross[2 * j : 2 * j + 2, 2 * i : 2 * i + 2].T
            nu = measured[j] - predicted[i]
            assert distances[j, i] == pytest.approx(nu @ np.linalg.solve(s, nu))


def test_joint_nis_matches_direct_stacked_computation() -> None:
    predicted, joint = _common_shift_map(5, 0.5, 0.05)
    measured = predicted[[0, 2, 4]] + np.array([0.3, -0.2])
    r = _scan_cov(3, 0.05)
    result = associate_jcbb(measured, r, predicted, joint)
    assert list(result.assignments) == [0, 2, 4]
    rows = np.concatenate([[2 * i, 2 * i + 1] for i in result.assignments])
    s = joint[np.ix_(rows, rows)] + np.kron(np.eye(3), 0.05**2 * np.eye(2))
    nu = (measured - predicted[result.assignments]).ravel()
    assert result.joint_nis == pytest.approx(nu @ np.linalg.solve(s, nu), rel=1e-9)
    assert result.dof == 6


def test_jcbb_finds_shifted_correspondence_that_nearest_neighbour_misses() -> None:
    # Every prediction is off by one landmark spacing (a common vehicle error): nearest
    # neighbour pairs each measurement with the wrong neighbour, JCBB finds the shift.
    predicted, joint = _common_shift_map(4, 1.0, 0.05)
    measured = predicted + np.array([1.0, 0.0])
    r = _scan_cov(4, 0.05)
    jcbb = associate_jcbb(measured, r, predicted, joint)
    nn = associate_nearest_neighbour(measured, r, predicted, joint)
    assert list(jcbb.assignments) == [0, 1, 2, 3]
    assert list(nn.assignments) != [0, 1, 2, 3]


def test_jcbb_rejects_spurious_pairing_that_breaks_joint_compatibility() -> None:
    predicted, joint = _common_shift_map(4, 1.0, 0.05)
    shift = np.array([0.5, 0.0])
    measured = np.vstack([predicted[:3] + shift, predicted[3] - shift])  # last one: clutter near L3
    r = _scan_cov(4, 0.05)
    distances = individual_compatibility(measured, r, predicted, joint)
    assert distances[3, 3] < chi2_gate(2, 0.99), (
        "the clutter must be individually compatible for this test"
    )
    jcbb = associate_jcbb(measured, r, predicted, joint)
    assert list(jcbb.assignments) == [0, 1, 2, -1]
    assert jcbb.ambiguous[3]
    nn = associate_nearest_neighbour(measured, r, predicted, joint)
    assert nn.assignments[3] == 3


def _clutter_trial(
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A 2-D map seen from an uncertain pose, with clutter: returns (z, R, h, HPH^T, truth)."""
    landmarks = rng.uniform(-15.0, 15.0, size=(30, 2))
    pose_cov = np.diag([0.3**2, 0.3**2, np.deg2rad(3.0) ** 2])
    landmark_sigma = 0.1
    true_pose = np.zeros(3)
    estimated_pose = rng.multivariate_normal(true_pose, pose_cov)
    landmark_estimates = landmarks + landmark_sigma * rng.normal(size=landmarks.shape)

    def to_body(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
        c, s = np.cos(pose[2]), np.sin(pose[2])
        rotation = np.array([[c, -s], [s, c]])
        return (points - pose[:2]) @ rotation

    predicted = to_body(estimated_pose, landmark_estimates)
    c, s = np.cos(estimated_pose[2]), np.sin(estimated_pose[2])
    rt = np.array([[c, s], [-s, c]])
    m = len(landmarks)
    jac = np.zeros((2 * m, 3 + 2 * m))
    for i, point in enumerate(predicted):
        jac[2 * i : 2 * i + 2, :2] = -rt
        jac[2 * i : 2 * i + 2, 2] = [point[1], -point[0]]  # d(R^T (l - r))/d theta = -S R^T(l - r)
        jac[2 * i : 2 * i + 2, 3 + 2 * i : 5 + 2 * i] = rt
    state_cov = np.zeros((3 + 2 * m, 3 + 2 * m))
    state_cov[:3, :3] = pose_cov
    state_cov[3:, 3:] = landmark_sigma**2 * np.eye(2 * m)
    joint = jac @ state_cov @ jac.T
    visible = np.flatnonzero(np.linalg.norm(landmarks, axis=1) < 10.0)
    measurement_sigma = 0.05
    z_true = to_body(true_pose, landmarks[visible])
    z = z_true + measurement_sigma * rng.normal(size=z_true.shape)
    clutter = rng.uniform(-10.0, 10.0, size=(3, 2))
    measured = np.vstack([z, clutter])
    truth = np.concatenate([visible, np.full(3, -1)])
    order = rng.permutation(len(measured))
    return (
        measured[order],
        _scan_cov(len(measured), measurement_sigma),
        predicted,
        joint,
        truth[order],
    )


def test_jcbb_precision_and_recall_on_simulated_clutter() -> None:
    rng = np.random.default_rng(7)
    correct = made = landmark_measurements = 0
    for _ in range(40):
        measured, r, predicted, joint, truth = _clutter_trial(rng)
        result = associate_jcbb(measured, r, predicted, joint)
        assigned = result.assignments >= 0
        made += int(assigned.sum())
        correct += int((result.assignments[assigned] == truth[assigned]).sum())
        landmark_measurements += int((truth >= 0).sum())
        assert not result.truncated
    precision = correct / made
    recall = correct / landmark_measurements
    assert precision >= 0.99
    assert recall >= 0.97


def test_node_cap_is_respected_and_result_stays_jointly_compatible() -> None:
    # Dense, highly correlated, ambiguous map: the full tree is huge.
    predicted, joint = _common_shift_map(25, 3.0, 0.05)
    rng = np.random.default_rng(3)
    measured = (
        predicted[rng.permutation(25)[:15]]
        + 0.02 * rng.normal(size=(15, 2))
        + np.array([0.37, 0.0])
    )
    r = _scan_cov(15, 0.05)
    result = associate_jcbb(measured, r, predicted, joint, max_nodes=40)
    assert result.nodes <= 40
    assert result.truncated
    assert result.pairs > 0
    assert result.joint_nis < chi2_gate(result.dof, 0.99)
    generous = associate_jcbb(measured, r, predicted, joint, max_nodes=200_000)
    assert generous.pairs >= result.pairs


def test_candidate_mask_excludes_pairs() -> None:
    predicted, joint = _common_shift_map(3, 0.2, 0.05)
    measured = predicted.copy()
    r = _scan_cov(3, 0.05)
    mask = np.ones((3, 3), dtype=bool)
    mask[1, 1] = False
    result = associate_jcbb(measured, r, predicted, joint, candidate_mask=mask)
    assert result.assignments[1] != 1


def test_empty_inputs_and_bad_input() -> None:
    result = associate_jcbb(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros((3, 2)), np.eye(6))
    assert result.assignments.shape == (0,)
    result = associate_jcbb(np.zeros((2, 2)), _scan_cov(2, 0.1), np.zeros((0, 2)), np.zeros((0, 0)))
    assert list(result.assignments) == [-1, -1]
    with pytest.raises(InputError, match="NaN"):
        associate_jcbb(np.array([[np.nan, 0.0]]), _scan_cov(1, 0.1), np.zeros((1, 2)), np.eye(2))
    with pytest.raises(InputError, match="shape"):
        associate_jcbb(np.zeros((1, 2)), np.eye(3)[None], np.zeros((1, 2)), np.eye(2))


def test_three_dimensional_measurements() -> None:
    rng = np.random.default_rng(11)
    predicted = rng.uniform(-5, 5, size=(6, 3))
    joint = np.kron(np.full((6, 6), 0.3**2), np.eye(3)) + 0.05**2 * np.eye(18)
    measured = predicted[[4, 1, 0]] + np.array([0.2, -0.1, 0.3])
    result = associate_jcbb(
        measured, np.repeat(0.05**2 * np.eye(3)[None], 3, axis=0), predicted, joint
    )
    assert list(result.assignments) == [4, 1, 0]
    assert result.dof == 9


class _FixedPredictor:
    """Independent landmarks at ``predicted`` (m, 2), each with covariance ``sigma^2 I``."""

    def __init__(self, predicted: np.ndarray, sigma: float) -> None:
        self.predicted = np.asarray(predicted, dtype=float)
        self.sigma = sigma

    def individual(self, indices):
        indices = np.asarray(indices, dtype=int)
        return self.predicted[indices], np.repeat(
            (self.sigma**2 * np.eye(2))[None], len(indices), axis=0
        )

    def joint(self, indices):
        indices = np.asarray(indices, dtype=int)
        return self.predicted[indices], self.sigma**2 * np.eye(2 * len(indices))


def test_a_sighting_between_the_gates_pairs_only_by_mutual_exclusion() -> None:
    """Outside every association gate (0.99) but inside exactly one landmark's new-landmark
    gate (0.9999), with no rival sighting and the landmark not yet matched: matched, with
    its noise inflated so that its NIS equals the association gate. Two landmarks in
    reach, a rival sighting, or a landmark already matched: ambiguous."""
    from datasets.estimate import AssociationDecision as Decision
    from datasets.estimator_options import AssociationOptions
    from filters.association import AssociationPolicy

    policy = AssociationPolicy(AssociationOptions(association="jcbb"), 2)
    # D^2 = 12 from its landmark: between chi2_2(0.99) = 9.2 and chi2_2(0.9999) = 18.4
    assert chi2_gate(2, 0.99) < 12.0 < chi2_gate(2, 0.9999)
    sigma, offset = 0.1, 0.1 * np.sqrt(12.0 / 2.0)  # noise 0.1 / sqrt(2) each, sum sigma^2
    noise = _scan_cov(1, sigma / np.sqrt(2.0))[0]
    predictor_sigma = sigma / np.sqrt(2.0)

    def decide(landmarks, sightings):
        sightings = np.asarray(sightings, dtype=float)
        covs = np.repeat(noise[None], len(sightings), axis=0)
        result = policy.by_geometry(
            sightings, covs, len(landmarks), _FixedPredictor(landmarks, predictor_sigma)
        )
        return list(result.decisions), list(result.candidates)

    lone = decide([[0.0, 0.0], [5.0, 0.0]], [[offset, offset]])
    assert lone == ([Decision.MATCHED], [0])
    # used as a sighting at the association gate: R' = R + (c - 1) S, c = D^2 / gate
    paired = policy.by_geometry(
        np.array([[offset, offset]]),
        noise[None],
        2,
        _FixedPredictor([[0.0, 0.0], [5.0, 0.0]], predictor_sigma),
    )
    factor = 12.0 / chi2_gate(2, 0.99)
    assert paired.inflation[0] == pytest.approx(factor)
    innovation = noise + predictor_sigma**2 * np.eye(2)
    assert np.allclose(paired.noise[0], noise + (factor - 1.0) * innovation)
    # its NIS with the inflated noise is the gate's
    inflated_nis = 2 * offset**2 / (paired.noise[0][0, 0] + predictor_sigma**2)
    assert inflated_nis == pytest.approx(chi2_gate(2, 0.99))
    two_in_reach = decide([[0.0, 0.0], [2 * offset, 2 * offset]], [[offset, offset]])
    assert two_in_reach[0] == [Decision.AMBIGUOUS]
    rivals = decide([[0.0, 0.0], [5.0, 0.0]], [[offset, offset], [-offset, -offset]])
    assert rivals[0] == [Decision.AMBIGUOUS, Decision.AMBIGUOUS]
    already = decide([[0.0, 0.0], [5.0, 0.0]], [[0.0, 0.01], [offset, offset]])
    assert already == ([Decision.MATCHED, Decision.AMBIGUOUS], [0, -1])
