"""Wheel odometry from a bag: pose messages to ``Odometry`` increments with a covariance.

Input: the messages of the odometry topic (``nav_msgs/Odometry``, or, when named, a
``PoseStamped`` / ``PoseWithCovarianceStamped`` topic), read as ``PoseSample``: the pose the
odometry integrated (``frame_id``, usually ``odom``) and, for ``nav_msgs/Odometry``, the twist
in the child (body) frame with its covariance.

Increments: the relative pose of consecutive samples, ``T_{k-1}^-1 T_k`` (rotation vector
[rad], translation [m], previous body frame: the ``Odometry.relative_pose`` convention of 3-D
increments), or, for a topic whose pose stands still while its twist says it moves (a driver
publishing only velocities), ``(omega dt, v dt)``. Increments are composed to at most
``max_rate_hz`` (the smoothers open a keyframe at every 3-D relative pose), the covariance
composed with them (right perturbation: ``Sigma_ac = Ad(U_bc^-1) Sigma_ab Ad(U_bc^-1)^T +
Sigma_bc``), and emitted as ``Odometry(frame=False)``: motion input, never a frame and never
truth.

Covariance, per axis, in GTSAM's Pose3 order [rotation x, y, z, translation x, y, z]:
- from the message's twist covariance where that axis's variance is meaningful (finite,
  positive and below ``PLACEHOLDER_VARIANCE``: drivers write 0 for "not computed" and 1e3 to
  1e6 for "not measured"). A twist covariance is per message: the error of a velocity held
  over one message interval ``dt_s`` (the topic's median); over an increment of ``dt`` it is
  ``variance * dt_s * dt`` (white noise at the topic's rate: the same whether increments are
  composed or not);
- else from the stated default model: ``WHEEL_ODOMETRY_NOISE`` for x, y and yaw (variance
  linear in time, distance and turn, ``datasets.odometry_noise``) and ``OUT_OF_PLANE_RATES``
  for z, roll and pitch (planar wheel odometry says nothing of them; per metre travelled).
``--data odometry_noise=model`` uses the model for every axis, ``=twist`` insists on the
twist (an ``InputError`` where the first message has none), or a YAML file from ``workbench
calibrate-noise`` replaces the default planar model.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np

from datasets.errors import InputError
from datasets.measurements import Measurement, Odometry, Sensor
from datasets.odometry_noise import OdometryNoiseModel, read_model_file
from datasets.rotations import (
    matrix_from_quat_wxyz,
    pose3_inverse_adjoint,
    quat_wxyz_from_matrix,
    so3_exp,
    so3_log,
)

PLACEHOLDER_VARIANCE = 1.0
"""A twist variance at or above this [(m/s)^2 or (rad/s)^2] is a placeholder, not a
measurement: a wheel speed known to 1 m/s is not known (diff_drive_controller writes 1e3 and
1e6 for the axes it does not measure)."""

WHEEL_ODOMETRY_NOISE = OdometryNoiseModel(
    np.array(
        [
            [1e-6, 1e-6, 1e-6],  # per second: x [m^2/s], y [m^2/s], yaw [rad^2/s]
            [4e-4, 4e-4, 5e-4],  # per metre: 2 cm, 2 cm, 0.022 rad per sqrt(m)
            [1e-4, 1e-4, 2.5e-3],  # per radian turned: 1 cm, 1 cm, 0.05 rad per sqrt(rad)
        ]
    ),
    "stated default for a bag's wheel odometry (datasets.bags.wheel_odometry)",
)
"""The planar noise of wheel odometry where the bag states none: 2 cm of position and 1.3
deg of heading per sqrt(metre) travelled, 5 % of the turn (per sqrt(rad)), a floor in time so
that a still robot keeps a positive covariance. Not fitted to any recording: a conservative
middle of what differential-drive robots on indoor and paved floors show; ``workbench
calibrate-noise`` fits one where truth exists."""

OUT_OF_PLANE_RATES = np.array([1e-4, 1e-4, 1e-4])
"""Variance per metre travelled of roll [rad^2/m], pitch [rad^2/m] and z [m^2/m] of a planar
wheel odometry's increments (1 cm and 0.01 rad per sqrt(metre)): what uneven floors do to a
source that reports none."""

OUT_OF_PLANE_FLOOR = 1e-6
"""Variance per second of roll, pitch and z [rad^2/s, m^2/s]: positive when still."""

ROS_TO_POSE3 = np.array([3, 4, 5, 0, 1, 2])
"""ROS orders a twist or pose covariance (x, y, z, rot x, rot y, rot z); GTSAM's Pose3
tangent (and ``Odometry.relative_pose``) is (rot x, rot y, rot z, x, y, z)."""

AXIS_NAMES = ("roll", "pitch", "yaw", "x", "y", "z")  # Pose3 order


@dataclass(frozen=True)
class PoseSample:
    """One message of the odometry topic as the bag reader emits it (internal to the bag
    source: turned into ``Odometry`` increments by ``WheelIncrements``).

    Attributes:
        t: header stamp [s].
        position: (3,) [m] in the message's frame.
        quaternion: (4,) (w, x, y, z), body to that frame.
        linear: (3,) body-frame velocity [m/s], or None (no twist in the message type).
        angular: (3,) body-frame angular rate [rad/s], or None.
        twist_covariance: (6, 6) in ROS order (x, y, z, rot x, rot y, rot z), or None.
    """

    t: float
    position: np.ndarray
    quaternion: np.ndarray
    linear: np.ndarray | None = None
    angular: np.ndarray | None = None
    twist_covariance: np.ndarray | None = None
    sensor = Sensor.ODOMETRY


def _vector(v) -> np.ndarray:
    return np.array([v.x, v.y, v.z], dtype=float)


def pose_sample(message, msgtype: str, stamp: float) -> PoseSample:
    """A ``PoseSample`` of an Odometry, PoseStamped or PoseWithCovarianceStamped message."""
    if msgtype == "nav_msgs/msg/Odometry":
        pose = message.pose.pose
        twist = message.twist
        linear, angular = _vector(twist.twist.linear), _vector(twist.twist.angular)
        covariance = np.asarray(twist.covariance, dtype=float).reshape(6, 6)
    else:
        pose = message.pose.pose if hasattr(message.pose, "covariance") else message.pose
        linear = angular = covariance = None
    q = pose.orientation
    return PoseSample(
        t=stamp,
        position=_vector(pose.position),
        quaternion=np.array([q.w, q.x, q.y, q.z], dtype=float),
        linear=linear,
        angular=angular,
        twist_covariance=covariance,
    )


def meaningful_axes(twist_covariance: np.ndarray | None) -> np.ndarray:
    """(6,) bool in Pose3 order: which axes of a ROS twist covariance are measurements
    (finite, positive, below ``PLACEHOLDER_VARIANCE``)."""
    if twist_covariance is None:
        return np.zeros(6, dtype=bool)
    variances = np.diag(np.asarray(twist_covariance, dtype=float))[ROS_TO_POSE3]
    with np.errstate(invalid="ignore"):
        return np.isfinite(variances) & (variances > 0) & (variances < PLACEHOLDER_VARIANCE)


@dataclass(frozen=True)
class WheelNoise:
    """How increment covariances are made (module docstring).

    Attributes:
        model: the planar model for x, y, yaw where the twist does not say.
        use_twist: take meaningful twist variances per axis.
        message_interval_s: the topic's median message interval (a twist variance's
            duration).
    """

    model: OdometryNoiseModel
    use_twist: bool
    message_interval_s: float

    def covariance(
        self, increment: np.ndarray, dt: float, twist_covariance: np.ndarray | None
    ) -> np.ndarray:
        """(6, 6) diagonal covariance of one increment (rotation vector, translation) over
        ``dt`` [s]."""
        rotation, translation = increment[:3], increment[3:]
        distance = float(np.hypot(translation[0], translation[1]))
        planar = self.model.variances(np.array([dt]), distance, rotation[2])[0]  # x, y, yaw
        out_of_plane = OUT_OF_PLANE_RATES * distance + OUT_OF_PLANE_FLOOR * dt
        variances = np.array(
            [out_of_plane[0], out_of_plane[1], planar[2], planar[0], planar[1], out_of_plane[2]]
        )
        if self.use_twist and twist_covariance is not None:
            given = meaningful_axes(twist_covariance)
            twist = np.diag(np.asarray(twist_covariance, dtype=float))[ROS_TO_POSE3]
            variances[given] = twist[given] * self.message_interval_s * dt
        return np.diag(variances)


def noise_policy(
    choice: str, first: PoseSample | None, message_interval_s: float, topic: str
) -> tuple[WheelNoise, str]:
    """The ``WheelNoise`` of ``--data odometry_noise=choice`` (``auto``, ``twist``, ``model``
    or a YAML model file) and one line of evidence for the decision."""
    given = meaningful_axes(first.twist_covariance if first else None)
    named = [AXIS_NAMES[i] for i in range(6) if given[i]]
    if choice in ("auto", "twist", "model"):
        model = WHEEL_ODOMETRY_NOISE
    else:
        model = read_model_file(choice)
    if choice == "twist" and not given.any():
        raise InputError(
            f"odometry_noise=twist: the first message on {topic} has no meaningful twist "
            "covariance (every variance zero, non-finite or a placeholder >= "
            f"{PLACEHOLDER_VARIANCE:g}); use odometry_noise=auto or model"
        )
    use_twist = choice in ("auto", "twist") and bool(given.any())
    model_text = (
        "the stated default model (datasets.bags.wheel_odometry.WHEEL_ODOMETRY_NOISE, "
        "OUT_OF_PLANE_RATES)"
        if choice in ("auto", "twist", "model")
        else f"the model in {choice}"
    )
    if use_twist:
        variances = np.diag(first.twist_covariance)[ROS_TO_POSE3]
        sigmas = ", ".join(
            f"{AXIS_NAMES[i]} {np.sqrt(variances[i]):.3g}" for i in range(6) if given[i]
        )
        others = [AXIS_NAMES[i] for i in range(6) if not given[i]]
        text = (
            f"covariance from the messages' twist covariance for {', '.join(named)} (sigma "
            f"{sigmas} per message, over {1e3 * message_interval_s:.3g} ms)"
            + (f"; {', '.join(others)} from {model_text}" if others else "")
        )
    else:
        why = (
            "odometry_noise=model"
            if choice == "model"
            else "the twist covariance is zero or placeholders on every axis"
            if first is not None and first.twist_covariance is not None
            else "the messages carry no twist covariance"
        )
        text = f"covariance from {model_text} ({why})"
    return WheelNoise(model, use_twist, message_interval_s), text


def relative_pose(previous: PoseSample, current: PoseSample) -> np.ndarray:
    """(6,) rotation vector and translation of ``current`` in ``previous``'s body frame."""
    r0 = matrix_from_quat_wxyz(previous.quaternion / np.linalg.norm(previous.quaternion))
    r1 = matrix_from_quat_wxyz(current.quaternion / np.linalg.norm(current.quaternion))
    return np.concatenate([so3_log(r0.T @ r1), r0.T @ (current.position - previous.position)])


