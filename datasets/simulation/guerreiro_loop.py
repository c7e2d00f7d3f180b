"""The ``guerreiro-loop`` scenario (Guerreiro et al. 2013, section V): its options, the
size check made before anything is drawn, and its builder, which draws the rate gyro and
assembles the loop's motion (``guerreiro_motion``) and sensors (``guerreiro_sensors``) into
a ``Sequence``. The corridor building is fixed; the noise comes from ``seed``."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from datasets.errors import InputError
from datasets.sequence import Sequence
from datasets.simulation.assembly import (
    SAMPLE_BYTES,
    SimulatedData,
    SizedStream,
    build_sequence,
    check_size,
    sample_times,
)
from datasets.simulation.floor_plan import ring_corridor_building
from datasets.simulation.guerreiro_motion import LOOP_PATH_LENGTH_M, guerreiro_loop_motion
from datasets.simulation.guerreiro_sensors import corner_scans, relative_pose_odometry
from datasets.simulation.imu import InertialNoise, simulate_planar_gyro
from datasets.simulation.landmarks import PAPER_LASER, UTM_30LX, anchor_order
from datasets.simulation.scenario_common import (
    CommonOptions,
    duration_text,
    noise_factors,
    noise_spec,
    scan_stream,
    scenario_metadata,
    seeded_generators,
)
from datasets.simulation.trajectories import RandomSpeed


class GuerreiroLoopOptions(CommonOptions):
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
        duration_text(options, duration, default),
        [
            SizedStream(f"gyro_rate_hz={options.gyro_rate_hz:g}", options.gyro_rate_hz, per_gyro),
            scan_stream(options, corners, f"{corners} corners"),
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
    generators = seeded_generators(seed)
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
    drawn, stated = noise_factors(options.noise_scale)
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
    scans, visible_at_start = corner_scans(
        plan,
        scan_times,
        scan_kinematics,
        laser,
        options,
        drawn,
        stated,
        generators["landmarks"],
        generators["spare"],
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
    noise = noise_spec(
        nominal.scaled(stated), laser.near_range_sigma_m * stated, rates, True, options
    )
    metadata = scenario_metadata(
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
