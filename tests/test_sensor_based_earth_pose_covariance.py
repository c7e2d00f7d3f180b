"""The sensor-based filter's Earth-pose covariance (``earth_pose_covariance``) against Monte
Carlo runs of the operations it linearises: entering landmarks into the Earth map, composing
increments, the rigid alignment that anchors the pose (2-D and 3-D), the dead-reckoned and
the odometry-driven motion."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from datasets.rotations import rot2, so3_exp, so3_log
from filters.sensor_based.earth_frame import weighted_rigid_alignment
from filters.sensor_based.earth_pose_covariance import (
    EarthErrorCovariance,
    accumulate_odometry_covariance,
    alignment_gains,
    motion_covariance,
    rotation_lever,
)

SAMPLES = 4000
OWN_SIGMA = 0.02  # each Earth entry's own error [m]


@dataclass(frozen=True)
class Scene:
    """A true anchored pose, its landmarks, and the error sizes of the experiment."""

    rotation: np.ndarray  # (d, d) true body-to-Earth rotation
    position: np.ndarray  # (d,)
    earth: np.ndarray  # (n, d) true Earth positions
    weights: np.ndarray  # (n,)
    entry_pose_covariance: np.ndarray  # (k, k) of the pose when the map entered
    increment: np.ndarray  # (d,) the motion before the second half of the map entered
    increment_covariance: np.ndarray  # (k, k)
    body_shared_covariance: np.ndarray  # (k, k) a rigid error shared by the body map

    @property
    def dimension(self) -> int:
        return len(self.position)

    @property
    def body(self) -> np.ndarray:
        return (self.earth - self.position) @ self.rotation  # s = R^T (y - p)


PLANAR = Scene(
    rotation=rot2(0.4),
    position=np.array([1.0, -2.0]),
    earth=np.array([[3.0, 1.0], [5.0, -1.5], [2.0, -4.0], [6.0, 2.5], [-1.0, 0.5], [4.0, -3.0]]),
    weights=np.array([1.0, 2.0, 0.5, 1.0, 3.0, 1.5]),
    entry_pose_covariance=np.diag([0.04**2, 0.04**2, 0.02**2]),
    increment=np.array([1.5, 0.5]),
    increment_covariance=np.diag([0.03**2, 0.02**2, 0.015**2]),
    body_shared_covariance=np.diag([0.05**2, 0.05**2, 0.01**2]),
)
SPATIAL = Scene(
    rotation=so3_exp(np.array([0.1, -0.2, 0.4])),
    position=np.array([1.0, -2.0, 0.5]),
    earth=np.array(
        [
            [3.0, 1.0, 0.0],
            [5.0, -1.5, 1.5],
            [2.0, -4.0, -1.0],
            [6.0, 2.5, 2.0],
            [-1.0, 0.5, 0.5],
            [4.0, -3.0, 3.0],
        ]
    ),
    weights=np.array([1.0, 2.0, 0.5, 1.0, 3.0, 1.5]),
    entry_pose_covariance=np.diag([0.04**2] * 3 + [0.015**2] * 3),
    increment=np.array([1.5, 0.5, 0.2]),
    increment_covariance=np.diag([0.03**2, 0.02**2, 0.02**2] + [0.01**2] * 3),
    body_shared_covariance=np.diag([0.05**2] * 3 + [0.008**2] * 3),
)


def _lever(points: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """(n, d, k): ``[I, J (point - centre)]``."""
    count, dimension = points.shape
    identity = np.broadcast_to(np.eye(dimension), (count, dimension, dimension))
    return np.concatenate([identity, rotation_lever(points - centres)], axis=2)


def _body_joint_covariance(scene: Scene) -> np.ndarray:
    """The robocentric map's errors: a shared rigid motion of the whole body map plus each
    landmark's own."""
    shared = _lever(scene.body, np.zeros(scene.dimension)).reshape(
        -1, len(scene.increment_covariance)
    )
    return shared @ scene.body_shared_covariance @ shared.T + 0.03**2 * np.eye(shared.shape[0])


SHARED_OWN_SIGMA = 0.1
"""A common offset of every entry's own error [m] (entries made together from one body map)."""


