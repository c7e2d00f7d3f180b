"""The prediction a keyframe's scans are associated and scored against: ``KeyframePredictor``,
the ``filters.association.Predictor`` of the smoothers.

A keyframe's motion (and GPS) factors are solved first, so the backend's estimate of the new
pose *is* the prediction and the joint marginal ``J`` of that pose and the landmarks the
scan may see is its covariance (one batched backend query per keyframe). From it the
predictor gives the association policy the predicted measurements ``h_i = R^T (l_i - p)``
and ``H J H^T``, and ``innovation`` gives the stacked NIS of the matched sightings
``nu^T (H J H^T + R)^-1 nu`` with its dof (rows), and each landmark's own: the statistics
every filter records (``filters.kalman.innovation_statistics``).

Jacobians on GTSAM's tangents (right perturbation): 3-D ``Pose3`` [omega, v]:
``dh/domega = [h]x``, ``dh/dv = -I``; 2-D ``Pose2`` [x, y, theta]: ``dh/d(x, y) = -I``,
``dh/dtheta = -J h`` with ``J = [[0, -1], [1, 0]]``; both ``dh/dl = R^T``.
"""

from __future__ import annotations

import numpy as np

from datasets.rotations import PLANAR_GENERATOR
from filters.kalman import Innovation, diagonal_blocks, innovation_statistics
from smoothers.joint_marginals import JointMarginals, JointQuery
from smoothers.landmark_book import MapLandmark


def predicted_measurements(pose, positions: np.ndarray, dimension: int) -> np.ndarray:
    """``h_i = R^T (l_i - p)`` for world positions (m, d) seen from a GTSAM pose, (m, d)."""
    rotation = pose.rotation().matrix()
    return (np.asarray(positions, dtype=float) - np.asarray(pose.translation())) @ rotation


class KeyframePredictor:
    """The association ``Predictor`` of a keyframe (module docstring).

    Args:
        pose: the keyframe's solved pose (``gtsam.Pose3`` or ``Pose2``). pose_key: its key.
        candidates: the m landmarks that may be seen, ``positions`` (m, d) their estimates
            in the world frame [m].
        joint: the backend's batched query, keys -> ``JointMarginals``.
        dimension: d, 2 or 3.

    Attributes:
        predicted: ``h_i`` of every candidate in the body frame (m, d) [m].
    """

    def __init__(
        self,
        pose,
        pose_key: int,
        candidates: list[MapLandmark],
        positions: np.ndarray,
        joint: JointQuery,
        dimension: int,
    ) -> None:
        self.pose = pose
        self.pose_key = pose_key
        self.candidates = candidates
        self.positions = np.asarray(positions, dtype=float).reshape(len(candidates), dimension)
        self.dimension = dimension
        self.rotation_t = pose.rotation().matrix().T
        self.predicted = predicted_measurements(pose, self.positions, dimension)
        self._query = joint
        self._cached: JointMarginals | None = None

    def subset(self, indices: np.ndarray) -> KeyframePredictor:
        """The same prediction restricted to the candidates ``indices`` (no new query)."""
        chosen = [self.candidates[int(i)] for i in indices]
        return KeyframePredictor(
            self.pose,
            self.pose_key,
            chosen,
            self.positions[np.asarray(indices, dtype=int)],
            self._query,
            self.dimension,
        )

    def _marginals(self, indices: np.ndarray) -> JointMarginals:
        """The joint marginal of the pose and ``indices``' landmarks, from the cached query
        when it covers them (one backend query per keyframe in the usual call order)."""
        keys = [self.pose_key] + [self.candidates[int(i)].key for i in indices]
        if self._cached is None or not self._cached.covers(keys):
            self._cached = self._query(keys)
        return self._cached

    def _jacobian(self, indices: np.ndarray) -> np.ndarray:
        """Stacked ``H`` (n d, pose dof + n d) on [pose, landmark_1, ..., landmark_n]."""
        d = self.dimension
        pose_dof = 6 if d == 3 else 3
        count = len(indices)
        jacobian = np.zeros((count * d, pose_dof + count * d))
        for row, index in enumerate(indices):
            h = self.predicted[int(index)]
            rows = slice(row * d, (row + 1) * d)
            if d == 3:
                skew = np.array([[0.0, -h[2], h[1]], [h[2], 0.0, -h[0]], [-h[1], h[0], 0.0]])
                jacobian[rows, :pose_dof] = np.hstack([skew, -np.eye(3)])
            else:
                jacobian[rows, :pose_dof] = np.hstack(
                    [-np.eye(2), (-PLANAR_GENERATOR @ h)[:, None]]
                )
            jacobian[rows, pose_dof + row * d : pose_dof + (row + 1) * d] = self.rotation_t
        return jacobian

    def joint(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(predicted (n, d), ``H J H^T`` (n d, n d)) of the candidates ``indices`` (n,)."""
        indices = np.asarray(indices, dtype=int)
        marginals = self._marginals(indices)
        keys = [self.pose_key] + [self.candidates[int(i)].key for i in indices]
        jacobian = self._jacobian(indices)
        covariance = jacobian @ marginals.matrix(keys) @ jacobian.T
        return self.predicted[indices], 0.5 * (covariance + covariance.T)

    def individual(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(predicted (n, d), each candidate's own block of ``H J H^T`` (n, d, d))."""
        predicted, joint = self.joint(indices)
        return predicted, diagonal_blocks(joint, self.dimension)

    def innovation(
        self, indices: np.ndarray, measured: np.ndarray, noise: np.ndarray
    ) -> Innovation | None:
        """The stacked and per-landmark NIS of the sightings ``measured`` (n, d) [m] with
        noise ``R`` blocks (n, d, d) [m^2] paired with the candidates ``indices`` (n,):
        ``S = H J H^T + R`` (None when S is not positive definite)."""
        predicted, joint = self.joint(indices)
        d, count = self.dimension, len(indices)
        stacked = joint.copy()
        for row in range(count):
            stacked[row * d : (row + 1) * d, row * d : (row + 1) * d] += noise[row]
        groups = [np.arange(row * d, (row + 1) * d) for row in range(count)]
        return innovation_statistics((np.asarray(measured) - predicted).ravel(), stacked, groups)
