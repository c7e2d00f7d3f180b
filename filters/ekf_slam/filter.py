"""``EkfSlam``: the world-centric EKF-SLAM baseline (2-D and 3-D), registered as ``ekf-slam``.

One joint Gaussian over the vehicle (``layout.VehicleLayout``) and every mapped landmark in
the world frame (Bailey, Nieto, Guivant, Stevens, Nebot 2006, section II; Dissanayake et
al. 2001):

- *Prediction* by the motion input the data offers (``config.use_odometry``): planar
  odometry (relative poses, or (v, omega) turned into ``(v dt, 0, omega dt)``) or, on
  gyro-only / IMU data, the gyro-driven constant-velocity model (``motion.predict_gyro_cv``;
  the IMU's accelerometer is not used). Only the vehicle rows and columns change:
  ``P_vv <- F P_vv F^T + Q``, ``P_vl <- F P_vl``. A scan is applied to the vehicle as
  predicted at the last motion sample (sources emit the motion sample of a scan's time
  first); the next motion sample then covers the whole interval since the previous one.
- *Association* by the shared policy (``filters.association.AssociationPolicy``): the
  scan's ids when it has them (a sighting outside the ``id_gate_probability`` gate is
  rejected and counted), else JCBB on the landmarks individually compatible with some
  sighting, with their joint predicted covariance ``H P H^T``.
- *Update*: all associated sightings of a scan stacked in one block-sparse update of the
  shared Kalman core (``filters.kalman.update``; each row block touches the vehicle and its
  own landmark only).
- *Landmark initialisation* on first sight with the full cross-covariances
  (``filters.kalman.augment``): ``l = p + R z``, ``P_ll = G_v P_vv G_v^T + R Sigma_z R^T``,
  ``P_lx = G_v P_vx``. With ``probation_s`` (the initialisation delay) a landmark stays
  provisional until its second sighting (``min_observations``) and is marginalised out if
  none comes in time: exact, since one sighting of a new landmark carries no information on
  the rest of the state.

Diagnostics: the stacked NIS of every scan update and the NIS of each associated sighting
(``d`` dof), one association decision for every sighting, the landmark count after every
scan, ``motion_gap`` events, map snapshots.
Exported blocks: pose (interface convention: right perturbation, ``boundary``), world
velocity and gyro bias (gyro model), world-frame landmarks.

Inconsistency (the point of this baseline): the Jacobians are evaluated at the current
estimate, so the filter gains spurious information about the unobservable global heading
and its covariance becomes too small over time (Bailey et al. 2006, section IV).
"""

from __future__ import annotations

import copy
from typing import ClassVar

import numpy as np
from pydantic import BaseModel

