"""Planar (Pose2 + Point2) motion factors between keyframes: ``PlanarMotion``, the keyframe
smoother's 2-D motion model, from whichever motion input the sequence provides:

- **Odometry** (``Odometry.relative_pose`` (dx, dy, dtheta) or ``Odometry.velocity``
  (v_forward, omega)): increments composed between keyframes into one
  ``BetweenFactorPose2`` with the composed covariance (``smoothers.planar_odometry``).
- **Gyro only** (``GyroSample``, e.g. ``sim:guerreiro-loop``): our documented motion model,
  a pose ``X_k`` and ``V_k = [v_x, v_y, b_omega]`` per keyframe, the rate gyro integrated
  between keyframes (``smoothers.gyro_integration``) into a constant-velocity
  ``CustomFactor`` and a ``BetweenFactorVector`` random walk of ``V``
  (``smoothers.gyro_motion_factor``: the model, its covariance and why).

This module owns the keys, the priors of keyframe 0, each new keyframe's factors and
initial values, dead reckoning, and the recorded blocks.
"""

from __future__ import annotations

import gtsam
import numpy as np
from gtsam.symbol_shorthand import V, X

from datasets.errors import InputError
from datasets.estimate import EstimateRecorder
from datasets.measurements import GyroSample, Odometry
from datasets.model_options import IntervalRate
from datasets.rotations import rot2
from datasets.sequence import InitialState
from datasets.state import BlockName, Frame
from smoothers.covariances import MarginalSource, pose_covariance, vector_covariance
from smoothers.gyro_integration import GyroAccumulator
from smoothers.gyro_motion_factor import (
    constant_velocity_factor,
    predict_constant_velocity,
)
from smoothers.planar_odometry import OdometryAccumulator
from smoothers.priors import InitialPriors


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
