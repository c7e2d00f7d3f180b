"""Where a bag without a lidar starts (``sensor_bag_start``): its world frame and initial
state at the start of the common time base, with the decision line saying where each part
comes from (``datasets.bags.sensor_source`` prints it with the sequence's other decisions):
- with GPS, the world is ENU about the first fix; the start is at the origin (its sigma the
  first fix's), the orientation from the IMU's own orientation where its messages state one
  (REP-103/REP-145: ENU), else the heading from the GPS course against the wheel odometry's
  over the first ``GPS_COURSE_MIN_M`` metres, else east with a warning. A named truth topic
  is then only scored (after alignment: its frame is not assumed to be the GPS's ENU);
- without GPS, from the truth topic when named (as for lidar bags), else the first body
  frame (the IMU's orientation where it states one) at the origin;
- the velocity from the truth, else from the wheel odometry's twist, else zero.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datasets.bags.bag_file import iter_messages
from datasets.bags.ground_truth import initial_state_from_truth
from datasets.bags.read_report import ReadReport
from datasets.bags.time_base import TimeBase
from datasets.bags.topic_roles import OdometryRole
from datasets.bags.wheel_odometry import PoseSample, pose_at
from datasets.rotations import matrix_from_quat_wxyz, wrap_angle, yaw_from_quat_wxyz
from datasets.sequence import InitialState
from datasets.state import GroundTruth

GPS_COURSE_MIN_M = 10.0
"""How far [m] the GPS track must have moved from its first fix before its course fixes
the start's heading (at 1 m GPS noise, 0.1 rad)."""
GPS_COURSE_WINDOW_S = 120.0
"""How long [s] from the start the GPS course is looked for."""


def _imu_orientation(reader, path: Path, topic: str, start_s: float):
    """The orientation (w, x, y, z) the Imu topic states at ``start_s`` (its first message
    at or after it), its sigma [rad] and a phrase of evidence; (None, None, why) where its
    messages state none (``orientation_covariance[0] == -1``, the ROS convention, or not a
    unit quaternion)."""
    for _, _, stamp, message in iter_messages(reader, path, [topic], report=ReadReport()):
        if stamp < start_s:
            continue
        covariance = np.asarray(message.orientation_covariance, dtype=float).reshape(3, 3)
        q = message.orientation
        quaternion = np.array([q.w, q.x, q.y, q.z], dtype=float)
        norm = float(np.linalg.norm(quaternion))
        if covariance[0, 0] == -1.0:
            return None, None, f"{topic} states no orientation (orientation_covariance[0] = -1)"
        if not (np.all(np.isfinite(quaternion)) and abs(norm - 1.0) < 0.01):
            return None, None, f"{topic}'s orientation is not a unit quaternion (norm {norm:.3g})"
        diagonal = np.diag(covariance)
        stated = bool(np.all(np.isfinite(diagonal)) and np.any(diagonal > 0))
        sigma = float(np.sqrt(np.max(diagonal))) if stated else 0.1
        rotation = matrix_from_quat_wxyz(quaternion / norm)
        roll = np.arctan2(rotation[2, 1], rotation[2, 2])
        pitch = -np.arcsin(np.clip(rotation[2, 0], -1.0, 1.0))
        text = (
            f"orientation from {topic} at t={stamp:.3f} (roll {np.rad2deg(roll):.1f}, pitch "
            f"{np.rad2deg(pitch):.1f}, yaw {np.rad2deg(yaw_from_quat_wxyz(quaternion)):.1f} deg; sigma "
            + (
                f"{sigma:.3g} rad from its covariance)"
                if stated
                else "0.1 rad: its covariance is zero, unknown)"
            )
        )
        return quaternion / norm, sigma, text
    return None, None, f"{topic} has no message after the start"


def _gps_course_heading(
    reader, path: Path, gps_topic: str, odometry: str, odometry_type: str, origin, start_s: float
) -> tuple[float | None, str]:
    """The start's yaw [rad] in ENU from the GPS course against the wheel odometry's: the
    first fix ``GPS_COURSE_MIN_M`` from the first one, its ENU displacement against the
    odometry's displacement between the two fixes' stamps in the odometry's body frame at
    the first, carried back to ``start_s`` by the odometry's own turn. (None, why) where the
    track does not move that far within ``GPS_COURSE_WINDOW_S``."""
    from datasets.bags.gps import geodetic_to_enu
    from datasets.bags.wheel_odometry import pose_sample

    fixes: list[tuple[float, np.ndarray]] = []
    samples: list[PoseSample] = []
    end_s = start_s + GPS_COURSE_WINDOW_S
    for topic, _, stamp, message in iter_messages(
        reader, path, [gps_topic, odometry], report=ReadReport()
    ):
        if stamp > end_s:
            break
        if topic == odometry:
            sample = pose_sample(message, odometry_type, stamp)
            if np.all(np.isfinite(sample.position)) and (not samples or stamp > samples[-1].t):
                samples.append(sample)
            continue
        if stamp < start_s or message.status.status < 0:
            continue
        fix = np.array([[message.latitude, message.longitude, message.altitude]], dtype=float)
        if np.all(np.isfinite(fix)):
            fixes.append((stamp, geodetic_to_enu(fix, origin)[0]))
        if len(fixes) > 1 and np.hypot(*(fixes[-1][1] - fixes[0][1])[:2]) >= GPS_COURSE_MIN_M:
            break
    if len(fixes) < 2 or np.hypot(*(fixes[-1][1] - fixes[0][1])[:2]) < GPS_COURSE_MIN_M:
        return (
            None,
            f"the GPS track moves less than {GPS_COURSE_MIN_M:g} m in its first {GPS_COURSE_WINDOW_S:g} s",
        )
    (t0, p0), (t1, p1) = fixes[0], fixes[-1]
    if len(samples) < 2 or samples[0].t > start_s or samples[-1].t < t1:
        return None, f"{odometry} does not cover the GPS fixes at t={t0:.3f}..{t1:.3f}"
    a_pos, a_q = pose_at(samples, t0)
    b_pos, _ = pose_at(samples, t1)
    s_pos, s_q = pose_at(samples, start_s)
    body = matrix_from_quat_wxyz(a_q).T @ (b_pos - a_pos)
    yaw_at_fix = np.arctan2(p1[1] - p0[1], p1[0] - p0[0]) - np.arctan2(body[1], body[0])
    yaw = float(wrap_angle(yaw_at_fix - (yaw_from_quat_wxyz(a_q) - yaw_from_quat_wxyz(s_q))))
    return yaw, (
        f"heading {np.rad2deg(yaw):.1f} deg (ENU, from east) from the GPS course over "
        f"{np.hypot(*(p1 - p0)[:2]):.1f} m (t={t0:.3f}..{t1:.3f}) against {odometry}'s "
        "displacement over the same stamps"
    )


