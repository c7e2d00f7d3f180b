"""Options of the sensor-based filter (``--set key=value``; defaults: the paper's section V
where it gives one)."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import ConfigDict, Field

from datasets.estimator_options import AssociationOptions, RecordingOptions, for_estimator
from datasets.model_options import (
    GapOptions,
    GyroNoiseOptions,
    InitialPriorOptions,
    IntervalRateOptions,
    LandmarkFieldOfViewOptions,
    LandmarkProbationOptions,
    LandmarkWalkOptions,
    OdometryLateralOptions,
    OdometryOptions,
    VelocityWalkOptions,
)

DEG = math.pi / 180.0

PAPER_BEARING_SIGMA_RAD = 3.75 * DEG
"""Guerreiro et al. (2013), section V: sigma_alpha of the filter's laser model."""
PAPER_RANGE_SIGMA_M = (0.15, 0.25)
"""Section V: sigma_rho up to ``PAPER_RANGE_SWITCH_M``, and beyond."""
PAPER_RANGE_SWITCH_M = 10.0
PAPER_GYRO_BIAS_WALK_RAD_S_SQRT_S = 5.7e-5 * DEG
"""Section V: sigma_br, the gyro-bias random walk [rad/s/sqrt(s)]."""
PAPER_LANDMARK_SIGMA_M = 0.05
"""Section V: sigma_p, the landmark disturbance [m/sqrt(s)] of the paper's tuning."""


