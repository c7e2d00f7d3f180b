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
association (ids when the scan has them, else ``filters.association`` JCBB), one stacked
update (40a)-(40c) with the Joseph form, then augmentation of new landmarks with their
cross-covariance (section 4.3). The measurement noise R is estimated on line (section 4.4,
eq. (42)) unless ``adaptive_noise=false``; by default from post-fit residuals, since the
printed prior-residual form collapses when the initial R is wrong (``adaptive_noise``
module; ``adaptive_residual=prior`` keeps it).

Bad input: a non-finite IMU sample or scan, or time going backwards, raises ``InputError``
before any state is touched (the state stays finite and usable). An empty scan is not an
error: it is counted (``landmark_count`` recorded, no update).

NIS is recorded once per scan for the stacked innovation of all updated landmarks
(anchors and map landmarks), dof = 3 x landmarks.
"""

from __future__ import annotations

from typing import ClassVar, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.errors import InputError
from datasets.estimate import Estimate, EstimateRecorder
from datasets.measurements import ImuSample, LandmarkScan, Measurement, Sensor
from datasets.rotations import skew
from datasets.sequence import Sequence
from datasets.state import BlockName, Frame, LandmarkMap
from filters.aghili import quaternion_jpl as quat
from filters.aghili.adaptive_noise import SlidingWindowNoise
from filters.aghili.measurement import predict, sensitivity
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
    POSITION,
    VEHICLE_DIM,
    VELOCITY,
    error_dynamics,
    lambda_matrices,
    vehicle_transition,
)

GRAVITY_M_S2 = 9.81
"""Magnitude of g in eq. (15) (``g = (0, 0, +9.81)`` world z-up, subtracted)."""


class AghiliConfig(BaseModel):
    """Options of the Aghili adaptive EKF SLAM (``--set key=value``)."""

    model_config = ConfigDict(extra="forbid")
    anchors: int = Field(
        3, ge=1, description="r: number of known anchor landmarks fixing the map (section 2.1)"
    )
    anchor_source: Literal["known", "first-observation"] = Field(
        "known",
        description="'known': the dataset's surveyed positions (NEES against truth meaningful); "
        "'first-observation': the paper's choice, from the first noisy observation (NEES not comparable)",
    )
    adaptive_noise: bool = Field(True, description="estimate R on line (section 4.4, eq. (42))")
    adaptive_window: int = Field(
        300, ge=10, description="w: landmark residuals in the eq. (42) sliding window"
    )
    adaptive_min_sigma_m: float = Field(
        0.005, gt=0, description="floor on the adapted landmark std [m] (keeps R PD)"
    )
    adaptive_min_samples: int = Field(
        30,
        ge=3,
        description="landmark residuals in the window before the adapted R replaces the initial one",
    )
    adaptive_residual: Literal["posterior", "prior"] = Field(
        "posterior",
        description="eq. (42) on post-fit residuals, R = mean(e e^T + H P+ H^T) (fails safe when P is off), "
        "or on prior residuals as printed, R = W - H P- H^T",
    )
    landmark_sigma_m: float | None = Field(
        None,
        gt=0,
        description="initial/fixed landmark std [m]; None: the covariances the scans carry",
    )
    process_noise: Literal["closed-form", "van-loan"] = Field(
        "closed-form",
        description="Q' by the verified closed form or by Van Loan's matrix exponential",
    )
    initial_velocity_sigma_m_s: float | None = Field(
        None, ge=0, description="initial velocity std [m/s]; None: the dataset's initial state"
    )
    initial_gyro_bias_sigma_rad_s: float | None = Field(
        None,
        ge=0,
        description="initial gyro bias std [rad/s]; None: the dataset's noise spec, else 0.01",
    )
    initial_accel_bias_sigma_m_s2: float | None = Field(
        None,
        ge=0,
        description="initial accelerometer bias std [m/s^2]; None: the dataset's noise spec, else 0.1",
    )
    association: Literal["auto", "jcbb", "nearest"] = Field(
        "auto",
        description="'auto': ids when scans carry them, else JCBB; 'jcbb'/'nearest' ignore ids",
    )
    gate_probability: float = Field(
        0.999, gt=0, lt=1, description="chi-square gate for association"
    )
    snapshot_interval_s: float = Field(
        1.0, gt=0, description="landmark map snapshot period in the history [s]"
    )
    max_gap_s: float = Field(1.0, gt=0, description="an IMU gap longer than this is an error [s]")


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
        self.recorder = EstimateRecorder(3)
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
                    (0.5 * start.rotation_sigma_rad) ** 2,  # dq_v is a half angle
                    start.position_sigma_m**2,
                    velocity_sigma**2,
                    gyro_bias_sigma**2,
                    accel_bias_sigma**2,
                ],
                3,
            )
        )
        self.landmark_ids: list[int] = []  # map id of each estimated landmark, in state order
        self.slot_of: dict[int, int] = {}  # map id -> state slot
        self.rho = np.zeros((0, 3))
        self._next_new_id = 0

        # anchors (section 2.1)
        self.anchor_ids: list[int] = []
        self.anchor_positions = np.zeros((0, 3))
        self._anchors_pending = False
        known = sequence.known_landmarks
        if config.anchor_source == "known":
            if known is None or len(known) < config.anchors:
                have = 0 if known is None else len(known)
                raise InputError(
                    f"{sequence.name}: anchors={config.anchors} known landmarks requested, the dataset offers {have} "
                    "(use anchor_source=first-observation)"
                )
            self.anchor_ids = [int(i) for i in known.ids[: config.anchors]]
            self.anchor_positions = np.array(known.positions[: config.anchors], dtype=float)
        else:
            self._anchors_pending = True
            if known is not None and len(known) >= config.anchors:
                self.anchor_ids = [int(i) for i in known.ids[: config.anchors]]
            self.notes.append(
                "anchors taken from their first noisy observation (paper section 2.1): the map frame differs "
                "from the world frame by the anchors' observation error, so NEES against truth is not comparable"
            )
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
            None if config.landmark_sigma_m is None else np.eye(3) * config.landmark_sigma_m**2
        )

        self._last_imu: ImuSample | None = None
        self._staged: tuple | None = None
        self._last_snapshot_t = -np.inf
        self.counts = {"imu": 0, "scans": 0, "empty_scans": 0, "quaternion_resets": 0}
        self._stage_record()

    # ------------------------------------------------------------------ propagation
    def _check_time(self, t: float, what: str) -> float:
        if not np.isfinite(t):
            raise InputError(f"{self.name}: non-finite {what} time stamp after t={self.t:.6f} s")
        dt = t - self.t
        if dt < 0.0:
            raise InputError(
                f"{self.name}: time goes backwards at {what} t={t:.6f} s (previous {self.t:.6f} s)"
            )
        return dt

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
        v = VEHICLE_DIM
        P = self.P
        P[:v, :v] = phi @ P[:v, :v] @ phi.T + q_vehicle
        if P.shape[0] > v:
            P[v:, :v] = P[v:, :v] @ phi.T
            P[:v, v:] = P[v:, :v].T
        P[:v, :v] = 0.5 * (P[:v, :v] + P[:v, :v].T)
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
        dt = self._check_time(float(sample.t), "IMU")
        if dt > self.config.max_gap_s and self._last_imu is not None:
            raise InputError(
                f"{self.name}: IMU gap of {dt:.3f} s at t={sample.t:.6f} s (max_gap_s={self.config.max_gap_s})"
            )
        if self._last_imu is None:
            gyro_mean, accel_mean = gyro, accel
        else:
            # eq. (34): interval average of the signal, trapezoid of the bounding samples
            gyro_mean = 0.5 * (gyro + np.asarray(self._last_imu.gyro, dtype=float))
            accel_mean = 0.5 * (accel + np.asarray(self._last_imu.accel, dtype=float))
        self._propagate(dt, gyro_mean, accel_mean)
        self._last_imu = sample
        self.counts["imu"] += 1
        self._stage_record()

    # ------------------------------------------------------------------ update
    def _measurement_noise(self, scan: LandmarkScan, count: int) -> np.ndarray:
        """R blocks (count, 3, 3) [m^2]: adapted (eq. (42)), configured, or the scan's own."""
        if self.noise_window is not None and self.noise_window.ready:
            return np.repeat(self.noise_window.estimate()[None], count, axis=0)
        if self.fixed_r is not None:
            return np.repeat(self.fixed_r[None], count, axis=0)
        return np.asarray(scan.covariances, dtype=float)

    def _map_targets(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All map landmarks (anchors first): ids (m,), world positions (m, 3), slots (m,)."""
        ids = np.array(self.anchor_ids[: len(self.anchor_positions)] + self.landmark_ids, dtype=int)
        positions = np.vstack([self.anchor_positions, self.rho])
        slots = np.r_[
            np.full(len(self.anchor_positions), -1), np.arange(len(self.landmark_ids))
        ].astype(int)
        return ids, positions, slots

    def _associate(self, scan: LandmarkScan, R: np.ndarray) -> np.ndarray:
        """Map id for each measured landmark (k,): existing id, -2 new landmark, -1 rejected."""
        k = scan.count
        map_ids, positions, slots = self._map_targets()
        known_ids = set(map_ids.tolist())
        if scan.ids is not None and self.config.association == "auto":
            result = np.empty(k, dtype=int)
            seen: set[int] = set()
            for j, raw in enumerate(np.asarray(scan.ids, dtype=int)):
                landmark_id = int(raw)
                if landmark_id in seen:
                    result[j] = -1  # the same id twice in one scan: keep the first only
                elif landmark_id in known_ids:
                    result[j] = landmark_id
                elif landmark_id in self.anchor_ids:
                    result[
                        j
                    ] = -1  # an anchor not yet placed (first-observation mode handled earlier)
                else:
                    result[j] = -2
                seen.add(landmark_id)
            return result
        from filters.association import associate_jcbb, associate_nearest_neighbour

        if len(map_ids) == 0:
            return np.full(k, -2, dtype=int)
        attitude = quat.rotation_matrix(self.q)
        predicted = predict(attitude, self.r, positions)
        H = sensitivity(attitude, predicted, slots, self.P.shape[0])
        predicted_cov = H @ self.P @ H.T
        associate = (
            associate_nearest_neighbour if self.config.association == "nearest" else associate_jcbb
        )
        outcome = associate(
            np.asarray(scan.points, float),
            R,
            predicted,
            predicted_cov,
            gate_probability=self.config.gate_probability,
        )
        result = np.where(outcome.assignments >= 0, map_ids[np.maximum(outcome.assignments, 0)], -2)
        result[
            outcome.ambiguous
        ] = -1  # compatible with something but not chosen: neither update nor add
        return result

    def _place_anchors(self, scan: LandmarkScan) -> None:
        """Section 2.1 alternative: anchors from their first (noisy) observation."""
        points = np.asarray(scan.points, float)
        attitude = quat.rotation_matrix(self.q)
        if self.anchor_ids and scan.ids is not None:
            index = {int(i): j for j, i in enumerate(np.asarray(scan.ids, int))}
            if not all(i in index for i in self.anchor_ids):
                return  # wait for a scan that sees all of them
            rows = [index[i] for i in self.anchor_ids]
        else:
            if len(points) < self.config.anchors:
                return
            rows = list(range(self.config.anchors))
            if scan.ids is not None:
                self.anchor_ids = [int(scan.ids[j]) for j in rows]
            else:
                self.anchor_ids = [self._new_id() for _ in rows]
        self.anchor_positions = points[rows] @ attitude.T + self.r  # rho_j = A p_j(0) + r
        self._anchors_pending = False

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
        dt = self._check_time(float(scan.t), "landmark scan")
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
            self._stage_record()
            return
        if self._anchors_pending:
            self._place_anchors(scan)
        R = self._measurement_noise(scan, k)
        targets = self._associate(scan, R)
        self._update(scan, points, R, targets)
        new_rows = np.flatnonzero(targets == -2)
        if self._anchors_pending:
            new_rows = np.zeros(0, dtype=int)  # the map is not anchored yet: nothing to attach to
        R_after = self._measurement_noise(scan, k)
        created = {}
        for j in new_rows:
            landmark_id = (
                int(scan.ids[j])
                if (scan.ids is not None and self.config.association == "auto")
                else self._new_id()
            )
            self._augment(points[j], R_after[j], landmark_id)
            created[j] = landmark_id
        for j in range(k):
            if j in created:
                self.recorder.association(scan.t, j, created[j], True)
            else:
                self.recorder.association(
                    scan.t, j, int(targets[j]) if targets[j] >= 0 else -1, False
                )
        self.recorder.landmark_count(scan.t, len(self.landmark_ids))
        if self.noise_window is not None:
            sigma = (
                np.sqrt(np.diag(self.noise_window.estimate()))
                if self.noise_window.ready
                else np.sqrt(np.diag(R[0]))
            )
            self.recorder.extra("adaptive_R_sigma_m", np.r_[scan.t, sigma])
        self._stage_record()
        if scan.t - self._last_snapshot_t >= self.config.snapshot_interval_s:
            self.recorder.landmarks(self._landmark_map(scan.t))
            self._last_snapshot_t = scan.t
            if len(self.anchor_positions):
                self.recorder.extra(
                    "gauge_yaw_variance_rad2", np.array([scan.t, self.gauge_yaw_variance()])
                )

    def _update(
        self, scan: LandmarkScan, points: np.ndarray, R: np.ndarray, targets: np.ndarray
    ) -> None:
        """Aghili eqs. (40a)-(40c) with the Joseph form, one stacked update per scan."""
        rows = np.flatnonzero(targets >= 0)
        if rows.size == 0:
            return
        map_ids, positions, slots = self._map_targets()
        where = {int(i): n for n, i in enumerate(map_ids)}
        chosen = np.array([where[int(targets[j])] for j in rows])
        attitude = quat.rotation_matrix(self.q)
        predicted = predict(attitude, self.r, positions[chosen])
        N = self.P.shape[0]
        H = sensitivity(attitude, predicted, slots[chosen], N)
        residual = (points[rows] - predicted).ravel()  # z - h(x^-)
        HP = H @ self.P
        predicted_cov = HP @ H.T
        if self.noise_window is not None and self.noise_window.residual == "prior":
            # eq. (42) as printed: prior residuals with their H P^- H^T blocks, used at once
            self.noise_window.add(residual.reshape(-1, 3), _diagonal_blocks(predicted_cov))
            if self.noise_window.ready:
                R = np.repeat(self.noise_window.estimate()[None], len(points), axis=0)
        R_stacked = np.zeros((3 * len(rows), 3 * len(rows)))
        for n, j in enumerate(rows):
            R_stacked[3 * n : 3 * n + 3, 3 * n : 3 * n + 3] = R[j]
        S = predicted_cov + R_stacked
        S = 0.5 * (S + S.T)
        try:
            chol = np.linalg.cholesky(S)
        except np.linalg.LinAlgError:
            self.recorder.event(
                scan.t, "update_skipped", reason="innovation covariance not positive definite"
            )
            return
        # K = P H^T S^-1 (eq. (40a)) via the Cholesky factor
        K = np.linalg.solve(chol.T, np.linalg.solve(chol, HP)).T
        whitened = np.linalg.solve(chol, residual)
        self.recorder.nis(scan.t, float(whitened @ whitened), residual.size)
        dx = K @ residual  # eq. (40b), with dq_v^- = 0 (the nominal is the prior)
        # Joseph form (I - KH) P (I - KH)^T + K R K^T, associated as ((I-KH)P)(I-KH)^T: O(N^2 m)
        left = self.P - K @ HP
        P_new = left - (left @ H.T) @ K.T + K @ R_stacked @ K.T
        self.P = 0.5 * (P_new + P_new.T)
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
            posterior = (residual - H @ dx).reshape(-1, 3)
            self.noise_window.add(posterior, _projected_blocks(H, self.P))

    def _augment(self, point: np.ndarray, R: np.ndarray, landmark_id: int) -> None:
        """Aghili section 4.3: add ``rho = Abar z + r`` with its cross-covariance.

        ``drho = -2 Abar [z x] dq_v + dr - Abar v``, so ``Upsilon = [-2 Abar [z x], 1, 0] P``
        and the new diagonal block is ``J P J^T + Abar R Abar^T``.
        """
        attitude = quat.rotation_matrix(self.q)
        N = self.P.shape[0]
        J = np.zeros((3, N))
        J[:, ATTITUDE] = -2.0 * attitude @ skew(point)
        J[:, POSITION] = np.eye(3)
        upsilon = J @ self.P  # (3, N)
        corner = upsilon @ J.T + attitude @ R @ attitude.T
        P_new = np.empty((N + 3, N + 3))
        P_new[:N, :N] = self.P
        P_new[N:, :N] = upsilon
        P_new[:N, N:] = upsilon.T
        P_new[N:, N:] = 0.5 * (corner + corner.T)
        self.P = P_new
        self.rho = np.vstack([self.rho, attitude @ point + self.r])
        self.slot_of[landmark_id] = len(self.landmark_ids)
        self.landmark_ids.append(landmark_id)

    def gauge_yaw_variance(self) -> float:
        """Variance [rad^2] along the rotation about gravity through the first anchor: the
        direction one anchor leaves unobservable (section 3), ``(u^T P^-1 u)^-1``."""
        direction = gauge_rotation_direction(
            quat.rotation_matrix(self.q), self.r, self.v, self.rho, self.anchor_positions[0]
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

    def _stage_record(self) -> None:
        """Stage the current posterior; an entry at the same time replaces the staged one."""
        if self._staged is not None and self._staged[0] != self.t:
            self._flush()
        attitude = quat.rotation_matrix(self.q)
        z_axis = np.array([0.0, 0.0, 1.0])
        yaw_variance = 4.0 * z_axis @ attitude @ self.P[ATTITUDE, ATTITUDE] @ attitude.T @ z_axis
        self._staged = (
            self.t,
            self.r.copy(),
            quat.to_interface_wxyz(self.q),
            self.interface_pose_covariance(),
            self.v.copy(),
            self.P[VELOCITY, VELOCITY].copy(),
            -self.b_g,  # interface: measured = true + bias
            self.P[GYRO_BIAS, GYRO_BIAS].copy(),
            -self.b_a,
            self.P[ACCEL_BIAS, ACCEL_BIAS].copy(),
            yaw_variance,
        )

    def _flush(self) -> None:
        if self._staged is None:
            return
        t, r, wxyz, pose_cov, v, v_cov, bg, bg_cov, ba, ba_cov, yaw_variance = self._staged
        self.recorder.pose(t, r, wxyz, pose_cov)
        self.recorder.block(BlockName.VELOCITY, t, v, v_cov, Frame.WORLD)
        self.recorder.block(BlockName.GYRO_BIAS, t, bg, bg_cov, Frame.BODY)
        self.recorder.block(BlockName.ACCEL_BIAS, t, ba, ba_cov, Frame.BODY)
        self.recorder.extra("yaw_variance_rad2", np.array([t, yaw_variance]))
        self._staged = None

    def _landmark_map(self, t: float | None) -> LandmarkMap:
        """Estimated landmarks (anchors excluded: they are fixed, not estimated), world frame."""
        n = len(self.landmark_ids)
        covariances = np.empty((n, 3, 3))
        for i in range(n):
            start = VEHICLE_DIM + 3 * i
            covariances[i] = self.P[start : start + 3, start : start + 3]
        return LandmarkMap(
            ids=np.array(self.landmark_ids, dtype=int),
            positions=self.rho.copy(),
            covariances=covariances,
            frame=Frame.WORLD,
            t=t,
        )

    # ------------------------------------------------------------------ protocol
    def process(self, measurement: Measurement) -> None:
        """Consume one measurement (IMU sample or landmark scan; others ignored)."""
        if isinstance(measurement, ImuSample):
            self._imu(measurement)
        elif isinstance(measurement, LandmarkScan):
            self._scan(measurement)

    def estimate(self) -> Estimate:
        """Finish: flush the last posterior, final map snapshot and map with covariances."""
        self._flush()
        final_map = self._landmark_map(self.t)
        if self._last_snapshot_t != self.t:
            self.recorder.landmarks(final_map)
            self._last_snapshot_t = self.t
        notes = list(self.notes)
        notes.append(
            f"anchors: {len(self.anchor_positions)} ({self.config.anchor_source}), not part of the landmark map; "
            "NIS is per scan (stacked innovation, dof = 3 x updated landmarks)"
        )
        if self.counts["empty_scans"]:
            notes.append(f"{self.counts['empty_scans']} empty landmark scans (no update)")
        if self.counts["quaternion_resets"]:
            notes.append(
                f"{self.counts['quaternion_resets']} attitude corrections with |dq_v| >= 1 (rescaled)"
            )
        return self.recorder.build(landmarks=final_map, notes=tuple(notes))


def _diagonal_blocks(matrix: np.ndarray) -> np.ndarray:
    """The 3 x 3 diagonal blocks (m, 3, 3) of a (3m, 3m) matrix."""
    count = matrix.shape[0] // 3
    return matrix.reshape(count, 3, count, 3)[np.arange(count), :, np.arange(count), :]


def _projected_blocks(H: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Diagonal 3 x 3 blocks of ``H P H^T`` (m, 3, 3) without forming the (3m, 3m) product.

    Each landmark row block of eq. (10) touches only the attitude, position and its own
    landmark columns, so a block costs O(1) instead of O(N^2).
    """
    count = H.shape[0] // 3
    blocks = np.empty((count, 3, 3))
    for i in range(count):
        rows = H[3 * i : 3 * i + 3]
        columns = np.flatnonzero(np.any(rows != 0.0, axis=0))
        local = rows[:, columns]
        blocks[i] = local @ P[np.ix_(columns, columns)] @ local.T
    return blocks
