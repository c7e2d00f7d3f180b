"""The Guerreiro et al. (2013) sensor-based SLAM filter, registered as ``sensor-based``.

Robocentric LTV Kalman filter: state = body-frame velocity, rate-gyro bias and body-frame
landmarks (optionally with line directions); inputs = rate gyro (``GyroSample``, or the
gyro of an ``ImuSample``: the accelerometer is unused) and ``LandmarkScan`` (body-frame
points); odometry optionally (``odometry``: an extension). Prediction at every gyro sample
(``dynamics.propagate_in_place``, eq. (10)), association by the shared policy
(``scan_association`` on ``filters.association``: the scan's ids, or JCBB), the section IV-B
update through the shared Kalman core (``update``), landmark management
(``landmark_management``), loop closing between the current and old landmark sets
(``loop_closing``, section IV-C) and the Earth-frame trajectory derived from the map history
(``earth_frame``, fed the motion since the last scan by ``earth_motion``); what is exported is
recorded by ``recording``. This module orchestrates them: the inputs, the propagation and the
order of a scan's steps.

Geometric association uses only the current set I_cur (landmarks seen within
``association_window_s``), as the paper does; an unassociated measurement starts a new
landmark only when it lies outside every current landmark's gate even at
``new_landmark_probability`` (otherwise it is ambiguous: recorded, neither used nor mapped).

Discretization: eq. (10) is forward Euler; the default solves the same LTV model exactly
over each step with the inputs held (``dynamics.propagate``), because Euler's ``I - Ts S(w)``
dilates the landmarks during turns, which the filter mistakes for speed (measured: a common
-3 mm/s forward-velocity error after each corridor corner of ``sim:guerreiro-loop``, four
times the true scatter). ``discretization="euler"`` gives the literal eq. (10).

Update: the section IV-B correction corrects the map's common rigid motion (the vehicle's
heading and position against the world, which every feature shares) to first order only,
``f + dp + M(f) dphi``, which dilates the map by ``r dphi^2 / 2`` at range ``r``. Its rigid
part is applied as an exact rotation by default (``rigid_correction``; ``"linear"``: the
Kalman correction as it is). On UTIAS dataset 1 with ids (SE(2) ATE, robots 1-5) linear /
exact: 0.130 / 0.112 / 0.080 / 0.166 / 0.106, 0.094 / 0.082 / 0.080 / 0.099 / 0.121 m;
after robot 2's 34 s without sightings one correction turned the map by 0.26 rad.

Multirate: the paper assumes synchronised gyro and laser; here ``A(t, y)`` holds each
visible feature's last measured value between scans (it enters only through the ``M(y) b``
bias term), for at most ``measured_hold_s`` (1 s): after that the feature is non-visible
and its estimate stands in, as for any feature out of view. Held across a gap without scans
(UTIAS between sightings: 121 gaps over 1 s on robot 2, the longest 34 s; CARMEN and
Victoria Park between corner scans, up to 52 s) while the vehicle turns, a stale ``y``
turns the bias term into a drift of the map: noise-free, 20 s at 0.3 rad/s with a 0.05
rad/s bias, 4.3 m against 0.04 m (``tests/test_sensor_based_filter.py``). On UTIAS
dataset 1 with ids (SE(2) ATE, robots 1-5; the linear update) held to the next scan / 1 s /
0.3 s: 0.124 / 0.119 / 0.082 / 0.201 / 0.108, 0.130 / 0.112 / 0.080 / 0.166 / 0.106, 0.129 /
0.112 / 0.080 / 0.168 / 0.106 m; Victoria Park (RMS from the batch smoother) 3.79 / 3.93 m;
CARMEN Intel 13.84 / 12.86 m, Freiburg 079 and MIT CSAIL unchanged
(docs/estimators/sensor-based.md).
Long steps are split into sub-steps of at most ``max_step_s``. The rate over a gyro
interval is, by default, the mean of the two samples that bracket it
(``interval_rate="average"``): a sampled gyro reads the instantaneous rate, and holding
the earlier sample (the literal forward Euler of eq. (10)) mis-integrates the heading by
``0.5 omega_dot Ts^2`` per step, which at the 10 Hz of the paper and a corner's
``omega_dot ~ 0.1 rad/s^2`` is a bias-sized error of 5e-3 rad/s.
``"hold"`` gives the literal scheme. A scan between gyro samples is reached with the held
rate; the rest of that interval uses the average once the next sample arrives.

Exported (DESIGN.md; ``recording``): ``velocity`` (body frame) and ``gyro_bias`` after
every scan, ``landmarks`` snapshots (body frame, the filter's own map ids) every
``snapshot_interval_s``; ``pose`` is the Earth-frame
trajectory *derived* from consecutive body-frame maps, planar with the first-order covariance
of ``earth_pose_covariance`` (our extension), 3-D without one (``earth_frame=false`` turns
it off), or, with ``earth_frame_source=filter_state``, read from the Earth frame's
non-visible features in the state with their first-order covariance (``earth_state``);
extras ``vehicle_t``/``vehicle_state``/``vehicle_covariance`` carry the joint [v, b] block
for the vehicle NEES. NIS: the stacked innovation of every scan, and one
value per associated landmark (eq. (11)), dof = its block size.

Measurement noise: the filter uses each scan's stated covariances (``tuning=paper``: the
paper's laser model, ``scan_association.paper_laser_covariances``). (The simulator gives
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
from datasets.measurements import (
    GyroSample,
    ImuSample,
    LandmarkScan,
    Measurement,
    Odometry,
    Sensor,
)
from datasets.model_options import interval_value
from datasets.sequence import Sequence
from datasets.state import LandmarkMap
from datasets.stream_clock import StreamClock
from filters.association import AssociationPolicy, Decision
from filters.sensor_based.config import SensorBasedConfig
from filters.sensor_based.dynamics import propagate_in_place, rate_dimension
from filters.sensor_based.earth_motion import MotionSinceScan, step_earth_frame
from filters.sensor_based.landmark_management import (
    LandmarkManager,
    ManagementPolicy,
    create_landmark,
    manage_after_scan,
)
from filters.sensor_based.loop_closing import LoopClosurePolicy, fuse_loop_closures
from filters.sensor_based.odometry import (
    odometry_increment,
    odometry_interval,
    odometry_rate,
    odometry_velocity,
    velocity_update,
)
from filters.sensor_based.prior import (
    add_earth_frame,
    earth_tracker,
    process_noise,
    vehicle_prior,
)
from filters.sensor_based.recording import (
    body_map,
    earth_frame_map,
    estimate_notes,
    frame_earth_map,
    record_associations,
    record_carried_pose,
    record_earth_pose,
    record_frame_pose,
    record_vehicle,
)
from filters.sensor_based.scan_association import (
    associate_scan,
    scan_sightings,
    usable_sightings,
)
from filters.sensor_based.update import update_matched


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
        self.rate_dim = rate_dimension(d)
        if config.tuning == "paper" and d != 2:
            raise InputError(
                f"{sequence.name}: tuning=paper is the paper's planar laser model (2-D datasets)"
            )
        self.noise = process_noise(config, sequence)
        # no gyro: the rate is the odometry's rotation over each increment (lidar odometry),
        # which has no bias of its own; the bias state stays, with a tight prior
        self.rate_from_odometry = not ({Sensor.GYRO, Sensor.IMU} & sequence.sensors)
        self.state = vehicle_prior(config, sequence, self.rate_from_odometry)
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
        self.earth = earth_tracker(config, sequence)
        # the Earth frame as features of the state (earth_state) instead of the tracker
        self.frame_in_state = add_earth_frame(config, sequence, self.state)
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
        self._last_scan_t: float | None = None
        self.motion = MotionSinceScan(d)  # the filter's own motion since the last scan
        start = sequence.initial_state
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
        record_vehicle(self.recorder, self.state, self.t if self.t is not None else 0.0)
        self._record_pose(self.t if self.t is not None else 0.0)

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
            rotation_before = self.motion.rotation
            if self.rate_from_odometry:
                self._odometry_rate(measurement)
            if self.use_odometry:
                self._odometry(measurement)
            self.motion.accumulate_odometry_covariance(
                measurement, rotation_before, None if self.earth is None else self.earth.errors
            )
            if measurement.frame and self.frame_in_state:
                # a sensor frame without a scan: the pose there is the state's frame now
                self._propagate_to(measurement.t)
                record_frame_pose(self.recorder, self.state, measurement.t)
            elif measurement.frame and self.earth is not None:
                # a sensor frame without a scan (a sweep without corners): the pose there is
                # the Earth pose carried by the motion since the last scan
                nv = self.state.vehicle_dim
                record_carried_pose(
                    self.recorder,
                    self.earth,
                    self.motion,
                    self.state.covariance[:nv, :nv],
                    self.noise,
                    measurement.t,
                    self.dimension,
                )

    def _odometry_rate(self, odometry: Odometry) -> None:
        """Without a gyro, the rate input over an odometry increment (``odometry.odometry_rate``:
        an extension beyond the paper), with the noise density it implies."""
        previous, self._rate_odometry_t = self._rate_odometry_t, float(odometry.t)
        if previous is None:
            previous = self.t
        found = odometry_rate(odometry, odometry_interval(odometry, previous), self.dimension)
        if found is None:
            self._propagate_to(odometry.t)
            return
        rate, density_sq = found
        if not (np.all(np.isfinite(rate)) and np.isfinite(density_sq)):
            self.skipped["nan_odometry"] += 1
            self._propagate_to(odometry.t)
            return
        self.noise = replace(self.noise, gyro_noise_density=math.sqrt(max(density_sq, 0.0)))
        rotation_before, translation_before = self.motion.rotation, self.motion.translation
        self._propagate_to(odometry.t, rate)
        self.rate = rate
        if odometry.relative_pose is not None:
            # the Earth-frame fallback's motion over this increment is the increment itself
            step, turn = odometry_increment(odometry, self.dimension)
            self.motion.carry_increment(rotation_before, translation_before, step, turn)

    def _odometry(self, odometry: Odometry) -> None:
        """Odometry as a measurement of the body velocity ``v`` (``odometry.odometry_velocity``,
        ``odometry.velocity_update``): an extension beyond the paper (config ``use_odometry``)."""
        d = self.dimension
        previous, self._odometry_t = self._odometry_t, float(odometry.t)
        self._propagate_to(odometry.t)
        measured, covariance = odometry_velocity(
            odometry, previous, d, self.odometry_model, self.config.odometry_lateral_sigma_m_s
        )
        if measured is None:
            return
        if not (np.all(np.isfinite(measured)) and np.all(np.isfinite(covariance))):
            self.skipped["nan_odometry"] += 1
            return
        velocity_update(self.state, self.recorder, odometry.t, measured, covariance)

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
        hold = self.config.measured_hold_s
        if hold is not None and self._last_scan_t is not None and self.state.visible.any():
            # the scan's measured values stand in A(t, y) only until they expire
            expiry = self._last_scan_t + hold
            if self.t < expiry < t:
                self._step_to(expiry, rate)
            if t >= expiry:
                self.state.visible[:] = False
        self._step_to(t, rate)

    def _step_to(self, t: float, rate: np.ndarray | None) -> None:
        """Propagate from ``self.t`` to ``t`` in sub-steps of at most ``max_step_s``."""
        dt = t - self.t
        if dt <= 0.0:
            return
        if rate is None:
            rate = self.rate if self.rate is not None else np.zeros(self.rate_dim)
        # a gap of a whole number of steps plus float64 rounding sub-steps as that number:
        # epoch stamps (1.3e9 s) resolve 0.1 s only to 2e-7 s, and 1e-9 of a step let the
        # same scans stamped two ways propagate in 2 or 3 steps
        steps = max(1, int(math.ceil(dt / self.config.max_step_s - 1e-5)))
        state = self.state
        for _ in range(steps):
            if self.earth is not None:  # only the Earth-frame fallback uses the motion
                self.motion.accumulate(rate, dt / steps, state.velocity, state.bias)
            state.x = propagate_in_place(
                state.x,
                state.covariance,
                state.translates,
                state.measured,
                state.visible,
                rate,
                dt / steps,
                self.noise,
                self.dimension,
                self.config.discretization,
                state.undisturbed if self.frame_in_state else None,
            )
        self.t = float(t)

    # ------------------------------------------------------------------ scans
    def _scan(self, scan: LandmarkScan) -> None:
        """A scan's steps: association, the section IV-B update, new landmarks, management,
        loop closing (section IV-C), the records and the Earth-frame step."""
        d = self.dimension
        points, covs = scan_sightings(scan, d, self.name, self.config.tuning == "paper")
        if self.rate is None:
            self.skipped["scan_without_rate"] += 1
        self._propagate_to(scan.t)
        t = float(scan.t)
        k = points.shape[0]
        usable = usable_sightings(points, covs)
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

        association = associate_scan(
            self.state,
            self.policy,
            self.manager,
            self.source_of,
            self.recorder,
            self.config.association_window_s,
            t,
            scan.ids,
            points,
            covs,
            usable,
        )
        # matched candidates are landmark ids here (``associate_scan``)
        association = self.policy.decorrelated(association, t, points, covs, association.candidates)
        self.state.visible[:] = False  # I_O is redefined by every scan (section IV-B)
        self._last_scan_t = t
        sigma = self.config.direction_sigma_rad
        assignment = update_matched(
            self.state,
            self.recorder,
            sigma,
            t,
            points,
            covs,
            directions,
            association,
            self.config.rigid_correction,
        )
        for j in association.rows(Decision.NEW):
            landmark_id = create_landmark(
                self.state,
                self.manager,
                sigma,
                t,
                points[j],
                covs[j],
                None if directions is None else directions[j],
            )
            assignment[j] = landmark_id
            self.policy.sighted(landmark_id, t)
            if association.mode == "ids":
                self.source_of[landmark_id] = int(scan.ids[j])
        record_associations(self.recorder, t, association, assignment)

        seen_ids = {int(a) for a in assignment if a >= 0}
        state = self.state
        manage_after_scan(state, self.manager, self.source_of, t, seen_ids)
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
        record_vehicle(self.recorder, state, t)
        if self.earth is not None:
            step_earth_frame(self.earth, state, self.manager.records, self.motion, self.noise)
        self._record_pose(t)
        if self.recorder.snapshot_due(t):
            self.recorder.landmarks(self.landmark_map(t))

    def _close_loops(self, t: float) -> None:
        """Section IV-C (``loop_closing.fuse_loop_closures``): fuse current landmarks with
        their old duplicates, keep the old id, and drop the duplicates everywhere."""
        fused = fuse_loop_closures(
            self.state,
            self.manager.records,
            self.source_of,
            self.loop_policy,
            self.config.loop_max_old_sigma_m,
            t,
        )
        if not fused:
            return
        removed_ids = [removed for _, removed in fused]
        if self.earth is not None:
            for removed in removed_ids:  # the old landmark's Earth position stays
                self.earth.forget(removed)
        self.state.remove_landmarks(removed_ids)
        self.manager.removed(removed_ids)
        self.recorder.event(t, "loop_closure", pairs=fused)

    # ------------------------------------------------------------------ output
    def landmark_map(self, t: float) -> LandmarkMap:
        """The body-frame map now: ids, positions (L, d), their joint covariance."""
        return body_map(self.state, t)

    def _record_pose(self, t: float) -> None:
        """The Earth-frame pose after a scan (``recording.record_frame_pose`` from the state's
        frame, or ``recording.record_earth_pose`` from the tracker)."""
        if self.frame_in_state:
            record_frame_pose(self.recorder, self.state, t)
        elif self.earth is not None:
            record_earth_pose(self.recorder, self.earth, t, self.dimension)

    def earth_map(self) -> LandmarkMap | None:
        """The current map in the Earth frame (derived; covariances rotated, pose uncertainty ignored)."""
        current = self.landmark_map(self.t if self.t is not None else 0.0)
        if self.frame_in_state:
            return frame_earth_map(self.state, current)
        if self.earth is None:
            return None
        return earth_frame_map(self.earth, current)

    def estimate(self) -> Estimate:
        notes = estimate_notes(
            self.earth, self.manager.deleted, self.use_odometry, self.skipped, self.frame_in_state
        )
        t = self.t if self.t is not None else 0.0
        return self.recorder.build(landmarks=self.landmark_map(t), notes=notes)
