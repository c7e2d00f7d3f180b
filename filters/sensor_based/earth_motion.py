"""The vehicle's motion since the last scan, and the Earth-frame step each scan takes with it.

The Earth-frame trajectory (``earth_frame``; Guerreiro et al. 2013, sections I and V,
Fig. 8) is derived from consecutive body-frame maps; between snapshots with too few common
landmarks it falls back on the motion since the previous scan. That motion is dead-reckoned
from the filter's own estimate (``omega_m - b_hat`` and ``v_hat``), or is the odometry's
increments where odometry gives the rate. Its covariance, for the planar Earth pose's
first-order covariance (``earth_pose_covariance``, our extension), is the odometry's own
where odometry drove it, else the filter's velocity and bias uncertainty over the motion.
"""

from __future__ import annotations

import numpy as np

from datasets.measurements import Odometry
from datasets.rotations import rot2, so3_exp
from filters.sensor_based.dynamics import ProcessNoise
from filters.sensor_based.earth_frame import EARTH_MIN_SIGHTINGS, EarthFrameTracker
from filters.sensor_based.earth_pose_covariance import (
    EarthErrorCovariance,
    accumulate_odometry_covariance,
    motion_covariance,
)
from filters.sensor_based.landmark_management import LandmarkRecord
from filters.sensor_based.odometry import odometry_interval
from filters.sensor_based.state import FilterState


class MotionSinceScan:
    """The body motion since the last scan (body frame at that scan).

    Attributes:
        rotation: (d, d), translation: (d,): the motion.
        velocity_gain: (d, d) ``sum_j R_j dt_j`` over the motion [s].
        duration: its length [s].
        odometry_covariance: (k, k) its covariance from odometry, None where odometry gave
            none.
        odometry_t: time of the previous odometry sample (kept across scans).
    """

    def __init__(self, dimension: int) -> None:
        self.dimension = dimension
        self.reset()
        self.odometry_t: float | None = None

    def reset(self) -> None:
        """A scan's Earth-frame step has taken the motion: start a new one."""
        d = self.dimension
        self.rotation, self.translation = np.eye(d), np.zeros(d)
        self.velocity_gain, self.duration = np.zeros((d, d)), 0.0
        self.odometry_covariance: np.ndarray | None = None

    def accumulate(
        self, rate: np.ndarray, dt: float, velocity: np.ndarray, bias: np.ndarray
    ) -> None:
        """Dead-reckoned body motion over one prediction step from ``omega_m - b_hat`` and
        ``v_hat`` (only the Earth-frame fallback uses it)."""
        self.velocity_gain = self.velocity_gain + self.rotation * dt
        self.duration += dt
        self.translation = self.translation + self.rotation @ (velocity * dt)
        omega = (np.asarray(rate, dtype=float) - bias) * dt
        increment = rot2(float(omega[0])) if self.dimension == 2 else so3_exp(omega)
        self.rotation = self.rotation @ increment

    def carry_increment(
        self,
        rotation_before: np.ndarray,
        translation_before: np.ndarray,
        step: np.ndarray,
        turn: np.ndarray,
    ) -> None:
        """The motion over an odometry increment is the increment itself (``step``, ``turn``
        composed onto the motion before it)."""
        self.translation = translation_before + rotation_before @ step
        self.rotation = rotation_before @ turn

    def accumulate_odometry_covariance(
        self, odometry: Odometry, rotation: np.ndarray, errors: EarthErrorCovariance | None
    ) -> None:
        """Compose the sample's covariance into the motion since the last scan, for the planar
        Earth pose's covariance (``earth_pose_covariance.accumulate_odometry_covariance``;
        ``errors`` None: there is none).
        ``rotation``: the motion's rotation when the sample arrived, which is its start, or
        its end where a gyro sample of the same time came first (UTIAS: 20 ms of turn, first
        order in a lever already small)."""
        previous, self.odometry_t = self.odometry_t, float(odometry.t)
        if errors is None:
            return
        dt = odometry_interval(odometry, previous)
        covariance = np.asarray(odometry.covariance, dtype=float)
        relative = odometry.relative_pose is not None
        if relative:
            step = np.asarray(odometry.relative_pose, dtype=float)[:2]
        else:
            step = np.array([float(np.asarray(odometry.velocity)[0]) * (dt or 0.0), 0.0])
        if not (dt and dt > 0.0 and np.all(np.isfinite(covariance)) and np.all(np.isfinite(step))):
            return
        accumulated = self.odometry_covariance
        self.odometry_covariance = accumulate_odometry_covariance(
            np.zeros_like(errors.pose) if accumulated is None else accumulated,
            rotation,
            step,
            dt,
            covariance,
            relative,
        )

    def covariance(self, vehicle_covariance: np.ndarray, noise: ProcessNoise) -> np.ndarray:
        """Covariance (k, k) of the motion: the odometry's, where odometry drove it, else the
        filter's own from its [v, b] covariance ``vehicle_covariance`` and process ``noise``
        (``earth_pose_covariance``)."""
        if self.odometry_covariance is not None:
            return self.odometry_covariance
        return motion_covariance(
            self.velocity_gain,
            self.duration,
            vehicle_covariance,
            noise.velocity_m_s,
            noise.gyro_bias_rad_s,
            noise.gyro_noise_density,
        )


def step_earth_frame(
    earth: EarthFrameTracker,
    state: FilterState,
    records: dict[int, LandmarkRecord],
    motion: MotionSinceScan,
    noise: ProcessNoise,
) -> None:
    """The Earth-frame step of a scan: the body-frame map now and the motion since the
    previous scan into ``earth``; the motion starts anew."""
    ids, positions = state.landmark_positions()
    blocks = state.position_blocks()
    # keyed by map id: a deleted landmark mapped again starts a new Earth entry
    # (keyed by its scan id instead, UTIAS robot 5 read 0.46 m ATE against 0.24 m:
    # old entries carry the pose error of their time)
    # only re-sighted landmarks fix the Earth frame (``earth_frame``: a once-seen
    # landmark may be a duplicate, dead-reckoned since)
    confirmed = np.array(
        [records[int(i)].observations >= EARTH_MIN_SIGHTINGS for i in ids],
        dtype=bool,
    )
    vehicle = state.vehicle_dim
    earth.step(
        ids,
        positions,
        blocks,
        motion.rotation,
        motion.translation,
        confirmed,
        motion_covariance=(
            motion.covariance(state.covariance[:vehicle, :vehicle], noise)
            if earth.errors is not None
            else None
        ),
        joint_covariance=state.position_covariance,
    )
    motion.reset()
