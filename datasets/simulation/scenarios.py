"""Named, seeded simulation scenarios: ``sim:aghili-rover``, ``sim:guerreiro-loop``,
``sim:circle``, ``sim:static``.

``load_scenario(argument, seed, options)`` is the dataset loader the registry names.
In the 3-D scenarios the world layout (landmark positions, per-landmark sigmas) comes
from the ``layout_seed`` option (default 0); the corridor building of ``guerreiro-loop`` is
fixed. The sensor noise comes from ``seed``: Monte Carlo runs over seeds see the same world
with fresh noise. Independent generators per sensor mean that
changing one sensor's option does not change another sensor's noise.

Noise scale: ``noise_scale`` multiplies every drawn noise std (inertial white noise, bias
walks, initial biases, landmark noise). The stated noise (``NoiseSpec``, scan
covariances) is scaled alike, except at ``noise_scale=0``: the data are then noise-free
but the stated noise stays nominal, so estimators keep invertible covariances (NEES is
meaningless there).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.errors import InputError, did_you_mean
from datasets.laser2d.simulation import Laser2dScenarioOptions, laser2d_scenario
from datasets.options import describe_model, parse_options
from datasets.rotations import wrap_angle
from datasets.sequence import NoiseSpec, Sequence
from datasets.simulation.assembly import (
    SAMPLE_BYTES,
    SCAN_BYTES,
    SIGHTING_BYTES,
    OdometrySeries,
    SimulatedData,
    SizedStream,
    build_sequence,
    check_size,
    sample_times,
)
from datasets.simulation.floor_plan import ring_corridor_building
from datasets.simulation.imu import (
    KITTI_IMU_METADATA,
    InertialNoise,
    kitti_imu_sigmas,
    simulate_imu,
    simulate_planar_gyro,
)
from datasets.simulation.landmarks import (
    PAPER_LASER,
    UTM_30LX,
    ScanSeries,
    anchor_order,
    field_of_view_mask,
    isotropic_observations,
    line_of_sight_mask,
    planar_direction_observations,
    range_bearing_observations,
    to_body_frame,
)
from datasets.simulation.trajectories import (
    CircleMotion,
    Kinematics,
    LateralDrift,
    PlanarPathMotion,
    RandomSpeed,
    RoundedPolylinePath,
    SinusoidalSpeed,
    StaticMotion,
    Terrain,
    TerrainViaPointLoop,
)


class _CommonOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")

    duration_s: float | None = Field(
        None, gt=0, description="length of the sequence [s]; default: the scenario's own"
    )
    noise_scale: float = Field(
        1.0, ge=0, description="multiplies every noise std (0: noise-free data)"
    )
    ids: bool = Field(True, description="scans carry the true landmark ids (false: ids withheld)")
    landmark_rate_hz: float = Field(10.0, gt=0, le=1000, description="landmark scan rate [Hz]")
    range_m: float = Field(20.0, gt=0, description="maximum landmark range [m]")
    fov_deg: float = Field(
        360.0, gt=0, le=360, description="horizontal field of view centred on body x [deg]"
    )


class _SpatialOptions(_CommonOptions):
    layout_seed: int = Field(
        0, ge=0, description="seed of the world layout (landmarks, sigmas); noise uses --seed"
    )
    imu_rate_hz: float = Field(100.0, gt=0, le=10000, description="IMU rate [Hz]")
    vertical_fov_deg: float = Field(60.0, gt=0, le=180, description="vertical field of view [deg]")
    gyro_bias_sigma_rad_s: float = Field(
        1e-3, ge=0, description="std of the initial gyro bias [rad/s]"
    )
    accel_bias_sigma_m_s2: float = Field(
        0.05, ge=0, description="std of the initial accelerometer bias [m/s^2]"
    )
    gyro_noise_density: float | None = Field(
        None,
        ge=0,
        description="gyro white noise [rad/s/sqrt(Hz)]; default: KITTI GyroscopeSigma (gtsam Data)",
    )
    accel_noise_density: float | None = Field(
        None,
        ge=0,
        description="accelerometer white noise [m/s^2/sqrt(Hz)]; default: KITTI AccelerometerSigma",
    )
    gyro_bias_walk: float | None = Field(
        None,
        ge=0,
        description="gyro bias random walk [rad/s^2/sqrt(Hz)]; default: KITTI GyroscopeBiasSigma",
    )
    accel_bias_walk: float | None = Field(
        None,
        ge=0,
        description="accelerometer bias random walk [m/s^3/sqrt(Hz)]; default: KITTI AccelerometerBiasSigma",
    )


class AghiliRoverOptions(_SpatialOptions):
    imu_rate_hz: float = Field(20.0, gt=0, le=10000, description="IMU rate [Hz] (paper: 20 Hz)")
    speed_m_s: float = Field(1.0, gt=0, le=5, description="cruise speed along the via points [m/s]")
    landmark_count: int = Field(
        60, ge=3, le=10000, description="landmarks scattered over the terrain"
    )
    landmark_sigma_min_m: float = Field(
        0.1, ge=0, description="smallest per-landmark noise sigma [m]"
    )
    landmark_sigma_max_m: float = Field(
        0.25, ge=0, description="largest per-landmark noise sigma [m]"
    )


class CircleOptions(_SpatialOptions):
    duration_s: float | None = Field(60.0, gt=0, description="length of the sequence [s]")
    radius_m: float = Field(10.0, gt=0, description="circle radius [m]")
    speed_m_s: float = Field(2.0, gt=0, description="constant speed [m/s]")
    landmark_count: int = Field(30, ge=3, le=10000, description="landmarks around the circle")
    landmark_sigma_m: float = Field(0.1, ge=0, description="landmark noise sigma [m]")


class StaticOptions(_SpatialOptions):
    duration_s: float | None = Field(60.0, gt=0, description="length of the sequence [s]")
    landmark_count: int = Field(20, ge=3, le=10000, description="landmarks around the vehicle")
    landmark_sigma_m: float = Field(0.1, ge=0, description="landmark noise sigma [m]")


class GuerreiroLoopOptions(_CommonOptions):
    range_m: float = Field(30.0, gt=0, description="laser range [m] (Hokuyo UTM-30LX: 30 m)")
    laser: Literal["utm-30lx", "paper"] = Field(
        "utm-30lx",
        description="the laser noise drawn and stated: 'utm-30lx' the sensor's own (3/5 cm, 0.25 deg); "
        "'paper' the paper's filter tuning (0.15/0.25 m, 3.75 deg) drawn as if it were the sensor's",
    )
    landmark_noise: Literal["polar", "cartesian"] = Field(
        "polar",
        description="'polar': noise drawn in range and bearing (the laser); 'cartesian': drawn from the "
        "stated first-order covariance (exactly a Cartesian estimator's model, for calibration)",
    )
    landmark_conversion: Literal["unbiased", "first-order"] = Field(
        "unbiased",
        description="polar sightings to body points: the unbiased converted measurement with its "
        "covariance (Mo et al. 1998, Duan et al. 2004) or the plain conversion with J diag J^T",
    )
    fov_deg: float = Field(
        270.0, gt=0, le=360, description="laser field of view [deg] (UTM-30LX: 270)"
    )
    gyro_rate_hz: float = Field(
        10.0, gt=0, le=10000, description="rate gyro rate [Hz] (paper: synchronised with the laser)"
    )
    mean_speed_m_s: float = Field(0.4, gt=0, le=3, description="average speed [m/s] (paper: 0.4)")
    speed_profile: Literal["sinusoidal", "random"] = Field(
        "sinusoidal",
        description="'sinusoidal': +-30 % in five smooth cycles (the same for every seed); 'random': a seeded "
        "mean-reverting random walk of density speed_walk_m_s_sqrt_s (the paper's velocity model (2))",
    )
    speed_reversion_s: float | None = Field(
        5.0,
        gt=0,
        description="mean-reversion time of the random speed [s]; null: a pure random walk (exactly "
        "the model of eq. (2), for calibration; not rescaled, so the run must end before the path does)",
    )
    lateral_walk_m_s_sqrt_s: float = Field(
        0.0,
        ge=0,
        le=0.05,
        description="density of a lateral body-velocity random walk [m/s/sqrt(s)]: the vehicle slips "
        "sideways while heading along the path (0: it follows the path)",
    )
    speed_walk_m_s_sqrt_s: float = Field(
        0.02,
        ge=0,
        le=0.1,
        description="density of the random speed profile [m/s/sqrt(s)] (speed_profile=random)",
    )
    gyro_noise_density: float = Field(
        float(np.deg2rad(0.1)),
        ge=0,
        description="gyro white noise [rad/s/sqrt(Hz)] (MEMS grade, 0.1 deg/s/sqrt(Hz))",
    )
    gyro_bias_walk: float = Field(
        float(np.deg2rad(5.7e-5)),
        ge=0,
        description="gyro bias random walk [rad/s^2/sqrt(Hz)] (paper: 5.7e-5 deg/s)",
    )
    gyro_bias_sigma_rad_s: float = Field(
        5e-3, ge=0, description="std of the initial gyro bias [rad/s]"
    )
    niche_depth_m: float | None = Field(
        None,
        gt=0,
        le=1.2,
        description="depth of every door niche [m] (default: 0.3-0.45 m, corners individually ambiguous at the "
        "paper's laser noise; 1.0: corners >= 0.8 m apart)",
    )
    directions: bool = Field(
        False, description="scans carry each corner's two wall directions (body frame)"
    )
    direction_sigma_deg: float = Field(
        2.0, ge=0, description="std of the wall direction angle noise [deg] (the paper states none)"
    )
    odometry: bool = Field(
        False,
        description="also wheel odometry (not in the paper, which has none): the true relative pose "
        "between consecutive gyro samples (previous body frame) plus white noise of "
        "odometry_sigma_m on dx and dy and odometry_sigma_rad on dtheta, stated exactly "
        "(model-matched relative-pose odometry, for the estimators' odometry mode)",
    )
    odometry_sigma_m: float = Field(
        0.005, ge=0, description="std of dx and dy of each odometry increment [m]"
    )
    odometry_sigma_rad: float = Field(
        0.002, ge=0, description="std of dtheta of each odometry increment [rad]"
    )


def _noise_factors(noise_scale: float) -> tuple[float, float]:
    """(scale of drawn noise, scale of stated noise): stated stays nominal at 0."""
    return noise_scale, (noise_scale if noise_scale > 0 else 1.0)


def _generators(seed: int) -> dict[str, np.random.Generator]:
    """Independent generators per purpose, all from ``seed``."""
    # spawn keys are indices: adding a name at the end leaves the others' streams unchanged
    names = ("inertial", "landmarks", "spare", "initial", "motion", "drift", "odometry")
    children = np.random.SeedSequence(seed).spawn(len(names))
    return {name: np.random.default_rng(child) for name, child in zip(names, children)}


def _metadata(scenario: str, seed: int, options: BaseModel, **extra: object) -> dict[str, object]:
    return {
        "source": "simulator",
        "scenario": scenario,
        "seed": seed,
        "options": options.model_dump(mode="json"),
        **extra,
    }


def _duration_text(options: _CommonOptions, duration_s: float, default: str) -> str:
    """How the sequence's length was chosen, for ``check_size``'s message: the option as
    given, or the scenario's default and what it follows from."""
    if options.duration_s is not None:
        return f"duration_s={options.duration_s:g}"
    return f"duration_s (default {duration_s:.6g} s: {default})"


