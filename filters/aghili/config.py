"""Options of the Aghili adaptive EKF SLAM (``--set key=value``)."""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field

from datasets.estimator_options import AssociationOptions, RecordingOptions, for_estimator
from datasets.model_options import (
    AnchorOptions,
    GapOptions,
    InitialAccelBiasOptions,
    InitialPriorOptions,
    LandmarkMeasurementNoiseOptions,
)


class AghiliConfig(
    AssociationOptions,
    RecordingOptions,
    AnchorOptions,
    GapOptions,
    InitialPriorOptions,
    InitialAccelBiasOptions,
    LandmarkMeasurementNoiseOptions,
):
    """Options of the Aghili adaptive EKF SLAM (``--set key=value``; association, snapshot,
    anchor, gap, prior and landmark-noise options: the shared vocabulary of
    ``datasets.estimator_options`` and ``datasets.model_options``)."""

    model_config = ConfigDict(extra="forbid")
    anchors: int | None = for_estimator(
        AnchorOptions,
        "anchors",
        "3, the paper's r (section 2.1; section 3, Proposition 1: observable with three "
        "anchors not on a line), "
        "from the first observations where the dataset offers none (anchor_source); at least "
        "1, None as 3",
        default=3,
        ge=1,
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
    landmark_measurement_sigma_m: float | None = for_estimator(
        LandmarkMeasurementNoiseOptions,
        "landmark_measurement_sigma_m",
        "R before the adaptive estimate (eq. (42)) takes over, or throughout with "
        "adaptive_noise=false",
    )
    process_noise: Literal["closed-form", "van-loan"] = Field(
        "closed-form",
        description="Q' by the verified closed form or by Van Loan's matrix exponential",
    )
