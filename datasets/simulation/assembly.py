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

from datasets.errors import InputError
from datasets.measurements import (
    GyroSample,
    ImuSample,
    LandmarkScan,
    Measurement,
    Odometry,
    Sensor,
)
from datasets.rotations import quat_wxyz_from_matrix, rot2, so3_exp, wrap_angle
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.simulation.imu import ImuSeries
from datasets.simulation.landmarks import ScanSeries
from datasets.simulation.trajectories import Kinematics
from datasets.state import BlockName, Frame, GroundTruth, LandmarkMap, StateBlock, StateHistory
from datasets.trajectory import Trajectory

TIME_DECIMALS = 9
"""Sample times are k / rate rounded to nanoseconds, so equal times of different sensors
compare equal and merge in a fixed order."""

MEMORY_BOUND_BYTES = 2 * 1024**3
"""The most one simulated sequence may hold in memory: 2 GiB (``check_size``)."""
SAMPLE_BYTES = 1024
"""Memory of one inertial (or odometry) sample: its truth (pose, velocity, biases), its
measurement arrays and the measurement object each pass over the stream builds; measured
with tracemalloc at about 760 B (3-D IMU) and 990 B (planar gyro with odometry)."""
SCAN_BYTES = 2048
"""Memory of one landmark scan before its sightings (measured: about 1.8 KB)."""
SIGHTING_BYTES = 128
"""Memory of one landmark in one scan: position, covariance, id (measured: about 100 B)."""


@dataclass(frozen=True)
class SizedStream:
    """A stream sampled at ``rate_hz`` for the length of a sequence, each sample costing
    ``sample_bytes`` of memory; ``options`` says which options set it (``imu_rate_hz=100``)."""

    options: str
    rate_hz: float
    sample_bytes: float


def check_size(
    context: str,
    duration_s: float,
    duration: str,
    streams: list[SizedStream],
    limited: str = "duration_s",
    bound_bytes: float = MEMORY_BOUND_BYTES,
    bounded: str = "a simulated sequence may hold in memory",
) -> None:
    """``InputError`` when ``streams`` over ``duration_s`` would need more than
    ``bound_bytes`` (``MEMORY_BOUND_BYTES``, 2 GiB, unless given) of simulated data, naming
    ``duration`` (the option and its value, e.g. ``duration_s=1e+07``), the rates and what a
    sample costs, the bound, and the longest ``limited`` these rates allow. The bound is
    what the samples cost (``SAMPLE_BYTES``, ``SCAN_BYTES``, ``SIGHTING_BYTES``) times their
    number, ``duration_s * rate_hz`` each, so it is checked before anything is allocated;
    an infinite or NaN duration fails it too."""
    per_second = sum(stream.rate_hz * stream.sample_bytes for stream in streams)
    needed = duration_s * per_second
    if needed <= bound_bytes:  # False for inf and NaN
        return
    size = f"about {needed / 1024**3:.4g} GiB" if np.isfinite(needed) else "unbounded memory"
    costs = "; ".join(f"{stream.options}: {stream.sample_bytes:g} B a sample" for stream in streams)
    raise InputError(
        f"{context}: {duration} needs {size} of simulated data ({costs}), above the "
        f"{bound_bytes / 1024**3:g} GiB {bounded}; at these rates {limited} can be at most "
        f"{bound_bytes / per_second:.6g} s"
    )


def sample_times(duration_s: float, rate_hz: float) -> np.ndarray:
    """``k / rate_hz`` for k = 0.. while <= duration (nanosecond-rounded), shape (N,)."""
    count = int(np.floor(duration_s * rate_hz + 1e-9)) + 1
    return np.round(np.arange(count) / rate_hz, TIME_DECIMALS)


@dataclass(frozen=True)
class OdometrySeries:
    """Planar relative-pose odometry: the increment over ``(t[k] - dt[k], t[k]]``.

    Attributes:
        t: end time of each increment [s], (n,).
        dt: its duration [s], (n,).
        increments: measured (dx, dy, dtheta) in the previous body frame [m, m, rad], (n, 3).
        covariance: the stated covariance of every increment, (3, 3).
    """

    t: np.ndarray
    dt: np.ndarray
    increments: np.ndarray
    covariance: np.ndarray


@dataclass(frozen=True)
class SimulatedData:
    """Everything a scenario simulated, before it becomes a ``Sequence``.

    Attributes:
        kinematics: truth at the inertial sample times.
        inertial: the inertial samples (3-D IMU, or planar gyro when ``accel`` is None).
        scans: landmark scans (true ids inside).
        landmark_ids: true ids (L,); landmark_positions: world positions (L, d).
        anchor_order: landmark row indices ordered for anchor use (L,).
        odometry: relative-pose odometry, or None (the default: no odometry).
    """

    kinematics: Kinematics
    inertial: ImuSeries
    scans: ScanSeries
    landmark_ids: np.ndarray
    landmark_positions: np.ndarray
    anchor_order: np.ndarray
    odometry: OdometrySeries | None = None


