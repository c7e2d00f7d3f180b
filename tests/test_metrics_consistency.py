"""NEES/NIS statistics: chi-square bounds, Monte Carlo averaging, pose errors, block NEES."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from datasets.rotations import quat_wxyz_from_rotation, so3_exp
from datasets.state import BlockName, Frame, GroundTruth, LandmarkMap, StateBlock, StateHistory
from datasets.trajectory import Trajectory
from workbench.metrics.consistency import (
    averaged_nees,
    below_fraction,
    chi2_interval,
    inside_fraction,
    nees,
    pose_errors,
)
from workbench.metrics.state_errors import nees_series


def _random_covariances(rng: np.random.Generator, count: int, dof: int) -> np.ndarray:
    factors = rng.normal(size=(count, dof, dof)) * 0.3
    return factors @ np.transpose(factors, (0, 2, 1)) + 0.05 * np.eye(dof)


def _gaussian_errors(rng: np.random.Generator, covariances: np.ndarray) -> np.ndarray:
    factors = np.linalg.cholesky(covariances)
    return np.einsum("nij,nj->ni", factors, rng.normal(size=covariances.shape[:2]))


def test_chi2_interval_for_two_dof_is_the_exponential_quantile() -> None:
    # chi-square with 2 dof is exponential with mean 2: quantile p is -2 ln(1 - p).
    low, high = chi2_interval(2)
    assert low == pytest.approx(-2.0 * np.log(0.975), rel=1e-10)
    assert high == pytest.approx(-2.0 * np.log(0.025), rel=1e-10)
    low_m, high_m = chi2_interval(3, runs=50)
    assert low_m < 3.0 < high_m and high_m - low_m < 1.5


@pytest.mark.parametrize("dof", [3, 6])
def test_averaged_nees_is_consistent_for_the_true_covariance_and_detects_scaled_ones(
    dof: int,
) -> None:
    rng = np.random.default_rng(41)
    runs, steps = 30, 200
    covariances = _random_covariances(rng, steps, dof)
    nees_runs = np.stack(
        [nees(_gaussian_errors(rng, covariances), covariances) for _ in range(runs)]
    )
    consistent = averaged_nees(nees_runs, dof)
    assert consistent.inside_fraction >= 0.9
    assert consistent.mean.mean() == pytest.approx(dof, rel=0.05)
    errors = [_gaussian_errors(rng, covariances) for _ in range(runs)]
    pessimistic = averaged_nees(np.stack([nees(e, 4.0 * covariances) for e in errors]), dof)
    optimistic = averaged_nees(np.stack([nees(e, 0.25 * covariances) for e in errors]), dof)
    assert pessimistic.inside_fraction < 0.05
    assert optimistic.inside_fraction < 0.05
    assert pessimistic.mean.mean() < consistent.lower < consistent.upper < optimistic.mean.mean()


def test_single_run_fractions_match_their_confidence() -> None:
    rng = np.random.default_rng(42)
    dofs = rng.choice([2, 3], size=20000)
    values = np.where(dofs == 2, rng.chisquare(2, 20000), rng.chisquare(3, 20000))
    assert inside_fraction(values, dofs) == pytest.approx(0.95, abs=0.01)
    assert below_fraction(values, dofs) == pytest.approx(0.95, abs=0.01)
    assert below_fraction(4.0 * values, dofs) < 0.7
    assert inside_fraction(np.array([]), 3) is None


def test_nees_marks_singular_covariances_as_nan() -> None:
    covariances = np.stack([np.eye(2), np.zeros((2, 2))])
    result = nees(np.ones((2, 2)), covariances)
    assert result[0] == pytest.approx(2.0) and np.isnan(result[1])


def test_pose_errors_equal_gtsam_between_in_3d_and_2d() -> None:
    rng = np.random.default_rng(43)
    for _ in range(10):
        est = gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(size=3)), rng.normal(size=3))
        true = gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(size=3)), rng.normal(size=3))
        between = est.between(true)
        expected = np.concatenate([gtsam.Rot3.Logmap(between.rotation()), between.translation()])
        trajectory = lambda pose: Trajectory(  # noqa: E731
            np.zeros(1),
            pose.translation()[None],
            quat_wxyz_from_rotation(Rotation.from_matrix(pose.rotation().matrix()))[None],
        )
        np.testing.assert_allclose(
            pose_errors(trajectory(est), trajectory(true))[0], expected, atol=1e-9
        )

        est2 = gtsam.Pose2(*rng.normal(size=3))
        true2 = gtsam.Pose2(*rng.normal(size=3))
        between2 = est2.between(true2)
        planar = lambda pose: Trajectory(
            np.zeros(1), np.array([[pose.x(), pose.y()]]), np.array([pose.theta()])
        )  # noqa: E731
        np.testing.assert_allclose(
            pose_errors(planar(est2), planar(true2))[0],
            [between2.x(), between2.y(), between2.theta()],
            atol=1e-9,
        )


def _perturbed_poses(
    rng: np.random.Generator, estimate: Trajectory, covariances: np.ndarray
) -> Trajectory:
    """Truth = estimate retracted by xi ~ N(0, P): R_true = R_est Exp(w), p_true = p_est + R_est v."""
    xi = _gaussian_errors(rng, covariances)
    rotations = estimate.rotation_matrices()
    true_rotations = rotations @ so3_exp(xi[:, :3])
    positions = estimate.positions + np.einsum("nij,nj->ni", rotations, xi[:, 3:])
    return Trajectory(
        estimate.t, positions, quat_wxyz_from_rotation(Rotation.from_matrix(true_rotations))
    )


def test_pose_and_block_nees_series_of_a_consistent_estimate() -> None:
    rng = np.random.default_rng(44)
    steps = 3000
    t = np.arange(steps) * 0.05
    covariances = _random_covariances(rng, steps, 6) * 0.1
    estimate = Trajectory(
        t,
        rng.normal(size=(steps, 3)),
        quat_wxyz_from_rotation(Rotation.random(steps, random_state=rng)),
        covariances,
    )
    truth_pose = _perturbed_poses(rng, estimate.without_covariances(), covariances)
    bias_covariances = _random_covariances(rng, steps, 3) * 0.01
    true_bias = rng.normal(size=(steps, 3))
    est_bias = true_bias - _gaussian_errors(rng, bias_covariances)
    body_velocity = rng.normal(size=(steps, 3))
    truth = GroundTruth(
        history=StateHistory(
            pose=truth_pose, blocks={BlockName.GYRO_BIAS: StateBlock(t, true_bias)}
        ),
        body_velocity=StateBlock(t, body_velocity),
    )
    history = StateHistory(
        pose=estimate,
        blocks={
            BlockName.GYRO_BIAS: StateBlock(t, est_bias, bias_covariances),
            # Velocity 10 sigma off: must show up as large NEES.
            BlockName.VELOCITY: StateBlock(
                t, body_velocity + 1.0, np.tile(0.01 * np.eye(3), (steps, 1, 1)), Frame.BODY
            ),
        },
    )
    series = nees_series(history, truth)
    assert np.nanmean(series["pose"].nees) == pytest.approx(6.0, rel=0.05)
    assert inside_fraction(series["pose"].nees, 6) == pytest.approx(0.95, abs=0.02)
    assert np.nanmean(series["attitude"].nees) == pytest.approx(3.0, rel=0.06)
    assert np.nanmean(series["position"].nees) == pytest.approx(3.0, rel=0.06)
    assert np.nanmean(series["gyro_bias"].nees) == pytest.approx(3.0, rel=0.06)
    assert np.all(series["velocity"].nees == pytest.approx(300.0))
    assert series["pose"].dof[0] == 6 and len(series["pose"].t) == steps


def test_truth_is_interpolated_at_the_estimate_times_and_out_of_span_steps_are_dropped() -> None:
    t_truth = np.arange(0.0, 10.0, 0.1)
    truth = GroundTruth(
        history=StateHistory(
            blocks={BlockName.ACCEL_BIAS: StateBlock(t_truth, np.column_stack([t_truth] * 3))}
        )
    )
    t_est = np.array([0.05, 5.55, 12.0])
    history = StateHistory(
        blocks={
            BlockName.ACCEL_BIAS: StateBlock(
                t_est, np.column_stack([t_est] * 3), np.tile(np.eye(3), (3, 1, 1))
            )
        }
    )
    series = nees_series(history, truth)["accel_bias"]
    np.testing.assert_allclose(series.t, [0.05, 5.55])
    np.testing.assert_allclose(series.nees, 0.0, atol=1e-20)


def test_landmark_nees_in_world_and_body_frames_uses_the_mapping() -> None:
    rng = np.random.default_rng(45)
    true_map = LandmarkMap(ids=np.array([10, 11, 12]), positions=rng.normal(size=(3, 3)) * 5)
    rotation = Rotation.from_rotvec([0.1, 0.2, 1.0])
    pose = Trajectory(
        np.array([0.0, 2.0]),
        np.array([[1.0, 2.0, 0.0], [3.0, 2.0, 0.5]]),
        quat_wxyz_from_rotation(rotation)[None].repeat(2, 0),
    )
    truth = GroundTruth(history=StateHistory(pose=pose), landmarks=true_map)
    sigma = 0.1
    offsets = np.array([[sigma, 0, 0], [0, -sigma, 0]])  # NEES 1 each
    world = LandmarkMap(
        np.array([0, 1]),
        true_map.positions[:2] - offsets,
        np.tile(sigma**2 * np.eye(3), (2, 1, 1)),
        Frame.WORLD,
        1.0,
    )
    body_truth = rotation.inv().apply(true_map.positions[1:] - pose.positions[1])
    body = LandmarkMap(
        np.array([1, 2]),
        body_truth + 2 * offsets,
        np.tile(sigma**2 * np.eye(3), (2, 1, 1)),
        Frame.BODY,
        2.0,
    )
    series = nees_series(
        StateHistory(landmarks=(world, body)), truth, mapping={0: 10, 1: 11, 2: 12}
    )
    np.testing.assert_allclose(series["landmarks"].nees, [1.0, 1.0, 4.0, 4.0], rtol=1e-9)
    np.testing.assert_array_equal(series["landmarks"].dof, [3, 3, 3, 3])
    np.testing.assert_array_equal(series["landmarks"].t, [1.0, 1.0, 2.0, 2.0])


def test_time_averaged_nis_of_gaussian_innovations_detects_a_scaled_innovation_covariance() -> None:
    rng = np.random.default_rng(46)
    count, dof = 500, 2
    covariances = _random_covariances(rng, count, dof)
    innovations = _gaussian_errors(rng, covariances)
    # Time average of K NIS values: K * mean ~ chi2(K n), bounds chi2_interval(n, runs=K).
    low, high = chi2_interval(dof, runs=count)
    assert low <= np.mean(nees(innovations, covariances)) <= high
    assert np.mean(nees(innovations, 4.0 * covariances)) < low
    assert np.mean(nees(innovations, 0.25 * covariances)) > high
    assert below_fraction(nees(innovations, covariances), dof) == pytest.approx(0.95, abs=0.03)
    assert below_fraction(nees(innovations, 0.25 * covariances), dof) < 0.75
