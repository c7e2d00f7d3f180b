"""KISS-ICP's frame-to-frame error on the synthetic lidar bag under three deskews: KISS-ICP's
own constant-velocity prediction (``--data imu_deskew=false``), the IMU's rotation (the
default with an IMU topic, ``datasets.lidar.imu_deskew``), and the *true* motion, an upper
bound no deskew can beat (each point moved to its sweep end by the simulator's poses, the
cloud then handed to KISS-ICP stamped there, without times).

Errors are against the truth topic: per frame, the yaw of KISS-ICP's rotation increment
against the true one [deg] and the forward error of its translation [cm]; the front end's
own time per frame (KISS-ICP and the deskew) [ms].

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lidar_imu_deskew.py [--seeds 0 1 2]
    [--duration 8] [--gyro-bias X Y Z]
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

import datasets.lidar.frontend as frontend
from datasets.bags.bag_options import BagOptions
from datasets.bags.source import bag_sequence
from datasets.lidar.corner_truth import interpolate_poses
from datasets.lidar.kiss_icp_odometry import KissIcpOdometry
from datasets.measurements import Odometry, PointCloud
from datasets.options import nest_dotted
from datasets.rotations import matrix_from_quat_wxyz, so3_exp, so3_log
from datasets.synthetic_lidar import write_lidar_bag

MODES = ("kiss-icp", "imu", "truth")


def pose_at(truth, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(R (3, 3), p (3,)) of the true body pose at ``t`` [s]."""
    position, quaternion = interpolate_poses(truth, np.array([t]))
    return matrix_from_quat_wxyz(quaternion[0]), position[0]


def truth_deskewed(cloud: PointCloud, truth) -> PointCloud:
    """``cloud`` moved to its sweep end by the true poses, stamped there, without times."""
    times = cloud.t + np.asarray(cloud.point_times)
    end = float(times.max())
    rotation_end, position_end = pose_at(truth, end)
    points = np.empty_like(cloud.points)
    unique, inverse = np.unique(np.round(times, 7), return_inverse=True)
    for index, t in enumerate(unique):
        rotation, position = pose_at(truth, t)
        selected = inverse == index
        points[selected] = (
            rotation_end.T
            @ (rotation @ cloud.points[selected].T + (position - position_end)[:, None])
        ).T
    return PointCloud(t=end, points=points)


def run(seed: int, mode: str, duration: float, gyro_bias: np.ndarray) -> dict[str, float]:
    """One bag, one deskew: the per-frame error figures."""
    options = {"ground_truth_topic": "/ground_truth", "imu_deskew": str(mode == "imu").lower()}
    original_register = KissIcpOdometry.register
    original_add_imu = frontend.LidarFrontEnd.add_imu
    with tempfile.TemporaryDirectory() as folder:
        bag = write_lidar_bag(Path(folder) / "bag", seed, "ros2", {"duration_s": str(duration)})
        sequence, source = bag_sequence(str(bag), BagOptions.model_validate(nest_dotted(options)))
        truth = sequence.ground_truth.pose
        if mode == "truth":
            KissIcpOdometry.register = lambda self, cloud: original_register(
                self,
                truth_deskewed(cloud, truth) if cloud.point_times is not None else cloud,
            )
        frontend.LidarFrontEnd.add_imu = lambda self, sample: original_add_imu(
            self, replace(sample, gyro=sample.gyro + gyro_bias)
        )
        try:
            measurements = list(sequence.measurements())
        finally:
            KissIcpOdometry.register = original_register
            frontend.LidarFrontEnd.add_imu = original_add_imu
    yaw, forward = [], []
    for item in measurements:
        if not isinstance(item, Odometry):
            continue
        (rotation0, position0), (rotation1, position1) = (
            pose_at(truth, item.t - item.dt),
            pose_at(truth, item.t),
        )
        error = item.relative_pose[3:] - rotation0.T @ (position1 - position0)
        rotation_error = (rotation0.T @ rotation1).T @ so3_exp(item.relative_pose[:3])
        yaw.append(np.degrees(so3_log(rotation_error)[2]))
        forward.append(100.0 * error[0])
    frames = source.front_end.frames
    yaw, forward = np.array(yaw), np.array(forward)
    return {
        "yaw_rms_deg": float(np.sqrt(np.mean(yaw**2))),
        "yaw_max_deg": float(np.max(np.abs(yaw))),
        "forward_first10_cm": float(np.mean(forward[:10])),
        "forward_rms_after20_cm": float(np.sqrt(np.mean(forward[20:] ** 2))),
        "ms_per_frame": 1e3 * float(np.mean([frame.icp_seconds for frame in frames])),
        "fallback_frames": len(source.front_end.imu_fallback_stamps),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--duration", type=float, default=8.0)
    parser.add_argument(
        "--gyro-bias",
        type=float,
        nargs=3,
        default=[0.0, 0.0, 0.0],
        help="added to every gyro sample [rad/s] (the simulator's IMU has none)",
    )
    args = parser.parse_args()
    bias = np.array(args.gyro_bias)
    results: dict[str, list[dict[str, float]]] = {mode: [] for mode in MODES}
    for seed in args.seeds:
        for mode in MODES:
            figures = run(seed, mode, args.duration, bias)
            results[mode].append(figures)
            print(
                f"seed {seed} {mode:9s} yaw RMS {figures['yaw_rms_deg']:.4f} deg "
                f"(max {figures['yaw_max_deg']:.3f}), forward frames 1-10 "
                f"{figures['forward_first10_cm']:+.2f} cm, RMS after 20 "
                f"{figures['forward_rms_after20_cm']:.2f} cm, KISS-ICP + deskew "
                f"{figures['ms_per_frame']:.1f} ms/frame, IMU fallbacks "
                f"{figures['fallback_frames']}",
                flush=True,
            )
    print(f"\n{len(args.seeds)} bags of {args.duration:g} s, gyro bias added {list(bias)} rad/s")
    for mode in MODES:
        rows = results[mode]
        print(
            f"{mode:9s} yaw RMS {np.mean([r['yaw_rms_deg'] for r in rows]):.4f} deg, "
            f"max {np.max([r['yaw_max_deg'] for r in rows]):.3f}; forward RMS after 20 "
            f"{np.mean([r['forward_rms_after20_cm'] for r in rows]):.2f} cm; "
            f"{np.mean([r['ms_per_frame'] for r in rows]):.1f} ms/frame"
        )


if __name__ == "__main__":
    main()