def _yaw_quaternion(yaw: float) -> np.ndarray:
    return np.array([np.cos(0.5 * yaw), 0.0, 0.0, np.sin(0.5 * yaw)])


def _odometry_velocity(
    reader, path: Path, role: OdometryRole, start_s: float, rotation: np.ndarray
) -> tuple[np.ndarray | None, str]:
    """World-frame velocity at ``start_s`` from the wheel odometry's twist (its first
    message at or after it), with ``rotation`` the start's orientation."""
    from datasets.bags.wheel_odometry import pose_sample

    if (
        role.topic is None
        or role.evidence is None
        or role.evidence.msgtype != "nav_msgs/msg/Odometry"
    ):
        return None, "zero (no wheel odometry twist)"
    for _, msgtype, stamp, message in iter_messages(
        reader, path, [role.topic], report=ReadReport()
    ):
        if stamp < start_s:
            continue
        sample = pose_sample(message, msgtype, stamp)
        if sample.linear is None or not np.all(np.isfinite(sample.linear)):
            break
        velocity = matrix_from_quat_wxyz(rotation) @ sample.linear
        return (
            velocity,
            f"{np.linalg.norm(velocity):.3g} m/s from {role.topic}'s twist at t={stamp:.3f}",
        )
    return None, "zero (no wheel odometry twist at the start)"


def sensor_bag_start(
    reader,
    path: Path,
    settings,
    time_base: TimeBase,
    imu_topic: str | None,
    gps_topic: str | None,
    origin,
    role: OdometryRole,
    ground_truth: GroundTruth | None,
    warnings: list[str],
) -> tuple[InitialState, str]:
    """The initial state and the decision line saying where it comes from (module
    docstring); ``reader``: the bag, open (``open_bag``)."""
    start_s = time_base.start_s
    truth = ground_truth.pose if ground_truth is not None else None
    if gps_topic is None and truth is not None:
        initial = initial_state_from_truth(start_s, truth)
        return initial, f"start: from the truth topic at t={initial.t:.3f} (its frame is the world)"
    quaternion, sigma, orientation_text = None, 1e-3, ""
    reasons = []
    if imu_topic:
        quaternion, sigma, imu_text = _imu_orientation(reader, path, imu_topic, start_s)
        orientation_text = imu_text
        if quaternion is None:
            reasons.append(imu_text)
    if quaternion is None and gps_topic and role.topic:
        yaw, course_text = _gps_course_heading(
            reader, path, gps_topic, role.topic, role.evidence.msgtype, origin, start_s
        )
        if yaw is not None:
            quaternion, sigma, orientation_text = _yaw_quaternion(yaw), 0.05, course_text
        else:
            reasons.append(course_text)
    if quaternion is None:
        quaternion, sigma = np.array([1.0, 0.0, 0.0, 0.0]), 1e-3
        why = f" ({'; '.join(reasons)})" if reasons else ""
        if gps_topic:
            orientation_text = f"level, facing east: assumed{why}"
            warnings.append(
                f"start heading unknown{why}: east assumed; the GPS-aided estimates are "
                "wrong where the vehicle started facing elsewhere"
            )
        else:
            orientation_text = f"the first body frame{why}"
    velocity, velocity_text = _odometry_velocity(reader, path, role, start_s, quaternion)
    if gps_topic:
        world = (
            f"world: ENU about the first fix of {gps_topic} (lat {origin[0]:.7f}, lon "
            f"{origin[1]:.7f}, alt {origin[2]:.2f} m)"
        )
        if truth is not None:
            world += (
                "; the truth topic is only scored, after alignment (its frame is not assumed "
                "to be this ENU)"
            )
        position_sigma = settings.gps_sigma_m
    else:
        world = "world: the start's body frame at the origin"
        position_sigma = 1e-3
    initial = InitialState(
        t=start_s,
        position=np.zeros(3),
        rotation=np.asarray(quaternion, dtype=float),
        velocity=velocity,
        position_sigma_m=position_sigma,
        rotation_sigma_rad=float(sigma),
    )
    return initial, (
        f"start at t={start_s:.3f} ({time_base.start_by}): {world}; orientation: "
        f"{orientation_text}; velocity: {velocity_text}"
    )
