"""The keyframe factor-graph smoother shared by the batch, iSAM2 and fixed-lag modes.

Data flow: motion samples (IMU in 3-D; odometry or a rate gyro in 2-D) are accumulated by a
motion model (``smoothers.imu_graph.ImuMotion``, ``smoothers.planar_graph.PlanarMotion``,
chosen by the sequence's dimension); measurements that need a state at their own time
(landmark scans, GPS fixes) open a keyframe at that time. A keyframe is committed once the
stream has moved past its time, so every motion sample up to it is in and measurements with
the same time stamp (duplicates) share one keyframe. Each committed keyframe goes to an
incremental backend (iSAM2 or the fixed-lag smoother) in one update.

Keyframe policy (``keyframe_imu_stride``): a keyframe at every landmark scan and GPS fix
always (a measurement needs a state at its own time; attaching it to a nearby keyframe would
inject a timing error), plus, when set, one every k motion samples (e.g. between sparse GPS
fixes, or to bound the preintegration length).

Association: by the scan's ids when it carries them (and ``association`` is ``auto`` or
``ids``); otherwise JCBB from ``filters.association`` against the current estimate: the
keyframe's motion (and GPS) factors are solved first, then the predicted measurements of
the landmarks within reach get the covariance ``H P H^T`` from the *joint* marginal of the
new pose and those landmarks (iSAM2; the fixed-lag smoother's Python API has no joint
marginal, so there the blocks are the individual marginals, correlations neglected).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, Literal

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L
from pydantic import BaseModel, ConfigDict, Field

from datasets.errors import InputError
from datasets.estimate import AssociationDecision, Estimate, EstimateRecorder
from datasets.measurements import (
    GpsFix,
    ImuSample,
    LandmarkScan,
    Measurement,
    Odometry,
    Sensor,
)
from datasets.sequence import Sequence
from datasets.state import Frame, LandmarkMap, StateHistory
from smoothers.covariances import vector_covariance
from smoothers.imu_graph import ImuMotion, ImuNoise
from smoothers.initialization import InitialPriors
from smoothers.landmark_factors import (
    body_point_factor_2d,
    body_point_factor_3d,
    cartesian_point_factor_3d,
    check_measurement_covariance,
    landmark_prior,
)
from smoothers.odometry_factors import RelativePoseAccumulator
from smoothers.planar_graph import PlanarMotion


class SmootherConfig(BaseModel):
    """Options shared by every smoother mode."""

    model_config = ConfigDict(extra="forbid")
    anchors: int | None = Field(
        None,
        ge=0,
        description="the first N of sequence.known_landmarks become known landmarks (tight priors), as for the filters; "
        "None: 3 when the dataset offers known landmarks (the aghili filter's default), else 0",
    )
    anchor_sigma_m: float = Field(
        1e-3, gt=0, description="std of an anchor landmark's prior [m] (tight: 'known')"
    )
    keyframe_imu_stride: int | None = Field(
        None,
        ge=1,
        description="also open a keyframe every k motion samples (None: only at scans/GPS fixes)",
    )
    max_imu_gap_s: float = Field(
        0.5, gt=0, description="a gap between motion samples longer than this is an InputError [s]"
    )
    gravity_m_s2: float | None = Field(
        None,
        gt=0,
        description="gravity magnitude [m/s^2]; None: sequence.metadata['gravity_m_s2'] or 9.81",
    )
    position_sigma_m: float | None = Field(
        None, gt=0, description="initial position prior std [m]; None: sequence.initial_state"
    )
    rotation_sigma_rad: float | None = Field(
        None, gt=0, description="initial rotation prior std [rad]; None: sequence.initial_state"
    )
    velocity_sigma_m_s: float | None = Field(
        None, gt=0, description="initial velocity prior std [m/s]; None: sequence.initial_state"
    )
    gyro_bias_sigma_rad_s: float | None = Field(
        None, gt=0, description="initial gyro bias std [rad/s]; None: sequence.noise, else 0.01"
    )
    accel_bias_sigma_m_s2: float | None = Field(
        None, gt=0, description="initial accel bias std [m/s^2]; None: sequence.noise, else 0.1"
    )
    landmark_factor: Literal["bearing-range", "cartesian"] = Field(
        "bearing-range",
        description="3-D landmark factor: native BearingRangeFactor3D with mapped noise, or an exact Python CustomFactor",
    )
    association: Literal["auto", "ids", "jcbb"] = Field(
        "auto", description="auto: ids when scans carry them, else JCBB"
    )
    gate_probability: float = Field(
        0.999, gt=0, lt=1, description="chi-square gate probability of JCBB"
    )
    use_gps: bool = Field(
        True, description="add GPS position factors when the sequence has GPS fixes"
    )
    use_odometry: bool = Field(
        True,
        description="3-D: add relative-pose factors from 6-D odometry (lidar) when the sequence has it",
    )
    relinearize_threshold: float = Field(0.05, gt=0, description="iSAM2 relinearisation threshold")
    relinearize_skip: int = Field(1, ge=1, description="iSAM2 relinearise every k updates")
    extra_iterations: int = Field(0, ge=0, description="extra iSAM2 update() calls per keyframe")
    planar_velocity_walk_m_s2: float = Field(
        0.1,
        gt=0,
        description="2-D gyro-only model: body-velocity random-walk density [m/s^2/sqrt(Hz)]",
    )
    planar_gyro_density: float | None = Field(
        None, gt=0, description="2-D gyro-only: gyro white-noise density; None: sequence.noise"
    )
    odometry_lateral_sigma_m_s: float = Field(
        0.02, gt=0, description="2-D velocity odometry: lateral-slip floor [m/s]"
    )
    imu_interpolation: bool = Field(
        True,
        description="integrate the line between consecutive samples (instantaneous samples); false: zero-order hold",
    )


@dataclass
class _Landmark:
    """One map landmark: its current variable key and bookkeeping."""

    map_id: int
    key: int
    anchor_position: np.ndarray | None = None
    observations: int = 0
    last_t: float = 0.0


@dataclass
class _Group:
    """Keyframe-creating measurements sharing one time stamp."""

    t: float
    scans: list[LandmarkScan] = field(default_factory=list)
    fixes: list[GpsFix] = field(default_factory=list)


class KeyframeSmoother:
    """Shared machinery of the smoother modes (see the module docstring).

    Subclasses choose the backend (``_make_backend``), whether to record the causal history
    (``record_causal``) and how to finish (``_finish``).
    """

    Config: ClassVar[type[BaseModel]] = SmootherConfig
    sensor_options: ClassVar[tuple[frozenset[Sensor], ...]] = (
        frozenset({Sensor.IMU, Sensor.LANDMARKS}),
        frozenset({Sensor.IMU, Sensor.GPS}),
        frozenset({Sensor.IMU, Sensor.ODOMETRY}),
        frozenset({Sensor.ODOMETRY, Sensor.LANDMARKS}),
        frozenset({Sensor.GYRO, Sensor.LANDMARKS}),
    )
    dimensions: ClassVar[frozenset[int]] = frozenset({2, 3})
    record_causal: ClassVar[bool] = True
    mode: ClassVar[str] = "smoother"

    def __init__(self, config: SmootherConfig, sequence: Sequence) -> None:
        self.config = config
        self.sequence_name = sequence.name
        self.dimension = sequence.dimension
        if sequence.initial_state is None:
            raise InputError(
                f"{sequence.name}: the smoother needs an initial state (sequence.initial_state) to fix the frame; "
                "the dataset gives none, so the system would be indeterminate"
            )
        self.start = sequence.initial_state
        self.priors = self._priors(sequence)
        self.motion = self._motion_model(sequence)
        self.recorder = EstimateRecorder(self.dimension)
        self.backend = self._make_backend()
        self.full_graph = gtsam.NonlinearFactorGraph()
        self.notes: list[str] = []
        self.landmarks: dict[int, _Landmark] = {}
        self.next_map_id = 0
        self.next_key_index = 0
        self.keyframe_t: list[float] = []
        self.group: _Group | None = None
        self.last_t = -np.inf
        self.estimate_values = gtsam.Values()
        self.causal_covariances = True
        self.has_gps = Sensor.GPS in sequence.sensors and config.use_gps
        self.odometry_3d = (
            RelativePoseAccumulator()
            if self.dimension == 3 and config.use_odometry and Sensor.ODOMETRY in sequence.sensors
            else None
        )
        graph, values = self.motion.initial(self.start, self.priors)
        self.pending_graph = graph
        self.pending_values = values
        self.pending_times = {key: float(self.start.t) for key in self.motion.keys(0)}
        self.keyframe_t.append(float(self.start.t))
        self.first_sightings: dict[int, tuple[int, np.ndarray]] = {}
        self._add_anchors(sequence)
        self.start_values = gtsam.Values(self.pending_values)
        if self.dimension == 3 and Sensor.IMU not in sequence.sensors:
            raise InputError(f"{sequence.name}: the 3-D smoother needs IMU samples")

    # ------------------------------------------------------------------ set-up
    def _priors(self, sequence: Sequence) -> InitialPriors:
        c, s, n = self.config, sequence.initial_state, sequence.noise
        assert s is not None
        return InitialPriors(
            position_sigma_m=c.position_sigma_m or s.position_sigma_m,
            rotation_sigma_rad=c.rotation_sigma_rad or s.rotation_sigma_rad,
            velocity_sigma_m_s=c.velocity_sigma_m_s or s.velocity_sigma_m_s,
            gyro_bias_sigma_rad_s=c.gyro_bias_sigma_rad_s or n.gyro_bias_sigma_rad_s or 0.01,
            accel_bias_sigma_m_s2=c.accel_bias_sigma_m_s2 or n.accel_bias_sigma_m_s2 or 0.1,
        )

    def _motion_model(self, sequence: Sequence) -> ImuMotion | PlanarMotion:
        c = self.config
        if sequence.dimension == 3:
            gravity = c.gravity_m_s2 or float(sequence.metadata.get("gravity_m_s2", 9.81))
            return ImuMotion(
                ImuNoise.from_spec(sequence.noise, sequence.name),
                gravity,
                c.max_imu_gap_s,
                c.imu_interpolation,
            )
        if Sensor.ODOMETRY in sequence.sensors:
            source = "odometry"
        elif Sensor.GYRO in sequence.sensors:
            source = "gyro"
        else:
            raise InputError(f"{sequence.name}: the planar smoother needs odometry or a rate gyro")
        gyro_density = c.planar_gyro_density or sequence.noise.gyro_noise_density
        if source == "gyro" and not gyro_density:
            raise InputError(
                f"{sequence.name}: gyro-only planar smoother needs the gyro noise density (sequence.noise or planar_gyro_density)"
            )
        gyro_walk = sequence.noise.gyro_bias_walk or 1e-4
        return PlanarMotion(
            source,
            c.planar_velocity_walk_m_s2,
            gyro_density or 0.0,
            gyro_walk,
            c.odometry_lateral_sigma_m_s,
            c.max_imu_gap_s,
        )

    def _add_anchors(self, sequence: Sequence) -> None:
        count = self.config.anchors
        if count is None:
            count = 3 if sequence.known_landmarks is not None and self.dimension == 3 else 0
        self.anchor_count = count
        if count == 0:
            return
        known = sequence.known_landmarks
        if known is None or len(known) < count:
            have = 0 if known is None else len(known)
            raise InputError(
                f"{sequence.name}: anchors={count} but the dataset offers {have} known landmarks"
            )
        if known.dimension != self.dimension:
            raise InputError(
                f"{sequence.name}: known landmarks are {known.dimension}-D, the sequence is {self.dimension}-D"
            )
        for index in range(count):
            map_id = int(known.ids[index])
            position = np.asarray(known.positions[index], dtype=float)
            landmark = self._new_landmark(map_id, position, self.start.t)
            landmark.anchor_position = position
            self.pending_graph.add(
                landmark_prior(landmark.key, position, self.config.anchor_sigma_m)
            )
        self.next_map_id = max(self.next_map_id, int(np.max(known.ids[:count])) + 1)

    def _new_landmark(self, map_id: int, position: np.ndarray, t: float) -> _Landmark:
        key = L(self.next_key_index)
        self.next_key_index += 1
        landmark = self.landmarks.get(map_id)
        if landmark is None:
            landmark = _Landmark(map_id=map_id, key=key)
            self.landmarks[map_id] = landmark
        else:
            landmark.key = key
        self.pending_values.insert(key, position)
        self.pending_times[key] = float(t)
        landmark.last_t = float(t)
        return landmark

    # ------------------------------------------------------------------ subclass hooks
    def _make_backend(self):  # pragma: no cover - abstract
        raise NotImplementedError

    def _before_update(self, t_new: float) -> None:
        """Hook run before each backend update (fixed lag records leaving keyframes)."""

    # ------------------------------------------------------------------ stream
    def process(self, measurement: Measurement) -> None:
        t = float(measurement.t)
        if not np.isfinite(t):
            raise InputError(
                f"non-finite time stamp after t={self.last_t:.6f} s ({type(measurement).__name__})"
            )
        if t < self.last_t:
            raise InputError(
                f"time goes backwards at t={t:.6f} s (previous {self.last_t:.6f} s, {type(measurement).__name__})"
            )
        self.last_t = t
        if self.group is not None and t > self.group.t:
            if self.motion.accepts(measurement):
                self.motion.look_ahead(measurement)  # type: ignore[arg-type]
            self._commit_group()
        if self.motion.accepts(measurement):
            if (
                t < self.start.t
                and isinstance(measurement, Odometry)
                and measurement.relative_pose is not None
            ):
                return
            if isinstance(measurement, ImuSample):
                before = self.motion.integrator.held_t  # type: ignore[union-attr]
                self.motion.add(measurement)  # type: ignore[arg-type]
                if before == measurement.t:
                    self.recorder.event(t, "duplicate_imu_sample_skipped")
            else:
                self.motion.add(measurement)  # type: ignore[arg-type]
            stride = self.config.keyframe_imu_stride
            if stride and self.motion.since_keyframe() >= stride and t > self.keyframe_t[-1]:
                self._open_group(t)
            return
        if t < self.start.t:
            self.recorder.event(
                t, "measurement_before_start_skipped", kind=type(measurement).__name__
            )
            return
        if isinstance(measurement, LandmarkScan):
            self._open_group(t).scans.append(measurement)
        elif isinstance(measurement, GpsFix) and self.has_gps:
            self._open_group(t).fixes.append(measurement)
        elif (
            isinstance(measurement, Odometry) and self.odometry_3d is not None and t > self.start.t
        ):
            # A relative pose ends at a state: it opens a keyframe at its own time.
            self.odometry_3d.add(measurement)
            if measurement.relative_pose is not None:
                self._open_group(t)

    def _open_group(self, t: float) -> _Group:
        if self.group is None:
            self.group = _Group(t)
        return self.group

    def _commit_group(self) -> None:
        group = self.group
        assert group is not None
        self.group = None
        t = group.t
        k = len(self.keyframe_t) - 1
        created = t > self.keyframe_t[-1]
        if created:
            k += 1
            graph, values = self.motion.close(k, t, self._current_values())
            self.pending_graph.push_back(graph)
            self.pending_values.insert(values)
            for key in self.motion.keys(k):
                self.pending_times[key] = t
            self.keyframe_t.append(t)
            if self.odometry_3d is not None:
                factor = self.odometry_3d.factor(
                    self.motion.pose_key(k - 1), self.motion.pose_key(k)
                )
                if factor is not None:
                    self.pending_graph.add(factor)
                self.odometry_3d.start()
        for fix in group.fixes:
            self._add_gps(k, fix)
        if any(self._needs_jcbb(scan) for scan in group.scans):
            # Solve the motion (and GPS) factors first, so that JCBB sees this keyframe's
            # pose with its true marginal and its correlation with the map.
            self._solve_pending(t)
        for scan in group.scans:
            self._add_scan(k, scan)
        self._update(t)
        if created:
            self.motion.restart(t, self.estimate_values, k)

    def _current_values(self) -> gtsam.Values:
        """Newest keyframe's estimate, with the not yet committed values layered on top."""
        values = gtsam.Values(self.estimate_values)
        for key in self.pending_values.keys():
            if values.exists(key):
                values.erase(key)
        values.insert(self.pending_values)
        return values

    def _needs_jcbb(self, scan: LandmarkScan) -> bool:
        return self.config.association == "jcbb" or (
            self.config.association == "auto" and scan.ids is None
        )

    def _solve_pending(self, t: float) -> None:
        """Send the pending factors to the backend without recording a causal state."""
        self._before_update(t)
        self.full_graph.push_back(self.pending_graph)
        self.backend.update(self.pending_graph, self.pending_values, self.pending_times, t)
        self.pending_graph = gtsam.NonlinearFactorGraph()
        self.pending_values = gtsam.Values()
        self.pending_times = {}
        # Only the newest keyframe's state is needed to go on (the full estimate is O(n)).
        self.estimate_values = self.backend.values(self.motion.keys(len(self.keyframe_t) - 1))

    def _update(self, t: float) -> None:
        self._solve_pending(t)
        k = len(self.keyframe_t) - 1
        if self.record_causal:
            self.motion.record(
                self.recorder,
                t,
                self.estimate_values,
                k,
                self.backend_marginals() if self.causal_covariances else None,
            )

    def backend_marginals(self):
        return _BackendMarginals(self.backend)

    # ------------------------------------------------------------------ measurements
    def _add_gps(self, k: int, fix: GpsFix) -> None:
        position = np.asarray(fix.position, dtype=float)
        covariance = np.asarray(fix.covariance, dtype=float)
        if self.dimension != 3 or position.shape != (3,) or covariance.shape != (3, 3):
            raise InputError(
                f"GPS fix at t={fix.t:.6f} s: expected a 3-D position and a (3, 3) covariance"
            )
        if not (np.all(np.isfinite(position)) and np.all(np.isfinite(covariance))):
            raise InputError(f"GPS fix at t={fix.t:.6f} s is not finite")
        self.pending_graph.add(
            gtsam.GPSFactor(
                self.motion.pose_key(k), position, gtsam.noiseModel.Gaussian.Covariance(covariance)
            )
        )

    def _check_scan(self, scan: LandmarkScan) -> tuple[np.ndarray, np.ndarray]:
        points = np.asarray(scan.points, dtype=float)
        covariances = np.asarray(scan.covariances, dtype=float)
        d = self.dimension
        if points.ndim != 2 or points.shape[1] != d or covariances.shape != (points.shape[0], d, d):
            raise InputError(
                f"landmark scan at t={scan.t:.6f} s: points {points.shape} / covariances {covariances.shape} do not match dimension {d}"
            )
        if not np.all(np.isfinite(points)):
            raise InputError(f"landmark scan at t={scan.t:.6f} s contains non-finite points")
        for index, covariance in enumerate(covariances):
            check_measurement_covariance(covariance, scan.t, index)
        if scan.ids is not None and len(np.unique(scan.ids)) != len(scan.ids):
            raise InputError(f"landmark scan at t={scan.t:.6f} s repeats a landmark id")
        return points, covariances

    def _point_factor(
        self, pose_key: int, landmark_key: int, point: np.ndarray, covariance: np.ndarray
    ) -> gtsam.NonlinearFactor:
        if self.dimension == 2:
            return body_point_factor_2d(pose_key, landmark_key, point, covariance)
        if self.config.landmark_factor == "cartesian":
            return cartesian_point_factor_3d(pose_key, landmark_key, point, covariance)
        return body_point_factor_3d(pose_key, landmark_key, point, covariance)

    def _add_scan(self, k: int, scan: LandmarkScan) -> None:
        points, covariances = self._check_scan(scan)
        values = self._current_values()
        pose = self.motion.pose_of(values, k)
        use_ids = scan.ids is not None and self.config.association in ("auto", "ids")
        if self.config.association == "ids" and scan.ids is None:
            raise InputError(f"landmark scan at t={scan.t:.6f} s has no ids but association=ids")
        if use_ids:
            map_ids = [int(i) for i in scan.ids]  # type: ignore[union-attr]
        else:
            map_ids = self._associate(scan, points, covariances, pose, values)
        for index, (map_id, point, covariance) in enumerate(zip(map_ids, points, covariances)):
            if map_id == -2:  # ambiguous under JCBB: neither used nor a new landmark
                self.recorder.association(scan.t, index, -1, AssociationDecision.AMBIGUOUS)
                continue
            landmark = self.landmarks.get(map_id) if map_id >= 0 else None
            is_new = landmark is None or not self._key_alive(landmark.key)
            if is_new:
                if map_id < 0:
                    map_id = self.next_map_id
                    self.next_map_id += 1
                if self.dimension == 3 and np.linalg.norm(point) < 1e-3:
                    self.recorder.association(
                        scan.t, index, -1, AssociationDecision.REJECTED, "at the sensor origin"
                    )
                    continue
                world = pose.transformFrom(point)
                landmark = self._new_landmark(map_id, np.asarray(world, dtype=float), scan.t)
                self.first_sightings[landmark.key] = (k, np.asarray(point, dtype=float))
                if landmark.anchor_position is not None:  # a re-created anchor keeps its prior
                    self.pending_graph.add(
                        landmark_prior(
                            landmark.key, landmark.anchor_position, self.config.anchor_sigma_m
                        )
                    )
            assert landmark is not None
            self.pending_graph.add(
                self._point_factor(self.motion.pose_key(k), landmark.key, point, covariance)
            )
            landmark.observations += 1
            landmark.last_t = scan.t
            self.pending_times[landmark.key] = float(scan.t)
            decision = AssociationDecision.NEW if is_new else AssociationDecision.MATCHED
            self.recorder.association(scan.t, index, map_id, decision)
        self.recorder.landmark_count(
            scan.t, sum(1 for lm in self.landmarks.values() if self._key_alive(lm.key))
        )

    def _key_alive(self, key: int) -> bool:
        return self.pending_values.exists(key) or self.backend.contains(key)

    # ------------------------------------------------------------------ association
    def _associate(
        self,
        scan: LandmarkScan,
        points: np.ndarray,
        covariances: np.ndarray,
        pose,
        values: gtsam.Values,
    ) -> list[int]:
        """JCBB against the current map: map id per point, -1 new, -2 ambiguous."""
        from filters.association import associate_jcbb

        d = self.dimension
        # Landmarks created by another scan of this same time stamp are not solved yet.
        alive = [lm for lm in self.landmarks.values() if self.backend.contains(lm.key)]
        if not alive or len(points) == 0:
            return [-1] * len(points)
        current = self.backend.values([lm.key for lm in alive])
        positions = np.array(
            [current.atPoint3(lm.key) if d == 3 else current.atPoint2(lm.key) for lm in alive]
        )
        rotation = pose.rotation().matrix()
        translation = pose.translation()
        predicted = (positions - translation) @ rotation
        reach = float(np.max(np.linalg.norm(points, axis=1))) * 1.5 + 5.0
        near = np.linalg.norm(predicted, axis=1) < reach
        if not np.any(near):
            return [-1] * len(points)
        candidates = [lm for lm, ok in zip(alive, near) if ok]
        predicted = predicted[near]
        k = len(self.keyframe_t) - 1
        pose_key = self.motion.pose_key(k)
        joint = self._joint_covariance([pose_key] + [lm.key for lm in candidates])
        pose_dof = 6 if d == 3 else 3
        # Predicted measurement h_i = R^T (rho_i - r): H_i = [dh/dpose, R^T] on (pose, rho_i).
        jacobian = np.zeros((len(candidates) * d, pose_dof + len(candidates) * d))
        for i, h in enumerate(predicted):
            rows = slice(i * d, (i + 1) * d)
            if d == 3:
                skew = np.array([[0.0, -h[2], h[1]], [h[2], 0.0, -h[0]], [-h[1], h[0], 0.0]])
                jacobian[rows, :pose_dof] = np.hstack([skew, -np.eye(3)])
            else:
                jacobian[rows, :pose_dof] = np.hstack(
                    [-np.eye(2), (-np.array([[0.0, -1.0], [1.0, 0.0]]) @ h)[:, None]]
                )
            jacobian[rows, pose_dof + i * d : pose_dof + (i + 1) * d] = rotation.T
        predicted_cov = jacobian @ joint @ jacobian.T
        predicted_cov = 0.5 * (predicted_cov + predicted_cov.T)
        blocks = predicted_cov
        result = associate_jcbb(
            points, covariances, predicted, blocks, gate_probability=self.config.gate_probability
        )
        out = []
        for j, index in enumerate(result.assignments):
            if index >= 0:
                out.append(candidates[int(index)].map_id)
                self.recorder.nis(scan.t, float(result.individual_nis[j]), d)
            elif result.candidate_counts[j] > 0:
                out.append(-2)
            else:
                out.append(-1)
        return out

    def _joint_covariance(self, keys: list[int]) -> np.ndarray:
        """Joint marginal covariance of ``keys`` (iSAM2), or block-diagonal marginals
        (fixed lag, whose Python API has no joint marginal: cross-covariances neglected)."""
        joint = getattr(self.backend, "joint_marginal_covariance", None)
        if joint is not None:
            return joint(keys)
        blocks = [self.backend.marginal_covariance(key) for key in keys]
        size = sum(block.shape[0] for block in blocks)
        full = np.zeros((size, size))
        offset = 0
        for block in blocks:
            n = block.shape[0]
            full[offset : offset + n, offset : offset + n] = block
            offset += n
        return full

    # ------------------------------------------------------------------ output
    def _flush(self) -> None:
        if self.group is not None:
            self._commit_group()
        if self.pending_graph.size() or self.pending_values.size():
            self._update(self.keyframe_t[-1])

    def landmark_map(self, values: gtsam.Values, marginals) -> LandmarkMap:
        """World-frame map of the landmarks whose variables ``values`` holds."""
        ids, positions, covariances = [], [], []
        for landmark in sorted(self.landmarks.values(), key=lambda lm: lm.map_id):
            if not values.exists(landmark.key):
                continue
            ids.append(landmark.map_id)
            positions.append(
                values.atPoint3(landmark.key)
                if self.dimension == 3
                else values.atPoint2(landmark.key)
            )
            covariances.append(vector_covariance(marginals.marginalCovariance(landmark.key)))
        if not ids:
            return LandmarkMap.empty(self.dimension)
        return LandmarkMap(
            np.array(ids, dtype=int), np.array(positions), np.array(covariances), Frame.WORLD
        )

    def smoothed_history(self, values: gtsam.Values, marginals) -> StateHistory:
        recorder = EstimateRecorder(self.dimension)
        for k, t in enumerate(self.keyframe_t):
            self.motion.record(recorder, t, values, k, marginals)
        return recorder.history()

    def estimate(self) -> Estimate:  # pragma: no cover - subclasses
        raise NotImplementedError


class _BackendMarginals:
    """Adapter: ``marginalCovariance(key)`` of a backend."""

    def __init__(self, backend) -> None:
        self.backend = backend

    def marginalCovariance(self, key: int) -> np.ndarray:
        return self.backend.marginal_covariance(key)
