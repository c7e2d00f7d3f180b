"""The Guerreiro et al. (2013) sensor-based SLAM filter, registered as ``sensor-based``.

Robocentric LTV Kalman filter: state = body-frame velocity, rate-gyro bias and body-frame
landmarks (optionally with line directions); inputs = rate gyro (``GyroSample``, or the
gyro of an ``ImuSample``: the accelerometer is unused) and ``LandmarkScan`` (body-frame
points). Prediction at every gyro sample (``dynamics.propagate_in_place``, eq. (10)),
association by the shared policy (``filters.association``: the scan's ids, or JCBB), the
section IV-B update through the shared Kalman core (``update``), landmark
management (``landmark_management``), loop closing between the current and old landmark
sets (``loop_closing``, section IV-C) and the Earth-frame trajectory derived from the map
history (``earth_frame``).

Geometric association uses only the current set I_cur (landmarks seen within
``association_window_s``), as the paper does; an unassociated measurement starts a new
landmark only when it lies outside every current landmark's gate even at
``new_landmark_probability`` (otherwise it is ambiguous: recorded, neither used nor mapped).

Discretization: eq. (10) is forward Euler; the default solves the same LTV model exactly
over each step with the inputs held (``dynamics.propagate``), because Euler's ``I - Ts S(w)``
dilates the landmarks during turns, which the filter mistakes for speed (measured: a common
-3 mm/s forward-velocity error after each corridor corner of ``sim:guerreiro-loop``, four
times the true scatter). ``discretization="euler"`` gives the literal eq. (10).

Multirate: the paper assumes synchronised gyro and laser; here ``A(t, y)`` holds each
visible feature's last measured value between scans (stale by at most one scan period;
it enters only through the tiny ``M(y) b`` bias term). Long steps are split into sub-steps
of at most ``max_step_s``. The rate over a gyro interval is, by default, the mean of the
two samples that bracket it (``interval_rate="average"``): a sampled gyro reads the
instantaneous rate, and holding the earlier sample (the literal forward Euler of eq. (10))
mis-integrates the heading by ``0.5 omega_dot Ts^2`` per step, which at the 10 Hz of the
paper and a corner's ``omega_dot ~ 0.1 rad/s^2`` is a bias-sized error of 5e-3 rad/s.
``"hold"`` gives the literal scheme. A scan between gyro samples is reached with the held
rate; the rest of that interval uses the average once the next sample arrives.

Exported (DESIGN.md): ``velocity`` (body frame) and ``gyro_bias`` after every scan,
``landmarks`` snapshots (body frame, the filter's own map ids) every
``snapshot_interval_s``; ``pose`` is the Earth-frame
trajectory *derived* from consecutive body-frame maps, planar with the first-order covariance
of ``earth_pose_covariance`` (our extension), 3-D without one (``earth_frame=false`` turns
it off); extras ``vehicle_t``/``vehicle_state``/``vehicle_covariance`` carry the joint
[v, b] block for the vehicle NEES. NIS: the stacked innovation of every scan, and one
value per associated landmark (eq. (11)), dof = its block size.

Measurement noise: the filter uses each scan's stated covariances. (The simulator gives
the first-order polar-to-Cartesian ``J diag(sigma_rho^2, sigma_alpha^2) J^T``; the paper's
printed ``sigma_rho^2 M_alpha + sigma_alpha^2 dM_alpha/dalpha`` is not a covariance: its
second term is indefinite and lacks the rho^2 factor.)
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import ClassVar

import numpy as np
from pydantic import BaseModel

from datasets.errors import InputError
from datasets.estimate import Estimate, EstimateRecorder
from datasets.estimator_options import per_body_axis
from datasets.measurements import (
    GyroSample,
    ImuSample,
    LandmarkScan,
    Measurement,
    Odometry,
    Sensor,
)
from datasets.model_options import interval_value
from datasets.range_bearing import first_order_covariance
from datasets.rotations import matrix_from_quat_wxyz, quat_wxyz_from_matrix, rot2, so3_exp
from datasets.sequence import Sequence
from datasets.state import BlockName, Frame, LandmarkMap
from datasets.stream_clock import StreamClock
from filters import kalman
from filters.association import AssociationPolicy, Decision, Reason, ScanAssociation
from filters.ekf_slam.boundary import pose_covariance_to_interface
from filters.sensor_based.config import (
    PAPER_BEARING_SIGMA_RAD,
    PAPER_GYRO_BIAS_WALK_RAD_S_SQRT_S,
    PAPER_RANGE_SIGMA_M,
    PAPER_RANGE_SWITCH_M,
    SensorBasedConfig,
    landmark_disturbance,
)
from filters.sensor_based.directions import direction_covariance, match_direction
from filters.sensor_based.dynamics import ProcessNoise, propagate_in_place, rate_dimension
from filters.sensor_based.earth_frame import EARTH_MIN_SIGHTINGS, EarthFrameTracker
from filters.sensor_based.earth_pose_covariance import (
    accumulate_odometry_covariance,
    motion_covariance,
)
from filters.sensor_based.landmark_management import LandmarkManager, ManagementPolicy
from filters.sensor_based.loop_closing import (
    LoopClosurePolicy,
    constraint_update,
    find_loop_closure,
)
from filters.sensor_based.state import FilterState, LandmarkPredictor
from filters.sensor_based.update import selection_update


def paper_laser_covariances(points: np.ndarray) -> np.ndarray:
    """The paper's laser model (section V) for body-frame points (k, 2): the first-order
    covariance of range ``sigma_rho`` and bearing ``sigma_alpha`` at the measured range and
    bearing (``datasets.range_bearing``; the printed ``Theta_p`` is not a covariance, see
    there), shape (k, 2, 2)."""
    ranges = np.linalg.norm(points, axis=1)
    bearings = np.arctan2(points[:, 1], points[:, 0])
    near, far = PAPER_RANGE_SIGMA_M
    range_sigma = np.where(ranges <= PAPER_RANGE_SWITCH_M, near, far)
    return first_order_covariance(ranges, bearings, range_sigma, PAPER_BEARING_SIGMA_RAD)


ODOMETRY_RATE_BIAS_SIGMA_RAD_S = 1e-4
"""Prior std of the gyro-bias state when the rate comes from odometry (it has no bias; the
state stays so that the model is the paper's) [rad/s]."""


def _interval(odometry: Odometry, previous_t: float | None) -> float:
    """An odometry sample's interval [s]: its own ``dt``, else the time since the previous
    sample (0 for the first: ``previous_t`` None). A previous time of 0.0 is a time like any
    other (a run starting at t = 0 once lost its first increment here)."""
    if odometry.dt is not None:
        return odometry.dt
    return 0.0 if previous_t is None else odometry.t - previous_t


class SensorBasedSlam:
    """Guerreiro et al. (2013) GAS sensor-based SLAM filter, 2-D and 3-D."""

    Config: ClassVar[type[BaseModel]] = SensorBasedConfig
    sensor_options: ClassVar[tuple[frozenset[Sensor], ...]] = (
        frozenset({Sensor.GYRO, Sensor.LANDMARKS}),
        frozenset({Sensor.IMU, Sensor.LANDMARKS}),
        frozenset({Sensor.ODOMETRY, Sensor.LANDMARKS}),
    )
    dimensions: ClassVar[frozenset[int]] = frozenset({2, 3})

    def __init__(self, config: SensorBasedConfig, sequence: Sequence) -> None:
        self.config = config
        self.name = sequence.name
        self.dimension = d = sequence.dimension
        self.rate_dim = r = rate_dimension(d)
        density = config.gyro_noise_density_rad_s_sqrt_hz
        if density is None:
            density = sequence.noise.gyro_noise_density or 0.0
        if config.tuning == "paper" and d != 2:
            raise InputError(
                f"{sequence.name}: tuning=paper is the paper's planar laser model (2-D datasets)"
            )
        velocity_walk = per_body_axis(
            config.velocity_walk_m_s_sqrt_s, d, "velocity_walk_m_s_sqrt_s"
        )
        bias_walk = config.gyro_bias_walk_rad_s_sqrt_s
        if bias_walk is None:
            stated = sequence.noise.gyro_bias_walk
            bias_walk = PAPER_GYRO_BIAS_WALK_RAD_S_SQRT_S if stated is None else stated
        self.noise = ProcessNoise(
            velocity_m_s=velocity_walk,
            gyro_bias_rad_s=bias_walk,
            landmark_m=landmark_disturbance(config),
            direction=config.direction_walk_per_sqrt_s,
            gyro_noise_density=float(density),
        )
        start = sequence.initial_state
        velocity = np.zeros(d)
        velocity_sigma = config.initial_velocity_sigma_m_s or 2.0
        if start is not None and start.velocity is not None:
            rotation = (
                rot2(float(start.rotation)) if d == 2 else matrix_from_quat_wxyz(start.rotation)
            )
            velocity = rotation.T @ np.asarray(start.velocity, dtype=float)
            velocity_sigma = config.initial_velocity_sigma_m_s or start.velocity_sigma_m_s
        if config.initial_velocity_error_m_s is not None:
            velocity = velocity + self._vector(
                config.initial_velocity_error_m_s, d, "initial_velocity_error_m_s"
            )
        bias = np.zeros(r)
        if config.initial_gyro_bias_rad_s is not None:
            bias = self._vector(config.initial_gyro_bias_rad_s, r, "initial_gyro_bias_rad_s")
        # no gyro: the rate is the odometry's rotation over each increment (lidar odometry),
        # which has no bias of its own; the bias state stays, with a tight prior
        self.rate_from_odometry = not ({Sensor.GYRO, Sensor.IMU} & sequence.sensors)
        bias_sigma = config.initial_gyro_bias_sigma_rad_s or (
            ODOMETRY_RATE_BIAS_SIGMA_RAD_S
            if self.rate_from_odometry
            else sequence.noise.gyro_bias_sigma_rad_s or 0.05
        )
        self.state = FilterState(
            d, velocity, velocity_sigma**2 * np.eye(d), bias, bias_sigma**2 * np.eye(r)
        )
        self.manager = LandmarkManager(
            ManagementPolicy(
                in_view_range_m=config.in_view_range_m,
                field_of_view_deg=config.landmark_field_of_view_deg
                or sequence.noise.landmark_field_of_view_deg
                or 360.0,
                max_missed_in_view=config.max_missed_in_view,
                min_observations=config.min_observations,
                probation_s=math.inf if config.probation_s is None else config.probation_s,
                max_landmarks=config.max_landmarks,
            )
        )
        self.recorder = EstimateRecorder(d, config.snapshot_interval_s)
        self.policy = AssociationPolicy(config, d, sequence.noise.sighting_correlation)
        start_rotation, start_position = np.eye(d), np.zeros(d)
        start_covariance = None
        if start is not None:
            start_rotation = (
                rot2(float(start.rotation)) if d == 2 else matrix_from_quat_wxyz(start.rotation)
            )
            start_position = np.asarray(start.position, dtype=float)
            position_sigma = config.initial_position_sigma_m or start.position_sigma_m
            rotation_sigma = config.initial_rotation_sigma_rad or start.rotation_sigma_rad
            start_covariance = np.diag([position_sigma**2] * d + [rotation_sigma**2] * r)
        self.earth = (
            EarthFrameTracker(d, start_rotation, start_position, covariance=start_covariance)
            if config.earth_frame
            else None
        )
        self.loop_policy = LoopClosurePolicy(
            current_window_s=config.association_window_s,
            old_after_s=max(config.loop_old_after_s, config.association_window_s),
            min_pairs=config.loop_min_pairs,
            every_s=config.loop_every_s,
            gate_probability=config.gate_probability,
            max_nodes=config.max_jcbb_nodes,
            unambiguous_only=config.loop_unambiguous_only,
        )
        self._last_loop_search = -np.inf
        self._motion_rotation = np.eye(d)  # the filter's own motion since the last scan (fallback)
        self._motion_translation = np.zeros(d)
        self._motion_velocity_gain = np.zeros((d, d))  # sum_j R_j dt_j over that motion [s]
        self._motion_duration = 0.0  # [s]
        self._motion_odometry_covariance: np.ndarray | None = None  # (k, k), from odometry
        self._covariance_odometry_t: float | None = None
        self.t: float | None = None if start is None else float(start.t)
        self.clock = StreamClock(self.name, self.t)
        self.rate: np.ndarray | None = None
        self.scan_count = 0
        self.skipped: dict[str, int] = {
            "nan_rate": 0,
            "nan_points": 0,
            "scan_without_rate": 0,
            "nan_odometry": 0,
        }
        # odometry as a body-velocity measurement (an extension beyond the paper)
        self.use_odometry = Sensor.ODOMETRY in sequence.sensors and config.use_odometry
        self.odometry_model = sequence.noise.odometry
        self._odometry_t: float | None = None
        self._rate_odometry_t: float | None = None
        self.source_of: dict[int, int] = {}  # map id -> the scan id it was created from
        self._record_vehicle(self.t if self.t is not None else 0.0)
        self._record_pose(self.t if self.t is not None else 0.0)

    @staticmethod
    def _vector(values: list[float], size: int, name: str) -> np.ndarray:
        vector = np.asarray(values, dtype=float).ravel()
        if vector.size != size:
            raise InputError(f"config {name}: expected {size} values, got {vector.size}")
        return vector

    # ------------------------------------------------------------------ inputs
    def process(self, measurement: Measurement) -> None:
        self.clock.advance(measurement.t, type(measurement).__name__)
        if isinstance(measurement, GyroSample):
            self._rate_sample(measurement.t, np.asarray(measurement.rate, dtype=float).ravel())
        elif isinstance(measurement, ImuSample):
            gyro = np.asarray(measurement.gyro, dtype=float).ravel()
            self._rate_sample(measurement.t, gyro[2:3] if self.dimension == 2 else gyro)
        elif isinstance(measurement, LandmarkScan):
            self._scan(measurement)
        elif isinstance(measurement, Odometry):
            rotation_before = self._motion_rotation
            if self.rate_from_odometry:
                self._odometry_rate(measurement)
            if self.use_odometry:
                self._odometry(measurement)
            self._accumulate_odometry_covariance(measurement, rotation_before)
            if measurement.frame:
                # a sensor frame without a scan (a sweep without corners): the pose there is
                # the Earth pose carried by the motion since the last scan
                self._record_carried_pose(measurement.t)

    # ------------------------------------------------------------------ odometry
    def _accumulate_odometry_covariance(self, odometry: Odometry, rotation: np.ndarray) -> None:
        """Compose the sample's covariance into the motion since the last scan, for the planar
        Earth pose's covariance (``earth_pose_covariance.accumulate_odometry_covariance``).
        ``rotation``: the motion's rotation when the sample arrived, which is its start, or
        its end where a gyro sample of the same time came first (UTIAS: 20 ms of turn, first
        order in a lever already small)."""
        previous, self._covariance_odometry_t = self._covariance_odometry_t, float(odometry.t)
        if self.earth is None or self.earth.errors is None:
            return
        dt = _interval(odometry, previous)
        covariance = np.asarray(odometry.covariance, dtype=float)
        relative = odometry.relative_pose is not None
        if relative:
            step = np.asarray(odometry.relative_pose, dtype=float)[:2]
        else:
            step = np.array([float(np.asarray(odometry.velocity)[0]) * (dt or 0.0), 0.0])
        if not (dt and dt > 0.0 and np.all(np.isfinite(covariance)) and np.all(np.isfinite(step))):
            return
        accumulated = self._motion_odometry_covariance
        self._motion_odometry_covariance = accumulate_odometry_covariance(
            np.zeros_like(self.earth.errors.pose) if accumulated is None else accumulated,
            rotation,
            step,
            dt,
            covariance,
            relative,
        )

    def _odometry_rate(self, odometry: Odometry) -> None:
        """Without a gyro, the rate input over an odometry increment is its rotation over
        its duration (``log(dR) / dt``, held over the increment), and the white noise the
        model injects through ``G`` is the increment's rotation variance over ``dt``
        (a rate error of covariance ``Sigma_w / dt^2`` held for ``dt`` is a density
        ``Sigma_w / dt``). An extension beyond the paper, which assumes a rate gyro."""
        previous, self._rate_odometry_t = self._rate_odometry_t, float(odometry.t)
        if previous is None:
            previous = self.t
        dt = _interval(odometry, previous)
        covariance = np.asarray(odometry.covariance, dtype=float)
        if odometry.relative_pose is not None:
            if not dt or dt <= 0.0:
                self._propagate_to(odometry.t)
                return
            pose = np.asarray(odometry.relative_pose, dtype=float)
            rotation = pose[2:3] if self.dimension == 2 else pose[0:3]
            rotation_cov = covariance[2:3, 2:3] if self.dimension == 2 else covariance[0:3, 0:3]
            rate = rotation / dt
            density_sq = float(np.mean(np.diag(rotation_cov))) / dt
        else:
            velocity = np.asarray(odometry.velocity, dtype=float)
            rate = velocity[1:2] if self.dimension == 2 else velocity[3:6]
            rate_cov = covariance[1:2, 1:2] if self.dimension == 2 else covariance[3:6, 3:6]
            density_sq = float(np.mean(np.diag(rate_cov))) * max(dt or 0.0, 0.0)
        if not (np.all(np.isfinite(rate)) and np.isfinite(density_sq)):
            self.skipped["nan_odometry"] += 1
            self._propagate_to(odometry.t)
            return
        self.noise = replace(self.noise, gyro_noise_density=math.sqrt(max(density_sq, 0.0)))
        rotation_before, translation_before = self._motion_rotation, self._motion_translation
        self._propagate_to(odometry.t, rate)
        self.rate = rate
        if odometry.relative_pose is not None:
            # the Earth-frame fallback's motion over this increment is the increment itself
            # (the velocity state, still converging at the start, would lose the distance)
            pose = np.asarray(odometry.relative_pose, dtype=float)
            if self.dimension == 2:
                step, turn = pose[:2], rot2(float(pose[2]))
            else:
                step, turn = pose[3:6], so3_exp(pose[0:3])
            self._motion_translation = translation_before + rotation_before @ step
            self._motion_rotation = rotation_before @ turn

    def _odometry(self, odometry: Odometry) -> None:
        """Odometry as a measurement of the body velocity ``v`` (a selection of the state):
        an extension beyond the paper (config ``use_odometry``). The sample's mean velocity
        over its interval is taken as the velocity at its time; relative poses give
        ``translation / dt``. The noise is the sample's own; a planar velocity sample's
        lateral variance comes from the dataset's odometry noise model (else
        ``odometry_lateral_sigma_m_s``). Its innovations are recorded apart
        (``extras['odometry_velocity_nis']``): the table's NIS stays the landmarks' one."""
        d = self.dimension
        previous, self._odometry_t = self._odometry_t, float(odometry.t)
        self._propagate_to(odometry.t)
        measured, covariance = self._odometry_velocity(odometry, previous)
        if measured is None:
            return
        if not (np.all(np.isfinite(measured)) and np.all(np.isfinite(covariance))):
            self.skipped["nan_odometry"] += 1
            return
        state = self.state
        state.x, outcome = selection_update(
            state.x, state.covariance, np.arange(d), measured, covariance, [np.arange(d)]
        )
        if outcome.innovation is not None:
            self.recorder.extra(
                "odometry_velocity_nis",
                [odometry.t, outcome.innovation.nis, outcome.innovation.dof],
            )
        if outcome.correction is None:
            self.recorder.event(odometry.t, "update_refused", reason=outcome.refused)

    def _odometry_velocity(
        self, odometry: Odometry, previous_t: float | None
    ) -> tuple[np.ndarray | None, np.ndarray]:
        """(body velocity (d,), its covariance (d, d)) of an odometry sample, or None when
        its interval is unknown (the first velocity sample)."""
        d = self.dimension
        cov = np.asarray(odometry.covariance, dtype=float)
        if odometry.relative_pose is not None:
            dt = (
                odometry.dt
                if odometry.dt is not None
                else (odometry.t - previous_t if previous_t is not None else 0.0)
            )
            if not dt or dt <= 0:
                return None, cov
            pose = np.asarray(odometry.relative_pose, dtype=float)
            if d == 2:
                return pose[:2] / dt, cov[:2, :2] / dt**2
            return pose[3:6] / dt, cov[3:6, 3:6] / dt**2
        velocity = np.asarray(odometry.velocity, dtype=float)
        if d == 3:
            return velocity[:3], cov[:3, :3]
        if previous_t is None or odometry.t <= previous_t:
            return None, cov
        dt = odometry.t - previous_t
        model = self.odometry_model
        lateral = (
            model.variances(np.array([dt]), abs(velocity[0]) * dt, abs(velocity[1]) * dt)[0, 1]
            / dt**2
            if model is not None
            else self.config.odometry_lateral_sigma_m_s**2
        )
        return np.array([velocity[0], 0.0]), np.diag([cov[0, 0], max(lateral, 1e-12)])

    def _rate_sample(self, t: float, rate: np.ndarray) -> None:
        if rate.size != self.rate_dim:
            raise InputError(
                f"{self.name}: gyro sample at t={t:.6f} s has {rate.size} components, expected {self.rate_dim}"
            )
        if not np.all(np.isfinite(rate)):
            # Keep the previous rate (zero-order hold) and say so: a NaN must not reach the state.
            self.skipped["nan_rate"] += 1
            if self.skipped["nan_rate"] == 1:
                self.recorder.event(
                    t, "skipped_input", reason="non-finite gyro rate; previous rate held"
                )
            self._propagate_to(t)
            return
        if self.rate is None and self.config.interval_rate != "latest":
            self._propagate_to(t)  # no earlier sample to average or hold: zero rate
        else:
            self._propagate_to(t, interval_value(self.config.interval_rate, self.rate, rate))
        self.rate = rate

    def _propagate_to(self, t: float, rate: np.ndarray | None = None) -> None:
        if self.t is None:
            self.t = float(t)
            return
        dt = t - self.t  # >= 0: the stream clock has checked the order
        if dt > self.config.max_gap_s:
            raise InputError(
                f"{self.name}: gap of {dt:.3f} s before t={t:.6f} s exceeds max_gap_s={self.config.max_gap_s}"
            )
        if dt == 0.0:
            return
        if rate is None:
            rate = self.rate if self.rate is not None else np.zeros(self.rate_dim)
        # a gap of a whole number of steps plus float64 rounding sub-steps as that number:
        # epoch stamps (1.3e9 s) resolve 0.1 s only to 2e-7 s, and 1e-9 of a step let the
        # same scans stamped two ways propagate in 2 or 3 steps
        steps = max(1, int(math.ceil(dt / self.config.max_step_s - 1e-5)))
        state = self.state
        for _ in range(steps):
            self._accumulate_motion(rate, dt / steps)
            state.x = propagate_in_place(
                state.x,
                state.covariance,
                state.is_position,
                state.measured,
                state.visible,
                rate,
                dt / steps,
                self.noise,
                self.dimension,
                self.config.discretization,
            )
        self.t = float(t)

    def _accumulate_motion(self, rate: np.ndarray, dt: float) -> None:
        """Dead-reckoned body motion since the last scan from ``omega_m - b_hat`` and ``v_hat``
        (only the Earth-frame fallback uses it)."""
        if self.earth is None:
            return
        self._motion_velocity_gain = self._motion_velocity_gain + self._motion_rotation * dt
        self._motion_duration += dt
        self._motion_translation = self._motion_translation + self._motion_rotation @ (
            self.state.velocity * dt
        )
        omega = (np.asarray(rate, dtype=float) - self.state.bias) * dt
        increment = rot2(float(omega[0])) if self.dimension == 2 else so3_exp(omega)
        self._motion_rotation = self._motion_rotation @ increment

    # ------------------------------------------------------------------ scans
    def _scan(self, scan: LandmarkScan) -> None:
        d = self.dimension
        points = (
            np.asarray(scan.points, dtype=float).reshape(-1, d)
            if np.size(scan.points)
            else np.zeros((0, d))
        )
        covs = (
            np.asarray(scan.covariances, dtype=float).reshape(-1, d, d)
            if np.size(scan.covariances)
            else np.zeros((0, d, d))
        )
        if points.shape[0] != covs.shape[0]:
            raise InputError(
                f"{self.name}: scan at t={scan.t:.6f} s has {points.shape[0]} points but {covs.shape[0]} covariances"
            )
        if self.config.tuning == "paper":
            covs = paper_laser_covariances(points)
        if self.rate is None:
            self.skipped["scan_without_rate"] += 1
        self._propagate_to(scan.t)
        t = float(scan.t)
        k = points.shape[0]
        usable = np.all(np.isfinite(points), axis=1) & np.all(
            np.isfinite(covs.reshape(k, d * d)), axis=1
        )
        if not usable.all():
            self.skipped["nan_points"] += int((~usable).sum())
            self.recorder.event(
                t,
                "skipped_input",
                reason="non-finite scan points dropped",
                count=int((~usable).sum()),
            )
        directions = None
        if self.config.use_directions and scan.directions is not None:
            directions = np.asarray(scan.directions, dtype=float).reshape(k, -1, d)

        association = self._associate(t, scan.ids, points, covs, usable)
        # matched candidates are landmark ids here (``_associate``)
        association = self.policy.decorrelated(association, t, points, covs, association.candidates)
        self.state.visible[:] = False  # I_O is redefined by every scan (section IV-B)
        assignment = self._update(t, points, covs, directions, association)
        for j in association.rows(Decision.NEW):
            landmark_id = self._add_landmark(
                t, points[j], covs[j], None if directions is None else directions[j]
            )
            assignment[j] = landmark_id
            self.policy.sighted(landmark_id, t)
            if association.mode == "ids":
                self.source_of[landmark_id] = int(scan.ids[j])
        for j, decision in enumerate(association.decisions):
            self.recorder.association(
                t,
                j,
                int(assignment[j]),
                decision,
                association.reasons[j],
                association.inflation[j],
                association.alternatives_of(j),
            )

        seen_ids = {int(a) for a in assignment if a >= 0}
        state = self.state
        ids, positions = state.landmark_positions()
        blocks = state.position_blocks()
        doomed = self.manager.after_scan(t, ids, np.isin(ids, list(seen_ids)), positions, blocks)
        if doomed:
            state.remove_landmarks(doomed)
            self.manager.removed(doomed)
            for landmark_id in doomed:
                self.source_of.pop(landmark_id, None)
        # With ids the association itself closes a loop (a sighting pairs with the landmark
        # of its id wherever it is in the map); the geometric search of section IV-C is for
        # scans without ids (with ids it merged landmarks by layout against their ids:
        # pair precision 0.2-0.4 on UTIAS)
        if (
            self.config.loop_closing
            and self.policy.mode(scan.ids, t) != "ids"
            and t - self._last_loop_search >= self.loop_policy.every_s
        ):
            self._last_loop_search = t
            self._close_loops(t)
        self.scan_count += 1
        self.recorder.landmark_count(t, len(state.landmark_ids()))
        self.recorder.extra("visible_landmarks", float(len(seen_ids)))
        self._record_vehicle(t)
        if self.earth is not None:
            ids, positions = state.landmark_positions()
            blocks = state.position_blocks()
            # keyed by map id: a deleted landmark mapped again starts a new Earth entry
            # (keyed by its scan id instead, UTIAS robot 5 read 0.46 m ATE against 0.24 m:
            # old entries carry the pose error of their time)
            # only re-sighted landmarks fix the Earth frame (``earth_frame``: a once-seen
            # landmark may be a duplicate, dead-reckoned since)
            confirmed = np.array(
                [self.manager.records[int(i)].observations >= EARTH_MIN_SIGHTINGS for i in ids],
                dtype=bool,
            )
            self.earth.step(
                ids,
                positions,
                blocks,
                self._motion_rotation,
                self._motion_translation,
                confirmed,
                motion_covariance=(
                    self._motion_covariance() if self.earth.errors is not None else None
                ),
                joint_covariance=state.position_covariance,
            )
            self._motion_rotation, self._motion_translation = np.eye(d), np.zeros(d)
            self._motion_velocity_gain, self._motion_duration = np.zeros((d, d)), 0.0
            self._motion_odometry_covariance = None
            self._record_pose(t)
        if self.recorder.snapshot_due(t):
            self.recorder.landmarks(self.landmark_map(t))

    def _close_loops(self, t: float) -> None:
        """Section IV-C: fuse current landmarks with their old duplicates; keep the old id."""
        state = self.state
        ids, positions = state.landmark_positions()
        if len(ids) < 2:
            return
        ages = np.array([t - self.manager.records[int(i)].last_seen_t for i in ids])
        current = np.flatnonzero(ages <= self.loop_policy.current_window_s)
        old = np.flatnonzero(ages > self.loop_policy.old_after_s)
        if len(old):
            # Measured on the data: the true revisit on sim:guerreiro-loop pairs old landmarks
            # of std ~0.6 m; Victoria Park's false closures had 2-21 m (trees 5-10 m apart).
            largest = np.sqrt(np.linalg.eigvalsh(state.position_blocks(old))[:, -1])
            old = old[largest <= self.config.loop_max_old_sigma_m]
        if len(current) == 0 or len(old) == 0:
            return
        union = np.concatenate([current, old])  # only these landmarks' joint covariance
        local = find_loop_closure(
            positions[union],
            state.position_covariance(union),
            np.arange(len(current)),
            np.arange(len(current), len(union)),
            self.loop_policy,
        )
        pairs = [(int(union[i]), int(union[j])) for i, j in local]
        if not pairs:
            return
        features = state.position_features()
        first = state.state_indices(features[[i for i, _ in pairs]])
        second = state.state_indices(features[[j for _, j in pairs]])
        state.x, state.covariance = constraint_update(state.x, state.covariance, first, second)
        fused = []
        for current_index, old_index in pairs:
            kept, removed = int(ids[old_index]), int(ids[current_index])
            kept_record, removed_record = self.manager.records[kept], self.manager.records[removed]
            kept_record.last_seen_t = max(kept_record.last_seen_t, removed_record.last_seen_t)
            kept_record.observations += removed_record.observations
            kept_record.missed_in_view = 0
            kept_feature, removed_feature = features[old_index], features[current_index]
            if state.visible[removed_feature]:
                state.visible[kept_feature] = True
                state.measured[kept_feature] = state.measured[removed_feature]
            if removed in self.source_of:
                self.source_of.setdefault(kept, self.source_of.pop(removed))
            fused.append([kept, removed])
        removed_ids = [removed for _, removed in fused]
        if self.earth is not None:
            for removed in removed_ids:  # the old landmark's Earth position stays
                self.earth.forget(removed)
        state.remove_landmarks(removed_ids)
        self.manager.removed(removed_ids)
        self.recorder.event(t, "loop_closure", pairs=fused)

    def _add_landmark(
        self, t: float, point: np.ndarray, cov: np.ndarray, directions: np.ndarray | None
    ) -> int:
        direction_values = direction_covs = None
        if directions is not None:
            valid = [u for u in directions if np.all(np.isfinite(u)) and np.linalg.norm(u) > 0]
            if valid:
                direction_values = [u / np.linalg.norm(u) for u in valid]
                direction_covs = [
                    direction_covariance(u, self.config.direction_sigma_rad)
                    for u in direction_values
                ]
        landmark_id = self.state.add_landmark(point, cov, direction_values, direction_covs)
        self.manager.created(landmark_id, t)
        return landmark_id

    def _associate(
        self,
        t: float,
        scan_ids: np.ndarray | None,
        points: np.ndarray,
        covs: np.ndarray,
        usable: np.ndarray,
    ) -> ScanAssociation:
        """One decision per sighting (the shared policy): by ids against every landmark in
        the state, else JCBB against the current set I_cur only (the paper's section IV-B);
        non-finite sightings are rejected and counted."""
        ids, positions = self.state.landmark_positions()
        mode = self.policy.mode(scan_ids, t)
        rows = np.flatnonzero(usable)
        if mode == "ids":
            sources = np.array([self.source_of.get(int(i), -1) for i in ids], dtype=int)
            predictor = LandmarkPredictor(self.state, np.arange(len(ids)))
            found = self.policy.by_ids(scan_ids[rows], points[rows], covs[rows], sources, predictor)
        else:
            current = (
                np.flatnonzero(self.manager.recently_seen(ids, t, self.config.association_window_s))
                if len(ids)
                else np.zeros(0, dtype=int)
            )
            predictor = LandmarkPredictor(self.state, current)
            found = self.policy.by_geometry(points[rows], covs[rows], len(current), predictor, mode)
            found = self.policy.distinct_new(points[rows], covs[rows], found)
            if found.search is not None and found.search.truncated:
                self.recorder.event(t, "jcbb_truncated", nodes=found.search.nodes)
            found = found.relabelled(current)  # candidate index -> landmark index
        return found.relabelled(ids).embedded(rows, len(points), Reason.NOT_FINITE)

    def _update(
        self,
        t: float,
        points: np.ndarray,
        covs: np.ndarray,
        directions: np.ndarray | None,
        association: ScanAssociation,
    ) -> np.ndarray:
        """Section IV-B update of every matched landmark (with its direction features);
        returns the map id per sighting (-1 unless matched)."""
        state = self.state
        d = self.dimension
        assignment = np.where(
            np.array([decision == Decision.MATCHED for decision in association.decisions]),
            association.candidates,
            -1,
        )
        measured_features: list[int] = []
        values: list[np.ndarray] = []
        cov_blocks: list[np.ndarray] = []  # the noise each block is used with
        model_blocks: list[np.ndarray] = []  # the stated noise, for the NIS
        groups: list[np.ndarray] = []
        position_of = {
            int(owner): index
            for index, owner in zip(state.position_features(), state.landmark_ids())
        }
        for j in np.flatnonzero(assignment >= 0):
            landmark_id = int(assignment[j])
            start = len(values) * d
            measured_features.append(position_of[landmark_id])
            values.append(points[j])
            cov_blocks.append(association.noise[j])  # inflated where the policy says
            model_blocks.append(covs[j])
            if directions is not None:
                for feature in state.direction_features(landmark_id):
                    unit = match_direction(state.features[feature], directions[j])
                    if unit is not None:
                        measured_features.append(int(feature))
                        values.append(unit)
                        block = direction_covariance(unit, self.config.direction_sigma_rad)
                        cov_blocks.append(block)
                        model_blocks.append(block)
            groups.append(np.arange(start, len(values) * d))
        if not measured_features:
            return assignment
        features = np.array(measured_features)
        indices = state.state_indices(features)
        state.x, outcome = selection_update(
            state.x,
            state.covariance,
            indices,
            np.concatenate(values),
            kalman.block_diagonal(np.stack(cov_blocks)),
            groups,
            kalman.block_diagonal(np.stack(model_blocks)),
        )
        if outcome.innovation is not None:
            found = outcome.innovation
            self.recorder.innovation(t, found.nis, found.dof, found.group_nis, found.group_dof)
        if outcome.correction is None:
            self.recorder.event(t, "update_refused", reason=outcome.refused)
            return assignment
        state.measured[features] = np.stack(values)
        state.visible[features] = True
        return assignment

    # ------------------------------------------------------------------ output
    def landmark_map(self, t: float) -> LandmarkMap:
        """The body-frame map now: ids, positions (L, d), their joint covariance."""
        ids, positions = self.state.landmark_positions()
        joint = self.state.position_covariance(np.arange(len(ids)))
        return LandmarkMap.from_joint(ids, positions, joint, Frame.BODY, float(t))

    def _record_vehicle(self, t: float) -> None:
        state = self.state
        d, nv = self.dimension, state.vehicle_dim
        self.recorder.block(
            BlockName.VELOCITY,
            t,
            state.velocity.copy(),
            state.covariance[:d, :d].copy(),
            Frame.BODY,
        )
        self.recorder.block(
            BlockName.GYRO_BIAS,
            t,
            state.bias.copy(),
            state.covariance[d:nv, d:nv].copy(),
            Frame.BODY,
        )
        # The joint vehicle block (velocity and bias are correlated): for the vehicle NEES.
        self.recorder.extra("vehicle_t", float(t))
        self.recorder.extra("vehicle_state", state.x[:nv].copy())
        self.recorder.extra("vehicle_covariance", state.covariance[:nv, :nv].ravel().copy())

    def _motion_covariance(self) -> np.ndarray:
        """Covariance (k, k) of the motion accumulated since the last scan: the
        odometry's, where odometry drove it, else the filter's own
        (``earth_pose_covariance``)."""
        if self._motion_odometry_covariance is not None:
            return self._motion_odometry_covariance
        vehicle = self.state.vehicle_dim
        return motion_covariance(
            self._motion_velocity_gain,
            self._motion_duration,
            self.state.covariance[:vehicle, :vehicle],
            self.noise.velocity_m_s,
            self.noise.gyro_bias_rad_s,
            self.noise.gyro_noise_density,
        )

    def _record_carried_pose(self, t: float) -> None:
        """The Earth pose composed with the filter's own motion since the last scan (what
        the next scan's step falls back on without common landmarks), with the same
        covariance algebra (``EarthErrorCovariance.compose`` on a copy)."""
        if self.earth is None:
            return
        import copy

        earth = self.earth
        rotation = earth.rotation @ self._motion_rotation
        position = earth.position + earth.rotation @ self._motion_translation
        covariance = None
        if earth.errors is not None:
            errors = copy.deepcopy(earth.errors)
            errors.compose(earth.rotation, self._motion_translation, self._motion_covariance())
            covariance = pose_covariance_to_interface(rotation, errors.pose)
        self.recorder.pose(
            t,
            position,
            float(np.arctan2(rotation[1, 0], rotation[0, 0]))
            if self.dimension == 2
            else quat_wxyz_from_matrix(rotation),
            covariance,
        )

    def _record_pose(self, t: float) -> None:
        """The Earth-frame pose (derived from the map history) with its first-order
        covariance (``earth_pose_covariance``) converted to the interface's right
        perturbation; 3-D without one."""
        if self.earth is None:
            return
        rotation = self.earth.rotation
        covariance = self.earth.covariance
        if covariance is not None:
            covariance = pose_covariance_to_interface(rotation, covariance)
        self.recorder.pose(
            t,
            self.earth.position.copy(),
            float(np.arctan2(rotation[1, 0], rotation[0, 0]))
            if self.dimension == 2
            else quat_wxyz_from_matrix(rotation),
            covariance,
        )

    def earth_map(self) -> LandmarkMap | None:
        """The current map in the Earth frame (derived; covariances rotated, pose uncertainty ignored)."""
        if self.earth is None:
            return None
        current = self.landmark_map(self.t if self.t is not None else 0.0)
        rotation = self.earth.rotation
        covs = None if current.covariances is None else rotation @ current.covariances @ rotation.T
        return LandmarkMap(
            ids=current.ids,
            positions=self.earth.to_earth(current.positions),
            covariances=covs,
            frame=Frame.WORLD,
            t=None,
        )

    def estimate(self) -> Estimate:
        pose_note = (
            f"pose: Earth-frame trajectory DERIVED from consecutive body-frame maps by rigid alignment "
            f"({self.earth.aligned_steps} aligned, {self.earth.fallback_steps} dead-reckoned increments, "
            f"{self.earth.anchored_steps} anchored); "
            + (
                "first-order covariance (earth_pose_covariance)"
                if self.earth.errors is not None
                else "no covariance (3-D: earth_pose_covariance says why)"
            )
            if self.earth is not None
            else "robocentric only: no world pose"
        )
        notes = [
            "velocity and landmarks are body-frame (robocentric filter state)",
            pose_note,
            f"landmarks deleted: {self.manager.deleted}",
        ]
        if self.use_odometry:
            notes.append(
                "odometry used as a body-velocity measurement (an extension beyond the paper; "
                "use_odometry=false: the paper's gyro-only form)"
            )
        if any(self.skipped.values()):
            notes.append(f"skipped inputs: {self.skipped}")
        t = self.t if self.t is not None else 0.0
        return self.recorder.build(landmarks=self.landmark_map(t), notes=tuple(notes))
