"""Errors of an estimate's state blocks against the ground truth, and their NEES series.

Truth is looked up at the estimate's times (``timestamps.trajectory_at`` /
``vectors_at``: the exact sample within 1e-6 s, else linear interpolation of vectors and
slerp of rotations); estimate steps outside the truth's time span are left out, and so are
those the truth cannot vouch for: inside ``GroundTruth.excluded``, interpolated from an
excluded sample, or across a gap of the truth (``timestamps.MAX_INTERPOLATION_STEPS``).

Block by block (error = truth - estimate, in the frame the estimate states):

* ``pose``: ``consistency.pose_errors`` (interface tangent convention), with the
  sub-blocks ``attitude`` (3-D: the rotation part, 3 dof; 2-D: heading, 1 dof) and
  ``position`` (3-D: body-frame translation, 3 dof; 2-D: 2 dof) taken from the same
  error and the matching covariance sub-block;
* ``velocity``: a body-frame block against ``GroundTruth.body_velocity``, a world-frame
  block against ``GroundTruth.history.blocks[velocity]``;
* ``gyro_bias``, ``accel_bias``: against ``GroundTruth.history.blocks`` (sensor frame);
* ``map``: the joint NEES of each snapshot's mapped landmarks against the joint covariance
  (``map_nees_series``), V d dof;
* ``landmarks``: every landmark of every snapshot, d dof each, after mapping the
  estimator's ids to true ids (``data_association.landmark_id_mapping``); a world-frame
  snapshot against ``GroundTruth.landmarks``, a body-frame one against
  ``p = R_true(t)^T (rho - r_true(t))`` at the snapshot time ``t``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.state import BlockName, Frame, GroundTruth, LandmarkMap, StateBlock, StateHistory
from datasets.trajectory import Trajectory
from workbench.metrics.consistency import nees, pose_errors
from workbench.metrics.timestamps import trajectory_at, vectors_at


@dataclass(frozen=True)
class NeesSeries:
    """NEES of one block over time.

    Attributes:
        t: times [s], shape (K,) (landmarks: one entry per landmark per snapshot).
        nees: shape (K,), NaN where a covariance was singular.
        dof: degrees of freedom of each value, shape (K,).
    """

    t: np.ndarray
    nees: np.ndarray
    dof: np.ndarray


def truth_pose_at(
    ground_truth: GroundTruth, times: np.ndarray
) -> tuple[Trajectory, np.ndarray] | None:
    """True pose at ``times`` and the validity mask, or None without a true trajectory
    (times inside ``ground_truth.excluded`` or across a gap of the truth are invalid)."""
    if ground_truth.pose is None or len(ground_truth.pose) == 0:
        return None
    return trajectory_at(ground_truth.pose, times, ground_truth.excluded)


def pose_error_series(
    pose: Trajectory, ground_truth: GroundTruth
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(times, pose errors (K, dof), valid mask over the estimate's poses), or None when the
    truth has no pose of the same dimension."""
    found = truth_pose_at(ground_truth, pose.t)
    if found is None:
        return None
    truth, valid = found
    if truth.dimension != pose.dimension:
        return None
    return pose.t[valid], pose_errors(pose.select(valid), truth), valid


def _true_block(name: BlockName, frame: Frame, ground_truth: GroundTruth) -> StateBlock | None:
    if name == BlockName.VELOCITY and frame == Frame.BODY:
        return ground_truth.body_velocity
    return ground_truth.history.block(name)


