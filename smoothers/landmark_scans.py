"""Landmark scans in the smoother: the map's variables, the prediction a keyframe's scans
are associated and scored against, and their innovation statistics.

A keyframe's motion (and GPS) factors are solved first, so the backend's estimate of the new
pose *is* the prediction and the joint marginal of that pose and the landmarks is the
predicted covariance. From it the ``KeyframePredictor`` gives the association policy
(``filters.association``) the predicted measurements ``h_i = R^T (l_i - p)`` and ``H J H^T``
(J the joint marginal, one batched backend query), and ``innovation`` the stacked NIS of
the matched sightings ``nu^T (H J H^T + R)^-1 nu`` with its dof, and each landmark's own:
the same statistics every filter records. A landmark created in this keyframe has no
prediction and is not in the NIS.

Jacobians on GTSAM's tangents (right perturbation): 3-D ``Pose3`` [omega, v]:
``dh/domega = [h]x``, ``dh/dv = -I``; 2-D ``Pose2`` [x, y, theta]: ``dh/d(x, y) = -I``,
``dh/dtheta = -J h`` with ``J = [[0, -1], [1, 0]]``; both ``dh/dl = R^T``.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L

from filters.association import innovation_statistics
from smoothers.backends import JointMarginals

PLANAR_J = np.array([[0.0, -1.0], [1.0, 0.0]])


@dataclass
class MapLandmark:
    """One map landmark: its current variable key and bookkeeping.

    Attributes:
        map_id: the estimator's id (the scan id with ids).
        key: the GTSAM key of its current variable (a re-observed landmark whose variable
            was marginalised gets a new one).
        anchor_position: a known landmark's surveyed position, or None.
        observations: sightings used so far. last_t: time of the latest [s].
    """

    map_id: int
    key: int
    anchor_position: np.ndarray | None = None
    observations: int = 0
    last_t: float = 0.0


class LandmarkBook:
    """The map: map id -> ``MapLandmark``, with fresh GTSAM keys ``l0, l1, ...``."""

    def __init__(self) -> None:
        self.landmarks: dict[int, MapLandmark] = {}
        self.next_map_id = 0
        self._next_key_index = 0

    def variable(self, map_id: int, t: float) -> MapLandmark:
        """The landmark ``map_id`` with a new variable key (created when unknown)."""
        key = L(self._next_key_index)
        self._next_key_index += 1
        landmark = self.landmarks.get(map_id)
        if landmark is None:
            landmark = MapLandmark(map_id=map_id, key=key)
            self.landmarks[map_id] = landmark
            self.next_map_id = max(self.next_map_id, map_id + 1)
        else:
            landmark.key = key
        landmark.last_t = float(t)
        return landmark

    def new_map_id(self) -> int:
        map_id = self.next_map_id
        self.next_map_id += 1
        return map_id

    def sorted(self) -> list[MapLandmark]:
        return sorted(self.landmarks.values(), key=lambda landmark: landmark.map_id)


def predicted_measurements(pose, positions: np.ndarray, dimension: int) -> np.ndarray:
    """``h_i = R^T (l_i - p)`` for world positions (m, d) seen from a GTSAM pose, (m, d)."""
    rotation = pose.rotation().matrix()
    return (np.asarray(positions, dtype=float) - np.asarray(pose.translation())) @ rotation


class KeyframePredictor:
    """The association ``Predictor`` of a keyframe (module docstring).

    Args:
        pose: the keyframe's pose estimate (``gtsam.Pose3`` or ``Pose2``). pose_key: its key.
        candidates: the landmarks that may be seen, with ``positions`` (m, d) their estimates.
        joint: ``keys -> JointMarginals``, the backend's batched query.
    """

    def __init__(
        self,
        pose,
        pose_key: int,
        candidates: list[MapLandmark],
        positions: np.ndarray,
        joint,
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
        if self._cached is None or not set(keys) <= set(self._cached.keys):
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
                jacobian[rows, :pose_dof] = np.hstack([-np.eye(2), (-PLANAR_J @ h)[:, None]])
            jacobian[rows, pose_dof + row * d : pose_dof + (row + 1) * d] = self.rotation_t
        return jacobian

    def joint(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        indices = np.asarray(indices, dtype=int)
        marginals = self._marginals(indices)
        keys = [self.pose_key] + [self.candidates[int(i)].key for i in indices]
        jacobian = self._jacobian(indices)
        covariance = jacobian @ marginals.matrix(keys) @ jacobian.T
        return self.predicted[indices], 0.5 * (covariance + covariance.T)

    def individual(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        predicted, joint = self.joint(indices)
        d, count = self.dimension, len(predicted)
        blocks = joint.reshape(count, d, count, d)[np.arange(count), :, np.arange(count), :]
        return predicted, blocks

    def innovation(self, indices: np.ndarray, measured: np.ndarray, noise: np.ndarray):
        """``filters.association.innovation_statistics`` of the sightings ``measured``
        (n, d) with noise blocks (n, d, d) paired with the candidates ``indices`` (n,)."""
        predicted, joint = self.joint(indices)
        d, count = self.dimension, len(indices)
        stacked = joint.copy()
        for row in range(count):
            stacked[row * d : (row + 1) * d, row * d : (row + 1) * d] += noise[row]
        groups = [np.arange(row * d, (row + 1) * d) for row in range(count)]
        return innovation_statistics((np.asarray(measured) - predicted).ravel(), stacked, groups)


def pose_and_positions(values: gtsam.Values, pose_key: int, keys: list[int], dimension: int):
    """(pose, positions (m, d)) of ``pose_key`` and the landmark ``keys`` in ``values``."""
    pose = values.atPose3(pose_key) if dimension == 3 else values.atPose2(pose_key)
    read = values.atPoint3 if dimension == 3 else values.atPoint2
    positions = np.array([read(key) for key in keys], dtype=float).reshape(len(keys), dimension)
    return pose, positions
