"""Corners of a 2-D laser scan: split-and-merge lines, total-least-squares fits, corners where
two adjacent lines meet, each with a first-order covariance.

The steps are the 3-D lidar front end's (``datasets.lidar.corners`` and its ``corner_*``
modules, whose functions do the work here; a 2-D scan is already the "azimuth scan"
``datasets.lidar.corner_scan`` builds from a cloud):

1. **Breakpoints** between consecutive returns farther apart than the adaptive breakpoint
   detector's ``D = r sin(dphi) / sin(lambda - dphi) + 3 sigma_r`` (Borges and Aldon, "Line
   extraction in 2D range images for mobile robotics", J. Intelligent and Robotic Systems
   40(3), 2004, eq. (3)), with ``dphi`` the beam spacing and ``lambda`` the shallowest
   incidence at which a wall still counts as continuous (``breakpoint_angle_deg``), or
   where more than ``max_missing_beams`` beams in a row did not return. A scan of 1-deg
   beams and one of 0.5-deg beams thus break at the same wall incidence.
2. **Split-and-merge** (Pavlidis and Horowitz, "Segmentation of plane curves", IEEE Trans.
   Computers C-23(8), 1974; the sensor-based paper's ref. [35]; Nguyen et al., "A comparison
   of line extraction algorithms using 2D laser rangefinder for indoor mobile robotics",
   IROS 2005, found it the fastest with the best correctness of six methods on this kind of
   scan): iterative end-point fit with ``split_threshold_m``, then adjacent segments merged
   while their joint line fit's RMS is below ``merge_rms_m``.
3. **Total least squares** per segment (the orthogonal-regression line through the centroid,
   ``datasets.lidar.corner_segments._Moments.line``), leaving ``end_trim_points`` out at each
   end where the two faces of a corner mix; the line's offset/angle covariance by first-order
   propagation of each return's range and bearing noise (``line_parameter_covariance`` in
   ``datasets.lidar.corner_uncertainty``, the sandwich form of Arras and Siegwart, "Feature
   extraction and scene interpretation for map-based navigation and map building", SPIE 3210,
   1997, eq. (9)-(11), with heteroscedastic points).
4. **Corners** at the intersection of two consecutive segments of one cluster whose
   directions differ by ``min_corner_angle_deg`` to ``180 - min_corner_angle_deg``, whose
   segments both span ``min_segment_length_m`` and ``min_segment_points`` returns, and whose
   intersection lies within ``max_corner_gap_m`` of the bridge between the two segments'
   facing ends (the boundary refinement leaves adjacent segments no shared return). The
   corner's 2x2 covariance ``N^-1 diag(var v_1, var v_2) N^-T`` propagates the two lines'
   covariances to first order (``corner_covariance``; ``N`` stacks the lines' normals,
   ``var v_k`` is line ``k``'s variance along its normal at the corner), plus an isotropic
   ``model_sigma_m`` floor, all times ``covariance_scale`` (calibrated on the shared logs by
   re-observation NIS, ``datasets.laser2d.reobservation``).

Corners are found in the laser frame and turned into the body frame by the laser's mounting.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.laser2d.scan import PlanarScan, laser_to_body
from datasets.lidar.corner_config import CornerConfig, corner_option
from datasets.lidar.corners import Corners, scan_corners

COVARIANCE_SCALE = 1.0
"""The calibrated scale of the corner covariance (``Laser2dCornerSettings.covariance_scale``;
``datasets.laser2d.reobservation`` says how it was measured)."""


class Laser2dCornerSettings(BaseModel):
    """Corner extraction from a 2-D laser scan (module docstring); defaults for a SICK LMS
    class indoor laser at 0.5 or 1 deg spacing, the same on every log. An option named as one
    of the 3-D extractor's means the same (``datasets.lidar.corner_config.SHARED_MEANINGS``);
    its note says why its default differs."""

    model_config = ConfigDict(extra="forbid")

    range_sigma_m: float = corner_option(
        "range_sigma_m", 0.01, "0.01 for a SICK LMS class laser indoors (LMS 200: 1 cm)", gt=0
    )
    bearing_sigma_rad: float = corner_option(
        "bearing_sigma_rad",
        0.002,
        "0.002 for a SICK LMS class laser at 0.5 or 1 deg beams, stated for the sensor (not "
        "measured in the repo)",
        gt=0,
    )
    min_range_m: float = corner_option(
        "min_range_m",
        0.1,
        "0.1: an indoor robot passes walls and door frames closely (not measured in the repo)",
        ge=0,
    )
    max_range_m: float = corner_option(
        "max_range_m",
        20.0,
        "20: farther walls are too sparse to fit lines to (1 deg beams are 0.35 m apart there)",
        gt=0,
    )
    breakpoint_angle_deg: float = Field(
        10.0,
        gt=0,
        lt=90,
        description="adaptive breakpoint: the shallowest wall incidence still continuous [deg] "
        "(Borges and Aldon 2004)",
    )
    max_missing_beams: int = Field(
        1, ge=0, description="break the scan where more than this many beams in a row are missing"
    )
    split_threshold_m: float = corner_option(
        "split_threshold_m",
        0.05,
        "0.05, below the 3-D lidar's 0.06 with this laser's smaller range_sigma_m (not measured "
        "in the repo)",
        gt=0,
    )
    merge_rms_m: float = corner_option(
        "merge_rms_m",
        0.02,
        "0.02, below the 3-D lidar's 0.03 with this laser's smaller range_sigma_m (not measured "
        "in the repo)",
        gt=0,
    )
    min_segment_points: int = corner_option(
        "min_segment_points",
        5,
        "5 for a laser indoors, where door jambs and niches make short segments (not measured "
        "in the repo)",
        ge=3,
    )
    min_segment_length_m: float = corner_option(
        "min_segment_length_m",
        0.2,
        "0.2 for a laser indoors, where door jambs and niches make short segments (not "
        "measured in the repo)",
        gt=0,
    )
    end_trim_points: int = corner_option("end_trim_points", 1, ge=0)
    min_corner_angle_deg: float = corner_option(
        "min_corner_angle_deg",
        45.0,
        "45: indoor walls meet near right angles, 45-135 deg kept (not measured in the repo)",
        gt=0,
        lt=90,
    )
    max_corner_gap_m: float = corner_option(
        "max_corner_gap_m",
        0.2,
        "0.2, from the bridge between the refined segments' ends rather than from each end "
        "(not measured in the repo)",
        gt=0,
    )
    model_sigma_m: float = corner_option(
        "model_sigma_m",
        0.01,
        "0.01: a 2-D scan is not deskewed by an odometry estimate (the 3-D floor's deskew and "
        "odometry error), and covariance_scale, fitted on the shared logs, scales the rest; the "
        "0.01 itself is not measured in the repo",
        ge=0,
    )
    covariance_scale: float = Field(
        COVARIANCE_SCALE,
        gt=0,
        description="multiplies every corner covariance (calibrated by re-observation NIS on "
        "the three shared CARMEN logs, datasets.laser2d.reobservation)",
    )

    def corner_config(self, angle_step_rad: float) -> CornerConfig:
        """The 3-D front end's extractor settings for a scan of beam spacing
        ``angle_step_rad`` [rad] (one azimuth bin per beam)."""
        step = abs(float(angle_step_rad))
        incidence = np.deg2rad(self.breakpoint_angle_deg)
        ratio = np.sin(step) / np.sin(max(incidence - step, 1e-6))  # Borges-Aldon eq. (3)
        return CornerConfig(
            min_range_m=self.min_range_m,
            max_range_m=self.max_range_m,
            azimuth_resolution_deg=float(np.rad2deg(step)),
            range_sigma_m=self.range_sigma_m,
            bearing_sigma_rad=self.bearing_sigma_rad,
            break_distance_m=3.0 * self.range_sigma_m,
            break_range_ratio=float(ratio),
            max_gap_bins=self.max_missing_beams + 1,
            split_threshold_m=self.split_threshold_m,
            merge_rms_m=self.merge_rms_m,
            min_segment_points=self.min_segment_points,
            min_segment_length_m=self.min_segment_length_m,
            end_trim_points=self.end_trim_points,
            min_fit_points=3,
            refine_boundaries=True,
            min_corner_angle_deg=self.min_corner_angle_deg,
            max_corner_gap_m=self.max_corner_gap_m,
            directions=False,
            dimension=2,
            model_sigma_m=self.model_sigma_m,
        )


def planar_scan_corners(
    scan: PlanarScan, settings: Laser2dCornerSettings, config: CornerConfig | None = None
) -> Corners:
    """Corners of one scan in the body frame (module docstring); ``config``: the extractor
    settings for the scan's beam spacing when the caller has them
    (``settings.corner_config``), else derived here.

    Returns:
        ``Corners``: points (k, 2) [m], covariances (k, 2, 2) [m^2], directions (k, 2, 2)
        (unit, along each of the two lines away from the corner) and the fitted segments
        (m, 2, 2) [m], all in the body frame.
    """
    points, beams = scan.laser_points()
    angles = scan.angles
    step = float(angles[-1] - angles[0]) / (len(angles) - 1) if len(angles) > 1 else 1.0
    # bins: beam indices (the sensor's order and spacing, as ``scan_corners`` expects)
    if config is None:
        config = settings.corner_config(step)
    found = scan_corners(np.ascontiguousarray(points), beams.astype(np.int64), config)
    rotation, translation = laser_to_body(scan.mounting)
    return replace(
        found,
        points=found.points @ rotation.T + translation,
        covariances=settings.covariance_scale
        * np.einsum("ij,kjl,ml->kim", rotation, found.covariances, rotation),
        directions=None if found.directions is None else found.directions @ rotation.T,
        segments=found.segments @ rotation.T + translation,
    )