def _scan_stream(options: _CommonOptions, landmarks: int, count_option: str) -> SizedStream:
    """The landmark scans as ``check_size`` counts them: every landmark in every scan (the
    most the field of view can let through)."""
    return SizedStream(
        f"landmark_rate_hz={options.landmark_rate_hz:g} and {count_option}",
        options.landmark_rate_hz,
        SCAN_BYTES + landmarks * SIGHTING_BYTES,
    )


def _kitti_inertial_noise(options: _SpatialOptions) -> InertialNoise:
    """IMU densities: the options' where given, else the KITTI-equivalent ones read from
    gtsam's Data/KittiEquivBiasedImu_metadata.txt (Aghili's paper states no IMU grade)."""
    sigmas = kitti_imu_sigmas()

    def pick(value: float | None, kitti_name: str) -> float:
        return sigmas[kitti_name] if value is None else value

    return InertialNoise(
        gyro_noise_density=pick(options.gyro_noise_density, "GyroscopeSigma"),
        accel_noise_density=pick(options.accel_noise_density, "AccelerometerSigma"),
        gyro_bias_walk=pick(options.gyro_bias_walk, "GyroscopeBiasSigma"),
        accel_bias_walk=pick(options.accel_bias_walk, "AccelerometerBiasSigma"),
        gyro_bias_sigma_rad_s=options.gyro_bias_sigma_rad_s,
        accel_bias_sigma_m_s2=options.accel_bias_sigma_m_s2,
    )