class SensorBasedConfig(
    AssociationOptions,
    RecordingOptions,
    VelocityWalkOptions,
    GyroNoiseOptions,
    LandmarkWalkOptions,
    InitialPriorOptions,
    IntervalRateOptions,
    GapOptions,
    LandmarkFieldOfViewOptions,
    LandmarkProbationOptions,
    OdometryOptions,
    OdometryLateralOptions,
):
    """Options of the sensor-based filter (defaults: the paper's section V where it gives one;
    association, snapshot, motion-noise, prior, gap and landmark options: the shared
    vocabulary of ``datasets.estimator_options`` and ``datasets.model_options``)."""

    model_config = ConfigDict(extra="forbid")

    gyro_bias_walk_rad_s_sqrt_s: float | None = for_estimator(
        GyroNoiseOptions,
        "gyro_bias_walk_rad_s_sqrt_s",
        "default: the paper's sigma_br, 5.7e-5 deg/s/sqrt(s) (section V), not the dataset's "
        "value; None: the dataset's, the paper's where it states none",
        default=PAPER_GYRO_BIAS_WALK_RAD_S_SQRT_S,
    )
    gyro_noise_density_rad_s_sqrt_hz: float | None = for_estimator(
        GyroNoiseOptions,
        "gyro_noise_density_rad_s_sqrt_hz",
        "injected into the landmarks through G; 0 where the dataset states none",
    )
    landmark_walk_m_sqrt_s: float | None = for_estimator(
        LandmarkWalkOptions,
        "landmark_walk_m_sqrt_s",
        "sigma_p; None: 0 with tuning=stated (the landmarks of every dataset are static, and "
        "the gyro noise already reaches them through G), the paper's 0.05 with tuning=paper",
    )
    direction_walk_per_sqrt_s: float = Field(
        0.01,
        ge=0,
        description="random walk of direction features (process noise) [1/sqrt(s)]: a unit "
        "direction's std grows by this per sqrt(second)",
    )
    initial_velocity_sigma_m_s: float | None = for_estimator(
        InitialPriorOptions,
        "initial_velocity_sigma_m_s",
        "of the body velocity; 2 m/s where the dataset's initial state has no velocity",
    )
    initial_gyro_bias_sigma_rad_s: float | None = for_estimator(
        InitialPriorOptions,
        "initial_gyro_bias_sigma_rad_s",
        "0.05 where the dataset states none (a bias of unknown size); 1e-4 when the rate "
        "comes from odometry, which has no bias",
    )
    initial_position_sigma_m: float | None = for_estimator(
        InitialPriorOptions,
        "initial_position_sigma_m",
        "of the Earth-frame pose (earth_frame): the robocentric state has no position",
    )
    initial_rotation_sigma_rad: float | None = for_estimator(
        InitialPriorOptions,
        "initial_rotation_sigma_rad",
        "of the Earth-frame pose (earth_frame): the robocentric state has no attitude",
    )
    initial_velocity_error_m_s: list[float] | None = Field(
        None,
        description="added to the dataset's initial body velocity (to show convergence from a wrong guess)",
    )
    initial_gyro_bias_rad_s: list[float] | None = Field(
        None, description="initial bias guess (default zero)"
    )
    association_window_s: float = Field(
        20.0,
        gt=0,
        description="associate only landmarks seen within this many seconds (the paper's I_cur)",
    )
    use_directions: bool = Field(
        False, description="use the scan's line directions as direction landmarks"
    )
    direction_sigma_rad: float = Field(
        2.0 * DEG, gt=0, description="std of a measured line direction [rad]"
    )
    discretization: Literal["exact", "euler"] = Field(
        "exact",
        description="'exact': the model solved over each step with held inputs (F = expm(A Ts)); 'euler': "
        "eq. (10) as printed (dilates landmarks by (omega Ts)^2/2 per step: a speed bias after turns)",
    )
    max_step_s: float = Field(
        0.05, gt=0, description="longest prediction step; longer gaps are sub-stepped"
    )
    max_gap_s: float = for_estimator(
        GapOptions,
        "max_gap_s",
        "60, a gap between any inputs: its model propagates across a gap in max_step_s steps "
        "and its velocity walk widens the covariance as it goes (the CARMEN intel.clf "
        "odometry stops for 3.5 s)",
        default=60.0,
    )
    in_view_range_m: float = Field(
        5.0, gt=0, description="landmarks predicted within this range should be seen [m]"
    )
    max_missed_in_view: int = Field(
        100, ge=1, description="consecutive in-view misses before deletion"
    )
    min_observations: int = for_estimator(
        LandmarkProbationOptions,
        "min_observations",
        "3, with probation_s 3 s: the sensor-based landmark management's deletion of "
        "intermittent or spurious landmarks since the first sensor-based filter",
        default=3,
    )
    probation_s: float | None = for_estimator(
        LandmarkProbationOptions,
        "probation_s",
        "3, with min_observations 3",
        default=3.0,
    )
    max_landmarks: int = Field(200, ge=1, description="cap on landmarks in the state")
    loop_closing: bool = Field(
        True,
        description="search for loop closures between the current and old landmark sets (IV-C)",
    )
    loop_old_after_s: float = Field(
        60.0, gt=0, description="landmarks unseen for longer than this form the old set I_old [s]"
    )
    loop_min_pairs: int = Field(
        5,
        ge=1,
        description="jointly compatible pairs needed to close a loop (3-4 let one-niche-off matches through on sim:guerreiro-loop)",
    )
    loop_every_s: float = Field(2.0, gt=0, description="how often to search for a loop closure [s]")
    loop_max_old_sigma_m: float = Field(
        1.5,
        gt=0,
        description="old landmarks whose largest position std exceeds this are not loop candidates: a constellation match among landmarks this uncertain is not distinctive [m]",
    )
    loop_unambiguous_only: bool = Field(
        True,
        description="reject a loop closure when a second, disjoint constellation match of min_pairs pairs exists",
    )
    tuning: Literal["stated", "paper"] = Field(
        "stated",
        description="'stated': the scans' own covariances (the sensor model the data states) "
        "and static landmarks (sigma_p 0); 'paper': the paper's section V tuning, its laser "
        "model (sigma_alpha = 3.75 deg, sigma_rho = 0.15 m to 10 m and 0.25 m beyond, first "
        "order at the measured range and bearing; 2-D only; a conservative tuning for a "
        "Hokuyo UTM-30LX) and its landmark disturbance sigma_p = 0.05 m/sqrt(s)",
    )
    use_odometry: bool = for_estimator(
        OdometryOptions,
        "use_odometry",
        "as a body-velocity measurement, an extension beyond the paper, which uses the gyro "
        "and landmarks only; false: the paper's gyro-only form",
    )
    odometry_lateral_sigma_m_s: float = for_estimator(
        OdometryLateralOptions,
        "odometry_lateral_sigma_m_s",
        "used where the dataset states no odometry noise model (its lateral term otherwise)",
    )
    measured_hold_s: float | None = Field(
        1.0,
        gt=0,
        description="a visible feature's measured value y stands in A(t, y) for at most this "
        "long after its scan [s]; later it is non-visible (its estimate stands in); None: "
        "until the next scan, however long the gap (the filter module's docstring: a stale y "
        "turns the bias term into a drift across gaps; 1 s is longer than the scan period of "
        "every shared recording, so only gaps are affected)",
    )
    rigid_correction: Literal["exact", "linear"] = Field(
        "exact",
        description="'exact': the rigid part of a scan's correction (the map turning and "
        "shifting about the vehicle) applied as an exact rotation (rigid_correction); 'linear': "
        "the Kalman correction as it is, a rotation to first order only (section IV-B)",
    )
    earth_frame: bool = Field(
        True,
        description="export the Earth-frame trajectory (earth_frame_source) as the pose",
    )
    earth_frame_source: Literal["map_alignment", "filter_state"] = Field(
        "map_alignment",
        description="how the Earth-frame pose is found (Guerreiro et al. 2013, section I): "
        "map_alignment: closed-form alignment of consecutive body-frame maps, anchored to an "
        "Earth map (earth_frame); filter_state: the Earth frame as non-visible origin and axis "
        "features of the filter (earth_state)",
    )


def landmark_disturbance(config: SensorBasedConfig) -> float:
    """sigma_p [m/sqrt(s)]: the option when given; else 0 for ``tuning=stated`` and the
    paper's section V value for ``tuning=paper``.

    Why 0 by default: the landmarks of every dataset here are static, and the gyro noise
    already reaches them through G (the ``M(f) n`` term of eq. (2), added to first order in
    ``filters.sensor_based.dynamics``), so sigma_p is a disturbance no data states. The
    paper's 0.05 inflates each landmark by 0.16 m over 10 s unseen. On
    ``sim:guerreiro-loop --data ids=false`` (seed 0) it held the landmark NIS at 0.64 per
    dof and the association at 0.987 precision; with 0 they read 0.94 and 1.0. On UTIAS
    dataset 1 without ids (robots 1-3) the association precision went from 0.93 / 0.98 /
    0.89 to 0.99 / 0.98 / 0.99."""
    if config.landmark_walk_m_sqrt_s is not None:
        return float(config.landmark_walk_m_sqrt_s)
    return PAPER_LANDMARK_SIGMA_M if config.tuning == "paper" else 0.0
