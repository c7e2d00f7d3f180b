"""iSAM2, fixed-lag and the planar variant on short runs; JCBB association without ids."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from gtsam.symbol_shorthand import X

from datasets.measurements import LandmarkScan
from smoothers.backends import FixedLagBackend
from smoothers.modes import SmootherFixedLag, SmootherIsam2
from workbench.metrics.consistency import nees
from workbench.metrics.data_association import score_associations
from workbench.metrics.state_errors import pose_error_series
from workbench.registry import load_dataset


def _run(estimator_class, config, sequence):
    estimator = estimator_class(config, sequence)
    for measurement in sequence.measurements():
        estimator.process(measurement)
    return estimator, estimator.estimate()


def _position_rmse(history, sequence) -> float:
    _, errors, _ = pose_error_series(history.pose, sequence.ground_truth)
    d = sequence.dimension
    translation = errors[:, 3:6] if d == 3 else errors[:, 0:2]
    return float(np.sqrt(np.mean(np.sum(translation**2, axis=1))))


def test_isam2_causal_and_smoothed_histories_with_covariances_on_aghili_rover():
    sequence = load_dataset("sim:aghili-rover", 2, {"duration_s": "6"})
    estimator, estimate = _run(SmootherIsam2, SmootherIsam2.Config(anchors=3), sequence)
    for history in (estimate.causal, estimate.smoothed):
        assert len(history.pose) == len(estimator.keyframe_t)
        assert history.pose.covariances is not None
        for block in ("velocity", "gyro_bias", "accel_bias"):
            assert history.block(block).covariances is not None
    assert estimate.landmarks.covariances is not None and len(estimate.landmarks) > 3
    # Smoothing uses the future: not worse than the causal estimate, both centimetre-level.
    assert (
        _position_rmse(estimate.smoothed, sequence)
        <= _position_rmse(estimate.causal, sequence) * 1.05
    )
    assert _position_rmse(estimate.smoothed, sequence) < 0.2
    # Association recorded for every measured landmark, by the scans' ids.
    scans = sum(1 for m in sequence.measurements() if m.sensor == "landmarks")
    assert len(estimate.diagnostics.landmark_count) == scans


def test_fixed_lag_backend_marginalises_keys_older_than_latest_minus_lag():
    backend = FixedLagBackend(2.0, 0.05, 1, dimension=2)
    graph = gtsam.NonlinearFactorGraph()
    graph.add(gtsam.PriorFactorPose2(X(0), gtsam.Pose2(), gtsam.noiseModel.Isotropic.Sigma(3, 0.1)))
    values = gtsam.Values()
    values.insert(X(0), gtsam.Pose2())
    backend.update(graph, values, {X(0): 0.0}, 0.0)
    for k in range(1, 5):
        graph = gtsam.NonlinearFactorGraph()
        graph.add(
            gtsam.BetweenFactorPose2(
                X(k - 1), X(k), gtsam.Pose2(1, 0, 0), gtsam.noiseModel.Isotropic.Sigma(3, 0.1)
            )
        )
        values = gtsam.Values()
        values.insert(X(k), gtsam.Pose2(k, 0, 0))
        assert backend.leaving(float(k)) == [X(j) for j in range(k) if (k - 1) - 2.0 <= j < k - 2.0]
        backend.update(graph, values, {X(k): float(k)}, float(k))
        kept = sorted(gtsam.Symbol(key).index() for key in backend.estimate().keys())
        assert kept == [j for j in range(k + 1) if j >= k - 2.0]


def test_fixed_lag_on_aghili_rover_keeps_a_bounded_window_and_exports_everything():
    sequence = load_dataset("sim:aghili-rover", 3, {"duration_s": "6"})
    estimator, estimate = _run(
        SmootherFixedLag, SmootherFixedLag.Config(anchors=3, lag_s=1.0), sequence
    )
    window = estimator.backend.estimate()
    poses_in_window = sum(1 for key in window.keys() if chr(gtsam.Symbol(key).chr()) == "x")
    assert poses_in_window <= 12  # 10 Hz keyframes, 1 s lag
    assert len(estimate.smoothed.pose) == len(estimator.keyframe_t)
    assert estimate.smoothed.pose.covariances is not None
    _, errors, valid = pose_error_series(estimate.smoothed.pose, sequence.ground_truth)
    values = nees(errors, estimate.smoothed.pose.covariances[valid])
    assert np.nanmean(values) < 3 * 6
    assert len(estimate.landmarks) > 3


def test_planar_gyro_only_variant_on_guerreiro_loop():
    sequence = load_dataset("sim:guerreiro-loop", 1, {"duration_s": "12"})
    estimator, estimate = _run(SmootherIsam2, SmootherIsam2.Config(), sequence)
    assert estimator.motion.source == "gyro"
    assert estimate.smoothed.pose.dimension == 2
    assert estimate.smoothed.block("velocity").frame == "body"
    assert _position_rmse(estimate.smoothed, sequence) < 0.3
    _, errors, valid = pose_error_series(estimate.smoothed.pose, sequence.ground_truth)
    assert np.nanmean(nees(errors, estimate.smoothed.pose.covariances[valid])) < 3 * 3


def test_planar_odometry_variant_on_victoria_park():
    sequence = load_dataset("victoria-park", 0, {"max_steps": "300"})
    estimator, estimate = _run(SmootherIsam2, SmootherIsam2.Config(), sequence)
    assert estimator.motion.source == "odometry"
    assert len(estimate.landmarks) > 5
    assert np.all(np.isfinite(estimate.smoothed.pose.positions))


def test_jcbb_association_without_ids_matches_the_true_landmarks():
    sequence = load_dataset("sim:aghili-rover", 4, {"duration_s": "5", "ids": "false"})
    _, estimate = _run(
        SmootherIsam2, SmootherIsam2.Config(anchors=3, causal_covariances=False), sequence
    )
    from workbench.metrics.data_association import score_associations

    score = score_associations(estimate.diagnostics, sequence.ground_truth.scan_ids)
    assert score.precision > 0.95


def test_3d_relative_pose_odometry_factors_tighten_the_trajectory():
    """Exact lidar-like odometry (from the truth, small stated noise) between scans: the
    smoother uses it (more information: smaller pose covariances than without)."""
    from dataclasses import replace

    from datasets.measurements import LandmarkScan, Odometry, Sensor
    from datasets.rotations import so3_log

    sequence = load_dataset("sim:aghili-rover", 5, {"duration_s": "3"})
    truth = sequence.ground_truth.pose
    homogeneous = truth.homogeneous()
    items, previous = [], None
    for m in sequence.measurements():
        items.append(m)
        if isinstance(m, LandmarkScan):
            i = int(np.argmin(np.abs(truth.t - m.t)))
            if previous is not None:
                relative = np.linalg.inv(homogeneous[previous]) @ homogeneous[i]
                pose6 = np.r_[so3_log(relative[:3, :3]), relative[:3, 3]]
                items.append(Odometry(t=m.t, covariance=np.eye(6) * 1e-4, relative_pose=pose6))
            previous = i
    with_odometry = replace(
        sequence, sensors=sequence.sensors | {Sensor.ODOMETRY}, stream=lambda: iter(items)
    )
    _, plain = _run(SmootherIsam2, SmootherIsam2.Config(anchors=3), sequence)
    estimator, helped = _run(SmootherIsam2, SmootherIsam2.Config(anchors=3), with_odometry)
    assert estimator.odometry_3d is not None
    assert len(helped.smoothed.pose) == len(plain.smoothed.pose)
    plain_var = np.trace(plain.smoothed.pose.covariances[-1][3:, 3:])
    helped_var = np.trace(helped.smoothed.pose.covariances[-1][3:, 3:])
    assert helped_var < plain_var
    assert _position_rmse(helped.smoothed, sequence) < 0.2


@pytest.mark.study
def test_fixed_lag_bridges_gaps_longer_than_its_window_and_keeps_its_map():
    """Victoria Park's first 1000 steps have stretches without landmarks longer than the
    5 s window: keyframes on motion alone bridge them. With keep_map=true a landmark seen
    again is the same variable (the default); with keep_map=false it comes back from its
    departure marginal (an event per return)."""
    from datasets.victoria_park import default_path

    if not default_path().is_file():
        pytest.skip("gtsam's victoria_park.txt absent")
    sequence = load_dataset("victoria-park", 0, {"max_steps": "1000"})
    scan_times = np.array([m.t for m in sequence.measurements() if isinstance(m, LandmarkScan)])
    assert np.max(np.diff(scan_times)) > 5.0  # the gap the window must bridge
    assert SmootherFixedLag.Config().keep_map
    kept = SmootherFixedLag(SmootherFixedLag.Config(lag_s=5.0), sequence)
    for measurement in sequence.measurements():
        kept.process(measurement)
    estimate = kept.estimate()
    assert np.max(np.diff(kept.keyframe_t)) <= 2.5 + 0.2 + 1e-9  # half the window + a step
    returns = [e for e in estimate.diagnostics.events if e.kind == "landmark_returned"]
    assert returns == []
    seen = {int(i) for _, ids in sequence.ground_truth.scan_ids for i in ids}
    assert len(estimate.landmarks) == len(seen)
    leaving = SmootherFixedLag(SmootherFixedLag.Config(lag_s=5.0, keep_map=False), sequence)
    for measurement in sequence.measurements():
        leaving.process(measurement)
    left = leaving.estimate()
    returned = [e for e in left.diagnostics.events if e.kind == "landmark_returned"]
    assert len(returned) > 0
    # a return is an association with the landmark it was, not a new landmark: with ids
    # every sighting of a mapped landmark counts as associated (it read 0.96 on UTIAS)
    score = score_associations(left.diagnostics, sequence.ground_truth.scan_ids)
    assert score.new_landmarks == len(seen) and score.recall == 1.0


def test_isam2_smoothed_history_is_the_converged_solution_also_for_small_unit_variables():
    """iSAM2's smoothed gyro biases equal the batch optimum. With GTSAM's default wildfire
    threshold (0.001 per tangent component) a bias whose sigma is 1.8e-4 rad/s kept a stale
    delta: on this 10 s loop its smoothed value was up to 3.7 sigma from the batch's."""
    from smoothers.modes import SmootherBatch

    sequence = load_dataset(
        "sim:guerreiro-loop",
        0,
        {
            "duration_s": "10",
            "speed_profile": "random",
            "speed_reversion_s": "null",
            "speed_walk_m_s_sqrt_s": "0.01",
            "lateral_walk_m_s_sqrt_s": "0.0025",
        },
    )
    _, incremental = _run(SmootherIsam2, SmootherIsam2.Config(), sequence)
    _, batch = _run(SmootherBatch, SmootherBatch.Config(), sequence)
    isam2_bias = incremental.smoothed.block("gyro_bias")
    batch_bias = batch.smoothed.block("gyro_bias")
    sigma = np.sqrt(batch_bias.covariances[:, 0, 0])
    assert np.max(np.abs(isam2_bias.values[:, 0] - batch_bias.values[:, 0]) / sigma) < 0.1