def _noise_spec(
    noise: InertialNoise,
    landmark_sigma_m: float,
    rates: dict[str, float],
    planar: bool,
    options: _CommonOptions,
) -> NoiseSpec:
    return NoiseSpec(
        landmark_field_of_view_deg=options.fov_deg,
        landmark_range_m=options.range_m,
        gyro_noise_density=noise.gyro_noise_density,
        accel_noise_density=None if planar else noise.accel_noise_density,
        gyro_bias_walk=noise.gyro_bias_walk,
        accel_bias_walk=None if planar else noise.accel_bias_walk,
        gyro_bias_sigma_rad_s=noise.gyro_bias_sigma_rad_s,
        accel_bias_sigma_m_s2=None if planar else noise.accel_bias_sigma_m_s2,
        landmark_sigma_m=landmark_sigma_m,
        rate_hz=rates,
    )


def _spatial_scans(
    motion,
    times: np.ndarray,
    landmarks: np.ndarray,
    sigmas: np.ndarray,
    options: _SpatialOptions,
    rng: np.random.Generator,
) -> ScanSeries:
    """3-D scans: body-frame positions with isotropic per-landmark noise."""
    drawn, stated = _noise_factors(options.noise_scale)
    kinematics = motion.kinematics(times)
    points, covariances, ids = [], [], []
    for index in range(len(times)):
        body = to_body_frame(kinematics.rotation[index], kinematics.position[index], landmarks)
        visible = np.flatnonzero(
            field_of_view_mask(body, options.range_m, options.fov_deg, options.vertical_fov_deg)
        )
        measured, covariance = isotropic_observations(
            body[visible], sigmas[visible], drawn, stated, rng
        )
        points.append(measured)
        covariances.append(covariance)
        ids.append(visible.astype(int))
    return ScanSeries(t=times, points=tuple(points), covariances=tuple(covariances), ids=tuple(ids))


