"""``EkfSlam``: the world-centric EKF-SLAM baseline (2-D and 3-D), registered as ``ekf-slam``.

One joint Gaussian over the vehicle (``layout.VehicleLayout``) and every mapped landmark in
the world frame (Bailey, Nieto, Guivant, Stevens, Nebot 2006, section II; Dissanayake et
al. 2001):

- *Prediction* by the motion input the data offers (``config.motion_input``): planar
  odometry (relative poses, or (v, omega) turned into ``(v dt, 0, omega dt)``) or, on
  gyro-only / IMU data, the gyro-driven constant-velocity model (``motion.predict_gyro_cv``;
  the IMU's accelerometer is not used). Only the vehicle rows and columns change:
  ``P_vv <- F P_vv F^T + Q``, ``P_vl <- F P_vl``. A scan is applied to the vehicle as
  predicted at the last motion sample (sources emit the motion sample of a scan's time
  first); the next motion sample then covers the whole interval since the previous one.
- *Association* by the scan's ids when it has them (a sighting whose NIS exceeds the
  ``id_gate_probability`` quantile is rejected), else JCBB from ``filters.association``
  on the landmarks individually compatible with some sighting (their joint predicted
  covariance ``H P H^T`` is passed, so the joint test sees the correlations).
  Unassigned sightings with no compatible landmark start new landmarks; ambiguous ones
  (compatible but left out of the hypothesis) are neither used nor mapped.
- *Update*: all associated sightings of a scan stacked in one update with the Joseph form
  ``P <- (I - K H) P (I - K H)^T + K R K^T``, evaluated as the algebraically identical
  ``P - K H P - (K H P)^T + K S K^T`` in O(n^2 p) (n state size, p stacked rows), which
  keeps P symmetric positive semi-definite for any gain.
- *Landmark initialisation* on first sight with the full cross-covariances:
  ``l = p + R z``, ``P_ll = G_v P_vv G_v^T + R Sigma_z R^T``, ``P_lx = G_v P_vx``.

Diagnostics: one NIS per associated sighting (its individual innovation against the prior,
``d`` dof), an association record for every sighting (map id, -1 when rejected or
ambiguous), the landmark count after every scan, ``motion_gap`` events, map snapshots.
Exported blocks: pose (interface convention: right perturbation, ``boundary``), world
velocity and gyro bias (gyro model), world-frame landmarks.

Inconsistency (the point of this baseline): the Jacobians are evaluated at the current
estimate, so the filter gains spurious information about the unobservable global heading
and its covariance becomes too small over time (Bailey et al. 2006, section IV).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from pydantic import BaseModel

from datasets.errors import InputError
from datasets.estimate import Estimate, EstimateRecorder
from datasets.measurements import GyroSample, ImuSample, LandmarkScan, Measurement, Odometry, Sensor
from datasets.rotations import matrix_from_quat_wxyz, quat_wxyz_from_matrix, so3_exp, wrap_angle
from datasets.sequence import Sequence
from datasets.state import BlockName, Frame, LandmarkMap
from filters.association import associate_jcbb, chi2_gate
from filters.ekf_slam.boundary import pose_covariance_to_interface
from filters.ekf_slam.config import EkfSlamConfig
from filters.ekf_slam.layout import VehicleLayout
from filters.ekf_slam.motion import GyroNoise, VehicleMean, predict_gyro_cv, predict_odometry_2d
from filters.ekf_slam.observation import initialise_landmark, predict_observations


class EkfSlam:
    """World-centric EKF-SLAM (see the module docstring)."""

    Config: ClassVar[type[BaseModel]] = EkfSlamConfig
    sensor_options: ClassVar[tuple[frozenset[Sensor], ...]] = (
        frozenset({Sensor.ODOMETRY, Sensor.LANDMARKS}),
        frozenset({Sensor.GYRO, Sensor.LANDMARKS}),
        frozenset({Sensor.IMU, Sensor.LANDMARKS}),
    )
    dimensions: ClassVar[frozenset[int]] = frozenset({2, 3})

    def __init__(self, config: EkfSlamConfig, sequence: Sequence) -> None:
        if sequence.initial_state is None:
            raise InputError(
                f"{sequence.name}: ekf-slam needs an initial state (the frame-defining prior), the dataset gives none"
            )
        self.config = config
        self.dimension = d = sequence.dimension
        self.input = self._choose_input(config, sequence)
        gyro_model = self.input is not Sensor.ODOMETRY
        self.layout = VehicleLayout(
            d, has_velocity=gyro_model, has_gyro_bias=gyro_model and config.estimate_gyro_bias
        )
        noise = sequence.noise
        self.gyro_noise = GyroNoise(
            gyro_density=_first(config.gyro_noise_density, noise.gyro_noise_density, 1e-3),
            bias_walk=_first(config.gyro_bias_walk, noise.gyro_bias_walk, 1e-5),
            acceleration_density=config.acceleration_density,
        )
        start = sequence.initial_state
        rotation = float(start.rotation) if d == 2 else matrix_from_quat_wxyz(start.rotation)
        velocity = np.zeros(d) if start.velocity is None else np.asarray(start.velocity, float)
        rotation_size = self.layout.rotation_size
        self.vehicle = VehicleMean(
            position=np.asarray(start.position, float).copy(),
            rotation=rotation,
            velocity=velocity.copy() if gyro_model else None,
            gyro_bias=np.zeros(rotation_size) if self.layout.has_gyro_bias else None,
        )
        variances = [start.position_sigma_m**2] * d + [start.rotation_sigma_rad**2] * rotation_size
        if self.layout.has_velocity:
            variances += [start.velocity_sigma_m_s**2] * d
        if self.layout.has_gyro_bias:
            variances += [
                _first(config.gyro_bias_sigma_rad_s, noise.gyro_bias_sigma_rad_s, 0.01) ** 2
            ] * rotation_size
        self.covariance = np.diag(variances)
        self.landmarks = np.zeros((0, d))
        self.map_ids: list[int] = []
        self.sightings: list[int] = []
        self.created_t: list[float] = []
        self.source_index: dict[int, int] = {}  # source id -> map index (id association)
        self.next_id = 0
        self.t = float(start.t)
        # time of the last motion input: a scan between motion samples moves ``t`` but not this
        self.motion_t = float(start.t)
        self.recorder = EstimateRecorder(d)
        self.last_snapshot_t = -np.inf
        self.pending_record = True
        self.gaps = 0
        self.association_modes: set[str] = set()
        self.last_rate: np.ndarray | None = None

    # ------------------------------------------------------------------ set-up
    @staticmethod
    def _choose_input(config: EkfSlamConfig, sequence: Sequence) -> Sensor:
        available = sequence.sensors
        if config.motion_input == "odometry":
            wanted = [Sensor.ODOMETRY]
        elif config.motion_input == "gyro":
            wanted = [Sensor.GYRO, Sensor.IMU]
        else:
            wanted = [Sensor.ODOMETRY, Sensor.GYRO, Sensor.IMU]
        for sensor in wanted:
            if sensor not in available:
                continue
            if sensor is Sensor.ODOMETRY and sequence.dimension != 2:
                continue  # 3-D odometry input is not modelled; fall through to the gyro
            return sensor
        raise InputError(
            f"{sequence.name}: ekf-slam motion_input={config.motion_input} needs one of "
            f"{', '.join(s.value for s in wanted)} ({sequence.dimension}-D), the dataset has {', '.join(sorted(s.value for s in available))}"
        )

    @property
    def vehicle_size(self) -> int:
        return self.layout.size

    # ------------------------------------------------------------------ inputs
    def process(self, measurement: Measurement) -> None:
        if not np.isfinite(measurement.t):
            raise InputError(f"non-finite time stamp after t={self.t:.6f} s")
        if measurement.t < self.t - 1e-9:
            raise InputError(
                f"time goes backwards at t={measurement.t:.6f} s (previous {self.t:.6f} s)"
            )
        if measurement.t > self.t and self.pending_record:
            self._record()
        if isinstance(measurement, LandmarkScan):
            self._scan(measurement)
        elif measurement.sensor is self.input:
            self._motion(measurement)

    def _motion(self, measurement: Measurement) -> None:
        dt = float(measurement.t) - self.motion_t
        if dt > self.config.max_gap_s:
            self.gaps += 1
            self.recorder.event(measurement.t, "motion_gap", gap_s=dt, input=self.input.value)
        if isinstance(measurement, Odometry):
            increment, increment_cov = _odometry_increment(measurement, dt)
            new, transition, process = predict_odometry_2d(
                self.vehicle,
                self.layout,
                increment,
                increment_cov * self.config.odometry_noise_scale,
            )
        else:
            if isinstance(measurement, ImuSample):
                rate = np.asarray(measurement.gyro, float).ravel()  # the accelerometer is not used
            elif isinstance(measurement, GyroSample):
                rate = np.asarray(measurement.rate, float).ravel()
            else:
                raise InputError(
                    f"ekf-slam cannot use a {type(measurement).__name__} as motion input (t={measurement.t:.6f} s)"
                )
            if rate.shape != (self.layout.rotation_size,) or not np.all(np.isfinite(rate)):
                raise InputError(
                    f"gyro rate at t={measurement.t:.6f} s must be {self.layout.rotation_size} finite values, got {rate}"
                )
            interval_rate = rate
            if self.config.gyro_interval_rate == "average" and self.last_rate is not None:
                interval_rate = 0.5 * (self.last_rate + rate)  # trapezoid of instantaneous samples
            self.last_rate = rate
            new, transition, process = predict_gyro_cv(
                self.vehicle,
                self.layout,
                interval_rate,
                max(dt, 0.0),
                self.gyro_noise,
                self.config.rotate_velocity_with_gyro,
            )
        if dt > self.config.max_gap_s:
            # The input says nothing reliable about an unobserved stretch: widen pose uncertainty.
            process = process.copy()
            process[self.layout.position, self.layout.position] += (
                np.eye(self.dimension) * (self.config.gap_speed_m_s * dt) ** 2
            )
            process[self.layout.rotation, self.layout.rotation] += (
                np.eye(self.layout.rotation_size) * (self.config.gap_rate_rad_s * dt) ** 2
            )
        self._propagate(new, transition, process)
        self.motion_t = float(measurement.t)
        self.t = max(self.t, float(measurement.t))
        self.pending_record = True

    def _propagate(self, new: VehicleMean, transition: np.ndarray, process: np.ndarray) -> None:
        """``P_vv <- F P_vv F^T + Q``, ``P_vl <- F P_vl`` (landmarks are static)."""
        v = self.vehicle_size
        P = self.covariance
        P[:v, :v] = transition @ P[:v, :v] @ transition.T + process
        if P.shape[0] > v:
            P[:v, v:] = transition @ P[:v, v:]
            P[v:, :v] = P[:v, v:].T
        P[:v, :v] = 0.5 * (P[:v, :v] + P[:v, :v].T)
        self.vehicle = new

    # ------------------------------------------------------------------ scans
    def _scan(self, scan: LandmarkScan) -> None:
        self.t = max(self.t, float(scan.t))
        if scan.points.ndim != 2 or scan.points.shape[1] != self.dimension:
            raise InputError(
                f"landmark scan at t={scan.t:.6f} s has points of shape {scan.points.shape}, expected (k, {self.dimension})"
            )
        if not (np.all(np.isfinite(scan.points)) and np.all(np.isfinite(scan.covariances))):
            raise InputError(f"landmark scan at t={scan.t:.6f} s contains NaN or inf")
        points = np.asarray(scan.points, float)
        noise = np.asarray(scan.covariances, float) * self.config.measurement_noise_scale
        mode = self._association_mode(scan)
        self.association_modes.add(mode)
        k = len(points)
        assignments = np.full(k, -1, dtype=int)  # map index per sighting
        new_sightings: list[int] = []
        if k and mode == "ids":
            assignments, new_sightings = self._associate_by_ids(scan, points, noise)
        elif k:
            assignments, new_sightings = self._associate_jcbb(scan.t, points, noise)
        paired = np.flatnonzero(assignments >= 0)
        if len(paired):
            self._update(scan.t, points[paired], noise[paired], assignments[paired])
        created: dict[int, int] = {}
        for j in new_sightings:
            created[j] = self._add_landmark(scan.t, points[j], noise[j])
            if scan.ids is not None and mode == "ids":
                self.source_index[int(scan.ids[j])] = created[j]
        for j in range(k):
            if j in created:
                self.recorder.association(scan.t, j, self.map_ids[created[j]], True)
            elif assignments[j] >= 0:
                self.sightings[assignments[j]] += 1
                self.recorder.association(scan.t, j, self.map_ids[assignments[j]], False)
            else:
                self.recorder.association(scan.t, j, -1, False)
        self._prune(scan.t)
        self.recorder.landmark_count(scan.t, len(self.map_ids))
        if scan.t - self.last_snapshot_t >= self.config.landmark_snapshot_every_s:
            self.recorder.landmarks(self._map_snapshot(scan.t))
            self.last_snapshot_t = scan.t
        self.pending_record = True

    def _association_mode(self, scan: LandmarkScan) -> str:
        if self.config.association == "ids":
            if scan.ids is None:
                raise InputError(
                    f"association=ids but the landmark scan at t={scan.t:.6f} s has no ids (use association=jcbb)"
                )
            return "ids"
        if self.config.association == "jcbb":
            return "jcbb"
        return "ids" if scan.ids is not None else "jcbb"

    def _predicted_blocks(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted observations (m, d) and the stacked Jacobian H (m*d, n) of map landmarks."""
        d, v, n = self.dimension, self.vehicle_size, self.covariance.shape[0]
        predicted, vehicle_jac, landmark_jac = predict_observations(
            self.vehicle, self.layout, self.landmarks[indices]
        )
        H = np.zeros((len(indices) * d, n))
        for row, index in enumerate(indices):
            H[row * d : row * d + d, :v] = vehicle_jac[row]
            H[row * d : row * d + d, self.layout.landmark(int(index))] = landmark_jac
        return predicted, H

    def _individual_distances(
        self, points: np.ndarray, noise: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-landmark predictions, their marginal covariances (m, d, d), and D^2 (k, m)."""
        m, d, v = len(self.map_ids), self.dimension, self.vehicle_size
        predicted, vehicle_jac, landmark_jac = predict_observations(
            self.vehicle, self.layout, self.landmarks
        )
        P = self.covariance
        starts = v + np.arange(m) * d
        cross = np.stack([P[:v, s : s + d] for s in starts]) if m else np.zeros((0, v, d))
        own = np.stack([P[s : s + d, s : s + d] for s in starts]) if m else np.zeros((0, d, d))
        hv_pvv = vehicle_jac @ P[:v, :v]
        blocks = hv_pvv @ np.swapaxes(vehicle_jac, 1, 2)
        mixed = vehicle_jac @ cross @ landmark_jac.T
        blocks = blocks + mixed + np.swapaxes(mixed, 1, 2) + landmark_jac @ own @ landmark_jac.T
        innovation = points[:, None, :] - predicted[None, :, :]
        total = noise[:, None, :, :] + blocks[None, :, :, :]
        distances = np.einsum(
            "kmi,kmi->km", innovation, np.linalg.solve(total, innovation[..., None])[..., 0]
        )
        return predicted, blocks, distances

    def _associate_by_ids(
        self, scan: LandmarkScan, points: np.ndarray, noise: np.ndarray
    ) -> tuple[np.ndarray, list[int]]:
        ids = np.asarray(scan.ids, dtype=int)
        assignments = np.full(len(points), -1, dtype=int)
        new: list[int] = []
        seen: set[int] = set()
        known = [j for j, i in enumerate(ids) if int(i) in self.source_index]
        for j, source_id in enumerate(ids):
            if int(source_id) in seen:
                continue  # the same id twice in one scan: use the first sighting only
            seen.add(int(source_id))
            if int(source_id) in self.source_index:
                assignments[j] = self.source_index[int(source_id)]
            else:
                new.append(j)
        if known and self.config.id_gate_probability is not None:
            _, _, distances = self._individual_distances(points[known], noise[known])
            gate = chi2_gate(self.dimension, self.config.id_gate_probability)
            for row, j in enumerate(known):
                if assignments[j] >= 0 and distances[row, assignments[j]] >= gate:
                    assignments[j] = -1
        return assignments, new

    def _associate_jcbb(
        self, t: float, points: np.ndarray, noise: np.ndarray
    ) -> tuple[np.ndarray, list[int]]:
        k, d = points.shape
        assignments = np.full(k, -1, dtype=int)
        if not self.map_ids:
            return assignments, list(range(k))
        _, _, distances = self._individual_distances(points, noise)
        compatible = distances < chi2_gate(d, self.config.gate_probability)
        subset = np.flatnonzero(compatible.any(axis=0))
        if len(subset) == 0:
            return assignments, list(range(k))
        predicted, H = self._predicted_blocks(subset)
        joint = H @ self.covariance @ H.T
        result = associate_jcbb(
            points,
            noise,
            predicted,
            0.5 * (joint + joint.T),
            gate_probability=self.config.gate_probability,
            max_nodes=self.config.max_nodes,
        )
        self.recorder.extra("jcbb_nodes", [t, result.nodes, float(result.truncated)])
        paired = result.assignments >= 0
        assignments[paired] = subset[result.assignments[paired]]
        # A sighting just outside the association gate is more likely a poorly predicted old
        # landmark than a new one: only sightings far from every landmark start one.
        far = distances.min(axis=1) >= chi2_gate(
            d, max(self.config.new_landmark_probability, self.config.gate_probability)
        )
        new = [
            j
            for j in range(k)
            if result.assignments[j] < 0 and result.candidate_counts[j] == 0 and far[j]
        ]
        return assignments, new

    def _update(self, t: float, points: np.ndarray, noise: np.ndarray, indices: np.ndarray) -> None:
        """Stacked EKF update with the Joseph form (see the module docstring)."""
        d = self.dimension
        predicted, H = self._predicted_blocks(indices)
        P = self.covariance
        R = np.zeros((len(indices) * d, len(indices) * d))
        for row in range(len(indices)):
            R[row * d : row * d + d, row * d : row * d + d] = noise[row]
        innovation = (points - predicted).ravel()
        HP = H @ P
        S = HP @ H.T + R
        S = 0.5 * (S + S.T)
        for row in range(len(indices)):
            block = slice(row * d, row * d + d)
            nu = innovation[block]
            self.recorder.nis(t, float(nu @ np.linalg.solve(S[block, block], nu)), d)
        gain = np.linalg.solve(S, HP).T  # K = P H^T S^-1 (S symmetric)
        self.covariance = joseph_update(P, HP, S, gain)
        self._inject(gain @ innovation)

    def _inject(self, correction: np.ndarray) -> None:
        """Add the error-state correction to the mean (multiplicatively on the 3-D rotation)."""
        layout = self.layout
        vehicle = self.vehicle
        dr = correction[layout.rotation]
        if self.dimension == 2:
            rotation: float | np.ndarray = float(wrap_angle(float(vehicle.rotation) + dr[0]))
        else:
            rotation = so3_exp(dr) @ np.asarray(vehicle.rotation)
        self.vehicle = VehicleMean(
            position=vehicle.position + correction[layout.position],
            rotation=rotation,
            velocity=None
            if layout.velocity is None
            else vehicle.velocity + correction[layout.velocity],
            gyro_bias=None
            if layout.gyro_bias is None
            else vehicle.gyro_bias + correction[layout.gyro_bias],
        )
        if len(self.map_ids):
            self.landmarks = self.landmarks + correction[self.vehicle_size :].reshape(
                -1, self.dimension
            )

    def _add_landmark(self, t: float, point: np.ndarray, noise: np.ndarray) -> int:
        """Augment the state with a new landmark and its cross-covariances; returns its map index."""
        v, n, d = self.vehicle_size, self.covariance.shape[0], self.dimension
        position, vehicle_jac, point_jac = initialise_landmark(self.vehicle, self.layout, point)
        P = self.covariance
        cross = vehicle_jac @ P[:v, :]  # (d, n): cov(l, x)
        own = vehicle_jac @ P[:v, :v] @ vehicle_jac.T + point_jac @ noise @ point_jac.T
        grown = np.zeros((n + d, n + d))
        grown[:n, :n] = P
        grown[n:, :n] = cross
        grown[:n, n:] = cross.T
        grown[n:, n:] = 0.5 * (own + own.T)
        self.covariance = grown
        self.landmarks = np.vstack([self.landmarks, position])
        self.map_ids.append(self.next_id)
        self.next_id += 1
        self.sightings.append(1)
        self.created_t.append(float(t))
        return len(self.map_ids) - 1

    def _prune(self, t: float) -> None:
        """Delete landmarks seen once and older than ``prune_single_sightings_after_s`` (marginalise)."""
        horizon = self.config.prune_single_sightings_after_s
        if horizon is None:
            return
        drop = [
            i
            for i in range(len(self.map_ids))
            if self.sightings[i] == 1 and t - self.created_t[i] > horizon
        ]
        if not drop:
            return
        keep = [i for i in range(len(self.map_ids)) if i not in set(drop)]
        v, d = self.vehicle_size, self.dimension
        rows = np.concatenate(
            [np.arange(v)] + [np.arange(v + i * d, v + i * d + d) for i in keep]
        ).astype(int)
        self.covariance = self.covariance[np.ix_(rows, rows)]
        self.landmarks = self.landmarks[keep]
        removed = [self.map_ids[i] for i in drop]
        remap = {old: new for new, old in enumerate(keep)}
        self.map_ids = [self.map_ids[i] for i in keep]
        self.sightings = [self.sightings[i] for i in keep]
        self.created_t = [self.created_t[i] for i in keep]
        self.source_index = {
            key: remap[index] for key, index in self.source_index.items() if index in remap
        }
        self.recorder.event(t, "landmarks_pruned", map_ids=removed, reason="seen once")

    # ------------------------------------------------------------------ output
    def _map_snapshot(self, t: float | None) -> LandmarkMap:
        v, d, m = self.vehicle_size, self.dimension, len(self.map_ids)
        covariances = (
            np.stack(
                [
                    self.covariance[v + i * d : v + i * d + d, v + i * d : v + i * d + d]
                    for i in range(m)
                ]
            )
            if m
            else np.zeros((0, d, d))
        )
        return LandmarkMap(
            ids=np.array(self.map_ids, dtype=int),
            positions=self.landmarks.copy(),
            covariances=covariances.copy(),
            frame=Frame.WORLD,
            t=t,
        )

    def _record(self) -> None:
        layout, P = self.layout, self.covariance
        rotation_matrix = self.vehicle.rotation_matrix()
        pose_size = layout.rotation.stop  # position then rotation lead the vehicle block
        pose_cov = pose_covariance_to_interface(rotation_matrix, P[:pose_size, :pose_size])
        rotation = (
            float(self.vehicle.rotation)
            if self.dimension == 2
            else quat_wxyz_from_matrix(rotation_matrix)
        )
        self.recorder.pose(self.t, self.vehicle.position, rotation, pose_cov)
        if layout.velocity is not None:
            self.recorder.block(
                BlockName.VELOCITY,
                self.t,
                self.vehicle.velocity,
                P[layout.velocity, layout.velocity],
                Frame.WORLD,
            )
        if layout.gyro_bias is not None:
            self.recorder.block(
                BlockName.GYRO_BIAS,
                self.t,
                self.vehicle.gyro_bias,
                P[layout.gyro_bias, layout.gyro_bias],
                Frame.BODY,
            )
        self.pending_record = False

    def estimate(self) -> Estimate:
        if self.pending_record:
            self._record()
        final_map = self._map_snapshot(None)
        single = int(sum(1 for count in self.sightings if count == 1))
        notes = (
            f"ekf-slam: motion input {self.input.value}, association {'+'.join(sorted(self.association_modes)) or 'none'}, "
            f"{len(self.map_ids)} landmarks mapped ({single} seen only once), {self.gaps} motion gaps > {self.config.max_gap_s} s",
        )
        return self.recorder.build(landmarks=final_map, notes=notes)


def joseph_update(P: np.ndarray, HP: np.ndarray, S: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """Joseph-form covariance update ``(I - K H) P (I - K H)^T + K R K^T`` in O(n^2 p).

    Expanded with ``S = H P H^T + R``: ``P - K H P - (K H P)^T + K S K^T``, the same matrix
    for *any* gain ``K`` (not only the optimal one), which is what makes the Joseph form
    robust; symmetrised on return.

    Args:
        P: prior covariance (n, n). HP: ``H @ P`` (p, n). S: innovation covariance (p, p).
        gain: K (n, p).
    """
    KHP = gain @ HP
    updated = P - KHP - KHP.T + gain @ S @ gain.T
    return 0.5 * (updated + updated.T)


def _first(*values: float | None) -> float:
    """The first value that is not None."""
    return float(next(value for value in values if value is not None))


def _odometry_increment(odometry: Odometry, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Planar increment (dx, dy, dtheta) and its covariance from relative-pose or (v, omega) odometry."""
    covariance = np.asarray(odometry.covariance, float)
    if odometry.relative_pose is not None:
        increment = np.asarray(odometry.relative_pose, float)
        if increment.shape != (3,):
            raise InputError(
                f"odometry at t={odometry.t:.6f} s: ekf-slam takes planar increments (3,), got {increment.shape}"
            )
    elif odometry.velocity is not None:
        speed, rate = np.asarray(odometry.velocity, float)
        step = max(dt, 0.0)
        increment = np.array([speed * step, 0.0, rate * step])
        jacobian = np.array([[step, 0.0], [0.0, 0.0], [0.0, step]])
        covariance = jacobian @ covariance @ jacobian.T
    else:
        raise InputError(f"odometry at t={odometry.t:.6f} s has neither relative_pose nor velocity")
    if not np.all(np.isfinite(increment)) or not np.all(np.isfinite(covariance)):
        raise InputError(f"non-finite odometry at t={odometry.t:.6f} s")
    return increment, covariance
