"""The named speed figures of ``workbench bench-speed``, measured in one process on
synthetic scenes (no data files): the filters' scan updates and propagation, the
sensor-based step, the smoothers' keyframe and finish, ekf-slam-mht's cost per hypothesis
against ekf-slam's per scan (a simulated loop without ids), and filterpy's dense EKF update on
the same matrices as an external anchor when filterpy is installed (it is not a
dependency).

Each function builds its scene once, then times only the step it names (median of
repetitions, wall clock). Small matrices on a shared 2-core machine are timed with one
BLAS thread (``OPENBLAS_NUM_THREADS=1``): the command says when that is not set.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from datasets.measurements import GyroSample, ImuSample, LandmarkScan, Sensor
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.state import Frame, LandmarkMap

SCAN_LANDMARKS = 10
"""Landmarks in one timed scan (the issue's "one scan of 10 landmarks")."""

_SIGMA_M = 0.05


def median_seconds(
    step: Callable[[], None], repetitions: int, setup: Callable[[], None] | None = None
) -> float:
    """Median wall-clock seconds of ``step`` over ``repetitions`` (``setup`` untimed before
    each)."""
    samples = []
    for _ in range(repetitions):
        if setup is not None:
            setup()
        start = time.perf_counter()
        step()
        samples.append(time.perf_counter() - start)
    return float(np.median(samples))


# ---------------------------------------------------------------------------- 3-D scenes


def _world_3d(count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` landmarks around the origin (5-30 m away, -1..3 m high), (count, 3)."""
    radius = rng.uniform(5.0, 30.0, count)
    angle = rng.uniform(-np.pi, np.pi, count)
    return np.column_stack(
        [radius * np.cos(angle), radius * np.sin(angle), rng.uniform(-1.0, 3.0, count)]
    )


def _imu_sequence(landmarks: np.ndarray, anchors: int) -> Sequence:
    """A static 3-D IMU + landmarks sequence (the stream is fed by hand)."""
    known = LandmarkMap(np.arange(anchors), landmarks[:anchors], None, Frame.WORLD)
    return Sequence(
        name="bench-speed 3-D",
        dimension=3,
        sensors=frozenset({Sensor.IMU, Sensor.LANDMARKS}),
        stream=lambda: iter(()),
        noise=NoiseSpec(
            gyro_noise_density=1e-3,
            accel_noise_density=1e-2,
            gyro_bias_walk=1e-5,
            accel_bias_walk=1e-4,
            gyro_bias_sigma_rad_s=1e-3,
            accel_bias_sigma_m_s2=1e-2,
        ),
        initial_state=InitialState(
            t=0.0,
            position=np.zeros(3),
            rotation=np.array([1.0, 0.0, 0.0, 0.0]),
            velocity=np.zeros(3),
        ),
        known_landmarks=known,
    )


def _scan_3d(
    t: float, landmarks: np.ndarray, ids: np.ndarray, rng: np.random.Generator
) -> LandmarkScan:
    """Body-frame sightings from the origin with identity attitude (the scene's pose)."""
    points = landmarks[ids] + rng.normal(0.0, _SIGMA_M, (len(ids), 3))
    covariances = np.repeat((_SIGMA_M**2 * np.eye(3))[None], len(ids), axis=0)
    return LandmarkScan(t=t, points=points, covariances=covariances, ids=np.asarray(ids))


def _imu(t: float) -> ImuSample:
    return ImuSample(t=t, gyro=np.array([0.0, 0.0, 0.01]), accel=np.array([0.0, 0.0, 9.81]))


def _aghili_with_map(landmark_count: int, rng: np.random.Generator):
    """An Aghili filter with ``landmark_count`` landmarks in its state (3 anchors besides)."""
    from filters.aghili.filter import AghiliConfig, AghiliFilter

    anchors = 3
    world = _world_3d(landmark_count + anchors, rng)
    config = AghiliConfig(adaptive_noise=False, snapshot_interval_s=1e9)
    aghili = AghiliFilter(config, _imu_sequence(world, anchors))
    aghili.process(_imu(0.0))
    aghili.process(_scan_3d(0.0, world, np.arange(len(world)), rng))
    assert len(aghili.landmark_ids) == landmark_count
    return aghili, world


def aghili_update_ms(landmarks: int = 200, repetitions: int = 30) -> float:
    """One scan of ``SCAN_LANDMARKS`` known landmarks (by ids), 3-D, ``landmarks`` in state:
    association, the stacked update (Aghili eqs. (40a)-(40c)) and recording [ms]."""
    rng = np.random.default_rng(0)
    aghili, world = _aghili_with_map(landmarks, rng)
    seen = np.arange(3, 3 + SCAN_LANDMARKS)
    scan = _scan_3d(0.0, world, seen, rng)
    saved = (
        aghili.P.copy(),
        aghili.q.copy(),
        aghili.r.copy(),
        aghili.v.copy(),
        aghili.b_g.copy(),
        aghili.b_a.copy(),
        aghili.rho.copy(),
    )

    def restore() -> None:
        np.copyto(aghili.P, saved[0])
        aghili.q, aghili.r, aghili.v, aghili.b_g, aghili.b_a, aghili.rho = (
            a.copy() for a in saved[1:]
        )

    return 1e3 * median_seconds(lambda: aghili.process(scan), repetitions, restore)


def aghili_propagate_us(landmarks: int, samples: int = 300) -> float:
    """One strap-down IMU step (Aghili eqs. (34)-(41)) with ``landmarks`` in state [us]."""
    rng = np.random.default_rng(0)
    aghili, _ = _aghili_with_map(landmarks, rng)
    stamps = iter(0.01 * np.arange(1, samples + 1))
    return 1e6 * median_seconds(lambda: aghili.process(_imu(next(stamps))), samples)


def ekf_slam_update_ms(landmarks: int = 200, repetitions: int = 30) -> float:
    """ekf-slam (3-D, gyro-driven) with ``landmarks`` in state: one scan of
    ``SCAN_LANDMARKS`` known landmarks (association, stacked update, recording) [ms]."""
    from filters.ekf_slam.config import EkfSlamConfig
    from filters.ekf_slam.filter import EkfSlam

    rng = np.random.default_rng(0)
    world = _world_3d(landmarks, rng)
    ekf = EkfSlam(EkfSlamConfig(snapshot_interval_s=1e9), _imu_sequence(world, 3))
    ekf.process(_imu(0.0))
    ekf.process(_scan_3d(0.0, world, np.arange(landmarks), rng))
    assert len(ekf.map_ids) == landmarks
    scan = _scan_3d(0.0, world, np.arange(SCAN_LANDMARKS), rng)
    saved = (ekf.covariance.copy(), ekf.vehicle, ekf.landmarks.copy())

    def restore() -> None:
        np.copyto(ekf.covariance, saved[0])
        ekf.vehicle, ekf.landmarks = saved[1], saved[2].copy()

    return 1e3 * median_seconds(lambda: ekf.process(scan), repetitions, restore)


def filterpy_update_ms(landmarks: int = 200, repetitions: int = 10) -> float | None:
    """filterpy's dense ``ExtendedKalmanFilter.update`` on the Aghili scene's P (15 + 3n)
    and the same scan's H (the anchor of the update figures) [ms]; None without filterpy."""
    try:
        from filterpy.kalman import ExtendedKalmanFilter
    except ImportError:
        return None
    from filters.aghili import quaternion_jpl as quat
    from filters.aghili.measurement import predict, sparse_sensitivity

    rng = np.random.default_rng(0)
    aghili, world = _aghili_with_map(landmarks, rng)
    seen = np.arange(3, 3 + SCAN_LANDMARKS)
    scan = _scan_3d(0.0, world, seen, rng)
    attitude = quat.rotation_matrix(aghili.q)
    rows = aghili.registry.order(seen)  # the landmarks' places among the estimated ones
    predicted = predict(attitude, aghili.r, aghili.rho[rows])
    size = aghili.P.shape[0]
    H = sparse_sensitivity(attitude, predicted, aghili.registry, seen).dense(size)
    R = np.kron(np.eye(SCAN_LANDMARKS), _SIGMA_M**2 * np.eye(3))
    dense = ExtendedKalmanFilter(dim_x=size, dim_z=H.shape[0])

    def setup() -> None:
        dense.x = np.zeros((size, 1))
        dense.P = aghili.P.copy()

    def step() -> None:
        dense.update(
            scan.points.reshape(-1, 1), lambda _: H, lambda _: predicted.reshape(-1, 1), R=R
        )

    return 1e3 * median_seconds(step, repetitions, setup)


# ---------------------------------------------------------------------------- 2-D scene


def sensor_based_step_ms(landmarks: int, steps: int = 40) -> float:
    """The sensor-based filter (2-D, ids) with ``landmarks`` in state: one 0.1 s step = a
    gyro prediction (two 0.05 s sub-steps, eq. (10)) and a scan of ``SCAN_LANDMARKS``
    landmarks (association, update, management, Earth frame) [ms]."""
    from filters.sensor_based.config import SensorBasedConfig
    from filters.sensor_based.filter import SensorBasedSlam

    rng = np.random.default_rng(0)
    radius = rng.uniform(2.0, 15.0, landmarks)
    angle = rng.uniform(-np.pi, np.pi, landmarks)
    world = np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])
    sequence = Sequence(
        name="bench-speed 2-D",
        dimension=2,
        sensors=frozenset({Sensor.GYRO, Sensor.LANDMARKS}),
        stream=lambda: iter(()),
        noise=NoiseSpec(gyro_noise_density=1e-3, gyro_bias_sigma_rad_s=0.01),
        initial_state=InitialState(
            t=0.0, position=np.zeros(2), rotation=np.array(0.0), velocity=np.zeros(2)
        ),
    )
    config = SensorBasedConfig(
        max_landmarks=landmarks, in_view_range_m=1.0, min_observations=1, snapshot_interval_s=1e9
    )
    sensor_based = SensorBasedSlam(config, sequence)
    covariance = np.repeat((_SIGMA_M**2 * np.eye(2))[None], landmarks, axis=0)
    rate = np.array([0.05])
    sensor_based.process(GyroSample(t=0.0, rate=rate))
    sensor_based.process(
        LandmarkScan(t=0.0, points=world.copy(), covariances=covariance, ids=np.arange(landmarks))
    )
    heading = 0.0

    def step(k: int) -> None:
        nonlocal heading
        t = 0.1 * k
        heading = 0.05 * t
        rotation = np.array(
            [[np.cos(heading), -np.sin(heading)], [np.sin(heading), np.cos(heading)]]
        )
        seen = rng.choice(landmarks, SCAN_LANDMARKS, replace=False)
        points = world[seen] @ rotation + rng.normal(0.0, _SIGMA_M, (SCAN_LANDMARKS, 2))
        sensor_based.process(GyroSample(t=t, rate=rate))
        sensor_based.process(
            LandmarkScan(t=t, points=points, covariances=covariance[:SCAN_LANDMARKS], ids=seen)
        )

    counter = iter(range(1, steps + 1))
    seconds = median_seconds(lambda: step(next(counter)), steps)
    assert len(sensor_based.state.landmark_ids()) == landmarks
    return 1e3 * seconds


def loop_without_ids_scan_ms(estimator: str, repetitions: int = 1) -> float:
    """``estimator`` (a planar registered name) on ``sim:guerreiro-loop`` without ids (5 s,
    seed 0, 51 scans, the corners of its door niches ambiguous): wall time of the whole run
    per scan [ms], the median of ``repetitions`` runs; for ``ekf-slam-mht`` divided further
    by the hypotheses kept on average (the ``hypotheses`` extra), i.e. the cost of one
    hypothesis over one scan."""
    from workbench.registry import load_dataset
    from workbench.runner import RunRequest, execute

    name = "sim:guerreiro-loop"
    warm_up = load_dataset(name, 0, {"duration_s": "0.5", "ids": "false"})
    execute(RunRequest(estimator, name), sequence=warm_up)  # imports, first-call costs
    sequence = load_dataset(name, 0, {"duration_s": "5", "ids": "false"})
    estimates = []  # the runs are deterministic: the same scans and hypotheses every time
    seconds = median_seconds(
        lambda: estimates.append(execute(RunRequest(estimator, name), sequence=sequence).estimate),
        repetitions,
    )
    diagnostics = estimates[-1].diagnostics
    per_scan = seconds / max(1, len(diagnostics.landmark_count_t))
    kept = diagnostics.extras.get("hypotheses")
    if kept is not None:
        per_scan /= float(np.mean(np.asarray(kept)[:, 1]))
    return 1e3 * per_scan


def figures(include: set[str] | None = None) -> dict[str, float | None]:
    """Every named figure (``include``: only these keys), in the issue's vocabulary."""

    def smoother(name: str, *args: object) -> Callable[[], float]:
        def measure() -> float:
            from workbench.speed import smoothers as smoother_speed  # GTSAM only when asked

            return getattr(smoother_speed, name)(*args)

        return measure

    measurements: dict[str, Callable[[], float | None]] = {
        "aghili_update_ms": lambda: aghili_update_ms(200),
        "ekf_slam_update_ms": lambda: ekf_slam_update_ms(200),
        "filterpy_update_ms": lambda: filterpy_update_ms(200),
        "aghili_propagate_us_n10": lambda: aghili_propagate_us(10),
        "aghili_propagate_us_n200": lambda: aghili_propagate_us(200),
        "sensor_based_step_ms_n200": lambda: sensor_based_step_ms(200),
        "sensor_based_step_ms_n400": lambda: sensor_based_step_ms(400),
        "isam2_keyframe_ms_n200": smoother("isam2_keyframe_ms", 200, "CHOLESKY"),
        "isam2_keyframe_ms_n200_qr": smoother("isam2_keyframe_ms", 200, "QR"),
        "smoother_finish_s_n200": smoother("smoother_finish_s", 200),
        # the anchor is cheap (0.1 s a run) and scatters: median of 9; one 8 s run of the MHT
        "ekf_slam_scan_ms_loop": lambda: loop_without_ids_scan_ms("ekf-slam", 9),
        "ekf_slam_mht_hypothesis_scan_ms_loop": lambda: loop_without_ids_scan_ms("ekf-slam-mht"),
    }
    found: dict[str, float | None] = {}
    for key, measure in measurements.items():
        if include is None or key in include:
            found[key] = measure()
    return found
