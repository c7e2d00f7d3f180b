"""What stands behind a bag's or a scan folder's ``Sequence`` besides its stream: the front
end that made its odometry and corners, and what the last pass over the stream skipped, for
the stream's ``PassReport`` and ``workbench bag``'s front-end report to read once the stream
has run. ``LidarSource``: a bag with a lidar, or a scan folder (the KISS-ICP and corner front
end); ``SensorSource``: a bag without one (the 2-D laser front end when its scans are used).
"""

from __future__ import annotations

from datasets.bags.read_report import ReadReport
from datasets.laser2d.frontend import Laser2dFrontEnd
from datasets.lidar.frontend import LidarFrontEnd


class LidarSource:
    """A bag or scan folder with its front end; remembers what the last pass skipped."""

    def __init__(self, front_end: LidarFrontEnd, lidar_messages: int | None = None) -> None:
        """``lidar_messages``: the clouds the bag's index lists on its lidar topic (for a
        progress bar; None where unknown)."""
        self.front_end = front_end
        self.report = ReadReport()
        self.lidar_messages = lidar_messages

    def pass_warnings(self) -> list[str]:
        """The last pass's skips and the front end's heading, warm-up and IMU deskew
        warnings (for ``datasets.pass_report.PassReport.record``)."""
        front_end = [
            self.front_end.heading_warning(),
            self.front_end.settling_warning(),
            self.front_end.imu_deskew_warning(),
        ]
        return [*self.report.lines(), *(line for line in front_end if line)]


class SensorSource:
    """What a pass over a bag without lidar skipped (``report``), and the 2-D laser front
    end when its scans are used (else None); ``front_end`` is None (no lidar front end) and
    ``lidar_messages`` None (no lidar topic), as ``LidarSource`` names them."""

    front_end = None
    lidar_messages = None

    def __init__(self, laser_front_end: Laser2dFrontEnd | None = None) -> None:
        self.laser_front_end = laser_front_end
        self.report = ReadReport()

    def pass_warnings(self) -> list[str]:
        """The last pass's skips (for ``datasets.pass_report.PassReport.record``)."""
        return self.report.lines()
