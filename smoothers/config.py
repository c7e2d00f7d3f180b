"""Options of the smoother modes (``--set key=value``)."""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field

from datasets.estimator_options import (
    AssociationOptions,
    MeasurementNoiseOptions,
    RecordingOptions,
)


class SmootherConfig(AssociationOptions, RecordingOptions, MeasurementNoiseOptions):
    """Options shared by every smoother mode (association, snapshot and noise-scale options:
    the shared vocabulary of ``datasets.estimator_options``)."""

    model_config = ConfigDict(extra="forbid")
    anchors: int | None = Field(
        None,
        ge=0,
        description="the first N of sequence.known_landmarks become known landmarks (tight priors), as for the filters; "
        "None: 3 when the dataset offers known landmarks (the aghili filter's default), else 0",
    )
    anchor_sigma_m: float = Field(
        1e-3, gt=0, description="std of an anchor landmark's prior [m] (tight: 'known')"
    )
    keyframe_imu_stride: int | None = Field(
        None,
        ge=1,
        description="also open a keyframe every k motion samples (None: only at scans/GPS fixes)",
    )
    max_imu_gap_s: float = Field(
        0.5, gt=0, description="a gap between motion samples longer than this is an InputError [s]"
    )
    gravity_m_s2: float | None = Field(
        None,
        gt=0,
        description="gravity magnitude [m/s^2]; None: sequence.metadata['gravity_m_s2'] or 9.81",
    )
    position_sigma_m: float | None = Field(
        None, gt=0, description="initial position prior std [m]; None: sequence.initial_state"
    )
    rotation_sigma_rad: float | None = Field(
        None, gt=0, description="initial rotation prior std [rad]; None: sequence.initial_state"
    )
    velocity_sigma_m_s: float | None = Field(
        None, gt=0, description="initial velocity prior std [m/s]; None: sequence.initial_state"
    )
    gyro_bias_sigma_rad_s: float | None = Field(
        None, gt=0, description="initial gyro bias std [rad/s]; None: sequence.noise, else 0.01"
    )
    accel_bias_sigma_m_s2: float | None = Field(
        None, gt=0, description="initial accel bias std [m/s^2]; None: sequence.noise, else 0.1"
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
    use_odometry: bool = Field(
        True,
        description="3-D: add relative-pose factors from 6-D odometry (lidar) when the sequence has it",
    )
    factorization: Literal["CHOLESKY", "QR"] = Field(
        "CHOLESKY",
        description="iSAM2 factorisation: CHOLESKY (fast) falls back to QR for the rest of the run "
        "when it fails (an event says when); QR from the start",
    )
    relinearize_threshold: float = Field(0.05, gt=0, description="iSAM2 relinearisation threshold")
    relinearize_skip: int = Field(1, ge=1, description="iSAM2 relinearise every k updates")
    extra_iterations: int = Field(0, ge=0, description="extra iSAM2 update() calls per keyframe")
    planar_velocity_walk_m_s2: float | list[float] = Field(
        0.1,
        description="2-D gyro-only model: body-velocity random-walk density [m/s^2/sqrt(Hz)]; "
        "or one value per body axis [forward, lateral]",
    )
    planar_gyro_density: float | None = Field(
        None, gt=0, description="2-D gyro-only: gyro white-noise density; None: sequence.noise"
    )
    odometry_lateral_sigma_m_s: float = Field(
        0.02, gt=0, description="2-D velocity odometry: lateral-slip floor [m/s]"
    )
    imu_interpolation: bool = Field(
        True,
        description="IMU or rate gyro: integrate the line between consecutive samples (instantaneous samples, the filters' 'average'); false: zero-order hold",
    )


class Isam2Config(SmootherConfig):
    """Options of ``smoother-isam2``."""

    causal_covariances: bool = Field(
        True, description="marginal covariances after every keyframe (NEES of the causal history)"
    )


class BatchConfig(SmootherConfig):
    """Options of ``smoother-batch``."""

    max_iterations: int = Field(100, ge=1, description="Levenberg-Marquardt iterations")
    initial_guess: Literal["incremental", "dead-reckoning"] = Field(
        "incremental",
        description="LM start: the incremental (iSAM2) solution, or dead reckoning (the trap, for comparison)",
    )


class FixedLagConfig(SmootherConfig):
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
    causal_covariances: bool = Field(True, description="marginal covariances after every keyframe")
    factorization: Literal["CHOLESKY", "QR"] = Field(
        "QR",
        description="iSAM2 factorisation of the window: QR by default here, because a switch to QR "
        "after Cholesky has failed mid-run does not recover a window cleanly (measured on "
        "victoria-park: NIS per dof 17.8 after a switch at t=954 s against 0.25 with QR "
        "throughout, at 7 % more time)",
    )
