"""The IMU deskew (datasets.lidar.imu_deskew) against closed forms, and its place in the
front end's stream (datasets.lidar.frontend_stream.with_front_end)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from datasets.lidar.frontend import LidarFrontEnd
from datasets.lidar.frontend_settings import FrontEndSettings
from datasets.lidar.frontend_stream import with_front_end
from datasets.lidar.imu_deskew import GyroBuffer, rotate_each
from datasets.measurements import ImuSample, LandmarkScan, Odometry, PointCloud


def _twist_matrix(velocity: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """4x4 se(3) element of a body twist (linear velocity, angular rate)."""
    matrix = np.zeros((4, 4))
    x, y, z = rate
    matrix[:3, :3] = [[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]]
    matrix[:3, 3] = velocity
    return matrix


def _buffer(times: np.ndarray, rates: np.ndarray) -> GyroBuffer:
    buffer = GyroBuffer()
    for t, rate in zip(times, rates, strict=True):
        buffer.add(float(t), rate)
    return buffer


def test_constant_twist_matches_the_se3_exponential() -> None:
    """Constant body rate and velocity: a point seen at s lands, in the sweep-end frame, at
    exp(-(t_e - s) xi) p (scipy's matrix exponential as the reference)."""
    rng = np.random.default_rng(3)
    rate = np.array([0.05, -0.1, 0.9])  # rad/s
    velocity = np.array([6.0, 0.3, -0.1])  # m/s
    imu_times = np.arange(-0.2, 0.3, 0.005)
    buffer = _buffer(imu_times, np.tile(rate, (len(imu_times), 1)))
    start, end = 0.0, 0.1
    motion = buffer.motion(start, end)
    point_times = rng.uniform(start, end, 200)
    points = rng.uniform(-20.0, 20.0, (200, 3))
    moved = motion.to_end(points, point_times, velocity)
    twist = _twist_matrix(velocity, rate)
    for point, t, result in zip(points, point_times, moved, strict=True):
        transform = expm(-(end - t) * twist)
        expected = transform[:3, :3] @ point + transform[:3, 3]
        # trapezoid on 5 ms knots: translation error O(h^2 |w| |v|), tens of micrometres
        assert np.linalg.norm(result - expected) < 5e-5


def test_a_changing_yaw_rate_is_integrated_not_held() -> None:
    """Yaw rate ramping 0 -> 1 rad/s over the sweep: the rotation at each knot is the
    integral of the rate (exact for a single axis), which a constant rate would miss."""
    imu_times = np.arange(-0.05, 0.2, 0.005)
    yaw_rate = np.clip(imu_times / 0.1, 0.0, 1.0)
    rates = np.column_stack([np.zeros_like(yaw_rate), np.zeros_like(yaw_rate), yaw_rate])
    motion = _buffer(imu_times, rates).motion(0.0, 0.1)
    # angle from s to the end: integral of t / 0.1 over [s, 0.1]
    expected = -(0.1**2 - motion.times**2) / (2 * 0.1)
    np.testing.assert_allclose(motion.rotation_vectors[:, 2], expected, atol=1e-9)
    np.testing.assert_allclose(motion.rotation_vectors[:, :2], 0.0, atol=1e-12)


def test_rotate_each_is_the_rotation_of_each_row() -> None:
    rng = np.random.default_rng(0)
    vectors = rng.normal(0.0, 1.0, (50, 3)) * np.r_[1e-12, 1e-3, 0.1, 2.0, 3.0].repeat(10)[:, None]
    points = rng.normal(0.0, 5.0, (50, 3))
    expected = Rotation.from_rotvec(vectors).apply(points)
    np.testing.assert_allclose(rotate_each(vectors, points), expected, atol=1e-12)


def test_coverage_needs_samples_at_both_ends() -> None:
    buffer = _buffer(np.arange(0.0, 0.1, 0.005), np.zeros((20, 3)))
    assert buffer.covers(0.0, 0.1)  # last sample 0.095, within 1.5 intervals of the end
    assert not buffer.covers(0.0, 0.12)
    assert not buffer.covers(-0.02, 0.09)
    gappy_times = np.r_[np.arange(0.0, 0.03, 0.005), np.arange(0.06, 0.1, 0.005)]
    gappy = _buffer(gappy_times, np.zeros((len(gappy_times), 3)))
    assert not gappy.covers(0.0, 0.1)  # 0.025 -> 0.06: seven intervals without a sample
    assert gappy.covers(0.065, 0.095)


def _sweep(t: float, rng: np.random.Generator) -> PointCloud:
    """A room-like cloud stamped at its sweep start, points over 0.1 s."""
    angles = np.linspace(-np.pi, np.pi, 720, endpoint=False)
    ranges = 8.0 / np.maximum(np.abs(np.cos(angles)), np.abs(np.sin(angles)))
    points = np.column_stack(
        [ranges * np.cos(angles), ranges * np.sin(angles), rng.uniform(-1.0, 1.0, 720)]
    )
    return PointCloud(t=t, points=points, point_times=np.linspace(0.0, 0.1, 720))


def _stream(rng: np.random.Generator, imu_gap: tuple[float, float] | None = None):
    """Clouds every 0.1 s stamped at their sweep start, IMU at 200 Hz (none in ``imu_gap``),
    in stamp order as the bag reader gives them: a cloud comes before the IMU samples of its
    sweep."""
    items = []
    for k in range(8):
        items.append((k * 0.1, 1, _sweep(k * 0.1, rng)))
    for t in np.arange(0.0, 0.9, 0.005):
        if imu_gap is None or not imu_gap[0] <= t <= imu_gap[1]:
            items.append((t, 0, ImuSample(t=float(t), gyro=np.zeros(3), accel=np.zeros(3))))
    return [item for *_, item in sorted(items, key=lambda row: (row[0], row[1]))]


def _settings(imu_deskew: bool) -> FrontEndSettings:
    return FrontEndSettings(
        imu_deskew=imu_deskew, confirm_corners=False, kiss={"max_range_m": 30.0}
    )


def test_held_clouds_keep_the_stream_ordered_and_the_same_on_every_pass() -> None:
    stream = _stream(np.random.default_rng(2))
    front_end = LidarFrontEnd(_settings(True))
    first = list(with_front_end(iter(stream), front_end))
    second = list(with_front_end(iter(stream), front_end))  # from the cache
    stamps = [item.t for item in first]
    assert stamps == sorted(stamps)
    assert [(type(a), a.t) for a in first] == [(type(b), b.t) for b in second]
    odometry = [item for item in first if isinstance(item, Odometry)]
    assert len(odometry) == 7 and front_end.imu_deskewed_frames == 8
    assert front_end.imu_deskew_warning() is None
    assert front_end.resolved()["deskew"] == "imu"
    # every IMU sample up to a frame's sweep end precedes its odometry and corners
    for index, item in enumerate(first):
        if isinstance(item, (Odometry, LandmarkScan)):
            assert all(
                not isinstance(later, ImuSample) or later.t >= item.t
                for later in first[index + 1 :]
            )


def test_frames_the_imu_misses_fall_back_and_are_counted() -> None:
    stream = _stream(np.random.default_rng(2), imu_gap=(0.32, 0.58))
    front_end = LidarFrontEnd(_settings(True))
    list(with_front_end(iter(stream), front_end))
    warning = front_end.imu_deskew_warning()
    assert front_end.imu_fallback_stamps == pytest.approx([0.3, 0.4, 0.5])
    assert warning is not None and "3 of 8 clouds" in warning and "t=0.300" in warning


def test_without_imu_deskew_the_stream_is_as_before() -> None:
    """imu_deskew off: clouds are not held, KISS-ICP deskews them itself."""
    stream = _stream(np.random.default_rng(2))
    front_end = LidarFrontEnd(_settings(False))
    items = list(with_front_end(iter(stream), front_end))
    assert front_end.imu_deskewed_frames == 0
    assert front_end.resolved()["deskew"] == "kiss-icp"
    assert sum(isinstance(item, Odometry) for item in items) == 7


def _kiss_yaw_errors(bag, imu_deskew: bool) -> tuple[np.ndarray, dict]:
    """KISS-ICP's per-frame yaw error against the bag's truth [deg], and the sequence's
    description (``Sequence.description``: its metadata, warnings and the pass's figures)."""
    from datasets.bags.bag_options import BagOptions
    from datasets.bags.source import bag_sequence
    from datasets.lidar.corner_truth import interpolate_poses
    from datasets.rotations import matrix_from_quat_wxyz, so3_exp, so3_log

    options = BagOptions(ground_truth_topic="/ground_truth", imu_deskew=imu_deskew)
    sequence, _ = bag_sequence(str(bag), options)
    truth = sequence.ground_truth.pose
    errors = []
    for item in sequence.measurements():
        if isinstance(item, Odometry):
            _, quaternions = interpolate_poses(truth, np.array([item.t - item.dt, item.t]))
            before, after = (matrix_from_quat_wxyz(q) for q in quaternions)
            error = (before.T @ after).T @ so3_exp(item.relative_pose[:3])
            errors.append(np.degrees(so3_log(error)[2]))
    return np.array(errors), sequence.description()


@pytest.mark.study
def test_imu_deskew_beats_constant_velocity_on_the_synthetic_bag(tmp_path) -> None:
    """The corridor bag turns at up to 31 deg/s: KISS-ICP's yaw error per frame with the
    IMU's rotation is well below that with its own constant-velocity deskew (seed 0, 8 s:
    0.017 against 0.044 deg RMS, benchmarks/bench_lidar_imu_deskew.py)."""
    from datasets.synthetic_lidar import write_lidar_bag

    bag = write_lidar_bag(tmp_path / "bag", 0, "ros2", {"duration_s": "8"})
    with_imu, metadata = _kiss_yaw_errors(bag, True)
    constant_velocity, _ = _kiss_yaw_errors(bag, False)
    assert metadata["kiss_icp"]["deskew"] == "imu"
    assert metadata["kiss_icp"]["imu_deskew_fallback_frames"] == 0
    assert not any("IMU deskew" in line for line in metadata["warnings"])
    rms_imu = float(np.sqrt(np.mean(with_imu**2)))
    rms_constant = float(np.sqrt(np.mean(constant_velocity**2)))
    assert rms_imu < 0.6 * rms_constant, (rms_imu, rms_constant)
