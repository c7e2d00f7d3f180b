"""The sensor-based filter's Earth-pose covariance (``earth_pose_covariance``) against Monte
Carlo runs of the operations it linearises: entering landmarks into the Earth map, composing
increments, the rigid alignment that anchors the pose, the dead-reckoned motion."""

from __future__ import annotations

import numpy as np

from datasets.rotations import rot2
from filters.sensor_based.earth_frame import weighted_rigid_alignment
from filters.sensor_based.earth_pose_covariance import (
    SKEW,
    EarthErrorCovariance,
    accumulate_odometry_covariance,
    alignment_gains,
    motion_covariance,
)

SAMPLES = 4000
TRUE_ROTATION = rot2(0.4)
TRUE_POSITION = np.array([1.0, -2.0])
EARTH = np.array([[3.0, 1.0], [5.0, -1.5], [2.0, -4.0], [6.0, 2.5], [-1.0, 0.5], [4.0, -3.0]])
BODY = (EARTH - TRUE_POSITION) @ TRUE_ROTATION  # s = R^T (y - p)
WEIGHTS = np.array([1.0, 2.0, 0.5, 1.0, 3.0, 1.5])
ENTRY_POSE_COVARIANCE = np.diag([0.04**2, 0.04**2, 0.02**2])
OWN_SIGMA = 0.02  # each entry's own error [m]
# the second half of the map enters after an increment of this translation (first pose frame)
INCREMENT = np.array([1.5, 0.5])
INCREMENT_COVARIANCE = np.diag([0.03**2, 0.02**2, 0.015**2])