def _inertial_samples(data: SimulatedData) -> list[Measurement]:
    times = data.kinematics.t
    if data.inertial.accel is None:
        return [
            GyroSample(t=float(t), rate=data.inertial.gyro[i].copy()) for i, t in enumerate(times)
        ]
    return [
        ImuSample(
            t=float(t), gyro=data.inertial.gyro[i].copy(), accel=data.inertial.accel[i].copy()
        )
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


def _odometry_measurements(odometry: OdometrySeries | None) -> list[Measurement]:
    if odometry is None:
        return []
    return [
        Odometry(
            t=float(t),
            covariance=odometry.covariance.copy(),
            relative_pose=odometry.increments[i].copy(),
            dt=float(odometry.dt[i]),
        )
        for i, t in enumerate(odometry.t)
    ]


def merged_stream(data: SimulatedData, with_ids: bool) -> Iterator[Measurement]:
    """Inertial samples, odometry and scans merged by time, in that order at equal times."""
    inertial_times, scan_times = data.kinematics.t, data.scans.t
    odometry_times = np.zeros(0) if data.odometry is None else data.odometry.t
    keys = np.concatenate([inertial_times, odometry_times, scan_times])
    priority = np.concatenate(
        [
            np.zeros(len(inertial_times)),
            np.full(len(odometry_times), 0.5),
            np.ones(len(scan_times)),
        ]
    )
    order = np.lexsort((priority, keys))
    measurements = (
        _inertial_samples(data)
        + _odometry_measurements(data.odometry)
        + _scan_measurements(data.scans, with_ids)
    )
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
        blocks[BlockName.ACCEL_BIAS] = StateBlock(
            t=t, values=data.inertial.accel_bias, frame=Frame.BODY
        )
    return GroundTruth(
        history=StateHistory(
            pose=Trajectory(t=t, positions=kinematics.position, rotations=rotations), blocks=blocks
        ),
        landmarks=LandmarkMap(
            ids=data.landmark_ids, positions=data.landmark_positions, frame=Frame.WORLD
        ),
        body_velocity=StateBlock(t=t, values=kinematics.body_velocity(), frame=Frame.BODY),
        scan_ids=tuple(
            (float(time), ids.copy()) for time, ids in zip(data.scans.t, data.scans.ids)
        ),
    )


@dataclass(frozen=True)
class InitialSigmas:
    """Stated uncertainty of the simulated initial state (before noise scaling)."""

    position_m: float = 0.01
    rotation_rad: float = 0.005
    velocity_m_s: float = 0.1


def initial_state_draw(
    pose: Trajectory,
    velocity: np.ndarray,
    rng: np.random.Generator,
    drawn: float,
    stated: float,
    sigmas: InitialSigmas,
) -> InitialState:
    """The initial state as a draw from its stated distribution around the true start.

    Errors follow the interface convention (right perturbation): ``R_true = R_0 Exp(dtheta)``
    and ``p_true = p_0 + R_0 dp`` with ``dtheta ~ N(0, s_r^2 I)``, ``dp ~ N(0, s_p^2 I)``;
    ``v_true = v_0 + dv``. Sigmas are floored at 1e-9 so a noise-free run keeps a valid prior.
    """
    dimension = pose.dimension
    position_error = rng.normal(0.0, sigmas.position_m * drawn, dimension)
    velocity_error = rng.normal(0.0, sigmas.velocity_m_s * drawn, dimension)
    if dimension == 3:
        rotation_error = rng.normal(0.0, sigmas.rotation_rad * drawn, 3)
        true_rotation = pose.rotation_matrices()[0]
        start_rotation = true_rotation @ so3_exp(-rotation_error)
        rotation = quat_wxyz_from_matrix(start_rotation)
    else:
        heading_error = rng.normal(0.0, sigmas.rotation_rad * drawn)
        start_heading = float(pose.rotations[0] - heading_error)
        start_rotation = rot2(start_heading)
        rotation = np.array(start_heading)
    return InitialState(
        t=float(pose.t[0]),
        position=pose.positions[0] - start_rotation @ position_error,
        rotation=rotation,
        velocity=np.asarray(velocity, dtype=float) - velocity_error,
        position_sigma_m=max(sigmas.position_m * stated, 1e-9),
        rotation_sigma_rad=max(sigmas.rotation_rad * stated, 1e-9),
        velocity_sigma_m_s=max(sigmas.velocity_m_s * stated, 1e-9),
    )


def build_sequence(
    name: str,
    data: SimulatedData,
    noise: NoiseSpec,
    with_ids: bool,
    metadata: dict[str, Any],
    initial_rng: np.random.Generator,
    drawn: float,
    stated: float,
    initial_sigmas: InitialSigmas = InitialSigmas(),
) -> Sequence:
    """The ``Sequence`` of simulated data: sensors, merged stream, truth, initial state,
    anchors in ``anchor_order``.

    The initial state is a draw around the true start with the sigmas it states (drawn
    sigmas scaled by ``drawn``, stated ones by ``stated``), so that an estimator that takes
    it as its prior starts consistent rather than over-confident or over-cautious.
    """
    kinematics = data.kinematics
    planar = data.inertial.accel is None
    truth = ground_truth(data)
    order = data.anchor_order
    initial_state = initial_state_draw(
        truth.history.pose, kinematics.velocity[0], initial_rng, drawn, stated, initial_sigmas
    )
    return Sequence(
        name=name,
        dimension=kinematics.dimension,
        sensors=frozenset(
            {Sensor.GYRO if planar else Sensor.IMU, Sensor.LANDMARKS}
            | ({Sensor.ODOMETRY} if data.odometry is not None else set())
        ),
        stream=lambda: merged_stream(data, with_ids),
        ground_truth=truth,
        noise=noise,
        initial_state=initial_state,
        known_landmarks=LandmarkMap(
            ids=data.landmark_ids[order].copy(),
            positions=data.landmark_positions[order].copy(),
            frame=Frame.WORLD,
        ),
        metadata=metadata,
        reference_source="simulated truth",
        landmark_ids=with_ids,
    )
