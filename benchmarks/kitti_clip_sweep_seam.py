"""Are the real KITTI clips' clouds motion-compensated? Two measurements that need neither
per-point times nor truth.

1. The decision the loaders make by default (``datasets.lidar.sweep_timing``, any spinning
   lidar: rings from elevation, the expected steps from the clouds' own motion), run on
   every window of ``--frames`` consecutive scans of both clips (``--decide``, the default).
   With 10 scans, every window of both clips (0-9, 10-19, 20-29; b: 0-9, 10-19) reads raw,
   clockwise from 173-182 deg (rings cutting at 167-187 deg: the HDL-64E lasers' azimuth
   offsets), 4-19 rings clockwise against 0-2 counterclockwise, no compensated cut on the
   ground (at most in 11-40 % of the clouds at one azimuth; 70 % needed), 0.61-0.82 m of
   travel per sweep.
2. The first check (``--seam``), KITTI-specific: a spinning lidar's sweep that is
   compensated to one time shows a range step at its seam, where the sweep's first and last
   points meet, of the distance travelled in the sweep projected on the ray; an
   uncompensated one shows none on the ground, whatever the motion (every point is where the
   sensor saw it from, so flat ground stays a circle of constant range). For each ground
   ring (median elevation below -8 deg; the clip stores its 64 rings one after the other,
   each from straight ahead counterclockwise: file order, which only KITTI's files promise),
   the ranges of neighbouring points in azimuth are differenced, and the median difference
   across the rings and the clip's frames is taken in 2 deg azimuth windows all round. The
   same measurement on the clouds after a synthetic compensation (KITTI raw's timing,
   ``datasets.lidar.sweep_times.azimuth_point_times``: the seam behind; 0.61 m forward per
   sweep, the clip's speed) shows the step the test looks for. On the first clip (every
   third scan): largest median step 0.023 m (at -134 deg; typical 0.006) as read, 0.611 m at
   the seam behind after the synthetic compensation (typical 0.005).

The clips' clouds are not compensated: the loaders time them by azimuth by default.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/kitti_clip_sweep_seam.py [--seam] [--every 3]
       [--frames 10]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from datasets.lidar.kiss_icp_odometry import deskew_to_end
from datasets.lidar.sweep_times import azimuth_point_times
from datasets.lidar.sweep_timing import decide_sweep_timing
from datasets.measurements import PointCloud
from datasets.scan_folder import read_scan

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
CLIP = DATA / "kitti-hdl64-clip"
CLIPS = ("kitti-hdl64-clip", "kitti-hdl64-clip-b")
WINDOW_DEG = 2.0
GROUND_ELEVATION_DEG = -8.0


def ring_blocks(points: np.ndarray) -> list[np.ndarray]:
    """Index blocks (k,) of the clip's rings: each starts where the azimuth crosses from
    negative to non-negative (straight ahead) in the file's order."""
    azimuth = np.arctan2(points[:, 1], points[:, 0])
    negative = azimuth < 0.0
    starts = np.flatnonzero(negative[:-1] & ~negative[1:] & (np.abs(np.diff(azimuth)) < 0.2)) + 1
    return np.split(np.arange(len(points)), starts)


def window_steps(points: np.ndarray, blocks: list[np.ndarray]) -> list[list[float]]:
    """Per azimuth window (360 / WINDOW_DEG of them, the first at -180 deg): the median range
    just before minus just after the window's start (1 deg either side), one value per ground
    ring that has three points on each side."""
    edges = np.arange(-180.0, 180.0, WINDOW_DEG)
    steps: list[list[float]] = [[] for _ in edges]
    for block in blocks:
        ring = points[block]
        ranges = np.hypot(ring[:, 0], ring[:, 1])
        if len(ring) < 1000 or np.median(np.degrees(np.arctan2(ring[:, 2], ranges))) > (
            GROUND_ELEVATION_DEG
        ):
            continue
        azimuth = np.degrees(np.arctan2(ring[:, 1], ring[:, 0]))
        for index, edge in enumerate(edges):
            offset = (azimuth - edge + 180.0) % 360.0 - 180.0
            before, after = (offset < 0) & (offset > -1.0), (offset >= 0) & (offset < 1.0)
            if before.sum() >= 3 and after.sum() >= 3:
                steps[index].append(float(np.median(ranges[before]) - np.median(ranges[after])))
    return steps


