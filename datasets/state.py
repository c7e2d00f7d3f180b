"""State histories: what an estimator knew over time, and what was true.

``StateHistory`` holds named blocks from a fixed vocabulary (``pose``, ``velocity``,
``gyro_bias``, ``accel_bias``, ``landmarks``). NEES of any block is computed the same way
for every estimator (``workbench.metrics.consistency``), so the blocks carry the frame they
are expressed in: a robocentric filter reports body-frame velocity and landmarks, a
world-centric one world-frame quantities, and the ground truth knows both.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

from datasets.trajectory import Trajectory
from datasets.truth_quality.intervals import TruthInterval, excluded_mask


class Frame(enum.StrEnum):
    """Frame a vector block is expressed in."""

    WORLD = "world"
    BODY = "body"


class BlockName(enum.StrEnum):
    """The fixed vocabulary of vector state blocks (pose and landmarks have their own types)."""

    VELOCITY = "velocity"
    GYRO_BIAS = "gyro_bias"
    ACCEL_BIAS = "accel_bias"


@dataclass(frozen=True)
class StateBlock:
    """One vector state over time.

    Attributes:
        t: times [s], shape (N,).
        values: shape (N, k).
        covariances: shape (N, k, k) or None.
        frame: frame of the vector (biases are always body/sensor frame).
    """

    t: np.ndarray
    values: np.ndarray
    covariances: np.ndarray | None = None
    frame: Frame = Frame.BODY

    def __post_init__(self) -> None:
        if self.values.ndim != 2 or self.values.shape[0] != len(self.t):
            raise ValueError(
                f"StateBlock values must be (N, k) with N={len(self.t)}, got {self.values.shape}"
            )
        if self.covariances is not None:
            k = self.values.shape[1]
            if self.covariances.shape != (len(self.t), k, k):
                raise ValueError(
                    f"StateBlock covariances must be {(len(self.t), k, k)}, got {self.covariances.shape}"
                )


@dataclass(frozen=True)
class LandmarkMap:
    """A set of point landmarks with ids.

    Attributes:
        ids: landmark ids, shape (k,) int. For an estimator these are its own map ids; for
            ground truth the true ids.
        positions: shape (k, d) [m].
        covariances: per-landmark marginal covariances, shape (k, d, d), or None.
        frame: world (a world-centric map) or body (a robocentric map at time ``t``).
        t: time of the snapshot [s] (None for a static world map).
        joint_covariance: the joint covariance of all positions, shape (k d, k d), rows in
            landmark order, or None. A map's landmarks share the vehicle's (and the gauge's)
            error, so only the joint covariance scores a map as a whole (the map NEES).
    """

    ids: np.ndarray
    positions: np.ndarray
    covariances: np.ndarray | None = None
    frame: Frame = Frame.WORLD
    t: float | None = None
    joint_covariance: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.positions.ndim != 2 or self.positions.shape[0] != len(self.ids):
            raise ValueError(
                f"LandmarkMap positions must be (k, d) with k={len(self.ids)}, got {self.positions.shape}"
            )
        if self.joint_covariance is not None:
            size = self.positions.size
            if np.shape(self.joint_covariance) != (size, size):
                raise ValueError(
                    f"LandmarkMap joint_covariance must be {(size, size)}, got {np.shape(self.joint_covariance)}"
                )

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def dimension(self) -> int:
        return int(self.positions.shape[1])

    @staticmethod
    def from_joint(
        ids: np.ndarray,
        positions: np.ndarray,
        joint_covariance: np.ndarray,
        frame: Frame = Frame.WORLD,
        t: float | None = None,
    ) -> LandmarkMap:
        """A map whose marginal covariances are the diagonal blocks of its joint covariance
        (copied: the snapshot must not change with the estimator's state)."""
        positions = np.array(positions, dtype=float)
        count, d = positions.shape
        joint = np.array(joint_covariance, dtype=float)
        blocks = joint.reshape(count, d, count, d)[np.arange(count), :, np.arange(count), :]
        return LandmarkMap(
            np.array(ids, dtype=int), positions, blocks.copy(), frame, t, joint_covariance=joint
        )

    @staticmethod
    def empty(dimension: int, frame: Frame = Frame.WORLD, t: float | None = None) -> LandmarkMap:
        return LandmarkMap(
            ids=np.zeros(0, dtype=int),
            positions=np.zeros((0, dimension)),
            covariances=np.zeros((0, dimension, dimension)),
            frame=frame,
            t=t,
        )


@dataclass(frozen=True)
class StateHistory:
    """Named state blocks over time (DESIGN.md: ``StateHistory``).

    Attributes:
        pose: the vehicle trajectory (with covariances for an estimate), or None for a
            robocentric estimator that has no world pose.
        blocks: vector blocks keyed by ``BlockName`` (velocity, gyro_bias, accel_bias).
        landmarks: landmark map snapshots over time (may be subsampled), oldest first.
    """

    pose: Trajectory | None = None
    blocks: dict[BlockName, StateBlock] = field(default_factory=dict)
    landmarks: tuple[LandmarkMap, ...] = ()

    def block(self, name: BlockName | str) -> StateBlock | None:
        """The block called ``name``, or None when this history does not have it."""
        return self.blocks.get(BlockName(name))


@dataclass(frozen=True)
class Relations:
    """Relative poses between pairs of times, obtained independently of any estimator (the
    "relations" of Kümmerle et al., "On measuring the accuracy of SLAM algorithms",
    Autonomous Robots 27(4), 2009): relation r is the pose at ``times[r, 1]`` in the frame
    of the pose at ``times[r, 0]``. The workbench reads and scores them (its relations
    metric); no loader needs to know them.

    Attributes:
        times: (t1, t2) [s], shape (R, 2), t1 != t2 (either order).
        poses: planar, shape (R, 3): [x [m], y [m], yaw [rad]]; or spatial, shape (R, 6):
            [x, y, z [m], roll, pitch, yaw [rad]], rotation Rz(yaw) Ry(pitch) Rx(roll).
        source: where they were read from (a file path), for messages.
        max_diff_s: stamp tolerance [s] to score them with, or None for the scorer's
            default.
    """

    times: np.ndarray
    poses: np.ndarray
    source: str = ""
    max_diff_s: float | None = None

    def __post_init__(self) -> None:
        count = len(self.times)
        if np.shape(self.times) != (count, 2):
            raise ValueError(f"Relations times must be (R, 2), got {np.shape(self.times)}")
        if np.ndim(self.poses) != 2 or np.shape(self.poses) not in ((count, 3), (count, 6)):
            raise ValueError(
                f"Relations poses must be (R, 3) or (R, 6) with R={count}, "
                f"got {np.shape(self.poses)}"
            )

    def __len__(self) -> int:
        return len(self.times)

    @property
    def dimension(self) -> int:
        """2 for planar relations [x, y, yaw], 3 for spatial ones."""
        return 2 if self.poses.shape[1] == 3 else 3


@dataclass(frozen=True)
class GroundTruth:
    """What the source knows to be true; any part may be missing (None / empty).

    Attributes:
        history: true states (no covariances). Velocity is kept in both frames where known:
            ``blocks[VELOCITY]`` is world-frame; ``body_velocity`` is body-frame.
        landmarks: the true world map (ids are true ids), or None.
        body_velocity: body-frame velocity, or None.
        scan_ids: true landmark ids of every landmark scan, as ``(t, ids[k])`` pairs in
            stream order, also when the ids are withheld from the measurements; used only
            to score data association.
        held_out_positions: positions withheld from the estimators and kept for evaluation
            (e.g. held-out GPS fixes) as ``(t[M], positions[M, d])``, or None.
        excluded: time intervals where the truth is not trustworthy
            (``datasets.truth_quality.assess.assess_truth``): the metrics score nothing inside
            them and never interpolate the truth across them. Empty: all of it is trusted.
        relations: relative poses between pairs of times (``Relations``), or None. No
            loader fills it: the workbench attaches a relations file given with any
            dataset (``--data relations=FILE``).
    """

    history: StateHistory
    landmarks: LandmarkMap | None = None
    body_velocity: StateBlock | None = None
    scan_ids: tuple[tuple[float, np.ndarray], ...] = ()
    held_out_positions: tuple[np.ndarray, np.ndarray] | None = None
    excluded: tuple[TruthInterval, ...] = ()
    relations: Relations | None = None

    @property
    def pose(self) -> Trajectory | None:
        return self.history.pose

    def trusted(self, times: np.ndarray) -> np.ndarray:
        """(N,) bool: True for times [s], shape (N,), outside every ``excluded`` interval
        (edges belong to the interval)."""
        return ~excluded_mask(np.asarray(times, dtype=float), self.excluded)
