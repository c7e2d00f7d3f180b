"""Tests of the seeded simulator (datasets/simulation)."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from datasets import BlockName, GyroSample, ImuSample, InputError, LandmarkScan, Sensor
from datasets.range_bearing import first_order_covariance as range_bearing_covariance
from datasets.rotations import matrix_from_quat_wxyz, so3_exp, so3_log
from datasets.simulation.figures import sequence_figures
from datasets.simulation.floor_plan import ring_corridor_building
from datasets.simulation.folder_format import read_sequence_folder, write_sequence_folder
from datasets.simulation.imu import kitti_imu_sigmas
from datasets.simulation.scenarios import describe_scenarios, load_scenario

SCENARIOS = ["aghili-rover", "guerreiro-loop", "circle", "static"]
SHORT = {"duration_s": "20"}


def scans_of(sequence) -> list[LandmarkScan]:
    return [m for m in sequence.measurements() if isinstance(m, LandmarkScan)]


def inertial_of(sequence) -> list:
    return [m for m in sequence.measurements() if isinstance(m, (ImuSample, GyroSample))]


def measurement_arrays(measurement) -> list[np.ndarray]:
    if isinstance(measurement, ImuSample):
        return [measurement.gyro, measurement.accel]
    if isinstance(measurement, GyroSample):
        return [measurement.rate]
    optional = [array for array in (measurement.ids, measurement.directions) if array is not None]
    return [measurement.points, measurement.covariances] + optional


def folder_digest(folder: Path) -> dict[str, str]:
    return {
        str(path.relative_to(folder)): hashlib.sha256(path.read_bytes()).hexdigest()
        for path in sorted(folder.rglob("*"))
        if path.is_file()
    }


def true_body_points(sequence, scan: LandmarkScan, true_ids: np.ndarray) -> np.ndarray:
    """R^T (rho - r) from the ground truth at the scan time (a truth sample time)."""
    truth = sequence.ground_truth
    index = int(np.argmin(np.abs(truth.pose.t - scan.t)))
    assert abs(truth.pose.t[index] - scan.t) < 1e-9
    rotation = truth.pose.rotation_matrices()[index]
    rho = truth.landmarks.positions[np.searchsorted(truth.landmarks.ids, true_ids)]
    return (rotation.T @ (rho - truth.pose.positions[index]).T).T


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_same_seed_gives_identical_streams_and_other_seed_other_noise(scenario):
    first, again, other = (load_scenario(scenario, seed, SHORT) for seed in (3, 3, 4))
    a, b, c = (list(sequence.measurements()) for sequence in (first, again, other))
    assert len(a) == len(b) == len(c)
    assert all(type(x) is type(y) and x.t == y.t for x, y in zip(a, b))
    for x, y in zip(a, b):
        for array_x, array_y in zip(measurement_arrays(x), measurement_arrays(y)):
            np.testing.assert_array_equal(array_x, array_y)
    inertial_a = np.array(
        [np.concatenate(measurement_arrays(m)) for m in a if not isinstance(m, LandmarkScan)]
    )
    inertial_c = np.array(
        [np.concatenate(measurement_arrays(m)) for m in c if not isinstance(m, LandmarkScan)]
    )
    assert np.mean(inertial_a != inertial_c) > 0.99
    points_a = np.concatenate([m.points for m in a if isinstance(m, LandmarkScan)])
    points_c = np.concatenate([m.points for m in c if isinstance(m, LandmarkScan)])
    assert points_a.shape == points_c.shape and np.mean(points_a != points_c) > 0.99
    # The world is the same for every noise seed.
    np.testing.assert_array_equal(
        first.ground_truth.landmarks.positions, other.ground_truth.landmarks.positions
    )


def test_stream_is_time_ordered_with_inertial_first_at_equal_times():
    sequence = load_scenario("aghili-rover", 0, SHORT)
    measurements = list(sequence.measurements())
    times = np.array([m.t for m in measurements])
    assert np.all(np.diff(times) >= 0)
    for previous, current in zip(measurements, measurements[1:]):
        if previous.t == current.t:
            assert not (isinstance(previous, LandmarkScan) and isinstance(current, ImuSample))
    assert (
        {m.sensor for m in measurements} == set(sequence.sensors) == {Sensor.IMU, Sensor.LANDMARKS}
    )
    planar = load_scenario("guerreiro-loop", 0, SHORT)
    assert planar.sensors == {Sensor.GYRO, Sensor.LANDMARKS} and planar.dimension == 2
    gyro = inertial_of(planar)[0]
    assert isinstance(gyro, GyroSample) and gyro.rate.shape == (1,)


def strapdown_final_error(sequence) -> tuple[float, float, float]:
    """Integrate noise-free IMU samples (second order: midpoint rotation, trapezoidal
    velocity, exact-for-linear position) from the true start; error at the end
    (position [m], velocity [m/s], rotation [rad])."""
    samples = inertial_of(sequence)
    t = np.array([m.t for m in samples])
    gyro = np.array([m.gyro for m in samples])
    accel = np.array([m.accel for m in samples])
    gravity = np.array([0.0, 0.0, -9.81])
    start = sequence.initial_state
    rotation = matrix_from_quat_wxyz(start.rotation)
    position, velocity = start.position.copy(), start.velocity.copy()
    for k in range(len(t) - 1):
        dt = t[k + 1] - t[k]
        next_rotation = rotation @ so3_exp(0.5 * (gyro[k] + gyro[k + 1]) * dt)
        a0, a1 = rotation @ accel[k] + gravity, next_rotation @ accel[k + 1] + gravity
        position = position + velocity * dt + (2 * a0 + a1) / 6 * dt**2
        velocity = velocity + 0.5 * (a0 + a1) * dt
        rotation = next_rotation
    truth = sequence.ground_truth
    true_rotation = matrix_from_quat_wxyz(truth.pose.rotations[-1])
    return (
        float(np.linalg.norm(position - truth.pose.positions[-1])),
        float(np.linalg.norm(velocity - truth.history.block(BlockName.VELOCITY).values[-1])),
        float(np.linalg.norm(so3_log(rotation.T @ true_rotation))),
    )


@pytest.mark.parametrize("scenario", ["aghili-rover", "circle", "static"])
def test_noise_free_imu_integrates_back_to_the_true_trajectory(scenario):
    sequence = load_scenario(
        scenario, 0, {"noise_scale": "0", "imu_rate_hz": "1000", "duration_s": "10"}
    )
    position_error, velocity_error, rotation_error = strapdown_final_error(sequence)
    assert position_error < 1e-4 and velocity_error < 1e-5 and rotation_error < 1e-6
    # At rest the accelerometer reads +9.81 along the world up axis.
    if scenario == "static":
        sample = inertial_of(sequence)[0]
        rotation = matrix_from_quat_wxyz(sequence.initial_state.rotation)
        np.testing.assert_allclose(rotation @ sample.accel, [0, 0, 9.81], atol=1e-12)


def test_noise_free_planar_gyro_integrates_to_the_true_heading():
    sequence = load_scenario(
        "guerreiro-loop", 0, {"noise_scale": "0", "gyro_rate_hz": "1000", "duration_s": "60"}
    )
    samples = inertial_of(sequence)
    t = np.array([m.t for m in samples])
    rate = np.array([m.rate[0] for m in samples])
    heading = sequence.initial_state.rotation + np.concatenate(
        [[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))]
    )
    truth = sequence.ground_truth.pose.rotations
    error = np.angle(np.exp(1j * (heading - truth)))
    assert np.max(np.abs(error)) < 1e-5
    # The planar velocity is the derivative of the position (central differences).
    positions = sequence.ground_truth.pose.positions
    velocity = sequence.ground_truth.history.block(BlockName.VELOCITY).values
    central = (positions[2:] - positions[:-2]) / (t[2:] - t[:-2])[:, None]
    assert np.max(np.abs(central - velocity[1:-1])) < 1e-5


def test_inertial_noise_has_the_stated_discrete_std():
    sequence = load_scenario(
        "static", 7, {"imu_rate_hz": "200", "duration_s": "60", "gyro_bias_sigma_rad_s": "0"}
    )
    samples = inertial_of(sequence)
    truth = sequence.ground_truth
    gyro = np.array([m.gyro for m in samples]) - truth.history.block(BlockName.GYRO_BIAS).values
    accel = np.array([m.accel for m in samples]) - truth.history.block(BlockName.ACCEL_BIAS).values
    rotation = matrix_from_quat_wxyz(truth.pose.rotations[0])
    accel -= rotation.T @ np.array([0.0, 0.0, 9.81])
    sigmas = kitti_imu_sigmas()
    assert sequence.noise.gyro_noise_density == sigmas["GyroscopeSigma"] == 1.75e-4
    assert sequence.noise.accel_noise_density == sigmas["AccelerometerSigma"] == 0.01
    np.testing.assert_allclose(
        np.std(gyro, axis=0), sigmas["GyroscopeSigma"] * np.sqrt(200), rtol=0.03
    )
    np.testing.assert_allclose(
        np.std(accel, axis=0), sigmas["AccelerometerSigma"] * np.sqrt(200), rtol=0.03
    )
    steps = np.diff(truth.history.block(BlockName.ACCEL_BIAS).values, axis=0)
    np.testing.assert_allclose(
        np.std(steps, axis=0), sigmas["AccelerometerBiasSigma"] * np.sqrt(1 / 200), rtol=0.05
    )
    np.testing.assert_array_equal(truth.history.block(BlockName.GYRO_BIAS).values[0], 0.0)


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_noise_free_landmarks_are_exactly_body_frame_positions(scenario):
    sequence = load_scenario(scenario, 1, {"noise_scale": "0", "duration_s": "30"})
    checked = 0
    for scan in scans_of(sequence):
        assert scan.points.shape == (scan.count, sequence.dimension)
        assert scan.covariances.shape == (scan.count, sequence.dimension, sequence.dimension)
        np.testing.assert_allclose(
            scan.points, true_body_points(sequence, scan, scan.ids), atol=1e-9
        )
        checked += scan.count
    assert checked > 100


def test_field_of_view_and_range_are_respected_and_complete():
    options = {
        "noise_scale": "0",
        "fov_deg": "90",
        "range_m": "12",
        "vertical_fov_deg": "20",
        "duration_s": "60",
    }
    sequence = load_scenario("aghili-rover", 2, options)
    truth = sequence.ground_truth
    for scan in scans_of(sequence):
        every = true_body_points(sequence, scan, truth.landmarks.ids)
        distance = np.linalg.norm(every, axis=1)
        azimuth = np.degrees(np.arctan2(every[:, 1], every[:, 0]))
        elevation = np.degrees(np.arctan2(every[:, 2], np.hypot(every[:, 0], every[:, 1])))
        expected = (
            (distance <= 12)
            & (distance >= 0.5)
            & (np.abs(azimuth) <= 45)
            & (np.abs(elevation) <= 10)
        )
        np.testing.assert_array_equal(np.sort(scan.ids), truth.landmarks.ids[expected])


def segments_cross(p, q, a, b) -> bool:
    """Independent scalar test: do segments pq and ab properly cross?"""

    def orient(u, v, w):
        return (v[0] - u[0]) * (w[1] - u[1]) - (v[1] - u[1]) * (w[0] - u[0])

    return orient(p, q, a) * orient(p, q, b) < 0 and orient(a, b, p) * orient(a, b, q) < 0


def test_walls_occlude_corners():
    sequence = load_scenario("guerreiro-loop", 0, {"noise_scale": "0"})
    plan = ring_corridor_building()
    truth = sequence.ground_truth
    pose_index = {round(t, 6): i for i, t in enumerate(truth.pose.t)}
    observed_pairs = 0
    for scan in scans_of(sequence)[::7]:
        sensor = truth.pose.positions[pose_index[round(scan.t, 6)]]
        for landmark_id in scan.ids:
            corner = plan.corners[landmark_id]
            shortened = corner - 1e-3 * (corner - sensor) / np.linalg.norm(corner - sensor)
            assert not any(segments_cross(sensor, shortened, a, b) for a, b in plan.walls)
            observed_pairs += 1
    assert observed_pairs > 500
    # From the middle of the bottom corridor, the top corners of the central block are behind it.
    central_block_top = [
        i
        for i, corner in enumerate(plan.corners)
        if 1.0 < corner[1] < 7.0 and corner[1] > 6.5 and 1.3 <= corner[0] <= 18.7
    ]
    assert central_block_top
    for scan in scans_of(sequence):
        sensor = truth.pose.positions[pose_index[round(scan.t, 6)]]
        if sensor[1] < 0.5 and 6.0 < sensor[0] < 14.0:
            assert not set(scan.ids) & set(central_block_top)
    counts = np.array([scan.count for scan in scans_of(sequence)])
    assert np.mean(counts >= 2) > 0.95
    # The vehicle itself never passes through a wall.
    path = truth.pose.positions[::5]
    assert not any(
        segments_cross(p, q, a, b) for p, q in zip(path, path[1:]) for a, b in plan.walls
    )


def whitened_errors(scenario: str, options: dict[str, str]) -> tuple[np.ndarray, int]:
    noisy = load_scenario(scenario, 5, options)
    errors = []
    for scan in scans_of(noisy):
        residual = scan.points - true_body_points(noisy, scan, scan.ids)
        errors.append(
            np.einsum("ki,kij,kj->k", residual, np.linalg.inv(scan.covariances), residual)
        )
    return np.concatenate(errors), noisy.dimension


@pytest.mark.parametrize("scenario", ["aghili-rover", "guerreiro-loop"])
def test_scan_covariance_matches_the_scatter(scenario):
    nees, dimension = whitened_errors(scenario, {})
    assert len(nees) > 10000
    # Mean of chi-square(d) is d with std sqrt(2 d / n); the planar laser model is
    # first-order (curved bearing noise), so allow a few per cent there.
    tolerance = 0.03 * dimension if dimension == 3 else 0.06 * dimension
    assert abs(np.mean(nees) - dimension) < tolerance


def test_aghili_rover_figures():
    sequence = load_scenario("aghili-rover", 0, {})
    truth = sequence.ground_truth
    speed = np.linalg.norm(truth.history.block(BlockName.VELOCITY).values, axis=1)
    duration = truth.pose.t[-1]
    assert 120 <= duration <= 240
    assert 0.9 <= np.mean(speed) <= 1.5 and np.min(speed) > 0.4
    assert np.all(truth.pose.positions[:, :2] >= 0) and np.all(
        truth.pose.positions[:, :2] <= [30, 60]
    )
    assert 1.0 < np.ptp(truth.pose.positions[:, 2]) < 6.0
    roll, pitch = [], []
    for matrix in truth.pose.rotation_matrices():
        pitch.append(-np.arcsin(matrix[2, 0]))
        roll.append(np.arctan2(matrix[2, 1], matrix[2, 2]))
    assert 2 < np.degrees(np.max(np.abs(pitch))) < 25 and 2 < np.degrees(np.max(np.abs(roll))) < 25
    assert np.diff(truth.pose.t)[0] == pytest.approx(1 / 20)
    sigmas = np.array(sequence.metadata["landmark_sigmas_m"])
    assert np.all((sigmas >= 0.1) & (sigmas <= 0.25)) and len(sigmas) == len(truth.landmarks)
    assert truth.history.block(BlockName.ACCEL_BIAS).values.shape == (len(truth.pose), 3)
    # Scans carry each landmark's own sigma: covariance sigma_i^2 I.
    scan = scans_of(sequence)[0]
    np.testing.assert_allclose(scan.covariances, sigmas[scan.ids][:, None, None] ** 2 * np.eye(3))


def test_anchor_order_starts_with_three_noncollinear_visible_landmarks():
    for scenario in SCENARIOS:
        sequence = load_scenario(scenario, 0, SHORT)
        first_scan = scans_of(sequence)[0]
        anchors = sequence.known_landmarks
        assert set(anchors.ids[:3]) <= set(first_scan.ids)
        assert sorted(anchors.ids) == sorted(sequence.ground_truth.landmarks.ids)
        a, b, c = anchors.positions[:3]
        u, v = b - a, c - a
        area = 0.5 * (
            np.linalg.norm(np.cross(u, v)) if len(u) == 3 else abs(u[0] * v[1] - u[1] * v[0])
        )
        assert area > 1.0


def test_guerreiro_loop_figures():
    sequence = load_scenario("guerreiro-loop", 0, {})
    truth = sequence.ground_truth
    positions = truth.pose.positions
    assert truth.pose.path_length() == pytest.approx(60.0, abs=0.5)
    speed = np.linalg.norm(truth.history.block(BlockName.VELOCITY).values, axis=1)
    assert np.mean(speed) == pytest.approx(0.4, abs=0.01) and np.ptp(speed) > 0.1
    # It passes its start again (loop closable) and ends a few metres past it.
    later = positions[len(positions) // 2 :]
    assert np.min(np.linalg.norm(later - positions[0], axis=1)) < 0.05
    assert np.linalg.norm(positions[-1] - positions[0]) < 10
    # Counterclockwise: the heading gains a full turn.
    headings = np.unwrap(truth.pose.rotations)
    assert headings[-1] - headings[0] == pytest.approx(2 * np.pi, abs=1e-6)
    # Early landmarks are seen again at the end.
    scans = scans_of(sequence)
    early = set(np.concatenate([scan.ids for scan in scans[:50]]))
    late = set(np.concatenate([scan.ids for scan in scans[-50:]]))
    assert len(early & late) >= 3
    assert truth.history.block(BlockName.GYRO_BIAS).values.shape == (len(truth.pose), 1)
    assert truth.body_velocity.values.shape == (len(truth.pose), 2)


def test_range_bearing_covariance_matches_monte_carlo_and_is_psd():
    rng = np.random.default_rng(0)
    rho, alpha, sigma_rho, sigma_alpha = 4.0, 0.7, 0.15, np.deg2rad(1.0)
    draws = 200000
    ranges = rho + sigma_rho * rng.standard_normal(draws)
    bearings = alpha + sigma_alpha * rng.standard_normal(draws)
    points = ranges[:, None] * np.column_stack([np.cos(bearings), np.sin(bearings)])
    covariance = range_bearing_covariance(
        np.array([rho]), np.array([alpha]), np.array([sigma_rho]), sigma_alpha
    )[0]
    np.testing.assert_allclose(np.cov(points.T), covariance, rtol=0.02, atol=1e-5)
    assert np.all(np.linalg.eigvalsh(covariance) > 0)


def test_ids_can_be_withheld_but_truth_keeps_them():
    sequence = load_scenario("guerreiro-loop", 2, {"ids": "false", "duration_s": "10"})
    scans = scans_of(sequence)
    assert all(scan.ids is None for scan in scans)
    truth_ids = sequence.ground_truth.scan_ids
    assert len(truth_ids) == len(scans)
    assert all(t == scan.t and len(ids) == scan.count for (t, ids), scan in zip(truth_ids, scans))
    # Withholding ids changes nothing else: same points, same noise.
    with_ids = scans_of(load_scenario("guerreiro-loop", 2, {"duration_s": "10"}))
    for withheld, shown, (_, true_ids) in zip(scans, with_ids, truth_ids, strict=True):
        np.testing.assert_array_equal(withheld.points, shown.points)
        np.testing.assert_array_equal(shown.ids, true_ids)


def test_empty_scans_are_emitted_with_zero_rows():
    sequence = load_scenario("static", 0, {"range_m": "1", "duration_s": "2"})
    scans = scans_of(sequence)
    assert len(scans) == 21
    assert all(
        scan.count == 0 and scan.points.shape == (0, 3) and scan.covariances.shape == (0, 3, 3)
        for scan in scans
    )
    figures = sequence_figures(sequence)
    assert (
        figures["scans"] == 21 and figures["visible_max"] == 0 and figures["path_length_m"] == 0.0
    )


@pytest.mark.parametrize(
    ("scenario", "options", "message"),
    [
        ("aghili-rover", {"colour": "red"}, "colour"),
        ("aghili-rover", {"duration_s": "-5"}, "duration_s"),
        ("guerreiro-loop", {"duration_s": "500"}, "duration_s"),
        ("circle", {"imu_rate_hz": "fast"}, "imu_rate_hz"),
        ("static", {"noise_scale": "-1"}, "noise_scale"),
        ("moon-walk", {}, "aghili-rover"),
    ],
)
def test_bad_options_raise_input_error(scenario, options, message):
    with pytest.raises(InputError, match=message):
        load_scenario(scenario, 0, options)


def test_metadata_is_plain_json_and_imu_densities_can_be_overridden():
    sequence = load_scenario("circle", 0, {"gyro_noise_density": "0.002", "duration_s": "1"})
    assert json.loads(json.dumps(sequence.metadata)) == sequence.metadata
    assert (
        sequence.metadata["source"] == "simulator"
        and sequence.metadata["options"]["gyro_noise_density"] == 0.002
    )
    assert sequence.noise.gyro_noise_density == 0.002 and sequence.noise.accel_noise_density == 0.01
    planar = load_scenario("guerreiro-loop", 0, {"duration_s": "1"})
    assert json.loads(json.dumps(planar.metadata)) == planar.metadata


def test_describe_lists_every_scenario_and_its_options():
    lines = describe_scenarios()
    for scenario in SCENARIOS:
        assert any(line.startswith(f"sim:{scenario}:") for line in lines)
    assert any("duration_s" in line for line in lines) and any(
        "landmark_rate_hz" in line for line in lines
    )


def test_corner_wall_directions_are_body_frame_unit_vectors():
    plan = ring_corridor_building()
    sequence = load_scenario(
        "guerreiro-loop", 0, {"directions": "true", "noise_scale": "0", "duration_s": "20"}
    )
    truth = sequence.ground_truth
    for scan in scans_of(sequence)[::10]:
        index = int(np.argmin(np.abs(truth.pose.t - scan.t)))
        rotation = truth.pose.rotation_matrices()[index]
        assert scan.directions.shape == (scan.count, 2, 2)
        expected = np.einsum("ji,kmj->kmi", rotation, plan.corner_directions[scan.ids])
        np.testing.assert_allclose(scan.directions, expected, atol=1e-12)
        # Each direction runs along a wall from the corner (to the adjacent corner).
        world = np.einsum("ij,kmj->kmi", rotation, scan.directions)
        assert np.all(np.abs(np.abs(world).max(axis=2) - 1.0) < 1e-9)
    noisy = load_scenario("guerreiro-loop", 0, {"directions": "true", "duration_s": "20"})
    angles = []
    for clean, dirty in zip(scans_of(sequence), scans_of(noisy)):
        cross = (
            clean.directions[..., 0] * dirty.directions[..., 1]
            - clean.directions[..., 1] * dirty.directions[..., 0]
        )
        dot = np.sum(clean.directions * dirty.directions, axis=2)
        angles.append(np.arctan2(cross, dot).ravel())
    assert np.degrees(np.std(np.concatenate(angles))) == pytest.approx(2.0, rel=0.05)
    assert all(
        scan.directions is None
        for scan in scans_of(load_scenario("guerreiro-loop", 0, {"duration_s": "2"}))
    )


@pytest.mark.parametrize(
    ("scenario", "extra"),
    [("aghili-rover", {}), ("guerreiro-loop", {}), ("guerreiro-loop", {"directions": "true"})],
)
def test_folder_is_byte_identical_per_seed_and_round_trips(scenario, extra, tmp_path):
    options = {"duration_s": "15", "ids": "false", **extra}
    first = write_sequence_folder(load_scenario(scenario, 1, options), tmp_path / "a")
    second = write_sequence_folder(load_scenario(scenario, 1, options), tmp_path / "b")
    other = write_sequence_folder(load_scenario(scenario, 2, options), tmp_path / "c")
    assert folder_digest(first) == folder_digest(second)
    assert (first / "README.md").is_file() and (first / "sequence.json").is_file()
    inertial_file = "imu.csv" if scenario == "aghili-rover" else "gyro.csv"
    assert (first / inertial_file).read_bytes() != (other / inertial_file).read_bytes()
    assert (first / "landmarks.csv").read_bytes() != (other / "landmarks.csv").read_bytes()

    original = load_scenario(scenario, 1, options)
    loaded = read_sequence_folder(first)
    assert loaded.name == original.name and loaded.dimension == original.dimension
    assert loaded.sensors == original.sensors and loaded.noise == original.noise
    assert loaded.metadata == original.metadata
    pairs = list(zip(original.measurements(), loaded.measurements(), strict=True))
    for expected, actual in pairs:
        assert type(expected) is type(actual) and expected.t == pytest.approx(actual.t, abs=1e-9)
        for array_expected, array_actual in zip(
            measurement_arrays(expected), measurement_arrays(actual), strict=True
        ):
            np.testing.assert_array_equal(array_expected, array_actual)
    truth, loaded_truth = original.ground_truth, loaded.ground_truth
    np.testing.assert_allclose(loaded_truth.pose.positions, truth.pose.positions, atol=1e-9)
    np.testing.assert_array_equal(loaded_truth.landmarks.positions, truth.landmarks.positions)
    for (t, ids), (loaded_t, loaded_ids) in zip(truth.scan_ids, loaded_truth.scan_ids, strict=True):
        assert t == pytest.approx(loaded_t, abs=1e-9)
        np.testing.assert_array_equal(ids, loaded_ids)
    for name in (BlockName.VELOCITY, BlockName.GYRO_BIAS):
        np.testing.assert_array_equal(
            loaded_truth.history.block(name).values, truth.history.block(name).values
        )
    np.testing.assert_array_equal(loaded.known_landmarks.ids, original.known_landmarks.ids)
    np.testing.assert_array_equal(loaded.initial_state.position, original.initial_state.position)


def test_reading_a_broken_folder_raises_input_error(tmp_path):
    folder = write_sequence_folder(load_scenario("static", 0, {"duration_s": "1"}), tmp_path / "s")
    with open(folder / "imu.csv", "a") as stream:
        stream.write("1.0,2.0\n")
    with pytest.raises(InputError, match="imu.csv"):
        read_sequence_folder(folder)
    with pytest.raises(InputError, match="sequence.json"):
        read_sequence_folder(tmp_path)


def test_guerreiro_random_speed_is_seeded_covers_the_loop_and_keeps_other_streams() -> None:
    """speed_profile=random: a different speed per seed, reproducible, the same 60 m path in
    the same time, lateral body velocity 0, and the sensor noise streams unchanged (the
    gyro noise of seed 3 is the same whatever the speed profile)."""
    from datasets.simulation.scenarios import load_scenario

    first = load_scenario("guerreiro-loop", 3, {"speed_profile": "random"})
    again = load_scenario("guerreiro-loop", 3, {"speed_profile": "random"})
    other = load_scenario("guerreiro-loop", 4, {"speed_profile": "random"})
    sinusoidal = load_scenario("guerreiro-loop", 3, {})
    speed = first.ground_truth.body_velocity.values
    np.testing.assert_array_equal(speed, again.ground_truth.body_velocity.values)
    assert np.abs(speed[:, 0] - other.ground_truth.body_velocity.values[:, 0]).max() > 0.01
    assert np.abs(speed[:, 1]).max() < 1e-12 and speed[:, 0].min() > 0.2
    np.testing.assert_allclose(
        first.ground_truth.pose.positions[-1], sinusoidal.ground_truth.pose.positions[-1], atol=1e-6
    )
    # increments of a random walk of density 0.02 m/s/sqrt(s) (mean reversion over 5 s is slow at 0.1 s)
    increments = np.diff(speed[:, 0])
    dt = np.diff(first.ground_truth.body_velocity.t)[0]
    assert 0.015 < np.std(increments) / np.sqrt(dt) < 0.025
    gyro_bias = first.ground_truth.history.block("gyro_bias").values
    np.testing.assert_array_equal(
        gyro_bias, sinusoidal.ground_truth.history.block("gyro_bias").values
    )


def test_niche_depth_sets_the_closest_corner_separation() -> None:
    def closest(plan) -> float:
        distances = np.linalg.norm(plan.corners[:, None] - plan.corners[None], axis=2)
        np.fill_diagonal(distances, np.inf)
        return float(distances.min())

    default, deep = ring_corridor_building(), ring_corridor_building(niche_depth_m=1.0)
    assert len(default.corners) == len(deep.corners) == 76
    assert closest(default) == pytest.approx(0.3)
    assert closest(deep) == pytest.approx(0.8)
    with pytest.raises(ValueError, match="niche depth"):
        ring_corridor_building(niche_depth_m=2.0)


def test_folder_keeps_the_nested_noise_models(tmp_path):
    """An odometry noise model and a sighting correlation model survive the folder format
    (``dataclasses.asdict`` writes them as mappings; they came back as plain dicts)."""
    from datasets.odometry_noise import OdometryNoiseModel
    from datasets.sighting_correlation import Autocorrelation, SightingCorrelation

    original = load_scenario("guerreiro-loop", 1, {"duration_s": "2"})
    odometry = OdometryNoiseModel(np.arange(9.0).reshape(3, 3) * 1e-4, "fitted somewhere")
    correlation = SightingCorrelation(Autocorrelation(0.9, 8.0), Autocorrelation(0.5, 3.0), "fit")
    noisy = dataclasses.replace(
        original,
        noise=dataclasses.replace(
            original.noise, odometry=odometry, sighting_correlation=correlation
        ),
    )
    loaded = read_sequence_folder(write_sequence_folder(noisy, tmp_path / "noise")).noise
    np.testing.assert_array_equal(loaded.odometry.rates, odometry.rates)
    assert loaded.odometry.source == odometry.source
    assert loaded.sighting_correlation == correlation
