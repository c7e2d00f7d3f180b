"""Lidar front-end speed on 64k-point clouds: reading, KISS-ICP, corner extraction.

Writes a synthetic corridor bag with a 32-beam x 2048-column lidar (65,536 rays a sweep;
misses are dropped, so clouds hold somewhat fewer points), then times, per frame:
- reading: rosbags read + deserialize + PointCloud2 decode (``read_stream``),
- KISS-ICP: ``KissIcpOdometry.register`` (deskew, voxelize, ICP, map update),
- corners: the front end's corner step (azimuth scan, deskew of the scan points, extraction),
and prints frames per second and the corner/KISS-ICP cost ratio (target: below 20 %),
plus the front end's corner precision/recall and KISS-ICP ATE on that bag.

Usage: python benchmarks/bench_lidar.py [--frames 20] [--threads 1] [--format ros1|ros2]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from datasets.bags.read_report import ReadReport, ReadSettings
from datasets.bags.reader import read_stream
from datasets.lidar.corner_truth import read_corner_truth, score_corners, sidecar_for
from datasets.lidar.frontend import LidarFrontEnd
from datasets.lidar.frontend_settings import FrontEndSettings
from datasets.lidar.kiss_icp_odometry import KissIcpSettings
from datasets.synthetic_lidar import write_lidar_bag


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--threads", type=int, default=1, help="KISS-ICP threads (0: automatic)")
    parser.add_argument("--format", default="ros1", choices=("ros1", "ros2"))
    parser.add_argument(
        "--start", type=float, default=5.0, help="where along the loop to start [s]"
    )
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as folder:
        started = time.perf_counter()
        bag = write_lidar_bag(
            Path(folder) / "bench",
            0,
            args.format,
            {
                "duration_s": str(args.frames / 10.0),
                "start_s": str(args.start),
                "beams": "32",
                "columns": "2048",
                "imu_rate_hz": "100",
            },
        )
        print(
            f"wrote {args.frames} sweeps of 32 x 2048 rays in {time.perf_counter() - started:.1f} s ({args.format})"
        )

        started = time.perf_counter()
        clouds = [m for _, m in read_stream(bag, ["/points"], ReadSettings(), ReadReport())]
        read_seconds = time.perf_counter() - started
        points = np.mean([len(c.points) for c in clouds])

        front_end = LidarFrontEnd(
            FrontEndSettings(kiss=KissIcpSettings(max_num_threads=args.threads))
        )
        for index, cloud in enumerate(clouds):
            front_end.frame(index, cloud)
        icp = np.array([f.icp_seconds for f in front_end.frames])
        corner = np.array([f.corner_seconds for f in front_end.frames])

        print(f"points per cloud (finite): {points:.0f}")
        print(
            f"reading:          {len(clouds) / read_seconds:8.1f} frames/s  ({1000 * read_seconds / len(clouds):.1f} ms/frame)"
        )
        print(
            f"KISS-ICP:         {1 / icp.mean():8.1f} frames/s  ({1000 * icp.mean():.1f} ms/frame, median {1000 * np.median(icp):.1f}, threads={args.threads})"
        )
        print(
            f"corner extraction:{1 / corner.mean():8.1f} frames/s  ({1000 * corner.mean():.2f} ms/frame, median {1000 * np.median(corner):.2f})"
        )
        print(
            f"corner / KISS-ICP time per frame: {100 * corner.mean() / icp.mean():.1f} % (median ratio {100 * np.median(corner / icp):.1f} %)"
        )

        from datasets.bags.ground_truth import read_ground_truth
        from datasets.trajectory import Trajectory
        from workbench.metrics.ate import ate_report

        t, positions, quats = read_ground_truth(bag, "/ground_truth", ReadReport())
        truth = Trajectory(t, positions, quats)
        config = front_end.settings.corner
        scores = score_corners(
            [(f.t, f.corners.points) for f in front_end.frames],
            read_corner_truth(sidecar_for(bag)),
            truth,
            config.min_range_m,
            config.max_range_m,
            config.azimuth_resolution_deg,
        )
        ate = ate_report(
            truth, front_end.trajectory(), align="se3", max_diff_s=0.05, allow_degenerate=True
        )["rmse_m"]
        print(
            f"corner precision {scores['corner_precision']:.3f}, recall {scores['corner_recall']:.3f} ({scores['detections']} detections, {scores['observable']} observable); KISS-ICP ATE {ate:.3f} m"
        )


if __name__ == "__main__":
    main()
