"""Are the real KITTI clip's clouds motion-compensated? A test that needs neither per-point
times nor truth: a spinning lidar's sweep that is compensated to one time shows a range step
at its seam, where the sweep's first and last points meet, of the distance travelled in the
sweep projected on the ray; an uncompensated one shows none, whatever the motion (every
point is where the sensor saw it from, so flat ground stays a circle of constant range).

For each ground ring (median elevation below -8 deg; the clip stores its 64 rings one after
the other, each from straight ahead counterclockwise), the ranges of neighbouring points in
azimuth are differenced, and the median difference across the rings and the clip's frames is
taken in 2 deg azimuth windows all round. A compensated seam anywhere but within a few
degrees of the sides would stand out from the windows' typical 5 mm. The same measurement on
the clouds after a synthetic compensation (KITTI raw's timing, ``datasets.lidar.sweep_times
.azimuth_point_times``: the seam behind; 0.61 m forward per sweep, the clip's speed) shows the
step the test looks for.

On the clip (every third scan): largest median step 0.023 m (at -134 deg; typical 0.006) as
read, 0.611 m at the seam behind after the synthetic compensation (typical 0.005). The clip's clouds are not compensated, whatever
its readme says; ``--data point_times=azimuth`` reads them as what they are.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/kitti_clip_sweep_seam.py [--every 3]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from datasets.lidar.kiss_icp_odometry import deskew_to_end
from datasets.lidar.sweep_times import azimuth_point_times
from datasets.scan_folder import read_scan

CLIP = Path(__file__).resolve().parents[2] / "shared" / "data" / "kitti-hdl64-clip"
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--every", type=int, default=3, help="use every n-th scan")
    parser.add_argument("--travel", type=float, default=0.61, help="synthetic travel per sweep [m]")
    args = parser.parse_args()
    files = sorted(CLIP.glob("*.pcd"))[:: args.every]
    clouds = [read_scan(path, 0.0).points for path in files]
    step, at, typical = largest_step(clouds, clouds)
    print(f"as read: largest median step {step:+.3f} m at {at:.0f} deg (typical {typical:.3f} m)")
    delta = np.eye(4)
    delta[0, 3] = args.travel
    compensated = []
    for cloud in clouds:
        # KITTI raw timing normalised to the sweep, moved to its end, then back to mid-sweep
        fraction = azimuth_point_times(cloud, 1.0) + 0.5
        moved = deskew_to_end(cloud, fraction, delta)
        moved[:, 0] += 0.5 * args.travel
        compensated.append(moved)
    step, at, typical = largest_step(compensated, clouds)
    print(
        f"after a synthetic compensation ({args.travel} m a sweep): largest median step "
        f"{step:+.3f} m at {at:.0f} deg (typical {typical:.3f} m)"
    )


if __name__ == "__main__":
    main()
