"""Every lidar-only estimator on the real KITTI HDL-64 clip (``../shared/data/kitti-hdl64-clip``,
30 scans, no truth), against KISS-ICP's own trajectory (the clip's natural reference):
largest position deviation (absolute and as a percentage of KISS-ICP's path length), largest
yaw deviation, NIS per dof and time per frame; the yaw-rate error of KISS-ICP that the
corners' re-observations imply (what the estimators' yaw deviation follows); plus the front
end's frames per second against KISS-ICP alone with its own defaults on the same scans (both read the files with the
same reader; the two interleaved frame by frame, measured in one run; the median of the
per-round ratios), and the largest difference of their poses.

The corners' disagreement with KISS-ICP is theirs, not KISS-ICP's
(``benchmarks/kitti_clip_registration_check.py``); ``--data point_times=azimuth`` takes the
clouds as uncompensated KITTI raw sweeps (``datasets.lidar.increment_noise`` gives the
figures). Its speed line then compares a deskewing front end with KISS-ICP alone without.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lidar_clip.py [--frames 30] [--data KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from datasets.rotations import matrix_from_quat_wxyz, so3_log
from workbench.commands.bag_estimators import choose_estimators
from workbench.registry import load_dataset
from workbench.runner import RunRequest, execute

CLIP = Path(__file__).resolve().parents[2] / "shared" / "data" / "kitti-hdl64-clip"


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


def front_end_speed(frames: int, rounds: int, data: dict[str, str]):
    """Print frames/s of KISS-ICP alone (``KISSConfig()``, voxel = range / 100 as its
    pipeline sets it) and of the front end (KISS-ICP + corners + confirmation, the whole
    ``scans:`` stream) with the ``scans:`` defaults (or ``data``), and their largest pose
    difference. The two run interleaved frame by frame (the front end's stream is pulled
    until it has made a frame, then KISS-ICP alone registers the same file), so that a slow
    spell of this 2-core machine falls on both: timing whole rounds one after the other gave
    per-round ratios of 0.81-1.18 and medians of 0.90 and 1.08 in two runs of 15 rounds.
    Returns the last round's ``LidarSource`` (its front end has run every frame)."""
    from kiss_icp.config import KISSConfig
    from kiss_icp.kiss_icp import KissICP

    from datasets.options import nest_dotted
    from datasets.scan_folder import ScanFolderOptions, read_scan, scans_sequence

    files = sorted(CLIP.glob("*.pcd"))[:frames]
    options = ScanFolderOptions.model_validate(nest_dotted({"max_frames": str(frames), **data}))
    alone_seconds, front_seconds, difference = [], [], 0.0
    for round_index in range(rounds + 1):  # the first round warms caches and imports
        config = KISSConfig()
        config.mapping.voxel_size = config.data.max_range / 100.0
        alone = KissICP(config)
        poses = []
        sequence, source = scans_sequence(str(CLIP), options)
        stream = iter(sequence.measurements())
        alone_total = front_total = 0.0
        exhausted = False
        while not exhausted:
            made = len(source.front_end.frames)
            started = time.perf_counter()
            while len(source.front_end.frames) == made:
                if next(stream, None) is None:
                    exhausted = True
                    break
            front_total += time.perf_counter() - started
            if len(poses) < len(source.front_end.frames):
                started = time.perf_counter()
                alone.register_frame(read_scan(files[len(poses)], 0.0).points, np.zeros(0))
                poses.append(np.array(alone.last_pose))
                alone_total += time.perf_counter() - started
        if round_index > 0:
            alone_seconds.append(alone_total)
            front_seconds.append(front_total)
        ours = np.array([frame.pose for frame in source.front_end.frames])
        difference = max(difference, float(np.max(np.abs(ours - np.array(poses)))))
    alone_seconds, front_seconds = np.array(alone_seconds), np.array(front_seconds)
    corner_ms = 1e3 * sum(f.corner_seconds for f in source.front_end.frames) / len(files)
    ratios = alone_seconds / front_seconds
    print(
        f"KISS-ICP alone: {len(files) / np.median(alone_seconds):.1f} frames/s; front end: "
        f"{len(files) / np.median(front_seconds):.1f} frames/s (corners {corner_ms:.2f} ms/frame); "
        f"ratio {np.median(ratios):.3f} (median of {rounds} rounds interleaved frame by frame, "
        f"range {np.min(ratios):.3f}-{np.max(ratios):.3f}); "
        f"largest pose difference {difference:.1e} m"
    )
    return source


def corner_yaw_rate(source) -> None:
    """Print the constant yaw-rate error of KISS-ICP that the corners' re-observations imply
    (``LidarFrontEnd.corner_yaw_rate``), from the front end the speed rounds ran."""
    times = np.array([frame.t for frame in source.front_end.frames])
    omega, error = source.front_end.corner_yaw_rate()
    print(
        f"corners' re-observations imply a KISS-ICP yaw-rate error of {np.rad2deg(omega):+.3f} "
        f"+- {np.rad2deg(error):.3f} deg/s (jackknife over corners), "
        f"{np.rad2deg(omega) * (times[-1] - times[0]):+.2f} deg over the {times[-1] - times[0]:.1f} s"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--data", action="append", default=[], help="scans: option KEY=VALUE")
    parser.add_argument(
        "--rounds", type=int, default=15, help="speed rounds of each (five are noise-dominated)"
    )
    parser.add_argument("--speed-only", action="store_true", help="only the front-end speed")
    args = parser.parse_args()
    source = front_end_speed(args.frames, args.rounds, dict(a.split("=", 1) for a in args.data))
    if args.speed_only:
        return
    corner_yaw_rate(source)
    options = {"max_frames": str(args.frames), **dict(a.split("=", 1) for a in args.data)}
    sequence = load_dataset(f"scans:{CLIP}", 0, options)
    started = time.perf_counter()
    for _ in sequence.measurements():
        pass
    front_seconds = time.perf_counter() - started
    reference = None
    rows = []
    # every registered estimator the clip allows (as `workbench bag` chooses), dead-reckoning
    # first: its pose is the reference
    for name in choose_estimators(None, sequence):
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
