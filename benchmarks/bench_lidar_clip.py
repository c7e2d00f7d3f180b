"""Every lidar-only estimator on the real KITTI HDL-64 clip (``../shared/data/kitti-hdl64-clip``,
30 scans, no truth), against KISS-ICP's own trajectory (the clip's natural reference):
largest position deviation (absolute and as a percentage of KISS-ICP's path length), largest
yaw deviation, NIS per dof and time per frame; plus the front end's frames per second
against KISS-ICP alone on the same scans (the same KISS-ICP settings, measured in one run).

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lidar_clip.py [--frames 30] [--data KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from datasets.rotations import matrix_from_quat_wxyz, so3_log
from workbench.registry import load_dataset
from workbench.runner import RunRequest, execute

CLIP = Path(__file__).resolve().parents[2] / "shared" / "data" / "kitti-hdl64-clip"
LIDAR_ONLY = (
    "dead-reckoning",
    "ekf-slam",
    "sensor-based",
    "smoother-isam2",
    "smoother-fixed-lag",
    "smoother-batch",
)


def deviation_from(reference, pose) -> tuple[float, float, float]:
    """(largest position deviation [m], its share of the reference's path length [%],
    largest heading deviation [deg]) of ``pose`` from ``reference``, paired by time."""
    index = np.searchsorted(reference.t, pose.t - 1e-6)
    index = np.clip(index, 0, len(reference.t) - 1)
    position = np.linalg.norm(pose.positions - reference.positions[index], axis=1)
    path = float(np.sum(np.linalg.norm(np.diff(reference.positions, axis=0), axis=1)))
    yaw = []
    for quat, ref_index in zip(pose.rotations, index, strict=True):
        relative = matrix_from_quat_wxyz(reference.rotations[ref_index]).T @ matrix_from_quat_wxyz(
            quat
        )
        yaw.append(abs(np.rad2deg(so3_log(relative)[2])))
    return float(position.max()), 100.0 * float(position.max()) / path, float(max(yaw))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--data", action="append", default=[], help="scans: option KEY=VALUE")
    args = parser.parse_args()
    options = {"max_frames": str(args.frames), **dict(a.split("=", 1) for a in args.data)}
    sequence = load_dataset(f"scans:{CLIP}", 0, options)
    started = time.perf_counter()
    for _ in sequence.measurements():
        pass
    front_seconds = time.perf_counter() - started
    reference = None
    rows = []
    for name in LIDAR_ONLY:
        result = execute(RunRequest(name, f"scans:{CLIP}"), sequence=sequence)
        history = (
            result.estimate.causal if result.estimate.causal.pose else result.estimate.smoothed
        )
        pose = history.pose
        if name == "dead-reckoning":
            reference = pose  # the composition of KISS-ICP's increments: its own trajectory
        timing = result.estimate.timing
        per_frame_ms = 1e3 * float(np.sum(timing.seconds)) / args.frames if timing else float("nan")
        nis = result.estimate.diagnostics
        nis_per_dof = float(np.sum(nis.scan_nis) / max(np.sum(nis.scan_nis_dof), 1))
        rows.append((name, *deviation_from(reference, pose), nis_per_dof, per_frame_ms))
    print(
        f"front end: {args.frames} frames in {front_seconds:.2f} s ({args.frames / front_seconds:.1f} frames/s)"
    )
    print(
        f"{'estimator':20s} {'max dev [m]':>11s} {'% path':>7s} {'max yaw [deg]':>13s} {'NIS/dof':>8s} {'ms/frame':>9s}"
    )
    for name, dev, share, yaw, nis_per_dof, ms in rows:
        print(f"{name:20s} {dev:11.3f} {share:7.2f} {yaw:13.3f} {nis_per_dof:8.3f} {ms:9.2f}")


if __name__ == "__main__":
    main()
