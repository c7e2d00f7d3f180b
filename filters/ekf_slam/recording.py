"""What the EKF-SLAM records of its estimate and of its run.

- the vehicle's posterior after every step (``record_vehicle``): the pose with its
  covariance converted to the interface convention (right perturbation, ``boundary``), and
  the world velocity and the gyro bias when the gyro model has them;
- the JCBB search of a scan without ids (``record_search``): nodes visited, truncation;
- the run's note on its input, association and map (``summary_note``).

The other diagnostics are recorded where they arise: NIS (``scan_update``), association
decisions and pruned landmarks (``landmarks``), motion gaps, landmark counts and map
snapshots (``filter``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from datasets.estimate import EstimateRecorder
from datasets.rotations import quat_wxyz_from_matrix
from datasets.state import BlockName, Frame
from filters.association import AssociationResult
from filters.ekf_slam.boundary import pose_covariance_to_interface

if TYPE_CHECKING:
    from filters.ekf_slam.filter import EkfSlam


def record_vehicle(ekf: EkfSlam, recorder: EstimateRecorder) -> None:
    """Record the vehicle's posterior (pose, velocity, gyro bias) at the filter's time."""
    layout, P = ekf.layout, ekf.covariance
    rotation_matrix = ekf.vehicle.rotation_matrix()
    pose_size = layout.rotation.stop  # position then rotation lead the vehicle block
    pose_cov = pose_covariance_to_interface(rotation_matrix, P[:pose_size, :pose_size])
    rotation = (
        float(ekf.vehicle.rotation)
        if ekf.dimension == 2
        else quat_wxyz_from_matrix(rotation_matrix)
    )
    recorder.pose(ekf.t, ekf.vehicle.position, rotation, pose_cov)
    if layout.velocity is not None:
        recorder.block(
            BlockName.VELOCITY,
            ekf.t,
            ekf.vehicle.velocity,
            P[layout.velocity, layout.velocity],
            Frame.WORLD,
        )
    if layout.gyro_bias is not None:
        recorder.block(
            BlockName.GYRO_BIAS,
            ekf.t,
            ekf.vehicle.gyro_bias,
            P[layout.gyro_bias, layout.gyro_bias],
            Frame.BODY,
        )


def record_search(recorder: EstimateRecorder, t: float, search: AssociationResult) -> None:
    """The extra ``jcbb_nodes`` ``[t, nodes, truncated]`` of a scan's search, and an event
    ``jcbb_truncated`` when the search was cut short."""
    recorder.extra("jcbb_nodes", [t, search.nodes, float(search.truncated)])
    if search.truncated:
        recorder.event(t, "jcbb_truncated", nodes=search.nodes)


def summary_note(ekf: EkfSlam, name: str, extra_gaps: int = 0) -> str:
    """The run's note on its input, association and map, headed ``name``;
    ``extra_gaps``: motion gaps counted outside the filter (``multi_hypothesis``)."""
    single = int(sum(1 for count in ekf.sightings if count == 1))
    return (
        f"{name}: motion input {ekf.input.value}, association {'+'.join(sorted(ekf.association_modes)) or 'none'}, "
        f"{len(ekf.map_ids)} landmarks mapped ({single} seen only once), {ekf.gaps + extra_gaps} motion gaps > {ekf.config.max_gap_s} s"
    )
