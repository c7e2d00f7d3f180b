"""Aghili's adaptive error-state EKF SLAM (F. Aghili, "Lidar SLAM for Autonomous Driving
Vehicles", sections 2, 4): strap-down IMU propagation, 3-D landmark position updates,
r known anchor landmarks fixing the map, IMU biases and the landmark noise estimated.

Inside the filter the paper's algebra is kept (``quaternion_jpl``): quaternion
``[q_v, q_o]``, error ``dq_v`` (half-angle, body frame), world-frame position/velocity
errors, biases "true = measured + bias" (eqs. (13), (15)), gravity ``g = (0, 0, +9.81)``
subtracted as in eq. (15). State (15 + 3n; eq. (6) omits the velocity, F/G/P do not)::

    [dq_v, dr, dr_dot, db_g, db_a, drho_1 .. drho_n]

Everything is converted at the boundary (``_export``; tested in
``tests/test_aghili_filter.py``):
- quaternion -> Hamilton (w, x, y, z) body-to-world (the same four numbers reordered);
- pose covariance -> [rotation, translation], both body-frame right perturbations:
  rotation vector = 2 dq_v (so 4x the dq_v covariance), translation = Abar^T dr;
- biases -> "measured = true + bias" (sign flipped, covariance unchanged);
- velocity and landmarks stay world-frame.

Cycle per IMU sample (section 4.2): nominal quaternion by the exact exponential (39), position
and velocity by integrating (15) exactly for the interval-average bias-corrected IMU values
(34) (trapezoid of the two samples bounding the interval), covariance by (41b) with the
corrected closed-form Phi' (35) and Q' (36), so a step costs O(n). Per landmark scan:
association by the shared policy (``filters.association``: ids when the scan has them,
else JCBB), one stacked block-sparse update (40a)-(40c) in the shared Kalman core
(``filters.kalman``), then augmentation of new landmarks with their cross-covariance
(section 4.3). The measurement noise R is estimated on line (section 4.4,
eq. (42)) unless ``adaptive_noise=false``; by default from post-fit residuals, since the
printed prior-residual form collapses when the initial R is wrong (``adaptive_noise``
module; ``adaptive_residual=prior`` keeps it).

Bad input: a non-finite IMU sample or scan, or time going backwards, raises ``InputError``
before any state is touched (the state stays finite and usable). An empty scan is not an
error: it is counted (``landmark_count`` recorded, no update).

NIS: the stacked innovation of every scan update (anchors and map landmarks, dof = 3 x
landmarks) and the NIS of each updated landmark (3 dof).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from pydantic import BaseModel

from datasets.errors import InputError
from datasets.estimate import Estimate, EstimateRecorder
from datasets.measurements import ImuSample, LandmarkScan, Measurement, Sensor
from datasets.model_options import interval_value
from datasets.rotations import skew
from datasets.sequence import Sequence
from datasets.state import BlockName, Frame, LandmarkMap
from datasets.stream_clock import StreamClock
from filters import kalman
from filters.aghili import quaternion_jpl as quat
from filters.aghili.adaptive_noise import SlidingWindowNoise
from filters.aghili.anchors import Anchors
from filters.aghili.config import AghiliConfig
from filters.aghili.measurement import map_predictor, predict, sparse_sensitivity
from filters.aghili.observability import gauge_rotation_direction, variance_along
from filters.aghili.process_noise import (
    noise_covariance,
    process_noise_van_loan,
    vehicle_process_noise,
)
from filters.aghili.transition import (
    ACCEL_BIAS,
    ATTITUDE,
    GYRO_BIAS,
    LANDMARK_BLOCKS,
    POSITION,
    VEHICLE_DIM,
    VELOCITY,
    error_dynamics,
    lambda_matrices,
    state_registry,
    vehicle_transition,
)
from filters.association import AssociationPolicy, Decision, ScanAssociation
from filters.landmark_predictor import projected_covariance

GRAVITY_M_S2 = 9.81
"""Magnitude of g in eq. (15) (``g = (0, 0, +9.81)`` world z-up, subtracted)."""


class AghiliFilter:
    """Aghili adaptive IMU error-state EKF SLAM (registered as ``aghili``)."""

    Config: ClassVar[type[BaseModel]] = AghiliConfig
    sensor_options: ClassVar[tuple[frozenset[Sensor], ...]] = (
        frozenset({Sensor.IMU, Sensor.LANDMARKS}),
    )
    dimensions: ClassVar[frozenset[int]] = frozenset({3})

    def __init__(self, config: AghiliConfig, sequence: Sequence) -> None:
        if sequence.dimension != 3:
            raise InputError(f"{sequence.name}: the Aghili filter is 3-D only")
        if sequence.initial_state is None:
            raise InputError(
                f"{sequence.name}: the Aghili filter needs an initial state, the dataset gives none"
            )
        self.config = config
        self.name = sequence.name
        self.recorder = EstimateRecorder(3, config.snapshot_interval_s)
        self.policy = AssociationPolicy(config, 3, sequence.noise.sighting_correlation)
        self.notes: list[str] = []
        noise = sequence.noise
        missing = [
            name
            for name in (
                "gyro_noise_density",
                "accel_noise_density",
                "gyro_bias_walk",
                "accel_bias_walk",
            )
            if getattr(noise, name) is None
        ]
        if missing:
            raise InputError(
                f"{sequence.name}: the Aghili filter needs IMU noise densities; missing {', '.join(missing)}"
            )
        self.densities = (
            noise.gyro_noise_density,
            noise.gyro_bias_walk,
            noise.accel_noise_density,
            noise.accel_bias_walk,
        )
        self.sigma = noise_covariance(*self.densities)

        start = sequence.initial_state
        self.t = float(start.t)
        self.q = quat.from_interface_wxyz(np.asarray(start.rotation, dtype=float))
        self.r = np.array(start.position, dtype=float)
        self.v = np.zeros(3) if start.velocity is None else np.array(start.velocity, dtype=float)
        self.b_g = np.zeros(3)  # paper sign: true = measured + b_g
        self.b_a = np.zeros(3)
        position_sigma = config.initial_position_sigma_m
        if position_sigma is None:
            position_sigma = start.position_sigma_m
        rotation_sigma = config.initial_rotation_sigma_rad
        if rotation_sigma is None:
            rotation_sigma = start.rotation_sigma_rad
        velocity_sigma = config.initial_velocity_sigma_m_s
        if velocity_sigma is None:
            velocity_sigma = start.velocity_sigma_m_s
        gyro_bias_sigma = config.initial_gyro_bias_sigma_rad_s
        if gyro_bias_sigma is None:
            gyro_bias_sigma = (
                noise.gyro_bias_sigma_rad_s if noise.gyro_bias_sigma_rad_s is not None else 0.01
            )
        accel_bias_sigma = config.initial_accel_bias_sigma_m_s2
        if accel_bias_sigma is None:
            accel_bias_sigma = (
                noise.accel_bias_sigma_m_s2 if noise.accel_bias_sigma_m_s2 is not None else 0.1
            )
        # The paper's P^-(0) gives the vehicle zero covariance; no real IMU knows its biases
        # exactly, so the initial velocity and bias covariances are configurable and nonzero.
        self.P = np.diag(
            np.repeat(
                [
                    (0.5 * rotation_sigma) ** 2,  # dq_v is a half angle
                    position_sigma**2,
                    velocity_sigma**2,
                    gyro_bias_sigma**2,
                    accel_bias_sigma**2,
                ],
                3,
            )
        )
        # where the vehicle blocks and each estimated landmark (map id -> its 3 entries) sit
        self.registry = state_registry()
        self.rho = np.zeros((0, 3))  # estimated landmarks' world positions, in state order
        self._next_new_id = 0

        # anchors (section 2.1)
        anchors = 3 if config.anchors is None else config.anchors
        self.anchors = Anchors(anchors, config.anchor_source, sequence)
        if self.anchors.decision is not None:
            self.notes.append(self.anchors.decision)
        if self.anchors.note is not None:
            self.notes.append(self.anchors.note)
        known = sequence.known_landmarks
        if known is not None and len(known):
            self._next_new_id = int(np.max(known.ids)) + 1

        # measurement noise
        self.noise_window = (
            SlidingWindowNoise(
                config.adaptive_window,
                config.adaptive_min_sigma_m,
                config.adaptive_min_samples,
                config.adaptive_residual,
            )
            if config.adaptive_noise
            else None
        )
        self.fixed_r = (
            None
            if config.landmark_measurement_sigma_m is None
            else np.eye(3) * config.landmark_measurement_sigma_m**2
        )

        self._last_imu: ImuSample | None = None
        self.clock = StreamClock(self.name, self.t)
        self.counts = {"imu": 0, "scans": 0, "empty_scans": 0, "quaternion_resets": 0}
        self._record()

    @property
    def landmark_ids(self) -> np.ndarray:
        """Map ids of the estimated landmarks in state order, (n,) (the registry's)."""
        return self.registry.ids

    # ------------------------------------------------------------------ propagation
    def _propagate(self, dt: float, gyro: np.ndarray, accel: np.ndarray) -> None:
        """Aghili eqs. (34), (39), (41a), (41b): propagate nominal state and covariance by dt [s].

        ``gyro``/``accel`` are the interval averages of the measured signals (34).
        """
        if dt <= 0.0:
            return
        omega_bar = gyro + self.b_g  # eq. (34a)
        a_bar = accel + self.b_a  # eq. (34b)
        attitude = quat.rotation_matrix(self.q)
        # eq. (15) integrated exactly for constant omega_bar, a_bar: A(s) = Abar exp([omega x] s)
        _, gamma_1, gamma_2 = lambda_matrices(-omega_bar, dt, 3)  # int exp(W s) ds, and twice
        gravity = np.array([0.0, 0.0, GRAVITY_M_S2])
        self.r = self.r + self.v * dt + attitude @ gamma_2 @ a_bar - 0.5 * gravity * dt**2
        self.v = self.v + attitude @ gamma_1 @ a_bar - gravity * dt
        self.q = quat.propagate(self.q, omega_bar, dt)  # eq. (39), exact exponential
        lambdas = lambda_matrices(omega_bar, dt, 5)
        phi = vehicle_transition(omega_bar, a_bar, attitude, dt, lambdas)
        if self.config.process_noise == "van-loan":
            F, G = error_dynamics(omega_bar, a_bar, attitude)
            q_vehicle = process_noise_van_loan(F, G, self.sigma, dt)
        else:
            q_vehicle = vehicle_process_noise(
                omega_bar, a_bar, attitude, dt, *self.densities, lambdas=lambdas
            )
        # eq. (41b): the landmark-landmark block is untouched: O(n) per step
        kalman.propagate_vehicle(self.P, VEHICLE_DIM, phi, q_vehicle)
        self.t += dt

    def _imu(self, sample: ImuSample) -> None:
        gyro = np.asarray(sample.gyro, dtype=float)
        accel = np.asarray(sample.accel, dtype=float)
        if (
            gyro.shape != (3,)
            or accel.shape != (3,)
            or not (np.all(np.isfinite(gyro)) and np.all(np.isfinite(accel)))
        ):
            raise InputError(
                f"{self.name}: non-finite or malformed IMU sample at t={sample.t:.6f} s"
            )
        dt = self.clock.advance(sample.t, "IMU")
        if dt > self.config.max_gap_s and self._last_imu is not None:
            raise InputError(
                f"{self.name}: IMU gap of {dt:.3f} s at t={sample.t:.6f} s (max_gap_s={self.config.max_gap_s})"
            )
        # eq. (34): interval average of the signal, trapezoid of the bounding samples
        last = self._last_imu
        gyro_mean = interval_value(
            "average", None if last is None else np.asarray(last.gyro, dtype=float), gyro
        )
        accel_mean = interval_value(
            "average", None if last is None else np.asarray(last.accel, dtype=float), accel
        )
        self._propagate(dt, gyro_mean, accel_mean)
        self._last_imu = sample
        self.counts["imu"] += 1
        self._record()

    # ------------------------------------------------------------------ update
    def _measurement_noise(self, scan: LandmarkScan, count: int) -> np.ndarray:
        """R blocks (count, 3, 3) [m^2]: adapted (eq. (42)), configured, or the scan's own."""
        if self.noise_window is not None and self.noise_window.ready:
            return np.repeat(self.noise_window.estimate()[None], count, axis=0)
        if self.fixed_r is not None:
            return np.repeat(self.fixed_r[None], count, axis=0)
        return np.asarray(scan.covariances, dtype=float)

    def _map_targets(self) -> tuple[np.ndarray, np.ndarray]:
        """All map landmarks (anchors first): ids (m,), world positions (m, 3). The anchors
        are not in the registry (known, not estimated)."""
        anchors = self.anchors
        ids = np.array(list(anchors.ids[: anchors.placed]) + list(self.landmark_ids), dtype=int)
        positions = np.vstack([anchors.positions, self.rho])
        return ids, positions

    def _associate(self, scan: LandmarkScan, R: np.ndarray) -> ScanAssociation:
        """One decision per sighting against the anchors and the map (the shared policy)."""
        points = np.asarray(scan.points, float)
        map_ids, positions = self._map_targets()
        predictor = map_predictor(
            quat.rotation_matrix(self.q), self.r, self.P, positions, map_ids, self.registry
        )
        mode = self.policy.mode(scan.ids, scan.t)
        if mode != "ids":
            return self.policy.by_geometry(points, R, len(map_ids), predictor, mode)
        association = self.policy.by_ids(scan.ids, points, R, map_ids, predictor)
        waiting = [
            j for j in association.rows(Decision.NEW) if self.anchors.waiting(int(scan.ids[j]))
        ]
        return association.overrule(waiting, Decision.REJECTED, "anchor not placed yet")

    def _new_id(self) -> int:
        landmark_id = self._next_new_id
        self._next_new_id += 1
        return landmark_id

    def _scan(self, scan: LandmarkScan) -> None:
        points = np.asarray(scan.points, dtype=float)
        k = int(points.shape[0]) if points.ndim == 2 else -1
        if points.ndim != 2 or (k > 0 and points.shape[1] != 3):
            raise InputError(
                f"{self.name}: landmark scan at t={scan.t:.6f} s has points of shape {points.shape}, need (k, 3)"
            )
        if not np.all(np.isfinite(points)):
            raise InputError(
                f"{self.name}: non-finite landmark position in the scan at t={scan.t:.6f} s"
            )
        covariances = np.asarray(scan.covariances, dtype=float)
        if k > 0 and (covariances.shape != (k, 3, 3) or not np.all(np.isfinite(covariances))):
            raise InputError(
                f"{self.name}: landmark scan at t={scan.t:.6f} s has covariances of shape {covariances.shape}, need ({k}, 3, 3) finite"
            )
        dt = self.clock.advance(scan.t, "landmark scan")
        if self._last_imu is not None:
            # zero-order hold of the last IMU sample up to the scan time
            self._propagate(
                dt, np.asarray(self._last_imu.gyro, float), np.asarray(self._last_imu.accel, float)
            )
        else:
            self.t += dt
        self.counts["scans"] += 1
        if k == 0:
            self.counts["empty_scans"] += 1
            self.recorder.landmark_count(scan.t, len(self.landmark_ids))
            self._record()
            return
        if self.anchors.pending:
            self.anchors.place(scan, quat.rotation_matrix(self.q), self.r, self._new_id)
        R = self._measurement_noise(scan, k)
        association = self._associate(scan, R)
        if self.anchors.pending:
            # the map is not anchored yet: nothing to attach a new landmark to
            association = association.overrule(
                association.rows(Decision.NEW), Decision.REJECTED, "map not anchored yet"
            )
        map_ids = self._map_targets()[0]
        matched = association.rows(Decision.MATCHED)
        landmarks = np.full(k, -1, dtype=int)
        landmarks[matched] = map_ids[association.candidates[matched]]
        association = self.policy.decorrelated(association, scan.t, points, R, landmarks)
        self._update(scan, points, R, association)
        R_after = self._measurement_noise(scan, k)
        for j, decision in enumerate(association.decisions):
            landmark_id = -1
            if decision == Decision.NEW:
                with_ids = scan.ids is not None and association.mode == "ids"
                landmark_id = int(scan.ids[j]) if with_ids else self._new_id()
                self._augment(points[j], R_after[j], landmark_id)
                self.policy.sighted(landmark_id, scan.t)
            elif decision == Decision.MATCHED:
                landmark_id = int(map_ids[association.candidates[j]])
            self.recorder.association(
                scan.t,
                j,
                landmark_id,
                decision,
                association.reasons[j],
                association.inflation[j],
                association.alternatives_of(j),
            )
        self.recorder.landmark_count(scan.t, len(self.landmark_ids))
        if self.noise_window is not None:
            sigma = (
                np.sqrt(np.diag(self.noise_window.estimate()))
                if self.noise_window.ready
                else np.sqrt(np.diag(R[0]))
            )
            self.recorder.extra("adaptive_R_sigma_m", np.r_[scan.t, sigma])
        self._record()
        if self.recorder.snapshot_due(scan.t):
            self.recorder.landmarks(self._landmark_map(scan.t))
            if self.anchors.placed:
                self.recorder.extra(
                    "gauge_yaw_variance_rad2", np.array([scan.t, self.gauge_yaw_variance()])
                )

    def _update(
        self, scan: LandmarkScan, points: np.ndarray, R: np.ndarray, association: ScanAssociation
    ) -> None:
        """Aghili eqs. (40a)-(40c): one stacked block-sparse update per scan (the shared
        Kalman core) of every matched sighting."""
        rows = association.rows(Decision.MATCHED)
        if rows.size == 0:
            return
        map_ids, positions = self._map_targets()
        chosen = association.candidates[rows]
        attitude = quat.rotation_matrix(self.q)
        predicted = predict(attitude, self.r, positions[chosen])
        jacobian = sparse_sensitivity(attitude, predicted, self.registry, map_ids[chosen])
        residual = (points[rows] - predicted).ravel()  # z - h(x^-)
        noise = R[rows]
        used = association.noise[rows]  # inflated where the policy says so
        if self.noise_window is not None and self.noise_window.residual == "prior":
            # eq. (42) as printed: prior residuals with their H P^- H^T blocks, used at once
            self.noise_window.add(
                residual.reshape(-1, 3),
                kalman.diagonal_blocks(projected_covariance(jacobian, self.P), 3),
            )
            if self.noise_window.ready:
                noise = used = np.repeat(self.noise_window.estimate()[None], len(rows), axis=0)
        groups = [np.arange(3 * n, 3 * n + 3) for n in range(len(rows))]
        outcome = kalman.update(self.P, residual, jacobian, used, groups, model_noise=noise)
        if outcome.innovation is not None:
            found = outcome.innovation
            self.recorder.innovation(scan.t, found.nis, found.dof, found.group_nis, found.group_dof)
        if outcome.correction is None:
            self.recorder.event(scan.t, "update_refused", reason=outcome.refused)
            return
        dx = outcome.correction  # eq. (40b), with dq_v^- = 0 (the nominal is the prior)
        if float(dx[ATTITUDE] @ dx[ATTITUDE]) >= 1.0:
            self.counts["quaternion_resets"] += 1
            self.recorder.event(
                scan.t, "large_attitude_correction", norm=float(np.linalg.norm(dx[ATTITUDE]))
            )
        self.q = quat.apply_error(dx[ATTITUDE], self.q)  # eq. (40c)
        self.r = self.r + dx[POSITION]
        self.v = self.v + dx[VELOCITY]
        self.b_g = self.b_g + dx[GYRO_BIAS]
        self.b_a = self.b_a + dx[ACCEL_BIAS]
        if len(self.landmark_ids):
            self.rho = self.rho + dx[VEHICLE_DIM:].reshape(-1, 3)
        if self.noise_window is not None and self.noise_window.residual == "posterior":
            # eq. (42) on post-fit residuals e = z - h(x^+) ~ rho - H dx, with H P^+ H^T
            # (module docstring of adaptive_noise); the next scan uses the new estimate
            posterior = (residual - jacobian.times(dx)).reshape(-1, 3)
            self.noise_window.add(
                posterior, kalman.diagonal_blocks(projected_covariance(jacobian, self.P), 3)
            )

    def _augment(self, point: np.ndarray, R: np.ndarray, landmark_id: int) -> None:
        """Aghili section 4.3: add ``rho = Abar z + r`` with its cross-covariance.

        ``drho = -2 Abar [z x] dq_v + dr - Abar v``, so ``Upsilon = [-2 Abar [z x], 1, 0] P``
        and the new diagonal block is ``J P J^T + Abar R Abar^T``.
        """
        attitude = quat.rotation_matrix(self.q)
        jacobian = kalman.SparseJacobian(
            self.registry.columns(("attitude", "position")),
            np.hstack([-2.0 * attitude @ skew(point), np.eye(3)]),
        )
        self.P = kalman.augment(self.P, jacobian, attitude @ R @ attitude.T)
        self.registry.augment(landmark_id, LANDMARK_BLOCKS)
        self.rho = np.vstack([self.rho, attitude @ point + self.r])

    def gauge_yaw_variance(self) -> float:
        """Variance [rad^2] along the rotation about gravity through the first anchor: the
        direction one anchor leaves unobservable (section 3), ``(u^T P^-1 u)^-1``."""
        direction = gauge_rotation_direction(
            quat.rotation_matrix(self.q), self.r, self.v, self.rho, self.anchors.positions[0]
        )
        return variance_along(self.P, direction)

    # ------------------------------------------------------------------ export
    def interface_pose_covariance(self) -> np.ndarray:
        """Pose covariance (6, 6) [rotation, translation], body-frame right perturbations.

        rotation vector = 2 dq_v; body translation = Abar^T dr (world error rotated by R^T).
        """
        attitude = quat.rotation_matrix(self.q)
        J = np.zeros((6, 6))
        J[0:3, 0:3] = 2.0 * np.eye(3)
        J[3:6, 3:6] = attitude.T
        return J @ self.P[0:6, 0:6] @ J.T

    def _record(self) -> None:
        """Record the current posterior at ``self.t`` (the recorder keeps one per time)."""
        t = self.t
        self.recorder.pose(
            t, self.r, quat.to_interface_wxyz(self.q), self.interface_pose_covariance()
        )
        self.recorder.block(BlockName.VELOCITY, t, self.v, self.P[VELOCITY, VELOCITY], Frame.WORLD)
        # interface: measured = true + bias, so the paper's biases flip sign
        self.recorder.block(
            BlockName.GYRO_BIAS, t, -self.b_g, self.P[GYRO_BIAS, GYRO_BIAS], Frame.BODY
        )
        self.recorder.block(
            BlockName.ACCEL_BIAS, t, -self.b_a, self.P[ACCEL_BIAS, ACCEL_BIAS], Frame.BODY
        )

    def _landmark_map(self, t: float | None) -> LandmarkMap:
        """Estimated landmarks (anchors excluded: they are fixed, not estimated), world frame,
        with their joint covariance (the landmark block of P)."""
        return LandmarkMap.from_joint(
            self.landmark_ids, self.rho, self.P[VEHICLE_DIM:, VEHICLE_DIM:], Frame.WORLD, t
        )

    # ------------------------------------------------------------------ protocol
    def process(self, measurement: Measurement) -> None:
        """Consume one measurement (IMU sample or landmark scan; others ignored)."""
        if isinstance(measurement, ImuSample):
            self._imu(measurement)
        elif isinstance(measurement, LandmarkScan):
            self._scan(measurement)

    def estimate(self) -> Estimate:
        """Finish: the final map snapshot and the map with covariances."""
        final_map = self._landmark_map(self.t)
        self.recorder.final_snapshot(final_map)
        notes = list(self.notes)
        notes.append(
            f"anchors: {self.anchors.placed} ({self.config.anchor_source}), not part of the landmark map; "
            "scan NIS: stacked innovation of anchors and landmarks, dof = 3 x updated landmarks"
        )
        if self.counts["empty_scans"]:
            notes.append(f"{self.counts['empty_scans']} empty landmark scans (no update)")
        if self.counts["quaternion_resets"]:
            notes.append(
                f"{self.counts['quaternion_resets']} attitude corrections with |dq_v| >= 1 (rescaled)"
            )
        return self.recorder.build(landmarks=final_map, notes=tuple(notes))