def _lever(points: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(n, 2, 3): ``[I, J (point - centre)]``; ``centre`` (2,) or one per point (n, 2)."""
    lever = np.zeros((len(points), 2, 3))
    lever[:, :, :2] = np.eye(2)
    lever[:, :, 2] = (points - centre) @ SKEW.T
    return lever


def _body_joint_covariance() -> np.ndarray:
    """The robocentric map's errors: a shared rigid motion of the whole body map plus each
    landmark's own."""
    shared = _lever(BODY, np.zeros(2)).reshape(-1, 3)
    return shared @ np.diag([0.05**2, 0.05**2, 0.01**2]) @ shared.T + 0.03**2 * np.eye(
        2 * len(BODY)
    )


def _predicted(two_entry_poses: bool) -> np.ndarray:
    """The anchored pose's covariance: the map entered from the origin (identity pose), or
    its second half after ``INCREMENT``."""
    errors = EarthErrorCovariance(ENTRY_POSE_COVARIANCE)
    half = len(EARTH) // 2
    for key, position in enumerate(EARTH):
        pose_position = np.zeros(2)
        if two_entry_poses and key == half:
            errors.compose(np.eye(2), INCREMENT, INCREMENT_COVARIANCE)
        if two_entry_poses and key >= half:
            pose_position = INCREMENT
        errors.enter(key, position, pose_position, OWN_SIGMA**2 * np.eye(2))
    errors.anchor(
        list(range(len(EARTH))),
        alignment_gains(TRUE_ROTATION, BODY, WEIGHTS),
        TRUE_ROTATION,
        _body_joint_covariance(),
    )
    return errors.pose


def _sampled(rng: np.random.Generator, two_entry_poses: bool) -> np.ndarray:
    """(SAMPLES, 3) errors ``[dp, dtheta]`` of the alignment on perturbed maps, built as
    ``_predicted`` describes."""
    body_noise = rng.multivariate_normal(np.zeros(2 * len(BODY)), _body_joint_covariance(), SAMPLES)
    first = rng.multivariate_normal(np.zeros(3), ENTRY_POSE_COVARIANCE, SAMPLES)
    increment = rng.multivariate_normal(np.zeros(3), INCREMENT_COVARIANCE, SAMPLES)
    half = len(EARTH) // 2
    errors = np.zeros((SAMPLES, 3))
    for sample in range(SAMPLES):
        pose_errors = np.repeat(first[sample][None], len(EARTH), axis=0)
        centres = np.zeros((len(EARTH), 2))
        if two_entry_poses:
            # composing an increment from a pose off by (dp, dtheta) (identity rotation)
            second = first[sample].copy()
            second[:2] += first[sample][2] * SKEW @ INCREMENT + increment[sample][:2]
            second[2] += increment[sample][2]
            pose_errors[half:] = second
            centres[half:] = INCREMENT
        earth = (
            EARTH
            + np.einsum("nij,nj->ni", _lever(EARTH, centres), pose_errors)
            + rng.normal(scale=OWN_SIGMA, size=EARTH.shape)
        )
        rotation, position = weighted_rigid_alignment(
            BODY + body_noise[sample].reshape(-1, 2), earth, WEIGHTS
        )
        errors[sample] = [
            *(position - TRUE_POSITION),
            np.arctan2(rotation[1, 0], rotation[0, 0]) - 0.4,
        ]
    return errors


def _assert_matches(errors: np.ndarray, predicted: np.ndarray) -> None:
    sampled = np.cov(errors.T)
    # standard deviations within 5 % (4000 samples: about 1.1 % sampling error each)
    assert np.allclose(np.sqrt(np.diag(sampled)), np.sqrt(np.diag(predicted)), rtol=0.05)
    nees = np.einsum("ni,ij,nj->n", errors, np.linalg.inv(predicted), errors)
    assert abs(nees.mean() / 3.0 - 1.0) < 0.05


def test_anchor_matches_monte_carlo_when_the_map_entered_at_one_pose() -> None:
    _assert_matches(_sampled(np.random.default_rng(0), False), _predicted(False))


def test_anchor_matches_monte_carlo_when_the_map_entered_at_two_poses() -> None:
    predicted = _predicted(True)
    _assert_matches(_sampled(np.random.default_rng(1), True), predicted)
    # the entries' shared pose error dominates: taken as independent it would be too small
    assert predicted[2, 2] > 2.0 * _predicted_independent()[2, 2]


def _predicted_independent() -> np.ndarray:
    """The same anchoring with each entry's pose error taken as its own."""
    gains = alignment_gains(TRUE_ROTATION, BODY, WEIGHTS)
    result = np.zeros((3, 3))
    for gain, lever in zip(gains, _lever(EARTH, np.zeros(2))):
        own = lever @ ENTRY_POSE_COVARIANCE @ lever.T + OWN_SIGMA**2 * np.eye(2)
        result += gain @ own @ gain.T
    body_gain = (gains @ TRUE_ROTATION).transpose(1, 0, 2).reshape(3, -1)
    return result + body_gain @ _body_joint_covariance() @ body_gain.T


def test_compose_matches_monte_carlo() -> None:
    rng = np.random.default_rng(2)
    covariance = np.array([[4e-4, 1e-4, 2e-5], [1e-4, 9e-4, -3e-5], [2e-5, -3e-5, 1e-4]])
    heading, translation = 0.7, np.array([1.5, 0.4])
    pose_errors = rng.multivariate_normal(np.zeros(3), covariance, SAMPLES)
    increment_errors = rng.multivariate_normal(np.zeros(3), INCREMENT_COVARIANCE, SAMPLES)
    start = np.array([2.0, 1.0])
    end = start + rot2(heading) @ translation
    errors = np.empty((SAMPLES, 3))
    for sample, (pose_error, increment_error) in enumerate(zip(pose_errors, increment_errors)):
        rotation = rot2(heading + pose_error[2])
        position = start + pose_error[:2] + rotation @ (translation + increment_error[:2])
        errors[sample] = [*(position - end), pose_error[2] + increment_error[2]]
    tracked = EarthErrorCovariance(covariance)
    tracked.compose(rot2(heading), translation, INCREMENT_COVARIANCE)
    _assert_matches(errors, tracked.pose)


def test_forget_drops_only_that_entry() -> None:
    both, only_second = (
        EarthErrorCovariance(ENTRY_POSE_COVARIANCE),
        EarthErrorCovariance(ENTRY_POSE_COVARIANCE),
    )
    both.enter(7, EARTH[0], np.zeros(2), 1e-4 * np.eye(2))
    for tracked in (both, only_second):
        tracked.enter(9, EARTH[1], np.zeros(2), 4e-4 * np.eye(2))
    both.forget(7)
    assert both.slots == {9: 0} and np.allclose(both.matrix, only_second.matrix)


def test_motion_covariance_matches_monte_carlo() -> None:
    rng = np.random.default_rng(3)
    vehicle = np.array([[4e-4, 5e-5, 1e-6], [5e-5, 1e-4, -2e-6], [1e-6, -2e-6, 1e-6]])
    velocity, rate, step, steps = np.array([0.5, 0.0]), 0.3, 0.02, 25
    rotations = [rot2(rate * step * j) for j in range(steps)]
    gain = sum(rotation * step for rotation in rotations)
    predicted = motion_covariance(gain, step * steps, vehicle, 0.0, 0.0, 0.0)
    nominal = sum(rotation @ velocity * step for rotation in rotations)
    errors = np.empty((SAMPLES, 3))
    for sample, error in enumerate(rng.multivariate_normal(np.zeros(3), vehicle, SAMPLES)):
        translation = sum(
            rot2((rate - error[2]) * step * j) @ (velocity + error[:2]) * step for j in range(steps)
        )
        errors[sample] = [*(translation - nominal), -error[2] * step * steps]
    _assert_matches(errors, predicted)
    # the random walks over T add sigma^2 T^3 / 3 and the white gyro noise sigma_g^2 T
    walks = motion_covariance(gain, 0.5, np.zeros((3, 3)), 0.1, 1e-3, 0.01)
    assert np.allclose(np.diag(walks), [0.01 * 0.125 / 3] * 2 + [1e-6 * 0.125 / 3 + 1e-4 * 0.5])


def test_accumulated_odometry_covariance_matches_monte_carlo() -> None:
    rng = np.random.default_rng(4)
    speed, rate, dt, steps = 0.4, 0.5, 0.02, 50
    sample_covariance = np.diag([0.05**2, 0.1**2])  # [v, omega] per sample
    predicted = np.zeros((3, 3))
    for j in range(steps):
        predicted = accumulate_odometry_covariance(
            predicted,
            rot2(rate * dt * j),
            np.array([speed * dt, 0.0]),
            dt,
            sample_covariance,
            False,
        )
    noise = rng.multivariate_normal(np.zeros(2), sample_covariance, (SAMPLES, steps))
    errors = np.empty((SAMPLES, 3))
    true_end = sum(rot2(rate * dt * j) @ [speed * dt, 0.0] for j in range(steps))
    for sample in range(SAMPLES):
        heading, position = 0.0, np.zeros(2)
        for j in range(steps):
            position = position + rot2(heading) @ [(speed + noise[sample, j, 0]) * dt, 0.0]
            heading += (rate + noise[sample, j, 1]) * dt
        errors[sample] = [*(position - true_end), heading - rate * dt * steps]
    _assert_matches(errors, predicted)
