"""What the sensor-based filter records of its estimate (DESIGN.md's exported blocks).

``velocity`` (body frame) and ``gyro_bias`` after every scan, with extras
``vehicle_t``/``vehicle_state``/``vehicle_covariance``: the joint [v, b] block for the
vehicle NEES (``record_vehicle``); the body-frame map (``body_map``); the Earth-frame pose
derived from the map history (``earth_frame``) with its first-order covariance
(``earth_pose_covariance``, our extension) converted to the interface's right perturbation,
after a scan (``record_earth_pose``) or carried by the motion since the last scan to a sensor
frame without one (``record_carried_pose``); the Earth-frame map (``earth_frame_map``); the notes
of the ``Estimate`` (``estimate_notes``).
"""

from __future__ import annotations

import copy

import numpy as np

from datasets.estimate import EstimateRecorder
from datasets.rotations import quat_wxyz_from_matrix
from datasets.state import BlockName, Frame, LandmarkMap
from filters.association import ScanAssociation
from filters.ekf_slam.boundary import pose_covariance_to_interface
from filters.sensor_based.dynamics import ProcessNoise
from filters.sensor_based.earth_frame import EarthFrameTracker
from filters.sensor_based.earth_motion import MotionSinceScan
from filters.sensor_based.earth_state import pose_covariance, pose_from_frame
from filters.sensor_based.state import FilterState


def _attitude(rotation: np.ndarray, dimension: int) -> float | np.ndarray:
    """The interface's attitude of a rotation matrix: heading (2-D), quaternion wxyz (3-D)."""
    return (
        float(np.arctan2(rotation[1, 0], rotation[0, 0]))
        if dimension == 2
        else quat_wxyz_from_matrix(rotation)
    )


def record_vehicle(recorder: EstimateRecorder, state: FilterState, t: float) -> None:
    """The velocity and gyro-bias blocks and the joint [v, b] block at ``t``."""
    v, b = state.registry.vehicle("velocity"), state.registry.vehicle("bias")
    nv = state.vehicle_dim
    recorder.block(
        BlockName.VELOCITY,
        t,
        state.velocity.copy(),
        state.covariance[v, v].copy(),
        Frame.BODY,
    )
    recorder.block(
        BlockName.GYRO_BIAS,
        t,
        state.bias.copy(),
        state.covariance[b, b].copy(),
        Frame.BODY,
    )
    # The joint vehicle block (velocity and bias are correlated): for the vehicle NEES.
    recorder.extra("vehicle_t", float(t))
    recorder.extra("vehicle_state", state.x[:nv].copy())
    recorder.extra("vehicle_covariance", state.covariance[:nv, :nv].ravel().copy())


def record_associations(
    recorder: EstimateRecorder, t: float, association: ScanAssociation, assignment: np.ndarray
) -> None:
    """One association record per sighting of the scan: its map id (``assignment``, -1
    where none) and the decision."""
    for j, decision in enumerate(association.decisions):
        recorder.association(
            t,
            j,
            int(assignment[j]),
            decision,
            association.reasons[j],
            association.inflation[j],
            association.alternatives_of(j),
        )


def record_earth_pose(
    recorder: EstimateRecorder, earth: EarthFrameTracker, t: float, dimension: int
) -> None:
    """The Earth-frame pose (derived from the map history) with its first-order
    covariance (``earth_pose_covariance``) converted to the interface's right
    perturbation; 3-D without one."""
    rotation = earth.rotation
    covariance = earth.covariance
    if covariance is not None:
        covariance = pose_covariance_to_interface(rotation, covariance)
    recorder.pose(
        t,
        earth.position.copy(),
        _attitude(rotation, dimension),
        covariance,
    )


def record_frame_pose(recorder: EstimateRecorder, state: FilterState, t: float) -> None:
    """The Earth-frame pose read from the state's Earth-frame features (``earth_state``)
    with its first-order covariance, in the interface's right perturbation."""
    features = state.earth_frame_features()
    frame = state.features[features]
    indices = state.state_indices(features)
    rotation, position = pose_from_frame(frame)
    covariance = pose_covariance(frame, state.covariance[np.ix_(indices, indices)])
    recorder.pose(
        t,
        position,
        _attitude(rotation, state.dimension),
        pose_covariance_to_interface(rotation, covariance),
    )