def _simulate_spatial(
    scenario: str,
    motion,
    duration_s: float,
    landmarks: np.ndarray,
    sigmas: np.ndarray,
    options: _SpatialOptions,
    seed: int,
    duration: str,
    **extra_metadata: object,
) -> Sequence:
    check_size(
        f"sim:{scenario} --data",
        duration_s,
        duration,
        [
            SizedStream(f"imu_rate_hz={options.imu_rate_hz:g}", options.imu_rate_hz, SAMPLE_BYTES),
            _scan_stream(options, len(landmarks), f"{len(landmarks)} landmarks"),
        ],
    )
    generators = _generators(seed)
    drawn, stated = _noise_factors(options.noise_scale)
    nominal = _kitti_inertial_noise(options)
    inertial_times = sample_times(duration_s, options.imu_rate_hz)
    kinematics = motion.kinematics(inertial_times)
    inertial = simulate_imu(
        kinematics, options.imu_rate_hz, nominal.scaled(drawn), generators["inertial"]
    )
    scan_times = sample_times(duration_s, options.landmark_rate_hz)
    scans = _spatial_scans(motion, scan_times, landmarks, sigmas, options, generators["landmarks"])
    start = motion.kinematics(np.zeros(1))
    start_body = to_body_frame(start.rotation[0], start.position[0], landmarks)
    visible_at_start = field_of_view_mask(
        start_body, options.range_m, options.fov_deg, options.vertical_fov_deg
    )
    data = SimulatedData(
        kinematics=kinematics,
        inertial=inertial,
        scans=scans,
        landmark_ids=np.arange(len(landmarks)),
        landmark_positions=landmarks,
        anchor_order=anchor_order(landmarks, visible_at_start, start.position[0]),
    )
    rates = {"imu": options.imu_rate_hz, "landmarks": options.landmark_rate_hz}
    noise = _noise_spec(
        nominal.scaled(stated), float(np.mean(sigmas)) * stated, rates, False, options
    )
    metadata = _metadata(
        scenario,
        seed,
        options,
        imu_noise_source=f"gtsam Data/{KITTI_IMU_METADATA}",
        **extra_metadata,
    )
    return build_sequence(
        f"sim:{scenario}", data, noise, options.ids, metadata, generators["initial"], drawn, stated
    )


# The Aghili case study world: a 30 x 60 m terrain (x across, y along) and seven via points.
ROVER_VIA_POINTS_XY = np.array(
    [[4.0, 4.0], [25.0, 6.0], [26.0, 24.0], [14.0, 32.0], [25.0, 51.0], [10.0, 56.0], [4.0, 31.0]]
)
ROVER_TERRAIN = Terrain(
    amplitudes_m=np.array([1.5, 0.7, 0.3]),
    wave_vectors=2 * np.pi * np.array([[1 / 60, 1 / 90], [-1 / 40, 1 / 45], [1 / 25, 1 / 20]]),
    phases_rad=np.array([0.4, 1.3, 2.2]),
)
TERRAIN_SIZE_M = (30.0, 60.0)


