"""Loop closing (section IV-C) and the Earth-frame trajectory of the sensor-based filter."""

from __future__ import annotations

import numpy as np

from datasets.rotations import rot2
from filters.sensor_based.config import SensorBasedConfig
from filters.sensor_based.earth_frame import weighted_rigid_alignment
from filters.sensor_based.filter import SensorBasedSlam
from filters.sensor_based.loop_closing import (
    LoopClosurePolicy,
    constraint_update,
    find_loop_closure,
)
from tests.sensor_based_support import planar_sequence, run

LANDMARKS = np.array([[3.0, 1.0], [2.0, -2.0], [5.0, 0.5], [4.0, 3.0], [7.0, -1.0]])


def test_constraint_update_makes_pairs_equal_and_fully_correlated() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(size=(6, 6))
    cov = a @ a.T + np.eye(6)
    x = rng.normal(size=6)
    x_post, cov_post = constraint_update(x, cov, np.array([0, 1]), np.array([2, 3]))
    assert np.allclose(x_post[:2], x_post[2:4], atol=1e-8)
    difference = cov_post[:2, :2] - cov_post[:2, 2:4] - cov_post[2:4, :2] + cov_post[2:4, 2:4]
    assert np.allclose(difference, 0.0, atol=1e-8)
    assert np.all(np.linalg.eigvalsh(cov_post) > -1e-9)


def test_find_loop_closure_uses_the_cross_covariance() -> None:
    # Old copies share a large common offset uncertainty with the current ones (drift):
    # individually far apart, jointly one rigid shift.
    old = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 3.0], [4.0, 4.0]])
    current = old + np.array([1.2, -0.8])
    positions = np.vstack([current, old])
    n = len(positions)
    joint = 0.01**2 * np.eye(2 * n)
    joint[8:, 8:] += np.kron(np.ones((4, 4)), np.eye(2))  # old set: common 1 m uncertainty
    pairs = find_loop_closure(
        positions, joint, np.arange(4), np.arange(4, 8), LoopClosurePolicy(min_pairs=3)
    )
    assert sorted(pairs) == [(0, 4), (1, 5), (2, 6), (3, 7)]
    assert (
        find_loop_closure(
            positions, joint, np.arange(2), np.arange(4, 8), LoopClosurePolicy(min_pairs=3)
        )
        == []
    )


def test_filter_closes_the_loop_after_losing_sight_of_its_landmarks() -> None:
    # Landmarks seen for 10 s, lost for 40 s (the map drifts), seen again: the filter starts
    # duplicates (the old ones are outside its association window) and loop closing fuses
    # each duplicate with its original.
    sequence = planar_sequence(
        60.0, (0.2, 0.0), 0.02, LANDMARKS + [8.0, 0.0], seed=1, blank=(10.0, 50.0)
    )
    # 40 s blind at sigma_v = 0.1 leaves the old landmarks metres uncertain: lift the
    # candidate limit, and check below that with the default limit the loop is not closed.
    config = SensorBasedConfig(
        association="jcbb",
        association_window_s=3.0,
        loop_old_after_s=20.0,
        loop_min_pairs=3,
        max_missed_in_view=10_000,
        loop_max_old_sigma_m=50.0,
    )
    estimator, estimate = run(SensorBasedSlam, config, sequence)
    closures = [event for event in estimate.diagnostics.events if event.kind == "loop_closure"]
    assert closures, "expected a loop closure on the revisit"
    fused = [pair for event in closures for pair in event.details["pairs"]]
    assert len(fused) >= 3
    # Original landmarks got ids 0..4 in measurement order; their duplicates >= 5 and were
    # created from the same measurement index, so a correct pair is (k, 5 + k).
    assert all(kept < 5 and removed - 5 == kept for kept, removed in fused)
    assert len(estimator.state.landmark_ids()) <= len(LANDMARKS) + 1
    strict = config.model_copy(update={"loop_max_old_sigma_m": 1.5})
    _, estimate = run(SensorBasedSlam, strict, sequence)
    assert not [event for event in estimate.diagnostics.events if event.kind == "loop_closure"]
    # With ids the association closes the loop: every sighting pairs with its id's landmark
    # wherever it is, and the geometric search (which ignores ids) does not run
    by_ids = config.model_copy(update={"association": "ids"})
    estimator, estimate = run(SensorBasedSlam, by_ids, sequence)
    assert not [event for event in estimate.diagnostics.events if event.kind == "loop_closure"]
    assert len(estimator.state.landmark_ids()) == len(LANDMARKS)


def test_weighted_rigid_alignment_recovers_a_known_motion() -> None:
    rng = np.random.default_rng(2)
    source = rng.normal(size=(6, 3))
    angle = np.array([0.2, -0.1, 0.4])
    from datasets.rotations import so3_exp

    rotation = so3_exp(angle)
    target = source @ rotation.T + np.array([1.0, 2.0, -0.5])
    estimated_rotation, translation = weighted_rigid_alignment(
        source, target, rng.uniform(0.5, 2.0, 6)
    )
    assert np.allclose(estimated_rotation, rotation) and np.allclose(translation, [1.0, 2.0, -0.5])
    planar = rng.normal(size=(4, 2))
    rotated = planar @ rot2(0.7).T + [0.3, -0.2]
    estimated_rotation, translation = weighted_rigid_alignment(planar, rotated)
    assert np.allclose(estimated_rotation, rot2(0.7)) and np.allclose(translation, [0.3, -0.2])


def test_earth_frame_trajectory_follows_the_true_circle() -> None:
    speed, yaw_rate = 0.5, 0.1
    sequence = planar_sequence(30.0, (speed, 0.0), yaw_rate, LANDMARKS * 2.0, seed=3)
    _, estimate = run(SensorBasedSlam, SensorBasedConfig(association="jcbb"), sequence)
    pose = estimate.causal.pose
    assert pose is not None and pose.covariances is not None
    assert np.all(np.linalg.eigvalsh(pose.covariances[1:]) > 0.0)  # first-order, derived
    t = pose.t
    a = yaw_rate * t
    truth = np.column_stack([np.sin(a), 1.0 - np.cos(a)]) * speed / yaw_rate
    error = np.linalg.norm(pose.positions - truth, axis=1)
    assert error[-1] < 0.3  # 15 m driven
    heading_error = np.angle(np.exp(1j * (pose.rotations - a)))
    assert np.max(np.abs(heading_error)) < 0.05


def test_ambiguous_constellation_is_not_closed() -> None:
    # A regular row of old landmarks with a 3 m common uncertainty: the current copies match
    # it at the true shift and, just as well, one spacing off. Such a loop is rejected.
    old = np.array([[float(k), 0.0] for k in range(8)])
    current = old[2:6] + np.array([0.05, 0.0])
    positions = np.vstack([current, old])
    joint = 0.01**2 * np.eye(2 * len(positions))
    joint[8:, 8:] += 9.0 * np.kron(np.ones((8, 8)), np.eye(2))
    policy = LoopClosurePolicy(min_pairs=3)
    assert find_loop_closure(positions, joint, np.arange(4), np.arange(4, 12), policy) == []
    permissive = LoopClosurePolicy(min_pairs=3, unambiguous_only=False)
    assert len(find_loop_closure(positions, joint, np.arange(4), np.arange(4, 12), permissive)) == 4
