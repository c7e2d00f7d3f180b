"""``--data`` options of ``carmen:FILE.clf[.bz2]`` (``datasets.carmen``)."""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field

from datasets.laser2d.frontend import Laser2dFrontEndSettings


class CarmenOptions(Laser2dFrontEndSettings):
    """``--data`` options of ``carmen:FILE``: the log's own, then the 2-D laser front end's
    (``confirm_corners``, ``corner.KEY``)."""

    model_config = ConfigDict(extra="forbid")

    laser: Literal["front", "rear"] = Field(
        "front",
        description="which laser's scans make the frames and corners: 'front' (FLASER, "
        "ROBOTLASER1) or 'rear' (RLASER); the other's lines are counted and skipped",
    )
    odometry: Literal["scan", "messages"] = Field(
        "scan",
        description="odometry at each scan: 'scan', the odom fields of the scan's own line "
        "(the pose CARMEN gave the scan; the only odometry of logs without ODOM lines), or "
        "'messages', the ODOM lines interpolated to the scan's stamp",
    )
    odometry_noise: str = Field(
        "calibrated",
        description="odometry noise: 'calibrated' (CARMEN_ODOMETRY, fitted against the batch "
        "smoother on the three shared logs pooled, datasets.carmen.noise) or a YAML model "
        "file from `workbench calibrate-noise`",
    )
    stale_odometry: Literal["spread", "keep"] = Field(
        "spread",
        description="a run of scans whose odometry pose repeats exactly and then jumps by the "
        "motion of the whole run (odometry that stopped arriving): 'spread' the jump over the "
        "run at constant velocity (counted and printed), 'keep' as logged",
    )
    laser_offset_m: float | None = Field(
        None,
        description="the laser's offset along the robot's x axis [m]; default: the log's "
        "PARAM robot_frontlaser_offset (rearlaser for the rear laser), or a ROBOTLASER1 "
        "line's own, else 0 (printed)",
    )
    scan_stride: int = Field(
        1, ge=1, description="use every N-th scan (1: all; a faster, coarser run)"
    )
    max_scans: int | None = Field(
        None, ge=2, description="use only the first max_scans scans (after the stride)"
    )