def aghili_rover(seed: int, options: AghiliRoverOptions) -> Sequence:
    """Aghili, "Lidar SLAM for Autonomous Driving Vehicles", section 5 case study: a rover
    at walking pace drives a closed loop through seven via points over a 30 x 60 m terrain
    with gentle slopes (heights within a few metres; pitch and roll follow the slope); IMU
    at 20 Hz with KITTI-equivalent sigmas (gtsam Data, the paper states none); landmarks
    scattered over the terrain (0.1..3 m above ground), observed as 3-D body-frame positions
    within range and field of view, each with its own sigma uniform in [0.1, 0.25] m (the
    paper's 0.1 < sigma_pi < 0.25), scan covariance sigma_i^2 I. Default duration: one lap.
    """
    if options.landmark_sigma_max_m < options.landmark_sigma_min_m:
        raise InputError("sim:aghili-rover: landmark_sigma_max_m must be >= landmark_sigma_min_m")
    motion = TerrainViaPointLoop(ROVER_VIA_POINTS_XY, options.speed_m_s, ROVER_TERRAIN)
    layout = np.random.default_rng([options.layout_seed, 1])
    width, length = TERRAIN_SIZE_M
    xy = layout.uniform([0.0, 0.0], [width, length], size=(options.landmark_count, 2))
    heights = ROVER_TERRAIN.height(xy) + layout.uniform(0.1, 3.0, size=options.landmark_count)
    sigmas = layout.uniform(
        options.landmark_sigma_min_m, options.landmark_sigma_max_m, size=options.landmark_count
    )
    duration = options.duration_s if options.duration_s is not None else motion.period_s
    return _simulate_spatial(
        "aghili-rover",
        motion,
        duration,
        np.column_stack([xy, heights]),
        sigmas,
        options,
        seed,
        _duration_text(options, duration, f"one lap at speed_m_s={options.speed_m_s:g}"),
        landmark_sigmas_m=[float(value) for value in sigmas],
        lap_duration_s=float(motion.period_s),
    )


def circle(seed: int, options: CircleOptions) -> Sequence:
    """A level constant-speed circle (radius 10 m, 2 m/s) with landmarks scattered 4..18 m
    from the centre, 1 m below to 3 m above the path plane; IMU with KITTI-equivalent sigmas."""
    motion = CircleMotion(np.zeros(3), options.radius_m, options.speed_m_s)
    layout = np.random.default_rng([options.layout_seed, 2])
    angles = layout.uniform(0, 2 * np.pi, options.landmark_count)
    radii = options.radius_m * layout.uniform(0.4, 1.8, options.landmark_count)
    landmarks = np.column_stack(
        [
            radii * np.cos(angles),
            radii * np.sin(angles),
            layout.uniform(-1, 3, options.landmark_count),
        ]
    )
    sigmas = np.full(options.landmark_count, options.landmark_sigma_m)
    duration = float(options.duration_s)
    return _simulate_spatial(
        "circle", motion, duration, landmarks, sigmas, options, seed, f"duration_s={duration:g}"
    )


def static(seed: int, options: StaticOptions) -> Sequence:
    """No motion: the vehicle rests at the origin, slightly tilted (yaw 30, pitch -3,
    roll 2 deg), with landmarks 3..15 m around it; IMU with KITTI-equivalent sigmas."""
    motion = StaticMotion(np.zeros(3), np.deg2rad(30.0), np.deg2rad(-3.0), np.deg2rad(2.0))
    layout = np.random.default_rng([options.layout_seed, 3])
    angles = layout.uniform(0, 2 * np.pi, options.landmark_count)
    radii = layout.uniform(3.0, 15.0, options.landmark_count)
    landmarks = np.column_stack(
        [
            radii * np.cos(angles),
            radii * np.sin(angles),
            layout.uniform(-1, 3, options.landmark_count),
        ]
    )
    sigmas = np.full(options.landmark_count, options.landmark_sigma_m)
    duration = float(options.duration_s)
    return _simulate_spatial(
        "static", motion, duration, landmarks, sigmas, options, seed, f"duration_s={duration:g}"
    )


LOOP_PATH_LENGTH_M = 60.0
LOOP_TURN_LENGTH_M = 3.0