def test_the_information_clock_stands_still_on_motion_alone():
    from smoothers.lag_clock import InformationClock

    clock = InformationClock(0.0)
    for t, informative in ((1.0, True), (2.0, True), (10.0, False), (20.0, False), (21.0, True)):
        clock.advance(t, informative)
    assert [clock(t) for t in (0.0, 1.5, 2.0, 6.0, 10.0, 15.0, 20.0, 20.5, 21.0, 22.0)] == [
        0.0, 1.5, 2.0, 2.0, 2.0, 2.0, 2.0, 2.5, 3.0, 4.0,
    ]  # fmt: skip
    assert clock.held_s == 18.0


@pytest.mark.parametrize("lag_clock", ["informative", "wall"])
def test_a_stretch_without_sightings_stays_in_the_window_until_its_end_is_solved(lag_clock):
    """Sightings removed for 3 lags: with the informative clock no keyframe of the stretch
    leaves the window before the sightings that end it arrive; on the wall clock most do
    (the failure ``smoothers.lag_clock`` describes)."""
    from dataclasses import replace

    sequence = load_dataset("sim:guerreiro-loop", 0, {"duration_s": "16"})
    gap = (8.0, 8.0 + 3 * 2.0)

    def stream():
        for m in sequence.measurements():
            if not (isinstance(m, LandmarkScan) and gap[0] <= m.t <= gap[1]):
                yield m

    gapped = replace(sequence, stream=stream)
    smoother = SmootherFixedLag(SmootherFixedLag.Config(lag_s=2.0, lag_clock=lag_clock), gapped)
    for measurement in gapped.measurements():
        if measurement.t > gap[1] and isinstance(measurement, LandmarkScan):
            break  # the first sighting after the stretch: not solved yet
        smoother.process(measurement)
    inside = [k for k, t in enumerate(smoother.keyframe_t) if gap[0] <= t <= gap[1]]
    left = [k for k in inside if k in smoother.exports.keyframes]
    assert len(inside) >= 3
    if lag_clock == "informative":
        assert left == []
    else:
        assert len(left) >= len(inside) // 2


