"""Options of the smoother modes (``--set key=value``)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from datasets.estimator_options import (
    AssociationOptions,
    MeasurementNoiseOptions,
    RecordingOptions,
    for_estimator,
)
from datasets.model_options import (
    AnchorOptions,
    GapOptions,
    GyroNoiseOptions,
    InitialAccelBiasOptions,
    InitialPriorOptions,
    IntervalRate,
    IntervalRateOptions,
    OdometryLateralOptions,
    OdometryOptions,
    VelocityWalkOptions,
)


class SmootherConfig(
    AssociationOptions,
    RecordingOptions,
    MeasurementNoiseOptions,
    AnchorOptions,
    GapOptions,
    InitialPriorOptions,
    InitialAccelBiasOptions,
    OdometryOptions,
    OdometryLateralOptions,
    VelocityWalkOptions,
    GyroNoiseOptions,
    IntervalRateOptions,
):
    """Options shared by every smoother mode (association, snapshot, noise-scale, anchor,
    gap, prior, odometry, motion-noise and interval options: the shared vocabulary of
    ``datasets.estimator_options`` and ``datasets.model_options``)."""

    model_config = ConfigDict(extra="forbid")
    anchor_sigma_m: float = Field(
        1e-3, gt=0, description="std of an anchor landmark's prior [m] (tight: 'known')"
    )
    keyframe_imu_stride: int | None = Field(
        None,
        ge=1,
        description="also open a keyframe every k motion samples (None: only at scans/GPS fixes)",
    )
    gravity_m_s2: float | None = Field(
        None,
        gt=0,
        description="gravity magnitude [m/s^2]; None: the sequence's (Sequence.gravity_m_s2) or 9.81",
    )
    landmark_factor: Literal["bearing-range", "cartesian"] = Field(
        "bearing-range",
        description="3-D landmark factor: native BearingRangeFactor3D with mapped noise, or an exact Python CustomFactor",
    )
    innovation_nis: bool = Field(
        True,
        description="record each scan's stacked NIS against the keyframe's prediction, as every "
        "filter does (one joint marginal query per keyframe: about 1 ms on sparse maps, "
        "45 ms with 160 landmarks in view)",
    )
    use_gps: bool = Field(
        True, description="add GPS position factors when the sequence has GPS fixes"
    )
    use_odometry: bool = for_estimator(
        OdometryOptions,
        "use_odometry",
        "2-D: odometry between-factors (false: the gyro-only model); 3-D: relative-pose "
        "factors from 6-D (lidar) odometry beside the IMU",
    )
    factorization: Literal["CHOLESKY", "QR"] = Field(
        "CHOLESKY",
        description="iSAM2 factorisation: CHOLESKY (fast) falls back to QR for the rest of the run "
        "when it fails (an event says when); QR from the start",
    )
    relinearize_threshold: float = Field(0.05, gt=0, description="iSAM2 relinearisation threshold")
    relinearize_skip: int = Field(1, ge=1, description="iSAM2 relinearise every k updates")
    extra_iterations: int = Field(0, ge=0, description="extra iSAM2 update() calls per keyframe")
    velocity_walk_m_s_sqrt_s: float | list[float] = for_estimator(
        VelocityWalkOptions, "velocity_walk_m_s_sqrt_s", "2-D gyro-only model"
    )
    gyro_noise_density_rad_s_sqrt_hz: float | None = for_estimator(
        GyroNoiseOptions,
        "gyro_noise_density_rad_s_sqrt_hz",
        "2-D gyro-only model (3-D: the IMU noise the dataset states); an error where the "
        "dataset states none",
    )
    gyro_bias_walk_rad_s_sqrt_s: float | None = for_estimator(
        GyroNoiseOptions,
        "gyro_bias_walk_rad_s_sqrt_s",
        "2-D gyro-only model (3-D: the IMU noise the dataset states); 1e-4 where the dataset "
        "states none",
    )
    odometry_lateral_sigma_m_s: float = for_estimator(
        OdometryLateralOptions,
        "odometry_lateral_sigma_m_s",
        "added to every held velocity sample's increment, also where the dataset states an "
        "odometry noise model",
    )
    interval_rate: IntervalRate = for_estimator(
        IntervalRateOptions,
        "interval_rate",
        "IMU and rate gyro alike: each sub-interval between keyframes takes the value of the "
        "straight line between its two samples at its midpoint ('average'), or one sample",
    )


class CausalCovarianceOptions(BaseModel):
    """The incremental smoothers' causal history (the batch smoother has none)."""

    model_config = ConfigDict(extra="forbid")
    causal_covariances: bool = Field(
        True, description="marginal covariances after every keyframe (NEES of the causal history)"
    )


class Isam2Config(SmootherConfig, CausalCovarianceOptions):
    """Options of ``smoother-isam2``."""


class BatchConfig(SmootherConfig):
    """Options of ``smoother-batch``."""

    max_iterations: int = Field(100, ge=1, description="Levenberg-Marquardt iterations")
    initial_guess: Literal["incremental", "dead-reckoning"] = Field(
        "incremental",
        description="LM start: the incremental (iSAM2) solution, or dead reckoning (the trap, for comparison)",
    )


class FixedLagConfig(SmootherConfig, CausalCovarianceOptions):
    """Options of ``smoother-fixed-lag``."""

    lag_s: float = Field(
        10.0,
        gt=0,
        description="window length [s]. 10 s: on UTIAS robot 5 a 5 s window marginalises the "
        "states of its 36 s sighting gap at their poor linearisation (SE(2) ATE 0.37 m, pose "
        "NEES 38, 5.7 % of sightings inflated); 7-60 s read 0.13 m and NEES 9.9-11.8 (iSAM2: "
        "0.13 m, 10.1); robots 1-4 read the same within 2 % (ATE), Victoria Park 2.30 against "
        "2.28 m RMS from the batch smoother, 44 against 46 s",
    )
    lag_clock: Literal["informative", "wall"] = Field(
        "informative",
        description="what lag_s is counted in: 'informative' (default) only the time in which "
        "landmark sightings or GPS fixes arrive, so a stretch on motion alone is never "
        "marginalised before the sightings that end it are solved with it (smoothers.lag_clock; "
        "a sighting gap longer than the lag otherwise fixes the stretch's linearisation at its "
        "drift: a recording never seen here left a 10 m arena by 640 m with a 10 s wall-clock "
        "window); 'wall': GTSAM's lag in seconds of the recording",
    )
    keep_map: bool = Field(
        True,
        description="true: landmarks stay in the window and only vehicle states leave it, so a "
        "landmark seen again is the same variable and a loop closes with the whole correlation "
        "(consistent; victoria-park: 2.30 m RMS from the batch smoother, 44 s for 151 landmarks); "
        "false: a landmark unseen for lag_s leaves the window and, seen again, comes back with "
        "its marginal at departure as an independent prior, a cost bounded by the window, but "
        "the dropped correlation with the window counts its information twice: optimistic "
        "(5 s window: sim:guerreiro-loop seed 0: pose NEES 215 per 3 dof against 6.4; "
        "victoria-park: 7.25 m from the batch smoother, 5 s)",
    )
    factorization: Literal["CHOLESKY", "QR"] = for_estimator(
        SmootherConfig,
        "factorization",
        "QR, because a switch to QR after Cholesky has failed mid-run does not recover a "
        "window cleanly (measured on victoria-park: NIS per dof 17.8 after a switch at "
        "t=954 s against 0.25 with QR throughout, at 7 % more time)",
        default="QR",
    )