def guerreiro_loop_motion(
    mean_speed_m_s: float,
    speed_walk_m_s_sqrt_s: float | None = None,
    rng: np.random.Generator | None = None,
    speed_reversion_s: float | None = 5.0,
    profile_s: float | None = None,
    lateral_walk_m_s_sqrt_s: float = 0.0,
    drift_rng: np.random.Generator | None = None,
) -> PlanarPathMotion:
    """The loop of Guerreiro et al. (2013) section V: start in the middle of the bottom
    corridor heading east, go counterclockwise round the ring corridor and on past the start
    until the path is 60 m long; corners rounded; speed 0.4 m/s on average, varying +-30 %
    in five smooth cycles, or, given ``speed_walk_m_s_sqrt_s`` and ``rng``, a random speed
    (``RandomSpeed``) with that density."""
    plan = ring_corridor_building()
    (x0, y0), (x1, _), (_, y1), _ = plan.corridor_centerline
    start = np.array([(x0 + x1) / 2, y0])
    vertices = [start, [x1, y0], [x1, y1], [x0, y1], [x0, y0]]
    lap = RoundedPolylinePath(np.array(vertices + [start]), LOOP_TURN_LENGTH_M)
    beyond = LOOP_PATH_LENGTH_M - lap.length_m
    path = RoundedPolylinePath(np.array(vertices + [start + [beyond, 0.0]]), LOOP_TURN_LENGTH_M)
    duration = path.length_m / mean_speed_m_s
    if profile_s is not None:
        duration = min(duration, profile_s)  # a pure random walk: drawn only as far as needed
    drift = None
    if lateral_walk_m_s_sqrt_s > 0.0:
        if drift_rng is None:
            raise ValueError("a lateral drift needs a generator")
        drift = LateralDrift(lateral_walk_m_s_sqrt_s, duration, drift_rng)
    if speed_walk_m_s_sqrt_s is None:
        return PlanarPathMotion(path, SinusoidalSpeed(mean_speed_m_s, 0.3, 5, duration), drift)
    if rng is None:
        raise ValueError("a random speed profile needs a generator")
    return PlanarPathMotion(
        path,
        RandomSpeed(mean_speed_m_s, speed_walk_m_s_sqrt_s, duration, rng, speed_reversion_s),
        drift,
    )


def relative_pose_odometry(
    kinematics: Kinematics,
    sigmas: np.ndarray,
    drawn: float,
    stated: float,
    rng: np.random.Generator,
) -> OdometrySeries:
    """Planar relative-pose odometry between consecutive truth samples: the true
    ``(dx, dy) = R_k^T (p_{k+1} - p_k)``, ``dtheta = theta_{k+1} - theta_k`` plus white noise
    of std ``sigmas * drawn`` (dx, dy, dtheta), stated as ``diag(sigmas * stated)^2``. The
    estimators compose ``p' = p + R u_xy``, ``theta' = theta + u_theta``, which is linear in
    the increment: the noise model is exactly theirs."""
    rotation = kinematics.rotation
    steps = np.einsum("kji,kj->ki", rotation[:-1], np.diff(kinematics.position, axis=0))
    headings = np.arctan2(rotation[:, 1, 0], rotation[:, 0, 0])
    turns = wrap_angle(np.diff(headings))
    true = np.column_stack([steps, turns])
    measured = true + rng.standard_normal(true.shape) * (np.asarray(sigmas) * drawn)
    return OdometrySeries(
        t=kinematics.t[1:].copy(),
        dt=np.diff(kinematics.t),
        increments=measured,
        covariance=np.diag((np.asarray(sigmas, float) * stated) ** 2),
    )


MOTION_GRID_BYTES = 64
"""Memory per point of the random speed and lateral drift profiles (a few float arrays on
their ``RandomSpeed.GRID_S`` grid)."""


def _check_loop_size(options: GuerreiroLoopOptions, walk: bool, corners: int) -> None:
    """``check_size`` for ``guerreiro_loop`` before anything is drawn: the random speed and
    drift profiles span the whole path (``duration_s`` for a pure walk), the samples the
    sequence."""
    context = "sim:guerreiro-loop --data"
    path_s = LOOP_PATH_LENGTH_M / options.mean_speed_m_s
    default = f"the {LOOP_PATH_LENGTH_M:g} m path at mean_speed_m_s={options.mean_speed_m_s:g}"
    if options.speed_profile == "random" or options.lateral_walk_m_s_sqrt_s > 0.0:
        span = options.duration_s if walk and options.duration_s is not None else path_s
        grid_hz = 1.0 / RandomSpeed.GRID_S
        check_size(
            context,
            span,
            f"a random profile of {span:.6g} s ({default})",
            [SizedStream(f"its {grid_hz:g} Hz grid", grid_hz, MOTION_GRID_BYTES)],
            limited="the profile",
        )
    duration = options.duration_s if options.duration_s is not None else path_s
    per_gyro = SAMPLE_BYTES * (2 if options.odometry else 1)  # odometry at the gyro's rate
    check_size(
        context,
        duration,
        _duration_text(options, duration, default),
        [
            SizedStream(f"gyro_rate_hz={options.gyro_rate_hz:g}", options.gyro_rate_hz, per_gyro),
            _scan_stream(options, corners, f"{corners} corners"),
        ],
    )


