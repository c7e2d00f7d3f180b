"""The sensor-based filter end to end: bad input, convergence, 3-D, association quality."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from datasets.errors import InputError
from datasets.measurements import GyroSample, LandmarkScan
from datasets.rotations import rot2
from datasets.simulation.scenarios import load_scenario
from datasets.state import Frame
from filters.sensor_based.config import SensorBasedConfig
from filters.sensor_based.filter import SensorBasedSlam
from tests.sensor_based_support import body_frame_landmarks, planar_sequence, run
from workbench.metrics.data_association import score_associations

LANDMARKS = np.array([[3.0, 1.0], [2.0, -2.0], [5.0, 0.5], [4.0, 3.0]])


def _finite(estimator: SensorBasedSlam) -> bool:
    return bool(
        np.all(np.isfinite(estimator.state.x)) and np.all(np.isfinite(estimator.state.covariance))
    )


def test_converges_from_wrong_initial_velocity_and_bias() -> None:
    sequence = planar_sequence(40.0, (0.5, 0.0), 0.05, LANDMARKS, seed=3, gyro_bias=0.01)
    config = SensorBasedConfig(
        association="jcbb",
        initial_velocity_error_m_s=[0.4, -0.3],
        initial_velocity_sigma_m_s=0.5,
        initial_gyro_bias_sigma_rad_s=0.03,
    )
    _, estimate = run(SensorBasedSlam, config, sequence)
    velocity = estimate.causal.block("velocity")
    bias = estimate.causal.block("gyro_bias")
    assert velocity.frame == Frame.BODY
    assert np.linalg.norm(velocity.values[0] - [0.5, 0.0]) > 0.4
    assert np.linalg.norm(velocity.values[-1] - [0.5, 0.0]) < 3 * np.sqrt(
        np.trace(velocity.covariances[-1])
    )
    assert abs(bias.values[-1, 0] - 0.01) < 3 * np.sqrt(bias.covariances[-1, 0, 0])
    # Uncertainty of the vehicle variables decreases (the paper's Fig. 2(a)).
    assert np.trace(velocity.covariances[-1]) < 0.05 * np.trace(velocity.covariances[0])
    assert bias.covariances[-1, 0, 0] < 0.05 * bias.covariances[0, 0, 0]
    snapshot = estimate.causal.landmarks[-1]
    assert snapshot.frame == Frame.BODY and len(snapshot) == len(LANDMARKS)


def test_long_stretch_without_landmarks_keeps_state_finite_and_recovers() -> None:
    sequence = planar_sequence(
        60.0, (0.3, 0.0), 0.0, LANDMARKS + [6.0, 0.0], seed=4, blank=(10.0, 40.0)
    )
    estimator, estimate = run(SensorBasedSlam, SensorBasedConfig(association="jcbb"), sequence)
    assert _finite(estimator)
    velocity = estimate.causal.block("velocity")
    t = velocity.t
    std = np.sqrt(np.trace(velocity.covariances, axis1=1, axis2=2))
    assert std[np.searchsorted(t, 39.0)] > 2 * std[np.searchsorted(t, 9.0)]  # grows while blind
    assert std[-1] < 0.5 * std[np.searchsorted(t, 39.0)]  # recovers when landmarks return
    assert np.linalg.norm(velocity.values[-1] - [0.3, 0.0]) < 0.1


def test_duplicate_points_in_a_scan_create_one_landmark() -> None:
    sequence = planar_sequence(5.0, (0.0, 0.0), 0.0, LANDMARKS[:1], seed=5)
    measurements = list(sequence.measurements())
    doubled = []
    for measurement in measurements:
        if isinstance(measurement, LandmarkScan):
            measurement = LandmarkScan(
                t=measurement.t,
                points=np.vstack([measurement.points, measurement.points]),
                covariances=np.concatenate([measurement.covariances, measurement.covariances]),
            )
        doubled.append(measurement)
    estimator, estimate = run(
        SensorBasedSlam, SensorBasedConfig(association="jcbb"), sequence, doubled
    )
    assert len(estimator.state.landmark_ids()) == 1
    diagnostics = estimate.diagnostics
    # Every scan: one measurement used, its duplicate recorded as rejected (-1).
    assert np.sum(diagnostics.assoc_landmark_id >= 0) == len(diagnostics.landmark_count)
    assert _finite(estimator)


def test_nan_rates_are_skipped_and_reported() -> None:
    sequence = planar_sequence(10.0, (0.3, 0.0), 0.1, LANDMARKS, seed=6)
    measurements = list(sequence.measurements())
    corrupted = [
        GyroSample(t=m.t, rate=np.array([np.nan]))
        if isinstance(m, GyroSample) and 2.0 < m.t < 3.0
        else m
        for m in measurements
    ]
    estimator, estimate = run(
        SensorBasedSlam, SensorBasedConfig(association="jcbb"), sequence, corrupted
    )
    assert _finite(estimator)
    assert estimator.skipped["nan_rate"] > 0
    assert any(event.kind == "skipped_input" for event in estimate.diagnostics.events)
    assert any("nan_rate" in note for note in estimate.notes)


def test_nan_points_are_dropped_and_time_going_backwards_is_an_input_error() -> None:
    sequence = planar_sequence(2.0, (0.3, 0.0), 0.0, LANDMARKS, seed=7)
    estimator = SensorBasedSlam(SensorBasedConfig(association="jcbb"), sequence)
    for measurement in sequence.measurements():
        estimator.process(measurement)
    bad = LandmarkScan(
        t=2.1,
        points=np.array([[np.nan, 1.0], [3.0, 1.0]]),
        covariances=np.repeat(np.eye(2)[None] * 0.01, 2, 0),
    )
    estimator.process(bad)
    assert estimator.skipped["nan_points"] == 1 and _finite(estimator)
    with pytest.raises(InputError, match="backwards"):
        estimator.process(GyroSample(t=1.0, rate=np.array([0.0])))
    with pytest.raises(InputError, match="components"):
        estimator.process(GyroSample(t=2.2, rate=np.zeros(3)))


def test_three_dimensional_filter_runs_on_the_rover_with_its_gyro() -> None:
    sequence = load_scenario("aghili-rover", 0, {"duration_s": "20", "ids": "true"})
    estimator, estimate = run(SensorBasedSlam, SensorBasedConfig(association="ids"), sequence)
    assert _finite(estimator)
    velocity = estimate.causal.block("velocity")
    assert velocity.values.shape[1] == 3 and estimate.causal.block("gyro_bias").values.shape[1] == 3
    truth = sequence.ground_truth.body_velocity
    index = np.searchsorted(truth.t, velocity.t[-1] - 1e-9)
    error = truth.values[index] - velocity.values[-1]
    assert error @ np.linalg.solve(velocity.covariances[-1], error) < 16.27  # chi2(3) 99.9 %
    nis = estimate.diagnostics.nis / estimate.diagnostics.nis_dof
    assert 0.5 < np.mean(nis) < 1.5


def _oracle_precision(sequence) -> float:
    """Assignment with the TRUE map and pose (globally optimal per scan, all landmarks)."""
    truth = sequence.ground_truth
    correct = total = 0
    scan_ids = {round(t, 6): ids for t, ids in truth.scan_ids}
    for measurement in sequence.measurements():
        if not isinstance(measurement, LandmarkScan) or measurement.count == 0:
            continue
        index = np.searchsorted(truth.pose.t, measurement.t - 1e-9)
        body = (truth.landmarks.positions - truth.pose.positions[index]) @ rot2(
            float(truth.pose.rotations[index])
        )
        nu = measurement.points[:, None, :] - body[None]
        cost = np.einsum("kmi,kij,kmj->km", nu, np.linalg.inv(measurement.covariances), nu)
        rows, columns = linear_sum_assignment(cost)
        correct += int(
            np.sum(truth.landmarks.ids[columns] == scan_ids[round(measurement.t, 6)][rows])
        )
        total += len(rows)
    return correct / total


def test_jcbb_association_on_the_loop_at_default_noise_beats_a_perfect_map_oracle() -> None:
    # At the paper's laser noise the door-niche corners (0.3-0.45 m apart) are closer than
    # one range/bearing sigma: even the true map and pose give ~0.85 precision. Ours must
    # not be worse than that bound (it is better: it only considers landmarks in its map).
    sequence = load_scenario("guerreiro-loop", 0, {"duration_s": "15"})
    _, estimate = run(SensorBasedSlam, SensorBasedConfig(association="jcbb"), sequence)
    score = score_associations(estimate.diagnostics, sequence.ground_truth.scan_ids)
    assert score.precision >= _oracle_precision(sequence)
    assert score.recall >= 0.85


def test_jcbb_association_precision_and_recall_at_reduced_noise() -> None:
    sequence = load_scenario("guerreiro-loop", 0, {"duration_s": "15", "noise_scale": "0.25"})
    _, estimate = run(SensorBasedSlam, SensorBasedConfig(association="jcbb"), sequence)
    score = score_associations(estimate.diagnostics, sequence.ground_truth.scan_ids)
    assert score.precision >= 0.99
    assert score.recall >= 0.99


# seed 0 in the default tier; seed 1 repeats the check in the study tier
@pytest.mark.parametrize("seed", [0, pytest.param(1, marks=pytest.mark.study)])
def test_jcbb_association_reaches_0_99_at_default_noise_when_corners_are_separable(
    seed: int,
) -> None:
    """The paper's laser noise, unchanged; 1 m deep door niches (corners >= 0.8 m apart
    instead of 0.3 m) and corners detected within 6 m; the joint gate at 0.999 (at 0.99 the
    gate alone rejects ~1 % of correct pairs). Measured over the 60 s: 0.9956/0.9950 and
    0.9959/0.9948; the full loop, seeds 0-2: precision 0.994-0.997, recall 0.990-0.994 (no
    loop closure fires at that range). On the default world the bound is not reachable:
    even JCBB against the true map from the true pose gets about 0.95."""
    options = {"duration_s": "60", "niche_depth_m": "1.0", "range_m": "6"}
    sequence = load_scenario("guerreiro-loop", seed, options)
    _, estimate = run(
        SensorBasedSlam, SensorBasedConfig(association="jcbb", gate_probability=0.999), sequence
    )
    score = score_associations(estimate.diagnostics, sequence.ground_truth.scan_ids)
    assert score.precision >= 0.99
    assert score.recall >= 0.99


def test_paper_tuning_is_a_preset_and_reads_conservative_on_the_laser_s_own_noise() -> None:
    """sim:guerreiro-loop draws a UTM-30LX-class laser's own noise (3 cm, 0.25 deg); the
    paper's filter tuning (0.15 m, 3.75 deg) is a named preset: its NIS per dof then falls
    far below that of the stated noise (both with the paper's process noise, itself
    conservative on this motion)."""
    from datasets.errors import InputError
    from filters.sensor_based.config import SensorBasedConfig
    from filters.sensor_based.filter import SensorBasedSlam
    from filters.sensor_based.scan_association import paper_laser_covariances
    from workbench.registry import load_dataset

    sequence = load_dataset("sim:guerreiro-loop", 0, {"duration_s": "10"})
    per_dof = {}
    for tuning in ("stated", "paper"):
        estimator = SensorBasedSlam(SensorBasedConfig(tuning=tuning), sequence)
        for measurement in sequence.measurements():
            estimator.process(measurement)
        diagnostics = estimator.estimate().diagnostics
        per_dof[tuning] = diagnostics.scan_nis.sum() / diagnostics.scan_nis_dof.sum()
    assert per_dof["paper"] < 0.2 * per_dof["stated"] and 0.4 < per_dof["stated"] < 1.3
    # at 4 m straight ahead: range sigma 0.15 m, across 4 m x 3.75 deg
    covariance = paper_laser_covariances(np.array([[4.0, 0.0]]))[0]
    np.testing.assert_allclose(np.sqrt(np.diag(covariance)), [0.15, 4.0 * np.deg2rad(3.75)])
    with pytest.raises(InputError, match="2-D"):
        SensorBasedSlam(
            SensorBasedConfig(tuning="paper"), load_dataset("sim:circle", 0, {"duration_s": "2"})
        )


@pytest.mark.parametrize("seed", [pytest.param(seed, marks=pytest.mark.study) for seed in (0, 4)])
def test_without_ids_the_default_loop_associates_and_closes_its_loops(seed: int) -> None:
    """Issue 14 on ``sim:guerreiro-loop --data ids=false`` with every default (the full
    loop): association precision and recall >= 0.99, loop-closure pairs >= 0.95 correct,
    NIS per dof within 0.8-1.2. Seeds 0-9 measured with a suite: precision 1.0, recall
    0.9968-0.9977, pair precision 1.0 (two closures each), NIS/dof 0.956-0.986. Before the
    landmark disturbance defaulted to 0 and between-gate sightings paired by mutual
    exclusion, seeds 0 and 4 read 0.987 / 0.985, pair precision 0.857 and NIS 0.64."""
    from workbench.metrics.data_association import landmark_id_mapping, score_loop_closures

    sequence = load_scenario("guerreiro-loop", seed, {"ids": "false"})
    _, estimate = run(SensorBasedSlam, SensorBasedConfig(), sequence)
    diagnostics = estimate.diagnostics
    score = score_associations(diagnostics, sequence.ground_truth.scan_ids)
    assert score.precision >= 0.99 and score.recall >= 0.99
    loops = score_loop_closures(
        diagnostics.events, landmark_id_mapping(diagnostics, sequence.ground_truth)
    )
    assert loops.events >= 1 and loops.precision >= 0.95
    assert 0.8 <= diagnostics.scan_nis.sum() / diagnostics.scan_nis_dof.sum() <= 1.2


def test_the_landmark_disturbance_is_zero_unless_the_paper_preset_or_the_option_says() -> None:
    from filters.sensor_based.config import PAPER_LANDMARK_SIGMA_M, landmark_disturbance

    assert landmark_disturbance(SensorBasedConfig()) == 0.0
    assert landmark_disturbance(SensorBasedConfig(tuning="paper")) == PAPER_LANDMARK_SIGMA_M == 0.05
    assert (
        landmark_disturbance(SensorBasedConfig(tuning="paper", landmark_walk_m_sqrt_s=0.0)) == 0.0
    )
    assert landmark_disturbance(SensorBasedConfig(landmark_walk_m_sqrt_s=0.02)) == 0.02


def _odometry_only(sequence, shift_s: float):
    """``sequence``'s gyro samples as relative-pose odometry without ``dt`` (the sample
    interval is then the time since the previous sample), every time shifted by
    ``shift_s``."""
    from dataclasses import replace

    from datasets.measurements import Odometry, Sensor

    stream, previous = [], None
    for measurement in sequence.measurements():
        t = measurement.t + shift_s
        if isinstance(measurement, GyroSample):
            if previous is not None:
                dt = t - previous
                stream.append(
                    Odometry(
                        t=t,
                        covariance=np.diag([1e-4, 1e-4, 1e-5]),
                        relative_pose=np.array([1.0 * dt, 0.0, float(measurement.rate[0]) * dt]),
                    )
                )
            previous = t
        else:
            stream.append(replace(measurement, t=t))
    start = replace(sequence.initial_state, t=sequence.initial_state.t + shift_s)
    return replace(
        sequence,
        sensors=frozenset({Sensor.ODOMETRY, Sensor.LANDMARKS}),
        stream=lambda: iter(stream),
        initial_state=start,
    )


def test_odometry_without_dt_reads_the_same_whether_the_run_starts_at_zero_or_later() -> None:
    """The rate taken from relative-pose odometry without ``dt`` uses the time since the
    previous sample; a run starting at t = 0 once dropped its first increment (a previous
    time of 0.0 read as 'no previous sample'), so the same data shifted in time differed."""
    landmarks = np.array([[4.0, 3.0], [-3.0, 5.0], [2.0, -4.0], [-5.0, -2.0]])
    base = planar_sequence(3.0, (1.0, 0.0), 0.3, landmarks)
    headings = []
    for shift in (0.0, 7.0):
        _, estimate = run(SensorBasedSlam, SensorBasedConfig(), _odometry_only(base, shift))
        pose = estimate.causal.pose
        headings.append(float(pose.rotations[-1]))
        assert pose.t[-1] == pytest.approx(3.0 + shift)
    assert headings[0] == pytest.approx(headings[1], abs=1e-9)


@pytest.mark.parametrize("hold_s, exact", [(1.0, True), (None, False)])
def test_a_scan_s_measured_values_expire_across_a_gap_without_scans(hold_s, exact) -> None:
    """``A(t, y)`` takes a visible feature's bias coupling ``M(y) b`` at its measured value y
    (eqs. (3)-(4)); held across a 20 s gap without scans (UTIAS between sightings, CARMEN
    and Victoria Park between corner scans) while the vehicle turns, the stale y turns the
    bias's effect into a drift of the landmark. With the default ``measured_hold_s`` the
    features are non-visible after it and the gap is propagated with their estimates: the
    noise-free landmarks come out of the gap within the one second of stale coupling the hold
    allows (known bias, turning 0.3 rad/s; measured 0.037 m against 4.3 m held throughout)."""
    bias = 0.05
    sequence = planar_sequence(32.0, (0.4, 0.0), 0.3, LANDMARKS, gyro_bias=bias)
    kept = [
        m
        for m in sequence.measurements()
        if not (isinstance(m, LandmarkScan) and 10.0 < m.t < 30.0) and m.t < 29.95
    ]
    config = SensorBasedConfig(
        initial_gyro_bias_rad_s=[bias], initial_gyro_bias_sigma_rad_s=1e-9, measured_hold_s=hold_s
    )
    estimator, _ = run(SensorBasedSlam, config, sequence, kept)
    ids, positions = estimator.state.landmark_positions()
    truth = body_frame_landmarks(LANDMARKS, (0.4, 0.0), 0.3, estimator.t)
    error = np.abs(positions - truth[ids]).max()
    if exact:
        assert error < 0.05
    else:
        assert error > 0.5  # the stale coupling: what the default removes