def _own_joint(count: int, dimension: int, shared: bool) -> np.ndarray:
    """(n d, n d) joint own error of ``count`` entries: each its own ``OWN_SIGMA``, and with
    ``shared`` a common offset of ``SHARED_OWN_SIGMA``."""
    joint = OWN_SIGMA**2 * np.eye(count * dimension)
    if shared:
        joint += SHARED_OWN_SIGMA**2 * np.kron(np.ones((count, count)), np.eye(dimension))
    return joint


def _predicted(
    scene: Scene, two_entry_poses: bool, shared_own: bool = False, joint_own: bool = True
) -> np.ndarray:
    """The anchored pose's covariance: the map entered at the identity pose, or its second
    half after ``scene.increment`` (entries of one pose entered together, their own errors
    joint unless ``joint_own`` is False)."""
    errors = EarthErrorCovariance(scene.dimension, scene.entry_pose_covariance)
    dimension, count = scene.dimension, len(scene.earth)
    batches = (
        [range(count)] if not two_entry_poses else [range(count // 2), range(count // 2, count)]
    )
    for number, batch in enumerate(batches):
        if number == 1:
            errors.compose(np.eye(dimension), scene.increment, scene.increment_covariance)
        own = _own_joint(len(batch), dimension, shared_own)
        if not joint_own:
            own = own * np.kron(np.eye(len(batch)), np.ones((dimension, dimension)))
        errors.enter(
            list(batch),
            scene.earth[list(batch)],
            scene.increment if number == 1 else np.zeros(dimension),
            own,
        )
    errors.anchor(
        list(range(count)),
        alignment_gains(scene.rotation, scene.body, scene.weights),
        scene.rotation,
        _body_joint_covariance(scene),
    )
    return errors.pose


def _rotation_error(estimated: np.ndarray, true: np.ndarray) -> np.ndarray:
    """World-frame rotation error ``dphi`` with ``R_true = Exp(dphi) R_est`` (2-D: angle)."""
    if len(true) == 2:
        return np.array(
            [np.arctan2(true[1, 0], true[0, 0]) - np.arctan2(estimated[1, 0], estimated[0, 0])]
        )
    return so3_log(true @ estimated.T)


def _sampled(
    scene: Scene, rng: np.random.Generator, two_entry_poses: bool, shared_own: bool = False
) -> np.ndarray:
    """(SAMPLES, k) errors ``[dp, dphi]`` (true minus estimated) of the alignment on maps
    perturbed as ``_predicted`` describes."""
    dimension, size = scene.dimension, len(scene.entry_pose_covariance)
    body_noise = rng.multivariate_normal(
        np.zeros(scene.body.size), _body_joint_covariance(scene), SAMPLES
    )
    first = rng.multivariate_normal(np.zeros(size), scene.entry_pose_covariance, SAMPLES)
    increment = rng.multivariate_normal(np.zeros(size), scene.increment_covariance, SAMPLES)
    half = len(scene.earth) // 2
    centres = np.zeros_like(scene.earth)
    if two_entry_poses:
        centres[half:] = scene.increment
    errors = np.zeros((SAMPLES, size))
    for sample in range(SAMPLES):
        pose_errors = np.repeat(first[sample][None], len(scene.earth), axis=0)
        if two_entry_poses:
            # the increment composed from a pose off by (dp, dphi), identity rotation
            second = first[sample].copy()
            second[:dimension] += (
                rotation_lever(scene.increment[None])[0] @ first[sample][dimension:]
                + increment[sample][:dimension]
            )
            second[dimension:] += increment[sample][dimension:]
            pose_errors[half:] = second
        # an Earth position off by the (small) pose error of its entry, and its own error
        earth = (
            scene.earth
            + np.einsum("nij,nj->ni", _lever(scene.earth, centres), pose_errors)
            + rng.normal(scale=OWN_SIGMA, size=scene.earth.shape)
            + (rng.normal(scale=SHARED_OWN_SIGMA, size=dimension) if shared_own else 0.0)
        )
        rotation, position = weighted_rigid_alignment(
            scene.body + body_noise[sample].reshape(-1, dimension), earth, scene.weights
        )
        errors[sample] = [
            *(scene.position - position),
            *_rotation_error(rotation, scene.rotation),
        ]
    return errors


def _assert_matches(errors: np.ndarray, predicted: np.ndarray) -> None:
    sampled = np.cov(errors.T)
    # standard deviations within 5 % (4000 samples: about 1.1 % sampling error each)
    assert np.allclose(np.sqrt(np.diag(sampled)), np.sqrt(np.diag(predicted)), rtol=0.05)
    nees = np.einsum("ni,ij,nj->n", errors, np.linalg.inv(predicted), errors)
    assert abs(nees.mean() / len(predicted) - 1.0) < 0.05


@pytest.mark.parametrize("scene", [PLANAR, SPATIAL], ids=["2-D", "3-D"])
def test_anchor_matches_monte_carlo_when_the_map_entered_at_one_pose(scene: Scene) -> None:
    _assert_matches(_sampled(scene, np.random.default_rng(0), False), _predicted(scene, False))


@pytest.mark.parametrize("scene", [PLANAR, SPATIAL], ids=["2-D", "3-D"])
def test_anchor_matches_monte_carlo_when_the_map_entered_at_two_poses(scene: Scene) -> None:
    _assert_matches(_sampled(scene, np.random.default_rng(1), True), _predicted(scene, True))


@pytest.mark.parametrize("scene", [PLANAR, SPATIAL], ids=["2-D", "3-D"])
def test_entries_made_together_keep_their_shared_error(scene: Scene) -> None:
    predicted = _predicted(scene, False, shared_own=True)
    _assert_matches(_sampled(scene, np.random.default_rng(5), False, shared_own=True), predicted)
    one_by_one = _predicted(scene, False, shared_own=True, joint_own=False)
    assert np.trace(predicted[: scene.dimension, : scene.dimension]) > 1.5 * np.trace(
        one_by_one[: scene.dimension, : scene.dimension]
    )


def test_entries_taken_as_independent_would_understate_the_anchored_heading() -> None:
    scene = PLANAR
    gains = alignment_gains(scene.rotation, scene.body, scene.weights)
    independent = np.zeros((3, 3))
    for gain, lever in zip(gains, _lever(scene.earth, np.zeros(2))):
        own = lever @ scene.entry_pose_covariance @ lever.T + OWN_SIGMA**2 * np.eye(2)
        independent += gain @ own @ gain.T
    body_gain = (gains @ scene.rotation).transpose(1, 0, 2).reshape(3, -1)
    independent += body_gain @ _body_joint_covariance(scene) @ body_gain.T
    assert _predicted(scene, True)[2, 2] > 2.0 * independent[2, 2]


def test_compose_matches_monte_carlo() -> None:
    rng = np.random.default_rng(2)
    covariance = np.array([[4e-4, 1e-4, 2e-5], [1e-4, 9e-4, -3e-5], [2e-5, -3e-5, 1e-4]])
    heading, translation = 0.7, np.array([1.5, 0.4])
    increment_covariance = PLANAR.increment_covariance
    pose_errors = rng.multivariate_normal(np.zeros(3), covariance, SAMPLES)
    increment_errors = rng.multivariate_normal(np.zeros(3), increment_covariance, SAMPLES)
    start = np.array([2.0, 1.0])
    end = start + rot2(heading) @ translation
    errors = np.empty((SAMPLES, 3))
    for sample, (pose_error, increment_error) in enumerate(zip(pose_errors, increment_errors)):
        rotation = rot2(heading + pose_error[2])
        position = start + pose_error[:2] + rotation @ (translation + increment_error[:2])
        errors[sample] = [*(position - end), pose_error[2] + increment_error[2]]
    tracked = EarthErrorCovariance(2, covariance)
    tracked.compose(rot2(heading), translation, increment_covariance)
    _assert_matches(errors, tracked.pose)


def test_forget_drops_only_that_entry() -> None:
    covariance = PLANAR.entry_pose_covariance
    both, only_second = EarthErrorCovariance(2, covariance), EarthErrorCovariance(2, covariance)
    both.enter([7], PLANAR.earth[:1], np.zeros(2), 1e-4 * np.eye(2))
    for tracked in (both, only_second):
        tracked.enter([9], PLANAR.earth[1:2], np.zeros(2), 4e-4 * np.eye(2))
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
