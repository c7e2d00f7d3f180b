"""The options of the corner extractor (``CornerConfig``; the steps they steer are described
in ``datasets.lidar.corners``): the 3-D lidar front end's ``--data corner.KEY``, and the
settings the 2-D laser front end derives from its own (``datasets.laser2d.corners``).
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class CornerConfig(BaseModel):
    """Parameters of the corner extractor."""

    model_config = ConfigDict(extra="forbid")

    slab_height_m: float = Field(0.0, description="slab centre in the body frame (z) [m]")
    slab_half_thickness_m: float = Field(0.25, gt=0, description="half thickness of the slab [m]")
    min_range_m: float = Field(0.5, ge=0, description="nearest horizontal range used [m]")
    max_range_m: float = Field(15.0, gt=0, description="farthest horizontal range used [m]")
    azimuth_resolution_deg: float = Field(
        0.25, gt=0, description="azimuth bin of the 2-D scan [deg]"
    )
    range_sigma_m: float = Field(0.02, gt=0, description="range noise std of a point [m]")
    bearing_sigma_rad: float = Field(0.003, gt=0, description="bearing noise std of a point [rad]")
    break_distance_m: float = Field(
        0.2, gt=0, description="cluster break: fixed part of the jump [m]"
    )
    break_range_ratio: float = Field(
        0.05, ge=0, description="cluster break: part of the jump proportional to range"
    )
    max_gap_bins: int = Field(4, ge=1, description="cluster break: this many empty azimuth bins")
    split_threshold_m: float = Field(
        0.06,
        gt=0,
        description="split a segment whose farthest point is this far from its chord [m]",
    )
    merge_rms_m: float = Field(
        0.03, gt=0, description="merge adjacent segments whose joint line fit RMS is below this [m]"
    )
    min_segment_points: int = Field(6, ge=3, description="fewest points of a line segment")
    min_segment_length_m: float = Field(0.25, gt=0, description="shortest line segment [m]")
    end_trim_points: int = Field(
        1, ge=0, description="points left out of the line fit at each segment end"
    )
    refine_boundaries: bool = Field(
        False,
        description="move each boundary between adjacent segments of a cluster to where the "
        "two lines fit best (least total squared distance; "
        "datasets.lidar.corner_segments.refine_boundaries)",
    )
    min_fit_points: int | None = Field(
        None,
        ge=2,
        description="fewest points a trimmed line fit keeps; a segment with fewer after the "
        "trim is fitted untrimmed (None: min_segment_points)",
    )
    min_corner_angle_deg: float = Field(
        35.0, gt=0, lt=90, description="least angle between the two lines of a corner [deg]"
    )
    max_corner_gap_m: float = Field(
        0.3, gt=0, description="farthest the intersection may be from either segment end [m]"
    )
    directions: bool = Field(
        False, description="also output the two unit line directions of every corner"
    )
    dimension: int = Field(
        3, ge=2, le=3, description="2: planar corners; 3: corners at the slab height"
    )
    slab_sigma_m: float | None = Field(
        None, description="std of a 3-D corner's z [m] (default: half thickness / sqrt(3))"
    )
    model_sigma_m: float = Field(
        0.015,
        ge=0,
        description="isotropic horizontal std added to every corner for what the point noise model leaves out (deskew and odometry error, beam width) [m]",
    )