def block_error_series(
    name: BlockName, block: StateBlock, ground_truth: GroundTruth
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(times, errors (K, k), valid mask) of a vector block, or None without a true one."""
    truth = _true_block(name, block.frame, ground_truth)
    if truth is None or len(truth.t) == 0 or truth.values.shape[1] != block.values.shape[1]:
        return None
    true_values, valid = vectors_at(truth.t, truth.values, block.t, ground_truth.excluded)
    return block.t[valid], true_values - block.values[valid], valid


def true_landmarks_in_frame(
    snapshot: LandmarkMap, true_ids: np.ndarray, ground_truth: GroundTruth
) -> tuple[np.ndarray, np.ndarray]:
    """True positions of ``true_ids`` in the snapshot's frame.

    Returns (positions (V, d), valid mask over ``true_ids``). A body-frame snapshot needs the
    true pose at ``snapshot.t``; without it nothing is valid.
    """
    valid = np.zeros(len(true_ids), dtype=bool)
    if ground_truth.landmarks is None or len(true_ids) == 0:
        return np.zeros((0, snapshot.dimension)), valid
    index_of = {int(i): k for k, i in enumerate(np.asarray(ground_truth.landmarks.ids, dtype=int))}
    rows = np.array([index_of.get(int(i), -1) for i in true_ids])
    valid = rows >= 0
    world = ground_truth.landmarks.positions[rows[valid]]
    if world.shape[1] != snapshot.dimension:
        return np.zeros((0, snapshot.dimension)), np.zeros(len(true_ids), dtype=bool)
    if snapshot.frame == Frame.WORLD:
        return world, valid
    if snapshot.t is None:
        return np.zeros((0, snapshot.dimension)), np.zeros(len(true_ids), dtype=bool)
    found = truth_pose_at(ground_truth, np.array([snapshot.t]))
    if found is None or not found[1][0] or found[0].dimension != snapshot.dimension:
        return np.zeros((0, snapshot.dimension)), np.zeros(len(true_ids), dtype=bool)
    pose = found[0]
    rotation = pose.rotation_matrices()[0]
    return (world - pose.positions[0]) @ rotation, valid  # p = R^T (rho - r), row-wise


def landmark_errors(
    snapshot: LandmarkMap, mapping: dict[int, int], ground_truth: GroundTruth
) -> tuple[np.ndarray, np.ndarray]:
    """Errors (truth - estimate) of the snapshot's mapped landmarks.

    Returns (errors (V, d), valid mask over the snapshot's landmarks).
    """
    ids = np.asarray(snapshot.ids, dtype=int)
    true_ids = np.array([mapping.get(int(i), -1) for i in ids], dtype=int)
    mapped = true_ids != -1
    positions, valid_truth = true_landmarks_in_frame(snapshot, true_ids[mapped], ground_truth)
    valid = np.zeros(len(ids), dtype=bool)
    valid[np.flatnonzero(mapped)[valid_truth]] = True
    return positions - snapshot.positions[valid], valid


def landmark_nees_series(
    snapshots: tuple[LandmarkMap, ...], mapping: dict[int, int], ground_truth: GroundTruth
) -> NeesSeries | None:
    """Per-landmark NEES over all snapshots with covariances (d dof each), or None."""
    times, values, dofs = [], [], []
    for snapshot in snapshots:
        if snapshot.covariances is None or len(snapshot) == 0:
            continue
        errors, valid = landmark_errors(snapshot, mapping, ground_truth)
        if not np.any(valid):
            continue
        # A static world map (t None) gets NaN times: it has no place on a time axis.
        times.append(
            np.full(int(np.sum(valid)), np.nan if snapshot.t is None else float(snapshot.t))
        )
        values.append(nees(errors, snapshot.covariances[valid]))
        dofs.append(np.full(int(np.sum(valid)), snapshot.dimension, dtype=int))
    if not values:
        return None
    return NeesSeries(np.concatenate(times), np.concatenate(values), np.concatenate(dofs))


def map_nees_series(
    snapshots: tuple[LandmarkMap, ...], mapping: dict[int, int], ground_truth: GroundTruth
) -> NeesSeries | None:
    """The joint NEES of every snapshot that has a joint covariance: the stacked errors of
    its mapped landmarks (V d) against their block of the joint covariance, dof = V d. The
    landmarks of one map share the vehicle's (and the gauge's) error, so the map, not the
    landmark, is the unit a chi-square band can be built on. None without such snapshots."""
    times, values, dofs = [], [], []
    for snapshot in snapshots:
        if snapshot.joint_covariance is None or len(snapshot) == 0:
            continue
        errors, valid = landmark_errors(snapshot, mapping, ground_truth)
        if not np.any(valid):
            continue
        d = snapshot.dimension
        rows = (np.flatnonzero(valid)[:, None] * d + np.arange(d)).ravel()
        joint = snapshot.joint_covariance[np.ix_(rows, rows)]
        times.append(np.nan if snapshot.t is None else float(snapshot.t))
        values.append(nees(errors.reshape(1, -1), joint[None])[0])
        dofs.append(rows.size)
    if not values:
        return None
    return NeesSeries(np.array(times), np.array(values), np.array(dofs, dtype=int))


def _series(t: np.ndarray, errors: np.ndarray, covariances: np.ndarray) -> NeesSeries:
    return NeesSeries(t, nees(errors, covariances), np.full(len(t), errors.shape[1], dtype=int))


def nees_series(
    history: StateHistory, ground_truth: GroundTruth, mapping: dict[int, int] | None = None
) -> dict[str, NeesSeries]:
    """NEES per step of every block that has covariances and a truth to compare with.

    Args:
        history: an estimate's causal or smoothed history.
        ground_truth: the sequence's truth.
        mapping: estimator landmark id -> true id (``data_association.landmark_id_mapping``);
            None compares ids as they are.

    Returns:
        ``{block: NeesSeries}`` with keys among ``pose``, ``attitude``, ``position``,
        ``velocity``, ``gyro_bias``, ``accel_bias``, ``landmarks`` (per landmark) and ``map``
        (the joint NEES of each snapshot).
    """
    result: dict[str, NeesSeries] = {}
    pose = history.pose
    if pose is not None and pose.covariances is not None:
        found = pose_error_series(pose, ground_truth)
        if found is not None and len(found[0]):
            t, errors, valid = found
            covariances = pose.covariances[valid]
            attitude = slice(0, 3) if pose.dimension == 3 else slice(2, 3)
            position = slice(3, 6) if pose.dimension == 3 else slice(0, 2)
            result["pose"] = _series(t, errors, covariances)
            result["attitude"] = _series(t, errors[:, attitude], covariances[:, attitude, attitude])
            result["position"] = _series(t, errors[:, position], covariances[:, position, position])
    for name, block in history.blocks.items():
        if block.covariances is None:
            continue
        found_block = block_error_series(name, block, ground_truth)
        if found_block is not None and len(found_block[0]):
            t, errors, valid = found_block
            result[str(name)] = _series(t, errors, block.covariances[valid])
    if history.landmarks:
        if mapping is None:
            mapping = {int(i): int(i) for snapshot in history.landmarks for i in snapshot.ids}
        landmarks = landmark_nees_series(history.landmarks, mapping, ground_truth)
        if landmarks is not None:
            result["landmarks"] = landmarks
        joint_map = map_nees_series(history.landmarks, mapping, ground_truth)
        if joint_map is not None:
            result["map"] = joint_map
    return result
