"""``EkfSlam``: the world-centric EKF-SLAM baseline (2-D and 3-D), registered as ``ekf-slam``.

One joint Gaussian over the vehicle (``layout.VehicleLayout``) and every mapped landmark in
the world frame (Bailey, Nieto, Guivant, Stevens, Nebot 2006, section II; Dissanayake et
al. 2001). The class here sequences the steps below, each step's arithmetic in its module:

- *Prediction* by the motion input the data offers (``config.use_odometry``;
  ``motion_input``): planar odometry (relative poses, or (v, omega) turned into
  ``(v dt, 0, omega dt)``) or, on gyro-only / IMU data, the gyro-driven constant-velocity
  model (``motion.predict_gyro_cv``; the IMU's accelerometer is not used). Only the vehicle
  rows and columns change: ``P_vv <- F P_vv F^T + Q``, ``P_vl <- F P_vl``. A scan is
  applied to the vehicle as predicted at the last motion sample (sources emit the motion
  sample of a scan's time first); the next motion sample then covers the whole interval
  since the previous one.
- *Association* by the shared policy (``filters.association.AssociationPolicy``): the
  scan's ids when it has them (a sighting outside the ``id_gate_probability`` gate is
  rejected and counted), else JCBB on the landmarks individually compatible with some
  sighting, with their joint predicted covariance ``H P H^T`` (``scan_update.predictor``).
- *Update*: all associated sightings of a scan stacked in one block-sparse update of the
  shared Kalman core (``filters.kalman.update``; each row block touches the vehicle and its
  own landmark only; ``scan_update``).
- *Landmark initialisation* on first sight with the full cross-covariances
  (``filters.kalman.augment``): ``l = p + R z``, ``P_ll = G_v P_vv G_v^T + R Sigma_z R^T``,
  ``P_lx = G_v P_vx``. With ``probation_s`` (the initialisation delay) a landmark stays
  provisional until its second sighting (``min_observations``) and is marginalised out if
  none comes in time: exact, since one sighting of a new landmark carries no information on
  the rest of the state (``landmarks``).

Diagnostics: the stacked NIS of every scan update and the NIS of each associated sighting
(``d`` dof), one association decision for every sighting, the landmark count after every
scan, ``motion_gap`` events, map snapshots.
Exported blocks: pose (interface convention: right perturbation, ``boundary``), world
velocity and gyro bias (gyro model), world-frame landmarks (``recording``).

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
from datasets.measurements import LandmarkScan, Measurement, Odometry, Sensor
from datasets.model_options import interval_value
from datasets.rotations import matrix_from_quat_wxyz
from datasets.sequence import Sequence
from datasets.state import Frame, LandmarkMap
from datasets.stream_clock import StreamClock
from filters import kalman
from filters.association import AssociationPolicy, ScanAssociation
from filters.ekf_slam import recording, scan_update
from filters.ekf_slam.config import EkfSlamConfig
from filters.ekf_slam.landmarks import add_landmark, prune, record_associations
from filters.ekf_slam.layout import VehicleLayout
from filters.ekf_slam.motion import (
    GyroNoise,
    VehicleMean,
    predict_gyro_cv,
    predict_odometry_2d,
    predict_odometry_3d,
)
from filters.ekf_slam.motion_input import (
    choose_input,
    first_estimate_transition,
    gyro_rate,
    motion_gap,
    odometry_increment,
    planar_odometry_step,
    widen_for_gap,
)
from filters.state_registry import StateRegistry


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
        self.input = choose_input(config, sequence)
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
        # where the vehicle blocks and each landmark (map id -> its d entries) sit in the state
        self.registry = StateRegistry(self.layout.blocks())
        self.landmarks = np.zeros((0, d))  # world positions (L, d) [m], in state order
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
        copied.registry = self.registry.copy()
        copied.source_ids = list(self.source_ids)
        copied.sightings = list(self.sightings)
        copied.created_t = list(self.created_t)
        copied.predicted_position = self.predicted_position.copy()
        copied.association_modes = set(self.association_modes)
        copied.policy = self.policy.branch()
        copied.clock = copy.copy(self.clock)
        # landmarks, first_landmarks and the vehicle mean are replaced, never changed in place
        return copied

    @property
    def vehicle_size(self) -> int:
        return self.registry.vehicle_size

    @property
    def map_ids(self) -> np.ndarray:
        """Map ids of the landmarks in state order, (L,) (the registry's, read-only)."""
        return self.registry.ids

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
            increment, increment_cov = odometry_increment(
                measurement, dt, self.dimension, self.sequence_noise.odometry
            )
            new, transition, process = predict_odometry_3d(
                self.vehicle,
                self.layout,
                increment,
                increment_cov * self.config.odometry_noise_scale,
            )
            transition = self._first_estimate(new, transition)
        else:
            rate = gyro_rate(measurement, self.layout.rotation_size)
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
            process = widen_for_gap(process, self.layout, self.config, dt)
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
        transition = self._first_estimate(new, transition)
        kalman.propagate_vehicle(self.covariance, self.vehicle_size, transition, process)
        self.vehicle = new
        self.motion_t = float(t)
        self.t = max(self.t, float(t))

    def _first_estimate(self, new: VehicleMean, transition: np.ndarray) -> np.ndarray:
        """With ``fej_propagation``, the transition at the previous prediction (Huang et al.
        (2008), eq. (25): ``first_estimate_transition``); ``new`` becomes that prediction."""
        if not self.fej_propagation:
            return transition
        step = new.position - self.predicted_position
        transition = first_estimate_transition(self.layout, transition, step)
        self.predicted_position = new.position.copy()
        return transition

    # ------------------------------------------------------------------ scans
    def _scan(self, scan: LandmarkScan) -> None:
        points, noise = self.scan_inputs(scan)
        mode = self.policy.mode(scan.ids, scan.t)
        predictor = scan_update.predictor(self)
        if mode == "ids":
            association = self.policy.by_ids(
                scan.ids, points, noise, np.array(self.source_ids, dtype=int), predictor
            )
        else:
            association = self.policy.by_geometry(points, noise, len(self.map_ids), predictor, mode)
            if association.search is not None:
                recording.record_search(self.recorder, scan.t, association.search)
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
        landmarks[matched] = self.map_ids[association.candidates[matched]]
        association = self.policy.decorrelated(association, scan.t, points, noise, landmarks)
        if len(matched):
            scan_update.update(self, scan.t, points[matched], noise[matched], association, matched)
        created: dict[int, int] = {}
        for j in association.rows(AssociationDecision.NEW):
            source = int(scan.ids[j]) if association.mode == "ids" else -1
            created[int(j)] = add_landmark(self, scan.t, points[j], noise[j], source)
            self.policy.sighted(int(self.map_ids[created[int(j)]]), scan.t)
        record_associations(self, scan.t, association, created)
        prune(self, scan.t)
        self.recorder.landmark_count(scan.t, len(self.map_ids))
        if self.recorder.snapshot_due(scan.t):
            self.recorder.landmarks(self.map_snapshot(scan.t))

    def predict(self, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Map landmarks ``indices`` predicted with the configured Jacobians: z (m, d),
        vehicle (m, d, n_v) and landmark (m, d, d) Jacobians (``scan_update.predict``)."""
        return scan_update.predict(self, indices)

    def observation_jacobian(self, indices: np.ndarray) -> tuple[np.ndarray, kalman.SparseJacobian]:
        """Predictions (n, d) of map landmarks ``indices`` and their stacked sparse ``H``."""
        return scan_update.observation_jacobian(self, indices)

    # ------------------------------------------------------------------ output
    def map_snapshot(self, t: float | None) -> LandmarkMap:
        """The world map with its joint covariance (the landmark block of P)."""
        v = self.vehicle_size
        return LandmarkMap.from_joint(
            self.map_ids, self.landmarks, self.covariance[v:, v:], Frame.WORLD, t
        )

    def record_state(self, recorder: EstimateRecorder | None = None) -> None:
        """Record the vehicle's posterior (pose, velocity, gyro bias) into ``recorder``
        (default: the filter's own; ``recording.record_vehicle``)."""
        recording.record_vehicle(self, self.recorder if recorder is None else recorder)

    def estimate(self) -> Estimate:
        final_map = self.map_snapshot(self.t)
        self.recorder.final_snapshot(final_map)
        return self.recorder.build(landmarks=final_map, notes=(self.summary_note("ekf-slam"),))

    def summary_note(self, name: str, extra_gaps: int = 0) -> str:
        """The run's note on its input, association and map, headed ``name``;
        ``extra_gaps``: motion gaps counted outside the filter (``multi_hypothesis``)."""
        return recording.summary_note(self, name, extra_gaps)


def _first(*values: float | None) -> float:
    """The first value that is not None."""
    return float(next(value for value in values if value is not None))
