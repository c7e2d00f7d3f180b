"""The options of the corner extractor (``CornerConfig``; the steps they steer are described
in ``datasets.lidar.corners``): the 3-D lidar front end's ``--data corner.KEY``, and the
settings the 2-D laser front end derives from its own (``datasets.laser2d.corners``).

The 2-D laser's options (``Laser2dCornerSettings``: ``--data corner.KEY`` of ``carmen:``,
``laser.corner.KEY`` of a LaserScan ``bag:``) share twelve names with these; each means the
same in both (``SHARED_MEANINGS``: one description, and the 2-D front end hands the value to
the extractor's field of that name as it is). Eleven have other defaults, for the sensor:
2-D laser scans of indoor walls (a SICK LMS class laser, 0.5 or 1 deg beams) against a 64-beam
3-D lidar outdoors (the KITTI HDL-64E clips). Each field's note (``SENSOR_NOTE``) says its
default's reason; the repo measures one of them (the 3-D ``model_sigma_m`` floor), and a note
says so where a default is stated for its sensor without a measurement.
``tests/test_option_vocabulary.py`` holds the two to one name per idea.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from datasets.estimator_options import ESTIMATOR_NOTE

SENSOR_NOTE = ESTIMATOR_NOTE
"""Opens the part of a shared corner option's description that one extractor adds: its
default and why (the same marker as an estimator's note on a shared option)."""

SHARED_MEANINGS: dict[str, str] = {
    "range_sigma_m": "range noise std of one point (a lidar point, a laser return) [m]",
    "bearing_sigma_rad": "bearing noise std of one point [rad]",
    "min_range_m": "nearest range of a point used, in the scan plane [m]",
    "max_range_m": "farthest range of a point used, in the scan plane [m]",
    "split_threshold_m": "split a segment whose farthest point is this far from its chord [m]",
    "merge_rms_m": "merge adjacent segments whose joint line fit RMS is below this [m]",
    "min_segment_points": "fewest points of a line segment (and of each segment of a corner)",
    "min_segment_length_m": "shortest line segment (and each segment of a corner) [m]",
    "end_trim_points": "points left out of the line fit at each segment end",
    "min_corner_angle_deg": "least angle between the two lines of a corner (they meet at this "
    "to 180 minus this) [deg]",
    "max_corner_gap_m": "farthest the intersection may be from either segment's facing end "
    "(with refine_boundaries, as the 2-D front end has it: from the bridge between the two "
    "ends) [m]",
    "model_sigma_m": "isotropic horizontal std added to every corner for what the point noise "
    "model leaves out [m]",
}
"""What each option the 3-D and 2-D extractors share means, in both (``corner_option``)."""


def corner_option(name: str, default: Any, note: str | None = None, **constraints: Any) -> Any:
    """The shared option ``name`` (``SHARED_MEANINGS``) as one extractor declares it: its
    ``default`` and ``constraints``, the shared description, and ``note`` (why this default,
    for this sensor) after ``SENSOR_NOTE``."""
    description = SHARED_MEANINGS[name]
    if note is not None:
        description = f"{description}{SENSOR_NOTE}{note}]"
    return Field(default, description=description, **constraints)


class CornerConfig(BaseModel):
    """Parameters of the corner extractor; the defaults are the 3-D lidar front end's (a
    64-beam lidar outdoors; module docstring)."""

    model_config = ConfigDict(extra="forbid")

    slab_height_m: float = Field(0.0, description="slab centre in the body frame (z) [m]")
    slab_half_thickness_m: float = Field(0.25, gt=0, description="half thickness of the slab [m]")
    min_range_m: float = corner_option(
        "min_range_m",
        0.5,
        "0.5: points nearer a car-mounted lidar are the vehicle or noise, as "
        "datasets.lidar.sweep_raw_cut.MIN_RANGE_M says",
        ge=0,
    )
    max_range_m: float = corner_option(
        "max_range_m",
        15.0,
        "15 for a 64-beam lidar outdoors, not measured in the repo (farther, fewer rings cross "
        "the slab: those within slab_half_thickness_m / range of level)",
        gt=0,
    )
    azimuth_resolution_deg: float = Field(
        0.25, gt=0, description="azimuth bin of the 2-D scan [deg]"
    )
    range_sigma_m: float = corner_option(
        "range_sigma_m",
        0.02,
        "0.02 for a 64-beam lidar's point outdoors, stated for the sensor (not measured in the "
        "repo; what the corners show beyond it is model_sigma_m's)",
        gt=0,
    )
    bearing_sigma_rad: float = corner_option(
        "bearing_sigma_rad",
        0.003,
        "0.003 for a 64-beam lidar's azimuth, stated for the sensor (not measured in the repo)",
        gt=0,
    )
    break_distance_m: float = Field(
        0.2, gt=0, description="cluster break: fixed part of the jump [m]"
    )
    break_range_ratio: float = Field(
        0.05, ge=0, description="cluster break: part of the jump proportional to range"
    )
    max_gap_bins: int = Field(4, ge=1, description="cluster break: this many empty azimuth bins")
    split_threshold_m: float = corner_option(
        "split_threshold_m",
        0.06,
        "0.06, above the 2-D laser's 0.05 with this sensor's larger range_sigma_m (not measured "
        "in the repo)",
        gt=0,
    )
    merge_rms_m: float = corner_option(
        "merge_rms_m",
        0.03,
        "0.03, above the 2-D laser's 0.02 with this sensor's larger range_sigma_m (not measured "
        "in the repo)",
        gt=0,
    )
    min_segment_points: int = corner_option(
        "min_segment_points", 6, "6 for a 64-beam lidar outdoors (not measured in the repo)", ge=3
    )
    min_segment_length_m: float = corner_option(
        "min_segment_length_m",
        0.25,
        "0.25 for a 64-beam lidar outdoors (not measured in the repo)",
        gt=0,
    )
    end_trim_points: int = corner_option("end_trim_points", 1, ge=0)
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
    min_corner_angle_deg: float = corner_option(
        "min_corner_angle_deg",
        35.0,
        "35 for outlines outdoors (cars, building fronts), which meet at more varied angles "
        "than indoor walls (not measured in the repo)",
        gt=0,
        lt=90,
    )
    max_corner_gap_m: float = corner_option(
        "max_corner_gap_m",
        0.3,
        "0.3 for a 64-beam lidar outdoors, from each segment end (refine_boundaries off; not "
        "measured in the repo)",
        gt=0,
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
    model_sigma_m: float = corner_option(
        "model_sigma_m",
        0.015,
        "0.015 for deskew and odometry error and beam width, set where the synthetic corridor "
        "bag's corners scattered 1.8 cm RMS and the point model alone predicted 1.2 cm "
        "(datasets.lidar.corners)",
        ge=0,
    )
