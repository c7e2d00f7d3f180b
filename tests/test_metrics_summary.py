"""``compute_metrics`` on hand-built estimates with known errors, and on a simulated scenario."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from datasets.estimate import AssociationDecision, EstimateRecorder, StepTiming
from datasets.rotations import quat_wxyz_from_rotation, so3_exp
from datasets.sequence import Sequence
from datasets.state import BlockName, Frame, GroundTruth, LandmarkMap, StateBlock, StateHistory
from datasets.trajectory import Trajectory
from workbench.metrics.summary import compute_metrics, smoothed_key

REQUIRED_KEYS = (
    "ate_rmse_m", "ate_rmse_raw_m", "rpe_trans_rmse_m", "rpe_rot_rmse_deg", "final_orientation_error_deg",
    "nees_pose_per_dof", "nees_velocity_per_dof", "nees_gyro_bias_per_dof", "nees_accel_bias_per_dof", "nees_landmarks_per_dof",
    "nees_pose_inside_fraction", "nis_measurement_per_dof", "nis_dof", "nis_inside_fraction", "landmark_rmse_m", "landmarks_mapped", "landmarks_in_map",
    "association_precision", "association_recall", "loop_closures", "loop_closure_precision", "steps",
    "time_per_step_ms_median", "time_per_step_ms_p99", "gps_holdout_rmse_m", "ate_rmse_smoothed_m",
)  # fmt: skip

STEPS = 101
T = np.arange(STEPS) * 0.1


def _truth_3d() -> GroundTruth:
    angle = 0.2 * T
    positions = np.column_stack([10 * np.cos(angle), 10 * np.sin(angle), 0.1 * T])
    rotations = quat_wxyz_from_rotation(
        Rotation.from_rotvec(np.outer(angle + np.pi / 2, [0, 0, 1]))
    )
    velocity = np.column_stack([-2 * np.sin(angle), 2 * np.cos(angle), np.full(STEPS, 0.1)])
    blocks = {
        BlockName.VELOCITY: StateBlock(T, velocity, frame=Frame.WORLD),
        BlockName.GYRO_BIAS: StateBlock(T, np.tile([0.01, -0.02, 0.005], (STEPS, 1))),
    }
    landmarks = LandmarkMap(
        ids=np.arange(5),
        positions=np.array([[15.0, 0, 0], [0, 15, 1], [-15, 0, 2], [0, -15, 0], [5, 5, 5]]),
    )
    scan_ids = tuple((float(t), np.arange(5)) for t in T[::10])
    return GroundTruth(
        history=StateHistory(pose=Trajectory(T, positions, rotations), blocks=blocks),
        landmarks=landmarks,
        scan_ids=scan_ids,
        held_out_positions=(
            T[5::20] + 0.05,
            positions[5::20] + 0.5 * (positions[6::20] - positions[5::20]),
        ),
    )


def _sequence(truth: GroundTruth, dimension: int = 3) -> Sequence:
    return Sequence(
        name="hand-built",
        dimension=dimension,
        sensors=frozenset(),
        stream=lambda: iter(()),
        ground_truth=truth,
    )


def _estimate_3d(truth: GroundTruth):
    """Every pose 0.1 m off in world x, the last one also rotated 2 deg; covariances 0.01 I."""
    recorder = EstimateRecorder(dimension=3)
    pose = truth.pose
    for k in range(STEPS):
        rotation = pose.rotations[k]
        if k == STEPS - 1:
            rotation = quat_wxyz_from_rotation(
                Rotation.from_quat(rotation[[1, 2, 3, 0]])
                * Rotation.from_rotvec([0, 0, np.deg2rad(2.0)])
            )
        recorder.pose(T[k], pose.positions[k] + [0.1, 0.0, 0.0], rotation, 0.01 * np.eye(6))
        velocity = truth.history.blocks[BlockName.VELOCITY].values[k]
        recorder.block(
            BlockName.VELOCITY, T[k], velocity + [0.1, 0, 0], 0.01 * np.eye(3), Frame.WORLD
        )
        recorder.block(
            BlockName.GYRO_BIAS,
            T[k],
            truth.history.blocks[BlockName.GYRO_BIAS].values[k],
            1e-4 * np.eye(3),
        )
    for t, ids in truth.scan_ids:
        for index, true_id in enumerate(ids):
            decision = AssociationDecision.NEW if t == 0.0 else AssociationDecision.MATCHED
            recorder.association(t, index, 100 + int(true_id), decision)
    for value in (1.0, 2.0, 3.0, 30.0):
        recorder.nis(1.0, value, 2)
    recorder.event(5.0, "loop_closure", pairs=[[100, 101]])
    final_map = LandmarkMap(
        ids=100 + np.arange(5),
        positions=truth.landmarks.positions + [0.2, 0.0, 0.0],
        covariances=np.tile(0.04 * np.eye(3), (5, 1, 1)),
    )
    return recorder.build(landmarks=final_map)


def test_known_errors_give_known_metrics() -> None:
    truth = _truth_3d()
    estimate = replace(
        _estimate_3d(truth), timing=StepTiming(t=T, seconds=np.linspace(0.001, 0.003, STEPS))
    )
    metrics = compute_metrics(estimate, _sequence(truth))
    assert set(REQUIRED_KEYS) <= set(metrics)
    json.dumps(metrics, allow_nan=False)
    assert all(value is None or type(value) in (int, float) for value in metrics.values())

    assert metrics["ate_rmse_raw_m"] == pytest.approx(0.1, rel=1e-9)
    assert metrics["ate_rmse_m"] < 1e-9  # a constant offset is removed by the alignment
    assert metrics["rpe_trans_rmse_m"] < 1e-9
    assert metrics["rpe_rot_rmse_deg"] == pytest.approx(np.sqrt(4.0 / (STEPS - 1)), rel=1e-6)
    assert metrics["final_orientation_error_deg"] == pytest.approx(2.0, rel=1e-9)
    last_nees = 1.0 + np.deg2rad(2.0) ** 2 / 0.01 + 0.0  # attitude error adds; position stays 0.1 m
    # The last pose's rotated body frame leaves the 0.1 m position error's norm unchanged.
    assert metrics["nees_pose_per_dof"] == pytest.approx(
        (STEPS - 1 + last_nees) / STEPS / 6, rel=1e-6
    )
    assert metrics["nees_position_per_dof"] == pytest.approx(1.0 / 3, rel=1e-9)
    assert metrics["nees_velocity_per_dof"] == pytest.approx(1.0 / 3, rel=1e-9)
    assert metrics["nees_gyro_bias_per_dof"] == pytest.approx(0.0, abs=1e-12)
    assert metrics["nees_accel_bias_per_dof"] is None
    # NEES 1 with 6 dof lies below chi2.ppf(0.025, 6) = 1.24: never inside.
    assert metrics["nees_pose_inside_fraction"] == 0.0
    assert metrics["nees_landmarks_per_dof"] == pytest.approx(1.0 / 3, rel=1e-9)
    assert metrics["landmark_rmse_m"] == pytest.approx(0.2, rel=1e-9)
    assert metrics["landmarks_mapped"] == 5
    assert metrics["landmarks_in_map"] == 5
    assert metrics["nis_measurement_per_dof"] == pytest.approx(9.0 / 2)
    assert metrics["nis_dof"] == 2
    assert metrics["nis_inside_fraction"] == pytest.approx(0.75)
    assert metrics["nis_below_95_fraction"] == pytest.approx(0.75)
    assert (metrics["association_precision"], metrics["association_recall"]) == (1.0, 1.0)
    assert metrics["loop_closures"] == 1 and metrics["loop_closure_precision"] == 0.0
    assert metrics["steps"] == STEPS
    assert metrics["time_per_step_ms_median"] == pytest.approx(2.0)
    assert 2.9 < metrics["time_per_step_ms_p99"] <= 3.0
    # Held-out stamps halfway between poses: the estimate (0.1 m off) is interpolated there.
    assert metrics["gps_holdout_rmse_m"] == pytest.approx(0.1, rel=1e-6)
    assert metrics["ate_rmse_smoothed_m"] is None and metrics["nees_pose_per_dof_smoothed"] is None


def test_smoothed_history_fills_the_smoothed_keys() -> None:
    truth = _truth_3d()
    causal = _estimate_3d(truth)
    smoothed_pose = Trajectory(
        T,
        truth.pose.positions + [0.0, 0.3, 0.0],
        truth.pose.rotations,
        np.tile(0.09 * np.eye(6), (STEPS, 1, 1)),
    )
    metrics = compute_metrics(
        replace(causal, smoothed=StateHistory(pose=smoothed_pose)), _sequence(truth)
    )
    assert metrics["ate_rmse_raw_smoothed_m"] == pytest.approx(0.3, rel=1e-9)
    assert metrics["nees_pose_per_dof_smoothed"] == pytest.approx(1.0 / 6, rel=1e-9)
    assert metrics["ate_rmse_raw_m"] == pytest.approx(0.1, rel=1e-9)
    assert smoothed_key("time_per_step_ms") == "time_per_step_smoothed_ms"


def test_robocentric_estimate_without_a_world_pose_and_without_truth() -> None:
    truth = _truth_3d()
    recorder = EstimateRecorder(dimension=3)
    body_velocity = np.tile([2.0, 0.0, 0.1], (STEPS, 1))
    for k in range(STEPS):
        recorder.block(
            BlockName.VELOCITY, T[k], body_velocity[k] + [0, 0.2, 0], 0.04 * np.eye(3), Frame.BODY
        )
    estimate = recorder.build()
    with_body_truth = replace(truth, body_velocity=StateBlock(T, body_velocity))
    metrics = compute_metrics(estimate, _sequence(with_body_truth))
    for key in (
        "ate_rmse_m",
        "rpe_trans_rmse_m",
        "final_orientation_error_deg",
        "nees_pose_per_dof",
        "nees_pose_inside_fraction",
    ):
        assert metrics[key] is None
    assert metrics["nees_velocity_per_dof"] == pytest.approx(1.0 / 3, rel=1e-9)
    assert metrics["steps"] == STEPS
    no_truth = compute_metrics(estimate, Sequence("no-truth", 3, frozenset(), lambda: iter(())))
    json.dumps(no_truth, allow_nan=False)
    assert no_truth["nees_velocity_per_dof"] is None and no_truth["association_precision"] is None
    assert no_truth["landmarks_in_map"] is None  # no map at all


def test_a_map_without_truth_still_has_a_size() -> None:
    from workbench.metrics.summary import map_metrics

    final_map = LandmarkMap(ids=np.arange(7), positions=np.zeros((7, 3)))
    assert map_metrics(final_map, None, {}) == {
        "landmark_rmse_m": None,
        "landmarks_mapped": None,
        "landmarks_in_map": 7,
    }


def test_planar_estimate_uses_se2_alignment() -> None:
    angle = 0.3 * T
    positions = np.column_stack([5 * np.cos(angle), 5 * np.sin(angle)])
    truth = GroundTruth(history=StateHistory(pose=Trajectory(T, positions, angle + np.pi / 2)))
    rotation = np.array([[np.cos(0.5), -np.sin(0.5)], [np.sin(0.5), np.cos(0.5)]])
    recorder = EstimateRecorder(dimension=2)
    for k in range(STEPS):
        recorder.pose(
            T[k],
            rotation @ positions[k] + [1.0, 2.0],
            angle[k] + np.pi / 2 + 0.5,
            np.diag([0.01, 0.01, 0.001]),
        )
    metrics = compute_metrics(recorder.build(), _sequence(truth, dimension=2))
    assert metrics["ate_rmse_m"] < 1e-9
    assert metrics["ate_rmse_raw_m"] > 1.0
    assert metrics["final_orientation_error_deg"] == pytest.approx(np.rad2deg(0.5), rel=1e-9)


def test_simulated_scenario_with_a_consistent_oracle_estimate() -> None:
    from datasets.simulation.scenarios import load_scenario

    sequence = load_scenario("circle", seed=3, options={"duration_s": "20"})
    truth = sequence.ground_truth
    rng = np.random.default_rng(4)
    pose = truth.pose
    # An oracle: truth perturbed by xi ~ N(0, P) through the interface retraction.
    sigmas = np.array([0.01, 0.01, 0.02, 0.1, 0.1, 0.05])
    xi = rng.normal(size=(len(pose), 6)) * sigmas
    rotations = pose.rotation_matrices()
    recorder = EstimateRecorder(dimension=3)
    for k in range(len(pose)):
        # truth = estimate (+) xi  <=>  estimate = truth (+) (-xi) to first order; build it exactly:
        est_rotation = rotations[k] @ so3_exp(-xi[k, :3])
        est_position = pose.positions[k] - est_rotation @ xi[k, 3:]
        recorder.pose(
            pose.t[k],
            est_position,
            quat_wxyz_from_rotation(Rotation.from_matrix(est_rotation)),
            np.diag(sigmas**2),
        )
    metrics = compute_metrics(recorder.build(), sequence)
    json.dumps(metrics, allow_nan=False)
    assert metrics["nees_pose_per_dof"] == pytest.approx(1.0, rel=0.1)
    assert metrics["nees_pose_inside_fraction"] > 0.9
    assert metrics["ate_rmse_raw_m"] == pytest.approx(np.sqrt(np.sum(sigmas[3:] ** 2)), rel=0.15)


def test_static_truth_still_gets_an_aligned_ate() -> None:
    # evo refuses to align a static trajectory (degenerate); metrics.json takes a minimiser.
    truth = GroundTruth(
        history=StateHistory(
            pose=Trajectory(T, np.zeros((STEPS, 3)), np.tile([1.0, 0, 0, 0], (STEPS, 1)))
        )
    )
    recorder = EstimateRecorder(dimension=3)
    for k in range(STEPS):
        recorder.pose(T[k], [0.01 * k, 0.0, 0.0], [1.0, 0, 0, 0], None)
    metrics = compute_metrics(recorder.build(), _sequence(truth))
    drift = 0.01 * np.arange(STEPS)
    assert metrics["ate_rmse_m"] == pytest.approx(np.std(drift), rel=1e-9)
    assert metrics["ate_rmse_raw_m"] == pytest.approx(np.sqrt(np.mean(drift**2)), rel=1e-9)
    assert metrics["nees_pose_per_dof"] is None  # no covariance
    assert metrics["kitti_translation_percent"] is None


def test_too_few_poses_or_a_non_finite_reference_give_n_a_not_a_number() -> None:
    from datasets.state import GroundTruth, StateHistory
    from datasets.trajectory import Trajectory
    from workbench.metrics.summary import accuracy_metrics

    t = np.arange(10) * 0.1
    truth = Trajectory(t, np.column_stack([t, np.zeros(10)]), np.zeros(10))
    ground_truth = GroundTruth(history=StateHistory(pose=truth))
    one_pose = Trajectory(t[:1], np.zeros((1, 2)), np.zeros(1))
    assert accuracy_metrics(one_pose, ground_truth)["ate_rmse_m"] is None
    nan_truth = Trajectory(t, np.full((10, 2), np.nan), np.zeros(10))
    estimate = Trajectory(t, np.column_stack([t, np.zeros(10)]), np.zeros(10))
    metrics = accuracy_metrics(estimate, GroundTruth(history=StateHistory(pose=nan_truth)))
    assert metrics["ate_rmse_m"] is None and metrics["rpe_trans_rmse_m"] is None
    assert accuracy_metrics(estimate, ground_truth)["ate_rmse_m"] == pytest.approx(0.0, abs=1e-12)
