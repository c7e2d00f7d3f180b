"""Options of the world-centric EKF-SLAM (``--set key=value``)."""

from __future__ import annotations

from typing import Annotated, ClassVar, Literal

from pydantic import ConfigDict, Field

from datasets.estimator_options import (
    AssociationOptions,
    MeasurementNoiseOptions,
    RecordingOptions,
    for_estimator,
)
from datasets.model_options import (
    GapInflationOptions,
    GapOptions,
    GapPolicy,
    GyroNoiseOptions,
    InitialPriorOptions,
    IntervalRateOptions,
    LandmarkProbationOptions,
    OdometryOptions,
    VelocityWalkOptions,
)


class EkfSlamConfig(
    AssociationOptions,
    RecordingOptions,
    MeasurementNoiseOptions,
    OdometryOptions,
    VelocityWalkOptions,
    GyroNoiseOptions,
    IntervalRateOptions,
    InitialPriorOptions,
    GapOptions,
    GapInflationOptions,
    LandmarkProbationOptions,
):
    """Options of ``ekf-slam`` (association, snapshot, noise-scale, motion-noise, prior and
    gap options: the shared vocabulary of ``datasets.estimator_options`` and
    ``datasets.model_options``)."""

    model_config = ConfigDict(extra="forbid")
    gap_policies: ClassVar[tuple[str, ...]] = ("raise", "inflate")
    use_odometry: bool = for_estimator(
        OdometryOptions,
        "use_odometry",
        "as the motion input; false: the gyro (the IMU's gyro in 3-D) with the velocity walk",
    )
    velocity_walk_m_s_sqrt_s: float | list[float] = for_estimator(
        VelocityWalkOptions,
        "velocity_walk_m_s_sqrt_s",
        "0.3, gyro-driven model only. Against 0.1 the evidence is split: on the simulator 0.1 "
        "lowers the ATE (seeds 0-4: circle 0.031 to 0.025 m, guerreiro-loop 0.0095 to 0.0088 "
        "m, aghili-rover 0.048 to 0.039 m) with the pose NEES per dof within 0.05, and on "
        "UTIAS robots 1-5 with use_odometry=false it lowers the ATE by 8-41 %, but robots 1 "
        "and 4 then read pose NEES 3.0 and 2.2 per dof against 1.6 and 0.6",
        default=0.3,
    )
    gyro_noise_density_rad_s_sqrt_hz: float | None = for_estimator(
        GyroNoiseOptions, "gyro_noise_density_rad_s_sqrt_hz", "1e-3 where the dataset states none"
    )
    gyro_bias_walk_rad_s_sqrt_s: float | None = for_estimator(
        GyroNoiseOptions, "gyro_bias_walk_rad_s_sqrt_s", "1e-5 where the dataset states none"
    )
    gap_policy: GapPolicy = for_estimator(
        GapOptions,
        "gap_policy",
        "'inflate': a real robot's odometry may stop for a while (the CARMEN intel.clf log "
        "for 3.5 s) and the filter keeps its landmarks",
        default="inflate",
    )
    rotate_velocity_with_gyro: bool = Field(
        True,
        description="gyro-driven model: world velocity turns with the body (constant body-frame velocity); false: constant world velocity",
    )
    estimate_gyro_bias: bool = Field(True, description="gyro-driven model: gyro bias in the state")
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
    probation_s: float | None = for_estimator(
        LandmarkProbationOptions,
        "probation_s",
        "the landmark initialisation delay of docs/association.md: a new landmark is "
        "provisional until its second sighting (min_observations 2), and marginalising out "
        "a landmark seen once is exact: one sighting carries no information on the rest of "
        "the state",
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
