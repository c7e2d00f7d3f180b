"""Options of the Aghili adaptive EKF SLAM (``--set key=value``)."""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field

from datasets.estimator_options import AssociationOptions, RecordingOptions


class AghiliConfig(AssociationOptions, RecordingOptions):
    """Options of the Aghili adaptive EKF SLAM (``--set key=value``; association and snapshot
    options: the shared vocabulary of ``datasets.estimator_options``)."""

    model_config = ConfigDict(extra="forbid")
    anchors: int = Field(
        3, ge=1, description="r: number of known anchor landmarks fixing the map (section 2.1)"
    )
    anchor_source: Literal["auto", "known", "first-observation"] = Field(
        "auto",
        description="'auto': 'known' where the dataset offers r surveyed landmarks, else "
        "'first-observation' (a bag, a scan folder), and the run says which; 'known': the "
        "dataset's surveyed positions (NEES against truth meaningful); 'first-observation': the "
        "paper's choice, from the first noisy observation (NEES not comparable)",
    )
    adaptive_noise: bool = Field(True, description="estimate R on line (section 4.4, eq. (42))")
    adaptive_window: int = Field(
        300, ge=10, description="w: landmark residuals in the eq. (42) sliding window"
    )
    adaptive_min_sigma_m: float = Field(
        0.005, gt=0, description="floor on the adapted landmark std [m] (keeps R PD)"
    )
    adaptive_min_samples: int = Field(
        30,
        ge=3,
        description="landmark residuals in the window before the adapted R replaces the initial one",
    )
    adaptive_residual: Literal["posterior", "prior"] = Field(
        "posterior",
        description="eq. (42) on post-fit residuals, R = mean(e e^T + H P+ H^T) (fails safe when P is off), "
        "or on prior residuals as printed, R = W - H P- H^T",
    )
    landmark_sigma_m: float | None = Field(
        None,
        gt=0,
        description="initial/fixed landmark std [m]; None: the covariances the scans carry",
    )
    process_noise: Literal["closed-form", "van-loan"] = Field(
        "closed-form",
        description="Q' by the verified closed form or by Van Loan's matrix exponential",
    )
    initial_velocity_sigma_m_s: float | None = Field(
        None, ge=0, description="initial velocity std [m/s]; None: the dataset's initial state"
    )
    initial_gyro_bias_sigma_rad_s: float | None = Field(
        None,
        ge=0,
        description="initial gyro bias std [rad/s]; None: the dataset's noise spec, else 0.01",
    )
    initial_accel_bias_sigma_m_s2: float | None = Field(
        None,
        ge=0,
        description="initial accelerometer bias std [m/s^2]; None: the dataset's noise spec, else 0.1",
    )
    max_gap_s: float = Field(1.0, gt=0, description="an IMU gap longer than this is an error [s]")
