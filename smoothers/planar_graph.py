"""Planar (Pose2 + Point2) motion factors between keyframes.

Two motion inputs, whichever the sequence provides:

- **Odometry** (``Odometry.relative_pose`` (dx, dy, dtheta) or ``Odometry.velocity``
  (v_forward, omega)): increments are composed between keyframes into one
  ``BetweenFactorPose2`` with the composed covariance (right perturbation:
  ``Sigma_ac = Ad(b^-1) Sigma_ab Ad(b^-1)^T + Sigma_bc``). A velocity sample is held
  (zero-order hold) until the next one; its covariance is the error of the held velocity,
  so the increment over ``dt`` has covariance ``J Sigma J^T`` with ``J = [[dt, 0], [0, 0],
  [0, dt]]`` plus a lateral-slip floor ``odometry_lateral_sigma_m_s^2 dt^2`` (a unicycle
  cannot move sideways, a real one slips a little, and a zero row would make the factor
  degenerate).

- **Gyro only** (``GyroSample``, e.g. ``sim:guerreiro-loop``): our documented motion model.
  Each keyframe k has a pose ``X_k`` and a 3-vector ``V_k = [v_x, v_y, b_omega]``: the
  body-frame velocity [m/s] and the rate-gyro bias [rad/s] (measured = true + bias, as in the
  sensor-based paper's state). Between keyframes, over ``dt`` with the measured rotation
  increment ``dtheta_m = sum(omega_m dt_i)``:

      e_trans = R_k^T (t_{k+1} - t_k) - Rot(phi) (v_k + v_{k+1}) dt / 2,  phi = (dtheta_m - b_k dt) / 2
                                        (body velocity a random walk, trapezoid, midpoint heading)
      e_rot   = wrap(theta_{k+1} - theta_k - (dtheta_m - b_k dt))    (rotation from the gyro)

  with covariance ``diag(q_x^2 dt^3 / 12, q_y^2 dt^3 / 12, 0) + sigma_g^2 dt u u^T``,
  ``u = [-S Rot(phi) v dt / 2; -1]`` (``S`` the planar skew matrix), and a
  ``BetweenFactorVector`` ``V_{k+1} - V_k ~ N(0, diag(q_x^2 dt, q_y^2 dt, q_b^2 dt))``
  (``q`` the velocity random-walk density per body axis, ``sigma_g`` the gyro's white
  noise). Why the trapezoid: for a velocity random walk the displacement over ``dt`` and
  the velocity change are correlated (``q^2 [[dt^3/3, dt^2/2], [dt^2/2, dt]]``, correlation
  0.87); measured against the mean of the two velocities the displacement error is
  *uncorrelated* with the velocity change and has variance ``q^2 dt^3 / 12``
  (``tests/test_smoother_factors.py`` checks both against Van Loan's ``expm``), so two
  independent factors are exact. The earlier form (``v_k`` alone, ``dt^3 / 3``, the
  correlation ignored) made the smoothers' velocity conservative: NEES 0.64 per dof on the
  calibration loop where the filters read 0.94-0.98.
  The gyro's white noise ``n`` (variance ``sigma_g^2 dt`` over the interval) enters both
  rows: ``e_rot`` as ``-n`` and ``e_trans`` through the midpoint heading as
  ``-S Rot(phi) v dt n / 2``, hence the rank-one term, fully correlated between the two
  (``u`` is evaluated at the velocity and bias estimate of ``V_k`` when the factor is made).
  The midpoint heading is bias-corrected like ``e_rot``. Both were missing before
  (``Rot(dtheta_m / 2)`` and a diagonal covariance): on the 100 s model-matched loop, whose
  lateral walk (0.0025 m/s/sqrt(s)) gives a lateral sigma of 2.3e-5 m per 0.1 s keyframe,
  the uncorrected 5 mrad/s bias moved the midpoint by 2.5e-5 m, about one sigma, always
  the same way, and the smoothers' NIS read 1.016 per dof against ekf-slam's 0.999 on the
  same runs.
  No native GTSAM factor has this form, so it is a ``CustomFactor`` with analytic
  Jacobians (tested against finite differences); gyro-only scenarios are small, and
  ``benchmarks/bench_smoother.py`` reports its cost.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np
from gtsam.symbol_shorthand import V, X

from datasets.errors import InputError
from datasets.estimate import EstimateRecorder
from datasets.measurements import GyroSample, Odometry
from datasets.model_options import IntervalRate
from datasets.rotations import PLANAR_GENERATOR, rot2, wrap_angle
from datasets.sequence import InitialState
from datasets.state import BlockName, Frame
from smoothers.covariances import MarginalSource, pose_covariance, vector_covariance
from smoothers.held_input import held_interval
from smoothers.priors import InitialPriors


def compose_increment(
    first: gtsam.Pose2, first_cov: np.ndarray, second: gtsam.Pose2, second_cov: np.ndarray
) -> tuple[gtsam.Pose2, np.ndarray]:
    """``first * second`` with its covariance in the right-perturbation tangent [x, y, theta]."""
    adjoint = second.inverse().AdjointMap()
    covariance = adjoint @ first_cov @ adjoint.T + second_cov
    return first.compose(second), 0.5 * (covariance + covariance.T)


@dataclass
class OdometryAccumulator:
    """Composes odometry between keyframes into one relative pose with covariance.

    Attributes:
        lateral_sigma_m_s: lateral-slip floor for velocity odometry [m/s].
        max_gap_s: a velocity hold longer than this is an ``InputError``.
    """

    lateral_sigma_m_s: float
    max_gap_s: float
    increment: gtsam.Pose2 = field(default_factory=gtsam.Pose2)
    covariance: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    cursor: float = 0.0
    held: Odometry | None = None
    count: int = 0

    def start(self, t: float) -> None:
        self.increment = gtsam.Pose2()
        self.covariance = np.zeros((3, 3))
        self.cursor = float(t)
        self.count = 0

    def _append(self, delta: gtsam.Pose2, covariance: np.ndarray) -> None:
        self.increment, self.covariance = compose_increment(
            self.increment, self.covariance, delta, covariance
        )
        self.count += 1

    def _integrate_velocity_until(self, t: float) -> None:
        if self.held is None or self.held.velocity is None:
            return
        dt = t - self.cursor
        if dt <= 0.0:
            return
        if t - self.held.t > self.max_gap_s:
            raise InputError(
                f"odometry gap: no sample between t={self.held.t:.6f} s and t={t:.6f} s (max gap {self.max_gap_s} s)"
            )
        v, omega = float(self.held.velocity[0]), float(self.held.velocity[1])
        jacobian = np.array([[dt, 0.0], [0.0, 0.0], [0.0, dt]])
        covariance = jacobian @ np.asarray(self.held.covariance, dtype=float)[:2, :2] @ jacobian.T
        covariance[1, 1] += (self.lateral_sigma_m_s * dt) ** 2
        self._append(gtsam.Pose2.Expmap(np.array([v * dt, 0.0, omega * dt])), covariance)
        self.cursor = t

    def add(self, odometry: Odometry) -> None:
        if odometry.relative_pose is not None:
            dx, dy, dtheta = np.asarray(odometry.relative_pose, dtype=float)[:3]
            covariance = np.asarray(odometry.covariance, dtype=float)[:3, :3]
            self._append(gtsam.Pose2(dx, dy, dtheta), covariance)
            self.cursor = odometry.t
            return
        if odometry.velocity is None:
            raise InputError(
                f"odometry at t={odometry.t:.6f} s has neither a relative pose nor a velocity"
            )
        self._integrate_velocity_until(odometry.t)
        self.held = odometry
        self.cursor = max(self.cursor, odometry.t)

    def close(self, t: float) -> tuple[gtsam.Pose2, np.ndarray]:
        """The composed increment since the last keyframe, up to ``t``."""
        self._integrate_velocity_until(t)
        if self.count == 0:
            raise InputError(f"keyframe at t={t:.6f} s: no odometry since the previous keyframe")
        return self.increment, self.covariance


@dataclass
class GyroAccumulator:
    """Integrates a rate gyro between keyframes: ``dtheta_m`` and ``dt``.

    With ``interval_rate="average"`` (default) samples are instantaneous values (the
    simulator's convention, and the filters' default): each sub-interval takes the straight
    line between the held sample and the next one at its midpoint, i.e. the mean of the two
    samples over a whole interval. The next sample is the one being added, or ``lookahead``
    when a keyframe is closed between two samples. ``"hold"``: zero-order hold, first order
    in the sample interval; ``"latest"``: the next sample. Measured on the 10 Hz gyro of ``sim:guerreiro-loop`` (one
    sample per keyframe; noise-free data, the truth's states): the hold's rotation residual
    alone read 0.48 per keyframe in units of the stated gyro variance, 1.39 with the noise,
    so the heading was optimistic and the smoothers' NIS read 1.016 per dof against
    ekf-slam's 0.999 on the same runs."""

    max_gap_s: float
    interval_rate: IntervalRate = "average"
    cursor: float = 0.0
    held_t: float | None = None
    held_rate: float = 0.0
    dtheta: float = 0.0
    elapsed: float = 0.0
    lookahead: tuple[float, float] | None = None

    def start(self, t: float) -> None:
        self.cursor = float(t)
        self.dtheta = 0.0
        self.elapsed = 0.0

    def _integrate_until(self, t: float, following: tuple[float, float] | None) -> None:
        dt = held_interval(self.cursor, self.held_t, t, self.max_gap_s, "gyro")
        if dt <= 0.0:
            return
        assert self.held_t is not None
        rate = self.held_rate
        later = following is not None and following[0] > self.held_t
        if self.interval_rate == "average" and later:
            next_t, next_rate = following
            weight = (0.5 * (self.cursor + t) - self.held_t) / (next_t - self.held_t)
            rate = rate + weight * (next_rate - rate)
        elif self.interval_rate == "latest" and later:
            rate = following[1]
        self.dtheta += rate * dt
        self.elapsed += dt
        self.cursor = t

    def add(self, sample: GyroSample) -> None:
        rate = float(np.asarray(sample.rate, dtype=float).ravel()[-1])
        if self.held_t is None:
            self.held_t, self.held_rate = float(sample.t), rate
        self._integrate_until(sample.t, (float(sample.t), rate))
        self.held_t, self.held_rate = float(sample.t), rate
        self.lookahead = None

    def close(self, t: float) -> tuple[float, float]:
        """(dtheta_m [rad], dt [s]) since the last keyframe, up to ``t``."""
        if self.held_t is None:
            raise InputError(f"keyframe at t={t:.6f} s: no gyro sample has arrived")
        self._integrate_until(t, self.lookahead)
        return self.dtheta, self.elapsed


def constant_velocity_error(
    pose_k: gtsam.Pose2,
    pose_next: gtsam.Pose2,
    state_k: np.ndarray,
    state_next: np.ndarray,
    dtheta_m: float,
    dt: float,
) -> tuple[np.ndarray, list[np.ndarray]]:
    """Residual (3,) of the gyro-only motion model and its Jacobians (3x3 each, with respect
    to ``X_k``, ``X_{k+1}``, ``V_k``, ``V_{k+1}``).

    See the module docstring; pose Jacobians are with respect to GTSAM's Pose2 tangent (right
    perturbation, [x, y, theta]), ``V = [v_x, v_y, b_omega]``.
    """
    rotation_k = pose_k.rotation().matrix()
    delta_world = pose_next.translation() - pose_k.translation()
    delta_body = rotation_k.T @ delta_world
    bias = float(state_k[2])
    midpoint = rot2(midpoint_angle(dtheta_m, bias, dt))
    velocity = 0.5 * (state_k[:2] + state_next[:2])
    error = np.empty(3)
    error[:2] = delta_body - midpoint @ velocity * dt
    error[2] = float(wrap_angle(pose_next.theta() - pose_k.theta() - (dtheta_m - bias * dt)))
    d_pose_k = np.zeros((3, 3))
    d_pose_k[:2, :2] = -np.eye(2)
    d_pose_k[:2, 2] = -PLANAR_GENERATOR @ delta_body
    d_pose_k[2, 2] = -1.0
    d_pose_next = np.zeros((3, 3))
    d_pose_next[:2, :2] = rotation_k.T @ pose_next.rotation().matrix()
    d_pose_next[2, 2] = 1.0
    d_state_k = np.zeros((3, 3))
    d_state_k[:2, :2] = -0.5 * midpoint * dt
    d_state_k[:2, 2] = 0.5 * dt**2 * PLANAR_GENERATOR @ midpoint @ velocity
    d_state_k[2, 2] = dt
    d_state_next = np.zeros((3, 3))
    d_state_next[:2, :2] = -0.5 * midpoint * dt
    return error, [d_pose_k, d_pose_next, d_state_k, d_state_next]


def midpoint_angle(dtheta_m: float, bias: float, dt: float) -> float:
    """Heading of the interval's midpoint relative to ``X_k`` [rad]: half the bias-corrected
    measured rotation."""
    return 0.5 * (dtheta_m - bias * dt)


def motion_factor_covariance(
    dtheta_m: float,
    dt: float,
    velocity_walk: np.ndarray,
    gyro_density: float,
    state_estimate: np.ndarray,
) -> np.ndarray:
    """Covariance (3, 3) of the gyro-only motion residual [e_x, e_y, e_theta] (module
    docstring): the velocity walk's ``q^2 dt^3 / 12`` per body axis plus the gyro noise
    ``sigma_g^2 dt u u^T`` with ``u = [-S Rot(phi) v dt / 2; -1]`` at ``state_estimate``
    ``[v_x, v_y, b]``; plus 1e-12 on the diagonal (a zero density would make the factor a
    constraint)."""
    state_estimate = np.asarray(state_estimate, dtype=float)
    phi = midpoint_angle(dtheta_m, float(state_estimate[2]), dt)
    u = np.append(-0.5 * dt * PLANAR_GENERATOR @ rot2(phi) @ state_estimate[:2], -1.0)
    covariance = gyro_density**2 * dt * np.outer(u, u)
    covariance[:2, :2] += np.diag(
        np.broadcast_to(np.asarray(velocity_walk, float), (2,)) ** 2 * dt**3 / 12.0
    )
    return covariance + 1e-12 * np.eye(3)


def constant_velocity_factor(
    pose_key: int,
    next_pose_key: int,
    state_key: int,
    next_state_key: int,
    dtheta_m: float,
    dt: float,
    velocity_walk: np.ndarray,
    gyro_density: float,
    state_estimate: np.ndarray,
) -> gtsam.CustomFactor:
    """The gyro-only motion factor between ``X_k``, ``X_{k+1}``, ``V_k`` and ``V_{k+1}``
    (module docstring); ``velocity_walk`` (2,) per body axis [forward, lateral] (variances
    floored at 1e-12: a zero density would make the factor a constraint);
    ``state_estimate`` (3,) the current ``V_k`` estimate, for the gyro noise's share of the
    displacement (``motion_factor_covariance``)."""
    noise = gtsam.noiseModel.Gaussian.Covariance(
        motion_factor_covariance(dtheta_m, dt, velocity_walk, gyro_density, state_estimate)
    )

    def error(
        factor: gtsam.CustomFactor, values: gtsam.Values, jacobians: list | None
    ) -> np.ndarray:
        keys = factor.keys()
        residual, blocks = constant_velocity_error(
            values.atPose2(keys[0]),
            values.atPose2(keys[1]),
            values.atVector(keys[2]),
            values.atVector(keys[3]),
            dtheta_m,
            dt,
        )
        if jacobians is not None:
            for index, block in enumerate(blocks):
                jacobians[index] = block
        return residual

    return gtsam.CustomFactor(noise, [pose_key, next_pose_key, state_key, next_state_key], error)


def predict_constant_velocity(
    pose_k: gtsam.Pose2, state_k: np.ndarray, dtheta_m: float, dt: float
) -> gtsam.Pose2:
    """The motion model's mean: the pose at ``k+1`` from ``X_k``, ``V_k`` and the gyro."""
    midpoint = rot2(midpoint_angle(dtheta_m, float(state_k[2]), dt))
    translation = pose_k.translation() + pose_k.rotation().matrix() @ midpoint @ state_k[:2] * dt
    return gtsam.Pose2(
        translation[0], translation[1], pose_k.theta() + dtheta_m - float(state_k[2]) * dt
    )


class PlanarMotion:
    """2-D keyframe motion model: ``X_k`` (Pose2), and with a gyro only also ``V_k``.

    Args:
        source: ``"odometry"`` or ``"gyro"`` (chosen from the sequence's sensors, odometry
            first).
        velocity_walk: ``q_v`` of the gyro-only model per body axis [forward, lateral]
            [m/s^2/sqrt(Hz)], shape (2,).
        gyro_density: rate-gyro white-noise density [rad/s/sqrt(Hz)].
        gyro_bias_walk: ``q_b`` [rad/s^2/sqrt(Hz)].
        lateral_sigma_m_s: lateral-slip floor of velocity odometry [m/s].
        max_gap_s: longest allowed hold of a motion sample [s].
        interval_rate: the gyro's rate over an interval (``GyroAccumulator``).
    """

    dimension = 2

    def __init__(
        self,
        source: str,
        velocity_walk: np.ndarray,
        gyro_density: float,
        gyro_bias_walk: float,
        lateral_sigma_m_s: float,
        max_gap_s: float,
        interval_rate: IntervalRate = "average",
    ) -> None:
        self.source = source
        self.velocity_walk = velocity_walk
        self.gyro_density = gyro_density
        self.gyro_bias_walk = gyro_bias_walk
        self.odometry = OdometryAccumulator(lateral_sigma_m_s, max_gap_s)
        self.gyro = GyroAccumulator(max_gap_s, interval_rate)
        self.increments: dict[int, tuple] = {}

    def keys(self, k: int) -> list[int]:
        return [X(k), V(k)] if self.source == "gyro" else [X(k)]

    @staticmethod
    def pose_key(k: int) -> int:
        return X(k)

    def accepts(self, measurement: object) -> bool:
        if self.source == "gyro":
            return isinstance(measurement, GyroSample)
        return isinstance(measurement, Odometry)

    def look_ahead(self, measurement: GyroSample | Odometry) -> None:
        """The next gyro sample, known before a keyframe between it and the held one is
        closed (odometry increments are held: they are interval values)."""
        if isinstance(measurement, GyroSample):
            rate = float(np.asarray(measurement.rate, dtype=float).ravel()[-1])
            self.gyro.lookahead = (float(measurement.t), rate)

    def add(self, measurement: GyroSample | Odometry) -> bool:
        if isinstance(measurement, GyroSample):
            if not np.all(np.isfinite(measurement.rate)):
                raise InputError(f"non-finite gyro sample at t={measurement.t:.6f} s")
            self.gyro.add(measurement)
        else:
            self.odometry.add(measurement)
        return True

    def initial(
        self, start: InitialState, priors: InitialPriors
    ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
        position = np.asarray(start.position, dtype=float)
        heading = float(np.asarray(start.rotation, dtype=float))
        pose = gtsam.Pose2(position[0], position[1], heading)
        graph = gtsam.NonlinearFactorGraph()
        sigmas = np.array(
            [priors.position_sigma_m, priors.position_sigma_m, priors.rotation_sigma_rad]
        )
        graph.add(gtsam.PriorFactorPose2(X(0), pose, gtsam.noiseModel.Diagonal.Sigmas(sigmas)))
        values = gtsam.Values()
        values.insert(X(0), pose)
        if self.source == "gyro":
            world_velocity = (
                np.zeros(2) if start.velocity is None else np.asarray(start.velocity, dtype=float)
            )
            state = np.r_[rot2(heading).T @ world_velocity, 0.0]
            state_sigmas = np.array(
                [priors.velocity_sigma_m_s] * 2 + [priors.gyro_bias_sigma_rad_s]
            )
            graph.add(
                gtsam.PriorFactorVector(V(0), state, gtsam.noiseModel.Diagonal.Sigmas(state_sigmas))
            )
            values.insert(V(0), state)
            self.gyro.start(start.t)
        else:
            self.odometry.start(start.t)
        return graph, values

    def close(
        self, k: int, t: float, estimate: gtsam.Values
    ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        previous = estimate.atPose2(X(k - 1))
        if self.source == "gyro":
            dtheta, dt = self.gyro.close(t)
            self.increments[k] = (dtheta, dt)
            if dt <= 0.0:
                raise InputError(
                    f"keyframe at t={t:.6f} s: no gyro time since the previous keyframe"
                )
            state = estimate.atVector(V(k - 1))
            graph.add(
                constant_velocity_factor(
                    X(k - 1),
                    X(k),
                    V(k - 1),
                    V(k),
                    dtheta,
                    dt,
                    self.velocity_walk,
                    self.gyro_density,
                    state,
                )
            )
            walk = np.sqrt(
                np.maximum([*(self.velocity_walk**2 * dt), self.gyro_bias_walk**2 * dt], 1e-12)
            )
            graph.add(
                gtsam.BetweenFactorVector(
                    V(k - 1), V(k), np.zeros(3), gtsam.noiseModel.Diagonal.Sigmas(walk)
                )
            )
            values.insert(X(k), predict_constant_velocity(previous, state, dtheta, dt))
            values.insert(V(k), state)
        else:
            increment, covariance = self.odometry.close(t)
            self.increments[k] = (increment,)
            covariance = covariance + np.eye(3) * 1e-12
            graph.add(
                gtsam.BetweenFactorPose2(
                    X(k - 1), X(k), increment, gtsam.noiseModel.Gaussian.Covariance(covariance)
                )
            )
            values.insert(X(k), previous.compose(increment))
        return graph, values

    def dead_reckoning_step(self, k: int, values: gtsam.Values) -> gtsam.Values:
        """Open-loop state of keyframe ``k`` from ``k-1`` in ``values``."""
        step = gtsam.Values()
        previous = values.atPose2(X(k - 1))
        if self.source == "gyro":
            dtheta, dt = self.increments[k]
            state = values.atVector(V(k - 1))
            step.insert(X(k), predict_constant_velocity(previous, state, dtheta, dt))
            step.insert(V(k), state)
        else:
            step.insert(X(k), previous.compose(self.increments[k][0]))
        return step

    def restart(self, t: float, estimate: gtsam.Values, k: int) -> None:
        if self.source == "gyro":
            self.gyro.start(t)
        else:
            self.odometry.start(t)

    def since_keyframe(self) -> int:
        return self.odometry.count if self.source == "odometry" else int(self.gyro.elapsed > 0)

    @staticmethod
    def pose_of(values: gtsam.Values, k: int) -> gtsam.Pose2:
        return values.atPose2(X(k))

    def record(
        self,
        recorder: EstimateRecorder,
        t: float,
        values: gtsam.Values,
        k: int,
        marginals: MarginalSource | None,
    ) -> None:
        """Pose [x, y, theta] (and, gyro-only, body velocity and gyro bias) of keyframe ``k``."""
        pose = values.atPose2(X(k))
        pose_cov = (
            None if marginals is None else pose_covariance(marginals.marginalCovariance(X(k)))
        )
        recorder.pose(t, pose.translation(), pose.theta(), pose_cov)
        if self.source == "gyro":
            state = values.atVector(V(k))
            state_cov = (
                None if marginals is None else vector_covariance(marginals.marginalCovariance(V(k)))
            )
            recorder.block(
                BlockName.VELOCITY,
                t,
                state[:2],
                None if state_cov is None else state_cov[:2, :2],
                Frame.BODY,
            )
            recorder.block(
                BlockName.GYRO_BIAS,
                t,
                state[2:3],
                None if state_cov is None else state_cov[2:3, 2:3],
                Frame.BODY,
            )
