"""The options that set an estimator's model, one name per idea (issue 39): motion noise,
odometry use, interval rate, gap policy, initial priors and landmark noise.

Estimator configs inherit these pydantic models beside ``datasets.estimator_options``
(association, recording), so each name is defined once, keys stay flat on the command line
(``--set velocity_walk_m_s_sqrt_s=0.05``) and ``workbench config E`` shows one description.
An estimator whose paper (or whose data) fixes another default keeps the shared field and
states why (``estimator_options.for_estimator``); ``tests/test_option_vocabulary.py``
fails on a second spelling of an idea, on one name with two meanings, and on a physical
quantity without its unit in the name.

Units in names: ``_m``, ``_rad``, ``_s``, ``_m_s``, ``_rad_s``, ``_m_s2``, ``_deg``. A random
walk's density is the std it adds per square root of a second (``_sqrt_s``: a velocity
walk of ``0.1 m/s/sqrt(s)`` leaves the velocity 0.1 m/s uncertain after 1 s unseen, 0.32 m/s
after 10 s); a white noise's density is per square root of a hertz (``_sqrt_hz``: a sample
at rate f has std ``density * sqrt(f)``). The two are the same unit; the name says which
model. Old names are accepted with a warning (``datasets.option_renames``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

if TYPE_CHECKING:
    import numpy as np

DEFAULT_VELOCITY_WALK_M_S_SQRT_S = 0.1
"""Guerreiro et al. (2013), section V: sigma_v = 0.1 m/s/sqrt(s) on every axis."""
DEFAULT_MAX_GAP_S = 1.0
"""No motion input of the shipped data leaves a gap above 0.2 s (UTIAS robots 1-5 0.02 s,
victoria-park 0.2 s, the simulator 0.1 s, kitti-imu-gps 0.02 s): 1 s only catches an outage."""
DEFAULT_ODOMETRY_LATERAL_SIGMA_M_S = 0.02
"""The Vicon of the UTIAS MRCLAM robots 1-5 (dataset 1) moves them sideways by 1.4-2.5 mm
RMS per second (0.015-0.025 over any 0.5-1 s window), which a 50 Hz velocity sample whose
lateral error is white explains with 0.010-0.018 m/s per sample: 0.02 covers every robot
(0.05, sensor-based's earlier default, is three to five times the data)."""


class VelocityWalkOptions(BaseModel):
    """The body velocity of a model without an accelerometer (gyro-driven)."""

    model_config = ConfigDict(extra="forbid")
    velocity_walk_m_s_sqrt_s: float | list[float] = Field(
        DEFAULT_VELOCITY_WALK_M_S_SQRT_S,
        description="body-velocity random walk [m/s/sqrt(s) = m/s^2/sqrt(Hz)]: a white "
        "acceleration along the body axes in continuous time (velocity variance grows by its "
        "square times dt) drives the velocity of the models without an accelerometer; one "
        "value for every axis, or one per body axis [forward, lateral(, vertical)] (a vehicle "
        "that follows its heading: a small lateral value); default: the sensor-based paper's "
        "sigma_v (Guerreiro et al. 2013, section V)",
    )


class GyroNoiseOptions(BaseModel):
    """The rate gyro's noise as the model states it (None: the data's own statement)."""

    model_config = ConfigDict(extra="forbid")
    gyro_noise_density_rad_s_sqrt_hz: float | None = Field(
        None,
        ge=0,
        description="gyro white-noise density [rad/s/sqrt(Hz)]; None: the dataset's stated "
        "value (sequence.noise.gyro_noise_density)",
    )
    gyro_bias_walk_rad_s_sqrt_s: float | None = Field(
        None,
        ge=0,
        description="gyro-bias random walk [rad/s/sqrt(s) = rad/s^2/sqrt(Hz)]; None: the "
        "dataset's stated value (sequence.noise.gyro_bias_walk)",
    )


class OdometryOptions(BaseModel):
    """Whether and how an estimator uses the dataset's odometry."""

    model_config = ConfigDict(extra="forbid")
    use_odometry: bool = Field(
        True,
        description="use the dataset's odometry where it has some (each estimator's page says "
        "how: the motion input, a body-velocity measurement, or relative-pose factors); "
        "false: never (the gyro or IMU alone drives the model)",
    )

    @field_validator("use_odometry", mode="before")
    @classmethod
    def _null_is_default(cls, value: object) -> object:
        # sensor-based wrote null for 'where the dataset has odometry' before issue 39
        return True if value is None else value


class OdometryLateralOptions(BaseModel):
    """The lateral axis a velocity odometry sample (v, omega) does not state."""

    model_config = ConfigDict(extra="forbid")
    odometry_lateral_sigma_m_s: float = Field(
        DEFAULT_ODOMETRY_LATERAL_SIGMA_M_S,
        gt=0,
        description="std of the lateral body velocity of a (v, omega) odometry sample, which "
        "states none (a unicycle does not move sideways, a real one slips a little) [m/s], "
        "white per sample; default: the Vicon of UTIAS robots 1-5 (0.010-0.018 m/s per 50 Hz "
        "sample)",
    )


IntervalRate = Literal["average", "hold", "latest"]


class IntervalRateOptions(BaseModel):
    """Which rate a gyro or IMU interval between two samples is integrated with."""

    model_config = ConfigDict(extra="forbid")
    interval_rate: IntervalRate = Field(
        "average",
        description="rate over the interval between two gyro/IMU samples: 'average' the mean "
        "of its two samples (samples are instantaneous values: the simulator's convention; "
        "second order), 'hold' the earlier sample held (zero-order hold), 'latest' the later "
        "sample (samples are averages over the interval that ends at them)",
    )


def interval_value(
    policy: IntervalRate, earlier: np.ndarray | None, later: np.ndarray
) -> np.ndarray:
    """The rate (or specific force) used over the interval between two samples, as
    ``interval_rate`` says: 'average' the trapezoid ``(earlier + later) / 2`` (Aghili eq. (34):
    samples are instantaneous values), 'hold' the earlier sample, 'latest' the later one.
    Without an earlier sample (the first interval) the later one. Shapes as given (any
    matching arrays). The smoothers' preintegration interpolates within an interval instead
    (``smoothers.imu_graph.KeyframeImuIntegrator``: IMU sub-intervals cut at keyframes)."""
    if earlier is None or policy == "latest":
        return later
    if policy == "average":
        return 0.5 * (earlier + later)
    return earlier


GapPolicy = Literal["raise", "inflate"]


class GapOptions(BaseModel):
    """What an estimator does when its motion input stops for a while."""

    model_config = ConfigDict(extra="forbid")
    gap_policies: ClassVar[tuple[str, ...]] = ("raise",)
    """The policies the estimator implements (``inflate`` needs a way to widen its pose)."""
    max_gap_s: float = Field(
        DEFAULT_MAX_GAP_S,
        gt=0,
        description="longest gap between motion inputs the model bridges as it is [s]; "
        "longer: gap_policy",
    )
    gap_policy: GapPolicy = Field(
        "raise",
        description="beyond max_gap_s: 'raise' an input error naming the gap (the model is "
        "meaningless across an outage); 'inflate' bridge it, logged as an event motion_gap, "
        "with the pose covariance widened by gap_speed_m_s and gap_rate_rad_s per second of "
        "the gap (ekf-slam)",
    )

    @field_validator("gap_policy")
    @classmethod
    def _implemented(cls, value: str) -> str:
        if value not in cls.gap_policies:
            raise ValueError(
                f"'{value}' is not implemented by this estimator (it takes "
                f"{' or '.join(repr(p) for p in cls.gap_policies)})"
            )
        return value


class GapInflationOptions(BaseModel):
    """How much a bridged motion gap widens the pose (``gap_policy=inflate``)."""

    model_config = ConfigDict(extra="forbid")
    gap_speed_m_s: float = Field(
        0.5, ge=0, description="position std added per second of a motion gap [m/s]"
    )
    gap_rate_rad_s: float = Field(
        0.2, ge=0, description="heading std added per second of a motion gap [rad/s]"
    )


class InitialPriorOptions(BaseModel):
    """The prior on the start (None: what the dataset states, ``sequence.initial_state``
    and ``sequence.noise``); each estimator reads the blocks its state has."""

    model_config = ConfigDict(extra="forbid")
    initial_position_sigma_m: float | None = Field(
        None,
        gt=0,
        description="initial position prior std [m] per axis; None: the dataset's "
        "(sequence.initial_state.position_sigma_m)",
    )
    initial_rotation_sigma_rad: float | None = Field(
        None,
        gt=0,
        description="initial rotation prior std [rad] per axis (2-D: heading); None: the "
        "dataset's (sequence.initial_state.rotation_sigma_rad)",
    )
    initial_velocity_sigma_m_s: float | None = Field(
        None,
        gt=0,
        description="initial velocity prior std [m/s] per axis; None: the dataset's "
        "(sequence.initial_state.velocity_sigma_m_s)",
    )
    initial_gyro_bias_sigma_rad_s: float | None = Field(
        None,
        gt=0,
        description="initial gyro-bias prior std [rad/s] per axis (around zero); None: the "
        "dataset's (sequence.noise.gyro_bias_sigma_rad_s), 0.01 where it states none",
    )


class InitialAccelBiasOptions(BaseModel):
    """The prior on the accelerometer bias (estimators with an accelerometer)."""

    model_config = ConfigDict(extra="forbid")
    initial_accel_bias_sigma_m_s2: float | None = Field(
        None,
        gt=0,
        description="initial accelerometer-bias prior std [m/s^2] per axis (around zero); "
        "None: the dataset's (sequence.noise.accel_bias_sigma_m_s2), 0.1 where it states none",
    )


class LandmarkMeasurementNoiseOptions(BaseModel):
    """A measurement noise of landmark sightings set by the estimator, not the data."""

    model_config = ConfigDict(extra="forbid")
    landmark_measurement_sigma_m: float | None = Field(
        None,
        gt=0,
        description="landmark sighting (measurement) noise std [m] per axis, used in place "
        "of the covariances the scans carry; None: the scans' own",
    )


class LandmarkWalkOptions(BaseModel):
    """A process noise on landmarks: a random walk of each landmark (robocentric models,
    where the landmarks are states in the moving body frame)."""

    model_config = ConfigDict(extra="forbid")
    landmark_walk_m_sqrt_s: float | None = Field(
        None,
        ge=0,
        description="landmark position random walk (process noise) [m/sqrt(s)]: each "
        "landmark's position std grows by this per sqrt(second); None: the estimator's "
        "default (static landmarks: 0)",
    )


class LandmarkFieldOfViewOptions(BaseModel):
    """Where the landmark sensor can see (which unseen landmarks count as missed)."""

    model_config = ConfigDict(extra="forbid")
    landmark_field_of_view_deg: float | None = Field(
        None,
        gt=0,
        le=360,
        description="landmark sensor's horizontal field of view centred on the body x axis "
        "[deg] (a landmark outside it is not missed); None: the dataset's "
        "(sequence.noise.landmark_field_of_view_deg), 360 where it states none",
    )


class AnchorOptions(BaseModel):
    """Known landmarks that fix the map's frame (the filters and smoothers alike)."""

    model_config = ConfigDict(extra="forbid")
    anchors: int | None = Field(
        None,
        ge=0,
        description="number of anchor landmarks fixing the map: the first N of the dataset's "
        "surveyed landmarks (sequence.known_landmarks) with tight priors; None: 3 in 3-D where "
        "the dataset offers them (Aghili's r, section 2.1), else 0",
    )


class LandmarkProbationOptions(BaseModel):
    """A new landmark on probation: removed unless sighted again soon (clutter, a false
    association), the landmark initialisation delay."""

    model_config = ConfigDict(extra="forbid")
    probation_s: float | None = Field(
        None,
        ge=0,
        description="landmark probation [s]: a landmark sighted fewer than min_observations "
        "times by this age is removed from the state (marginalised out); None: every "
        "landmark stays",
    )
    min_observations: int = Field(
        2, ge=1, description="sightings a landmark needs by the age probation_s to stay"
    )
