"""An independent check of KISS-ICP's heading on the real KITTI HDL-64 clip
(``../shared/data/kitti-hdl64-clip``, no truth): each checkpoint frame registered directly
to the first one, at full resolution, by a point-to-plane ICP that shares nothing with
KISS-ICP but the clouds.

Why: on the clip the corners' re-observations disagree with KISS-ICP's yaw rate
(``LidarFrontEnd.corner_yaw_rate``: -0.41 +- 0.10 deg/s, -1.2 deg over the 2.9 s), and every
estimator, weighing the two, ends up to 0.7 deg from KISS-ICP. Which side is wrong decides
whether that 0.7 deg is a correction or an error. KISS-ICP composes frame-to-map increments
on a 1 m voxel map; this check registers frame ``k`` to frame 0 in one step (no composition,
no map), on 0.15 m voxels, from KISS-ICP's pose and from starts rotated +-0.5 deg, with a
Huber kernel (0.1 m) on point-to-plane residuals against planar target neighbourhoods.

What it does not check: anything both methods share. Both read the clouds as they are, so a
distortion of the clouds themselves (their motion compensation) would bias both alike.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/kitti_clip_registration_check.py
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from datasets.options import nest_dotted
from datasets.rotations import so3_exp
from datasets.scan_folder import ScanFolderOptions, read_scan, scans_sequence

CLIP = Path(__file__).resolve().parents[2] / "shared" / "data" / "kitti-hdl64-clip"
VOXEL_M = 0.15
RANGE_M = (3.0, 60.0)
HUBER_M = 0.1
MATCH_M = 1.0
MIN_PLANARITY = 0.3


def voxel_sample(points: np.ndarray) -> np.ndarray:
    """The points within ``RANGE_M``, one per ``VOXEL_M`` voxel (KISS-ICP's own downsampler,
    only the sampling: no map, no registration), (m, 3) [m]."""
    from kiss_icp.voxelization import voxel_down_sample

    ranges = np.linalg.norm(points, axis=1)
    return voxel_down_sample(points[(ranges > RANGE_M[0]) & (ranges < RANGE_M[1])], VOXEL_M)


class PlaneTarget:
    """The first frame as a point-to-plane target: a KD-tree, each point's normal (smallest
    principal axis of its 12 nearest neighbours) and planarity ((l2 - l1) / l3)."""

    def __init__(self, points: np.ndarray) -> None:
        self.points = points
        self.tree = cKDTree(points)
        _, neighbours = self.tree.query(points, k=12)
        centred = points[neighbours] - points[neighbours].mean(axis=1, keepdims=True)
        values, vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", centred, centred))
        self.normals = vectors[:, :, 0]
        self.planarity = (values[:, 1] - values[:, 0]) / np.maximum(values[:, 2], 1e-12)

    def register(self, source: np.ndarray, start: np.ndarray, iterations: int = 60):
        """Gauss-Newton on SE(3) (left perturbation) from ``start`` (4, 4): the pose, the
        RMS point-to-plane residual [m] and the number of correspondences used."""
        pose = start.copy()
        for _ in range(iterations):
            moved = source @ pose[:3, :3].T + pose[:3, 3]
            distance, index = self.tree.query(moved, distance_upper_bound=MATCH_M)
            found = np.isfinite(distance)
            index = np.where(found, index, 0)
            used = found & (self.planarity[index] > MIN_PLANARITY)
            point, normal = moved[used], self.normals[index[used]]
            residual = np.einsum("ij,ij->i", point - self.points[index[used]], normal)
            jacobian = np.hstack([np.cross(point, normal), normal])
            weight = np.minimum(1.0, HUBER_M / np.maximum(np.abs(residual), 1e-12))
            step = -np.linalg.solve(
                jacobian.T @ (jacobian * weight[:, None]), jacobian.T @ (weight * residual)
            )
            update = np.eye(4)
            update[:3, :3] = so3_exp(step[:3])
            update[:3, 3] = step[3:]
            pose = update @ pose
            if np.linalg.norm(step) < 1e-8:
                break
        return pose, float(np.sqrt(np.mean(residual**2))), int(used.sum())


def yaw_deg(pose: np.ndarray) -> float:
    return float(np.degrees(np.arctan2(pose[1, 0], pose[0, 0])))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--every", type=int, default=5, help="checkpoint spacing [frames]")
    args = parser.parse_args()
    files = sorted(CLIP.glob("*.pcd"))[: args.frames]
    options = ScanFolderOptions.model_validate(nest_dotted({"max_frames": str(args.frames)}))
    sequence, source = scans_sequence(str(CLIP), options)
    for _ in sequence.measurements():  # the workbench's own KISS-ICP run, with its defaults
        pass
    kiss = np.array([frame.pose for frame in source.front_end.frames])
    target = PlaneTarget(voxel_sample(read_scan(files[0], 0.0).points))
    print(
        f"{'frame':>5s} {'KISS yaw':>9s} {'ICP yaw':>9s} {'ICP-KISS':>9s} "
        f"{'from -0.5/+0.5 deg':>19s} {'|dp| [m]':>8s} {'RMS [m]':>8s} {'pairs':>6s}"
    )
    checkpoints = list(range(args.every, len(files), args.every))
    if checkpoints[-1] != len(files) - 1:
        checkpoints.append(len(files) - 1)
    for k in checkpoints:
        cloud = voxel_sample(read_scan(files[k], 0.0).points)
        start = np.linalg.inv(kiss[0]) @ kiss[k]
        pose, rms, pairs = target.register(cloud, start)
        perturbed = []
        for offset in (-0.5, 0.5):
            rotated = start.copy()
            rotated[:3, :3] = so3_exp(np.array([0.0, 0.0, np.radians(offset)])) @ start[:3, :3]
            perturbed.append(yaw_deg(target.register(cloud, rotated)[0]))
        print(
            f"{k:5d} {yaw_deg(start):9.3f} {yaw_deg(pose):9.3f} "
            f"{yaw_deg(pose) - yaw_deg(start):+9.3f} {perturbed[0]:9.3f}/{perturbed[1]:<9.3f} "
            f"{np.linalg.norm(pose[:3, 3] - start[:3, 3]):8.3f} {rms:8.3f} {pairs:6d}"
        )
    omega, error = source.front_end.corner_yaw_rate()
    span = source.front_end.frames[-1].t - source.front_end.frames[0].t
    print(
        f"for comparison, the corners' re-observations: {np.degrees(omega):+.3f} +- "
        f"{np.degrees(error):.3f} deg/s, {np.degrees(omega) * span:+.2f} deg over {span:.1f} s"
    )


if __name__ == "__main__":
    main()
