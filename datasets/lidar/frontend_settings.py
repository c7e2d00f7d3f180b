"""What a lidar front end is asked to compute, and how (``FrontEndSettings``); the ``--data``
options every point-cloud source shares, bags and scan folders alike (``LidarSourceOptions``:
how to read per-point times, what the front end emits, its KISS-ICP and corner settings);
and their lines for ``workbench list --verbose`` (``describe_lidar_options``).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from datasets.lidar.corner_config import CornerConfig
from datasets.lidar.kiss_icp_odometry import KissIcpSettings
from datasets.lidar.sweep_times import POINT_TIMES_DESCRIPTION, SweepOptions


class FrontEndSettings(BaseModel):
    """What the front end computes, and how."""

    model_config = ConfigDict(extra="forbid")

    odometry: bool = Field(True, description="run KISS-ICP")
    corners: bool = Field(True, description="extract corner landmarks")
    warmup_frames: int = Field(
        1,
        ge=0,
        description="withhold the corners of this many first frames of clouds with per-point times (no motion estimate to deskew them with yet)",
    )
    kiss: KissIcpSettings = Field(default_factory=KissIcpSettings, description="KISS-ICP settings")
    imu_deskew: bool = Field(
        False,
        description="deskew clouds with per-point times by the IMU's rotation "
        "(datasets.lidar.imu_deskew; the stream must carry ImuSample), not KISS-ICP's "
        "constant-velocity prediction",
    )
    corner: CornerConfig = Field(
        default_factory=CornerConfig, description="corner extractor settings"
    )
    confirm_corners: bool = Field(
        True,
        description="emit a corner only once it is found again where it was in the previous frame (KISS-ICP's poses): sliding outlines are never landmarks",
    )


class LidarSourceOptions(BaseModel):
    """``--data`` options every point-cloud source shares (bags and scan folders): how to
    read per-point times, and what the front end emits."""

    model_config = ConfigDict(extra="forbid")

    point_time_unit: str = Field(
        "auto", pattern="^(auto|s|ms|us|ns)$", description="unit of per-point times"
    )
    point_times: Literal["auto", "field", "azimuth"] = Field(
        "auto", description=POINT_TIMES_DESCRIPTION
    )
    sweep: SweepOptions = Field(
        default_factory=SweepOptions,
        description="spinning-lidar sweep timing, as sweep.KEY=VALUE (listed below)",
    )
    point_clouds: bool = Field(True, description="emit the clouds themselves in the stream")
    max_frames: int | None = Field(None, ge=1, description="stop after this many clouds")
    odometry: bool = Field(True, description="KISS-ICP odometry")
    corners: bool = Field(True, description="corner landmarks")
    warmup_frames: int = Field(
        1, ge=0, description="withhold the corners of this many first frames (not yet deskewable)"
    )
    kiss: KissIcpSettings = Field(
        default_factory=KissIcpSettings,
        description="KISS-ICP settings, as kiss.KEY=VALUE (listed below)",
    )
    corner: CornerConfig = Field(
        default_factory=CornerConfig,
        description="corner extractor settings, as corner.KEY=VALUE (listed below)",
    )
    confirm_corners: bool = Field(
        True,
        description="emit a corner only once it is found again where it was in the previous frame (KISS-ICP's poses; datasets.lidar.corner_tracking): the outline of a car slides with the viewpoint and is never a landmark",
    )

    def front_end_settings(self) -> FrontEndSettings:
        """The front end's share of these options."""
        return FrontEndSettings(
            **{
                name: getattr(self, name)
                for name in FrontEndSettings.model_fields
                if name in type(self).model_fields
            }
        )


def describe_lidar_options(model: type[LidarSourceOptions]) -> list[str]:
    """Option lines of a lidar source for ``workbench list --verbose``: its own, then the
    nested sweep timing, KISS-ICP and corner settings as ``sweep.KEY``, ``kiss.KEY`` and
    ``corner.KEY``."""
    from datasets.options import describe_model

    return (
        describe_model(model)
        + [f"sweep.{line}" for line in describe_model(SweepOptions)]
        + [f"kiss.{line}" for line in describe_model(KissIcpSettings)]
        + [f"corner.{line}" for line in describe_model(CornerConfig)]
    )
