"""Turn simulated arrays (kinematics, inertial series, scans) into a ``Sequence``.

The stream merges the inertial samples and the landmark scans by time; at equal times the
inertial sample comes first, so an estimator propagates to a scan's time before updating.
Measurements are built afresh on every call of ``stream()`` from arrays held here, so a
sequence can be read any number of times and always yields the same values.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from datasets.measurements import GyroSample, ImuSample, LandmarkScan, Measurement, Sensor
from datasets.rotations import quat_wxyz_from_matrix, wrap_angle
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.simulation.imu import ImuSeries
from datasets.simulation.landmarks import ScanSeries
from datasets.simulation.trajectories import Kinematics
from datasets.state import BlockName, Frame, GroundTruth, LandmarkMap, StateBlock, StateHistory
from datasets.trajectory import Trajectory

TIME_DECIMALS = 9
"""Sample times are k / rate rounded to nanoseconds, so equal times of different sensors
compare equal and merge in a fixed order."""


def sample_times(duration_s: float, rate_hz: float) -> np.ndarray:
    """``k / rate_hz`` for k = 0.. while <= duration (nanosecond-rounded), shape (N,)."""
    count = int(np.floor(duration_s * rate_hz + 1e-9)) + 1
    return np.round(np.arange(count) / rate_hz, TIME_DECIMALS)


@dataclass(frozen=True)
class SimulatedData:
    """Everything a scenario simulated, before it becomes a ``Sequence``.

    Attributes:
        kinematics: truth at the inertial sample times.
        inertial: the inertial samples (3-D IMU, or planar gyro when ``accel`` is None).
        scans: landmark scans (true ids inside).
        landmark_ids: true ids (L,); landmark_positions: world positions (L, d).
        anchor_order: landmark row indices ordered for anchor use (L,).
    """

    kinematics: Kinematics
    inertial: ImuSeries
    scans: ScanSeries
    landmark_ids: np.ndarray
    landmark_positions: np.ndarray
    anchor_order: np.ndarray


def _inertial_samples(data: SimulatedData) -> list[Measurement]:
    times = data.kinematics.t
    if data.inertial.accel is None:
        return [GyroSample(t=float(t), rate=data.inertial.gyro[i].copy()) for i, t in enumerate(times)]
    return [
        ImuSample(t=float(t), gyro=data.inertial.gyro[i].copy(), accel=data.inertial.accel[i].copy())
        for i, t in enumerate(times)
    ]


def _scan_measurements(scans: ScanSeries, with_ids: bool) -> list[Measurement]:
    return [
        LandmarkScan(
            t=float(t),
            points=scans.points[i].copy(),
            covariances=scans.covariances[i].copy(),
            ids=scans.ids[i].copy() if with_ids else None,
            directions=None if scans.directions is None else scans.directions[i].copy(),
        )
        for i, t in enumerate(scans.t)
    ]


def merged_stream(data: SimulatedData, with_ids: bool) -> Iterator[Measurement]:
    """Inertial samples and scans merged by time, inertial first at equal times."""
    inertial_times, scan_times = data.kinematics.t, data.scans.t
    keys = np.concatenate([inertial_times, scan_times])
    priority = np.concatenate([np.zeros(len(inertial_times)), np.ones(len(scan_times))])
    order = np.lexsort((priority, keys))
    measurements = _inertial_samples(data) + _scan_measurements(data.scans, with_ids)
    for index in order:
        yield measurements[index]


def ground_truth(data: SimulatedData) -> GroundTruth:
    """True pose, velocity (world and body), biases, landmark map and per-scan ids."""
    kinematics = data.kinematics
    t = kinematics.t
    if kinematics.dimension == 3:
        rotations = quat_wxyz_from_matrix(kinematics.rotation)
    else:
        rotations = np.asarray(wrap_angle(kinematics.heading), dtype=float)
    blocks = {
        BlockName.VELOCITY: StateBlock(t=t, values=kinematics.velocity, frame=Frame.WORLD),
        BlockName.GYRO_BIAS: StateBlock(t=t, values=data.inertial.gyro_bias, frame=Frame.BODY),
    }
    if data.inertial.accel_bias is not None:
        blocks[BlockName.ACCEL_BIAS] = StateBlock(t=t, values=data.inertial.accel_bias, frame=Frame.BODY)
    return GroundTruth(
        history=StateHistory(pose=Trajectory(t=t, positions=kinematics.position, rotations=rotations), blocks=blocks),
        landmarks=LandmarkMap(ids=data.landmark_ids, positions=data.landmark_positions, frame=Frame.WORLD),
        body_velocity=StateBlock(t=t, values=kinematics.body_velocity(), frame=Frame.BODY),
        scan_ids=tuple((float(time), ids.copy()) for time, ids in zip(data.scans.t, data.scans.ids)),
    )


def build_sequence(
    name: str,
    data: SimulatedData,
    noise: NoiseSpec,
    with_ids: bool,
    metadata: dict[str, Any],
    velocity_sigma_m_s: float = 0.1,
) -> Sequence:
    """The ``Sequence`` of simulated data: sensors, merged stream, truth, initial state
    (the true start, stated with small sigmas), anchors in ``anchor_order``."""
    kinematics = data.kinematics
    planar = data.inertial.accel is None
    truth = ground_truth(data)
    start_rotation = truth.history.pose.rotations[0]
    order = data.anchor_order
    return Sequence(
        name=name,
        dimension=kinematics.dimension,
        sensors=frozenset({Sensor.GYRO if planar else Sensor.IMU, Sensor.LANDMARKS}),
        stream=lambda: merged_stream(data, with_ids),
        ground_truth=truth,
        noise=noise,
        initial_state=InitialState(
            t=float(kinematics.t[0]),
            position=kinematics.position[0].copy(),
            rotation=np.array(start_rotation, dtype=float),
            velocity=kinematics.velocity[0].copy(),
            velocity_sigma_m_s=velocity_sigma_m_s,
        ),
        known_landmarks=LandmarkMap(
            ids=data.landmark_ids[order].copy(), positions=data.landmark_positions[order].copy(), frame=Frame.WORLD
        ),
        metadata=metadata,
    )