from datasets.errors import InputError
from datasets.estimate import AssociationDecision, Estimate, EstimateRecorder
from datasets.estimator_options import per_body_axis
from datasets.measurements import GyroSample, ImuSample, LandmarkScan, Measurement, Odometry, Sensor
from datasets.model_options import interval_value
from datasets.odometry_noise import OdometryNoiseModel
from datasets.rotations import (
    PLANAR_GENERATOR,
    matrix_from_quat_wxyz,
    quat_wxyz_from_matrix,
    skew,
    so3_exp,
    wrap_angle,
)
from datasets.sequence import Sequence
from datasets.state import BlockName, Frame, LandmarkMap
from datasets.stream_clock import StreamClock
from filters import kalman
from filters.association import AssociationPolicy, ScanAssociation
from filters.ekf_slam.boundary import pose_covariance_to_interface
from filters.ekf_slam.config import EkfSlamConfig
from filters.ekf_slam.layout import VehicleLayout
from filters.ekf_slam.motion import (
    GyroNoise,
    VehicleMean,
    predict_gyro_cv,
    predict_odometry_2d,
    predict_odometry_3d,
)
from filters.ekf_slam.observation import (
    initialise_landmark,
    observability_constrained,
    predict_observations,
)


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
        self.name = sequence.name
        self.dimension = d = sequence.dimension
        self.input = self._choose_input(config, sequence)
        gyro_model = self.input is not Sensor.ODOMETRY
        self.layout = VehicleLayout(
            d, has_velocity=gyro_model, has_gyro_bias=gyro_model and config.estimate_gyro_bias
        )
        noise = sequence.noise
        self.sequence_noise = noise
        self.gyro_noise = GyroNoise(
            gyro_density=_first(
                config.gyro_noise_density_rad_s_sqrt_hz, noise.gyro_noise_density, 1e-3
            ),
            bias_walk=_first(config.gyro_bias_walk_rad_s_sqrt_s, noise.gyro_bias_walk, 1e-5),
            velocity_walk=per_body_axis(
                config.velocity_walk_m_s_sqrt_s, d, "velocity_walk_m_s_sqrt_s"
            ),
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
        position_sigma = _first(config.initial_position_sigma_m, start.position_sigma_m)
        rotation_sigma = _first(config.initial_rotation_sigma_rad, start.rotation_sigma_rad)
        variances = [position_sigma**2] * d + [rotation_sigma**2] * rotation_size
        if self.layout.has_velocity:
            variances += [
                _first(config.initial_velocity_sigma_m_s, start.velocity_sigma_m_s) ** 2
            ] * d
        if self.layout.has_gyro_bias:
            variances += [
                _first(config.initial_gyro_bias_sigma_rad_s, noise.gyro_bias_sigma_rad_s, 0.01) ** 2
            ] * rotation_size
        self.covariance = np.diag(variances)
        self.landmarks = np.zeros((0, d))
        self.map_ids: list[int] = []
        self.source_ids: list[int] = []  # the scan id each landmark was created from (-1: none)
        self.sightings: list[int] = []
        self.created_t: list[float] = []
        self.next_id = 0
        # the observability constraint (odometry input only; config.jacobians): landmarks'
        # first estimates, and the last prediction
        self.jacobians = config.jacobians if self.input is Sensor.ODOMETRY else "standard"
        self.fej_propagation = self.jacobians != "standard"  # both constrained forms
        self.first_landmarks = np.zeros((0, d))
        self.predicted_position = np.asarray(start.position, float).copy()
        self.t = float(start.t)
        self.clock = StreamClock(f"ekf-slam on {sequence.name}", start.t)
        # time of the last motion input: a scan between motion samples moves ``t`` but not this
        self.motion_t = float(start.t)
        self.recorder = EstimateRecorder(d, config.snapshot_interval_s)
        self.policy = AssociationPolicy(config, d, sequence.noise.sighting_correlation)
        self.gaps = 0
        self.association_modes: set[str] = set()
        self.last_rate: np.ndarray | None = None
        self.record_state()

    def branch(self) -> EkfSlam:
        """An independent copy of the filter's state (mean, covariance, map, association
        record) sharing the configuration and the recorder, for a multi-hypothesis
        estimator that continues it under another association (``multi_hypothesis``)."""
        copied = copy.copy(self)
        copied.covariance = self.covariance.copy()
        copied.map_ids = list(self.map_ids)
        copied.source_ids = list(self.source_ids)
        copied.sightings = list(self.sightings)
        copied.created_t = list(self.created_t)
        copied.predicted_position = self.predicted_position.copy()
        copied.association_modes = set(self.association_modes)
        copied.policy = self.policy.branch()
        copied.clock = copy.copy(self.clock)
        # landmarks, first_landmarks and the vehicle mean are replaced, never changed in place
        return copied

    # ------------------------------------------------------------------ set-up
    @staticmethod
    def _choose_input(config: EkfSlamConfig, sequence: Sequence) -> Sensor:
        available = sequence.sensors
        wanted = [Sensor.GYRO, Sensor.IMU]
        if config.use_odometry:
            wanted.insert(0, Sensor.ODOMETRY)
        for sensor in wanted:
            if sensor not in available:
                continue
            return sensor
        raise InputError(
            f"{sequence.name}: ekf-slam with use_odometry={str(config.use_odometry).lower()} "
            f"needs one of {', '.join(s.value for s in wanted)} ({sequence.dimension}-D), the "
            f"dataset has {', '.join(sorted(s.value for s in available))}"
        )

    @property
    def vehicle_size(self) -> int:
        return self.layout.size

    # ------------------------------------------------------------------ inputs
    def process(self, measurement: Measurement) -> None:
        self.clock.advance(measurement.t, type(measurement).__name__)
        self.t = max(self.t, float(measurement.t))
        if isinstance(measurement, LandmarkScan):
            self._scan(measurement)
        elif measurement.sensor is self.input:
            self._motion(measurement)
        else:
            return
        self.record_state()

    def _motion(self, measurement: Measurement) -> None:
        dt = float(measurement.t) - self.motion_t
        if dt > self.config.max_gap_s:
            motion_gap(self.config, self.name, float(measurement.t), dt)
            self.gaps += 1
            self.recorder.event(measurement.t, "motion_gap", gap_s=dt, input=self.input.value)
        if isinstance(measurement, Odometry) and self.dimension == 2:
            increment, increment_cov = planar_odometry_step(
                self.config, self.sequence_noise.odometry, measurement, dt
            )
            self.advance_planar(increment, increment_cov, float(measurement.t))
            return
        if isinstance(measurement, Odometry):
            increment, increment_cov = _odometry_increment(
                measurement, dt, self.dimension, self.sequence_noise.odometry
            )
            new, transition, process = predict_odometry_3d(
                self.vehicle,
                self.layout,
                increment,
                increment_cov * self.config.odometry_noise_scale,
            )
            if self.fej_propagation:
                # Huang et al. (2008), eq. (25), 3-D: the world-frame rotation error's column
                # at the previous prediction, -[p' - p_{k|k-1}]x
                step = new.position - self.predicted_position
                transition = transition.copy()
                transition[self.layout.position, self.layout.rotation] = -skew(step)
                self.predicted_position = new.position.copy()
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
            interval_rate = interval_value(self.config.interval_rate, self.last_rate, rate)
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
        kalman.propagate_vehicle(self.covariance, self.vehicle_size, transition, process)
        self.vehicle = new
        self.motion_t = float(measurement.t)

    def advance_planar(self, increment: np.ndarray, increment_cov: np.ndarray, t: float) -> None:
        """Compose a planar increment ``(dx, dy, dtheta)`` [m, m, rad] with its covariance
        (3, 3) (scale and gap uncertainty already in it: ``planar_odometry_step``), reached at
        ``t`` [s]. One sample's increment or several composed (``compose_planar``) give the
        same mean and covariance: the transition's rotation column telescopes, with FEJ too
        (``tests/test_ekf_slam_multi_hypothesis.py``)."""
        new, transition, process = predict_odometry_2d(
            self.vehicle, self.layout, increment, increment_cov
        )
        if self.fej_propagation:
            # Huang et al. (2008), eq. (25): the rotation column at the previous prediction
            # p_{k|k-1} instead of the updated p_{k|k}
            step = new.position - self.predicted_position
            transition = transition.copy()
            layout = self.layout
            transition[layout.position, layout.rotation] = (PLANAR_GENERATOR @ step)[:, None]
            self.predicted_position = new.position.copy()
        kalman.propagate_vehicle(self.covariance, self.vehicle_size, transition, process)
        self.vehicle = new
        self.motion_t = float(t)
        self.t = max(self.t, float(t))

    # ------------------------------------------------------------------ scans
    def _scan(self, scan: LandmarkScan) -> None:
        points, noise = self.scan_inputs(scan)
        mode = self.policy.mode(scan.ids, scan.t)
        predictor = MapPredictor(self)
        if mode == "ids":
            association = self.policy.by_ids(
                scan.ids, points, noise, np.array(self.source_ids, dtype=int), predictor
            )
        else:
            association = self.policy.by_geometry(points, noise, len(self.map_ids), predictor, mode)
            if association.search is not None:
                search = association.search
                self.recorder.extra("jcbb_nodes", [scan.t, search.nodes, float(search.truncated)])
                if search.truncated:
                    self.recorder.event(scan.t, "jcbb_truncated", nodes=search.nodes)
        self.apply_association(scan, points, noise, association)

    def scan_inputs(self, scan: LandmarkScan) -> tuple[np.ndarray, np.ndarray]:
        """The scan's points (k, d) [m] and the covariances (k, d, d) the filter uses them
        with (``measurement_noise_scale`` applied), checked."""
        if scan.points.ndim != 2 or scan.points.shape[1] != self.dimension:
            raise InputError(
                f"landmark scan at t={scan.t:.6f} s has points of shape {scan.points.shape}, expected (k, {self.dimension})"
            )
        if not (np.all(np.isfinite(scan.points)) and np.all(np.isfinite(scan.covariances))):
            raise InputError(f"landmark scan at t={scan.t:.6f} s contains NaN or inf")
        points = np.asarray(scan.points, float)
        return points, np.asarray(scan.covariances, float) * self.config.measurement_noise_scale

    def apply_association(
        self,
        scan: LandmarkScan,
        points: np.ndarray,
        noise: np.ndarray,
        association: ScanAssociation,
    ) -> None:
        """Update with the matched sightings, map the new ones, record every decision."""
        self.association_modes.add(association.mode)
        matched = association.rows(AssociationDecision.MATCHED)
        landmarks = np.full(len(points), -1, dtype=int)
        landmarks[matched] = np.asarray(self.map_ids, dtype=int)[association.candidates[matched]]
        association = self.policy.decorrelated(association, scan.t, points, noise, landmarks)
        if len(matched):
            self._update(scan.t, points[matched], noise[matched], association, matched)
        created: dict[int, int] = {}
        for j in association.rows(AssociationDecision.NEW):
            source = int(scan.ids[j]) if association.mode == "ids" else -1
            created[int(j)] = self._add_landmark(scan.t, points[j], noise[j], source)
            self.policy.sighted(self.map_ids[created[int(j)]], scan.t)
        self._record_associations(scan.t, association, created)
        self._prune(scan.t)
        self.recorder.landmark_count(scan.t, len(self.map_ids))
        if self.recorder.snapshot_due(scan.t):
            self.recorder.landmarks(self.map_snapshot(scan.t))

    def _record_associations(
        self, t: float, association: ScanAssociation, created: dict[int, int]
    ) -> None:
        for j, decision in enumerate(association.decisions):
            if decision == AssociationDecision.NEW:
                landmark_id = self.map_ids[created[j]]
            elif decision == AssociationDecision.MATCHED:
                self.sightings[association.candidates[j]] += 1
                landmark_id = self.map_ids[association.candidates[j]]
            else:
                landmark_id = -1
            self.recorder.association(
                t,
                j,
                landmark_id,
                decision,
                association.reasons[j],
                association.inflation[j],
                association.alternatives_of(j),
            )

    def predict(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``predict_observations`` of map landmarks ``indices`` with the configured
        Jacobians: predicted (m, d), vehicle Jacobians (m, d, n_v), landmark Jacobians
        (m, d, d)."""
        indices = np.asarray(indices, dtype=int)
        first = self.first_landmarks[indices]
        predicted, vehicle_jac, landmark_jac = predict_observations(
            self.vehicle,
            self.layout,
            self.landmarks[indices],
            first if self.jacobians == "first-estimate" else None,
        )
        if self.jacobians == "observability-constrained":
            return predicted, *observability_constrained(
                self.layout, vehicle_jac, landmark_jac, self.predicted_position, first
            )
        d = self.dimension
        return predicted, vehicle_jac, np.broadcast_to(landmark_jac, (len(indices), d, d))

    def observation_jacobian(self, indices: np.ndarray) -> tuple[np.ndarray, kalman.SparseJacobian]:
        """Predicted observations (n, d) of map landmarks ``indices`` and the stacked ``H``
        (n d rows) by its non-zero columns: the vehicle block and each landmark's own."""
        d, v = self.dimension, self.vehicle_size
        indices = np.asarray(indices, dtype=int)
        predicted, vehicle_jac, landmark_jac = self.predict(indices)
        n = len(indices)
        columns = np.concatenate([np.arange(v), (v + indices[:, None] * d + np.arange(d)).ravel()])
        values = np.zeros((n * d, v + n * d))
        values[:, :v] = vehicle_jac.reshape(n * d, v)
        for row in range(n):
            values[row * d : row * d + d, v + row * d : v + row * d + d] = landmark_jac[row]
        return predicted, kalman.SparseJacobian(columns, values)

    def _update(
        self,
        t: float,
        points: np.ndarray,
        noise: np.ndarray,
        association: ScanAssociation,
        rows: np.ndarray,
    ) -> None:
        """One stacked update of the sightings ``rows`` (the shared core), with the noise the
        association says (inflated outside the id gate), scored against ``noise``."""
        d = self.dimension
        indices = association.candidates[rows]
        predicted, jacobian = self.observation_jacobian(indices)
        groups = [np.arange(row * d, row * d + d) for row in range(len(indices))]
        outcome = kalman.update(
            self.covariance,
            (points - predicted).ravel(),
            jacobian,
            association.noise[rows],
            groups,
            model_noise=noise,
        )
        if outcome.innovation is not None:
            innovation = outcome.innovation
            self.recorder.innovation(
                t, innovation.nis, innovation.dof, innovation.group_nis, innovation.group_dof
            )
        if outcome.correction is None:
            self.recorder.event(t, "update_refused", reason=outcome.refused)
            return
        self._inject(outcome.correction)

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

    def _add_landmark(self, t: float, point: np.ndarray, noise: np.ndarray, source: int) -> int:
        """Augment the state with a new landmark and its cross-covariances; returns its map
        index. ``source``: the scan id it was created from (-1 without ids)."""
        position, vehicle_jac, point_jac = initialise_landmark(self.vehicle, self.layout, point)
        jacobian = kalman.SparseJacobian(np.arange(self.vehicle_size), vehicle_jac)
        self.covariance = kalman.augment(self.covariance, jacobian, point_jac @ noise @ point_jac.T)
        self.landmarks = np.vstack([self.landmarks, position])
        self.first_landmarks = np.vstack([self.first_landmarks, position])
        self.map_ids.append(self.next_id)
        self.source_ids.append(int(source))
        self.next_id += 1
        self.sightings.append(1)
        self.created_t.append(float(t))
        return len(self.map_ids) - 1

    def _prune(self, t: float) -> None:
        """Marginalise out the provisional landmarks (seen fewer than ``min_observations``
        times) older than ``probation_s``: the landmark initialisation delay (module
        docstring)."""
        horizon = self.config.probation_s
        if horizon is None:
            return
        needed = self.config.min_observations
        drop = {
            i
            for i in range(len(self.map_ids))
            if self.sightings[i] < needed and t - self.created_t[i] > horizon
        }
        if not drop:
            return
        keep = [i for i in range(len(self.map_ids)) if i not in drop]
        v, d = self.vehicle_size, self.dimension
        rows = np.concatenate([np.arange(v)] + [np.arange(v + i * d, v + i * d + d) for i in keep])
        self.covariance = kalman.marginalize(self.covariance, rows)
        self.landmarks = self.landmarks[keep]
        self.first_landmarks = self.first_landmarks[keep]
        removed = [self.map_ids[i] for i in sorted(drop)]
        self.map_ids = [self.map_ids[i] for i in keep]
        self.source_ids = [self.source_ids[i] for i in keep]
        self.sightings = [self.sightings[i] for i in keep]
        self.created_t = [self.created_t[i] for i in keep]
        reason = "seen once" if needed == 2 else f"seen fewer than {needed} times"
        self.recorder.event(t, "landmarks_pruned", map_ids=removed, reason=reason)

    # ------------------------------------------------------------------ output
    def map_snapshot(self, t: float | None) -> LandmarkMap:
        """The world map with its joint covariance (the landmark block of P)."""
        v = self.vehicle_size
        return LandmarkMap.from_joint(
            self.map_ids, self.landmarks, self.covariance[v:, v:], Frame.WORLD, t
        )

    def record_state(self, recorder: EstimateRecorder | None = None) -> None:
        """Record the vehicle's posterior (pose, velocity, gyro bias) into ``recorder``
        (default: the filter's own)."""
        recorder = self.recorder if recorder is None else recorder
        layout, P = self.layout, self.covariance
        rotation_matrix = self.vehicle.rotation_matrix()
        pose_size = layout.rotation.stop  # position then rotation lead the vehicle block
        pose_cov = pose_covariance_to_interface(rotation_matrix, P[:pose_size, :pose_size])
        rotation = (
            float(self.vehicle.rotation)
            if self.dimension == 2
            else quat_wxyz_from_matrix(rotation_matrix)
        )
        recorder.pose(self.t, self.vehicle.position, rotation, pose_cov)
        if layout.velocity is not None:
            recorder.block(
                BlockName.VELOCITY,
                self.t,
                self.vehicle.velocity,
                P[layout.velocity, layout.velocity],
                Frame.WORLD,
            )
        if layout.gyro_bias is not None:
            recorder.block(
                BlockName.GYRO_BIAS,
                self.t,
                self.vehicle.gyro_bias,
                P[layout.gyro_bias, layout.gyro_bias],
                Frame.BODY,
            )

    def estimate(self) -> Estimate:
        final_map = self.map_snapshot(self.t)
        self.recorder.final_snapshot(final_map)
        return self.recorder.build(landmarks=final_map, notes=(self.summary_note("ekf-slam"),))

    def summary_note(self, name: str, extra_gaps: int = 0) -> str:
        """The run's note on its input, association and map, headed ``name``;
        ``extra_gaps``: motion gaps counted outside the filter (``multi_hypothesis``)."""
        single = int(sum(1 for count in self.sightings if count == 1))
        return (
            f"{name}: motion input {self.input.value}, association {'+'.join(sorted(self.association_modes)) or 'none'}, "
            f"{len(self.map_ids)} landmarks mapped ({single} seen only once), {self.gaps + extra_gaps} motion gaps > {self.config.max_gap_s} s"
        )


class MapPredictor:
    """The association ``Predictor`` of the EKF's map (world landmarks seen from the
    vehicle): predictions and ``H P H^T`` with the state's correlations."""

    def __init__(self, ekf: EkfSlam) -> None:
        self.ekf = ekf

    def individual(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ekf = self.ekf
        d, v = ekf.dimension, ekf.vehicle_size
        indices = np.asarray(indices, dtype=int)
        predicted, vehicle_jac, landmark_jac = ekf.predict(indices)
        P = ekf.covariance
        starts = v + indices * d
        rows = starts[:, None] + np.arange(d)
        cross = P[:v][:, rows].transpose(1, 0, 2)  # (n, v, d): cov(vehicle, landmark)
        own = P[rows[:, :, None], rows[:, None, :]]  # (n, d, d)
        blocks = vehicle_jac @ P[:v, :v] @ np.swapaxes(vehicle_jac, 1, 2)
        landmark_t = np.swapaxes(landmark_jac, 1, 2)  # (n, d, d): one per landmark
        mixed = vehicle_jac @ cross @ landmark_t
        blocks = blocks + mixed + np.swapaxes(mixed, 1, 2) + landmark_jac @ own @ landmark_t
        return predicted, blocks

    def joint(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        predicted, jacobian = self.ekf.observation_jacobian(indices)
        values, columns = jacobian.values, jacobian.columns
        joint = values @ self.ekf.covariance[np.ix_(columns, columns)] @ values.T
        return predicted, 0.5 * (joint + joint.T)


def motion_gap(config: EkfSlamConfig, name: str, t: float, dt: float) -> None:
    """A motion-input gap of ``dt`` [s] longer than ``max_gap_s`` ending at ``t``:
    ``InputError`` with ``gap_policy=raise``; with ``inflate`` the caller logs and bridges it."""
    if config.gap_policy == "raise":
        raise InputError(
            f"{name}: motion-input gap of {dt:.3f} s before t={t:.6f} s exceeds "
            f"max_gap_s={config.max_gap_s} (gap_policy=raise)"
        )


def _first(*values: float | None) -> float:
    """The first value that is not None."""
    return float(next(value for value in values if value is not None))


def planar_odometry_step(
    config: EkfSlamConfig, model: OdometryNoiseModel | None, odometry: Odometry, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """One planar odometry sample over ``dt`` [s] since the previous motion input: the
    increment ``(dx, dy, dtheta)`` [m, m, rad] and its covariance (3, 3), the data's (or the
    noise model's) times ``odometry_noise_scale``, plus, after a gap longer than
    ``max_gap_s``, the gap's uncertainty: ``(gap_speed_m_s dt)^2`` on each position axis and
    ``(gap_rate_rad_s dt)^2`` on the heading. Isotropic in position, so added in the
    increment's frame it is the world-frame widening the other inputs get."""
    increment, covariance = _odometry_increment(odometry, dt, 2, model)
    covariance = covariance * config.odometry_noise_scale
    if dt > config.max_gap_s:
        widening = [(config.gap_speed_m_s * dt) ** 2] * 2 + [(config.gap_rate_rad_s * dt) ** 2]
        covariance = covariance + np.diag(widening)
    return increment, covariance


def _odometry_increment(
    odometry: Odometry, dt: float, dimension: int, model: OdometryNoiseModel | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The increment and its covariance from relative-pose or (v, omega) odometry: planar
    (dx, dy, dtheta), or spatial (rotation vector, translation) in 3-D. A planar velocity
    sample's (v, omega) covariance has no lateral axis: when the sequence states its
    odometry noise model, the increment's covariance is the model's (with the lateral
    term), else the sample's covariance mapped through ``dt``."""
    covariance = np.asarray(odometry.covariance, float)
    size = 3 if dimension == 2 else 6
    if odometry.relative_pose is not None:
        increment = np.asarray(odometry.relative_pose, float)
        if increment.shape != (size,) or covariance.shape != (size, size):
            raise InputError(
                f"odometry at t={odometry.t:.6f} s: {dimension}-D ekf-slam takes increments ({size},) with a ({size}, {size}) covariance, got {increment.shape} and {covariance.shape}"
            )
    elif dimension == 3:
        raise InputError(
            f"odometry at t={odometry.t:.6f} s is a velocity; 3-D ekf-slam composes relative poses"
        )
    elif odometry.velocity is not None:
        speed, rate = np.asarray(odometry.velocity, float)
        step = max(dt, 0.0)
        increment = np.array([speed * step, 0.0, rate * step])
        if model is not None and step > 0.0:
            covariance = model.increment_covariance(increment, step)
        else:
            jacobian = np.array([[step, 0.0], [0.0, 0.0], [0.0, step]])
            covariance = jacobian @ covariance @ jacobian.T
    else:
        raise InputError(f"odometry at t={odometry.t:.6f} s has neither relative_pose nor velocity")
    if not np.all(np.isfinite(increment)) or not np.all(np.isfinite(covariance)):
        raise InputError(f"non-finite odometry at t={odometry.t:.6f} s")
    return increment, covariance