def compose(
    first: np.ndarray, first_cov: np.ndarray, second: np.ndarray, second_cov: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``U_ab U_bc`` of two increments (rotation vector, translation) with their
    covariances (right perturbation, Pose3 order)."""
    r_ab, r_bc = so3_exp(first[:3]), so3_exp(second[:3])
    rotation = so3_log(r_ab @ r_bc)
    translation = first[3:] + r_ab @ second[3:]
    adjoint = pose3_inverse_adjoint(second[:3], second[3:])
    covariance = adjoint @ first_cov @ adjoint.T + second_cov
    return np.concatenate([rotation, translation]), 0.5 * (covariance + covariance.T)


@dataclass
class WheelIncrements:
    """Turns the ``PoseSample`` stream of the odometry topic into ``Odometry`` increments
    (module docstring); fed in stamp order, one instance per pass over the bag.

    Attributes:
        noise: the covariance policy.
        from_twist: increments from the twist (the pose stands still), not pose differences.
        max_rate_hz: compose increments to at most this rate (None: every message).
        start_s: increments are counted from the first sample at or after it (the time
            base's start); earlier samples only set the pose the first increment starts at.
    """

    noise: WheelNoise
    from_twist: bool = False
    max_rate_hz: float | None = None
    start_s: float | None = None
    _previous: PoseSample | None = None
    _pending: tuple[np.ndarray, np.ndarray, float, float] | None = field(default=None)
    emitted: int = 0
    composed: int = 0

    def convert(self, measurements: Iterable[Measurement]) -> Iterator[Measurement]:
        """``measurements`` with each ``PoseSample`` (the odometry topic's) replaced by the
        increment it completes, when one is due; every other measurement as it is."""
        for measurement in measurements:
            if isinstance(measurement, PoseSample):
                odometry = self.add(measurement)
                if odometry is not None:
                    yield odometry
            else:
                yield measurement

    def add(self, sample: PoseSample) -> Odometry | None:
        """The increment ending at ``sample`` when one is due, else None."""
        previous, self._previous = self._previous, sample
        if previous is None or (self.start_s is not None and previous.t < self.start_s):
            return None
        dt = sample.t - previous.t
        if dt <= 0:
            return None
        if self.from_twist and sample.linear is not None:
            increment = np.concatenate([sample.angular * dt, sample.linear * dt])
        else:
            increment = relative_pose(previous, sample)
        if not np.all(np.isfinite(increment)):
            return None
        covariance = self.noise.covariance(increment, dt, sample.twist_covariance)
        if self._pending is None:
            start = previous.t
            pending = (increment, covariance, start, sample.t)
        else:
            total, total_cov, start, _ = self._pending
            total, total_cov = compose(total, total_cov, increment, covariance)
            pending = (total, total_cov, start, sample.t)
            self.composed += 1
        span = pending[3] - pending[2]
        if self.max_rate_hz is not None and span < (1.0 - 1e-6) / self.max_rate_hz:
            self._pending = pending
            return None
        self._pending = None
        self.emitted += 1
        return Odometry(
            t=sample.t,
            covariance=pending[1],
            relative_pose=pending[0],
            dt=span,
            frame=False,
        )


def pose_at(samples: list[PoseSample], t: float) -> tuple[np.ndarray, np.ndarray]:
    """Position (3,) and quaternion (4,) of the odometry at ``t`` (linear in position,
    slerp-free rotation interpolation by the relative rotation vector)."""
    times = np.array([s.t for s in samples])
    k = int(np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(samples) - 2))
    a, b = samples[k], samples[k + 1]
    u = 0.0 if b.t == a.t else float(np.clip((t - a.t) / (b.t - a.t), 0.0, 1.0))
    ra = matrix_from_quat_wxyz(a.quaternion / np.linalg.norm(a.quaternion))
    rb = matrix_from_quat_wxyz(b.quaternion / np.linalg.norm(b.quaternion))
    rotation = ra @ so3_exp(u * so3_log(ra.T @ rb))
    return a.position + u * (b.position - a.position), quat_wxyz_from_matrix(rotation)
