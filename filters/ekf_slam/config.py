"""Options of the world-centric EKF-SLAM (``--set key=value``)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import ConfigDict, Field

from datasets.estimator_options import (
    AssociationOptions,
    MeasurementNoiseOptions,
    RecordingOptions,
)


class EkfSlamConfig(AssociationOptions, RecordingOptions, MeasurementNoiseOptions):
    """Options of ``ekf-slam`` (association, snapshot and noise-scale options: the shared
    vocabulary of ``datasets.estimator_options``)."""

    model_config = ConfigDict(extra="forbid")
    motion_input: Literal["auto", "odometry", "gyro"] = Field(
        "auto",
        description="motion model input: auto = odometry when the data has it, else the gyro (IMU gyro in 3-D)",
    )
    acceleration_density: float | list[float] = Field(
        0.3,
        description="gyro-driven model: white acceleration density driving the velocity "
        "[m/s^2/sqrt(Hz)]; or one value per body axis [forward, lateral(, vertical)]",
    )
    rotate_velocity_with_gyro: bool = Field(
        True,
        description="gyro-driven model: world velocity turns with the body (constant body-frame velocity); false: constant world velocity",
    )
    gyro_interval_rate: Literal["average", "latest"] = Field(
        "average",
        description="rate over a gyro interval: mean of its two samples (instantaneous samples, the simulator's convention) or the later sample (interval averages)",
    )
    estimate_gyro_bias: bool = Field(True, description="gyro-driven model: gyro bias in the state")
    gyro_noise_density: float | None = Field(
        None, ge=0, description="[rad/s/sqrt(Hz)]; None: the dataset's NoiseSpec (else 1e-3)"
    )
    gyro_bias_walk: float | None = Field(
        None, ge=0, description="[rad/s^2/sqrt(Hz)]; None: the dataset's NoiseSpec (else 1e-5)"
    )
    gyro_bias_sigma_rad_s: float | None = Field(
        None, ge=0, description="initial bias std; None: the dataset's NoiseSpec (else 0.01)"
    )
    jacobians: Literal["observability-constrained", "first-estimate", "standard"] = Field(
        "observability-constrained",
        description="with odometry input, how the filter keeps from gaining information along "
        "the unobservable global pose: 'observability-constrained' (OC-EKF, Huang, Mourikis, "
        "Roumeliotis 2010: each measurement Jacobian at the current estimates, projected to "
        "H N = 0), 'first-estimate' (FEJ-EKF, Huang et al. 2008: each landmark's Jacobian at "
        "its first estimate; UTIAS robot 5 diverges with it), 'standard' (the textbook, "
        "inconsistent EKF); both constrained forms propagate with FEJ's transition Jacobian",
    )
    odometry_noise_scale: float = Field(
        1.0, gt=0, description="multiplies the odometry covariance of the data"
    )
    max_gap_s: float = Field(
        1.0,
        gt=0,
        description="a motion-input gap longer than this is logged (event motion_gap) and inflates the pose covariance",
    )
    gap_speed_m_s: float = Field(
        0.5, ge=0, description="position std added per second of a motion gap [m/s]"
    )
    gap_rate_rad_s: float = Field(
        0.2, ge=0, description="heading std added per second of a motion gap [rad/s]"
    )
    prune_single_sightings_after_s: float | None = Field(
        None,
        gt=0,
        description="landmark initialisation delay [s]: a new landmark is provisional until a "
        "second sighting; one not sighted again this long after its first is marginalised out "
        "(exact: one sighting carries no information on the rest of the state; "
        "docs/association.md). None: keep every landmark",
    )


class MultiHypothesisEkfSlamConfig(EkfSlamConfig):
    """Options of ``ekf-slam-mht``: those of ``ekf-slam`` plus how many association
    hypotheses it keeps (``filters.ekf_slam.multi_hypothesis``)."""

    max_hypotheses: int = Field(
        60,
        ge=1,
        description="association hypotheses kept after each scan (the most likely; 1: a "
        "single-hypothesis filter deciding by likelihood)",
    )
    hypothesis_log_window: float = Field(
        20.0,
        gt=0,
        description="a hypothesis whose log likelihood is more than this below the best one's "
        "is dropped (natural log)",
    )
    commit_after_s: float | None = Field(
        30.0,
        gt=0,
        description="N-scan-back pruning [s]: the decisions made this long ago are fixed to "
        "those of the best hypothesis, and hypotheses that differ there are dropped, leaving "
        "room for alternatives of recent scans (UTIAS robot 2 without ids: 0.999 precision "
        "with 30 s, 0.909 with 60 s, 0.920 without; docs/estimators/ekf-slam-mht.md). "
        "None: never fixed",
    )
    new_landmark_density: float = Field(
        1.5e-4,
        gt=0,
        description="density of sightings of landmarks not yet mapped in the sighting space "
        "[1/m^d]: the likelihood of a 'new landmark' interpretation of a sighting",
    )
    detection_probability: Annotated[float, Field(gt=0, lt=1)] | Literal["sequence", "none"] = (
        Field(
            "sequence",
            description="P_D, the probability that a landmark predicted inside the sensor's "
            "view (the sequence's landmark_field_of_view_deg and landmark_range_m) is sighted "
            "in a scan: a hypothesis pays log(1 - P_D) for each one it leaves unsighted and "
            "gains log P_D for each it pairs (Reid 1979, eq. 16). 'sequence': the sequence's "
            "stated P_D by range (NoiseSpec.landmark_detection; UTIAS fits one at load), no "
            "such term where it states none; a number: that P_D at every range; 'none': no term",
        )
    )  # 'none', not 'off': --set reads values as YAML, where off is false
