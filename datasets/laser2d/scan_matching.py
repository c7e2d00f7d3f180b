"""KISS-ICP on 2-D laser scans (planar points at z = 0), for comparison with wheel odometry.

The 2-D laser path's motion input is the log's wheel odometry; scan matching is not used by
default. The evidence (``benchmarks/bench_carmen.py --scan-matching``, ``docs/laser2d.md``):
KISS-ICP (``datasets.lidar.kiss_icp_odometry``, its defaults, one thread, no deskew: a
laser line carries no per-beam times) registers these logs at several hundred scans per
second, but on the planar points of a 5 Hz SICK whose robot turns fast it loses track: on
Freiburg 079 its per-scan heading differs from the odometry's by more than 8.5 deg on a
tenth of the scans, and on MIT CSAIL it spins (hundreds of radians of heading over the log),
while on Intel it follows the odometry to a third of a degree per scan, no worse in the
corridors than elsewhere. A motion input that fails on two logs of three is no default.
"""

from __future__ import annotations

import time

import numpy as np

from datasets.laser2d.scan import PlanarScan, laser_to_body
from datasets.lidar.kiss_icp_odometry import KissIcpOdometry, KissIcpSettings
from datasets.measurements import PointCloud


def planar_kiss_icp(
    scans: list[PlanarScan], settings: KissIcpSettings | None = None
) -> tuple[np.ndarray, np.ndarray, float]:
    """KISS-ICP over ``scans`` (their returns in the body frame, z = 0).

    Returns:
        times (n,) [s], planar poses (n, 3) (x [m], y [m], heading [rad]; world = the first
        scan's body frame) and the registration rate [scans/s].
    """
    settings = settings or KissIcpSettings(max_num_threads=1, deskew=False)
    odometry = KissIcpOdometry(settings)
    poses, times = [], []
    started = time.perf_counter()
    for scan in scans:
        points, _ = scan.laser_points()
        rotation, translation = laser_to_body(scan.mounting)
        body = points @ rotation.T + translation
        cloud = np.column_stack([body, np.zeros(len(body))])
        frame = odometry.register(PointCloud(t=scan.t, points=cloud))
        pose = frame.pose
        poses.append([pose[0, 3], pose[1, 3], np.arctan2(pose[1, 0], pose[0, 0])])
        times.append(scan.t)
    elapsed = time.perf_counter() - started
    return np.array(times), np.array(poses), len(scans) / max(elapsed, 1e-9)
