"""``Trajectory``: timed poses with optional covariances, for ground truth and estimates alike."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from datasets.rotations import matrix_from_quat_wxyz, rot2_batch


@dataclass(frozen=True)
class Trajectory:
    """Poses over time. Immutable: operations return new objects.

    Attributes:
        t: times [s], shape (N,), non-decreasing.
        positions: world-frame positions [m], shape (N, d), d = 2 or 3.
        rotations: 3-D: body-to-world quaternions (w, x, y, z), shape (N, 4);
            2-D: heading angles [rad], shape (N,).
        covariances: pose covariances or None. 3-D: shape (N, 6, 6), order [rotation,
            translation], both perturbations in the body frame (GTSAM Pose3 tangent, right
            perturbation). 2-D: shape (N, 3, 3), order [x, y, theta], right perturbation
            (GTSAM Pose2).
    """

    t: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray
    covariances: np.ndarray | None = None

    def __post_init__(self) -> None:
        count = len(self.t)
        if self.positions.shape[0] != count or self.rotations.shape[0] != count:
            raise ValueError(
                f"Trajectory arrays disagree in length: t {count}, positions "
                f"{self.positions.shape[0]}, rotations {self.rotations.shape[0]}"
            )
        if self.positions.ndim != 2 or self.positions.shape[1] not in (2, 3):
            raise ValueError(f"positions must be (N, 2) or (N, 3), got {self.positions.shape}")
        expected = (count, 4) if self.dimension == 3 else (count,)
        if self.rotations.shape != expected:
            raise ValueError(f"rotations must have shape {expected}, got {self.rotations.shape}")
        if self.covariances is not None:
            size = self.pose_dof
            if self.covariances.shape != (count, size, size):
                raise ValueError(
                    f"covariances must have shape {(count, size, size)}, "
                    f"got {self.covariances.shape}"
                )

    @property
    def dimension(self) -> int:
        """2 for planar, 3 for spatial trajectories."""
        return int(self.positions.shape[1])

    @property
    def pose_dof(self) -> int:
        """Degrees of freedom of one pose: 3 (planar) or 6 (spatial)."""
        return 3 if self.dimension == 2 else 6

    def __len__(self) -> int:
        return len(self.t)

    def rotation_matrices(self) -> np.ndarray:
        """Body-to-world rotation matrices, shape (N, d, d)."""
        if self.dimension == 3:
            return matrix_from_quat_wxyz(self.rotations).reshape(-1, 3, 3)
        return rot2_batch(self.rotations)

    def homogeneous(self) -> np.ndarray:
        """Poses as homogeneous matrices, shape (N, d+1, d+1)."""
        d = self.dimension
        poses = np.tile(np.eye(d + 1), (len(self), 1, 1))
        poses[:, :d, :d] = self.rotation_matrices()
        poses[:, :d, d] = self.positions
        return poses

    def select(self, indices: np.ndarray | slice) -> Trajectory:
        """A new trajectory with the poses at ``indices``."""
        return Trajectory(
            t=self.t[indices],
            positions=self.positions[indices],
            rotations=self.rotations[indices],
            covariances=None if self.covariances is None else self.covariances[indices],
        )

    def without_covariances(self) -> Trajectory:
        """The same poses with ``covariances=None``."""
        return replace(self, covariances=None)

    def path_length(self) -> float:
        """Length of the polyline through the positions [m]."""
        return float(np.sum(np.linalg.norm(np.diff(self.positions, axis=0), axis=1)))


def trajectory_from_homogeneous(t: np.ndarray, poses: np.ndarray) -> Trajectory:
    """Build a trajectory from homogeneous poses, shape (N, d+1, d+1)."""
    from datasets.rotations import quat_wxyz_from_matrix

    d = poses.shape[1] - 1
    positions = poses[:, :d, d].copy()
    if d == 3:
        rotations = quat_wxyz_from_matrix(poses[:, :3, :3]).reshape(-1, 4)
    else:
        rotations = np.arctan2(poses[:, 1, 0], poses[:, 0, 0])
    return Trajectory(t=np.asarray(t, dtype=float), positions=positions, rotations=rotations)
