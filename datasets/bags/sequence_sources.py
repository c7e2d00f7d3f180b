"""What stands behind a bag's or a scan folder's ``Sequence`` besides its stream: the front
end that made its odometry and corners, and what the last pass over the stream skipped
(``LidarSource``), for the loader's metadata and ``workbench bag``'s front-end report to read
once the stream has run.
"""

from __future__ import annotations

from datasets.bags.read_report import ReadReport
from datasets.lidar.frontend import LidarFrontEnd


class LidarSource:
    """A bag or scan folder with its front end; remembers what the last pass skipped."""

    def __init__(self, front_end: LidarFrontEnd, lidar_messages: int | None = None) -> None:
        """``lidar_messages``: the clouds the bag's index lists on its lidar topic (for a
        progress bar; None where unknown)."""
        self.front_end = front_end
        self.report = ReadReport()
        self.lidar_messages = lidar_messages

    def record_warnings(self, warnings: list[str]) -> None:
        """Add the last pass's skips and the front end's heading, warm-up and IMU deskew
        warnings to ``warnings`` (``datasets.Sequence`` metadata), each once however often
        the stream is read."""
        front_end = [
            self.front_end.heading_warning(),
            self.front_end.settling_warning(),
            self.front_end.imu_deskew_warning(),
        ]
        for line in [*self.report.lines(), *(line for line in front_end if line)]:
            if line not in warnings:
                warnings.append(line)