def largest_step(
    clouds: list[np.ndarray], block_source: list[np.ndarray]
) -> tuple[float, float, float]:
    """(largest |median step| [m], its window's azimuth [deg], the windows' median |step| [m])."""
    edges = np.arange(-180.0, 180.0, WINDOW_DEG)
    pooled: list[list[float]] = [[] for _ in edges]
    for cloud, source in zip(clouds, block_source, strict=True):
        for index, values in enumerate(window_steps(cloud, ring_blocks(source))):
            pooled[index].extend(values)
    medians = np.array([np.median(values) for values in pooled])
    worst = int(np.argmax(np.abs(medians)))
    return float(medians[worst]), float(edges[worst]), float(np.median(np.abs(medians)))


def decide(frames: int) -> None:
    """The default decision on every window of ``frames`` scans of both clips."""
    for name in CLIPS:
        files = sorted((DATA / name).glob("*.pcd"))
        for first in range(0, len(files) - frames + 1, frames):
            clouds = [
                PointCloud(t=0.1 * k, points=read_scan(path, 0.0).points)
                for k, path in enumerate(files[first : first + frames])
            ]
            decision = decide_sweep_timing(clouds, 0.1)
            evidence = decision.evidence
            print(
                f"{name} scans {first}-{first + frames - 1}: {decision.outcome}"
                + (f", {decision.azimuth.describe()}" if decision.azimuth is not None else "")
                + f"; raw-cut rings clockwise {evidence['raw_cut_rings_clockwise']}, "
                f"counterclockwise {evidence['raw_cut_rings_counterclockwise']}"
                + (
                    f" (at {evidence['cut_spread_deg'][0]:.0f}-{evidence['cut_spread_deg'][1]:.0f}"
                    " deg)"
                    if "cut_spread_deg" in evidence
                    else ""
                )
                + f"; compensated cut in {100 * evidence['compensated_cut_clouds_fraction']:.0f} %"
                f" of the clouds at most; travel {evidence['travel_m_per_sweep']:.3f} m/sweep"
            )


def seam(every: int, travel: float) -> None:
    """The first, KITTI-specific check (module docstring) on the first clip."""
    files = sorted(CLIP.glob("*.pcd"))[::every]
    clouds = [read_scan(path, 0.0).points for path in files]
    step, at, typical = largest_step(clouds, clouds)
    print(f"as read: largest median step {step:+.3f} m at {at:.0f} deg (typical {typical:.3f} m)")
    delta = np.eye(4)
    delta[0, 3] = travel
    compensated = []
    for cloud in clouds:
        # KITTI raw timing normalised to the sweep, moved to its end, then back to mid-sweep
        fraction = azimuth_point_times(cloud, 1.0) + 0.5
        moved = deskew_to_end(cloud, fraction, delta)
        moved[:, 0] += 0.5 * travel
        compensated.append(moved)
    step, at, typical = largest_step(compensated, clouds)
    print(
        f"after a synthetic compensation ({travel} m a sweep): largest median step "
        f"{step:+.3f} m at {at:.0f} deg (typical {typical:.3f} m)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seam", action="store_true", help="the first, KITTI-specific check")
    parser.add_argument("--every", type=int, default=3, help="--seam: use every n-th scan")
    parser.add_argument("--travel", type=float, default=0.61, help="synthetic travel per sweep [m]")
    parser.add_argument("--frames", type=int, default=10, help="scans per decision")
    args = parser.parse_args()
    if args.seam:
        seam(args.every, args.travel)
    else:
        decide(args.frames)


if __name__ == "__main__":
    main()
