"""The 3-D scenarios' shared part (``aghili-rover``, ``circle``, ``static``): their options
(IMU rate and noise, vertical field of view, world layout seed), the IMU noise with
KITTI-equivalent defaults, the 3-D landmark scans, and ``simulate_spatial``, which turns a
motion and a landmark layout into a ``Sequence``.

The world layout (landmark positions, per-landmark sigmas) comes from the ``layout_seed``
option (default 0), the sensor noise from ``seed``: Monte Carlo runs over seeds see the same
world with fresh noise.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from datasets.sequence import Sequence
from datasets.simulation.assembly import (
    SAMPLE_BYTES,
    SimulatedData,
    SizedStream,
    build_sequence,
    check_size,
    sample_times,
)
from datasets.simulation.imu import (
    KITTI_IMU_METADATA,
    InertialNoise,
    kitti_imu_sigmas,
    simulate_imu,
)
from datasets.simulation.landmarks import (
    ScanSeries,
    anchor_order,
    field_of_view_mask,
    isotropic_observations,
    to_body_frame,
)
from datasets.simulation.scenario_common import (
    CommonOptions,
    noise_factors,
    noise_spec,
    scan_stream,
    scenario_metadata,
    seeded_generators,
)


class SpatialOptions(CommonOptions):
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


def kitti_inertial_noise(options: SpatialOptions) -> InertialNoise:
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


def _spatial_scans(
    motion,
    times: np.ndarray,
    landmarks: np.ndarray,
    sigmas: np.ndarray,
    options: SpatialOptions,
    rng: np.random.Generator,
) -> ScanSeries:
    """3-D scans: body-frame positions with isotropic per-landmark noise."""
    drawn, stated = noise_factors(options.noise_scale)
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


def simulate_spatial(
    scenario: str,
    motion,
    duration_s: float,
    landmarks: np.ndarray,
    sigmas: np.ndarray,
    options: SpatialOptions,
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
            scan_stream(options, len(landmarks), f"{len(landmarks)} landmarks"),
        ],
    )
    generators = seeded_generators(seed)
    drawn, stated = noise_factors(options.noise_scale)
    nominal = kitti_inertial_noise(options)
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
    noise = noise_spec(
        nominal.scaled(stated), float(np.mean(sigmas)) * stated, rates, False, options
    )
    metadata = scenario_metadata(
        scenario,
        seed,
        options,
        imu_noise_source=f"gtsam Data/{KITTI_IMU_METADATA}",
        **extra_metadata,
    )
    return build_sequence(
        f"sim:{scenario}", data, noise, options.ids, metadata, generators["initial"], drawn, stated
    )