@pytest.mark.parametrize("estimator_class", [SmootherIsam2, SmootherFixedLag])
def test_a_solver_failure_mid_run_stops_the_run_and_is_reported_as_divergence(
    estimator_class, monkeypatch
):
    """GTSAM meeting an indeterminate system mid-run (a diverged window: the Intel laser log's
    fixed-lag run reached values of 1e250 first) stops the run with what it has, an event, a
    note and a divergence at that time; the same failure at the first solve (nothing fixes
    some state) stays an error."""
    from smoothers import backends
    from smoothers.gtsam_errors import IndeterminateSystem
    from workbench.metrics.divergence import detect_divergence

    sequence = load_dataset("sim:guerreiro-loop", 1, {"duration_s": "12"})
    fetch = backends.fetch_values
    calls = {"n": 0}
    fail_from = 40

    def failing(source, keys, dimension):
        calls["n"] += 1
        if calls["n"] >= fail_from:
            raise RuntimeError(
                "\nIndeterminant linear system detected while working near variable l3"
            )
        return fetch(source, keys, dimension)

    monkeypatch.setattr(backends, "fetch_values", failing)
    estimator, estimate = _run(estimator_class, estimator_class.Config(), sequence)
    assert estimator.stopped is not None
    t_stop = estimator.stopped[0]
    assert sequence.initial_state.t < t_stop < sequence.ground_truth.history.pose.t[-1] - 1.0
    assert estimator.dropped_after_stop > 0
    causal = estimate.causal.pose
    assert len(causal) > 5 and causal.t[-1] <= t_stop
    assert np.all(np.isfinite(causal.positions))
    assert [e.t for e in estimate.diagnostics.events if e.kind == "solver_failed"] == [t_stop]
    assert any("stopped at t=" in note for note in estimate.notes)
    assert f"{estimator.dropped_after_stop} measurement(s) after the stop not used" in " ".join(
        estimate.notes
    )
    divergence = detect_divergence(estimate, sequence)
    assert divergence is not None and divergence.t == t_stop
    assert "solver stopped" in divergence.reason

    calls["n"] = 0
    fail_from = 1
    with pytest.raises(IndeterminateSystem, match="indeterminate"):
        _run(estimator_class, estimator_class.Config(), sequence)
