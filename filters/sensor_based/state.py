"""The sensor-based filter's state vector, covariance and feature bookkeeping.

Layout ``x = [v (d), b (r), features]`` (see ``dynamics``). A landmark owns one position
feature and optionally direction features, stored contiguously: position first. Map ids
are the filter's own (assigned in creation order, never reused). Where each landmark and
feature sits is the ``filters.state_registry.StateRegistry``'s to say: vehicle blocks
``velocity`` and ``bias``, landmark blocks ``position`` and ``direction`` (d each); a
feature index is the position of its block among the registry's landmark blocks.
"""

from __future__ import annotations

import numpy as np

from filters import kalman
from filters.landmark_predictor import LandmarkMeasurement, LandmarkPredictor
from filters.sensor_based.dynamics import rate_dimension
from filters.sensor_based.earth_state import EARTH_AXIS, EARTH_FRAME_OWNER, EARTH_ORIGIN
from filters.state_registry import StateRegistry

POSITION = "position"
DIRECTION = "direction"


class FilterState:
    """Mean, covariance and per-feature metadata.

    Attributes:
        dimension: d. rate_dim: r. vehicle_dim: d + r.
        x: (n,). covariance: (n, n).
        registry: where the vehicle blocks and every landmark's features sit.
        owner: (F,) map id of the landmark each feature belongs to (the registry's).
        is_position: (F,) bool (the registry's block names).
        measured: (F, d) last measured value of each feature (the ``y`` of ``A(t, y)``).
        visible: (F,) bool, measured in the latest scan (the set I_O).
    """

    def __init__(
        self,
        dimension: int,
        velocity: np.ndarray,
        velocity_cov: np.ndarray,
        bias: np.ndarray,
        bias_cov: np.ndarray,
    ) -> None:
        self.dimension = dimension
        self.rate_dim = rate_dimension(dimension)
        self.registry = StateRegistry([("velocity", dimension), ("bias", self.rate_dim)])
        self.vehicle_dim = self.registry.vehicle_size
        self.x = np.concatenate(
            [np.asarray(velocity, float).ravel(), np.asarray(bias, float).ravel()]
        )
        self.covariance = np.zeros((self.vehicle_dim, self.vehicle_dim))
        v, b = self.registry.vehicle("velocity"), self.registry.vehicle("bias")
        self.covariance[v, v] = velocity_cov
        self.covariance[b, b] = bias_cov
        self.measured = np.zeros((0, dimension))
        self.visible = np.zeros(0, dtype=bool)
        self._next_id = 0

    # ------------------------------------------------------------------ views
    @property
    def owner(self) -> np.ndarray:
        return self.registry.block_owners

    @property
    def is_position(self) -> np.ndarray:
        return self.registry.block_names == POSITION

    @property
    def translates(self) -> np.ndarray:
        """(F,) bool: features that move with the vehicle's translation (the ``-v`` of eq. (1)):
        landmark positions and the Earth origin."""
        names = self.registry.block_names
        return (names == POSITION) | (names == EARTH_ORIGIN)

    @property
    def undisturbed(self) -> np.ndarray:
        """(F,) bool: the Earth frame's features, exactly static in the Earth frame, which take
        no disturbance (``earth_state``)."""
        return self.registry.block_owners == EARTH_FRAME_OWNER

    def earth_frame_features(self) -> np.ndarray:
        """Feature indices of the Earth frame ``[origin, axes...]`` (empty when not in the state)."""
        return np.flatnonzero(self.undisturbed)

    def add_earth_frame(self, values: np.ndarray, covariance: np.ndarray) -> None:
        """Append the Earth frame's features (``earth_state.frame_from_pose``): values
        (1 + axes, d), covariance (k d, k d), uncorrelated with the state so far."""
        d = self.dimension
        values = np.asarray(values, dtype=float)
        blocks = [(EARTH_ORIGIN, d)] + [(EARTH_AXIS, d)] * (len(values) - 1)
        self._append(EARTH_FRAME_OWNER, blocks, values, np.asarray(covariance), visible=False)

    def _append(
        self,
        owner: int,
        blocks: list[tuple[str, int]],
        values: np.ndarray,
        covariance: np.ndarray,
        visible: bool,
    ) -> None:
        """Append features (F, d) of one owner with their covariance (F d, F d), uncorrelated
        with the state so far (robocentric: a measurement *is* the landmark; the Earth frame
        starts from the stated start pose)."""
        uncorrelated = kalman.SparseJacobian(np.zeros(0, dtype=int), np.zeros((values.size, 0)))
        self.covariance = kalman.augment(self.covariance, uncorrelated, covariance)
        self.registry.augment(owner, blocks)
        self.x = np.concatenate([self.x, values.ravel()])
        self.measured = np.vstack([self.measured, values])
        self.visible = np.concatenate([self.visible, np.full(len(values), visible)])

    @property
    def feature_count(self) -> int:
        return int(self.owner.size)

    @property
    def velocity(self) -> np.ndarray:
        return self.x[self.registry.vehicle("velocity")]

    @property
    def bias(self) -> np.ndarray:
        return self.x[self.registry.vehicle("bias")]

    @property
    def features(self) -> np.ndarray:
        """(F, d) view of the feature values."""
        return self.x[self.vehicle_dim :].reshape(-1, self.dimension)

    def landmark_ids(self) -> np.ndarray:
        """Map ids of the landmarks in state order, (L,)."""
        return self.owner[self.is_position]

    def position_features(self) -> np.ndarray:
        """Feature index of each landmark's position, (L,) (same order as ``landmark_ids``)."""
        return np.flatnonzero(self.is_position)

    def state_indices(self, feature_indices: np.ndarray) -> np.ndarray:
        """State-vector indices of features, (len * d,) in feature order."""
        return self.registry.block_indices(feature_indices)

    def direction_features(self, landmark_id: int) -> np.ndarray:
        return np.flatnonzero(
            (self.owner == landmark_id) & (self.registry.block_names == DIRECTION)
        )

    def landmark_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """(ids (L,), body-frame positions (L, d)), in state order."""
        features = self.position_features()
        return self.owner[features], self.features[features]

    def position_blocks(self, landmarks: np.ndarray | None = None) -> np.ndarray:
        """Marginal covariances (n, d, d) of the given landmarks' positions (indices into
        ``landmark_ids``; all when None): only the diagonal blocks are gathered."""
        features = self.position_features()
        if landmarks is not None:
            features = features[np.asarray(landmarks, dtype=int)]
        rows = self.state_indices(features).reshape(-1, self.dimension)
        return self.covariance[rows[:, :, None], rows[:, None, :]]

    def position_covariance(self, landmarks: np.ndarray) -> np.ndarray:
        """Joint covariance (n d, n d) of the given landmarks' positions (indices into
        ``landmark_ids``)."""
        indices = self.state_indices(self.position_features()[np.asarray(landmarks, dtype=int)])
        return self.covariance[np.ix_(indices, indices)]

    # ------------------------------------------------------------------ edits
    def add_landmark(
        self,
        position: np.ndarray,
        position_cov: np.ndarray,
        directions: np.ndarray | None = None,
        direction_covs: np.ndarray | None = None,
    ) -> int:
        """Append a landmark initialised from a body-frame measurement; returns its map id.

        In the robocentric frame the measurement *is* the landmark, so the new block has the
        measurement covariance and no correlation with the rest of the state.
        """
        d = self.dimension
        values = [np.asarray(position, float).ravel()]
        covs = [np.asarray(position_cov, float)]
        blocks = [(POSITION, d)]
        if directions is not None:
            for direction, cov in zip(directions, direction_covs):
                values.append(np.asarray(direction, float).ravel())
                covs.append(np.asarray(cov, float))
                blocks.append((DIRECTION, d))
        landmark_id = self._next_id
        self._next_id += 1
        # robocentric: the measurement *is* the landmark, uncorrelated with the state
        self._append(
            landmark_id,
            blocks,
            np.stack(values),
            kalman.block_diagonal(np.stack(covs)),
            visible=True,
        )
        return landmark_id

    def remove_landmarks(self, landmark_ids: list[int] | np.ndarray) -> None:
        """Drop every feature of the given landmarks (marginalisation: delete rows/columns)."""
        landmark_ids = np.asarray(landmark_ids, dtype=int)
        drop = np.isin(self.owner, landmark_ids)
        if not drop.any():
            return
        keep_features = np.flatnonzero(~drop)  # per-feature data kept, in feature order
        keep = self.registry.marginalize(landmark_ids)
        self.x = self.x[keep]
        self.covariance = kalman.marginalize(self.covariance, keep)
        self.measured = self.measured[keep_features]
        self.visible = self.visible[keep_features]


def landmark_predictor(state: FilterState, landmarks: np.ndarray) -> LandmarkPredictor:
    """The association ``Predictor`` of the robocentric map (the shared
    ``filters.landmark_predictor``): a landmark's predicted measurement is its own position
    feature (``y_i = x_i``, eq. (2)), a selection, so ``H P H^T`` is that feature's block
    of the covariance. ``landmarks``: candidate index -> landmark index (into
    ``landmark_ids``)."""
    landmarks = np.asarray(landmarks, dtype=int)

    def measure(indices: np.ndarray) -> LandmarkMeasurement:
        chosen = landmarks[indices]
        ids, positions = state.landmark_positions()
        return LandmarkMeasurement(positions[chosen], ids[chosen], block=POSITION)

    return LandmarkPredictor(state.registry, state.covariance, measure)