def guerreiro_loop(seed: int, options: GuerreiroLoopOptions) -> Sequence:
    """Guerreiro, Batista, Silvestre, Oliveira, "Globally Asymptotically Stable Sensor-Based
    SLAM", section V: a planar vehicle flies about 60 m round a ring corridor at 0.4 m/s on
    average and passes its start again, so early landmarks are seen again (loop closable).
    Landmarks are the wall corners (building corners and door niches). A laser (range 30 m,
    270 deg field of view, 10 Hz by default) sees a corner only with line of sight (walls
    occlude). Laser noise (``laser``): by default a Hokuyo UTM-30LX-class sensor's own
    (``landmarks.UTM_30LX``: 3 cm up to 10 m, 5 cm beyond, 0.25 deg); ``laser=paper`` draws
    the paper's filter tuning (sigma_alpha = 3.75 deg, sigma_rho = 0.15 m up to 10 m, 0.25 m
    beyond), which is a conservative tuning, not the laser. Drawn in range and bearing
    (``landmark_noise``) and converted by the unbiased converted measurement
    (``landmark_conversion``, ``datasets.range_bearing``). A rate gyro at the laser rate
    with bias (walk 5.7e-5 deg/s/sqrt(s) as the paper's sigma_br) and MEMS white noise. No
    odometry unless ``odometry=true`` (``relative_pose_odometry``, not in the paper). With ``directions=true`` each observed corner also carries the
    body-frame unit directions of its two walls (the paper's direction landmarks), each
    rotated by N(0, direction_sigma_deg^2) noise.
    """
    generators = _generators(seed)
    random_speed = options.speed_profile == "random"
    walk = random_speed and options.speed_reversion_s is None
    plan = ring_corridor_building(niche_depth_m=options.niche_depth_m)
    _check_loop_size(options, walk, len(plan.corners))
    try:
        motion = guerreiro_loop_motion(
            options.mean_speed_m_s,
            options.speed_walk_m_s_sqrt_s if random_speed else None,
            generators["motion"] if random_speed else None,
            options.speed_reversion_s,
            options.duration_s if walk else None,
            options.lateral_walk_m_s_sqrt_s,
            generators["drift"],
        )
    except ValueError as error:
        raise InputError(f"sim:guerreiro-loop seed {seed}: {error}") from None
    full = motion.duration_s if not walk else LOOP_PATH_LENGTH_M / options.mean_speed_m_s
    duration = options.duration_s if options.duration_s is not None else full
    if duration > full + 1e-9:
        raise InputError(
            f"sim:guerreiro-loop: duration_s={duration} exceeds the path's {full:.1f} s"
        )
    if random_speed and options.speed_reversion_s is None:
        travelled = float(motion.speed.evaluate(np.array([duration]))[0][0])
        if travelled > motion.path.length_m:
            raise InputError(
                f"sim:guerreiro-loop: with speed_reversion_s=null the walk of seed {seed} reaches "
                f"the end of the {motion.path.length_m:.0f} m path before t={duration:g} s: "
                "shorten duration_s"
            )
    drawn, stated = _noise_factors(options.noise_scale)
    nominal = InertialNoise(
        gyro_noise_density=options.gyro_noise_density,
        accel_noise_density=0.0,
        gyro_bias_walk=options.gyro_bias_walk,
        accel_bias_walk=0.0,
        gyro_bias_sigma_rad_s=options.gyro_bias_sigma_rad_s,
        accel_bias_sigma_m_s2=0.0,
    )
    gyro_times = sample_times(duration, options.gyro_rate_hz)
    kinematics = motion.kinematics(gyro_times)
    inertial = simulate_planar_gyro(
        kinematics, options.gyro_rate_hz, nominal.scaled(drawn), generators["inertial"]
    )

    laser = UTM_30LX if options.laser == "utm-30lx" else PAPER_LASER
    scan_times = sample_times(duration, options.landmark_rate_hz)
    scan_kinematics = motion.kinematics(scan_times)
    rng = generators["landmarks"]
    direction_rng = generators["spare"]
    points, covariances, ids, directions = [], [], [], []
    visible_at_start = None
    for index in range(len(scan_times)):
        position, rotation = scan_kinematics.position[index], scan_kinematics.rotation[index]
        body = to_body_frame(rotation, position, plan.corners)
        mask = field_of_view_mask(body, options.range_m, options.fov_deg)
        mask &= line_of_sight_mask(position, plan.corners, plan.walls)
        if index == 0:
            visible_at_start = mask
        visible = np.flatnonzero(mask)
        measured, covariance = range_bearing_observations(
            body[visible],
            laser,
            drawn,
            stated,
            rng,
            options.landmark_noise,
            options.landmark_conversion,
        )
        points.append(measured)
        covariances.append(covariance)
        ids.append(visible.astype(int))
        if options.directions:
            body_directions = plan.corner_directions[visible] @ rotation  # R^T u for each direction
            directions.append(
                planar_direction_observations(
                    body_directions, np.deg2rad(options.direction_sigma_deg), drawn, direction_rng
                )
            )
    scans = ScanSeries(
        t=scan_times,
        points=tuple(points),
        covariances=tuple(covariances),
        ids=tuple(ids),
        directions=tuple(directions) if options.directions else None,
    )
    data = SimulatedData(
        kinematics=kinematics,
        inertial=inertial,
        scans=scans,
        landmark_ids=np.arange(len(plan.corners)),
        landmark_positions=plan.corners,
        anchor_order=anchor_order(plan.corners, visible_at_start, scan_kinematics.position[0]),
        odometry=(
            relative_pose_odometry(
                kinematics,
                np.array([options.odometry_sigma_m] * 2 + [options.odometry_sigma_rad]),
                drawn,
                stated,
                generators["odometry"],
            )
            if options.odometry
            else None
        ),
    )
    rates = {"gyro": options.gyro_rate_hz, "landmarks": options.landmark_rate_hz}
    if options.odometry:
        rates["odometry"] = options.gyro_rate_hz
    noise = _noise_spec(
        nominal.scaled(stated), laser.near_range_sigma_m * stated, rates, True, options
    )
    metadata = _metadata(
        "guerreiro-loop",
        seed,
        options,
        path_length_m=float(motion.path.length_m),
        laser=options.laser,
        laser_bearing_sigma_deg=float(np.rad2deg(laser.bearing_sigma_rad)),
        laser_range_sigma_m={
            "up_to_10_m": laser.near_range_sigma_m,
            "beyond_10_m": laser.far_range_sigma_m,
        },
        landmark_measurement_model=(
            f"planar laser, noise drawn in range/bearing, {options.landmark_conversion} conversion"
            if options.landmark_noise == "polar"
            else "Cartesian noise drawn from the stated first-order covariance"
        ),
    )
    return build_sequence(
        "sim:guerreiro-loop",
        data,
        noise,
        options.ids,
        metadata,
        generators["initial"],
        drawn,
        stated,
    )


