"""IMU preintegration between keyframes: ``CombinedImuFactor`` (bias random walk inside).

Conventions (DESIGN.md, and GTSAM's own):
- noise densities are continuous-time; GTSAM's ``set*Covariance`` take exactly the squared
  continuous densities and divide by ``dt`` internally, so no conversion is applied here;
- measured = true + bias (GTSAM's ``ConstantBias``: ``correctAccelerometer(a) = a - b_a``);
- gravity is an acceleration (0, 0, -g) in a z-up world: ``MakeSharedU(g)``;
- ``ConstantBias.vector()`` is ordered [accelerometer, gyroscope].

Sample timing: samples are instantaneous values; over ``[t_i, t_{i+1})`` the value used is
the straight line between the two samples at the sub-interval's midpoint (zero-order hold of
``t_i``'s sample with ``interval_rate=hold``), and the specific force is applied at the
sub-interval's mid-attitude (``specific_force_at_step_start``). A keyframe that falls between
two samples splits that interval, so every keyframe sits at the exact time of its measurement.

A known, small inconsistency of this rule: a keyframe at a sample time shares that sample
between the factor before it and the one after it, while GTSAM models the two factors as
independent, each with the continuous density's covariance. Causal estimates (which sum the
increments) are unaffected to about 1 %; a *smoothed* velocity (which differences them)
reads conservative, the more so the fewer samples per keyframe: about 0.96 per dof at 2
samples per keyframe (``sim:aghili-rover``, 20 Hz IMU), 0.99 at 10. Exact figures for a
linear stand-in: ``python benchmarks/imu_interpolation_correlation.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np
from gtsam.symbol_shorthand import B, V, X

from datasets.errors import InputError
from datasets.estimate import EstimateRecorder
from datasets.measurements import ImuSample
from datasets.model_options import IntervalRate
from datasets.rotations import matrix_from_quat_wxyz, quat_wxyz_from_matrix
from datasets.sequence import InitialState, NoiseSpec
from datasets.state import BlockName, Frame
from smoothers.covariances import (
    MarginalSource,
    bias_covariances,
    pose_covariance,
    vector_covariance,
)
from smoothers.held_input import held_interval
from smoothers.priors import InitialPriors


@dataclass(frozen=True)
class ImuNoise:
    """Continuous-time IMU noise used by the preintegration (GTSAM's parameters).

    Attributes:
        gyro_noise_density: [rad/s/sqrt(Hz)].
        accel_noise_density: [m/s^2/sqrt(Hz)].
        gyro_bias_walk: [rad/s^2/sqrt(Hz)].
        accel_bias_walk: [m/s^3/sqrt(Hz)].
        integration_sigma: position integration error density (GTSAM's integration
            covariance; a small regulariser) [m/s/sqrt(Hz)].
    """

    gyro_noise_density: float
    accel_noise_density: float
    gyro_bias_walk: float
    accel_bias_walk: float
    integration_sigma: float = 1e-4

    @staticmethod
    def from_spec(spec: NoiseSpec, where: str) -> ImuNoise:
        """Take the densities from a ``NoiseSpec``; ``InputError`` naming a missing one."""
        values = {
            "gyro_noise_density": spec.gyro_noise_density,
            "accel_noise_density": spec.accel_noise_density,
            "gyro_bias_walk": spec.gyro_bias_walk,
            "accel_bias_walk": spec.accel_bias_walk,
        }
        missing = [
            name
            for name, value in values.items()
            if value is None or not np.isfinite(value) or value <= 0
        ]
        if missing:
            raise InputError(
                f"{where}: the smoother needs positive IMU noise densities; missing or invalid: {', '.join(missing)}"
            )
        return ImuNoise(**{name: float(value) for name, value in values.items()})  # type: ignore[arg-type]


def combined_params(noise: ImuNoise, gravity_m_s2: float) -> gtsam.PreintegrationCombinedParams:
    """GTSAM ``PreintegrationCombinedParams`` for a z-up world with gravity (0, 0, -g)."""
    params = gtsam.PreintegrationCombinedParams.MakeSharedU(gravity_m_s2)
    params.setGyroscopeCovariance(np.eye(3) * noise.gyro_noise_density**2)
    params.setAccelerometerCovariance(np.eye(3) * noise.accel_noise_density**2)
    params.setBiasOmegaCovariance(np.eye(3) * noise.gyro_bias_walk**2)
    params.setBiasAccCovariance(np.eye(3) * noise.accel_bias_walk**2)
    params.setIntegrationCovariance(np.eye(3) * noise.integration_sigma**2)
    return params


def specific_force_at_step_start(
    accel: np.ndarray, gyro: np.ndarray, dt: float, bias: gtsam.imuBias.ConstantBias
) -> np.ndarray:
    """The specific force to hand GTSAM so that it is applied at the step's mid-attitude.

    GTSAM's preintegration rotates a step's specific force by the attitude at the *start* of
    the step (``deltaVij += deltaRik a dt``; checked: one step of 0.5 s at 1 rad/s about z
    with a = (1, 0, 0) gives deltaV = (0.5, 0, 0), the exact integral being
    (sin 0.5, 1 - cos 0.5, 0)), which is first order in dt however well the sample itself
    is interpolated. Over a step the body turns by (omega - b_g) dt; rotating the unbiased
    specific force by half of that turn, ``Exp((omega - b_g) dt / 2) (a - b_a) + b_a``,
    makes GTSAM apply it at the mid-attitude: second order, the midpoint rule. On the
    noise-free ``sim:aghili-rover`` (20 Hz IMU, 60 s) the start-attitude rule alone put
    iSAM2's smoothed attitude NEES at 1.66 (3 dof) and the smoothers read optimistic on
    every rover row of the consistency suite (smoothed attitude 2.4 per dof at 20 Hz).

    The noise is isotropic, so its covariance is unchanged; the bias Jacobians GTSAM keeps
    are off by the half turn (a first-order term in dt), as its own are.

    Args:
        accel: the step's specific force [m/s^2], shape (3,).
        gyro: the step's angular rate [rad/s], shape (3,).
        dt: the step [s].
        bias: the bias the preintegration is linearised at.

    Returns:
        The specific force to pass to ``integrateMeasurement`` [m/s^2], shape (3,).
    """
    accel_bias = bias.accelerometer()
    half_turn = gtsam.Rot3.Expmap((gyro - bias.gyroscope()) * (0.5 * dt))
    return half_turn.rotate(accel - accel_bias) + accel_bias


@dataclass
class KeyframeImuIntegrator:
    """Accumulates IMU samples into a preintegration since the last keyframe.

    ``add(t, gyro, accel)`` integrates the *previous* sample over ``[cursor, t)`` and holds the
    new one; ``close(t_k)`` integrates the held sample up to ``t_k`` and returns the
    preintegrated measurement of ``[t_prev_keyframe, t_k]``, then starts a new one.

    With ``interval_rate="average"`` (default) the value used over a sub-interval is the
    linear interpolation between the held sample and the next one at the sub-interval's
    midpoint (samples are instantaneous values, e.g. the simulator's), which needs the next
    sample: ``lookahead`` is set by the smoother before it closes a keyframe (keyframes are
    committed only once the stream has moved past their time). ``"hold"``: zero-order hold;
    ``"latest"``: the next sample (samples are averages over the interval ending at them).
    Without a next sample (the end of the stream) both hold.

    Attributes:
        params: GTSAM preintegration parameters.
        max_gap_s: a hold longer than this is an ``InputError`` (an IMU outage).
    """

    params: gtsam.PreintegrationCombinedParams
    max_gap_s: float
    cursor: float = 0.0
    held_t: float | None = None
    held_gyro: np.ndarray = field(default_factory=lambda: np.zeros(3))
    held_accel: np.ndarray = field(default_factory=lambda: np.zeros(3))
    pim: gtsam.PreintegratedCombinedMeasurements | None = None
    integrated_s: float = 0.0
    samples_since_keyframe: int = 0
    interval_rate: IntervalRate = "average"
    lookahead: tuple[float, np.ndarray, np.ndarray] | None = None

    def start(self, t: float, bias: gtsam.imuBias.ConstantBias) -> None:
        """Begin a new preintegration at keyframe time ``t`` linearised at ``bias``."""
        self.cursor = float(t)
        self.pim = gtsam.PreintegratedCombinedMeasurements(self.params, bias)
        self.integrated_s = 0.0
        self.samples_since_keyframe = 0

    def _integrate_until(self, t: float) -> None:
        dt = held_interval(self.cursor, self.held_t, t, self.max_gap_s, "IMU")
        if dt <= 0.0:
            return
        assert self.pim is not None and self.held_t is not None
        gyro, accel = self.held_gyro, self.held_accel
        following = self.lookahead is not None and self.lookahead[0] > self.held_t
        if self.interval_rate == "average" and following:
            # Samples are instantaneous values: use the straight line between this sample
            # and the next one at the sub-interval's midpoint (second-order accurate).
            next_t, next_gyro, next_accel = self.lookahead
            weight = (0.5 * (self.cursor + t) - self.held_t) / (next_t - self.held_t)
            gyro = gyro + weight * (next_gyro - gyro)
            accel = accel + weight * (next_accel - accel)
        elif self.interval_rate == "latest" and following:
            _, gyro, accel = self.lookahead
        accel = specific_force_at_step_start(accel, gyro, dt, self.pim.biasHat())
        self.pim.integrateMeasurement(accel, gyro, dt)
        self.integrated_s += dt
        self.cursor = t

    def _hold(self, t: float, gyro: np.ndarray, accel: np.ndarray) -> None:
        self.held_t = float(t)
        self.held_gyro = np.asarray(gyro, dtype=float)
        self.held_accel = np.asarray(accel, dtype=float)

    def add(self, t: float, gyro: np.ndarray, accel: np.ndarray) -> bool:
        """Hold a new sample; returns False (and ignores it) for a repeated timestamp."""
        if self.held_t is not None and t == self.held_t:
            return False
        if self.held_t is None:
            if t - self.cursor > self.max_gap_s:
                raise InputError(
                    f"IMU gap: first sample at t={t:.6f} s, {t - self.cursor:.3f} s after the start "
                    f"(max_gap_s={self.max_gap_s})"
                )
            # The first sample also covers the short stretch from the start to itself.
            self._hold(t, gyro, accel)
            self._integrate_until(t)
        else:
            self.lookahead = (
                float(t),
                np.asarray(gyro, dtype=float),
                np.asarray(accel, dtype=float),
            )
            self._integrate_until(t)
            self._hold(t, gyro, accel)
        self.lookahead = None
        self.samples_since_keyframe += 1
        return True

    def close(self, t: float) -> gtsam.PreintegratedCombinedMeasurements:
        """Integrate up to keyframe time ``t`` and return the finished preintegration."""
        if self.held_t is None:
            raise InputError(
                f"a keyframe at t={t:.6f} s needs IMU samples before it; none has arrived"
            )
        self._integrate_until(t)
        assert self.pim is not None
        if self.integrated_s <= 0.0:
            raise InputError(f"keyframe at t={t:.6f} s has no IMU time since the previous keyframe")
        return self.pim


def navstate_prior_sigmas(rotation_sigma_rad: float, position_sigma_m: float) -> np.ndarray:
    """Pose3 prior sigmas in GTSAM's tangent order [rotation, translation], shape (6,)."""
    return np.array([rotation_sigma_rad] * 3 + [position_sigma_m] * 3)


def bias_prior_sigmas(accel_sigma_m_s2: float, gyro_sigma_rad_s: float) -> np.ndarray:
    """ConstantBias prior sigmas in GTSAM's order [accelerometer, gyroscope], shape (6,)."""
    return np.array([accel_sigma_m_s2] * 3 + [gyro_sigma_rad_s] * 3)


class ImuMotion:
    """3-D keyframe motion model: ``X_k`` (Pose3), ``V_k`` (world velocity), ``B_k`` (bias),
    linked by one ``CombinedImuFactor`` per keyframe interval (bias random walk inside)."""

    dimension = 3

    def __init__(
        self,
        noise: ImuNoise,
        gravity_m_s2: float,
        max_gap_s: float,
        interval_rate: IntervalRate = "average",
    ) -> None:
        self.params = combined_params(noise, gravity_m_s2)
        self.integrator = KeyframeImuIntegrator(self.params, max_gap_s, interval_rate=interval_rate)
        self.preintegrations: dict[int, gtsam.PreintegratedCombinedMeasurements] = {}

    @staticmethod
    def keys(k: int) -> list[int]:
        return [X(k), V(k), B(k)]

    @staticmethod
    def pose_key(k: int) -> int:
        return X(k)

    def accepts(self, measurement: object) -> bool:
        return isinstance(measurement, ImuSample)

    def look_ahead(self, sample: ImuSample) -> None:
        """The next sample, known before a keyframe between it and the held one is closed."""
        self.integrator.lookahead = (
            float(sample.t),
            np.asarray(sample.gyro, dtype=float),
            np.asarray(sample.accel, dtype=float),
        )

    def add(self, sample: ImuSample) -> bool:
        """Take one IMU sample; False for a repeat of the previous sample's time."""
        if not (np.all(np.isfinite(sample.gyro)) and np.all(np.isfinite(sample.accel))):
            raise InputError(f"non-finite IMU sample at t={sample.t:.6f} s")
        return self.integrator.add(sample.t, sample.gyro, sample.accel)

    def initial(
        self, start: InitialState, priors: InitialPriors
    ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
        """Variables and priors of keyframe 0 at ``start.t``."""
        pose = gtsam.Pose3(
            gtsam.Rot3(matrix_from_quat_wxyz(start.rotation)),
            np.asarray(start.position, dtype=float),
        )
        velocity = (
            np.zeros(3) if start.velocity is None else np.asarray(start.velocity, dtype=float)
        )
        bias = gtsam.imuBias.ConstantBias()
        graph = gtsam.NonlinearFactorGraph()
        graph.add(
            gtsam.PriorFactorPose3(
                X(0),
                pose,
                gtsam.noiseModel.Diagonal.Sigmas(
                    navstate_prior_sigmas(priors.rotation_sigma_rad, priors.position_sigma_m)
                ),
            )
        )
        graph.add(
            gtsam.PriorFactorVector(
                V(0), velocity, gtsam.noiseModel.Isotropic.Sigma(3, priors.velocity_sigma_m_s)
            )
        )
        graph.add(
            gtsam.PriorFactorConstantBias(
                B(0),
                bias,
                gtsam.noiseModel.Diagonal.Sigmas(
                    bias_prior_sigmas(priors.accel_bias_sigma_m_s2, priors.gyro_bias_sigma_rad_s)
                ),
            )
        )
        values = gtsam.Values()
        values.insert(X(0), pose)
        values.insert(V(0), velocity)
        values.insert(B(0), bias)
        self.integrator.start(start.t, bias)
        return graph, values

    def close(
        self, k: int, t: float, estimate: gtsam.Values
    ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
        """``CombinedImuFactor`` from ``k-1`` to ``k`` and the predicted state of ``k``."""
        pim = self.integrator.close(t)
        self.preintegrations[k] = pim
        graph = gtsam.NonlinearFactorGraph()
        graph.add(gtsam.CombinedImuFactor(X(k - 1), V(k - 1), X(k), V(k), B(k - 1), B(k), pim))
        previous = gtsam.NavState(estimate.atPose3(X(k - 1)), estimate.atVector(V(k - 1)))
        bias = estimate.atConstantBias(B(k - 1))
        predicted = pim.predict(previous, bias)
        values = gtsam.Values()
        values.insert(X(k), predicted.pose())
        values.insert(V(k), predicted.velocity())
        values.insert(B(k), bias)
        return graph, values

    def dead_reckoning_step(self, k: int, values: gtsam.Values) -> gtsam.Values:
        """Open-loop state of keyframe ``k`` from ``k-1`` in ``values`` (bias held at k-1's)."""
        bias = values.atConstantBias(B(k - 1))
        predicted = self.preintegrations[k].predict(
            gtsam.NavState(values.atPose3(X(k - 1)), values.atVector(V(k - 1))), bias
        )
        step = gtsam.Values()
        step.insert(X(k), predicted.pose())
        step.insert(V(k), predicted.velocity())
        step.insert(B(k), bias)
        return step

    def restart(self, t: float, estimate: gtsam.Values, k: int) -> None:
        """Begin the next interval at keyframe ``k``, linearised at its bias estimate."""
        self.integrator.start(t, estimate.atConstantBias(B(k)))

    def since_keyframe(self) -> int:
        return self.integrator.samples_since_keyframe

    @staticmethod
    def pose_of(values: gtsam.Values, k: int) -> gtsam.Pose3:
        return values.atPose3(X(k))

    @staticmethod
    def record(
        recorder: EstimateRecorder,
        t: float,
        values: gtsam.Values,
        k: int,
        marginals: MarginalSource | None,
    ) -> None:
        """Pose, world velocity and both biases of keyframe ``k`` in interface conventions."""
        pose = values.atPose3(X(k))
        bias = values.atConstantBias(B(k))
        pose_cov = velocity_cov = gyro_cov = accel_cov = None
        if marginals is not None:
            pose_cov = pose_covariance(marginals.marginalCovariance(X(k)))
            velocity_cov = vector_covariance(marginals.marginalCovariance(V(k)))
            split = bias_covariances(marginals.marginalCovariance(B(k)))
            gyro_cov, accel_cov = split.gyro, split.accel
        recorder.pose(
            t, pose.translation(), quat_wxyz_from_matrix(pose.rotation().matrix()), pose_cov
        )
        recorder.block(BlockName.VELOCITY, t, values.atVector(V(k)), velocity_cov, Frame.WORLD)
        recorder.block(BlockName.GYRO_BIAS, t, bias.gyroscope(), gyro_cov, Frame.BODY)
        recorder.block(BlockName.ACCEL_BIAS, t, bias.accelerometer(), accel_cov, Frame.BODY)