def record_carried_pose(
    recorder: EstimateRecorder,
    earth: EarthFrameTracker,
    motion: MotionSinceScan,
    vehicle_covariance: np.ndarray,
    noise: ProcessNoise,
    t: float,
    dimension: int,
) -> None:
    """The Earth pose composed with the filter's own motion since the last scan (what
    the next scan's step falls back on without common landmarks), with the same
    covariance algebra (``EarthErrorCovariance.compose`` on a copy)."""
    rotation = earth.rotation @ motion.rotation
    position = earth.position + earth.rotation @ motion.translation
    covariance = None
    if earth.errors is not None:
        errors = copy.deepcopy(earth.errors)
        errors.compose(
            earth.rotation, motion.translation, motion.covariance(vehicle_covariance, noise)
        )
        covariance = pose_covariance_to_interface(rotation, errors.pose)
    recorder.pose(
        t,
        position,
        _attitude(rotation, dimension),
        covariance,
    )


def body_map(state: FilterState, t: float) -> LandmarkMap:
    """The body-frame map: ids, positions (L, d), their joint covariance."""
    ids, positions = state.landmark_positions()
    joint = state.position_covariance(np.arange(len(ids)))
    return LandmarkMap.from_joint(ids, positions, joint, Frame.BODY, float(t))


def earth_frame_map(earth: EarthFrameTracker, current: LandmarkMap) -> LandmarkMap:
    """The ``current`` body-frame map in the Earth frame (derived; covariances rotated, pose
    uncertainty ignored)."""
    return _map_in_earth(current, earth.rotation, earth.position)


def frame_earth_map(state: FilterState, current: LandmarkMap) -> LandmarkMap:
    """The ``current`` body-frame map in the Earth frame through the state's Earth-frame
    features (``R l + p``, which is ``R (l - o)``; covariances rotated, the frame's
    uncertainty ignored)."""
    rotation, position = pose_from_frame(state.features[state.earth_frame_features()])
    return _map_in_earth(current, rotation, position)


def _map_in_earth(current: LandmarkMap, rotation: np.ndarray, position: np.ndarray) -> LandmarkMap:
    """Body-frame map through the pose ``(R, p)``: positions ``R l + p``, covariances
    ``R C R^T``."""
    covs = None if current.covariances is None else rotation @ current.covariances @ rotation.T
    return LandmarkMap(
        ids=current.ids,
        positions=current.positions @ rotation.T + position,
        covariances=covs,
        frame=Frame.WORLD,
        t=None,
    )


def estimate_notes(
    earth: EarthFrameTracker | None,
    deleted: dict[str, int],
    use_odometry: bool,
    skipped: dict[str, int],
    frame_in_state: bool = False,
) -> tuple[str, ...]:
    """The notes of the ``Estimate``: frames, how the pose was derived, deletions, inputs."""
    pose_note = (
        f"pose: Earth-frame trajectory DERIVED from consecutive body-frame maps by rigid alignment "
        f"({earth.aligned_steps} aligned, {earth.fallback_steps} dead-reckoned increments, "
        f"{earth.anchored_steps} anchored); "
        + (
            "first-order covariance (earth_pose_covariance)"
            if earth.errors is not None
            else "no covariance (3-D: earth_pose_covariance says why)"
        )
        if earth is not None
        else "robocentric only: no world pose"
    )
    if frame_in_state:
        pose_note = (
            "pose: Earth frame estimated as non-visible origin and axis features of the filter "
            "(earth_frame_source=filter_state); first-order covariance"
        )
    notes = [
        "velocity and landmarks are body-frame (robocentric filter state)",
        pose_note,
        f"landmarks deleted: {deleted}",
    ]
    if use_odometry:
        notes.append(
            "odometry used as a body-velocity measurement (an extension beyond the paper; "
            "use_odometry=false: the paper's gyro-only form)"
        )
    if any(skipped.values()):
        notes.append(f"skipped inputs: {skipped}")
    return tuple(notes)
