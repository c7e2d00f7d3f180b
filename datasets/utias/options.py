"""``--data`` options of ``utias:FOLDER#robotN`` (``datasets.utias``)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, NonNegativeFloat, PositiveFloat

CALIBRATION_SOURCES = ("other-robots", "own-truth", "none")


class UtiasOptions(BaseModel):
    """``--data`` options of ``utias:FOLDER#robotN``."""

    model_config = ConfigDict(extra="forbid")
    calibration: Literal["other-robots", "own-truth", "none"] = Field(
        "other-robots",
        description="where every 'fit' below is fitted: 'other-robots' (default) against the "
        "Vicon and survey of the folder's OTHER robots, never the scored robot's own truth "
        "(cross-validated; a folder with one robot falls back to 'none' with a warning); "
        "'own-truth' against this robot's own Vicon, the truth the run is scored on (tuning on "
        "the test set: for comparison only); 'none' fits nothing (commanded velocities, white "
        "odometry noise, independent sightings, no detection probability)",
    )
    ids: bool = Field(
        True,
        description="attach the barcodes to the scans (false: withheld, association by the estimator)",
    )
    landmark_conversion: Literal["unbiased", "first-order"] = Field(
        "unbiased",
        description="range/bearing sightings to body points: the unbiased converted measurement with "
        "its covariance (Mo et al. 1998, Duan et al. 2004) or the plain conversion with J diag J^T",
    )
    bearing_sigma_rad: float = Field(
        0.03, gt=0, description="bearing noise std [rad] (measured on this data: about 0.03)"
    )
    range_sigma_fraction: float = Field(
        0.05, ge=0, description="range noise std as a fraction of the range"
    )
    range_sigma_floor_m: float = Field(
        0.05, gt=0, description="lower bound of the range noise std [m]"
    )
    odometry_noise: str = Field(
        "fit",
        description="odometry noise model: 'fit' (variances growing with time, distance and turn, "
        "fitted at load from the `calibration` source, datasets.odometry_noise), 'white' (the "
        "per-sample white noise below), or a YAML file from `workbench calibrate-noise`",
    )
    odometry_noise_window_s: float = Field(
        5.0, gt=0, description="'fit': window over which odometry is compared with the truth [s]"
    )
    odometry_sigma_v_m_s: float = Field(
        0.15,
        gt=0,
        description="odometry_noise=white: per-sample white-noise std of the forward velocity [m/s] (fits the 20 s drift vs Vicon of robot 1)",
    )
    odometry_sigma_omega_rad_s: float = Field(
        0.3,
        gt=0,
        description="odometry_noise=white: per-sample white-noise std of the angular velocity [rad/s] (fits the 1-20 s heading drift vs Vicon of robot 1)",
    )
    grid_step_s: float = Field(0.02, gt=0, description="row spacing of the resampled files [s]")
    drop_stale_repeats: bool = Field(
        True, description="drop a sighting identical to the previous one of the same barcode"
    )
    fix_swapped_labels: bool = Field(
        True,
        description="ground truth: swap the survey positions of barcodes whose sightings (placed "
        "with the Vicon poses) sit at each other's surveyed position (detected; dataset 1: 18 and 61)",
    )
    max_dropped_fraction: float = Field(
        0.01,
        ge=0,
        le=1,
        description="rows whose time does not increase are dropped and counted; more than this "
        "fraction of the odometry and ground truth is an error (the file is broken, not quirky)",
    )
    max_heading_rate_rad_s: float = Field(
        3.0,
        gt=0,
        description="the largest physical turn rate [rad/s]: Vicon heading changes faster than "
        "this are glitches (repaired), odometry rows turning faster are implausible (dropped, "
        "counted, warned)",
    )
    max_speed_m_s: float = Field(
        10.0,
        gt=0,
        description="odometry rows faster than this are implausible for a ground robot (the "
        "MRCLAM robots drive at 0.5 m/s at most): dropped, counted and warned; more than "
        "max_dropped_fraction of them is an error",
    )
    duration_s: float | None = Field(
        None, gt=0, description="use only the first duration_s seconds"
    )
    odometry_gap_s: float = Field(
        0.5, gt=0, description="odometry gaps longer than this are listed in the metadata"
    )
    odometry_delay_s: float = Field(
        0.0,
        ge=0,
        description="calibration: shift the odometry (and gyro) later by this [s] (the commanded velocity leads the motion by about 0.16 s)",
    )
    sighting_correlation: Literal["fit", "none"] = Field(
        "fit",
        description="'fit': the errors of consecutive sightings of one landmark are correlated in "
        "time (range 0.9-0.98 within 0.5 s on dataset 1), fitted at load from the `calibration` "
        "source's Vicon and the surveyed map, and every estimator inflates a sighting's noise for the "
        "time since the previous one (datasets.sighting_correlation); 'none': independent "
        "sightings (the filters' pose NEES then reads 5-25 per 3 dof)",
    )
    odometry_speed_scale: PositiveFloat | Literal["fit"] = Field(
        "fit",
        description="calibration: multiply the forward velocity by this; 'fit': the factor that "
        "best matches the `calibration` source's Vicon over whole recordings "
        "(datasets.odometry_calibration.fit_scales); 1 keeps the commanded speed",
    )
    odometry_turn_scale: PositiveFloat | Literal["fit"] = Field(
        "fit",
        description="calibration: multiply the angular velocity by this; 'fit' as for the speed "
        "(the commanded turn rate overstates the turn by 4-7 percent on every dataset-1 robot); 1 "
        "keeps the commanded rate",
    )
    odometry_speed_turn_coupling: NonNegativeFloat | Literal["fit"] = Field(
        "fit",
        description="calibration [s/rad]: the forward velocity is further multiplied by "
        "max(0, 1 - coupling * |commanded turn rate|); 'fit' as for the speed (dataset 1: "
        "Vicon over commanded speed 1.02-1.03 driving straight, 0.59-0.62 at 0.3-0.6 rad/s, "
        "on every robot); 0 keeps the speed independent of the turn",
    )
    detection_probability: Literal["fit", "none"] = Field(
        "fit",
        description="'fit': how often the camera sights a barcode in its view, by range "
        "(datasets.detection_probability), fitted at load from the `calibration` source's Vicon "
        "and the surveyed map over whole recordings (dataset 1: 0.5-0.8 within 3 m, 0.15-0.25 "
        "beyond 5 m); ekf-slam-mht scores missed detections with it; 'none': not stated",
    )