_SCENARIOS: dict[str, tuple[type[BaseModel], Callable[[int, BaseModel], Sequence], str]] = {
    "aghili-rover": (
        AghiliRoverOptions,
        aghili_rover,
        "Aghili sec. 5: 3-D rover loop through 7 via points on a 30x60 m sloped terrain, 1 m/s, IMU 20 Hz, landmarks 10 Hz, one lap 144 s",
    ),
    "guerreiro-loop": (
        GuerreiroLoopOptions,
        guerreiro_loop,
        "Guerreiro sec. V: 2-D 60 m corridor loop at 0.4 m/s (150 s), 76 wall corners, laser 10 Hz with line of sight, rate gyro 10 Hz",
    ),
    "circle": (
        CircleOptions,
        circle,
        "3-D level circle, r 10 m at 2 m/s, IMU 100 Hz + landmarks, 60 s",
    ),
    "static": (StaticOptions, static, "3-D vehicle at rest (tilted), IMU 100 Hz + landmarks, 60 s"),
    "laser2d": (
        Laser2dScenarioOptions,
        laser2d_scenario,
        "2-D laser scans (181 beams, 5 Hz) ray-cast in the guerreiro-loop building, odometry, corners by the CARMEN front end (datasets.laser2d), no ids",
    ),
}

SCENARIO_NAMES: tuple[str, ...] = tuple(_SCENARIOS)


def load_scenario(argument: str | None, seed: int, options: dict[str, str]) -> Sequence:
    """Simulate scenario ``argument`` with noise ``seed`` and ``--data`` options."""
    if argument not in _SCENARIOS:
        raise InputError(
            f"unknown simulation scenario '{argument}'{did_you_mean(argument, list(_SCENARIOS))} "
            f"(known: {', '.join(_SCENARIOS)})"
        )
    model, simulate, _ = _SCENARIOS[argument]
    parsed = parse_options(model, options, f"sim:{argument} --data")
    return simulate(int(seed), parsed)


def describe_scenarios() -> list[str]:
    """Lines for ``workbench list --verbose``: each scenario, then its options."""
    lines = []
    for name, (model, _, summary) in _SCENARIOS.items():
        lines.append(f"sim:{name}: {summary}")
        lines += [f"    {line}" for line in describe_model(model)]
    return lines
